#include "sim/ranges_node.h"

#include <gtest/gtest.h>

#include <cmath>
#include <map>

#include "core/trilat/trilateration.h"
#include "msgio/trilat_conversions.h"
#include "roomfix/range_set_t.hpp"
#include "tests/testing/demo_site.h"
#include "tests/testing/test_paths.h"

namespace roomfix {
namespace {

TEST(SimRangesNode, FiresOnScheduleWithRangesThatPutTheBeaconOnItsTrajectory) {
  Site site;
  std::string error;
  ASSERT_TRUE(LoadSite(testing::DemoSitePath(), &site, &error));
  LoopbackBus bus;
  std::vector<range_set_t> sets;
  bus.Subscribe<range_set_t>("RANGES",
                             [&](const range_set_t& s, const MessageInfo&) { sets.push_back(s); });
  SimRangesNodeOptions options;
  options.noise.sigma_m = 0.0;
  options.clock_ppm = 0.0;  // the beacon's crystal exact: firings on the 10 Hz grid
  options.start_utime = 1000000;
  SimRangesNode node(site, &bus, options);
  for (int64_t t = 1000000; t <= 2000000; t += 7000) node.Tick(t);
  // 10 Hz, each published 30 ms after its firing: firings at 0.0 .. 0.9 s.
  ASSERT_EQ(sets.size(), 10u);
  trilat::SolverOptions solver;
  solver.fixed_height_m = site.beacons[0].height_m;
  std::vector<trilat::RangeMeasurement> ranges;
  for (size_t k = 0; k < sets.size(); ++k) {
    EXPECT_EQ(sets[k].firing_seq, static_cast<int64_t>(k));
    EXPECT_EQ(sets[k].utime, 1000000 + static_cast<int64_t>(k) * 100000);
    EXPECT_EQ(sets[k].num_ranges, 4);
    RangesFromMessage(sets[k], &ranges);
    const trilat::Fix fix = trilat::Solve(ranges, solver);
    const GroundTruthPose truth = site.simulation.robots[0].trajectory->PoseAt(k * 0.1);
    // Noise-free ranges to the trajectory's own position: the solver gives it
    // back to its convergence, far inside a nanometre.
    constexpr double kNoiseFreeFixM = 1e-9;
    EXPECT_NEAR(fix.position_m.x(), truth.x_m, kNoiseFreeFixM);
    EXPECT_NEAR(fix.position_m.y(), truth.y_m, kNoiseFreeFixM);
  }
}

TEST(SimRangesNode, CollidingBeaconsGiveWrongRangesAndTheTdmaTableNone) {
  Site site;
  std::string error;
  ASSERT_TRUE(LoadSite(testing::SourceDir() + "/config/sites/two_radios.yaml", &site, &error))
      << error;
  const double c = SpeedOfSound(site.simulation.temperature_c);
  // Each beacon's trajectory, by beacon id.
  std::map<int, const Trajectory*> trajectories;
  for (const SimulatedRobot& sr : site.simulation.robots) {
    const Robot* robot = site.FindRobot(sr.robot_id);
    if (robot != nullptr && robot->beacon_id) trajectories[*robot->beacon_id] = sr.trajectory.get();
  }
  for (auto mode : {FiringPlanOptions::Mode::kTdma, FiringPlanOptions::Mode::kFreeRunning}) {
    LoopbackBus bus;
    int64_t ranges = 0, wrong = 0;
    SimRangesNodeOptions options;
    options.noise.sigma_m = 0.0;
    options.schedule = mode;
    options.start_utime = 1'000'000;
    SimRangesNode node(site, &bus, options);
    bus.Subscribe<range_set_t>("RANGES", [&](const range_set_t& s, const MessageInfo&) {
      const auto it = trajectories.find(s.beacon_id);
      if (it == trajectories.end()) {
        ADD_FAILURE() << "a set from beacon " << s.beacon_id << ", which no robot carries";
        return;
      }
      const GroundTruthPose p = it->second->PoseAt((s.utime - options.start_utime) * 1e-6);
      for (const range_t& r : s.ranges) {
        const Receiver& rc = *site.FindReceiver(r.receiver_id);
        const double truth_m =
            std::hypot(rc.position_m[0] - p.x_m, rc.position_m[1] - p.y_m,
                       rc.position_m[2] - site.FindBeacon(s.beacon_id)->height_m);
        ++ranges;
        // Without noise a range is the true distance to rounding; a wrong
        // one is another beacon's pulse, shorter by at least a millimetre.
        if (std::abs(r.range_m - truth_m) > 1e-6) {
          ++wrong;
          EXPECT_LT(r.range_m, truth_m);
        }
      }
      constexpr double kSameFormulaMps = 1e-12;  // the node's own formula, rounding only
      EXPECT_NEAR(s.speed_of_sound_mps, c, kSameFormulaMps);
    });
    for (int64_t t = options.start_utime; t <= options.start_utime + 20'000'000; t += 10'000) {
      node.Tick(t);
    }
    EXPECT_EQ(node.air().counters().early, wrong);
    if (mode == FiringPlanOptions::Mode::kTdma) {
      EXPECT_EQ(wrong, 0);
      EXPECT_EQ(node.air().counters().armed_in_tail, 0);
      EXPECT_GT(ranges, 8 * 3 * 20 * node.air().rate_hz() - 8 * 3 * 2);
    } else {
      // Three beacons at 10 Hz in a hall whose slot is 0.11 s: most ranges
      // are lost (armed in a tail, dropped) or wrong.
      EXPECT_GT(node.air().counters().corrupted(), node.air().counters().pairs / 2);
      EXPECT_GT(wrong, 0);
    }
  }
}

}  // namespace
}  // namespace roomfix
