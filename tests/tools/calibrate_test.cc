// `roomfix calibrate` and `roomfix map`, run as a user would, on points
// generated from a synthetic fisheye camera.
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <random>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "core/calib/calibration_file.h"
#include "core/calib/fisheye_camera.h"
#include "core/world/file_io.h"
#include "tests/testing/demo_site.h"
#include "tests/testing/test_paths.h"

namespace roomfix {
namespace {

using calib::Calibration;
using calib::CameraModel;
using testing::BinDir;
using testing::ChildProcess;
using testing::DemoSitePath;
using testing::ReadFile;
using testing::SharedDataDir;
using testing::SourceDir;
using testing::TempDir;
using testing::WriteFile;

constexpr double kCalibrationHeightM = 0.2;

// The demo room's camera (config/sites/demo_room.yaml) as built: a few
// centimetres off its nominal mount, tilted by a degree, fx 4 % long, with
// a real lens's distortion.
CameraModel TrueCamera() {
  CameraModel m = calib::NominalCamera({2.0, 1.5, 3.1}, 120.0, 1920, 1080);
  m.intrinsics.fx_px *= 1.04;
  m.intrinsics.fy_px *= 1.04;
  m.intrinsics.cx_px += 5.0;
  m.intrinsics.cy_px -= 3.0;
  m.intrinsics.k = {0.02, -0.01, 0.0, 0.0};
  Eigen::Matrix3d tilt;
  const double a = 1.0 * M_PI / 180;
  tilt << 1, 0, 0, 0, std::cos(a), -std::sin(a), 0, std::sin(a), std::cos(a);
  m.pose.R_room_from_camera = m.pose.R_room_from_camera * tilt;
  m.pose.position_m += Eigen::Vector3d(0.004, -0.003, 0.003);
  return m;
}

struct RunResult {
  int exit_code = 0;
  std::string out;
};

// Runs `roomfix ARGS...`; `stderr_only` captures standard error instead of
// standard output (through sh: ChildProcess captures one stream).
RunResult Roomfix(const std::vector<std::string>& args, bool stderr_only = false) {
  TempDir dir;
  std::vector<std::string> argv;
  if (stderr_only) {
    std::string command = "'" + BinDir() + "/roomfix'";
    for (const auto& a : args) command += " '" + a + "'";
    argv = {"/bin/sh", "-c", command + " 2>&1 >/dev/null"};
  } else {
    argv = {BinDir() + "/roomfix"};
    argv.insert(argv.end(), args.begin(), args.end());
  }
  ChildProcess p(argv, dir.File("out.txt"));
  RunResult r;
  r.exit_code = p.Wait(120);
  r.out = ReadFile(dir.File("out.txt"));
  return r;
}

// 20 markers spread over the 4 x 3 m floor at 0.2 m, seen with 0.3 px
// Gaussian noise, as CSV; `outlier` >= 0 moves that point's u by 15 px.
std::string PointsCsv(int outlier = -1) {
  std::mt19937 rng(11);
  std::normal_distribution<double> noise(0.0, 0.3);
  const CameraModel truth = TrueCamera();
  std::ostringstream csv;
  csv.precision(12);
  csv << "u,v,x_m,y_m,height_m\n";
  int k = 0;
  for (int i = 0; i < 5; ++i) {
    for (int j = 0; j < 4; ++j, ++k) {
      const double x = 0.4 + 0.8 * i, y = 0.3 + 0.8 * j;
      double u, v;
      EXPECT_TRUE(truth.ProjectToPixel(Eigen::Vector3d(x, y, kCalibrationHeightM), &u, &v));
      u += noise(rng) + (k == outlier ? 15.0 : 0.0);
      v += noise(rng);
      csv << u << "," << v << "," << x << "," << y << "," << kCalibrationHeightM << "\n";
    }
  }
  return csv.str();
}

std::vector<std::vector<double>> ParseCsv(const std::string& text) {
  std::vector<std::vector<double>> rows;
  std::istringstream lines(text);
  std::string line;
  std::getline(lines, line);  // header
  while (std::getline(lines, line)) {
    std::vector<double> row;
    std::stringstream fields(line);
    std::string field;
    while (std::getline(fields, field, ',')) row.push_back(std::stod(field));
    rows.push_back(row);
  }
  return rows;
}

TEST(RoomfixCalibrate, FitsTheSyntheticCameraFlagsTheOutlierAndWritesYamlAndPng) {
  TempDir dir;
  ASSERT_TRUE(WriteFile(dir.File("points.csv"), PointsCsv(/*outlier=*/7)));
  const RunResult r =
      Roomfix({"calibrate", "--points", dir.File("points.csv"), "--out", dir.File("cam0.yaml"),
               "--site", DemoSitePath(), "--camera", "0", "--pixel-sigma", "0.3"});
  std::cout << r.out;
  ASSERT_EQ(r.exit_code, 0);
  // Point 7 is flagged in its table row and in its own line.
  std::istringstream lines(r.out);
  std::string line;
  int outlier_rows = 0;
  while (std::getline(lines, line)) {
    if (line.find("OUTLIER") != std::string::npos) {
      ++outlier_rows;
      EXPECT_EQ(line.rfind("    7    9 ", 0), 0u) << line;
    }
  }
  EXPECT_EQ(outlier_rows, 1);
  EXPECT_NE(r.out.find("outlier: point 7 (line 9)"), std::string::npos);
  EXPECT_NE(r.out.find("full model: RMS "), std::string::npos);
  EXPECT_NE(r.out.find("9-region model: "), std::string::npos);

  Calibration cal;
  std::string error;
  ASSERT_TRUE(calib::LoadCalibration(dir.File("cam0.yaml"), &cal, &error)) << error;
  ASSERT_EQ(cal.model, Calibration::Model::kFull);
  EXPECT_EQ(cal.width_px(), 1920);
  EXPECT_EQ(cal.height_px(), 1080);
  // The written model maps the floor at the calibration height to a few mm.
  const CameraModel truth = TrueCamera();
  double sum2 = 0;
  int n = 0;
  for (double x = 0.0; x <= 4.0; x += 0.25) {
    for (double y = 0.0; y <= 3.0; y += 0.25, ++n) {
      double u, v, mx, my;
      ASSERT_TRUE(truth.ProjectToPixel(Eigen::Vector3d(x, y, kCalibrationHeightM), &u, &v));
      ASSERT_TRUE(cal.PixelToFloor(u, v, kCalibrationHeightM, &mx, &my, &error)) << error;
      sum2 += std::pow(mx - x, 2) + std::pow(my - y, 2);
    }
  }
  EXPECT_LT(std::sqrt(sum2 / n), 0.003);

  const std::string png = ReadFile(dir.File("cam0.png"));
  ASSERT_GT(png.size(), 1000u);
  EXPECT_EQ(png.substr(1, 3), "PNG");
  // The fit's residual is stored for camera_proc and check-config: the 0.3
  // px noise of the points, well under their 2 px tolerance.
  EXPECT_GT(cal.fit_rms_px, 0.1);
  EXPECT_LT(cal.fit_rms_px, 0.6);
  EXPECT_EQ(calib::CheckFitResidual(cal), "");
}

// Runs `roomfix calibrate` on DIR/p.csv into DIR/cal.yaml with the demo
// site and `extra` flags, and expects a refusal: exit code 1, `message` as
// the start of the only line on standard error, no calibration written.
void ExpectCalibrateRefuses(const TempDir& dir, const std::vector<std::string>& extra,
                            const std::string& message) {
  std::vector<std::string> args = {"calibrate",          "--points", dir.File("p.csv"), "--out",
                                   dir.File("cal.yaml"), "--site",   DemoSitePath()};
  args.insert(args.end(), extra.begin(), extra.end());
  const RunResult r = Roomfix(args, /*stderr_only=*/true);
  EXPECT_EQ(r.exit_code, 1) << message;
  EXPECT_EQ(r.out.rfind(message, 0), 0u) << r.out;
  EXPECT_EQ(std::count(r.out.begin(), r.out.end(), '\n'), 1) << r.out;
  EXPECT_FALSE(std::filesystem::exists(dir.File("cal.yaml"))) << message;
}

// Issue #15: a fit that does not reproduce its points is refused, not
// written; the tolerance is a flag (default 2 px, what camera_proc accepts).
TEST(RoomfixCalibrate, RefusesAFitOverTheResidualToleranceWithOneLine) {
  TempDir dir;
  ASSERT_TRUE(WriteFile(dir.File("p.csv"), PointsCsv()));
  struct Case {
    std::vector<std::string> extra;
    std::string message;
  };
  const std::vector<Case> cases = {
      // The points carry 0.3 px of noise: a 0.1 px tolerance cannot be met.
      {{"--max-rms-px", "0.1"}, "roomfix calibrate: full model: RMS 0."},
      {{"--max-rms-px", "0"}, "roomfix calibrate: --max-rms-px: expected a positive number"},
      {{"--max-rms-px", "nan"}, "roomfix calibrate: --max-rms-px: expected a positive number"},
  };
  for (const Case& c : cases) ExpectCalibrateRefuses(dir, c.extra, c.message);
  const RunResult r =
      Roomfix({"calibrate", "--points", dir.File("p.csv"), "--out", dir.File("cal.yaml"), "--site",
               DemoSitePath(), "--max-rms-px", "0.1"},
              /*stderr_only=*/true);
  EXPECT_NE(r.out.find(" px over the points is over the 0.10 px tolerance (--max-rms-px); "
                       "not written"),
            std::string::npos)
      << r.out;
}

// Every numeric flag is checked while the command line is parsed (CLI11
// validators, tools/flag_checks.h), NaN and infinities included: one line
// naming the command and the flag, exit 1, nothing written.
TEST(RoomfixCalibrate, RefusesAnOutOfRangeFlagWhileParsingWithOneLine) {
  TempDir dir;
  ASSERT_TRUE(WriteFile(dir.File("p.csv"), PointsCsv()));
  const std::vector<std::pair<std::vector<std::string>, std::string>> cases = {
      {{"--model", "pinhole"}, "roomfix calibrate: --model: pinhole not in {full,regions}"},
      {{"--square", "nan"}, "roomfix calibrate: --square: expected the square size in metres"},
      {{"--board-height", "-0.01"}, "roomfix calibrate: --board-height: expected metres >= 0"},
      {{"--mount-sigma", "0"}, "roomfix calibrate: --mount-sigma: expected a positive number"},
      {{"--outlier-px", "inf"}, "roomfix calibrate: --outlier-px: expected a positive number"},
      {{"--pixel-sigma", "-1"}, "roomfix calibrate: --pixel-sigma: expected a positive number"},
      {{"--fov", "nan"}, "roomfix calibrate: --fov: expected degrees >= 0"},
      {{"--max-iterations", "0"},
       "roomfix calibrate: --max-iterations: Value 0 not in range 1 to 100000"},
  };
  for (const auto& [extra, message] : cases) ExpectCalibrateRefuses(dir, extra, message);
}

// More outliers than a fit may leave out (20 % of the points): refused at
// once instead of refitting once per outlier.
TEST(RoomfixCalibrate, RefusesPointsWithMoreOutliersThanItMayLeaveOut) {
  TempDir dir;
  std::string csv = PointsCsv();
  // Move 6 of the 20 points' u by 40 px (4 may be left out).
  std::istringstream in(csv);
  std::string line, moved;
  for (int i = -1; std::getline(in, line); ++i) {
    if (i >= 0 && i % 3 == 0) {
      const size_t comma = line.find(',');
      line = std::to_string(std::stod(line.substr(0, comma)) + 40.0) + line.substr(comma);
    }
    moved += line + "\n";
  }
  ASSERT_TRUE(WriteFile(dir.File("p.csv"), moved));
  const RunResult r = Roomfix({"calibrate", "--points", dir.File("p.csv"), "--out",
                               dir.File("cal.yaml"), "--site", DemoSitePath()},
                              /*stderr_only=*/true);
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(r.out.rfind("roomfix calibrate: full model: ", 0), 0u) << r.out;
  EXPECT_NE(r.out.find("over the 4 that may be left out as outliers: the points do not fit one "
                       "camera"),
            std::string::npos)
      << r.out;
  EXPECT_FALSE(std::filesystem::exists(dir.File("cal.yaml")));
}

// Issue #15's row: 2 000 random points. Refused (either model) with one
// line, quickly, nothing written. Measured 2.5-3 s on the 2-core machine
// (GSL's 200 iterations over 2 000 points); the bound allows a loaded one.
constexpr double kRandomPointsMaxSeconds = 20.0;

TEST(RoomfixCalibrate, RefusesTwoThousandRandomPointsQuickly) {
  TempDir dir;
  std::mt19937 rng(15);
  std::uniform_real_distribution<double> u(0, 1920), v(0, 1080), x(0, 4), y(0, 3);
  std::ostringstream csv;
  csv << "u,v,x_m,y_m,height_m\n";
  for (int i = 0; i < 2000; ++i)
    csv << u(rng) << "," << v(rng) << "," << x(rng) << "," << y(rng) << ",0\n";
  ASSERT_TRUE(WriteFile(dir.File("random.csv"), csv.str()));
  for (const std::string model : {"full", "regions"}) {
    const auto start = std::chrono::steady_clock::now();
    const RunResult r = Roomfix({"calibrate", "--points", dir.File("random.csv"), "--out",
                                 dir.File("cal.yaml"), "--site", DemoSitePath(), "--model", model},
                                /*stderr_only=*/true);
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    std::printf("calibrate --model %s on 2000 random points: exit %d after %.1f s: %s",
                model.c_str(), r.exit_code, seconds, r.out.c_str());
    EXPECT_EQ(r.exit_code, 1) << model;
    EXPECT_EQ(std::count(r.out.begin(), r.out.end(), '\n'), 1) << r.out;
    EXPECT_LT(seconds, kRandomPointsMaxSeconds) << model;
    EXPECT_FALSE(std::filesystem::exists(dir.File("cal.yaml"))) << model;
  }
}

// Issue #28, item 8: one wrong row (a u off by 400 px, a mistyped digit)
// pulled the least-squares fit so that every point was "more than 3 px
// off" and the set was refused without saying which row was wrong. The
// worst is left out and the fit judged again: the wrong row is named.
constexpr double kWrongRowPx = 400.0;

TEST(RoomfixCalibrate, OneWrongRowIsNamedRatherThanEveryPointCalledOff) {
  TempDir dir;
  std::istringstream in(PointsCsv());
  std::string line, csv;
  for (int i = -1; std::getline(in, line); ++i) {
    if (i == 7) {
      const size_t comma = line.find(',');
      line = std::to_string(std::stod(line.substr(0, comma)) + kWrongRowPx) + line.substr(comma);
    }
    csv += line + "\n";
  }
  ASSERT_TRUE(WriteFile(dir.File("p.csv"), csv));
  const RunResult r =
      Roomfix({"calibrate", "--points", dir.File("p.csv"), "--out", dir.File("cal.yaml"), "--site",
               DemoSitePath(), "--pixel-sigma", "0.3"});
  EXPECT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("outlier: point 7 (line 9)"), std::string::npos) << r.out;
  EXPECT_EQ(r.out.find("outlier: point 1 "), std::string::npos) << r.out;
}

// Issue #28, item 8: no cap on the rows (3 000 still running after 60 s),
// and a coordinate of 1e308 reported as "all points lie on a line".
TEST(RoomfixCalibrate, RefusesTooManyRowsAndCoordinatesOutOfRangeNamingTheLine) {
  TempDir dir;
  std::string csv = "u,v,x_m,y_m,height_m\n";
  for (int i = 0; i < 501; ++i) csv += "960,540,2,1.5,0\n";
  ASSERT_TRUE(WriteFile(dir.File("many.csv"), csv));
  RunResult r = Roomfix({"calibrate", "--points", dir.File("many.csv"), "--out",
                         dir.File("cal.yaml"), "--site", DemoSitePath()},
                        /*stderr_only=*/true);
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.out.find("many.csv:502: more than 500 points (the cap of a calibration CSV)"),
            std::string::npos)
      << r.out;

