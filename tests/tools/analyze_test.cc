// `roomfix analyze` on logs written with known trajectories and known noise:
// it must give back what was put in.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cmath>
#include <nlohmann/json.hpp>
#include <random>

#include "core/world/trajectory.h"
#include "msgio/log.h"
#include "roomfix/pose2d_t.hpp"
#include "tests/testing/demo_site.h"
#include "tests/testing/test_messages.h"
#include "tests/testing/test_paths.h"

namespace roomfix {
namespace {

using nlohmann::json;
using testing::BinDir;
using testing::ChildProcess;
using testing::ReadFile;
using testing::TempDir;

constexpr int64_t kT0 = 1'700'000'000'000'000;
// A statistic of random draws must lie within this many of its standard
// errors of the truth: a correct one fails about once in 16 000, a wrong
// formula or unit at once.
constexpr double kStandardErrors = 4.0;

class LogBuilder {
 public:
  explicit LogBuilder(const std::string& path) {
    std::string error;
    writer_ = LogWriter::Create(path, true, &error);
    EXPECT_NE(writer_, nullptr) << error;
  }
  void Pose(int8_t source, int64_t utime, double x_m, double y_m, int64_t latency_us = 5000,
            int8_t status = pose2d_t::STATUS_OK) {
    pose2d_t p = testing::MakeTestPose(utime, 1, x_m, y_m);
    p.source = source;
    p.status = status;
    p.latency_us = latency_us;
    std::vector<uint8_t> buffer(static_cast<size_t>(p.getEncodedSize()));
    p.encode(buffer.data(), 0, static_cast<int>(buffer.size()));
    const char* channel = source == pose2d_t::SOURCE_CAMERA       ? "POSE_CAMERA"
                          : source == pose2d_t::SOURCE_ULTRASOUND ? "POSE_ULTRASOUND"
                                                                  : "POSE_GROUND_TRUTH";
    std::string error;
    EXPECT_TRUE(writer_->Write(utime + latency_us, channel, buffer.data(),
                               static_cast<int>(buffer.size()), &error))
        << error;
  }
  void Close() { writer_.reset(); }

