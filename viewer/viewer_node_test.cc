#include "viewer/viewer_node.h"

#include <gtest/gtest.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>

#include "msgio/log.h"
#include "msgio/site_message.h"
#include "roomfix/pose2d_t.hpp"
#include "roomfix/process_status_t.hpp"
#include "roomfix/range_set_t.hpp"
#include "tests/testing/demo_site.h"
#include "tests/testing/test_messages.h"
#include "tests/testing/test_paths.h"
#include "tests/testing/wire_test_messages.h"
#include "viewer/render.h"
#include "viewer/viewer_app.h"

namespace roomfix {
namespace {

constexpr int64_t kT0 = 1'700'000'000'000'000;

Site DemoSite() {
  Site site;
  std::string error;
  EXPECT_TRUE(LoadSite(testing::DemoSitePath(), &site, &error)) << error;
  return site;
}

pose2d_t Pose(int8_t source, int64_t utime, double x_m, double y_m) {
  pose2d_t p = testing::MakeTestPose(utime, 1, x_m, y_m);
  p.source = source;
  p.latency_us = 12'000;
  return p;
}

std::string TwoCamerasPath() { return testing::SourceDir() + "/config/sites/two_cameras.yaml"; }

// Runs in another working folder and comes back.
class InFolder {
 public:
  explicit InFolder(const std::string& folder) {
    char here[4096];
    if (::getcwd(here, sizeof(here)) != nullptr) back_ = here;
    EXPECT_EQ(::chdir(folder.c_str()), 0) << folder;
  }
  ~InFolder() {
    if (!back_.empty()) {
      EXPECT_EQ(::chdir(back_.c_str()), 0);
    }
  }

