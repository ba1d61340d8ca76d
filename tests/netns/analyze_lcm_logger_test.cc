// `roomfix analyze` reads a log written by LCM's own lcm-logger: the
// simulator's ground truth recorded over multicast (inside the private
// network namespace of scripts/netns_run) gives back the reference circle.
#include <gtest/gtest.h>
#include <signal.h>

#include <chrono>
#include <nlohmann/json.hpp>
#include <thread>

#include "tests/testing/demo_site.h"
#include "tests/testing/test_paths.h"

namespace roomfix {
namespace {

using testing::BinDir;
using testing::ChildProcess;
using testing::DemoSitePath;

TEST(RoomfixAnalyze, ReadsALogRecordedByLcmLogger) {
  testing::TempDir dir;
  ChildProcess logger({"lcm-logger", "-q", "-f", dir.File("sim.lcm")});
  ASSERT_TRUE(logger.started());
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  ChildProcess sim({BinDir() + "/roomfix_sim", "--config", DemoSitePath(), "--duration", "4",
                    "--rate-hz", "30", "--log-level", "warn"});
  ASSERT_EQ(sim.Wait(20), 0);
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  logger.Signal(SIGINT);
  logger.Wait(5);

  ChildProcess analyze({BinDir() + "/roomfix", "analyze", dir.File("sim.lcm"), "--json",
                        "--no-figures", "--out", dir.File("report")},
                       dir.File("out.json"));
  ASSERT_EQ(analyze.Wait(60), 0);
  const auto out = nlohmann::json::parse(testing::ReadFile(dir.File("out.json")));
  const auto& truth = out["robots"]["1"]["ground_truth"];
  EXPECT_GE(truth["fixes"].get<int>(), 100);
  // A 4 s real-time run on a shared machine: when the first and last
  // samples are sent moves the measured rate by a fraction of a hertz; 0.5 Hz
  // still tells 30 Hz from 25 or 60.
  constexpr double kLiveRateTolHz = 0.5;
  EXPECT_NEAR(truth["timing"]["rate_hz"].get<double>(), 30.0, kLiveRateTolHz);
  // The simulator's samples lie exactly on the circle: the fit is exact to
  // rounding (and the whole-microsecond stamps: 0.2 um at 0.18 m/s).
  constexpr double kExactFitM = 1e-6;
  constexpr double kExactFitRadps = 1e-6;
  const auto& fit = truth["circle"]["circular_motion"];
  EXPECT_NEAR(fit["radius_m"].get<double>(), 0.419, kExactFitM);
  EXPECT_NEAR(fit["angular_speed_radps"].get<double>(), -0.439, kExactFitRadps);
  EXPECT_FALSE(out["logs"][0]["damaged"].get<bool>());
}

}  // namespace
}  // namespace roomfix
