// Two processes exchange pose2d_t over LCM's UDP multicast. Runs inside a
// private network namespace (scripts/netns_run), so nothing leaves the host.
#include <gtest/gtest.h>
#include <signal.h>

#include <chrono>
#include <cmath>

#include "core/world/site.h"
#include "msgio/bus.h"
#include "msgio/process.h"
#include "roomfix/pose2d_t.hpp"
#include "tests/testing/demo_site.h"
#include "tests/testing/test_paths.h"

namespace roomfix {
namespace {

using testing::BinDir;
using testing::ChildProcess;
using testing::DemoSitePath;

// The simulator computes the pose in double precision from the same
// trajectory; the wire format is IEEE doubles, so agreement is exact to
// rounding in the drift term.
constexpr double kOnCircle_m = 1e-9;

TEST(UdpmExchange, PosesFromTheSimulatorProcessArriveIntactOverMulticast) {
  std::string error;
  auto bus = LcmBus::Create(kDefaultLcmUrl, &error);
  ASSERT_NE(bus, nullptr) << error;
  std::vector<pose2d_t> poses;
  std::vector<process_status_t> beats;
  bus->Subscribe<pose2d_t>("POSE_GROUND_TRUTH",
                           [&](const pose2d_t& p, const MessageInfo&) { poses.push_back(p); });
  bus->Subscribe<process_status_t>(
      "STATUS", [&](const process_status_t& s, const MessageInfo&) { beats.push_back(s); });

  ChildProcess sim({BinDir() + "/roomfix_sim", "--config", DemoSitePath(), "--rate-hz", "50",
                    "--duration", "2.5", "--log-level", "warn"});
  ASSERT_TRUE(sim.started());
  ASSERT_TRUE(HandleUntil(
      bus.get(), [&] { return poses.size() >= 60 && beats.size() >= 2; }, 20))
      << "received " << poses.size() << " poses and " << beats.size() << " heartbeats";
  EXPECT_EQ(sim.Wait(10), 0) << "roomfix_sim did not stop cleanly after --duration";

  Site site;
  ASSERT_TRUE(LoadSite(DemoSitePath(), &site, &error)) << error;
  const CircleTrajectoryOptions circle;  // demo_room drives the reference circle.
  const int64_t start_utime = poses[0].utime - poses[0].measurement_seq * 20000;
  for (size_t i = 0; i < poses.size(); ++i) {
    const pose2d_t& p = poses[i];
    EXPECT_EQ(p.source, pose2d_t::SOURCE_GROUND_TRUTH);
    EXPECT_EQ(p.robot_id, 1);
    if (i > 0) {
      EXPECT_EQ(p.measurement_seq, poses[i - 1].measurement_seq + 1) << "sample lost";
    }
    const double t_s = (p.utime - start_utime) * 1e-6;
    const GroundTruthPose truth = site.simulation.robots[0].trajectory->PoseAt(t_s);
    EXPECT_NEAR(p.x_m, truth.x_m, kOnCircle_m);
    EXPECT_NEAR(p.y_m, truth.y_m, kOnCircle_m);
    EXPECT_NEAR(std::hypot(p.x_m - circle.cx_m - circle.drift_x_mps * t_s,
                           p.y_m - circle.cy_m - circle.drift_y_mps * t_s),
                circle.radius_m, kOnCircle_m);
  }
  EXPECT_EQ(beats[0].process, "roomfix_sim");
  EXPECT_EQ(beats[0].pid, sim.pid());
}

TEST(UdpmExchange, SigtermStopsAProcessCleanly) {
  std::string error;
  auto bus = LcmBus::Create(kDefaultLcmUrl, &error);
  ASSERT_NE(bus, nullptr) << error;
  int poses = 0;
  bus->Subscribe<pose2d_t>("POSE_GROUND_TRUTH",
                           [&](const pose2d_t&, const MessageInfo&) { ++poses; });
  for (int sig : {SIGTERM, SIGINT}) {
    poses = 0;
    ChildProcess sim(
        {BinDir() + "/roomfix_sim", "--config", DemoSitePath(), "--log-level", "warn"});
    ASSERT_TRUE(HandleUntil(
        bus.get(), [&] { return poses > 3; }, 20));
    sim.Signal(sig);
    EXPECT_EQ(sim.Wait(5), 0) << "signal " << sig;
  }
}

}  // namespace
}  // namespace roomfix