 private:
  std::string back_;
};

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
  EXPECT_EQ(t.source, PoseSource::kUltrasound);
  EXPECT_DOUBLE_EQ(t.x_m, 1.29);
  // 30 poses exactly 100 ms apart: 10 Hz but for the division's rounding.
  constexpr double kExactRateHz = 1e-6;
  EXPECT_NEAR(t.rate_hz, 10.0, kExactRateHz);
  EXPECT_DOUBLE_EQ(t.latency_ms, 12.0);
  // 1 s of trail at 10 Hz: the newest and the 10 before it.
  EXPECT_EQ(t.trail.size(), 11u);
}

TEST(ViewerNode, MarksARangeThatDisagreesWithItsFiringsFixAsRejected) {
  const Site site = DemoSite();
  LoopbackBus bus;
  ViewerNode node(site, &bus, {}, kT0);
  bus.set_now_utime(kT0 + 10'000);
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
    bus.set_now_utime(kT0 + k * 1'000'000);
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

// Issue #20: two processes stating different sites in STATUS are named,
// shown over the process list, counted and reported in the viewer's STATUS.
TEST(ViewerNode, WarnsWhenProcessesRunWithDifferentSites) {
  const Site site = DemoSite();
  LoopbackBus bus;
  ViewerNode node(site, &bus, {}, kT0);
  bus.set_now_utime(kT0);
  const std::pair<const char*, int64_t> processes[] = {{"trilat_proc", 0x0123456789abcdeLL},
                                                       {"fusion_proc", 0x0123456789abcdeLL}};
  for (const auto& [name, hash] : processes) {
    process_status_t s{};
    s.utime = kT0;
    s.process = name;
    s.host = "lab-pc";
    s.counters = {counter_t{kSiteHashCounter, hash}};
    s.num_counters = 1;
    bus.Publish("STATUS", s);
  }
  EXPECT_EQ(node.StateAt(kT0).site_warning, "") << "the same site";
  process_status_t other{};
  other.utime = kT0;
  other.process = "camera_proc";
  other.host = "camera-pc";
  other.counters = {counter_t{kSiteHashCounter, 0x0fedcba98765432LL}};
  other.num_counters = 1;
  bus.Publish("STATUS", other);
  EXPECT_EQ(node.StateAt(kT0).site_warning,
            "processes disagree on the site: 0123456789ab by fusion_proc@lab-pc, "
            "trilat_proc@lab-pc; 0fedcba98765 by camera_proc@camera-pc");
  EXPECT_EQ(node.status().counter("site_disagreements"), 1);
  // Drawn without trouble (the text is fitted to the panel).
  cv::Mat picture;
  viewer::Render(node.StateAt(kT0), {}, &picture);
  EXPECT_FALSE(picture.empty());
}

// Issue #15: the viewer tells a slow process (its kernel buffer overflowed)
// from a hostile sender (forged fragments) by the causes behind `dropped`;
// other counters are not losses and stay out of that list.
TEST(ViewerNode, ShowsWhatMakesUpAProcesssDroppedCount) {
  const Site site = DemoSite();
  LoopbackBus bus;
  ViewerNode node(site, &bus, {}, kT0);
  bus.set_now_utime(kT0);
  process_status_t s{};
  s.utime = kT0;
  s.process = "roomfix_logger";
  s.host = "base";
  s.dropped = 12;
  s.counters = {counter_t{"dropped_kernel_overflow", 10}, counter_t{"files_opened", 1},
                counter_t{"fragments_over_budget", 2}};
  s.num_counters = 3;
  bus.Publish("STATUS", s);
  const viewer::ViewState& v = node.StateAt(kT0);
  ASSERT_EQ(v.processes.size(), 1u);
  EXPECT_EQ(v.processes[0].dropped, 12);
  const std::vector<std::pair<std::string, int64_t>> expected = {{"dropped_kernel_overflow", 10},
                                                                 {"fragments_over_budget", 2}};
  EXPECT_EQ(v.processes[0].losses, expected);
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

// ---------------------------------------------------------------------------
// Limits: what a flood or a broken publisher leaves behind.

double ThreadCpuSeconds() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + ts.tv_nsec * 1e-9;
}

// CPU time of drawing frame_count frames of the node's state, one per
// 1/30 s of view time from now_utime: what the live viewer spends.
double RenderCpuSeconds(ViewerNode* node, int64_t now_utime, int frame_count) {
  viewer::RenderOptions render;
  cv::Mat image;
  const double start = ThreadCpuSeconds();
  for (int k = 0; k < frame_count; ++k) {
    viewer::Render(node->StateAt(now_utime + k * 33'333), render, &image);
  }
  return ThreadCpuSeconds() - start;
}

TEST(ViewerNode, KeepsRowsOnlyForSiteRobotsUnderAFloodOfInventedIds) {
  const Site site = DemoSite();  // Robot 1 only.
  LoopbackBus bus;
  ViewerNode node(site, &bus, {}, kT0);
  bus.set_now_utime(kT0);
  for (int id = 0; id < 20000; ++id) {
    pose2d_t p = Pose(pose2d_t::SOURCE_FUSED, kT0, 1.0, 1.0);
    p.robot_id = 1000 + id;
    bus.Publish("POSE_FUSED", p);
  }
  bus.Publish("POSE_FUSED", Pose(pose2d_t::SOURCE_FUSED, kT0, 2.0, 1.0));
  const viewer::ViewState& s = node.StateAt(kT0);
  ASSERT_EQ(s.tracks.size(), 1u);
  EXPECT_EQ(s.tracks[0].robot_id, 1);
  EXPECT_EQ(node.status().rejected("unknown_robot"), 20000);
}

TEST(ViewerNode, ForgetsEveryRowTenSecondsAfterTheTrafficStops) {
  const Site site = DemoSite();
  LoopbackBus bus;
  ViewerNode node(site, &bus, {}, kT0);
  // A flood on the one robot the site has, from every source, at 20 kHz for
  // one second, plus STATUS from 1000 invented processes.
  for (int k = 0; k < 20000; ++k) {
    const int64_t t = kT0 + k * 50;
    bus.set_now_utime(t);
    for (int8_t source : {pose2d_t::SOURCE_CAMERA, pose2d_t::SOURCE_ULTRASOUND,
                          pose2d_t::SOURCE_FUSED, pose2d_t::SOURCE_GROUND_TRUTH}) {
      bus.Publish("POSE_X", Pose(source, t, 1.0 + k * 1e-5, 1.5));
    }
  }
  const int64_t end = kT0 + 19'999 * 50;  // The last message's receive time.
  for (int k = 0; k < 1000; ++k) {
    process_status_t st{};
    st.utime = end;
    st.process = "flood_" + std::to_string(k);
    st.host = "attacker";
    bus.Publish("STATUS", st);
  }
  const viewer::ViewState& during = node.StateAt(end);
  ASSERT_EQ(during.tracks.size(), 4u);
  for (const viewer::TrackView& t : during.tracks) EXPECT_LE(t.trail.size(), 2000u);
  EXPECT_EQ(during.processes.size(), 64u);
  EXPECT_EQ(node.status().rejected("too_many_processes"), 1000 - 64);
  // 10 s after the last message every track is gone; the process rows stay
  // (stale) for their own, longer time, then go too.
  EXPECT_EQ(node.StateAt(end + 10'000'000).tracks.size(), 4u);
  EXPECT_TRUE(node.StateAt(end + 10'000'001).tracks.empty());
  EXPECT_EQ(node.StateAt(end + 10'000'001).processes.size(), 64u);
  EXPECT_TRUE(node.StateAt(end + 300'000'001).processes.empty());
}

// After a flood, drawing costs what an idle viewer's drawing costs: the
// work per frame does not grow with what came and went. Measured in CPU
// time of this thread over 2 s of frames (60 at 30 Hz); the tolerance is
// 50 % plus 50 ms because the 2 shared cores' caches and frequency make
// two identical runs differ by some tens of percent, while the flood in the
// issue (6 888 rows kept) made each frame cost several times more.
TEST(ViewerNode, DrawsAsCheaplyAfterAFloodAsWhenIdle) {
  const Site site = DemoSite();
  constexpr int kFrames = 60;
  LoopbackBus idle_bus;
  ViewerNode idle(site, &idle_bus, {}, kT0);
  const int64_t later = kT0 + 20'000'000;
  RenderCpuSeconds(&idle, later, 5);  // Warm up caches and allocations.
  const double idle_s = RenderCpuSeconds(&idle, later, kFrames);

  LoopbackBus bus;
  ViewerNode node(site, &bus, {}, kT0);
  for (int k = 0; k < 20000; ++k) {
    bus.set_now_utime(kT0 + k * 50);
    pose2d_t p = Pose(pose2d_t::SOURCE_FUSED, kT0 + k * 50, 1.0, 1.0);
    p.robot_id = k % 2 == 0 ? 1 : 1000 + k;
    bus.Publish("POSE_FUSED", p);
  }
  RenderCpuSeconds(&node, later, 5);
  const double after_s = RenderCpuSeconds(&node, later, kFrames);
  EXPECT_TRUE(node.StateAt(later).tracks.empty());
  std::printf("render CPU over %d frames: idle %.3f s, after the flood %.3f s\n", kFrames, idle_s,
              after_s);
  EXPECT_LE(after_s, 1.5 * idle_s + 0.05) << "idle " << idle_s << " s, after " << after_s << " s";
}

TEST(ViewerNode, RefusesFarOffTimesInfinitiesAndUnknownBeacons) {
  const Site site = DemoSite();
  LoopbackBus bus;
  ViewerNode node(site, &bus, {}, kT0);
  bus.set_now_utime(kT0);
  pose2d_t p = Pose(pose2d_t::SOURCE_CAMERA, std::numeric_limits<int64_t>::min(), 1.0, 1.0);
  bus.Publish("POSE_CAMERA", p);
  p.utime = kT0 + int64_t{3600} * 1'000'000 + 1;
  bus.Publish("POSE_CAMERA", p);
  process_status_t st{};
  st.utime = std::numeric_limits<int64_t>::min();
  st.process = "clockless";
  bus.Publish("STATUS", st);
  EXPECT_EQ(node.status().rejected("utime_out_of_range"), 3);
  EXPECT_TRUE(node.StateAt(kT0).processes.empty());
  p.utime = kT0;
  p.x_m = std::numeric_limits<double>::infinity();
  bus.Publish("POSE_CAMERA", p);
  p.x_m = 1.0;
  p.covariance[1][1] = -std::numeric_limits<double>::infinity();
  bus.Publish("POSE_CAMERA", p);
  EXPECT_EQ(node.status().rejected("non_finite"), 2);
  EXPECT_TRUE(node.StateAt(kT0).tracks.empty());

  range_set_t set{};
  set.utime = kT0;
  set.beacon_id = 99;
  bus.Publish("RANGES", set);
  EXPECT_EQ(node.status().rejected("unknown_beacon"), 1);
  set.beacon_id = 1;
  // Under the wire cap (256) but over the site's receivers: the node refuses.
  for (int k = 0; k < 200; ++k) set.ranges.push_back(range_t{});
  set.num_ranges = 200;
  bus.Publish("RANGES", set);
  EXPECT_EQ(node.status().rejected("too_many_ranges"), 1);
  set.ranges.resize(2);
  set.num_ranges = 2;
  set.ranges[0].receiver_id = site.receivers[0].id;
  set.ranges[0].range_m = 2.0;
  set.ranges[1].receiver_id = 999;
  set.ranges[1].range_m = 2.0;
  bus.Publish("RANGES", set);
  EXPECT_EQ(node.status().rejected("unknown_receiver"), 1);
  set.ranges[0].range_m = std::numeric_limits<double>::quiet_NaN();
  bus.Publish("RANGES", set);
  EXPECT_EQ(node.status().rejected("non_finite"), 3);
  const viewer::ViewState& s = node.StateAt(kT0);
  ASSERT_EQ(s.range_sets.size(), 1u);
  ASSERT_EQ(s.range_sets[0].ranges.size(), 1u);
  EXPECT_DOUBLE_EQ(s.range_sets[0].ranges[0].range_m, 2.0);
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

namespace roomfix {
namespace {

// Several cameras (issue 19): each camera's footprint from its calibration,
// and which camera sees which robot.
TEST(ViewerNode, DrawsEachCamerasFootprintAndWhichCameraSeesARobot) {
  LoadedSite loaded;
  std::string error;
  ASSERT_TRUE(LoadSiteWithTexts(TwoCamerasPath(), &loaded, &error)) << error;
  const Site& site = loaded.site;
  LoopbackBus bus;
  ViewerNodeOptions options;
  options.calibration_texts = CalibrationTextsById(loaded);
  ViewerNode node(site, &bus, options, kT0);
  const viewer::ViewState& empty = node.StateAt(kT0);
  ASSERT_EQ(empty.footprints.size(), 2u);
  // At the marker height (0.2 m) the middle of each 82-degree image's left
  // and right edges lies 2.52 m from its lens (2.9 m tan 41 deg; the site
  // file's comment): camera 0's right edge at x 4.52 m, camera 1's left edge
  // at 3.48 m, the 1 m overlap; the corners reach further (the fisheye's
  // diagonal: 2.9 m tan(800 px / 894 px) x 0.8 = 2.89 m in x). The border is
  // walked clockwise from the top-left corner, 32 points a side: index 32 is
  // the top-right corner, 48 the right edge's middle, 112 the left edge's.
  // 2 cm: the fitted lens is not exactly the nominal one.
  constexpr double kFittedLensFootprintM = 0.02;
  // config/calibration/two_cameras_cam1.yaml's fitted lens x, 6.00006 m, the
  // site's 6.0 m mount to within a millimetre.
  constexpr double kFittedMountM = 0.001;
  ASSERT_EQ(empty.footprints[0].floor_m.size(), 128u);
  ASSERT_EQ(empty.footprints[1].floor_m.size(), 128u);
  EXPECT_TRUE(empty.footprints[0].calibrated);
  EXPECT_TRUE(empty.footprints[1].calibrated);
  EXPECT_NEAR(empty.footprints[0].floor_m[48][0], 4.52, kFittedLensFootprintM);
  EXPECT_NEAR(empty.footprints[0].floor_m[48][1], 1.5, kFittedLensFootprintM);
  EXPECT_NEAR(empty.footprints[1].floor_m[112][0], 3.48, kFittedLensFootprintM);
  EXPECT_NEAR(empty.footprints[0].floor_m[32][0], 4.89, kFittedLensFootprintM);
  EXPECT_NEAR(empty.footprints[1].lens_m[0], 6.0, kFittedMountM);

  // Robot 1 in the overlap, seen by both cameras; an id the site does not
  // list is not remembered.
  for (int camera_id : {0, 1, 7}) {
    pose2d_t p = Pose(pose2d_t::SOURCE_CAMERA, kT0 + 10'000, 4.0, 1.5);
    p.camera_id = camera_id;
    bus.set_now_utime(kT0 + 20'000);
    bus.Publish("POSE_CAMERA", p);
  }
  const viewer::ViewState& s = node.StateAt(kT0 + 30'000);
  ASSERT_EQ(s.tracks.size(), 1u);
  ASSERT_EQ(s.tracks[0].camera_seen_recv_utime.size(), 2u);
  EXPECT_EQ(s.tracks[0].camera_seen_recv_utime.count(0), 1u);
  EXPECT_EQ(s.tracks[0].camera_seen_recv_utime.count(1), 1u);
  // The picture renders with both footprints and the lines.
  cv::Mat image;
  viewer::Render(s, viewer::RenderOptions{}, &image);
  EXPECT_EQ(image.rows, viewer::RenderOptions{}.height_px);
}

// The bus must not call into a destroyed node: its six handlers capture
// `this`. (Junk bytes: delivered to the handlers, refused before the node's
// code.)

// Issue #28, item 3: with --log and no --config the viewer loaded each
// camera's calibration by the path the log's SITE names, relative to the
// working folder (`../calibration/...`), or absolute (`/etc/passwd`). A
// site from a log refers only to the texts it carries: here camera 0 carries
// camera 1's calibration under its own name and camera 1 carries none, run
// from config/sites/, where both names resolve to the real files on disk.
TEST(ViewerNode, ASiteFromALogDrawsOnlyTheCalibrationsItCarries) {
  LoadedSite file;
  std::string error;
  ASSERT_TRUE(LoadSiteWithTexts(TwoCamerasPath(), &file, &error)) << error;
  ASSERT_EQ(file.texts.files.size(), 2u);
  const std::string cam0 = "../calibration/two_cameras_cam0.yaml";
  const std::string cam1 = "../calibration/two_cameras_cam1.yaml";
  LoadedSite forged = file;
  forged.texts.files[cam0] = file.texts.files.at(cam1);
  forged.texts.files.erase(cam1);
  forged.content_hash = SiteContentHash(forged.texts);
  site_t msg;
  ASSERT_TRUE(MakeSiteMessage(forged, "trilat_proc", kT0, &msg, &error)) << error;
  LoadedSite from_log;
  ASSERT_TRUE(LoadSiteFromMessage(msg, "test.lcm: SITE", &from_log, &error)) << error;
  ASSERT_EQ(from_log.site.cameras[1].calibration_file, cam1);

  InFolder sites(testing::SourceDir() + "/config/sites");
  LoopbackBus bus;
  ViewerNodeOptions options;
  options.calibration_texts = CalibrationTextsById(from_log);
  ViewerNode node(from_log.site, &bus, options, kT0);
  const viewer::ViewState& s = node.StateAt(kT0);
  ASSERT_EQ(s.footprints.size(), 2u);
  // Camera 0 drawn with the text it carries (camera 1's lens, fitted at
  // x 6.00006 m), not the file its name resolves to here (a lens at 2 m).
  constexpr double kFittedMountM = 0.001;
  EXPECT_TRUE(s.footprints[0].calibrated);
  EXPECT_NEAR(s.footprints[0].lens_m[0], 6.0, kFittedMountM);
  // Camera 1 carries none: the nominal model, though its file is on disk.
  EXPECT_FALSE(s.footprints[1].calibrated);
}
TEST(ViewerNode, ADestroyedNodeReceivesNothingMore) {
  const Site site = DemoSite();
  LoopbackBus bus;
  const uint8_t junk[3] = {1, 2, 3};
  const std::vector<std::string> channels = {"POSE_FUSED", "RANGES",         "STATUS",
                                             "SITE",       "CAMERA_PREVIEW", "MARKER_PIXELS"};
  {
    ViewerNode node(site, &bus, {}, kT0);
    for (const std::string& c : channels) bus.Inject(c, junk, sizeof(junk), kT0);
    EXPECT_EQ(bus.stats().received, 6);
  }
  for (const std::string& c : channels) bus.Inject(c, junk, sizeof(junk), kT0 + 1);
  EXPECT_EQ(bus.stats().received, 6) << "delivered to a destroyed node";
}

TEST(ViewerNode, KeepsTheLatestDetectorViewWithEachRobotsLineAndRefusesOneItCannotPlace) {
  const Site site = DemoSite();
  LoopbackBus bus;
  ViewerNode node(site, &bus, ViewerNodeOptions{}, kT0);
  bus.set_now_utime(kT0);
  bus.Publish(kDetectorViewChannel, testing::MakeTestDetectorView());
  const viewer::ViewState& s = node.StateAt(kT0);
  ASSERT_TRUE(s.has_detector_view);
  EXPECT_EQ(s.detector_view.camera_id, 1);
  EXPECT_EQ(s.detector_view.region_width_px, 1920);
  ASSERT_EQ(s.detector_view.robots.size(), 2u);
  EXPECT_TRUE(s.detector_view.robots[0].found);
  EXPECT_FALSE(s.detector_view.robots[1].found);
  EXPECT_EQ(s.detector_view.robots[1].text, "robot 2: blob of class green too small");
  // A region running off its frame cannot be drawn over the preview.
  detector_view_t off = testing::MakeTestDetectorView();
  off.region_u_px = 1800;
  off.camera_id = 2;
  bus.Publish(kDetectorViewChannel, off);
  EXPECT_EQ(node.status().rejected("bad_detector_view"), 1);
  EXPECT_EQ(node.StateAt(kT0).detector_view.camera_id, 1);
}

TEST(ViewerNode, TheDKeyAsksEveryCameraForItsDetectorViewAtTheNextTick) {
  const Site site = DemoSite();
  LoopbackBus bus;
  std::vector<detector_view_request_t> requests;
  bus.Subscribe<detector_view_request_t>(
      kDetectorViewRequestChannel,
      [&](const detector_view_request_t& r, const MessageInfo&) { requests.push_back(r); });
  ViewerNodeOptions options;
  options.detector_view_rate_hz = 2.0;
  options.detector_view_duration_s = 20.0;
  ViewerNode node(site, &bus, options, kT0);
  node.Tick(kT0);
  EXPECT_TRUE(requests.empty());
  viewer::RenderOptions render;
  EXPECT_EQ(viewer::ApplyKey('d', &render, node.mutable_state()), viewer::KeyAction::kNone);
  node.Tick(kT0 + 1'000'000);
  ASSERT_EQ(requests.size(), 1u);
  EXPECT_EQ(requests[0].camera_id, -1);
  EXPECT_EQ(requests[0].region_width_px, 0);  // the whole frame
  EXPECT_DOUBLE_EQ(requests[0].rate_hz, 2.0);
  EXPECT_DOUBLE_EQ(requests[0].duration_s, 20.0);
  EXPECT_EQ(requests[0].utime, kT0 + 1'000'000);
  node.Tick(kT0 + 2'000'000);
  EXPECT_EQ(requests.size(), 1u) << "one request per key press";
}

}  // namespace
}  // namespace roomfix
