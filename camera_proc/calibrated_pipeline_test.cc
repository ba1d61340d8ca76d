// The calibration issue's pipeline target, end to end in one process with
// every real component: the synthetic camera renders the reference's tripod
// images through a lens the test knows but the fit does not, the marker
// detector finds the marker in each, the camera model is fitted to those
// points, and camera_proc's node then tracks a robot on frames rendered
// through the same lens, mapping with the fitted calibration.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <memory>
#include <opencv2/imgcodecs.hpp>
#include <random>
#include <vector>

#include "camera_proc/camera_node.h"
#include "core/analysis/fix_quality.h"
#include "core/calib/calibration_file.h"
#include "core/calib/camera_fit.h"
#include "core/calib/marker_projection.h"
#include "core/vision/marker_detector.h"
#include "roomfix/pose2d_t.hpp"
#include "sim/sim_frame_source.h"
#include "sim/synthetic_camera.h"
#include "tests/testing/demo_site.h"
#include "tests/testing/test_paths.h"

namespace roomfix {
namespace {

constexpr double kStaticRmseM = 0.003;
constexpr double kCircleRmseM = 0.005;
// The calibration condition: pixel noise of 0.3 px on the points.
constexpr double kPointNoisePx = 0.3;
constexpr int64_t kStartUtime = 1'700'000'000'000'000;

class CalibratedPipelineTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string error;
    ASSERT_TRUE(LoadSite(testing::DemoSitePath(), &site_, &error)) << error;
    camera_ = site_.cameras.front();
    webcam_camera_ = camera_;
    // The demo site's camera is a webcam; the `clean` tests render an ideal
    // camera, exposed at once and stamped exactly, on a robot that does not
    // rock.
    camera_.readout_s = camera_.exposure_s = camera_.timestamp_latency_s = 0.0;
    for (CameraRobot& r : camera_.robots) r.tilt_sigma_deg = 0.0;
    // The true lens: a real fisheye's distortion, an off-centre principal
    // point, a 0.3 degree tilt and a mount 3 mm from where it was measured.
    truth_ = calib::NominalCamera(camera_.mount_position_m, camera_.field_of_view_deg,
                                  camera_.width_px, camera_.height_px);
    truth_.intrinsics.fx_px *= 0.98;
    truth_.intrinsics.fy_px = truth_.intrinsics.fx_px;
    truth_.intrinsics.k = {0.02, -0.006, 0.0, 0.0};
    truth_.intrinsics.cx_px += 7.0;
    truth_.intrinsics.cy_px -= 5.0;
    truth_.pose.R_room_from_camera =
        truth_.pose.R_room_from_camera *
        Eigen::AngleAxisd(0.005, Eigen::Vector3d(1, 0.5, 0).normalized()).toRotationMatrix();
    truth_.pose.position_m += Eigen::Vector3d(0.002, -0.002, 0.001);
  }

