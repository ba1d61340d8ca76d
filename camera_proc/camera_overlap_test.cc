// Several cameras (issue 19): a robot in the overlap of two ceiling cameras
// is seen by both, consistently. Each camera of config/sites/two_cameras.yaml
// renders the robot through its true lens (the synthetic camera's, which the
// site's calibration files were fitted to with roomfix calibrate: camera 0
// from the tripod procedure, camera 1 from its own tripod points plus the
// marker images it shares with camera 0), and each camera's own CameraNode
// (one camera_proc per camera) detects and maps it with its calibration.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "camera_proc/camera_node.h"
#include "core/calib/calibration_file.h"
#include "core/world/site.h"
#include "core/world/trajectory.h"
#include "roomfix/pose2d_t.hpp"
#include "sim/sim_frame_source.h"
#include "sim/synthetic_camera.h"
#include "tests/testing/test_paths.h"

namespace roomfix {
namespace {

constexpr int64_t kStartUtime = 1'700'000'000'000'000;
constexpr int kFrames = 10;
// The condition: the cameras' calibrations agree to a few
// millimetres in the overlap. Each calibration maps to about 1 mm of the
// truth over its tripod points (the calibration files' headers), and a
// marker at the edge of an image is seen through the most distorted part of
// the lens, so two independent errors of up to about 1.5 mm: 3 mm.
constexpr double kMaxDisagreementM = 0.003;

struct MeanPose {
  double x_m = 0.0;
  double y_m = 0.0;
  int poses = 0;
};

// The mean of robot 1's poses from one camera's node over kFrames frames,
// checking that every pose names the camera.
MeanPose SeenBy(const Site& site, const Camera& camera) {
  MeanPose mean;
  std::string error;
  calib::Calibration calibration;
  EXPECT_TRUE(calib::LoadCalibration(camera.calibration_file, &calibration, &error)) << error;
  sim::SimScenario scenario;
  EXPECT_TRUE(sim::ParseSimScenario("clean", &scenario, &error));
  scenario.noise_sigma_dn = 2.0;
  auto render = std::make_shared<sim::SyntheticCamera>(
      site, camera,
      calib::NominalCamera(camera.mount_position_m, camera.field_of_view_deg, camera.width_px,
                           camera.height_px),
      scenario);
  sim::SimSourceOptions so;
  so.fps = camera.fps;
  so.start_utime = kStartUtime;
  so.realtime = false;
  sim::SimFrameSource source(render, so);
  LoopbackBus bus;
  std::vector<pose2d_t> poses;
  bus.Subscribe<pose2d_t>(kCameraPoseChannel,
                          [&](const pose2d_t& p, const MessageInfo&) { poses.push_back(p); });
  CameraNode node(site, camera, calibration, &bus, CameraNodeOptions{}, kStartUtime);
  for (int i = 0; i < kFrames; ++i) {
    camera::Frame frame;
    EXPECT_EQ(source.Read(&frame, &error), camera::ReadStatus::kFrame) << error;
    node.OnFrame(&frame, frame.capture_utime);
  }
  for (const pose2d_t& p : poses) {
    EXPECT_EQ(p.camera_id, camera.id);
    EXPECT_EQ(p.source, pose2d_t::SOURCE_CAMERA);
    if (p.robot_id != 1 || p.status == pose2d_t::STATUS_LOST) continue;
    mean.x_m += p.x_m;
    mean.y_m += p.y_m;
    ++mean.poses;
  }
  if (mean.poses > 0) {
    mean.x_m /= mean.poses;
    mean.y_m /= mean.poses;
  }
  return mean;
}

TEST(CameraOverlap, TwoCalibratedCamerasAgreeOnTheSameRobot) {
  Site site;
  std::string error;
  ASSERT_TRUE(LoadSite(testing::SourceDir() + "/config/sites/two_cameras.yaml", &site, &error))
      << error;
  ASSERT_EQ(site.cameras.size(), 2u);
  double worst_m = 0.0;
  // Across the overlap (x 3.5 .. 4.5 m at the marker height), edge to edge
  // in y.
  for (const auto& [x, y] : std::vector<std::pair<double, double>>{
           {3.75, 1.5}, {4.0, 0.6}, {4.0, 1.5}, {4.0, 2.4}, {4.25, 1.5}, {3.8, 2.2}, {4.2, 0.8}}) {
    StaticTrajectoryOptions o;
    o.x_m = x;
    o.y_m = y;
    o.heading_rad = 0.5;
    for (SimulatedRobot& robot : site.simulation.robots) {
      if (robot.robot_id == 1) robot.trajectory = MakeStaticTrajectory(o, &error);
    }
    const MeanPose a = SeenBy(site, *site.FindCamera(0));
    const MeanPose b = SeenBy(site, *site.FindCamera(1));
    ASSERT_EQ(a.poses, kFrames) << "camera 0 lost the robot at " << x << ", " << y;
    ASSERT_EQ(b.poses, kFrames) << "camera 1 lost the robot at " << x << ", " << y;
    const double apart_m = std::hypot(a.x_m - b.x_m, a.y_m - b.y_m);
    std::printf(
        "robot at (%.2f, %.2f): camera 0 (%.4f, %.4f), camera 1 (%.4f, %.4f): %.2f mm apart, "
        "errors %.2f / %.2f mm\n",
        x, y, a.x_m, a.y_m, b.x_m, b.y_m, apart_m * 1e3, std::hypot(a.x_m - x, a.y_m - y) * 1e3,
        std::hypot(b.x_m - x, b.y_m - y) * 1e3);
    worst_m = std::max(worst_m, apart_m);
    EXPECT_LT(apart_m, kMaxDisagreementM) << "at " << x << ", " << y;
  }
  std::printf("two cameras' disagreement in the overlap: worst %.2f mm\n", worst_m * 1e3);
}

}  // namespace
}  // namespace roomfix
