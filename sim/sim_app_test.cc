#include "sim/sim_app.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <memory>
#include <string>

#include "tests/testing/check_context.h"
#include "tests/testing/demo_site.h"

namespace roomfix {
namespace {

TEST(SimAppOptionsTest, TheDefaultsAreValid) {
  std::string error;
  EXPECT_TRUE(SimAppOptions().IsValid(&error)) << error;
}

TEST(SimAppOptionsTest, RefusesABadNodeOptionNamingWhatItConcerns) {
  std::string error;
  SimAppOptions options;
  options.ground_truth.rate_hz = 0.0;
  EXPECT_FALSE(options.IsValid(&error));
  EXPECT_EQ(error, "--rate-hz: rate_hz must be in (0, 10000]");

  options = SimAppOptions();
  options.ranges.rate_hz = 2000.0;
  EXPECT_FALSE(options.IsValid(&error));
  EXPECT_EQ(error, "ranges: rate_hz must be in (0, 1000]");

  options = SimAppOptions();
  options.wall.faults.lost_report_probability = 2.0;
  EXPECT_FALSE(options.IsValid(&error));
  EXPECT_EQ(error, "wall devices: lost report probability must be in [0, 1]");
}

TEST(SimAppOptionsTest, RefusesBothRangePathsAtOnce) {
  // Each path alone is valid; together they would publish every firing's
  // range set twice on RANGES.
  SimAppOptions options;
  std::string error;
  options.publish_ranges = true;
  EXPECT_TRUE(options.IsValid(&error)) << error;
  options.publish_ranges = false;
  options.radio_pty = true;
  EXPECT_TRUE(options.IsValid(&error)) << error;
  options.publish_ranges = true;
  EXPECT_FALSE(options.IsValid(&error));
  EXPECT_EQ(error,
            "--ranges and --radio-pty exclude each other: the ideal radio publishes RANGES "
            "itself, the virtual devices feed zigbee_bridge");
}

TEST(RunAirBenchTest, TakesOneToAThousandSeedsAndRefusesOthersBeforePrinting) {
  for (int seeds : {0, 1001}) {
    std::string error;
    ::testing::internal::CaptureStdout();
    EXPECT_EQ(RunAirBench(testing::DemoSitePath(), SharedAirOptions(), 1.0, seeds, &error), 1);
    EXPECT_EQ(::testing::internal::GetCapturedStdout(), "") << seeds;
    EXPECT_EQ(error, "--bench-seeds must be in [1, 1000]") << seeds;
  }
  // One seed of 0.1 s per row: six lines of header (the room, its air, the
  // pulse, the slot, the runs, the column names), then 5 beacon counts x 2
  // schedules.
  std::string error;
  ::testing::internal::CaptureStdout();
  EXPECT_EQ(RunAirBench(testing::DemoSitePath(), SharedAirOptions(), 0.1, 1, &error), 0) << error;
  const std::string out = ::testing::internal::GetCapturedStdout();
  EXPECT_EQ(out.rfind("Air of demo_room: 4.0 x 3.0 x 3.3 m", 0), 0u) << out;
  EXPECT_EQ(std::count(out.begin(), out.end(), '\n'), 6 + 10) << out;
}

class RunSimulatorTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string error;
    ctx_ = testing::DemoCheckContext("roomfix_sim", &error);
    ASSERT_NE(ctx_, nullptr) << error;
  }
  std::unique_ptr<ProcessContext> ctx_;
};

TEST_F(RunSimulatorTest, CheckPrintsWhatWouldRunWithoutABus) {
  // --check opens no bus (StartProcess leaves it empty), so nothing may run.
  SimAppOptions options;
  options.radio_pty = true;
  options.faults_preset = "all";
  std::string error;
  ::testing::internal::CaptureStdout();
  EXPECT_EQ(RunSimulator(ctx_.get(), options, &error), 0) << error;
  // spdlog's default logger (StartProcess has not moved it to stderr) writes
  // the robots' trajectories to stdout first: the check line comes last.
  const std::string out = ::testing::internal::GetCapturedStdout();
  const std::string line =
      "roomfix_sim: ok: 1 robot(s) at 30 Hz on memq://, wall devices (behavioural) on a "
      "pseudo-terminal "
      "(faults all)\n";
  ASSERT_GE(out.size(), line.size()) << out;
  EXPECT_EQ(out.substr(out.size() - line.size()), line) << out;
}

TEST_F(RunSimulatorTest, RefusesASiteWithNothingToSimulate) {
  ctx_->site.simulation.robots.clear();
  std::string error;
  EXPECT_EQ(RunSimulator(ctx_.get(), SimAppOptions(), &error), 1);
  EXPECT_EQ(error, ctx_->options.config_path + ": simulation.robots is empty; nothing to simulate");
}

}  // namespace
}  // namespace roomfix