  std::string huge = PointsCsv();
  huge.replace(huge.find('\n') + 1, 0, "1e308,540,2,1.5,0.2\n");
  ASSERT_TRUE(WriteFile(dir.File("huge.csv"), huge));
  r = Roomfix({"calibrate", "--points", dir.File("huge.csv"), "--out", dir.File("cal.yaml"),
               "--site", DemoSitePath()},
              /*stderr_only=*/true);
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.out.find("huge.csv:2: u: 1e308 is out of range (at most 100000 px either way)"),
            std::string::npos)
      << r.out;
  EXPECT_EQ(r.out.find("on a line"), std::string::npos) << r.out;
  EXPECT_FALSE(std::filesystem::exists(dir.File("cal.yaml")));
}

// Every file calibrate writes reports a failed write: exit 1 and the reason.
TEST(RoomfixCalibrate, AFullDiskIsAFailedRunNamingTheFile) {
  TempDir dir;
  ASSERT_TRUE(WriteFile(dir.File("p.csv"), PointsCsv()));
  const std::string site = DemoSitePath();
  const RunResult yaml =
      Roomfix({"calibrate", "--points", dir.File("p.csv"), "--out", "/dev/full", "--site", site},
              /*stderr_only=*/true);
  EXPECT_EQ(yaml.exit_code, 1);
  EXPECT_EQ(yaml.out, "roomfix calibrate: /dev/full: cannot write: No space left on device\n");
  const RunResult png = Roomfix({"calibrate", "--points", dir.File("p.csv"), "--out",
                                 dir.File("cal.yaml"), "--png", "/dev/full", "--site", site},
                                /*stderr_only=*/true);
  EXPECT_EQ(png.exit_code, 1);
  EXPECT_EQ(png.out, "roomfix calibrate: /dev/full: cannot write: No space left on device\n");
}

