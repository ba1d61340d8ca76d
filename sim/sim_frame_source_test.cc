#include "sim/sim_frame_source.h"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <memory>
#include <opencv2/core.hpp>
#include <string>
#include <thread>

#include "core/calib/fisheye_camera.h"
#include "core/world/site.h"
#include "tests/testing/demo_site.h"
#include "tests/testing/test_paths.h"

namespace roomfix::sim {
namespace {

using camera::Frame;
using camera::ReadStatus;

// A small webcam in the demo room (320 x 180, the same lens angle), so that
// the frames are cheap.
std::shared_ptr<const SyntheticCamera> SmallWebcam(SimScenario* scenario) {
  Site site;
  std::string error;
  EXPECT_TRUE(LoadSite(testing::DemoSitePath(), &site, &error)) << error;
  Camera camera = site.cameras.at(0);
  camera.width_px = 320;
  camera.height_px = 180;
  EXPECT_TRUE(ParseSimScenario("sim:webcam", site, scenario, &error)) << error;
  return std::make_shared<const SyntheticCamera>(
      site, camera, calib::NominalCamera(camera.mount_position_m, 120, 320, 180), *scenario);
}

TEST(SimFrameSource, WebcamFramesAreStampedAtTheLastRowsReadPlusLatency) {
  SimScenario scenario;
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

int64_t WallUtime() {
  return std::chrono::duration_cast<std::chrono::microseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

cv::Mat Pixels(Frame* frame) {
  cv::Mat bgr;
  std::string error;
  EXPECT_TRUE(frame->image->DecodeRegion(
      cv::Rect(0, 0, frame->image->width_px(), frame->image->height_px()), &bgr, &error))
      << error;
  return bgr;
}

TEST(SimFrameSource, RealtimeFramesFromTheProducerThreadEqualTheVirtualClocksFrames) {
  // A frame is a function of its seq: rendered ahead on the producer thread
  // it is the same frame, stamp and pixels, as rendered in Read.
  SimScenario scenario;
  const auto webcam = SmallWebcam(&scenario);
  SimSourceOptions o;
  o.start_utime = WallUtime();
  o.realtime = true;
  SimFrameSource live(webcam, o);
  o.realtime = false;
  SimFrameSource virtual_clock(webcam, o);
  std::string error;
  ASSERT_TRUE(live.Open(&error)) << error;
  ASSERT_TRUE(virtual_clock.Open(&error)) << error;
  Frame expected;
  for (int i = 0; i < 4; ++i) {
    Frame frame;
    ASSERT_EQ(live.Read(&frame, &error), ReadStatus::kFrame) << error;
    // A realtime frame is never handed over before its own timestamp.
    EXPECT_GE(WallUtime(), frame.capture_utime);
    do {
      ASSERT_EQ(virtual_clock.Read(&expected, &error), ReadStatus::kFrame) << error;
    } while (expected.seq < frame.seq);
    EXPECT_EQ(frame.capture_utime, expected.capture_utime) << frame.seq;
    EXPECT_EQ(cv::norm(Pixels(&frame), Pixels(&expected), cv::NORM_INF), 0.0) << frame.seq;
  }
  live.Close();
  Frame after;
  EXPECT_EQ(live.Read(&after, &error), ReadStatus::kDeviceLost);
}

TEST(SimFrameSource, RendererBehindRealTimeIsCountedApartFromFramesTheReaderMissed) {
  SimScenario scenario;
  const auto webcam = SmallWebcam(&scenario);
  SimSourceOptions o;
  o.fps = 30.0;
  o.queue_frames = 2;
  // t = 0 a second ago: the renderer starts 30 frames behind and skips to
  // the newest, which is its own skip, not the reader's.
  o.start_utime = WallUtime() - 1'000'000;
  SimFrameSource source(webcam, o);
  std::string error;
  ASSERT_TRUE(source.Open(&error)) << error;
  Frame first;
  ASSERT_EQ(source.Read(&first, &error), ReadStatus::kFrame) << error;
  EXPECT_GE(first.seq, 29);
  EXPECT_EQ(first.source_skipped, first.seq);
  EXPECT_GE(source.render_skipped(), first.seq);
  // The reader sleeps 10 frame periods: the queue keeps the 2 newest, so
  // about 8 are the reader's drops; whatever the renderer itself skipped
  // under load is counted in the frame, and the two add up to the gap.
  std::this_thread::sleep_for(std::chrono::milliseconds(333));
  const int64_t skipped_before = source.render_skipped();
  Frame next;
  ASSERT_EQ(source.Read(&next, &error), ReadStatus::kFrame) << error;
  const int64_t gap = next.seq - first.seq - 1;
  const int64_t reader_missed = gap - next.source_skipped;
  EXPECT_GE(reader_missed, 5) << "gap " << gap << ", source skipped " << next.source_skipped;
  EXPECT_LE(next.source_skipped, source.render_skipped() - first.source_skipped);
  EXPECT_GE(source.render_skipped(), skipped_before);
  // The destructor stops and joins the producer thread (no Close).
}

TEST(SimFrameSource, ClosingStopsTheProducerWhileItWaitsForAFrame) {
  SimScenario scenario;
  const auto webcam = SmallWebcam(&scenario);
  SimSourceOptions o;
  o.fps = 1.0;  // the producer sleeps most of a second between frames
  o.start_utime = WallUtime();
  SimFrameSource source(webcam, o);
  std::string error;
  ASSERT_TRUE(source.Open(&error)) << error;
  Frame frame;
  ASSERT_EQ(source.Read(&frame, &error), ReadStatus::kFrame) << error;
  const auto begin = std::chrono::steady_clock::now();
  source.Close();
  // Close wakes the producer instead of waiting for the next frame's time.
  EXPECT_LT(std::chrono::steady_clock::now() - begin, std::chrono::milliseconds(500));
  // Opened again, it goes on from the clock's present, never repeating a
  // frame.
  ASSERT_TRUE(source.Open(&error)) << error;
  ASSERT_EQ(source.Read(&frame, &error), ReadStatus::kFrame) << error;
  EXPECT_GE(frame.seq, 1);
}

TEST(SimFrameSource, DeviceTimingIsTheScenariosOwn) {
  SimScenario scenario;
  const auto webcam = SmallWebcam(&scenario);
  const std::optional<calib::CameraTiming> t = SimFrameSource(webcam, {}).device_timing();
  ASSERT_TRUE(t.has_value());
  EXPECT_EQ(t->readout_s, scenario.webcam.readout_s);
  EXPECT_EQ(t->exposure_s, scenario.webcam.exposure_s);
  EXPECT_EQ(t->latency_s, scenario.webcam.timestamp_latency_s);
  EXPECT_EQ(t->height_px, 180);
  ASSERT_GT(scenario.webcam.readout_s, 0.0);
  SimScenario clean;
  std::string error;
  ASSERT_TRUE(ParseSimScenario("sim:clean", &clean, &error)) << error;
  const calib::CameraTiming c = ScenarioTiming(clean, 180);
  EXPECT_EQ(c.readout_s, 0.0);
  EXPECT_EQ(c.exposure_s, 0.0);
  EXPECT_EQ(c.latency_s, 0.0);
}

}  // namespace
}  // namespace roomfix::sim
