#include "viewer/viewer_node.h"

#include <gtest/gtest.h>

#include <cmath>

#include "msgio/log.h"
#include "msgio/test_messages.h"
#include "roomfix/pose2d_t.hpp"
#include "roomfix/process_status_t.hpp"
#include "roomfix/range_set_t.hpp"
#include "tests/testing/test_paths.h"
#include "viewer/render.h"

namespace roomfix {
namespace {

constexpr int64_t kT0 = 1'700'000'000'000'000;

Site DemoSite() {
  Site site;
  std::string error;
  EXPECT_TRUE(LoadSite(testing::SourceDir() + "/config/sites/demo_room.yaml", &site, &error))
      << error;
  return site;
}

pose2d_t Pose(int8_t source, int64_t utime, double x_m, double y_m) {
  pose2d_t p = testing::MakeTestPose(utime, 1, x_m, y_m);
  p.source = source;
  p.latency_us = 12'000;
  return p;
}

TEST(ViewerNode, KeepsEachSourcesTrackWithItsRateLatencyAndTrail) {
  const Site site = DemoSite();
  LoopbackBus bus;
  ViewerNodeOptions options;
  options.trail_s = 1.0;
  ViewerNode node(site, &bus, options, kT0);
  for (int k = 0; k < 30; ++k) {
    bus.set_now_utime(kT0 + k * 100'000);
    bus.Publish("POSE_ULTRASOUND",
                Pose(pose2d_t::SOURCE_ULTRASOUND, kT0 + k * 100'000, 1.0 + k * 0.01, 1.5));
  }
  const viewer::ViewState& s = node.StateAt(kT0 + 2'900'000);
  ASSERT_EQ(s.tracks.size(), 1u);
  const viewer::TrackView& t = s.tracks[0];
  EXPECT_EQ(t.source, viewer::Source::kUltrasound);
  EXPECT_DOUBLE_EQ(t.x_m, 1.29);
  EXPECT_NEAR(t.rate_hz, 10.0, 1e-6);
  EXPECT_DOUBLE_EQ(t.latency_ms, 12.0);
  // 1 s of trail at 10 Hz: the newest and the 10 before it.
  EXPECT_EQ(t.trail.size(), 11u);
}

TEST(ViewerNode, MarksARangeThatDisagreesWithItsFiringsFixAsRejected) {
  const Site site = DemoSite();
  LoopbackBus bus;
  ViewerNode node(site, &bus, {}, kT0);
  range_set_t set{};
  set.utime = kT0;
  set.beacon_id = 1;
  for (const Receiver& r : site.receivers) {
    range_t range{};
    range.receiver_id = r.id;
    for (int k = 0; k < 3; ++k) range.receiver_position_m[k] = r.position_m[k];
    const double dx = r.position_m[0] - 2.0, dy = r.position_m[1] - 1.5, dz = r.position_m[2] - 1.3;
    // Receiver 3 heard a reflection half a metre longer.
    range.range_m = std::sqrt(dx * dx + dy * dy + dz * dz) + (r.id == 3 ? 0.5 : 0.0);
    set.ranges.push_back(range);
  }
  set.num_ranges = static_cast<int32_t>(set.ranges.size());
  bus.Publish("RANGES", set);
  bus.Publish("POSE_ULTRASOUND", Pose(pose2d_t::SOURCE_ULTRASOUND, kT0, 2.0, 1.5));
  const viewer::ViewState& s = node.StateAt(kT0 + 50'000);
  ASSERT_EQ(s.range_sets.size(), 1u);
  EXPECT_DOUBLE_EQ(s.range_sets[0].beacon_height_m, 1.3);
  for (const viewer::RangeView& r : s.range_sets[0].ranges) {
    EXPECT_EQ(r.rejected, r.receiver_id == 3) << "receiver " << r.receiver_id;
  }
}

TEST(ViewerNode, ShowsEachProcessFromItsHeartbeatWithItsOutputRate) {
  const Site site = DemoSite();
  LoopbackBus bus;
  ViewerNode node(site, &bus, {}, kT0);
  for (int k = 0; k < 2; ++k) {
    process_status_t s{};
    s.utime = kT0 + k * 1'000'000;
    s.process = "zigbee_bridge";
    s.host = "radio-host";
    s.pid = 42;
    s.state = process_status_t::STATE_DEGRADED;
    s.outputs = 10 * k;
    s.rejected = {counter_t{"unknown_address", 3}, counter_t{"late_report", 7}};
    s.num_rejected = 2;
    s.last_error = "/dev/ttyUSB0: device gone";
    bus.Publish("STATUS", s);
  }
  const viewer::ViewState& v = node.StateAt(kT0 + 1'000'000);
  ASSERT_EQ(v.processes.size(), 1u);
  EXPECT_EQ(v.processes[0].host, "radio-host");
  EXPECT_DOUBLE_EQ(v.processes[0].output_rate_hz, 10.0);
  EXPECT_EQ(v.processes[0].rejected.front().first, "late_report") << "largest first";
  EXPECT_EQ(v.processes[0].last_error, "/dev/ttyUSB0: device gone");
}

TEST(ViewerNode, ABurstOfMessagesIsNotAnInfiniteRateAndARestartKeepsOneRow) {
  const Site site = DemoSite();
  LoopbackBus bus;
  ViewerNode node(site, &bus, {}, kT0);
  bus.set_now_utime(kT0);
  for (int k = 0; k < 10; ++k) {
    bus.Publish("POSE_CAMERA", Pose(pose2d_t::SOURCE_CAMERA, kT0 - k * 1000, 1.0, 1.0));
  }
  for (int pid : {100, 200}) {
    process_status_t s{};
    s.utime = kT0;
    s.process = "trilat_proc";
    s.host = "base";
    s.pid = pid;
    bus.Publish("STATUS", s);
  }
  const viewer::ViewState& v = node.StateAt(kT0);
  ASSERT_EQ(v.tracks.size(), 1u);
  EXPECT_LE(v.tracks[0].rate_hz, 10.0) << "10 messages at once, over at least a second";
  ASSERT_EQ(v.processes.size(), 1u) << "the restarted process takes over its row";
  EXPECT_EQ(v.processes[0].pid, 200);
}

TEST(ViewerNode, RendersARecordedSessionReplayedThroughTheSameNode) {
  const Site site = DemoSite();
  LoopbackBus bus;
  ViewerNode node(site, &bus, {}, 0);
  const ReplaySummary summary =
      ReplayLog(testing::SourceDir() + "/tests/data/trilat_replay.lcm", &bus);
  ASSERT_TRUE(summary.ok) << summary.error;
  const viewer::ViewState& s = node.StateAt(summary.last_utime);
  ASSERT_EQ(s.tracks.size(), 1u);
  EXPECT_GE(s.tracks[0].trail.size(), 30u);
  ASSERT_EQ(s.range_sets.size(), 1u);
  cv::Mat image;
  viewer::Render(s, viewer::RenderOptions{}, &image);
  EXPECT_EQ(image.cols, 1280);
  EXPECT_EQ(image.rows, 800);
}

}  // namespace
}  // namespace roomfix