TEST(RoomfixMap, FullModelRoundTripsPixelToFloorAndBackWithin1e6) {
  TempDir dir;
  ASSERT_TRUE(WriteFile(dir.File("points.csv"), PointsCsv()));
  ASSERT_EQ(
      Roomfix({"calibrate", "--points", dir.File("points.csv"), "--out", dir.File("cam0.yaml"),
               "--mount", "2.0,1.5,3.1", "--mount-sigma", "0.005", "--size", "1920x1080"})
          .exit_code,
      0);
  const std::vector<std::vector<double>> pixels = {
      {960, 540, 0.2}, {100, 80, 0.0}, {1850, 1000, 0.5}, {1234.5, 321.25, 0.2}};
  std::ostringstream in;
  in << "u,v,height_m\n";
  for (const auto& p : pixels) in << p[0] << "," << p[1] << "," << p[2] << "\n";
  ASSERT_TRUE(WriteFile(dir.File("pixels.csv"), in.str()));

  const RunResult forward =
      Roomfix({"map", "--calibration", dir.File("cam0.yaml"), dir.File("pixels.csv")});
  ASSERT_EQ(forward.exit_code, 0) << forward.out;
  EXPECT_EQ(forward.out.rfind("x_m,y_m,height_m\n", 0), 0u);
  ASSERT_TRUE(WriteFile(dir.File("floor.csv"), forward.out));
  const RunResult back =
      Roomfix({"map", "--calibration", dir.File("cam0.yaml"), "--inverse", dir.File("floor.csv")});
  ASSERT_EQ(back.exit_code, 0) << back.out;
  const auto floor = ParseCsv(forward.out);
  const auto again = ParseCsv(back.out);
  ASSERT_EQ(again.size(), pixels.size());
  // The promise of the test's name: far above what the CSV's 12 significant
  // digits lose (1e-11 m at a few hundred px/m: ~1e-9 px), far below what any
  // marker detector resolves.
  constexpr double kRoundTripPx = 1e-6;
  for (size_t i = 0; i < pixels.size(); ++i) {
    EXPECT_NEAR(again[i][0], pixels[i][0], kRoundTripPx) << i;
    EXPECT_NEAR(again[i][1], pixels[i][1], kRoundTripPx) << i;
    EXPECT_EQ(again[i][2], pixels[i][2]);
  }
  // The image centre is near the nadir: below the 3.1 m mount. Near, not at:
  // the fitted principal point and the lens's tilt move it; 10 cm checks the
  // axes and the origin, not the fit's accuracy.
  constexpr double kNearTheNadirM = 0.1;
  EXPECT_NEAR(floor[0][0], 2.0, kNearTheNadirM);
  EXPECT_NEAR(floor[0][1], 1.5, kNearTheNadirM);
}

