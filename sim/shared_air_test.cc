#include "sim/shared_air.h"

#include <gtest/gtest.h>

#include "sim/wall_devices.h"
#include "tests/testing/demo_site.h"
#include "tests/testing/test_paths.h"

namespace roomfix {
namespace {

Site DemoRoom() {
  Site site;
  std::string error;
  EXPECT_TRUE(LoadSite(testing::DemoSitePath(), &site, &error)) << error;
  return site;
}

// The demo room with n robots, each with a beacon, all driving the first
// robot's trajectory (their sound, not their places, is under test).
Site DemoRoomWithBeacons(int n) {
  Site site = DemoRoom();
  const SimulatedRobot first = site.simulation.robots.at(0);
  const Beacon beacon = site.beacons.at(0);
  for (int k = 2; k <= n; ++k) {
    Beacon b = beacon;
    b.id = k;
    b.address = beacon.address + static_cast<uint64_t>(k);
    site.beacons.push_back(b);
    site.robots.push_back({10 + k, "robot" + std::to_string(k), k, 1.0});
    site.simulation.robots.push_back({10 + k, first.trajectory});
  }
  return site;
}

TEST(SharedAir, TheTdmaTableKeepsTwelveBeaconsApartWithDriftAndLostAnnouncements) {
  const Site site = DemoRoom();
  SharedAirOptions o;
  o.clock_ppm = 50.0;
  o.sync_loss_probability = 0.2;  // every fifth announcement unheard by the other beacons
  const AirBenchRow row = MeasureAir(site, 12, o, 120.0);
  // 12 slots of the demo room's slot each, no overlap anywhere.
  EXPECT_GT(row.counters.firings, 12 * 120 * row.rate_per_beacon_hz - 12);
  EXPECT_EQ(row.counters.corrupted(), 0);
  EXPECT_EQ(row.counters.none, 0);
  EXPECT_EQ(row.counters.own, row.counters.pairs);
}

TEST(SharedAir, FreeRunningBeaconsCollide) {
  const Site site = DemoRoom();
  SharedAirOptions o;
  o.mode = FiringPlanOptions::Mode::kFreeRunning;
  // One beacon at 10 Hz in the demo room: its own tail has died before its
  // next firing (the slot is below 0.1 s).
  const AirBenchRow one = MeasureAir(site, 1, o, 60.0);
  EXPECT_EQ(one.counters.corrupted(), 0);
  // Two at 10 Hz on their own clocks: whenever their phases come within a
  // slot of each other, which random phases do in most runs (2 slots of
  // the 0.1 s period), both corrupt. Averaged over seeds, far above zero.
  int64_t corrupted = 0, pairs = 0;
  for (uint64_t seed = 1; seed <= 10; ++seed) {
    o.seed = seed;
    const AirBenchRow two = MeasureAir(site, 2, o, 20.0);
    corrupted += two.counters.corrupted();
    pairs += two.counters.pairs;
  }
  EXPECT_GT(static_cast<double>(corrupted) / pairs, 0.2);
  // Twelve at 10 Hz: a firing every 8 ms on average against a slot of
  // several tens of ms: almost everything is corrupted.
  o.seed = 1;
  const AirBenchRow twelve = MeasureAir(site, 12, o, 20.0);
  EXPECT_GT(twelve.corrupted_share(), 0.9);
}

TEST(VirtualWallDevices, ReportsWhatTheDetectorsTimedAmongCollidingBeacons) {
  const Site site = DemoRoomWithBeacons(4);
  for (auto mode : {FiringPlanOptions::Mode::kTdma, FiringPlanOptions::Mode::kFreeRunning}) {
    WallDevicesOptions o;
    o.schedule = mode;
    o.faults.ultrasound.sigma_m = 0.0;
    o.start_utime = 1'000'000;
    VirtualWallDevices devices(site, o);
    std::vector<uint8_t> bytes;
    for (int64_t t = o.start_utime; t <= o.start_utime + 30'000'000; t += 10'000) {
      devices.Advance(t, &bytes);
    }
    int64_t corrupted = 0, reports = 0;
    for (const auto& [key, record] : devices.ledger()) {
      for (const FiringRecord::Report& r : record.reports) {
        ++reports;
        if (r.air == Detection::Kind::kEarly || r.air == Detection::Kind::kArmedInTail) {
          ++corrupted;
          // A corrupted report never carries the true flight: it is shorter.
          const Receiver& rc = *site.FindReceiver(r.receiver_id);
          const GroundTruthPose p = site.simulation.robots[0].trajectory->PoseAt(
              (record.fire_utime - o.start_utime) * 1e-6);
          const double true_tof_s = std::hypot(rc.position_m[0] - p.x_m, rc.position_m[1] - p.y_m,
                                               rc.position_m[2] - site.beacons[0].height_m) /
                                    SpeedOfSound(site.simulation.temperature_c);
          EXPECT_LT(r.time_of_flight_ns * 1e-9, true_tof_s);
        }
      }
    }
    EXPECT_EQ(devices.air().counters().corrupted(), corrupted);
    if (mode == FiringPlanOptions::Mode::kTdma) {
      EXPECT_EQ(corrupted, 0);
      // Four beacons share a frame of four slots.
      constexpr double kSameDivisionHz = 1e-9;  // the same quotient, rounding only
      EXPECT_NEAR(devices.air().rate_hz(), 1.0 / (4 * devices.air().decay().slot_s),
                  kSameDivisionHz);
    } else {
      EXPECT_GT(corrupted, reports / 10);
    }
  }
}

}  // namespace
}  // namespace roomfix
