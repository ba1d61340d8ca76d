#include "sim/sim_camera_source.h"

#include <gtest/gtest.h>

#include <chrono>
#include <cstdio>
#include <string>
#include <thread>

#include "msgio/process.h"
#include "roomfix/process_status_t.hpp"
#include "sim/synthetic_camera.h"
#include "tests/testing/demo_site_test_fixture.h"
#include "tests/testing/test_paths.h"

namespace roomfix {
namespace {

using SimCameraSourceTest = testing::DemoSiteTest;

TEST_F(SimCameraSourceTest, ChecksASyntheticSourceWithoutBuildingIt) {
  CameraSourceOptions options;
  SimCameraOptions sim_options;
  options.calibration_path = "none";
  CameraChoice choice;
  std::string error;
  ASSERT_TRUE(ChooseCamera(site_, options, &choice, &error)) << error;
  std::unique_ptr<camera::FrameSource> source;
  std::string summary;
  ASSERT_TRUE(MakeCameraSource(site_, choice, options, sim_options, /*start_utime=*/1,
                               /*check_only=*/true, &source, &summary, &error))
      << error;
  EXPECT_EQ(source, nullptr);
  EXPECT_EQ(summary, "camera " + std::to_string(choice.camera.id) + ", synthetic webcam, " +
                         std::to_string(choice.camera.robots.size()) + " robots, pixels only");

  choice.device = "sim:no_such_scenario";
  EXPECT_FALSE(MakeCameraSource(site_, choice, options, sim_options, 1, /*check_only=*/true,
                                &source, &summary, &error));
  EXPECT_NE(error.find("no_such_scenario"), std::string::npos) << error;
}

// Issue #32: sim_demo.pmd ran the site's sim:webcam with the site's
// calibration, which was fitted to the nominal lens; the webcam renders
// through its own (principal point 6, -4 px off, k1 + 0.03), so every pose
// on the reference circle was 2.3 cm off. camera_proc now says so before
// the first frame.
TEST_F(SimCameraSourceTest, FindsASyntheticCamerasCalibrationOfAnotherLens) {
  // The nominal lens's calibration against the webcam's lens over the
  // floor: 7.2 px of principal point at 3.2 mm/px in the middle, growing
  // towards the walls where k1 adds: 29.8 mm RMS, 82.6 mm at most (camera_proc --check).
  constexpr double kNominalRmsAtLeastM = 0.020;
  // demo_room_webcam.yaml is a fit to the webcam's own images (0.07 mm RMS
  // over its 35 points) that also absorbs the disc centroid's perspective
  // bias; over the whole floor, corners it had no points in included,
  // measured 1.81 mm RMS (2.56 mm at most).
  constexpr double kWebcamFitRmsWithinM = 0.0025;
  CameraSourceOptions options;
  const SimCameraOptions sim_options;
  CameraChoice choice;
  std::string error;
  ASSERT_TRUE(ChooseCamera(site_, options, &choice, &error)) << error;
  ASSERT_EQ(choice.device, "sim:webcam");
  const std::string mismatch = SimCalibrationMismatch(site_, choice, sim_options);
  EXPECT_NE(mismatch.find("demo_room_camera.yaml is not the lens sim:webcam renders through"),
            std::string::npos)
      << mismatch;

  sim::SimScenario webcam;
  ASSERT_TRUE(sim::ParseSimScenario("sim:webcam", site_, &webcam, &error)) << error;
  const calib::CameraModel truth = sim::TruthLens(
      calib::NominalCamera(choice.camera.mount_position_m, choice.camera.field_of_view_deg,
                           choice.camera.width_px, choice.camera.height_px),
      webcam);
  const double height_m = choice.camera.robots.front().marker_height_m;
  const CalibrationError nominal =
      CalibrationErrorOverRoom(truth, *choice.calibration, site_.room, height_m);
  std::printf("the site's calibration against the webcam's lens: %.1f mm RMS, %.1f mm max\n",
              nominal.rms_m * 1e3, nominal.max_m * 1e3);
  EXPECT_GT(nominal.points, 1000);
  EXPECT_GT(nominal.rms_m, kNominalRmsAtLeastM);

  options.calibration_path = testing::SourceDir() + "/config/calibration/demo_room_webcam.yaml";
  ASSERT_TRUE(ChooseCamera(site_, options, &choice, &error)) << error;
  EXPECT_EQ(SimCalibrationMismatch(site_, choice, sim_options), "");
  const CalibrationError fitted =
      CalibrationErrorOverRoom(truth, *choice.calibration, site_.room, height_m);
  std::printf("demo_room_webcam.yaml against the webcam's lens: %.2f mm RMS, %.2f mm max\n",
              fitted.rms_m * 1e3, fitted.max_m * 1e3);
  EXPECT_EQ(fitted.points, nominal.points);
  EXPECT_LT(fitted.rms_m, kWebcamFitRmsWithinM);

  // The clean scenarios render through the nominal lens, which the site's
  // calibration was fitted to; a real device is never checked.
  options.calibration_path.clear();
  options.device = "sim:reference_circle";
  ASSERT_TRUE(ChooseCamera(site_, options, &choice, &error)) << error;
  EXPECT_EQ(SimCalibrationMismatch(site_, choice, sim_options), "");
  options.device = "/dev/video7";
  ASSERT_TRUE(ChooseCamera(site_, options, &choice, &error)) << error;
  EXPECT_EQ(SimCalibrationMismatch(site_, choice, sim_options), "");
}

// roomfix_sim's t = 0 is its STATUS time minus its uptime; other processes'
// heartbeats are not its clock.
TEST(WaitForSimClock, TakesRoomfixSimsStartFromItsHeartbeat) {
  std::string error;
  auto bus = OpenBus("memq://", &error);
  ASSERT_NE(bus, nullptr) << error;
  process_status_t other{};
  other.process = "trilat_proc";
  other.utime = 5'000'000;
  other.uptime_us = 1'000'000;
  process_status_t sim{};
  sim.process = "roomfix_sim";
  sim.utime = 1'700'000'010'000'000;
  sim.uptime_us = 10'000'000;
  // Published once the wait has subscribed, as a heartbeat comes.
  std::thread heartbeats([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    bus->Publish(kStatusChannel, other);
    bus->Publish(kStatusChannel, sim);
  });
  const int64_t start_utime = WaitForSimClock(bus.get(), 5.0);
  heartbeats.join();
  EXPECT_EQ(start_utime, 1'700'000'000'000'000);
}

TEST(WaitForSimClock, GivesZeroWhenNoSimulatorIsHeard) {
  std::string error;
  auto bus = OpenBus("memq://", &error);
  ASSERT_NE(bus, nullptr) << error;
  EXPECT_EQ(WaitForSimClock(bus.get(), 0.2), 0);
}

TEST(SimCameraOptions, RefusesAQualityOrWaitOutOfRange) {
  SimCameraOptions options;
  std::string error;
  EXPECT_TRUE(options.IsValid(&error)) << error;
  options.jpeg_quality = 101;
  EXPECT_FALSE(options.IsValid(&error));
  options = SimCameraOptions{};
  options.wait_s = -1.0;
  EXPECT_FALSE(options.IsValid(&error));
  EXPECT_NE(error.find("wait"), std::string::npos) << error;
}

}  // namespace
}  // namespace roomfix