  // The reference's procedure: a marker on a tripod at the 0.5 m grid points,
  // one image each, the marker found automatically.
  // point_noise_px is added to each found pixel (0: the detector's own
  // noise only, as the demo's calibration was made).
  // as_frames: each image goes through the JPEG encoding the camera's
  // frames get (sim::SimSourceOptions::jpeg_quality), as tripod images
  // taken with the camera itself would.
  calib::Calibration CalibrateFromTripodImages(double point_noise_px = kPointNoisePx,
                                               bool as_frames = false,
                                               const std::string& scenario_name = "clean") {
    sim::SimScenario scenario;
    std::string error;
    EXPECT_TRUE(sim::ParseSimScenario(scenario_name, site_, &scenario, &error));
    if (scenario_name == "clean") scenario.noise_sigma_dn = 2.0;
    const sim::SyntheticCamera render(site_, camera_, truth_, scenario);
    const CameraRobot& robot = camera_.robots.front();
    vision::ColourClass orange;
    for (const MarkerClass& mc : camera_.marker_classes) {
      if (mc.name == robot.position_marker) {
        orange.name = mc.name;
        orange.hsv_min = mc.hsv_min;
        orange.hsv_max = mc.hsv_max;
      }
    }
    const vision::MarkerDetector detector({orange}, vision::DetectorOptions{});
    // The marker's disc: the fit maps its centre, as roomfix calibrate does.
    const double marker_radius_m = PositionMarkerDiameterM(camera_, robot) / 2.0;
    std::mt19937 rng(3);
    std::normal_distribution<double> noise(0.0, 1.0);
    std::vector<calib::Correspondence> points;
    int seq = 0;
    for (double x = 0.5; x < 3.6; x += 1.0) {
      for (double y = 0.5; y < 2.6; y += 0.5) {
        cv::Mat image;
        render.Render(0.0, seq++, {sim::RobotState{robot.robot_id, x, y, 0.0}}, &image);
        if (as_frames) {
          // The camera's own JPEG (the webcam scenario's MJPEG quality).
          std::vector<uint8_t> jpeg;
          EXPECT_TRUE(render.Encode(image, sim::SimSourceOptions{}.jpeg_quality, &jpeg));
          image = cv::imdecode(jpeg, cv::IMREAD_COLOR);
        }
        const std::vector<vision::Blob> blobs = detector.Detect(image, vision::ImageWindow{});
        EXPECT_EQ(blobs.size(), 1u) << "marker at " << x << ", " << y;
        if (blobs.size() != 1) continue;
        const double du = point_noise_px * noise(rng), dv = point_noise_px * noise(rng);
        points.push_back(
            {blobs[0].u_px + du, blobs[0].v_px + dv, x, y, robot.marker_height_m, marker_radius_m});
      }
    }
    calib::CameraFitOptions options;
    options.equal_focal_lengths = true;
    options.distortion_terms = 2;
    options.position_prior_sigma_m = 0.005;
    options.pixel_sigma_px = kPointNoisePx;
    const calib::CameraModel initial = calib::NominalCamera(
        camera_.mount_position_m, camera_.field_of_view_deg, camera_.width_px, camera_.height_px);
    const calib::CameraFitSummary fit = calib::FitCameraToMarkers(points, initial, options);
    EXPECT_TRUE(fit.usable) << fit.message;
    std::printf("tripod calibration: %zu points, %.3f px RMS\n", points.size(), fit.rms_px);
    calib::Calibration c;
    c.model = calib::Calibration::Model::kFull;
    c.camera = fit.model;
    c.fit_rms_px = fit.rms_px;
    // As roomfix calibrate writes it: one focal length, the principal
    // point, k1, k2, rotation and position.
    c.pixel_sigma_px = calib::PixelSigmaFromFit(fit.rms_px, static_cast<int>(points.size()), 11);
    return c;
  }

  // The RMS error of the node's poses over `frames` frames; with
  // `inside_95`, also the share of errors inside each pose's own 95 %
  // covariance ellipse.
  // Each pose is judged against the robot where it was at the pose's own
  // utime (its marker's row time; the capture time for an ideal camera).
  double RmseOnFrames(const calib::Calibration& calibration, int frames,
                      double* inside_95 = nullptr, const std::string& scenario_name = "clean",
                      int64_t* dropped = nullptr) {
    sim::SimScenario scenario;
    std::string error;
    EXPECT_TRUE(sim::ParseSimScenario(scenario_name, site_, &scenario, &error));
    if (scenario_name == "clean") scenario.noise_sigma_dn = 2.0;
    auto render = std::make_shared<sim::SyntheticCamera>(site_, camera_, truth_, scenario);
    sim::SimSourceOptions so;
    so.fps = camera_.fps;
    so.start_utime = kStartUtime;
    so.realtime = false;
    sim::SimFrameSource source(render, so);
    LoopbackBus bus;
    std::vector<pose2d_t> poses;
    bus.Subscribe<pose2d_t>(kCameraPoseChannel,
                            [&](const pose2d_t& p, const MessageInfo&) { poses.push_back(p); });
    CameraNodeOptions node_options;
    if (use_device_timing_) node_options.device_timing = source.device_timing();
    CameraNode node(site_, camera_, calibration, &bus, node_options, kStartUtime);
    node_timing_ = node.timing();
    double sum2 = 0.0;
    int n = 0;
    int inside = 0;
    for (int i = 0; i < frames; ++i) {
      camera::Frame frame;
      EXPECT_EQ(source.Read(&frame, &error), camera::ReadStatus::kFrame);
      poses.clear();
      node.OnFrame(&frame, frame.capture_utime);
      EXPECT_EQ(poses.size(), 1u);
      if (poses.empty() || poses[0].status == pose2d_t::STATUS_LOST) continue;
      if (!scenario.webcam_effects) {
        EXPECT_EQ(poses[0].utime, frame.capture_utime);
      }
      const pose2d_t& p = poses[0];
      const sim::RobotState truth = render->SimulatedRobots((p.utime - kStartUtime) * 1e-6).front();
      sum2 += std::pow(p.x_m - truth.x_m, 2) + std::pow(p.y_m - truth.y_m, 2);
      const double d2 = analysis::SquaredMahalanobis2D(
          p.x_m - truth.x_m, p.y_m - truth.y_m, p.covariance[0][0],
          0.5 * (p.covariance[0][1] + p.covariance[1][0]), p.covariance[1][1]);
      inside += d2 <= analysis::Chi2Quantile2Dof(0.95) ? 1 : 0;
      ++n;
    }
    EXPECT_EQ(n, frames);
    if (dropped != nullptr) *dropped = node.status().dropped();
    if (inside_95 != nullptr) *inside_95 = static_cast<double>(inside) / std::max(1, n);
    return std::sqrt(sum2 / std::max(1, n));
  }