 private:
  std::unique_ptr<LogWriter> writer_;
};

json Analyze(const std::vector<std::string>& args, int* exit_code) {
  TempDir dir;
  std::vector<std::string> argv = {BinDir() + "/roomfix", "analyze", "--json"};
  argv.insert(argv.end(), args.begin(), args.end());
  ChildProcess p(argv, dir.File("out.json"));
  *exit_code = p.Wait(120);
  return json::parse(ReadFile(dir.File("out.json")), nullptr, false);
}

bool NonEmptyFile(const std::string& path) {
  struct stat st {};
  return ::stat(path.c_str(), &st) == 0 && st.st_size > 1000;
}

TEST(RoomfixAnalyze, RecoversTheStaticRepeatabilityAndTheCameraCycleOfTheReference) {
  // The reference's Fig. 7 and Figs. 3-4: 1172 fixes of a static robot, std
  // 3.8 mm in x and 4.9 mm in y, one fix every 6 to 8 camera frames.
  constexpr int kFixes = 1172;
  constexpr double kSigmaXM = 0.0038;
  constexpr double kSigmaYM = 0.0049;
  // 4 standard errors of a sample standard deviation, sigma / sqrt(2 (n - 1)).
  const double std_tol_x = kStandardErrors * kSigmaXM / std::sqrt(2.0 * (kFixes - 1));
  const double std_tol_y = kStandardErrors * kSigmaYM / std::sqrt(2.0 * (kFixes - 1));
  TempDir dir;
  LogBuilder log(dir.File("static.lcm"));
  std::mt19937_64 rng(3);
  std::normal_distribution<double> nx(0.0, kSigmaXM), ny(0.0, kSigmaYM);
  int frames_of[3] = {0, 0, 0};
  int64_t t = kT0;
  for (int i = 0; i < kFixes; ++i) {
    log.Pose(pose2d_t::SOURCE_CAMERA, t, 1.0 + nx(rng), 2.0 + ny(rng));
    const int frames = 6 + i % 3;                 // 6, 7, 8 frames in turn
    if (i + 1 < kFixes) ++frames_of[frames - 6];  // the last one leads to no fix
    // Capture times on the 30 fps frame grid, with 3 ms of jitter.
    t += static_cast<int64_t>(frames * 1e6 / 30.0) + (i % 2 == 0 ? 3000 : -3000);
  }
  log.Close();

  int rc = -1;
  // A folder name with a space, a quote and a semicolon: gnuplot gets it as
  // data, never a shell.
  const std::string report = dir.File("it's a; report");
  const json out = Analyze({dir.File("static.lcm"), "--out", report}, &rc);
  ASSERT_EQ(rc, 0);
  ASSERT_FALSE(out.is_discarded());
  const json& camera = out["robots"]["1"]["camera"];
  EXPECT_EQ(camera["fixes"], kFixes);
  EXPECT_TRUE(camera["static"].get<bool>());
  const json& r = camera["repeatability"];
  EXPECT_NEAR(r["mean_x_m"].get<double>(), 1.0, kStandardErrors * kSigmaXM / std::sqrt(kFixes));
  EXPECT_NEAR(r["std_x_m"].get<double>(), kSigmaXM, std_tol_x);
  EXPECT_NEAR(r["std_y_m"].get<double>(), kSigmaYM, std_tol_y);
  // P(|x| > 1.5 cm or |y| > 1.5 cm) for these sigmas: 1 - (1 - erfc(a / sqrt 2)) (1 - ...).
  const double px = std::erfc(0.015 / kSigmaXM / std::sqrt(2.0));
  const double py = std::erfc(0.015 / kSigmaYM / std::sqrt(2.0));
  const double expected_share = 1 - (1 - px) * (1 - py);
  EXPECT_NEAR(r["share_outside"].get<double>(), expected_share,
              kStandardErrors * std::sqrt(expected_share / kFixes) + 1.0 / kFixes);
  int64_t in_histogram = r["histogram"]["outside"].get<int64_t>();
  for (const auto& c : r["histogram"]["counts"]) in_histogram += c.get<int64_t>();
  EXPECT_EQ(in_histogram, kFixes);

  // Whole frames, counted exactly.
  const json& frames = camera["timing"]["interval_frames"]["counts"];
  EXPECT_EQ(frames[6].get<int>(), frames_of[0]);
  EXPECT_EQ(frames[7].get<int>(), frames_of[1]);
  EXPECT_EQ(frames[8].get<int>(), frames_of[2]);
  // The mean interval is 7 frames but for the cycle's remainder (1171
  // intervals: one 6 more than 7s and 8s, 1/1171 of a frame = 0.03 ms) and
  // the alternating 3 ms jitter (cancels to <= 6 ms / 1171 = 0.005 ms);
  // 0.1 ms is above both and far below one frame (33 ms).
  constexpr double kMeanIntervalTolMs = 0.1;
  EXPECT_NEAR(camera["timing"]["mean_ms"].get<double>(), 7 * 1000.0 / 30.0, kMeanIntervalTolMs);
  // Every pose states latency_us = 5000 exactly (LogBuilder::Pose): only the
  // conversion to ms in doubles can move it.
  constexpr double kExactMs = 1e-9;
  EXPECT_NEAR(camera["latency_publish_ms"]["median_ms"].get<double>(), 5.0, kExactMs);

  EXPECT_TRUE(NonEmptyFile(report + "/static_camera_robot1.png"));
  EXPECT_TRUE(NonEmptyFile(report + "/intervals_camera_robot1.png"));
  const std::string md = ReadFile(report + "/report.md");
  EXPECT_NE(md.find("static_camera_robot1.png"), std::string::npos);
  EXPECT_NE(md.find("0.38 cm, 0.49 cm"), std::string::npos) << "the reference beside ours";
}

// The reference circle's log: ground truth at 30 Hz; the camera sees it 2 cm
// east and 1 cm south of the truth with 1 mm noise; ultrasound at 10 Hz
// with kSigmaUsM noise per axis, and one lost fix after the end.
constexpr double kSigmaUsM = 0.01;

void WriteCircleLog(const std::string& path) {
  constexpr double kSeconds = 60.0;
  std::string error;
  const std::unique_ptr<Trajectory> circle = MakeCircleTrajectory({}, &error);
  ASSERT_NE(circle, nullptr) << error;
  LogBuilder log(path);
  std::mt19937_64 rng(5);
  std::normal_distribution<double> us(0.0, kSigmaUsM), cam(0.0, 0.001);
  for (int k = 0; k <= kSeconds * 30; ++k) {
    const double t = k / 30.0;
    const GroundTruthPose p = circle->PoseAt(t);
    const auto utime = kT0 + static_cast<int64_t>(t * 1e6);
    log.Pose(pose2d_t::SOURCE_GROUND_TRUTH, utime, p.x_m, p.y_m, 0);
    log.Pose(pose2d_t::SOURCE_CAMERA, utime, p.x_m + 0.02 + cam(rng), p.y_m - 0.01 + cam(rng));
    if (k % 3 == 0) {
      log.Pose(pose2d_t::SOURCE_ULTRASOUND, utime, p.x_m + us(rng), p.y_m + us(rng), 12000);
    }
  }
  log.Pose(pose2d_t::SOURCE_ULTRASOUND, kT0 + 61'000'000, std::nan(""), std::nan(""), 12000,
           pose2d_t::STATUS_LOST);
  log.Close();
}

// The circle fitted to the ultrasound fixes of WriteCircleLog's log.
void ExpectReferenceCircle(const json& u) {
  // 601 fixes with 1 cm noise: the radius to about 1 cm / sqrt(601) = 0.4 mm.
  constexpr double kRadiusTolM = 0.002;
  const json& a = u["circle"]["drifting_centre"];
  EXPECT_NEAR(a["radius_m"].get<double>(), 0.419, kRadiusTolM);
  EXPECT_NEAR(a["cx_m"].get<double>(), 1.911, kRadiusTolM);
  // The reference's drift of the centre, (0.264, -0.096) mm/s, is small
  // against 1 cm noise over 60 s; the fit must contain it within 4 of its
  // own standard deviations, which must be honest (well under 1 mm/s).
  for (const auto& [axis, truth_mps] : {std::pair<const char*, double>{"vx", 0.000264},
                                        std::pair<const char*, double>{"vy", -0.000096}}) {
    const double sigma = a[std::string(axis) + "_sigma_mps"].get<double>();
    EXPECT_GT(sigma, 0.0);
    EXPECT_LT(sigma, 0.001);
    EXPECT_NEAR(a[std::string(axis) + "_mps"].get<double>(), truth_mps, kStandardErrors * sigma)
        << axis;
  }
  // The reference circle's w and phase (CircleTrajectoryOptions, from the
  // reference's fit). 1 cm noise at r = 0.419 m is 0.024 rad of phase per
  // fix: over 601 fixes and 60 s the rate's standard error is about
  // 0.024 sqrt(12 / 601) / 60 s = 6e-5 rad/s and the phase's about
  // 0.024 sqrt(4 / 601) = 0.002 rad. The bounds are about 15 and 5 of those:
  // loose for the drifting centre the fit shares the data with, tight
  // against a wrong sign, unit or period.
  constexpr double kAngularSpeedTolRadps = 0.001;
  constexpr double kPhaseTolRad = 0.01;
  const json& b = u["circle"]["circular_motion"];
  EXPECT_NEAR(b["angular_speed_radps"].get<double>(), -0.439, kAngularSpeedTolRadps);
  EXPECT_NEAR(b["phase_rad"].get<double>(), 3.163, kPhaseTolRad);
}

TEST(RoomfixAnalyze, FitsTheReferenceCircleAndComparesEachSourceWithTruthAndCamera) {
  TempDir dir;
  ASSERT_NO_FATAL_FAILURE(WriteCircleLog(dir.File("circle.lcm")));
  int rc = -1;
  const json out = Analyze({dir.File("circle.lcm"), "--out", dir.File("report")}, &rc);
  ASSERT_EQ(rc, 0);
  const json& u = out["robots"]["1"]["ultrasound"];
  EXPECT_EQ(u["fixes"], 601);
  EXPECT_EQ(u["lost"], 1);
  EXPECT_FALSE(u["static"].get<bool>());
  ExpectReferenceCircle(u);
  // A statistic of the 601 ultrasound fixes with 1 cm noise per axis: its
  // standard error is at most 1 cm / sqrt(601) = 0.4 mm; 2 mm is 5 of those.
  constexpr double kUltrasoundStatisticTolM = 0.002;
  // Error against the truth: the 2D error of N(0, 1 cm) per axis has RMS
  // sqrt(2) cm.
  EXPECT_NEAR(u["ground_truth_error"]["rmse_m"].get<double>(), std::sqrt(2.0) * kSigmaUsM,
              kUltrasoundStatisticTolM);
  // Every third frame of 30 Hz: 10 Hz but for the whole-microsecond stamps
  // and the log's ends; half a percent, so 9 or 11 fixes a second fail.
  constexpr double kRateTolHz = 0.05;
  EXPECT_NEAR(u["timing"]["rate_hz"].get<double>(), 10.0, kRateTolHz);
  // Differencing fixes 0.1 s apart adds sqrt(2) x 1 cm / 0.1 s = 0.141 m/s of
  // noise per axis to the true 0.184 m/s, so each step's speed is Rice
  // distributed: mean sigma sqrt(pi/2) L_1/2(-nu^2 / 2 sigma^2) = 0.245 m/s
  // (nu 0.184, sigma 0.141). Its mean over the 600 steps spreads by 3.1 mm/s
  // (300 simulated draws of this log), so 4 of those: the true speed alone
  // (0.184), a unit slip, 0 or a negative speed all fail.
  constexpr double kNoisyMeanSpeedMps = 0.245;
  constexpr double kNoisySpeedTolMps = kStandardErrors * 0.0031;
  EXPECT_NEAR(u["motion"]["mean_speed_mps"].get<double>(), kNoisyMeanSpeedMps, kNoisySpeedTolMps)
      << "noise inflates the speed between fixes by a known amount";
  // Camera as the reference for ultrasound: ultrasound - camera = (-2, +1) cm.
  const json& vs = u["vs_camera"];
  EXPECT_NEAR(vs["mean_dx_m"].get<double>(), -0.02, kUltrasoundStatisticTolM);
  EXPECT_NEAR(vs["mean_dy_m"].get<double>(), 0.01, kUltrasoundStatisticTolM);
  // The camera's error is its (2, -1) cm offset plus 1 mm noise per axis:
  // RMS sqrt(5 cm^2 + 2 mm^2), 0.04 mm above the offset's length; 1 mm, the
  // camera's own noise, bounds it.
  constexpr double kCameraRmseTolM = 0.001;
  EXPECT_NEAR(out["robots"]["1"]["camera"]["ground_truth_error"]["rmse_m"].get<double>(),
              std::hypot(0.02, 0.01), kCameraRmseTolM);
  // Every ultrasound pose states latency_us = 12000 exactly.
  constexpr double kExactMs = 1e-9;
  EXPECT_NEAR(out["sources"]["ultrasound"]["latency_ms_median"].get<double>(), 12.0, kExactMs);
  // Whether each source can be trusted. Every pose states a 1 cm sigma per
  // axis (tests/testing/test_messages.h): honest for the ultrasound, whose 601
  // errors must fill the 95 % ellipse as a Gaussian does (binomial standard
  // deviation 0.9 %, three of them allowed) with a median squared distance
  // of 2 ln 2 (its sampling spread about 0.08); the lost fix is a share.
  const json& uq = u["quality"];
  EXPECT_EQ(uq["fixes"], 602);
  EXPECT_EQ(uq["lost"], 1);
  constexpr double kRatioOfCounts = 1e-12;        // a count over a count: one division's rounding
  constexpr double kThreeBinomialSigmas = 0.027;  // 3 x sqrt(0.95 x 0.05 / 601) = 3 x 0.0089
  constexpr double kMedianTol = 0.25;             // about 3 x its 0.08 sampling spread
  EXPECT_NEAR(uq["share_ok"].get<double>(), 601.0 / 602.0, kRatioOfCounts);
  EXPECT_NEAR(uq["share_inside_95"].get<double>(), 0.95, kThreeBinomialSigmas);
  EXPECT_NEAR(uq["median_squared_mahalanobis"].get<double>(), 1.386, kMedianTol);  // 2 ln 2
  EXPECT_DOUBLE_EQ(uq["worst_ok_m"].get<double>(), uq["max_m"].get<double>());
  EXPECT_GE(uq["p99_m"].get<double>(), u["ground_truth_error"]["p95_m"].get<double>());
  // The camera's (2, -1) cm bias is not in its covariance: every squared
  // distance is about (2^2 + 1^2) cm^2 / 1 cm^2 = 5, far above 1.39. With the
  // camera's 1 mm noise (a, b unit normal) it is 5 + 0.4 a + 0.2 b: spread
  // 0.45, its median over 1801 frames within 0.02 of 5; 0.3 is loose, yet
  // far from the 1.39 of an honest covariance.
  constexpr double kBiasedMedianTol = 0.3;
  EXPECT_NEAR(out["robots"]["1"]["camera"]["quality"]["median_squared_mahalanobis"].get<double>(),
              5.0, kBiasedMedianTol);
  EXPECT_TRUE(out["sources"]["ultrasound"].contains("quality"));
  EXPECT_TRUE(NonEmptyFile(dir.File("report/trajectory_robot1.png")));
  EXPECT_TRUE(NonEmptyFile(dir.File("report/error_ultrasound_robot1.png")));
}

TEST(RoomfixAnalyze, CountsAPoseRecordedInTwoLogsOnceAndKeepsTheFigureSmallAcrossAGap) {
  // Two overlapping recordings of one session, then a second session an
  // hour later.
  TempDir dir;
  for (const char* name : {"a.lcm", "b.lcm"}) {
    LogBuilder log(dir.File(name));
    for (int k = 0; k < 30; ++k) log.Pose(pose2d_t::SOURCE_ULTRASOUND, kT0 + k * 100'000, 1.0, 1.0);
    log.Close();
  }
  {
    LogBuilder log(dir.File("c.lcm"));
    for (int k = 0; k < 30; ++k) {
      log.Pose(pose2d_t::SOURCE_ULTRASOUND, kT0 + 3'600'000'000 + k * 100'000, 1.0, 1.0);
    }
    log.Close();
  }
  int rc = -1;
  const json out = Analyze({dir.File("a.lcm"), dir.File("b.lcm"), dir.File("c.lcm"), "--no-figures",
                            "--out", dir.File("r")},
                           &rc);
  ASSERT_EQ(rc, 0);
  const json& u = out["robots"]["1"]["ultrasound"];
  EXPECT_EQ(u["fixes"], 60);
  // 20 medians of 100 ms: the hour-long gap is counted above the figure.
  EXPECT_LE(u["timing"]["interval_ms"]["counts"].size(), 2000u);
  EXPECT_EQ(u["timing"]["interval_ms"]["above"], 1);
}

TEST(RoomfixAnalyze, AnalysesTheReadablePartOfATruncatedLogAndSaysWhere) {
  TempDir dir;
  LogBuilder log(dir.File("cut.lcm"));
  for (int k = 0; k < 100; ++k) {
    log.Pose(pose2d_t::SOURCE_ULTRASOUND, kT0 + k * 100'000, 1.0 + 0.001 * (k % 3), 1.0);
  }
  log.Close();
  struct stat st {};
  ASSERT_EQ(::stat(dir.File("cut.lcm").c_str(), &st), 0);
  ASSERT_EQ(::truncate(dir.File("cut.lcm").c_str(), st.st_size - 20), 0);
  int rc = -1;
  const json out = Analyze({dir.File("cut.lcm"), "--no-figures", "--out", dir.File("r")}, &rc);
  ASSERT_EQ(rc, 0);
  EXPECT_TRUE(out["logs"][0]["damaged"].get<bool>());
  EXPECT_LT(out["logs"][0]["bytes_read"].get<int64_t>(), st.st_size - 20);
  EXPECT_EQ(out["robots"]["1"]["ultrasound"]["fixes"], 99);
  EXPECT_NE(ReadFile(dir.File("r/report.md")).find("damaged: skipped "), std::string::npos);
}

TEST(RoomfixAnalyze, ReportsEmptyCorruptAndMissingLogsWithoutCrashing) {
  TempDir dir;
  testing::WriteFile(dir.File("empty.lcm"), "");
  std::string garbage(4096, '\0');
  for (size_t i = 0; i < garbage.size(); ++i) garbage[i] = static_cast<char>(i * 131 + 7);
  testing::WriteFile(dir.File("garbage.lcm"), garbage);
  int rc = -1;
  json out = Analyze({dir.File("empty.lcm"), dir.File("garbage.lcm"), "--out", dir.File("r")}, &rc);
  EXPECT_EQ(rc, 0);
  ASSERT_FALSE(out.is_discarded());
  EXPECT_TRUE(out["robots"].empty());
  EXPECT_NE(ReadFile(dir.File("r/report.md")).find("No pose2d_t"), std::string::npos);

  out = Analyze({dir.File("missing.lcm"), "--out", dir.File("r2")}, &rc);
  EXPECT_EQ(rc, 1) << "nothing readable at all";
  out = Analyze({dir.path(), "--out", dir.File("r3")}, &rc);
  EXPECT_EQ(rc, 1) << "a folder is not a log";
  out = Analyze({dir.File("empty.lcm"), "--max-gap", "nan", "--out", dir.File("r4")}, &rc);
  EXPECT_EQ(rc, 1) << "options are checked";
}

// The README's headline figures of `make demo` (each source's RMSE and the
// share of its errors inside its own 95 % ellipse), on a fixed recording:
// the live demo runs in real time (frames the renderer skips, the order in
// which camera and ultrasonic poses reach fusion_proc), so it is not
// repeatable, but `roomfix replay` re-runs camera_proc's (from the recorded
// marker pixels), trilat_proc's and fusion_proc's nodes over a recorded demo
// deterministically and `roomfix analyze` scores them. tests/data/demo_30s.lcm
// is 30 s of `make demo` (scripts/record_test_logs.sh); the replay gives its
// live figures back (camera bit for bit). Two live `make demo` runs
// (2026-11-29, a shared 2-core machine) gave camera 90.0 and 90.0 % inside
// (3.0 mm), fused 90.8 and 90.6 % (3.0 and 3.1 mm).
TEST(DemoFigures, AReplayedDemoGivesTheReadmesFigures) {
  TempDir dir;
  // The site as the demo's camera_proc runs it: with the calibration of the
  // lens the simulated webcam renders through (scripts/demo.sh).
  std::string error;
  const std::string site = testing::WriteDemoSiteVariant(
      dir, "demo_webcam", "calibration: ../calibration/demo_room_camera.yaml",
      "calibration: " + testing::SourceDir() + "/config/calibration/demo_room_webcam.yaml", &error);
  ASSERT_FALSE(site.empty()) << error;
  ChildProcess replay(
      {BinDir() + "/roomfix", "replay", testing::SourceDir() + "/tests/data/demo_30s.lcm",
       "--config", site, "--nodes", "trilat,fusion,camera", "--out", dir.File("replayed.lcm")},
      dir.File("replay.out"));
  ASSERT_EQ(replay.Wait(120), 0) << ReadFile(dir.File("replay.out"));
  int rc = -1;
  const json out = Analyze({dir.File("replayed.lcm")}, &rc);
  ASSERT_EQ(rc, 0);
  // Measured on this recording (deterministic; GCC 12, RelWithDebInfo).
  struct Figures {
    const char* source;
    double rmse_m;
    double inside_95;
    double median_d2;
  };
  const Figures measured[] = {{"camera", 0.0030127, 0.89965, 1.5500},
                              {"fused", 0.0030650, 0.90641, 1.6441},
                              {"ultrasound", 0.027110, 0.95470, 1.4016}};
  // The replay is deterministic; another compiler's or libjpeg's rounding
  // moves a pose by far less than a micrometre, so a few of the ~900 poses
  // that lie on their ellipse's edge at most. The margins: the RMSE may
  // grow by 5 % of itself, the share inside by 1 point either way (9
  // camera poses of 877), the median squared distance by 0.1 (its sampling
  // spread would be 0.07 over 877 independent poses): a change of the camera's, the
  // solver's or the filter's errors or covariances shows.
  constexpr double kRmseMargin = 1.05;
  constexpr double kInsideMargin = 0.01;
  constexpr double kMedianD2Margin = 0.1;
  for (const Figures& f : measured) {
    const json& q = out["robots"]["1"][f.source]["quality"];
    ASSERT_TRUE(q.is_object()) << f.source;
    std::printf("%s: RMSE %.2f mm, %.1f %% inside the own 95 %% ellipse, median d2 %.2f\n",
                f.source, q["rmse_m"].get<double>() * 1e3, 100 * q["share_inside_95"].get<double>(),
                q["median_squared_mahalanobis"].get<double>());
    EXPECT_LT(q["rmse_m"].get<double>(), f.rmse_m * kRmseMargin) << f.source;
    EXPECT_NEAR(q["share_inside_95"].get<double>(), f.inside_95, kInsideMargin) << f.source;
    EXPECT_NEAR(q["median_squared_mahalanobis"].get<double>(), f.median_d2, kMedianD2Margin)
        << f.source;
  }
}

}  // namespace
}  // namespace roomfix
