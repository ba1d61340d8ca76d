#include "camera_proc/camera_node.h"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <opencv2/imgcodecs.hpp>
#include <random>
#include <utility>
#include <vector>

#include "core/calib/camera_timing.h"
#include "roomfix/detector_view_request_t.hpp"
#include "roomfix/detector_view_t.hpp"
#include "roomfix/image_t.hpp"
#include "roomfix/marker_pixels_t.hpp"
#include "roomfix/pose2d_t.hpp"
#include "sim/sim_frame_source.h"
#include "sim/synthetic_camera.h"
#include "tests/testing/demo_site.h"
#include "tests/testing/test_paths.h"

namespace roomfix {
namespace {

// The issue targets (camera #5: 3 mm static, 5 mm on the circle) are met
// ten times over here, with the true lens as the calibration so that only
// detection and mapping are judged; the bounds are what these renders
// measure (deterministic: fixed scenes, seeds and JPEG quality; printed by
// each test), times kMargin. The margin leaves room for another compiler's
// or libjpeg's rounding, which moves these figures by a few hundredths of a
// millimetre, and fails a change that makes them half as bad again.
constexpr double kMargin = 1.5;
// Measured 0.05, 0.19 and 0.30 mm at the three static places (the worst at
// the corner (3.4, 2.5), where the fisheye squeezes a pixel into most floor).
constexpr double kStaticRmseM = 0.00030 * kMargin;
// Measured 0.11 mm on the reference circle (300 clean frames).
constexpr double kCircleRmseM = 0.00011 * kMargin;
// Measured 0.23 mm under "lighting" and "harsh" (with hints), worst fix
// 0.73 mm in both.
constexpr double kLightingRmseM = 0.00023 * kMargin;
constexpr double kLightingWorstM = 0.00073 * kMargin;
// Measured 0.12 and 0.13 mm for the two robots of 60 frames.
constexpr double kTwoRobotsRmseM = 0.00013 * kMargin;
constexpr double kDetectionRate = 0.995;
// A find farther than this from the truth is a false track.
constexpr double kFalseTrackM = 0.03;
// Heading from two markers 10 cm apart: measured 0.38 to 2.69 mrad (the
// largest under the rolling shutter, 2.20 on the circle).
constexpr double kHeadingRmseRad = 0.00269 * kMargin;
constexpr int64_t kStartUtime = 1'700'000'000'000'000;

struct PipelineRun {
  std::vector<pose2d_t> poses;
  std::vector<marker_pixels_t> pixels;
  std::vector<image_t> previews;
  std::vector<detector_view_t> views;
  // The ultrasound hints published, with the index of the frame they
  // preceded.
  std::vector<std::pair<size_t, pose2d_t>> hints;
  std::vector<std::vector<sim::RobotState>> truth;  // per frame
  std::unique_ptr<CameraNode> node;
};

class CameraNodeTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string error;
    ASSERT_TRUE(LoadSite(testing::DemoSitePath(), &site_, &error)) << error;
    camera_ = site_.cameras.front();
    // The demo site's camera is a webcam (rolling shutter, exposure,
    // latency, a rocking robot); these tests render the ideal `clean`
    // camera, whose frames are exposed at once and stamped exactly.
    camera_.readout_s = camera_.exposure_s = camera_.timestamp_latency_s = 0.0;
    for (CameraRobot& r : camera_.robots) r.tilt_sigma_deg = 0.0;
    lens_ = calib::NominalCamera(camera_.mount_position_m, camera_.field_of_view_deg,
                                 camera_.width_px, camera_.height_px);
    // A real lens is not the ideal equidistant one, nor mounted perfectly.
    lens_.intrinsics.k = {0.015, -0.004, 0.001, 0.0};
    lens_.intrinsics.cx_px += 6.0;
    lens_.intrinsics.cy_px -= 4.0;
  }

  void MakeStatic(double x_m, double y_m, double heading_rad) {
    StaticTrajectoryOptions o;
    o.x_m = x_m;
    o.y_m = y_m;
    o.heading_rad = heading_rad;
    std::string error;
    site_.simulation.robots.front().trajectory = MakeStaticTrajectory(o, &error);
  }

