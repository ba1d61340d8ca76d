#include "sim/ranges_node.h"

#include <gtest/gtest.h>

#include "core/trilat/trilateration.h"
#include "msgio/trilat_conversions.h"
#include "roomfix/range_set_t.hpp"
#include "tests/testing/test_paths.h"

namespace roomfix {
namespace {

TEST(SimRangesNode, FiresOnScheduleWithRangesThatPutTheBeaconOnItsTrajectory) {
  Site site;
  std::string error;
  ASSERT_TRUE(LoadSite(testing::SourceDir() + "/config/sites/demo_room.yaml", &site, &error));
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
    EXPECT_NEAR(fix.position_m.x(), truth.x_m, 1e-9);
    EXPECT_NEAR(fix.position_m.y(), truth.y_m, 1e-9);
  }
}

}  // namespace
}  // namespace roomfix
