#include "core/calib/camera_fit.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <fstream>
#include <iostream>
#include <map>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "core/calib/camera_start.h"
#include "tests/testing/test_paths.h"

namespace roomfix::calib {
namespace {

constexpr double kCalibrationHeightM = 0.2;
constexpr double kPixelNoisePx = 0.3;
// The target: every floor point to within 2 mm RMS.
constexpr double kTargetRmsM = 0.002;

CameraModel Nominal() { return NominalCamera({2.0, 1.5, 3.1}, 120.0, 1280, 960); }

// The "true" camera: the nominal one mounted a few centimetres off, tilted
// by about a degree, with fx 5 % long and the distortion of a real
// 120-degree lens.
CameraModel TrueCamera() {
  CameraModel m = Nominal();
  m.intrinsics.fx_px *= 1.05;
  m.intrinsics.fy_px *= 1.05;
  m.intrinsics.cx_px += 6.0;
  m.intrinsics.cy_px -= 4.0;
  m.intrinsics.k = {0.02, -0.01, 0.003, -0.0005};
  m.pose.R_room_from_camera =
      m.pose.R_room_from_camera *
      Eigen::AngleAxisd(1.0 * M_PI / 180, Eigen::Vector3d(1, 0.6, 0).normalized())
          .toRotationMatrix();
  m.pose.position_m += Eigen::Vector3d(0.04, -0.03, 0.03);
  return m;
}

// Where the reference's 20 markers sit.
// kCentral: the 5 x 4 interior points of a 0.5 m grid centred on the floor
//   (x = 1.0..3.0, y = 0.75..2.25): the literal reading of "0.5 m grid,
//   about 20 points"; the floor's corners are then 1.1 m outside it.
// kSpread: 5 x 4 points spread over the whole floor (x = 0.4..3.6,
//   y = 0.3..2.7, 0.8 m pitch), so that the corners are interpolated.
enum class Layout { kCentral, kSpread };

// The reference's grid seen by `truth` with Gaussian pixel noise (fixed
// seed); heights taken in turn from `heights_m`.
std::vector<Correspondence> ReferenceGrid(const CameraModel& truth,
                                          const std::vector<double>& heights_m, unsigned seed,
                                          Layout layout = Layout::kSpread) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, kPixelNoisePx);
  std::vector<Correspondence> out;
  size_t k = 0;
  for (int i = 0; i < 5; ++i) {
    for (int j = 0; j < 4; ++j) {
      Correspondence c;
      c.x_m = layout == Layout::kCentral ? 1.0 + 0.5 * i : 0.4 + 0.8 * i;
      c.y_m = layout == Layout::kCentral ? 0.75 + 0.5 * j : 0.3 + 0.8 * j;
      c.height_m = heights_m[k++ % heights_m.size()];
      truth.ProjectToPixel(Eigen::Vector3d(c.x_m, c.y_m, c.height_m), &c.u_px, &c.v_px);
      c.u_px += noise(rng);
      c.v_px += noise(rng);
      out.push_back(c);
    }
  }
  return out;
}

struct MappingError {
  double rms_m = 0;
  double worst_m = 0;
  double worst_corner_m = 0;
  int unmapped = 0;  // pixels the fitted model could not map at all
};

// Every 5 cm over the floor at `height_m`: the true camera's pixel (no
// noise), mapped back with the fitted model.
MappingError MapFloor(const CameraModel& truth, const CameraModel& fitted, double height_m) {
  MappingError e;
  double sum2 = 0;
  int n = 0;
  for (int i = 0; i <= 80; ++i) {
    for (int j = 0; j <= 60; ++j) {
      const double x = 0.05 * i, y = 0.05 * j;
      double u, v, fx, fy;
      EXPECT_TRUE(truth.ProjectToPixel(Eigen::Vector3d(x, y, height_m), &u, &v));
      if (!fitted.PixelToFloor(u, v, height_m, &fx, &fy)) {
        ++e.unmapped;
        continue;
      }
      const double d = std::hypot(fx - x, fy - y);
      sum2 += d * d;
      ++n;
      e.worst_m = std::max(e.worst_m, d);
      if ((i == 0 || i == 80) && (j == 0 || j == 60))
        e.worst_corner_m = std::max(e.worst_corner_m, d);
    }
  }
  e.rms_m = n > 0 ? std::sqrt(sum2 / n) : INFINITY;
  return e;
}

// The site's measurement of the mount: the true position off by a few
// millimetres (a laser distance meter to floor and walls).
CameraModel MeasuredMount() {
  const Eigen::Vector3d p = TrueCamera().pose.position_m + Eigen::Vector3d(0.003, -0.002, 0.004);
  return NominalCamera({p.x(), p.y(), p.z()}, 120.0, 1280, 960);
}