  Site site_;
  Camera camera_;
  // The site's camera as it is: the webcam's timing and the robot's tilt.
  Camera webcam_camera_;
  calib::CameraModel truth_;
  // Give the node the frame source's own timing, as camera_proc does.
  bool use_device_timing_ = false;
  // The timing the last RmseOnFrames's node used.
  calib::CameraTiming node_timing_;
};

TEST_F(CalibratedPipelineTest, StaticRobotWithinThreeMillimetres) {
  const calib::Calibration calibration = CalibrateFromTripodImages();
  for (const auto& [x, y] :
       std::vector<std::pair<double, double>>{{2.0, 1.5}, {0.7, 0.6}, {3.3, 2.4}, {1.2, 2.5}}) {
    StaticTrajectoryOptions o;
    o.x_m = x;
    o.y_m = y;
    o.heading_rad = 1.0;
    std::string error;
    site_.simulation.robots.front().trajectory = MakeStaticTrajectory(o, &error);
    const double rmse = RmseOnFrames(calibration, 20);
    std::printf("static robot at (%.1f, %.1f): %.2f mm RMS\n", x, y, rmse * 1e3);
    EXPECT_LT(rmse, kStaticRmseM);
  }
}

TEST_F(CalibratedPipelineTest, ReferenceCircleWithinFiveMillimetres) {
  // The demo site's robot drives the reference circle (r 41.9 cm at
  // 0.439 rad/s: 18.4 cm/s); poses are stamped with the capture time.
  const calib::Calibration calibration = CalibrateFromTripodImages();
  const double rmse = RmseOnFrames(calibration, 300);
  std::printf("reference circle: %.2f mm RMS over 300 frames\n", rmse * 1e3);
  EXPECT_LT(rmse, kCircleRmseM);
}

TEST_F(CalibratedPipelineTest, PoseCovarianceCoversNinetyFivePercentOfTheErrorsOnTheCircle) {
  // The calibration made as the demo's was (the marker found in each tripod
  // image, no noise added) states its pixel error, pixel_sigma_px: the
  // detector's centroid noise measured by the fit's residual plus the
  // fitted model's own error. Through the mapping's Jacobian that is each
  // pose's covariance; on the reference circle the errors against the
  // simulator's truth must fill it as a Gaussian would: 95 % inside the 95 %
  // ellipse. 300 poses: the binomial standard deviation of the share is
  // 1.3 %, and the errors of neighbouring frames share the calibration's
  // error at that place (fewer independent samples), so the band
  // 90-98 % is the tolerance.
  constexpr double kCoverageLow = 0.90;
  constexpr double kCoverageHigh = 0.98;
  const calib::Calibration calibration =
      CalibrateFromTripodImages(/*point_noise_px=*/0.0, /*as_frames=*/true);
  ASSERT_GT(calibration.pixel_sigma_px, 0.0);
  double inside_95 = 0.0;
  const double rmse = RmseOnFrames(calibration, 300, &inside_95);
  std::printf(
      "tripod fit %.4f px RMS -> pixel sigma %.4f px; circle: %.3f mm RMS, %.1f %% inside "
      "the own 95 %% ellipse\n",
      calibration.fit_rms_px, calibration.pixel_sigma_px, rmse * 1e3, inside_95 * 100.0);
  EXPECT_GE(inside_95, kCoverageLow);
  EXPECT_LE(inside_95, kCoverageHigh);
}