TEST(RoomfixMap, TheShippedRegionTableMapsItsOwnHeightAndRefusesAnother) {
  TempDir dir;
  const std::string example = SourceDir() + "/config/calibration/reference_9_region_example.yaml";
  // The image centre sees the nadir (2.0, 1.5); 0.0 m is not the table's
  // height, so that line gives nan and the exit code 2.
  ASSERT_TRUE(WriteFile(dir.File("in.csv"), "959.5,539.5,0.2\n959.5,539.5,0.0\n1500,300,0.2\n"));
  const RunResult r = Roomfix({"map", "--calibration", example, dir.File("in.csv")});
  EXPECT_EQ(r.exit_code, 2);
  const auto rows = ParseCsv(r.out);
  ASSERT_EQ(rows.size(), 3u);
  // The file's centre region (row 1, col 1) maps the centre pixel to
  // (2.000, 1.500) m; 1 cm lets the example be refitted (the table's RMS is
  // 28 mm) and still fails a wrong region (os2 metres apart) or axis.
  constexpr double kCentreRegionM = 0.01;
  EXPECT_NEAR(rows[0][0], 2.0, kCentreRegionM);
  EXPECT_NEAR(rows[0][1], 1.5, kCentreRegionM);
  EXPECT_TRUE(std::isnan(rows[1][0]));
  const RunResult why = Roomfix({"map", "--calibration", example, dir.File("in.csv")}, true);
  EXPECT_NE(why.out.find(":2: height 0 m differs from the calibration height 0.2 m"),
            std::string::npos)
      << why.out;

  // Inside a region the table inverts exactly.
  std::ostringstream floor;
  floor.precision(12);
  floor << "x_m,y_m,height_m\n" << rows[2][0] << "," << rows[2][1] << ",0.2\n";
  ASSERT_TRUE(WriteFile(dir.File("floor.csv"), floor.str()));
  const RunResult back =
      Roomfix({"map", "--calibration", example, "--inverse", dir.File("floor.csv")});
  ASSERT_EQ(back.exit_code, 0);
  const auto pixel = ParseCsv(back.out);
  ASSERT_EQ(pixel.size(), 1u);
  // An affine map and its inverse, through 12 printed digits each way.
  constexpr double kRoundTripPx = 1e-6;
  EXPECT_NEAR(pixel[0][0], 1500, kRoundTripPx);
  EXPECT_NEAR(pixel[0][1], 300, kRoundTripPx);
}

// Each refusal: exit code 1, one line on standard error, no file written.
TEST(RoomfixCalibrate, RefusesBadPointSetsWithOneClearLine) {
  TempDir dir;
  const std::string good = PointsCsv();
  std::vector<std::string> rows;
  {
    std::istringstream lines(good);
    std::string line;
    while (std::getline(lines, line)) rows.push_back(line);
  }
  auto csv = [&](size_t n) {
    std::string text;
    for (size_t i = 0; i < n && i < rows.size(); ++i) text += rows[i] + "\n";
    return text;
  };
  struct Case {
    std::string name;
    std::string points;
    std::vector<std::string> extra;
    std::string message;
  };
  std::string outside = good;
  outside.replace(outside.find('\n') + 1,
                  outside.find(',', outside.find('\n')) - outside.find('\n') - 1, "2500");
  std::string line_points = "u,v,x_m,y_m,height_m\n";
  for (int i = 0; i < 12; ++i) {
    line_points += std::to_string(300 + 100 * i) + ",540," + std::to_string(0.3 * i) + ",1.5,0.2\n";
  }
  std::string mixed = good;
  mixed.replace(mixed.rfind(",0.2\n"), 5, ",0.5\n");
  std::string mirrored = "u,v,x_m,y_m,height_m\n";
  for (size_t i = 1; i < rows.size(); ++i) {
    std::vector<std::string> f;
    std::stringstream fields(rows[i]);
    std::string field;
    while (std::getline(fields, field, ',')) f.push_back(field);
    mirrored += f[0] + "," + f[1] + "," + f[2] + ",-" + f[3] + "," + f[4] + "\n";
  }
  std::string patch = "u,v,x_m,y_m,height_m\n";
  for (int i = 0; i < 4; ++i) {
    for (int j = 0; j < 4; ++j) {
      const double x = 2.3 + 0.04 * i, y = 1.4 + 0.04 * j;
      double u, v;
      ASSERT_TRUE(TrueCamera().ProjectToPixel(Eigen::Vector3d(x, y, 0.0), &u, &v));
      patch += std::to_string(u) + "," + std::to_string(v) + "," + std::to_string(x) + "," +
               std::to_string(y) + ",0\n";
    }
  }
  std::string above = good;
  above.replace(above.rfind(",0.2\n"), 5, ",3.5\n");
  const std::vector<Case> cases = {
      {"too few",
       csv(6),
       {},
       "roomfix calibrate: full model: too few points: need at least 10, got 5"},
      {"line", line_points, {}, "roomfix calibrate: full model: all points lie on a line"},
      {"outside", outside, {}, "roomfix calibrate: full model: point 0: pixel (2500, "},
      {"heights, regions",
       mixed,
       {"--model", "regions"},
       "roomfix calibrate: 9-region model: inconsistent heights: point 0 is at 0.2 m, point 19 at "
       "0.5 m"},
      {"heights, full",
       above,
       {},
       "roomfix calibrate: full model: point 19: height 3.5 m is inconsistent"},
      {"not converged",
       good,
       {"--max-iterations", "1"},
       "roomfix calibrate: full model: the fit did not converge"},
      // The floor's y negated: only a camera under the floor sees that
      // (camera_start.h), with or without a mount.
      {"mirrored, no mount",
       mirrored,
       {"--size", "1920x1080"},
       "roomfix calibrate: full model: the points put the camera below them (at z = -"},
      {"mirrored", mirrored, {}, "roomfix calibrate: full model: the points put the camera below"},
      // 16 markers in a 12 cm square: 0.8 deg of view, no start without a
      // mount (with one, the fit starts from the nominal camera there).
      {"small patch, no mount",
       patch,
       {"--size", "1920x1080"},
       "roomfix calibrate: full model: all points lie in one small patch of the image: they span "
       "0.8"},
      {"bad csv",
       "u,v,x_m,y_m,height_m\n1,2,3,four,5\n",
       {},
       ":2: y_m: expected a number, got 'four'"},
  };
  for (const Case& c : cases) {
    ASSERT_TRUE(WriteFile(dir.File("p.csv"), c.points));
    std::vector<std::string> args = {"calibrate", "--points", dir.File("p.csv"), "--out",
                                     dir.File("cal.yaml")};
    if (c.name.find("no mount") == std::string::npos) {
      args.insert(args.end(), {"--site", DemoSitePath()});
    }
    args.insert(args.end(), c.extra.begin(), c.extra.end());
    const RunResult r = Roomfix(args, /*stderr_only=*/true);
    EXPECT_EQ(r.exit_code, 1) << c.name;
    EXPECT_NE(r.out.find(c.message), std::string::npos) << c.name << ": " << r.out;
    EXPECT_EQ(std::count(r.out.begin(), r.out.end(), '\n'), 1) << c.name << ": " << r.out;
    EXPECT_TRUE(ReadFile(dir.File("cal.yaml")).empty()) << c.name;
  }
}