struct Scenario {
  std::string name;
  CameraFitOptions options;
  CameraModel initial;
  std::vector<double> grid_heights_m;
  Layout layout = Layout::kSpread;
};

struct Outcome {
  bool usable = false;
  std::string message;
  double height_error_m = 0;
  // At the calibration height 0.2 m and at 0.0 and 0.5 m.
  MappingError at[3];
  // Report: over 20 noise seeds, the median of the worst-height RMS.
  double median_worst_rms_m = INFINITY;
  double WorstRms() const {
    return usable ? std::max({at[0].rms_m, at[1].rms_m, at[2].rms_m}) : INFINITY;
  }
};

constexpr double kTestHeightsM[3] = {kCalibrationHeightM, 0.0, 0.5};

Outcome Evaluate(const Scenario& sc, unsigned seed) {
  Outcome o;
  const CameraModel truth = TrueCamera();
  const auto points = ReferenceGrid(truth, sc.grid_heights_m, seed, sc.layout);
  const CameraFitSummary fit = FitCamera(points, sc.initial, sc.options);
  o.message = fit.message;
  if (!fit.usable) return o;
  o.usable = true;
  o.height_error_m = fit.model.pose.position_m.z() - truth.pose.position_m.z();
  for (int h = 0; h < 3; ++h) o.at[h] = MapFloor(truth, fit.model, kTestHeightsM[h]);
  return o;
}

// Prints seed 1's figures and the spread of the worst-height RMS over 20
// noise seeds; returns seed 1's outcome.
Outcome Report(const Scenario& sc) {
  Outcome first = Evaluate(sc, 1);
  std::cout << sc.name << "\n  " << first.message << "\n";
  if (first.usable) {
    std::cout << "  camera height error " << first.height_error_m * 1000 << " mm\n";
  }
  for (int h = 0; h < 3 && first.usable; ++h) {
    std::cout << "  height " << kTestHeightsM[h] << " m: RMS " << first.at[h].rms_m * 1000
              << " mm, worst " << first.at[h].worst_m * 1000 << " mm, worst corner "
              << first.at[h].worst_corner_m * 1000 << " mm";
    if (first.at[h].unmapped > 0) std::cout << ", " << first.at[h].unmapped << " unmapped";
    std::cout << "\n";
  }
  std::vector<double> rms;
  for (unsigned seed = 1; seed <= 20; ++seed) rms.push_back(Evaluate(sc, seed).WorstRms());
  std::sort(rms.begin(), rms.end());
  std::cout << "  20 noise seeds, RMS at the worst of the 3 heights: median " << rms[10] * 1000
            << " mm, max " << rms.back() * 1000 << " mm (inf: fit unusable)\n";
  first.median_worst_rms_m = rms[10];
  return first;
}

// What 20 points at one height determine. A single view of one plane does
// not fix the camera's height: moving it up and lengthening f (with k1, k2
// bending to match) reproduces the grid's pixels within the noise, so the
// unconstrained fit lands metres off in height and maps the calibration
// plane well but every other plane badly. The choice that meets the target
// is the one the header describes: fx = fy, k1 and k2 only (the points
// reach 40 degrees off axis, where k3 and k4 are below the noise), and
// the site's measured mount position as a 5 mm prior. The other rows are
// printed to show why.
TEST(CameraFit, RecoversTheFloorMappingFromTheReferencesGridTo2mm) {
  CameraFitOptions full;
  full.pixel_sigma_px = kPixelNoisePx;
  CameraFitOptions reduced = full;
  reduced.equal_focal_lengths = true;
  reduced.distortion_terms = 2;
  CameraFitOptions measured = reduced;
  measured.position_prior_sigma_m = 0.005;
  const std::vector<double> one = {kCalibrationHeightM};
  const std::vector<double> two = {0.0, 0.5};

  const Outcome chosen = Report({"CHOSEN: spread grid at 0.2 m, fx = fy, k1..k2, mount prior 5 mm",
                                 measured, MeasuredMount(), one, Layout::kSpread});
  Report(
      {"spread grid at 0.2 m, all 14 parameters, no prior", full, Nominal(), one, Layout::kSpread});
  Report({"spread grid at 0.2 m, fx = fy, k1..k2, no prior", reduced, Nominal(), one,
          Layout::kSpread});
  Report({"spread grid alternating 0.0 / 0.5 m, fx = fy, k1..k2, no prior", reduced, Nominal(), two,
          Layout::kSpread});
  Report({"central 0.5 m grid at 0.2 m, fx = fy, k1..k2, mount prior 5 mm", measured,
          MeasuredMount(), one, Layout::kCentral});
  Report({"central 0.5 m grid at 0.2 m, all 14 parameters, no prior", full, Nominal(), one,
          Layout::kCentral});

  ASSERT_TRUE(chosen.usable) << chosen.message;
  for (int h = 0; h < 3; ++h) {
    EXPECT_EQ(chosen.at[h].unmapped, 0);
    const std::string height = std::to_string(kTestHeightsM[h]);
    RecordProperty("rms_mm_at_" + height, std::to_string(chosen.at[h].rms_m * 1000));
    RecordProperty("worst_corner_mm_at_" + height,
                   std::to_string(chosen.at[h].worst_corner_m * 1000));
    EXPECT_LE(chosen.at[h].rms_m, kTargetRmsM) << "height " << height;
  }
  // Seed 1 is one draw of the noise; the target holds for the typical draw
  // too, but not for every one: over 20 seeds the worst-height RMS reached
  // 2.9 mm (printed above). 20 points at 0.3 px carry that much noise; more
  // points, or markers at two heights, bring it down.
  EXPECT_LE(chosen.median_worst_rms_m, kTargetRmsM);
}

