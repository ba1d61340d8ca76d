#include "camera_proc/sim_frame_source.h"

#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <string>

#include "core/calib/fisheye_camera.h"
#include "core/world/site.h"
#include "tests/testing/test_paths.h"

namespace roomfix::camera {
namespace {

// A small webcam in the demo room (320 x 180, the same lens angle), so that
// the frames are cheap.
std::shared_ptr<const sim::SyntheticCamera> SmallWebcam(sim::SimScenario* scenario) {
  Site site;
  std::string error;
  EXPECT_TRUE(LoadSite(testing::SourceDir() + "/config/sites/demo_room.yaml", &site, &error))
      << error;
  Camera camera = site.cameras.at(0);
  camera.width_px = 320;
  camera.height_px = 180;
  EXPECT_TRUE(sim::ParseSimScenario("sim:webcam", site, scenario, &error)) << error;
  return std::make_shared<const sim::SyntheticCamera>(
      site, camera, calib::NominalCamera(camera.mount_position_m, 120, 320, 180), *scenario);
}

TEST(SimFrameSource, WebcamFramesAreStampedAtTheLastRowsReadPlusLatency) {
  sim::SimScenario scenario;
  const auto webcam = SmallWebcam(&scenario);
  SimSourceOptions o;
  o.fps = 30.0;
  o.start_utime = 1'700'000'000'000'000;
  o.realtime = false;
  SimFrameSource source(webcam, o);
  std::string error;
  ASSERT_TRUE(source.Open(&error)) << error;
  EXPECT_NE(source.Describe().find("JPEG 80"), std::string::npos) << source.Describe();
  const WebcamSimulation& w = scenario.webcam;
  // t_read(H - 1) - t_read(0) + latency, and the jitter's bound (plus a
  // microsecond of rounding).
  const double nominal_us = 1e6 * (w.readout_s * 179.0 / 180.0 + w.timestamp_latency_s);
  const double bound_us = 1e6 * w.timestamp_jitter_s + 1.0;
  for (int64_t seq = 0; seq < 5; ++seq) {
    Frame frame;
    ASSERT_EQ(source.Read(&frame, &error), ReadStatus::kFrame) << error;
    EXPECT_EQ(frame.seq, seq);
    const double frame_start_us = o.start_utime + std::llround(seq * 1e6 / 30.0);
    EXPECT_NEAR(frame.capture_utime - frame_start_us, nominal_us, bound_us) << seq;
    EXPECT_EQ(frame.capture_utime,
              frame_start_us + std::llround(webcam->TimestampDelayS(seq) * 1e6));
    ASSERT_NE(frame.image, nullptr);
  }
}

}  // namespace
}  // namespace roomfix::camera