TEST_F(CalibratedPipelineTest, ARobotsOwnPixelSigmaSetsItsCovariance) {
  // robot_pixel_sigma_px (calibration_file.h) replaces the fit's figure for
  // that robot only: a quarter of the figure shrinks the ellipse's radius 4
  // times over the same errors, so a pose that was inside at d^2 <= 5.99 is
  // now inside only at d^2 <= 0.37, where a Gaussian error lies 17 % of the
  // time (under half, with room for the circle's correlated errors); a
  // figure for a robot the camera does not have changes nothing at all.
  constexpr double kShrunkCoverageAtMost = 0.5;
  constexpr int kFrames = 100;
  calib::Calibration calibration =
      CalibrateFromTripodImages(/*point_noise_px=*/0.0, /*as_frames=*/true);
  double as_fitted = 0.0, shrunk = 0.0, other_robot = 0.0;
  RmseOnFrames(calibration, kFrames, &as_fitted);
  calibration.robot_pixel_sigma_px[camera_.robots.front().robot_id + 100] = 1e-6;
  RmseOnFrames(calibration, kFrames, &other_robot);
  calibration.robot_pixel_sigma_px[camera_.robots.front().robot_id] =
      calibration.pixel_sigma_px / 4.0;
  RmseOnFrames(calibration, kFrames, &shrunk);
  std::printf(
      "inside the 95 %% ellipse: as fitted %.2f, another robot's figure %.2f, a quarter "
      "of the figure %.2f\n",
      as_fitted, other_robot, shrunk);
  EXPECT_EQ(other_robot, as_fitted);
  EXPECT_LT(shrunk, kShrunkCoverageAtMost);
}

// Issue 17's targets on the simulated webcam (the demo site's `webcam`
// scenario: lens blur, vignetting, the lens's own distortion, 15.6 ms
// exposure, 30 ms rolling readout, shot and read noise, sRGB, Bayer,
// MJPEG q80, AE/WB drift, a rocking robot, worn markers, 5 ms latency and
// jitter), calibrated from tripod images taken by that webcam: static robot
// at most 3 mm RMS, the reference circle at most 5 mm RMS, no frame
// dropped on the virtual clock, and 90-98 % of the errors inside each
// pose's own 95 % ellipse. Poses are judged at their own utime.
class WebcamPipelineTest : public CalibratedPipelineTest {
 protected:
  void SetUp() override {
    CalibratedPipelineTest::SetUp();
    camera_ = webcam_camera_;
  }
};

constexpr double kCoverageLow = 0.90;
constexpr double kCoverageHigh = 0.98;

TEST_F(WebcamPipelineTest, StaticRobotWithinThreeMillimetres) {
  const calib::Calibration calibration =
      CalibrateFromTripodImages(/*point_noise_px=*/0.0, /*as_frames=*/true, "webcam");
  std::printf("webcam tripod fit %.4f px RMS -> pixel sigma %.4f px\n", calibration.fit_rms_px,
              calibration.pixel_sigma_px);
  int inside = 0, n = 0;
  for (const auto& [x, y] :
       std::vector<std::pair<double, double>>{{2.0, 1.5}, {0.7, 0.6}, {3.3, 2.4}, {1.2, 2.5}}) {
    StaticTrajectoryOptions o;
    o.x_m = x;
    o.y_m = y;
    o.heading_rad = 1.0;
    std::string error;
    site_.simulation.robots.front().trajectory = MakeStaticTrajectory(o, &error);
    double inside_95 = 0.0;
    int64_t dropped = -1;
    const double rmse = RmseOnFrames(calibration, 30, &inside_95, "webcam", &dropped);
    std::printf("webcam static robot at (%.1f, %.1f): %.2f mm RMS, %.1f %% inside 95 %%\n", x, y,
                rmse * 1e3, inside_95 * 100.0);
    EXPECT_LT(rmse, kStaticRmseM);
    EXPECT_EQ(dropped, 0);
    inside += static_cast<int>(std::lround(inside_95 * 30));
    n += 30;
  }
  // A still robot's error is mostly one bias, its lean (0.5 degrees: 1.7 mm
  // at 20 cm), the same in every frame: the ellipse holds it or not, so the
  // share cannot be near 95 % for one robot. It must hold it: the stated
  // covariance is not too small.
  std::printf("webcam static: %.1f %% inside the own 95 %% ellipse\n", 100.0 * inside / n);
  EXPECT_GE(static_cast<double>(inside) / n, kCoverageLow);
}