// Builds a valid set from the reference grid and breaks one thing at a time.
TEST(CameraFit, RejectsTooFewPointsALineOutsideTheImageAndBadHeights) {
  const auto good = ReferenceGrid(TrueCamera(), {kCalibrationHeightM}, 3);
  const CameraFitOptions options;
  ASSERT_TRUE(FitCamera(good, Nominal(), options).usable);

  auto expect_rejected = [&](const std::vector<Correspondence>& pts, const std::string& words,
                             const CameraFitOptions& o = CameraFitOptions()) {
    const CameraFitSummary s = FitCamera(pts, Nominal(), o);
    EXPECT_FALSE(s.usable);
    EXPECT_NE(s.message.find(words), std::string::npos) << s.message;
    std::cout << "rejected: " << s.message << "\n";
  };
  expect_rejected({good.begin(), good.begin() + kMinPoints - 1}, "too few points");

  std::vector<Correspondence> line;
  for (int i = 0; i < 12; ++i) {
    Correspondence c;
    c.x_m = 0.5 + 0.25 * i;
    c.y_m = 0.3 + 0.2 * c.x_m;
    c.height_m = kCalibrationHeightM;
    TrueCamera().ProjectToPixel(Eigen::Vector3d(c.x_m, c.y_m, c.height_m), &c.u_px, &c.v_px);
    line.push_back(c);
  }
  expect_rejected(line, "on a line");

  auto outside = good;
  outside[4].u_px = 1300;
  expect_rejected(outside, "outside");

  for (double h : {-0.1, 3.2, std::nan("")}) {
    auto bad = good;
    bad[7].height_m = h;
    expect_rejected(bad, "height");
  }

  CameraFitOptions invalid;
  invalid.outlier_px = 0;
  expect_rejected(good, "invalid options", invalid);

  CameraFitOptions starved;
  starved.max_iterations = 1;
  expect_rejected(good, "did not converge", starved);
}

TEST(CameraFit, FlagsAnOutlierPoint) {
  auto points = ReferenceGrid(TrueCamera(), {kCalibrationHeightM}, 4);
  points[9].u_px += 10.0;
  const CameraFitSummary s = FitCamera(points, Nominal(), CameraFitOptions());
  ASSERT_TRUE(s.usable) << s.message;
  std::cout << s.message << "; moved point's residual " << s.residual_px[9] << " px\n";
  for (size_t i = 0; i < points.size(); ++i) EXPECT_EQ(s.outlier[i], i == 9) << i;
  // Left out, the point no longer drags the fit: its residual shows the
  // whole 10 px and the rest fit at the noise level.
  EXPECT_GT(s.residual_px[9], 8.0);
  EXPECT_LT(s.rms_px, 2 * kPixelNoisePx);
}

// ---------------------------------------------------------------------------
// A real lens: GoPro Hero3+ fisheye images of a 15 x 9 chessboard, 26 mm
// squares; OpenCV's corners in derived_corners_opencv.csv.

constexpr double kSquareM = 0.026;

struct BoardCorner {
  int col, row;
  double u_px, v_px;
};

std::map<std::string, std::vector<BoardCorner>> ReadCorners(const std::string& path) {
  std::map<std::string, std::vector<BoardCorner>> out;
  std::ifstream in(path);
  std::string line;
  std::getline(in, line);  // image,corner_index,col,row,board_x_mm,board_y_mm,u_px,v_px
  while (std::getline(in, line)) {
    std::stringstream ss(line);
    std::string image, field;
    std::vector<double> f;
    std::getline(ss, image, ',');
    while (std::getline(ss, field, ',')) f.push_back(std::stod(field));
    if (f.size() != 7) continue;
    out[image].push_back({static_cast<int>(f[1]), static_cast<int>(f[2]), f[5], f[6]});
  }
  return out;
}