// Chessboard detection on the real GoPro images (../shared/data/fisheye_gopro:
// 1000 x 750 fisheye photos of a board with 15 x 9 inner corners, 26 mm
// squares) against the corners OpenCV found there offline
// (derived_corners_opencv.csv: image,corner_index,col,row,...,u_px,v_px;
// 22 of the 24 images). One tilted board photo is not a ceiling camera's
// view, so only the detection is checked, through --corners-csv without a
// fit. The dataset's corners come from another detector, so they are a
// reference, not the truth: measured, 0.20 px RMS over the 22 images,
// at most 0.37 px RMS per image, worst corner 1.63 px (3D_L0480, 1.02 px
// on 3D_L0479, under 1 px on the rest).
constexpr double kCornerToleranceRmsPx = 1.0;     // every image
constexpr double kCornerToleranceMaxPx = 1.0;     // kMaxCheckedImage
constexpr double kCornerToleranceAnyMaxPx = 2.0;  // every image
const char kMaxCheckedImage[] = "3D_L0478.JPG";

std::vector<std::string> SplitFields(std::string line) {
  if (!line.empty() && line.back() == '\r') line.pop_back();
  std::vector<std::string> fields;
  std::stringstream s(line);
  std::string field;
  while (std::getline(s, field, ',')) fields.push_back(field);
  return fields;
}

TEST(RoomfixCalibrate, DetectsTheGoProChessboardCornersAsTheDataset) {
  const std::string data = SharedDataDir();
  if (data.empty()) GTEST_SKIP() << "no shared data dir (../shared/data): GoPro images missing";
  const std::string dir = data + "/fisheye_gopro/";
  // (image, col, row) -> (u, v) from the dataset.
  std::map<std::string, std::map<std::pair<int, int>, std::pair<double, double>>> expected;
  {
    std::istringstream lines(ReadFile(dir + "derived_corners_opencv.csv"));
    std::string line;
    std::getline(lines, line);
    ASSERT_EQ(SplitFields(line).size(), 8u) << line;
    ASSERT_EQ(line.rfind("image,corner_index,col,row,board_x_mm,board_y_mm,u_px,v_px", 0), 0u);
    while (std::getline(lines, line)) {
      const auto f = SplitFields(line);
      ASSERT_EQ(f.size(), 8u) << line;
      expected[f[0]][{std::stoi(f[2]), std::stoi(f[3])}] = {std::stod(f[6]), std::stod(f[7])};
    }
  }
  std::vector<std::string> images;
  for (const auto& [image, corners] : expected) images.push_back(image);
  TempDir tmp;
  std::vector<std::string> args = {"calibrate", "--board", "15x9", "--corners-csv",
                                   tmp.File("corners.csv")};
  for (const auto& image : images) args.insert(args.end(), {"--chessboard", dir + image});
  const RunResult r = Roomfix(args);
  std::cout << r.out;
  ASSERT_EQ(r.exit_code, 0) << r.out;

  std::istringstream lines(ReadFile(tmp.File("corners.csv")));
  std::string line;
  std::getline(lines, line);
  ASSERT_EQ(line, "image,i,j,u_px,v_px");
  std::map<std::string, int> count;
  std::map<std::string, double> sum2, worst;
  while (std::getline(lines, line)) {
    const auto f = SplitFields(line);
    ASSERT_EQ(f.size(), 5u) << line;
    const std::string image = f[0].substr(f[0].rfind('/') + 1);
    const auto& board = expected[image];
    const auto it = board.find({std::stoi(f[1]), std::stoi(f[2])});
    ASSERT_NE(it, board.end()) << line;
    const double d =
        std::hypot(std::stod(f[3]) - it->second.first, std::stod(f[4]) - it->second.second);
    ++count[image];
    sum2[image] += d * d;
    worst[image] = std::max(worst[image], d);
  }
  double all_sum2 = 0.0, all_worst = 0.0;
  for (const auto& image : images) {
    ASSERT_EQ(count[image], 15 * 9) << image;
    all_sum2 += sum2[image];
    all_worst = std::max(all_worst, worst[image]);
    const double rms = std::sqrt(sum2[image] / count[image]);
    std::cout << image << ": corners vs dataset: RMS " << rms << " px, max " << worst[image]
              << " px\n";
    EXPECT_LT(rms, kCornerToleranceRmsPx) << image;
    EXPECT_LT(worst[image],
              image == kMaxCheckedImage ? kCornerToleranceMaxPx : kCornerToleranceAnyMaxPx)
        << image;
  }
  std::cout << images.size() << " images: RMS " << std::sqrt(all_sum2 / (135.0 * images.size()))
            << " px, max " << all_worst << " px\n";
}

// Each refusal: exit code 1 and one line on standard error naming the image.
TEST(RoomfixCalibrate, RefusesAnImageWithoutTheBoardOrUnreadableWithOneClearLine) {
  const std::string data = SharedDataDir();
  if (data.empty()) GTEST_SKIP() << "no shared data dir (../shared/data): sample image missing";
  TempDir dir;
  const std::string smarties = data + "/opencv_samples/smarties.png";
  const std::string missing = dir.File("no_such_image.png");
  struct Case {
    std::vector<std::string> args;
    std::string message;
  };
  const std::vector<Case> cases = {
      {{"--chessboard", smarties, "--board", "15x9", "--corners-csv", dir.File("c.csv")},
       "roomfix calibrate: " + smarties + ": no 15x9 chessboard found"},
      {{"--chessboard", missing, "--board", "15x9", "--corners-csv", dir.File("c.csv")},
       "roomfix calibrate: " + missing + ": cannot open: No such file or directory"},
      {{"--chessboard", smarties, "--board", "15x9", "--square", "0.026", "--out",
        dir.File("cal.yaml"), "--mount", "0,0,3", "--size", "413x356"},
       "roomfix calibrate: --board-origin: expected one per --chessboard (1), got 0"},
      {{"--chessboard", smarties, "--board", "15", "--corners-csv", dir.File("c.csv")},
       "roomfix calibrate: --board: expected COLSxROWS inner corners (e.g. 9x6), got '15'"},
  };
  for (const Case& c : cases) {
    std::vector<std::string> args = {"calibrate"};
    args.insert(args.end(), c.args.begin(), c.args.end());
    const RunResult r = Roomfix(args, /*stderr_only=*/true);
    EXPECT_EQ(r.exit_code, 1) << c.message;
    EXPECT_NE(r.out.find(c.message), std::string::npos) << r.out;
    EXPECT_EQ(std::count(r.out.begin(), r.out.end(), '\n'), 1) << r.out;
    EXPECT_TRUE(ReadFile(dir.File("cal.yaml")).empty()) << c.message;
  }
}

