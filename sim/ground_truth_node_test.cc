#include "sim/ground_truth_node.h"

#include <gtest/gtest.h>

#include "roomfix/pose2d_t.hpp"
#include "tests/testing/demo_site.h"
#include "tests/testing/test_paths.h"

namespace roomfix {
namespace {

class GroundTruthNodeTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string error;
    ASSERT_TRUE(LoadSite(testing::DemoSitePath(), &site_, &error)) << error;
    bus_.Subscribe<pose2d_t>(
        kGroundTruthPoseChannel,
        [this](const pose2d_t& p, const MessageInfo&) { poses_.push_back(p); });
  }
  Site site_;
  LoopbackBus bus_;
  std::vector<pose2d_t> poses_;
};

TEST_F(GroundTruthNodeTest, PublishesTheTrajectoryOnAFixedGridWhateverTheTickTimes) {
  GroundTruthNodeOptions options;
  options.rate_hz = 10.0;
  options.start_utime = 1700000000000000;
  GroundTruthNode node(site_, &bus_, options);
  // Ticks at irregular times, never on the grid.
  for (int64_t dt : {3000, 104000, 151000, 230000, 299000, 310000}) {
    node.Tick(options.start_utime + dt);
  }
  ASSERT_EQ(poses_.size(), 4u);
  const auto& trajectory = *site_.simulation.robots[0].trajectory;
  for (size_t i = 0; i < poses_.size(); ++i) {
    const pose2d_t& p = poses_[i];
    EXPECT_EQ(p.utime, options.start_utime + static_cast<int64_t>(i) * 100000);
    EXPECT_EQ(p.measurement_seq, static_cast<int64_t>(i));
    EXPECT_EQ(p.source, pose2d_t::SOURCE_GROUND_TRUTH);
    EXPECT_EQ(p.robot_id, 1);
    const GroundTruthPose truth = trajectory.PoseAt(i * 0.1);
    EXPECT_DOUBLE_EQ(p.x_m, truth.x_m);
    EXPECT_DOUBLE_EQ(p.y_m, truth.y_m);
    EXPECT_DOUBLE_EQ(p.heading_rad, truth.heading_rad);
  }
  EXPECT_EQ(poses_[2].latency_us, 30000);  // Sample at 200 ms, published at 230 ms.
}

TEST_F(GroundTruthNodeTest, SkipsAndCountsSamplesWhenTicksComeLate) {
  GroundTruthNodeOptions options;
  options.rate_hz = 100.0;
  options.start_utime = 0;
  GroundTruthNode node(site_, &bus_, options);
  node.Tick(0);
  node.Tick(55000);  // Samples 1..5 are due; only 5 is published.
  ASSERT_EQ(poses_.size(), 2u);
  EXPECT_EQ(poses_[1].measurement_seq, 5);
  EXPECT_EQ(node.status().counter("late_samples"), 4);
}

TEST_F(GroundTruthNodeTest, SendsAHeartbeatEverySecond) {
  std::vector<process_status_t> beats;
  bus_.Subscribe<process_status_t>(
      "STATUS", [&](const process_status_t& s, const MessageInfo&) { beats.push_back(s); });
  GroundTruthNodeOptions options;
  options.start_utime = 0;
  GroundTruthNode node(site_, &bus_, options);
  for (int64_t t = 0; t <= 2500000; t += 10000) node.Tick(t);
  ASSERT_EQ(beats.size(), 3u);
  EXPECT_EQ(beats[2].process, "roomfix_sim");
  EXPECT_EQ(beats[2].state, process_status_t::STATE_RUNNING);
  EXPECT_EQ(beats[2].outputs, 61);  // Samples 0..60 at 30 Hz by t = 2 s.
  node.Stop(2600000);
  ASSERT_EQ(beats.size(), 4u);
  EXPECT_EQ(beats[3].state, process_status_t::STATE_STOPPING);
}

TEST(GroundTruthNodeOptions, RejectsANonPositiveRate) {
  GroundTruthNodeOptions options;
  options.rate_hz = 0.0;
  std::string error;
  EXPECT_FALSE(options.IsValid(&error));
  EXPECT_EQ(error, "rate_hz must be in (0, 10000]");
}

}  // namespace
}  // namespace roomfix
