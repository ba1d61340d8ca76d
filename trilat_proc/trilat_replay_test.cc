// Deterministic replay: the range sets of a recorded live session, fed
// through the same node class trilat_proc runs, give back the poses the live
// process published, field for field.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <map>

#include "msgio/log.h"
#include "roomfix/pose2d_t.hpp"
#include "tests/testing/demo_site.h"
#include "tests/testing/test_paths.h"
#include "trilat_proc/trilat_node.h"

namespace roomfix {
namespace {

// Recorded by lcm-logger while trilat_proc --method robust ran on the demo
// room and roomfix_sim --ranges published noisy range sets with
// non-line-of-sight outliers and dropouts (tests/data/README.md).
std::string ReplayLogPath() { return testing::SourceDir() + "/tests/data/trilat_replay.lcm"; }

// Bitwise equality, so that NaN equals NaN and -0 differs from 0.
bool Same(double a, double b) { return std::memcmp(&a, &b, sizeof(double)) == 0; }

TEST(TrilatReplay, ReproducesTheRecordedPosesExactly) {
  std::map<int64_t, pose2d_t> recorded;
  {
    std::string error;
    auto reader = LogReader::Open(ReplayLogPath(), &error);
    ASSERT_NE(reader, nullptr) << error;
    LogEvent e;
    while (reader->Next(&e)) {
      if (e.channel != kUltrasoundPoseChannel) continue;
      pose2d_t p{};
      ASSERT_EQ(p.decode(e.data.data(), 0, static_cast<int>(e.data.size())),
                static_cast<int>(e.data.size()));
      recorded[p.measurement_seq] = p;
    }
  }
  ASSERT_GE(recorded.size(), 25u);

  Site site;
  std::string error;
  ASSERT_TRUE(LoadSite(testing::DemoSitePath(), &site, &error));
  LoopbackBus bus;
  TrilatNodeOptions options;
  options.solver.method = trilat::Method::kRobust;
  TrilatNode node(site, &bus, options, 0);
  std::vector<pose2d_t> replayed;
  bus.Subscribe<pose2d_t>(kUltrasoundPoseChannel,
                          [&](const pose2d_t& p, const MessageInfo&) { replayed.push_back(p); });
  ReplayOptions replay;
  replay.channel_regex = kRangesChannel;
  const ReplaySummary summary = ReplayLog(ReplayLogPath(), &bus, replay);
  ASSERT_TRUE(summary.ok) << summary.error;
  EXPECT_FALSE(summary.damaged);

  int compared = 0;
  int degraded = 0;
  for (const pose2d_t& p : replayed) {
    auto it = recorded.find(p.measurement_seq);
    if (it == recorded.end()) continue;  // The live logger missed that pose.
    const pose2d_t& r = it->second;
    EXPECT_EQ(p.utime, r.utime);
    EXPECT_EQ(p.robot_id, r.robot_id);
    EXPECT_EQ(p.status, r.status) << "firing " << p.measurement_seq;
    EXPECT_EQ(p.num_measurements, r.num_measurements);
    EXPECT_TRUE(Same(p.x_m, r.x_m)) << p.x_m << " vs " << r.x_m << " firing " << p.measurement_seq;
    EXPECT_TRUE(Same(p.y_m, r.y_m)) << p.y_m << " vs " << r.y_m;
    EXPECT_TRUE(Same(p.z_m, r.z_m));
    EXPECT_TRUE(Same(p.residual_m, r.residual_m));
    for (int a = 0; a < 3; ++a) {
      for (int b = 0; b < 3; ++b) EXPECT_TRUE(Same(p.covariance[a][b], r.covariance[a][b]));
    }
    degraded += p.status == pose2d_t::STATUS_DEGRADED;
    ++compared;
  }
  EXPECT_EQ(compared, static_cast<int>(recorded.size()));
  // The session exercises the robust path: some firings lost receivers or
  // carried a reflected range.
  EXPECT_GT(degraded, 0);
}

}  // namespace
}  // namespace roomfix