// A chessboard of 0.25 m squares lying on the floor, as the demo room's
// camera sees it: every pixel of the 1920 x 1080 image mapped to the floor
// through the true camera and coloured by the square it falls in.
bool RenderFloorChessboard(const CameraModel& camera, const std::string& png_path) {
  constexpr double kSquareM = 0.25;
  constexpr double kX0 = 0.5, kY0 = 0.5;  // outer corner of the board
  constexpr int kSquaresX = 12, kSquaresY = 8;
  cv::Mat image(camera.intrinsics.height_px, camera.intrinsics.width_px, CV_8UC1, cv::Scalar(160));
  for (int v = 0; v < image.rows; ++v) {
    for (int u = 0; u < image.cols; ++u) {
      double x, y;
      if (!camera.PixelToFloor(u + 0.5, v + 0.5, 0.0, &x, &y)) continue;
      const double i = std::floor((x - kX0) / kSquareM), j = std::floor((y - kY0) / kSquareM);
      if (i < 0 || j < 0 || i >= kSquaresX || j >= kSquaresY) continue;
      image.at<uint8_t>(v, u) = (static_cast<int>(i + j) % 2 == 0) ? 20 : 235;
    }
  }
  return cv::imwrite(png_path, image);
}

TEST(RoomfixCalibrate, CalibratesFromAChessboardOnTheFloorToMillimetres) {
  // The board's 11 x 7 inner corners span (0.75..3.25, 0.75..2.25) m; seen
  // from the ceiling the first detected corner (the image's top-left) is at
  // room (0.75, 2.25), rows running along +x and columns along -y.
  const CameraModel truth = TrueCamera();
  TempDir dir;
  ASSERT_TRUE(RenderFloorChessboard(truth, dir.File("board.png")));
  const RunResult r =
      Roomfix({"calibrate", "--chessboard", dir.File("board.png"), "--board", "11x7", "--square",
               "0.25", "--board-origin", "0.75,2.25", "--board-axes", "+x-y", "--out",
               dir.File("cam0.yaml"), "--site", DemoSitePath(), "--camera", "0"});
  std::cout << r.out;
  ASSERT_EQ(r.exit_code, 0) << r.out;
  Calibration cal;
  std::string error;
  ASSERT_TRUE(calib::LoadCalibration(dir.File("cam0.yaml"), &cal, &error)) << error;
  // The board's plane (the floor) and, through the mount prior, 0.2 m above
  // it: millimetres over the board's area, the 77 corners being the data.
  // Corners found by OpenCV on a rendered (aliased) image: about 0.1 px.
  constexpr double kBoardAreaRmsM = 0.003;
  for (const double height : {0.0, 0.2}) {
    double sum2 = 0;
    int n = 0;
    for (double x = 0.75; x <= 3.25; x += 0.125) {
      for (double y = 0.75; y <= 2.25; y += 0.125, ++n) {
        double u, v, mx, my;
        ASSERT_TRUE(truth.ProjectToPixel(Eigen::Vector3d(x, y, height), &u, &v));
        ASSERT_TRUE(cal.PixelToFloor(u, v, height, &mx, &my, &error)) << error;
        sum2 += std::pow(mx - x, 2) + std::pow(my - y, 2);
      }
    }
    const double rms = std::sqrt(sum2 / n);
    std::cout << "board area at " << height << " m: RMS " << rms * 1e3 << " mm\n";
    EXPECT_LT(rms, kBoardAreaRmsM) << height << " m";
  }
}

}  // namespace
}  // namespace roomfix