TEST_F(WebcamPipelineTest, ReferenceCircleWithinFiveMillimetresAndCovered) {
  const calib::Calibration calibration =
      CalibrateFromTripodImages(/*point_noise_px=*/0.0, /*as_frames=*/true, "webcam");
  double inside_95 = 0.0;
  int64_t dropped = -1;
  const double rmse = RmseOnFrames(calibration, 300, &inside_95, "webcam", &dropped);
  std::printf("webcam reference circle: %.2f mm RMS over 300 frames, %.1f %% inside 95 %%\n",
              rmse * 1e3, inside_95 * 100.0);
  EXPECT_LT(rmse, kCircleRmseM);
  EXPECT_EQ(dropped, 0);
  EXPECT_GE(inside_95, kCoverageLow);
  EXPECT_LE(inside_95, kCoverageHigh);
}

}  // namespace
}  // namespace roomfix

namespace roomfix {
namespace {

// camera_proc run with a pinned synthetic device (--device sim:SCENARIO): the
// device decides the timing physics, whatever the site's camera says.
using DeviceTimingTest = CalibratedPipelineTest;

TEST_F(DeviceTimingTest, CleanSimDeviceOnTheWebcamSitePublishesPosesAtTheirTrueTimes) {
  // The demo site's camera states the webcam's 30 ms readout, 15.6 ms
  // exposure and 5 ms latency; the clean scenario exposes every row at the
  // frame's instant and stamps it exactly. With the site's figures the poses
  // would be dated about 28 ms early (5 mm at 18 cm/s).
  camera_ = webcam_camera_;
  for (CameraRobot& r : camera_.robots) r.tilt_sigma_deg = 0.0;
  ASSERT_GT(camera_.readout_s, 0.0);
  use_device_timing_ = true;
  const calib::Calibration calibration = CalibrateFromTripodImages();
  // RmseOnFrames asserts, for a scenario without webcam effects, that each
  // pose's utime is its frame's capture time.
  const double rmse = RmseOnFrames(calibration, 150);
  EXPECT_EQ(node_timing_.readout_s, 0.0);
  EXPECT_EQ(node_timing_.exposure_s, 0.0);
  EXPECT_EQ(node_timing_.latency_s, 0.0);
  EXPECT_EQ(node_timing_.height_px, camera_.height_px);
  std::printf("clean device on the webcam site: %.2f mm RMS\n", rmse * 1e3);
  EXPECT_LT(rmse, kCircleRmseM);
}

TEST_F(DeviceTimingTest, WebcamSimDeviceUsesTheWebcamsTimingOverASiteThatStatesNone) {
  // The fixture's camera_ states an ideal camera (all 0); the device renders
  // the webcam, whose rows are late by up to 30 ms: its figures must win.
  use_device_timing_ = true;
  const calib::Calibration calibration =
      CalibrateFromTripodImages(/*point_noise_px=*/0.0, /*as_frames=*/true, "webcam");
  const double rmse = RmseOnFrames(calibration, 90, nullptr, "webcam");
  const WebcamSimulation& w = site_.simulation.webcam;
  EXPECT_EQ(node_timing_.readout_s, w.readout_s);
  EXPECT_EQ(node_timing_.exposure_s, w.exposure_s);
  EXPECT_EQ(node_timing_.latency_s, w.timestamp_latency_s);
  ASSERT_GT(w.readout_s, 0.0);
  std::printf("webcam device on an ideal-camera site: %.2f mm RMS\n", rmse * 1e3);
  EXPECT_LT(rmse, kCircleRmseM);
}

}  // namespace
}  // namespace roomfix