// The board as the floor: corner (col, row) at (row s, col s, 0). Rows run
// down the image and columns across it, so this (x, y) order puts the
// board's +z towards the camera, which the fit needs (markers below it).
Eigen::Vector3d BoardPoint(const BoardCorner& c) {
  return Eigen::Vector3d(c.row * kSquareM, c.col * kSquareM, 0.0);
}

TEST(CameraFit, MapsHeldOutChessboardCornersOfARealFisheyeLens) {
  const std::string data = roomfix::testing::SharedDataDir();
  if (data.empty())
    GTEST_SKIP() << "no shared data (ROOMFIX_SHARED_DATA_DIR): real-lens test skipped";
  const std::string path = data + "/fisheye_gopro/derived_corners_opencv.csv";
  const auto images = ReadCorners(path);
  if (images.empty()) GTEST_SKIP() << "cannot read " << path;
  // 1000 x 750 px. The nominal lens: 120 degrees across the width
  // (f = 477 px; a Hero3 Black measures 121 degrees); FindCameraStart
  // searches 0.6-1.67 times that focal length (the fits land at 404-509 px).
  const CameraModel lens = NominalCamera({0, 0, 1}, 120.0, 1000, 750);
  // The held-out corners lie between the fitted ones on the same board, so
  // the error is the model's interpolation error plus corner noise (OpenCV's
  // subpixel corners: about 0.1-0.3 px, which is 0.1-0.5 mm on a board
  // 0.15-0.3 m from a lens of about 430 px/rad). 1 mm RMS, 3 mm worst --
  // several pixels -- would mean the model does not fit the lens.
  constexpr double kHeldOutRmsM = 0.001;
  constexpr double kHeldOutMaxM = 0.003;
  int tested = 0;
  for (const auto& [image, corners] : images) {
    ++tested;
    std::vector<Correspondence> fit_points;
    std::vector<BoardCorner> held_out;
    for (size_t i = 0; i < corners.size(); ++i) {
      if (i % 2 == 0) {
        const Eigen::Vector3d p = BoardPoint(corners[i]);
        fit_points.push_back({corners[i].u_px, corners[i].v_px, p.x(), p.y(), 0.0});
      } else {
        held_out.push_back(corners[i]);
      }
    }
    // The start from the fitted corners alone (camera_start.h).
    const CameraStart start = FindCameraStart(fit_points, lens);
    ASSERT_TRUE(start.usable) << image << ": " << start.message;
    const CameraFitSummary fit = FitCamera(fit_points, start.model, CameraFitOptions());
    ASSERT_TRUE(fit.usable) << image << ": " << fit.message;
    double sum2 = 0, worst = 0;
    for (const BoardCorner& c : held_out) {
      double x, y;
      ASSERT_TRUE(fit.model.PixelToFloor(c.u_px, c.v_px, 0.0, &x, &y))
          << image << " corner " << c.col << "," << c.row << " at " << c.u_px << "," << c.v_px
          << ": " << fit.message << " k " << fit.model.intrinsics.k[0] << " "
          << fit.model.intrinsics.k[1] << " " << fit.model.intrinsics.k[2] << " "
          << fit.model.intrinsics.k[3] << " f " << fit.model.intrinsics.fx_px << " z "
          << fit.model.pose.position_m.z();
      const Eigen::Vector3d p = BoardPoint(c);
      const double d = std::hypot(x - p.x(), y - p.y());
      sum2 += d * d;
      worst = std::max(worst, d);
    }
    const double rms = std::sqrt(sum2 / held_out.size());
    const auto& in = fit.model.intrinsics;
    std::cout << image << ": " << fit.message << ", camera " << fit.model.pose.position_m.z() * 1000
              << " mm above the board, f (" << in.fx_px << ", " << in.fy_px << ") px, k ("
              << in.k[0] << ", " << in.k[1] << ", " << in.k[2] << ", " << in.k[3] << "); held-out "
              << held_out.size() << " corners: RMS " << rms * 1000 << " mm, max " << worst * 1000
              << " mm\n";
    RecordProperty(image + "_held_out_rms_mm", std::to_string(rms * 1000));
    RecordProperty(image + "_held_out_max_mm", std::to_string(worst * 1000));
    EXPECT_LT(rms, kHeldOutRmsM) << image;
    EXPECT_LT(worst, kHeldOutMaxM) << image;
  }
  std::cout << tested << " images\n";
  EXPECT_GE(tested, 5);
}

}  // namespace
}  // namespace roomfix::calib