  // Renders `frames` frames of `scenario` as JPEG and runs them through a
  // node calibrated with the true lens (or uncalibrated).
  PipelineRun RunFrames(const std::string& scenario_name, int frames, bool calibrated = true,
                        CameraNodeOptions options = {}) {
    PipelineRun run;
    sim::SimScenario scenario;
    std::string error;
    EXPECT_TRUE(sim::ParseSimScenario(scenario_name, &scenario, &error)) << error;
    auto camera = std::make_shared<sim::SyntheticCamera>(site_, camera_, lens_, scenario);
    sim::SimSourceOptions so;
    so.fps = camera_.fps;
    so.start_utime = kStartUtime;
    so.realtime = false;
    so.jpeg_quality = 90;
    sim::SimFrameSource source(camera, so);
    EXPECT_TRUE(source.Open(&error));
    std::optional<calib::Calibration> calibration;
    if (calibrated) {
      calib::Calibration c;
      c.model = calib::Calibration::Model::kFull;
      c.camera = lens_;
      calibration = c;
    }
    bus_ = std::make_unique<LoopbackBus>();
    bus_->Subscribe<pose2d_t>(kCameraPoseChannel, [&run](const pose2d_t& p, const MessageInfo&) {
      run.poses.push_back(p);
    });
    bus_->Subscribe<marker_pixels_t>(
        kMarkerPixelsChannel,
        [&run](const marker_pixels_t& m, const MessageInfo&) { run.pixels.push_back(m); });
    bus_->Subscribe<image_t>(kCameraPreviewChannel, [&run](const image_t& m, const MessageInfo&) {
      run.previews.push_back(m);
    });
    bus_->Subscribe<detector_view_t>(
        kDetectorViewChannel,
        [&run](const detector_view_t& m, const MessageInfo&) { run.views.push_back(m); });
    run.node =
        std::make_unique<CameraNode>(site_, camera_, calibration, bus_.get(), options, kStartUtime);
    EXPECT_TRUE(run.node->ok(&error)) << error;
    std::mt19937 rng(11);
    for (int i = 0; i < frames; ++i) {
      camera::Frame frame;
      EXPECT_EQ(source.Read(&frame, &error), camera::ReadStatus::kFrame) << error;
      run.truth.push_back(camera->SimulatedRobots((frame.capture_utime - kStartUtime) * 1e-6));
      if (hint_sigma_m_ > 0.0 && i % 3 == 0) {
        // An ultrasonic fix of the same instant, as trilat_proc publishes.
        std::normal_distribution<double> noise(0.0, hint_sigma_m_);
        pose2d_t hint{};
        hint.utime = frame.capture_utime;
        hint.source = pose2d_t::SOURCE_ULTRASOUND;
        hint.robot_id = run.truth.back().front().robot_id;
        hint.x_m = run.truth.back().front().x_m + noise(rng);
        hint.y_m = run.truth.back().front().y_m + noise(rng);
        hint.covariance[0][0] = hint.covariance[1][1] = hint_sigma_m_ * hint_sigma_m_;
        hint.status = pose2d_t::STATUS_OK;
        bus_->set_now_utime(frame.capture_utime + 5'000);  // The radio's delay.
        bus_->Publish("POSE_ULTRASOUND", hint);
        run.hints.emplace_back(static_cast<size_t>(i), hint);
      }
      if (before_frame_) {
        bus_->set_now_utime(frame.capture_utime);
        before_frame_(i, run.node.get());
      }
      run.node->OnFrame(&frame, frame.capture_utime + 1000);
    }
    return run;
  }

  struct Errors {
    double rmse_m = 0.0;
    double heading_rmse_rad = 0.0;
    double detection_rate = 0.0;
    double worst_m = 0.0;
  };
  static Errors Score(const PipelineRun& run) {
    Errors e;
    double sum2 = 0.0, head2 = 0.0;
    int found = 0, headings = 0;
    for (size_t i = 0; i < run.poses.size(); ++i) {
      const pose2d_t& p = run.poses[i];
      if (p.status == pose2d_t::STATUS_LOST) continue;
      const sim::RobotState& t = run.truth[i].front();
      const double d = std::hypot(p.x_m - t.x_m, p.y_m - t.y_m);
      sum2 += d * d;
      e.worst_m = std::max(e.worst_m, d);
      ++found;
      if (std::isfinite(p.heading_rad)) {
        const double dh = std::remainder(p.heading_rad - t.heading_rad, 2 * M_PI);
        head2 += dh * dh;
        ++headings;
      }
    }
    e.rmse_m = found > 0 ? std::sqrt(sum2 / found) : NAN;
    e.heading_rmse_rad = headings > 0 ? std::sqrt(head2 / headings) : NAN;
    e.detection_rate = run.poses.empty() ? 0.0 : static_cast<double>(found) / run.poses.size();
    return e;
  }

  Site site_;
  Camera camera_;
  calib::CameraModel lens_;
  std::unique_ptr<LoopbackBus> bus_;
  // > 0: ultrasonic fixes with this noise are published as hints.
  double hint_sigma_m_ = 0.0;
  // Called before frame i, with the bus's clock at its capture time.
  std::function<void(int, CameraNode*)> before_frame_;
};

TEST_F(CameraNodeTest, StaticRobotIsLocatedToHalfAMillimetre) {
  for (const auto& [x, y] :
       std::vector<std::pair<double, double>>{{2.0, 1.5}, {0.6, 0.5}, {3.4, 2.5}}) {
    MakeStatic(x, y, 0.7);
    const PipelineRun run = RunFrames("clean", 30);
    const Errors e = Score(run);
    std::printf("static at (%.1f, %.1f): RMSE %.2f mm, worst %.2f mm, heading %.2f mrad\n", x, y,
                e.rmse_m * 1e3, e.worst_m * 1e3, e.heading_rmse_rad * 1e3);
    EXPECT_EQ(e.detection_rate, 1.0);
    EXPECT_LT(e.rmse_m, kStaticRmseM) << x << ", " << y;
    EXPECT_LT(e.heading_rmse_rad, kHeadingRmseRad);
  }
}

TEST_F(CameraNodeTest, ReferenceCircleIsTrackedToAFifthOfAMillimetre) {
  // The reference's test drive at about 18 cm/s; 10 s of frames.
  const PipelineRun run = RunFrames("clean", 300);
  const Errors e = Score(run);
  std::printf("circle: RMSE %.2f mm, worst %.2f mm, heading %.2f mrad, detection %.4f\n",
              e.rmse_m * 1e3, e.worst_m * 1e3, e.heading_rmse_rad * 1e3, e.detection_rate);
  EXPECT_GE(e.detection_rate, kDetectionRate);
  EXPECT_LT(e.rmse_m, kCircleRmseM);
  EXPECT_LT(e.heading_rmse_rad, kHeadingRmseRad);
  // After the first frame's full search, the robot is followed in a window.
  ASSERT_EQ(run.pixels.size(), 300u);
  EXPECT_EQ(run.pixels.front().search_mode, marker_pixels_t::SEARCH_FULL_FRAME);
  int windows = 0;
  for (const marker_pixels_t& m : run.pixels) {
    windows += m.search_mode == marker_pixels_t::SEARCH_REGION_OF_INTEREST;
  }
  EXPECT_GE(windows, 295);
  // A quarter-size JPEG preview once a second for the viewer: 10 s, 10.
  ASSERT_EQ(run.previews.size(), 10u);
  EXPECT_EQ(run.previews.front().width_px, 480);
  EXPECT_EQ(run.previews.front().source_width_px, 1920);
  EXPECT_EQ(run.previews.front().format, "jpeg");
  EXPECT_EQ(cv::imdecode(run.previews.front().data, cv::IMREAD_COLOR).cols, 480);
  // Poses are stamped with the frame's capture time, not the publish time.
  for (size_t i = 0; i < run.poses.size(); ++i) {
    EXPECT_EQ(run.poses[i].utime, run.pixels[i].utime);
    EXPECT_EQ(run.poses[i].source, pose2d_t::SOURCE_CAMERA);
  }
}

TEST_F(CameraNodeTest, HoldsThroughLightingChangesFlickerAndNoise) {
  const PipelineRun run = RunFrames("lighting", 300);
  const Errors e = Score(run);
  std::printf("lighting: RMSE %.2f mm, worst %.2f mm, detection %.4f\n", e.rmse_m * 1e3,
              e.worst_m * 1e3, e.detection_rate);
  EXPECT_GE(e.detection_rate, kDetectionRate);
  EXPECT_LT(e.worst_m, kLightingWorstM);
  EXPECT_LT(e.rmse_m, kLightingRmseM);
}

TEST_F(CameraNodeTest, NeverLocksOnToALookalikeAtStartUp) {
  // "harsh" lays an orange disc with a green one beside it on the floor: to
  // the camera alone it is a second robot. The node says so (lost poses,
  // ambiguous in STATUS) and never picks one.
  const PipelineRun run = RunFrames("harsh", 60);
  const Errors e = Score(run);
  EXPECT_EQ(e.detection_rate, 0.0);
  EXPECT_EQ(run.node->status().counter("ambiguous_frames"), 60);
}

TEST_F(CameraNodeTest, AnUltrasoundHintResolvesTheLookalikeAndTheTrackHolds) {
  // The ultrasound's fixes (10 Hz, 3 cm noise) say roughly where the robot
  // is; once the camera has it, the window keeps the look-alike out through
  // the lighting changes and noise of "harsh".
  hint_sigma_m_ = 0.03;
  const PipelineRun run = RunFrames("harsh", 300);
  const Errors e = Score(run);
  std::printf("distractors + lighting, with hints: RMSE %.2f mm, worst %.2f mm, detection %.4f\n",
              e.rmse_m * 1e3, e.worst_m * 1e3, e.detection_rate);
  EXPECT_GE(e.detection_rate, kDetectionRate);
  EXPECT_LT(e.worst_m, kFalseTrackM) << "locked on to the look-alike";
  EXPECT_LT(e.worst_m, kLightingWorstM);
  EXPECT_LT(e.rmse_m, kLightingRmseM);
  EXPECT_GT(run.node->status().counter("hints"), 0);
}

TEST_F(CameraNodeTest, TwoRobotsWithTheirOwnMarkerPairsKeepTheirIds) {
  // A second robot with blue and magenta markers, on a circle of its own.
  camera_.marker_classes.push_back({"blue", {100, 120, 60}, {125, 255, 255}, 0.10});
  camera_.marker_classes.push_back({"magenta", {145, 100, 60}, {170, 255, 255}, 0.05});
  camera_.robots.push_back({2, "blue", "magenta", 0.15});
  site_.robots.push_back({2, "robot2", std::nullopt});
  CircleTrajectoryOptions circle;
  circle.cx_m = 1.0;
  circle.cy_m = 1.0;
  circle.radius_m = 0.3;
  circle.angular_speed_radps = 0.5;
  std::string error;
  site_.simulation.robots.push_back({2, MakeCircleTrajectory(circle, &error)});
  site_.cameras.front() = camera_;
  const PipelineRun run = RunFrames("clean", 60);
  std::map<int, std::pair<double, int>> sum2_and_count;
  for (size_t i = 0; i < run.poses.size(); ++i) {
    const pose2d_t& p = run.poses[i];
    ASSERT_NE(p.status, pose2d_t::STATUS_LOST) << "robot " << p.robot_id;
    const int frame = static_cast<int>(p.measurement_seq);
    for (const sim::RobotState& t : run.truth[static_cast<size_t>(frame)]) {
      if (t.robot_id != p.robot_id) continue;
      auto& [sum2, n] = sum2_and_count[p.robot_id];
      sum2 += std::pow(p.x_m - t.x_m, 2) + std::pow(p.y_m - t.y_m, 2);
      ++n;
    }
  }
  ASSERT_EQ(sum2_and_count.size(), 2u);
  for (const auto& [id, s] : sum2_and_count) {
    const double rmse = std::sqrt(s.first / s.second);
    std::printf("robot %d: %d poses, %.2f mm RMS\n", id, s.second, rmse * 1e3);
    EXPECT_EQ(s.second, 60);
    EXPECT_LT(rmse, kTwoRobotsRmseM);
  }
}

TEST_F(CameraNodeTest, AReferenceNineRegionTableStillWorks) {
  // The reference's calibration form, loaded from its table: the robot is
  // found and mapped, to the table's (centimetre-level) accuracy; a robot at
  // another height than the table's is refused up front. Measured 4.4 mm
  // (the table's interpolation error at this place, deterministic).
  constexpr double kNineRegionRmseM = 0.0044 * kMargin;
  lens_ = calib::NominalCamera(camera_.mount_position_m, camera_.field_of_view_deg,
                               camera_.width_px, camera_.height_px);
  calib::Calibration table;
  std::string error;
  ASSERT_TRUE(calib::LoadCalibration(
      testing::SourceDir() + "/config/calibration/reference_9_region_example.yaml", &table, &error))
      << error;
  MakeStatic(1.2, 1.0, 0.3);
  bus_ = std::make_unique<LoopbackBus>();
  std::vector<pose2d_t> poses;
  bus_->Subscribe<pose2d_t>(kCameraPoseChannel,
                            [&](const pose2d_t& p, const MessageInfo&) { poses.push_back(p); });
  CameraNode node(site_, camera_, table, bus_.get(), CameraNodeOptions{}, kStartUtime);
  ASSERT_TRUE(node.ok(&error)) << error;
  sim::SimScenario scenario;
  ASSERT_TRUE(sim::ParseSimScenario("clean", &scenario, &error));
  sim::SyntheticCamera camera(site_, camera_, lens_, scenario);
  for (int i = 0; i < 10; ++i) {
    cv::Mat bgr;
    camera.Render(i / 30.0, i, camera.SimulatedRobots(i / 30.0), &bgr);
    camera::Frame frame;
    frame.seq = i;
    frame.capture_utime = kStartUtime + i * 33'333;
    frame.image = camera::MakeDecodedImage(bgr);
    node.OnFrame(&frame, frame.capture_utime);
  }
  ASSERT_EQ(poses.size(), 10u);
  double sum2 = 0.0;
  for (const pose2d_t& p : poses) {
    ASSERT_NE(p.status, pose2d_t::STATUS_LOST);
    sum2 += std::pow(p.x_m - 1.2, 2) + std::pow(p.y_m - 1.0, 2);
  }
  const double rmse = std::sqrt(sum2 / poses.size());
  std::printf("9-region table: %.1f mm RMS at (1.2, 1.0)\n", rmse * 1e3);
  EXPECT_LT(rmse, kNineRegionRmseM);

  camera_.robots.front().marker_height_m = 0.35;
  CameraNode wrong_height(site_, camera_, table, bus_.get(), CameraNodeOptions{}, kStartUtime);
  EXPECT_FALSE(wrong_height.ok(&error));
  EXPECT_NE(error.find("9-region"), std::string::npos) << error;
}

TEST_F(CameraNodeTest, RefusesHintsForUnknownRobotsFarOffTimesAndInfinities) {
  MakeStatic(1.0, 1.0, 0.0);
  calib::Calibration calibration;
  calibration.model = calib::Calibration::Model::kFull;
  calibration.camera = lens_;
  bus_ = std::make_unique<LoopbackBus>();
  CameraNode node(site_, camera_, calibration, bus_.get(), CameraNodeOptions{}, kStartUtime);
  std::string error;
  ASSERT_TRUE(node.ok(&error)) << error;
  bus_->set_now_utime(kStartUtime);
  pose2d_t hint{};
  hint.utime = kStartUtime;
  hint.source = pose2d_t::SOURCE_ULTRASOUND;
  hint.robot_id = site_.robots.front().id;
  hint.x_m = 1.0;
  hint.y_m = 1.0;
  hint.covariance[0][0] = hint.covariance[1][1] = 0.01;
  hint.status = pose2d_t::STATUS_OK;
  pose2d_t bad = hint;
  for (int id = 0; id < 20000; ++id) {
    bad.robot_id = 1000 + id;
    bus_->Publish("POSE_ULTRASOUND", bad);
  }
  bad = hint;
  bad.utime = std::numeric_limits<int64_t>::min();
  bus_->Publish("POSE_ULTRASOUND", bad);
  bad.utime = kStartUtime + int64_t{3600} * 1'000'000 + 1;
  bus_->Publish("POSE_ULTRASOUND", bad);
  bad = hint;
  bad.x_m = std::numeric_limits<double>::infinity();
  bus_->Publish("POSE_ULTRASOUND", bad);
  bad = hint;
  bad.covariance[1][1] = std::numeric_limits<double>::infinity();
  bus_->Publish("POSE_ULTRASOUND", bad);
  EXPECT_EQ(node.status().rejected("unknown_robot"), 20000);
  EXPECT_EQ(node.status().rejected("utime_out_of_range"), 2);
  EXPECT_EQ(node.status().rejected("non_finite"), 2);
  EXPECT_EQ(node.status().counter("hints"), 0);
  bus_->Publish("POSE_ULTRASOUND", hint);
  EXPECT_EQ(node.status().counter("hints"), 1);
}

// The detector view (docs/camera.md, "What the detector sees").
detector_view_request_t WholeFrameViewRequest(int64_t utime, double rate_hz, double duration_s) {
  detector_view_request_t r{};
  r.utime = utime;
  r.camera_id = -1;
  r.rate_hz = rate_hz;
  r.duration_s = duration_s;
  return r;
}

TEST_F(CameraNodeTest, ARequestTurnsTheDetectorViewOnAtTheCappedRateWithAPngAndTheRobotsReason) {
  MakeStatic(1.9, 1.5, 0.3);
  constexpr int kRequestFrame = 5;
  constexpr int kFrames = kRequestFrame + 30;  // one second at 30 fps after it
  CameraNodeOptions options;
  options.detector_view_max_hz = 2.0;
  before_frame_ = [&](int i, CameraNode*) {
    if (i != kRequestFrame) return;
    // Ten per second asked; the node's cap is two.
    bus_->Publish(kDetectorViewRequestChannel,
                  WholeFrameViewRequest(bus_->now_utime(), 10.0, 60.0));
  };
  const PipelineRun run = RunFrames("clean", kFrames, true, options);
  EXPECT_EQ(run.node->status().counter("detector_view_requests"), 1);
  // Frames kRequestFrame (t = 0) and kRequestFrame + 15 (t = 0.5 s): 2 Hz.
  ASSERT_EQ(run.views.size(), 2u);
  EXPECT_EQ(run.views[0].frame_seq, run.pixels[kRequestFrame].frame_seq);
  EXPECT_EQ(run.views[1].frame_seq, run.pixels[kRequestFrame + 15].frame_seq);
  for (const detector_view_t& v : run.views) {
    EXPECT_EQ(v.format, "png");
    EXPECT_EQ(v.scale, 2);  // 1920 px wide over the default 960 px
    EXPECT_EQ(v.region_width_px, camera_.width_px);
    const cv::Mat png = cv::imdecode(v.data, cv::IMREAD_COLOR);
    ASSERT_FALSE(png.empty());
    EXPECT_EQ(png.cols, v.width_px);
    EXPECT_EQ(png.rows, v.height_px);
    EXPECT_EQ(v.width_px, camera_.width_px / 2);
    ASSERT_EQ(v.robots.size(), 1u);
    EXPECT_EQ(v.robots[0].robot_id, camera_.robots.front().robot_id);
    EXPECT_EQ(v.robots[0].reason, detector_view_robot_t::REASON_FOUND) << v.robots[0].text;
  }
}

TEST_F(CameraNodeTest, TheDetectorViewIsOffUnlessAskedOrFlagged) {
  MakeStatic(1.9, 1.5, 0.3);
  EXPECT_TRUE(RunFrames("clean", 10).views.empty());
  CameraNodeOptions options;
  options.detector_view_hz = 1.0;
  // 45 frames at 30 fps: views at t = 0 and 1 s.
  EXPECT_EQ(RunFrames("clean", 45, true, options).views.size(), 2u);
}

TEST_F(CameraNodeTest, BadDetectorViewRequestsAreRefusedCountedAndNeverTurnTheViewOn) {
  MakeStatic(1.9, 1.5, 0.3);
  before_frame_ = [&](int i, CameraNode*) {
    if (i != 0) return;
    const int64_t now = bus_->now_utime();
    detector_view_request_t r = WholeFrameViewRequest(now, -1.0, 10.0);
    bus_->Publish(kDetectorViewRequestChannel, r);  // a negative rate
    r = WholeFrameViewRequest(now, 1.0, std::numeric_limits<double>::quiet_NaN());
    bus_->Publish(kDetectorViewRequestChannel, r);
    r = WholeFrameViewRequest(now, 1.0, 10.0);
    r.region_u_px = camera_.width_px - 10;  // runs off the frame
    r.region_width_px = 200;
    r.region_height_px = 200;
    bus_->Publish(kDetectorViewRequestChannel, r);
    r = WholeFrameViewRequest(now, 1.0, 10.0);
    r.camera_id = -7;
    bus_->Publish(kDetectorViewRequestChannel, r);
    r = WholeFrameViewRequest(now, 1.0, 10.0);
    r.camera_id = camera_.id + 1;  // another camera's: not ours, not an error
    bus_->Publish(kDetectorViewRequestChannel, r);
  };
  const PipelineRun run = RunFrames("clean", 10);
  const StatusReporter& status = run.node->status();
  EXPECT_EQ(status.rejected("detector_view_bad_rate"), 1);
  EXPECT_EQ(status.rejected("detector_view_bad_duration"), 1);
  EXPECT_EQ(status.rejected("detector_view_bad_region"), 1);
  EXPECT_EQ(status.rejected("detector_view_bad_camera"), 1);
  EXPECT_EQ(status.counter("detector_view_other_camera"), 1);
  EXPECT_EQ(status.counter("detector_view_requests"), 0);
  EXPECT_TRUE(run.views.empty());
  // The frames themselves went on as ever.
  EXPECT_EQ(run.pixels.size(), 10u);
}

TEST_F(CameraNodeTest, ARegionRequestShowsThatRegionAtFullResolution) {
  MakeStatic(1.9, 1.5, 0.3);
  before_frame_ = [&](int i, CameraNode*) {
    if (i != 0) return;
    detector_view_request_t r = WholeFrameViewRequest(bus_->now_utime(), 1.0, 10.0);
    r.region_u_px = 800;
    r.region_v_px = 400;
    r.region_width_px = 320;
    r.region_height_px = 240;
    bus_->Publish(kDetectorViewRequestChannel, r);
  };
  const PipelineRun run = RunFrames("clean", 3);
  ASSERT_EQ(run.views.size(), 1u);
  const detector_view_t& v = run.views[0];
  EXPECT_EQ(v.scale, 1);
  EXPECT_EQ(v.region_u_px, 800);
  EXPECT_EQ(v.width_px, 320);
  EXPECT_EQ(v.height_px, 240);
  EXPECT_FALSE(cv::imdecode(v.data, cv::IMREAD_COLOR).empty());
}

TEST_F(CameraNodeTest, WithoutCalibrationPublishesPixelsOnly) {
  MakeStatic(1.0, 1.0, 0.0);
  const PipelineRun run = RunFrames("clean", 5, /*calibrated=*/false);
  EXPECT_TRUE(run.poses.empty());
  ASSERT_EQ(run.pixels.size(), 5u);
  for (const marker_pixels_t& m : run.pixels) {
    EXPECT_EQ(m.width_px, 1920);
    EXPECT_EQ(m.height_px, 1080);
    int position = 0, heading = 0;
    for (const marker_t& k : m.markers) {
      position += k.role == marker_t::ROLE_POSITION && k.robot_id == 1;
      heading += k.role == marker_t::ROLE_HEADING && k.robot_id == 1;
    }
    EXPECT_EQ(position, 1);
    EXPECT_EQ(heading, 1);
  }
}

TEST_F(CameraNodeTest, FramesTheSourceSkippedAreNotCountedAsDropped) {
  MakeStatic(2.0, 1.5, 0.0);
  PipelineRun run = RunFrames("clean", 3);  // seq 0..2
  sim::SimScenario scenario;
  std::string error;
  ASSERT_TRUE(sim::ParseSimScenario("clean", &scenario, &error));
  sim::SyntheticCamera camera(site_, camera_, lens_, scenario);
  cv::Mat bgr;
  camera.Render(0.3, 9, camera.SimulatedRobots(0.3), &bgr);
  camera::Frame frame;
  // Frames 3..8 never came: the synthetic renderer skipped 4 of them (it
  // fell behind real time), so camera_proc dropped the other 2.
  frame.seq = 9;
  frame.source_skipped = 4;
  frame.capture_utime = kStartUtime + 300'000;
  frame.image = camera::MakeDecodedImage(bgr);
  run.node->OnFrame(&frame, frame.capture_utime);
  EXPECT_EQ(run.node->status().dropped(), 2);
  EXPECT_EQ(run.node->status().counter("source_skipped_frames"), 4);
}

TEST_F(CameraNodeTest, CorruptFramesAreCountedAndSkipped) {
  MakeStatic(2.0, 1.5, 0.0);
  PipelineRun run = RunFrames("clean", 3);
  // A JPEG cut short: its header reads, its body does not.
  sim::SimScenario scenario;
  std::string error;
  ASSERT_TRUE(sim::ParseSimScenario("clean", &scenario, &error));
  sim::SyntheticCamera camera(site_, camera_, lens_, scenario);
  cv::Mat bgr;
  camera.Render(0.2, 3, camera.SimulatedRobots(0.2), &bgr);
  std::vector<uint8_t> bytes;
  cv::imencode(".jpg", bgr, bytes);
  bytes.resize(bytes.size() / 2);
  camera::Frame frame;
  frame.seq = 5;  // frames 3 and 4 never came
  frame.capture_utime = kStartUtime + 200'000;
  frame.image = camera::MakeJpegImage(bytes, &error);
  ASSERT_NE(frame.image, nullptr) << error;
  run.node->OnFrame(&frame, frame.capture_utime);
  EXPECT_EQ(run.node->status().rejected("corrupt_frame"), 1);
  EXPECT_EQ(run.node->status().dropped(), 2);
  EXPECT_EQ(run.pixels.size(), 3u);  // nothing published for it
  // A frame of the wrong size is refused, not searched.
  camera::Frame small;
  small.seq = 6;
  small.image = camera::MakeDecodedImage(cv::Mat(480, 640, CV_8UC3, cv::Scalar(0, 0, 0)));
  run.node->OnFrame(&small, kStartUtime + 300'000);
  EXPECT_EQ(run.node->status().rejected("wrong_frame_size"), 1);
}

TEST_F(CameraNodeTest, ARobotOutOfViewIsLost) {
  // Far beyond the floor's edge, outside the 120-degree view.
  MakeStatic(-5.0, 1.5, 0.0);
  const PipelineRun run = RunFrames("clean", 10);
  ASSERT_EQ(run.poses.size(), 10u);
  for (const pose2d_t& p : run.poses) {
    EXPECT_EQ(p.status, pose2d_t::STATUS_LOST);
    EXPECT_TRUE(std::isnan(p.x_m));
  }
  // Out of view: searched in full once every absent_search_period_frames,
  // from the first frame on; nothing is searched in between.
  const size_t period = static_cast<size_t>(CameraNodeOptions{}.absent_search_period_frames);
  ASSERT_GT(period, 1u);
  for (size_t k = 0; k < run.pixels.size(); ++k) {
    EXPECT_EQ(run.pixels[k].num_markers, 0);
    EXPECT_EQ(run.pixels[k].search_mode, k % period == 0
                                             ? marker_pixels_t::SEARCH_FULL_FRAME
                                             : marker_pixels_t::SEARCH_REGION_OF_INTEREST)
        << "frame " << k;
  }
  EXPECT_EQ(run.node->status().counter("full_searches"),
            static_cast<int64_t>((run.pixels.size() + period - 1) / period));
}

// The entry point for recorded pixels (roomfix replay --nodes camera) runs
// the code the live frame path runs after detection: fed the MARKER_PIXELS a
// live node published, a fresh node publishes the very same POSE_CAMERA,
// bit for bit. "harsh" has look-alikes, noise and lighting changes, so the
// run holds full-frame searches, window searches and refused candidates.
// A rolling-shutter webcam, made from the synthetic camera's instants: row r
// of frame k is read at t0 + r readout / H and holds the mean of the renders
// at every `step_s` within its exposure [t_read(r) - exposure, t_read(r)]
// (the rows near the robot; the floor elsewhere does not move). The frame is
// stamped when its last row has been read plus the latency, as a UVC camera
// does (docs/camera.md, "Time of a marker").
camera::Frame RollingShutterFrame(const sim::SyntheticCamera& cam, int64_t seq, double t0_s,
                                  const calib::CameraTiming& timing, double step_s) {
  const int h = cam.height_px();
  const double row_s = timing.readout_s / h;
  const double first_s = t0_s - timing.exposure_s;
  const double last_s = t0_s + (h - 1) * row_s;
  const int n = static_cast<int>(std::ceil((last_s - first_s) / step_s));
  std::vector<cv::Mat> renders(static_cast<size_t>(n));
  std::vector<double> times(static_cast<size_t>(n));
  cv::Rect roi;
  for (int j = 0; j < n; ++j) {
    times[j] = first_s + (j + 0.5) * step_s;
    std::vector<sim::MarkerTruth> truth;
    cam.Render(times[j], seq, cam.SimulatedRobots(times[j]), &renders[j], &truth);
    for (const sim::MarkerTruth& m : truth) {
      // The body disc (0.30 m) reaches ~50 px from the marker at the centre.
      const cv::Rect r(static_cast<int>(m.u_px) - 80, static_cast<int>(m.v_px) - 80, 160, 160);
      roi = roi.empty() ? r : (roi | r);
    }
  }
  roi &= cv::Rect(0, 0, cam.width_px(), h);
  cv::Mat image = renders.back().clone();
  for (int r = roi.y; r < roi.y + roi.height; ++r) {
    const double read_s = t0_s + r * row_s;
    cv::Mat1f sum = cv::Mat1f::zeros(1, roi.width * 3);
    int count = 0;
    for (int j = 0; j < n; ++j) {
      if (times[j] < read_s - timing.exposure_s || times[j] >= read_s) continue;
      cv::Mat row_f;
      renders[j].row(r).colRange(roi.x, roi.x + roi.width).reshape(1, 1).convertTo(row_f, CV_32F);
      sum += row_f;
      ++count;
    }
    sum /= std::max(count, 1);
    cv::Mat row_u8;
    sum.convertTo(row_u8, CV_8U);
    row_u8.reshape(3, 1).copyTo(image.row(r).colRange(roi.x, roi.x + roi.width));
  }
  std::vector<uint8_t> jpeg;
  cv::imencode(".jpg", image, jpeg, {cv::IMWRITE_JPEG_QUALITY, 90});
  camera::Frame frame;
  frame.seq = seq;
  frame.capture_utime = kStartUtime + std::llround((last_s + timing.latency_s) * 1e6);
  std::string error;
  frame.image = camera::MakeJpegImage(std::move(jpeg), &error);
  EXPECT_NE(frame.image, nullptr) << error;
  return frame;
}

// Issue 17: each pose's utime is its position marker's own row time. A robot
// on the reference circle (about 18 cm/s) under a 30 ms rolling readout,
// 16 ms exposure and 40 ms latency: at the stated utime the pose is where the
// robot was; at the frame's capture time it would be 0.18 m/s x (40 + 8 +
// up to 30 ms) away.
TEST_F(CameraNodeTest, RollingShutterPoseIsWhereTheRobotWasAtItsStatedUtime) {
  camera_.readout_s = 0.030;
  camera_.exposure_s = 0.016;
  camera_.timestamp_latency_s = 0.040;
  calib::CameraTiming timing;
  timing.readout_s = camera_.readout_s;
  timing.exposure_s = camera_.exposure_s;
  timing.latency_s = camera_.timestamp_latency_s;
  timing.height_px = camera_.height_px;
  sim::SimScenario scenario;
  std::string error;
  ASSERT_TRUE(sim::ParseSimScenario("clean", &scenario, &error)) << error;
  const sim::SyntheticCamera cam(site_, camera_, lens_, scenario);
  calib::Calibration calibration;
  calibration.model = calib::Calibration::Model::kFull;
  calibration.camera = lens_;
  LoopbackBus bus;
  std::vector<pose2d_t> poses;
  bus.Subscribe<pose2d_t>(kCameraPoseChannel,
                          [&](const pose2d_t& p, const MessageInfo&) { poses.push_back(p); });
  CameraNode node(site_, camera_, calibration, &bus, CameraNodeOptions{}, kStartUtime);
  ASSERT_TRUE(node.ok(&error)) << error;
  // 1 ms sub-steps: a row's exposure is known to 0.5 ms, 0.1 mm at 18 cm/s.
  constexpr double kStepS = 0.001;
  constexpr int kFrames = 24;
  for (int k = 0; k < kFrames; ++k) {
    camera::Frame frame = RollingShutterFrame(cam, k, 2.0 + k / camera_.fps, timing, kStepS);
    node.OnFrame(&frame, frame.capture_utime + 1000);
  }
  ASSERT_EQ(poses.size(), static_cast<size_t>(kFrames));
  double sum2 = 0.0, sum2_capture = 0.0, head2 = 0.0;
  int found = 0;
  for (int k = 0; k < kFrames; ++k) {
    const pose2d_t& p = poses[static_cast<size_t>(k)];
    ASSERT_NE(p.status, pose2d_t::STATUS_LOST) << k;
    const sim::RobotState at_utime = cam.SimulatedRobots((p.utime - kStartUtime) * 1e-6).front();
    const double capture_s =
        2.0 + k / camera_.fps + timing.readout_s * 1079.0 / 1080.0 + timing.latency_s;
    const sim::RobotState at_capture = cam.SimulatedRobots(capture_s).front();
    sum2 += std::pow(p.x_m - at_utime.x_m, 2) + std::pow(p.y_m - at_utime.y_m, 2);
    sum2_capture += std::pow(p.x_m - at_capture.x_m, 2) + std::pow(p.y_m - at_capture.y_m, 2);
    head2 += std::pow(std::remainder(p.heading_rad - at_utime.heading_rad, 2 * M_PI), 2);
    ++found;
  }
  const double rmse_m = std::sqrt(sum2 / found);
  const double rmse_capture_m = std::sqrt(sum2_capture / found);
  const double heading_rmse_rad = std::sqrt(head2 / found);
  std::printf(
      "rolling shutter: RMSE %.2f mm at the stated utime, %.2f mm at the capture time, "
      "heading %.2f mrad\n",
      rmse_m * 1e3, rmse_capture_m * 1e3, heading_rmse_rad * 1e3);
  // The clean pipeline's 0.1 mm on the circle plus the 1 ms sub-steps' time
  // quantisation and the streak's JPEG edges: measured 0.13 mm.
  constexpr double kStatedTimeRmseM = 0.00013 * kMargin;
  EXPECT_LT(rmse_m, kStatedTimeRmseM);
  // Stamped with the capture time the same poses are a centimetre off.
  EXPECT_GT(rmse_capture_m, 0.008);
  EXPECT_LT(heading_rmse_rad, kHeadingRmseRad);
}

TEST_F(CameraNodeTest, RecordedMarkerPixelsGiveTheLivePosesBitForBit) {
  hint_sigma_m_ = 0.03;  // Resolves the look-alike, so the robot is tracked.
  const PipelineRun live = RunFrames("harsh", 120);
  ASSERT_EQ(live.pixels.size(), 120u);
  ASSERT_EQ(live.poses.size(), 120u);
  int windows = 0;
  for (const marker_pixels_t& m : live.pixels) {
    windows += m.search_mode == marker_pixels_t::SEARCH_REGION_OF_INTEREST;
  }
  EXPECT_GT(windows, 60) << "the run must exercise the tracking windows";

  calib::Calibration c;
  c.model = calib::Calibration::Model::kFull;
  c.camera = lens_;
  LoopbackBus bus;
  std::vector<pose2d_t> poses;
  int pixels_published = 0;
  bus.Subscribe<pose2d_t>(kCameraPoseChannel,
                          [&](const pose2d_t& p, const MessageInfo&) { poses.push_back(p); });
  bus.Subscribe<marker_pixels_t>(
      kMarkerPixelsChannel,
      [&](const marker_pixels_t&, const MessageInfo&) { ++pixels_published; });
  CameraNode node(site_, camera_, c, &bus, CameraNodeOptions{}, kStartUtime);
  std::string error;
  ASSERT_TRUE(node.ok(&error)) << error;
  // The hints in the order the live node heard them, before their frame.
  size_t next_hint = 0;
  for (size_t i = 0; i < live.pixels.size(); ++i) {
    for (; next_hint < live.hints.size() && live.hints[next_hint].first == i; ++next_hint) {
      bus.set_now_utime(live.hints[next_hint].second.utime + 5'000);
      bus.Publish("POSE_ULTRASOUND", live.hints[next_hint].second);
    }
    node.OnMarkerPixels(live.pixels[i], live.pixels[i].utime + 1000);
  }

  EXPECT_EQ(pixels_published, 0) << "the recorded pixels are the input, not republished";
  ASSERT_EQ(poses.size(), live.poses.size());
  int found = 0;
  for (size_t i = 0; i < poses.size(); ++i) {
    std::vector<uint8_t> a(static_cast<size_t>(poses[i].getEncodedSize()));
    std::vector<uint8_t> b(static_cast<size_t>(live.poses[i].getEncodedSize()));
    poses[i].encode(a.data(), 0, static_cast<int>(a.size()));
    live.poses[i].encode(b.data(), 0, static_cast<int>(b.size()));
    EXPECT_EQ(a, b) << "pose " << i << " (frame " << live.poses[i].measurement_seq << ")";
    found += poses[i].status != pose2d_t::STATUS_LOST;
  }
  EXPECT_GT(found, 100);
  EXPECT_EQ(node.status().counter("search_mode_differs"), 0) << "the trackers planned alike";
  EXPECT_EQ(node.status().counter("hints"), live.node->status().counter("hints"));
}

// Recorded pixels are outside input: a marker of a class the site lacks or
// with a centre that is not a number is refused and counted, the frame's
// good marker still tracked; pixels for another image size are refused.
TEST_F(CameraNodeTest, BadRecordedMarkerPixelsAreCountedNotTracked) {
  const PipelineRun live = RunFrames("clean", 3);
  ASSERT_EQ(live.pixels.size(), 3u);
  ASSERT_NE(live.poses.back().status, pose2d_t::STATUS_LOST);
  calib::Calibration c;
  c.model = calib::Calibration::Model::kFull;
  c.camera = lens_;
  LoopbackBus bus;
  std::vector<pose2d_t> poses;
  bus.Subscribe<pose2d_t>(kCameraPoseChannel,
                          [&](const pose2d_t& p, const MessageInfo&) { poses.push_back(p); });
  CameraNode node(site_, camera_, c, &bus, CameraNodeOptions{}, kStartUtime);
  marker_pixels_t bad = live.pixels[0];
  marker_t nan_marker = bad.markers.front();
  nan_marker.u_px = std::numeric_limits<double>::quiet_NaN();
  marker_t unknown = bad.markers.front();
  unknown.colour_class = "ultraviolet";
  bad.markers.push_back(nan_marker);
  bad.markers.push_back(unknown);
  bad.num_markers = static_cast<int32_t>(bad.markers.size());
  node.OnMarkerPixels(bad, bad.utime);
  marker_pixels_t wrong_size = live.pixels[1];
  wrong_size.width_px /= 2;
  node.OnMarkerPixels(wrong_size, wrong_size.utime);
  node.OnMarkerPixels(live.pixels[2], live.pixels[2].utime);
  EXPECT_EQ(node.status().rejected("non_finite_marker"), 1);
  EXPECT_EQ(node.status().rejected("unknown_marker_class"), 1);
  EXPECT_EQ(node.status().rejected("wrong_frame_size"), 1);
  ASSERT_EQ(poses.size(), 2u);  // Frames 0 and 2.
  EXPECT_NE(poses[0].status, pose2d_t::STATUS_LOST);
  EXPECT_EQ(poses[1].x_m, live.poses[2].x_m);
}

// The bus must not call into a destroyed node: its hint handler captures
// `this`. (Junk bytes: delivered to the handler, refused before the node's
// code.)
TEST_F(CameraNodeTest, ADestroyedNodeReceivesNoMoreHints) {
  LoopbackBus bus;
  calib::Calibration c;
  c.model = calib::Calibration::Model::kFull;
  c.camera = lens_;
  const uint8_t junk[3] = {1, 2, 3};
  {
    CameraNode node(site_, camera_, c, &bus, CameraNodeOptions(), kStartUtime);
    bus.Inject("POSE_ULTRASOUND", junk, sizeof(junk), kStartUtime);
    EXPECT_EQ(bus.stats().received, 1);
  }
  bus.Inject("POSE_ULTRASOUND", junk, sizeof(junk), kStartUtime + 1);
  EXPECT_EQ(bus.stats().received, 1) << "delivered to a destroyed node";
}

}  // namespace
}  // namespace roomfix