namespace roomfix {
namespace {

TEST(RoomfixCalibrate, CalibratesFromImagesOfAMarkerAtSurveyedPoints) {
  // The reference's procedure, automated: the synthetic camera renders the
  // marker at every 0.5 m grid point through the true lens (written as a
  // calibration file for render-camera), calibrate finds the marker in each
  // image and fits; the result maps the floor at the marker's height to
  // within the 2 mm.
  constexpr double kMappingRmsM = 0.002;
  TempDir dir;
  Calibration truth;
  truth.model = Calibration::Model::kFull;
  truth.camera = TrueCamera();
  truth.camera.intrinsics.width_px = 1920;
  truth.camera.intrinsics.height_px = 1080;
  std::string error;
  ASSERT_TRUE(calib::SaveCalibration(dir.File("truth.yaml"), truth, "true lens", &error)) << error;
  const std::string site = DemoSitePath();
  const RunResult render =
      Roomfix({"render-camera", "--site", site, "--calibration", dir.File("truth.yaml"),
               "--scenario", "lighting", "--tripod-grid", dir.File("tripod")});
  ASSERT_EQ(render.exit_code, 0) << render.out;
  const RunResult fit = Roomfix({"calibrate", "--site", site, "--marker-images",
                                 dir.File("tripod/points.csv"), "--out", dir.File("cam.yaml")});
  ASSERT_EQ(fit.exit_code, 0) << fit.out;
  EXPECT_NE(fit.out.find("orange marker at"), std::string::npos) << fit.out;
  Calibration fitted;
  ASSERT_TRUE(calib::LoadCalibration(dir.File("cam.yaml"), &fitted, &error)) << error;
  double sum2 = 0.0;
  int n = 0;
  for (double x = 0.25; x < 4.0; x += 0.25) {
    for (double y = 0.25; y < 3.0; y += 0.25) {
      double u, v, fx, fy;
      ASSERT_TRUE(truth.camera.ProjectToPixel(Eigen::Vector3d(x, y, kCalibrationHeightM), &u, &v));
      if (u < 0 || v < 0 || u > 1919 || v > 1079) continue;
      ASSERT_TRUE(fitted.PixelToFloor(u, v, kCalibrationHeightM, &fx, &fy, &error)) << error;
      sum2 += std::pow(fx - x, 2) + std::pow(fy - y, 2);
      ++n;
    }
  }
  const double rms = std::sqrt(sum2 / n);
  std::printf("tripod calibration: %d floor points mapped to %.2f mm RMS\n", n, rms * 1e3);
  EXPECT_LT(rms, kMappingRmsM);
}

TEST(RoomfixCalibrate, StatesEachRobotsHeldOutPixelSigmaFromImagesItDidNotFit) {
  // The tripod images come in the camera's own JPEG (as its frames) and only
  // where the camera sees the marker; --tripod-robots adds every robot half
  // a step off the grid, and --robot-images turns them into each robot's
  // held-out pixel sigma. The demo's one robot is the tripod's own marker, so
  // its held-out sigma is the fit's noise plus the lens's error between the
  // fitted points: within a factor kSameMarkerFactor of the fit's
  // pixel_sigma_px either way (a figure outside would measure something else).
  constexpr double kSameMarkerFactor = 3.0;
  TempDir dir;
  const std::string site = SourceDir() + "/config/sites/demo_room.yaml";
  const RunResult render = Roomfix({"render-camera", "--site", site, "--scenario", "lighting",
                                    "--tripod-grid", dir.File("tripod"), "--tripod-robots"});
  ASSERT_EQ(render.exit_code, 0) << render.out;
  EXPECT_TRUE(std::filesystem::exists(dir.File("tripod/tripod_000.jpg"))) << render.out;
  ASSERT_TRUE(std::filesystem::exists(dir.File("tripod/robots.csv"))) << render.out;
  const RunResult fit =
      Roomfix({"calibrate", "--site", site, "--marker-images", dir.File("tripod/points.csv"),
               "--robot-images", dir.File("tripod/robots.csv"), "--out", dir.File("cam.yaml")});
  ASSERT_EQ(fit.exit_code, 0) << fit.out;
  EXPECT_NE(fit.out.find("robot 1: "), std::string::npos) << fit.out;
  Calibration fitted;
  std::string error;
  ASSERT_TRUE(calib::LoadCalibration(dir.File("cam.yaml"), &fitted, &error)) << error;
  ASSERT_EQ(fitted.robot_pixel_sigma_px.size(), 1u);
  const double held_out_px = fitted.PixelSigmaFor(1);
  std::printf("fit pixel sigma %.4f px, robot 1 held out %.4f px\n", fitted.pixel_sigma_px,
              held_out_px);
  EXPECT_GT(held_out_px, fitted.pixel_sigma_px / kSameMarkerFactor);
  EXPECT_LT(held_out_px, fitted.pixel_sigma_px * kSameMarkerFactor);

  // A robot the camera does not carry is refused, naming the line.
  std::string rows;
  ASSERT_TRUE(ReadConfigFile(dir.File("tripod/robots.csv"), &rows, &error)) << error;
  const size_t last = rows.rfind(",1\n");
  ASSERT_NE(last, std::string::npos);
  rows.replace(last, 3, ",9\n");
  ASSERT_TRUE(WriteOutputFile(dir.File("tripod/robots.csv"), rows, &error)) << error;
  const RunResult refused =
      Roomfix({"calibrate", "--site", site, "--marker-images", dir.File("tripod/points.csv"),
               "--robot-images", dir.File("tripod/robots.csv"), "--out", dir.File("cam2.yaml")},
              /*stderr_only=*/true);
  EXPECT_NE(refused.exit_code, 0);
  EXPECT_NE(refused.out.find("has no robot 9"), std::string::npos) << refused.out;
  EXPECT_FALSE(std::filesystem::exists(dir.File("cam2.yaml")));
}

TEST(RoomfixCalibrate, RefusesAMarkerImageWithTwoMarkersNamingIt) {
  TempDir dir;
  const std::string site = DemoSitePath();
  // "distractors" puts two more orange discs on the floor.
  ASSERT_EQ(Roomfix({"render-camera", "--site", site, "--scenario", "distractors", "--png",
                     dir.File("busy.png")})
                .exit_code,
            0);
  ASSERT_TRUE(WriteFile(dir.File("points.csv"), "image,x_m,y_m,height_m\nbusy.png,1,1,0.2\n"));
  const RunResult r = Roomfix({"calibrate", "--site", site, "--marker-images",
                               dir.File("points.csv"), "--out", dir.File("cam.yaml")},
                              /*stderr_only=*/true);
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.out.find("busy.png: expected one orange marker, found 3"), std::string::npos)
      << r.out;
}

// A camera fitted against a calibrated neighbour (docs/calibration.md, "A
// camera beside a calibrated one"): the two options go together, and every
// listed image must show exactly one marker. The fit itself made
// config/calibration/two_cameras_cam1.yaml (its header), which
// CameraOverlap.TwoCalibratedCamerasAgreeOnTheSameRobot measures.
TEST(RoomfixCalibrate, SharedImagesNeedTheNeighbourAndOneMarkerInEachImage) {
  TempDir dir;
  const std::string site = SourceDir() + "/config/sites/two_cameras.yaml";
  ASSERT_TRUE(
      WriteFile(dir.File("shared.csv"), "image,neighbour_image,height_m\ncam1.png,cam0.png,0.2\n"));
  const RunResult alone = Roomfix({"calibrate", "--site", site, "--camera", "1", "--shared-images",
                                   dir.File("shared.csv"), "--out", dir.File("cam.yaml")},
                                  /*stderr_only=*/true);
  EXPECT_NE(alone.exit_code, 0);
  EXPECT_NE(alone.out.find("--shared-images and --neighbour go together"), std::string::npos)
      << alone.out;
  // At t = 0 robot 1 is at x = 1 m and robot 2 circles about x = 1.8 m:
  // camera 1 (x 3.5 .. 8.5 m) sees no orange marker.
  for (const char* camera : {"0", "1"}) {
    ASSERT_EQ(Roomfix({"render-camera", "--site", site, "--camera", camera, "--png",
                       dir.File(std::string("cam") + camera + ".png")})
                  .exit_code,
              0);
  }
  const RunResult empty = Roomfix(
      {"calibrate", "--site", site, "--camera", "1", "--shared-images", dir.File("shared.csv"),
       "--neighbour", SourceDir() + "/config/calibration/two_cameras_cam0.yaml", "--out",
       dir.File("cam.yaml")},
      /*stderr_only=*/true);
  EXPECT_NE(empty.exit_code, 0);
  EXPECT_NE(empty.out.find("cam1.png: expected one orange marker, found 0"), std::string::npos)
      << empty.out;
}

}  // namespace
}  // namespace roomfix

namespace roomfix {
namespace {

// Issue 17, part 5: calibration from the pictures, the points and the image
// size alone, on a real lens. For every GoPro Hero3+ image in
// ../shared/data/fisheye_gopro (1000 x 750 px; a 15 x 9-corner board of
// 26 mm squares, the data README and config-fisheye.xml's Square_Size), the
// board is the floor: `roomfix calibrate --corners-csv` detects the
// corners, half of them are fitted with `roomfix calibrate --points`
// (--size 1000x750 --fov 120: a nominal field of view -- a Hero3 Black
// measures 121 deg across, Ross Cunniff 2012 -- and no mount), and
// `roomfix map` maps the other half back onto the board.
//
// The hold-out is the chessboard's own colouring: corners with i + j even
// are fitted, odd ones held out. Every held-out corner then has fitted
// neighbours on all sides and the two halves cover the same angles of view,
// which is what a ceiling calibration is for: markers between the
// calibration points. Holding out one side of the board instead measures
// extrapolation to angles the fit never saw, which camera_fit.h already
// warns against (centimetres; the docs say to cover the floor).
constexpr double kGoProSquareM = 0.026;
// The target: 1 mm RMS on every image. The board is 0.15-0.55 m
// from the lens (f about 430 px), so 1 mm is 0.8-3 px: a fit that reaches
// it follows the lens to a fraction of a pixel.
constexpr double kGoProHeldOutRmsM = 0.001;

TEST(RoomfixCalibrate, GoProHeldOutCornersMapWithinAMillimetreWithoutAMount) {
  const std::string data = SharedDataDir();
  if (data.empty()) GTEST_SKIP() << "no shared data dir (../shared/data): GoPro images missing";
  const std::string dir = data + "/fisheye_gopro";
  if (!std::filesystem::is_directory(dir)) GTEST_SKIP() << dir << " missing: GoPro test skipped";
  std::vector<std::string> images;
  for (const auto& entry : std::filesystem::directory_iterator(dir)) {
    if (entry.path().extension() == ".JPG") images.push_back(entry.path().string());
  }
  std::sort(images.begin(), images.end());
  ASSERT_EQ(images.size(), 24u);
  TempDir tmp;
  int calibrated = 0;
  std::vector<std::string> no_board;
  double worst_rms = 0.0;
  std::string worst_image;
  for (const std::string& image : images) {
    const std::string name = image.substr(image.rfind('/') + 1);
    const RunResult detect = Roomfix({"calibrate", "--chessboard", image, "--board", "15x9",
                                      "--corners-csv", tmp.File("corners.csv")},
                                     /*stderr_only=*/true);
    if (detect.exit_code != 0) {
      // The board is cut by the image border: no full 15 x 9 pattern.
      EXPECT_NE(detect.out.find("no 15x9 chessboard found"), std::string::npos) << detect.out;
      no_board.push_back(name);
      continue;
    }
    std::string fit_csv = "u,v,x_m,y_m,height_m\n", held_csv = "u,v,height_m\n";
    std::vector<std::pair<double, double>> held_truth;
    std::istringstream lines(ReadFile(tmp.File("corners.csv")));
    std::string line;
    std::getline(lines, line);
    ASSERT_EQ(line, "image,i,j,u_px,v_px");
    while (std::getline(lines, line)) {
      const auto f = SplitFields(line);
      ASSERT_EQ(f.size(), 5u) << line;
      const int i = std::stoi(f[1]), j = std::stoi(f[2]);
      // First corner at the image's top-left; i runs right (+x), j down
      // the image (-y): the board seen from above, right-handed.
      const double x = i * kGoProSquareM, y = -j * kGoProSquareM;
      if ((i + j) % 2 == 0) {
        fit_csv += f[3] + "," + f[4] + "," + std::to_string(x) + "," + std::to_string(y) + ",0\n";
      } else {
        held_csv += f[3] + "," + f[4] + ",0\n";
        held_truth.emplace_back(x, y);
      }
    }
    ASSERT_EQ(held_truth.size(), 67u) << name;
    ASSERT_TRUE(WriteFile(tmp.File("fit.csv"), fit_csv));
    ASSERT_TRUE(WriteFile(tmp.File("held.csv"), held_csv));
    const RunResult fit = Roomfix({"calibrate", "--points", tmp.File("fit.csv"), "--size",
                                   "1000x750", "--fov", "120", "--out", tmp.File("cal.yaml")});
    ASSERT_EQ(fit.exit_code, 0) << name << "\n" << fit.out;
    const RunResult mapped =
        Roomfix({"map", "--calibration", tmp.File("cal.yaml"), tmp.File("held.csv")});
    ASSERT_EQ(mapped.exit_code, 0) << name << "\n" << mapped.out;
    const auto rows = ParseCsv(mapped.out);
    ASSERT_EQ(rows.size(), held_truth.size()) << name;
    double sum2 = 0.0, worst = 0.0;
    for (size_t k = 0; k < rows.size(); ++k) {
      const double d =
          std::hypot(rows[k][0] - held_truth[k].first, rows[k][1] - held_truth[k].second);
      sum2 += d * d;
      worst = std::max(worst, d);
    }
    const double rms = std::sqrt(sum2 / static_cast<double>(rows.size()));
    std::string summary;
    for (std::istringstream out(fit.out); std::getline(out, line);) {
      if (line.rfind("start from", 0) == 0 || line.rfind("full model:", 0) == 0) {
        summary += "\n    " + line;
      }
    }
    std::printf("%s: held-out 67 corners: RMS %.3f mm, max %.3f mm%s\n", name.c_str(), rms * 1e3,
                worst * 1e3, summary.c_str());
    ++calibrated;
    if (rms > worst_rms) {
      worst_rms = rms;
      worst_image = name;
    }
    EXPECT_LE(rms, kGoProHeldOutRmsM) << name;
  }
  std::string missing;
  for (const auto& n : no_board) missing += " " + n;
  std::printf("%d images calibrated, worst held-out RMS %.3f mm (%s); no full board in:%s\n",
              calibrated, worst_rms * 1e3, worst_image.c_str(), missing.c_str());
  // The dataset's own corner file has 22 of the 24 images for the same
  // reason: 3D_L0486 and 3D_L0496 show the board cut by the border.
  EXPECT_EQ(calibrated, 22);
}

// The whole --chessboard path without a mount on a real image, and the
// mirrored board refused with the reason.
TEST(RoomfixCalibrate, GoProChessboardCalibratesWithoutAMountAndRefusesAMirroredBoard) {
  const std::string data = SharedDataDir();
  if (data.empty()) GTEST_SKIP() << "no shared data dir (../shared/data): GoPro images missing";
  const std::string image = data + "/fisheye_gopro/3D_L0490.JPG";
  TempDir tmp;
  const std::vector<std::string> args = {"calibrate",
                                         "--chessboard",
                                         image,
                                         "--board",
                                         "15x9",
                                         "--square",
                                         "0.026",
                                         "--board-origin",
                                         "0,0",
                                         "--size",
                                         "1000x750",
                                         "--out",
                                         tmp.File("cal.yaml"),
                                         "--board-axes"};
  std::vector<std::string> good = args;
  good.push_back("+x-y");
  const RunResult r = Roomfix(good);
  std::string line;
  for (std::istringstream out(r.out); std::getline(out, line);) {
    if (line.rfind("start from", 0) == 0 || line.rfind("full model:", 0) == 0) {
      std::cout << line << "\n";
    }
  }
  ASSERT_EQ(r.exit_code, 0) << r.out;
  // All 135 corners fitted: the reprojection RMS is the corner noise
  // (about 0.1-0.3 px on these images, camera_fit_test).
  constexpr double kCornerNoisePx = 0.5;
  Calibration cal;
  std::string error;
  ASSERT_TRUE(calib::LoadCalibration(tmp.File("cal.yaml"), &cal, &error)) << error;
  EXPECT_LT(cal.fit_rms_px, kCornerNoisePx);
  // k3 and k4 freed as well (--distortion-terms 4): a larger model over the
  // same corners fits them more closely.
  std::vector<std::string> four = good;
  *std::find(four.begin(), four.end(), tmp.File("cal.yaml")) = tmp.File("cal4.yaml");
  four.insert(four.end(), {"--distortion-terms", "4"});
  const RunResult r4 = Roomfix(four);
  ASSERT_EQ(r4.exit_code, 0) << r4.out;
  Calibration cal4;
  ASSERT_TRUE(calib::LoadCalibration(tmp.File("cal4.yaml"), &cal4, &error)) << error;
  std::cout << "k1, k2: " << cal.fit_rms_px << " px; k1..k4: " << cal4.fit_rms_px << " px\n";
  EXPECT_LT(cal4.fit_rms_px, cal.fit_rms_px);
  EXPECT_NE(cal4.camera.intrinsics.k[3], 0.0);

  std::vector<std::string> mirrored = args;
  mirrored.push_back("x");
  const RunResult m = Roomfix(mirrored, /*stderr_only=*/true);
  EXPECT_EQ(m.exit_code, 1);
  EXPECT_NE(m.out.find("roomfix calibrate: full model: the points put the camera below them"),
            std::string::npos)
      << m.out;
  EXPECT_EQ(std::count(m.out.begin(), m.out.end(), '\n'), 1) << m.out;
}

}  // namespace
}  // namespace roomfix
