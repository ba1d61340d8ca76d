#include "core/world/air_model.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "core/world/ultrasound_model.h"

namespace roomfix {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// Tolerances, each for its reason.
// ISO 9613-1's table prints dB/km to two decimals.
constexpr double kIsoTableDbPerKm = 0.01;
// Sabine's T60 in a mirror room against the air-only bound: the walls'
// share S a / (4 m V) of the absorption, 2 % for Room(200, 200, 50, 0.01).
constexpr double kWallsShareOfT60 = 0.02;
// Closed forms recomputed here from the same formulas: only rounding and
// the order of operations differ. T60 goes through log and a division of
// values ~1e3 (the test's 4.3429448 is 10 / ln 10 to 8 digits: 1e-6 s);
// the others are sums and logs of values ~10.
constexpr double kT60FormulaS = 1e-6;
constexpr double kClosedFormM = 1e-9;
constexpr double kClosedFormDb = 1e-9;
constexpr double kClosedFormS = 1e-9;
constexpr double kExactS = 1e-12;
// Times in the air channel are microsecond integers turned into seconds.
constexpr double kMicrosecondRoundingS = 1e-9;

// A bare room with three receivers near the ceiling.
Site Room(double x_m, double y_m, double h_m, double wall_absorption) {
  Site site;
  site.room.size_x_m = x_m;
  site.room.size_y_m = y_m;
  site.room.height_m = h_m;
  site.receivers = {{1, 1, {}, {0.0, 0.0, h_m}, 0.0},
                    {2, 2, {}, {x_m, 0.0, h_m}, 0.0},
                    {3, 3, {}, {x_m, y_m, h_m}, 0.0}};
  site.acoustics.wall_absorption = wall_absorption;
  return site;
}

TEST(AirAbsorption, MatchesIso9613AtAudioAndUltrasound) {
  // ISO 9613-1 table at 20 degC, 50% RH: 4.66 dB/km at 1 kHz (the formula's
  // own table; rounding of the published value: 0.01 dB/km).
  EXPECT_NEAR(AirAbsorptionDbPerM(1000.0, 20.0, 50.0) * 1000.0, 4.66, kIsoTableDbPerKm);
  // At 40 kHz indoors (20 degC, 30-70% RH) air absorbs 1.1 to 1.4 dB/m.
  for (double rh : {30.0, 40.0, 50.0, 60.0, 70.0}) {
    const double a = AirAbsorptionDbPerM(40000.0, 20.0, rh);
    EXPECT_GT(a, 1.0) << rh;
    EXPECT_LT(a, 1.4) << rh;
  }
  // Dry air absorbs far less at 40 kHz (oxygen's relaxation needs water).
  EXPECT_LT(AirAbsorptionDbPerM(40000.0, 20.0, 5.0),
            0.5 * AirAbsorptionDbPerM(40000.0, 20.0, 50.0));
}

TEST(RoomDecay, AirAloneBoundsTheReverberationTimeOfAHugeMirrorRoom) {
  // With walls that absorb almost nothing, Sabine's T60 tends to
  // 60 dB / (c alpha): the air absorbs 60 dB over c T60 metres.
  const Site site = Room(200.0, 200.0, 50.0, 0.01);
  const RoomDecay d = ComputeRoomDecay(site, 20.0);
  const double bound_s = 60.0 / (SpeedOfSound(20.0) * d.air_absorption_db_per_m);
  EXPECT_LT(d.reverberation_time_s, bound_s);
  // 2% is the walls' share: S a / (4 m V) = 0.02 for this room.
  EXPECT_NEAR(d.reverberation_time_s, bound_s, kWallsShareOfT60 * bound_s);
}

TEST(RoomDecay, SizesASlotFromFlightDecayAndClock) {
  // A 12 x 8 x 3 m hall, walls absorbing 10%: worked by hand in
  // docs/trilateration.md ("Sharing the air").
  const Site site = Room(12.0, 8.0, 3.0, 0.1);
  const RoomDecay d = ComputeRoomDecay(site, 20.0);
  const double c = SpeedOfSound(20.0);
  const double alpha = AirAbsorptionDbPerM(40000.0, 20.0, 50.0);
  const double v = 12.0 * 8.0 * 3.0, s = 2.0 * (96.0 + 36.0 + 24.0);
  const double t60 = 24.0 * std::log(10.0) * v / (c * (s * 0.1 + 4.0 * alpha / 4.3429448 * v));
  EXPECT_NEAR(d.reverberation_time_s, t60, kT60FormulaS);
  const double r = std::sqrt(144.0 + 64.0 + 9.0);  // receiver 1 to the far floor corner
  EXPECT_NEAR(d.max_range_m, r, kClosedFormM);
  const double l1 = 20.0 * std::log10(r) + alpha * r + 10.0;
  EXPECT_NEAR(d.level_at_1m_db, l1, kClosedFormDb);
  const double tail = l1 + 10.0 * std::log10(4.0 * M_PI * c * 0.001 / v);
  EXPECT_NEAR(d.decay_s, 0.001 + tail / 60.0 * t60, kClosedFormS);
  EXPECT_NEAR(d.slot_s, r / c + d.decay_s + 0.001, kClosedFormS);
  // The figures the docs quote: a slot of 0.11 to 0.12 s.
  EXPECT_GT(d.slot_s, 0.10);
  EXPECT_LT(d.slot_s, 0.13);
}

TEST(RoomDecay, TheSiteCanStateItsMeasuredDecay) {
  Site site = Room(4.0, 3.0, 3.0, 0.1);
  site.acoustics.decay_s = 0.02;
  const RoomDecay d = ComputeRoomDecay(site, 20.0);
  EXPECT_TRUE(d.decay_from_site);
  EXPECT_DOUBLE_EQ(d.decay_s, 0.02);
  EXPECT_NEAR(d.slot_s, d.max_time_of_flight_s + 0.02 + 0.001, kExactS);
}

AirPulse Pulse(int64_t fire_utime, int beacon, int64_t seq, double arrival_s) {
  return AirPulse{fire_utime, beacon, seq, {arrival_s}};
}

TEST(AirChannel, AReceiverAloneTimesItsOwnPulse) {
  AirChannel air(/*decay_s=*/0.05, /*listen_s=*/0.03);
  const AirPulse p = Pulse(1'000'000, 1, 0, 0.010);
  air.Add(p);
  const auto d = air.Detect(p, {0.0101});
  EXPECT_EQ(d[0].kind, Detection::Kind::kOwn);
  EXPECT_DOUBLE_EQ(d[0].time_of_flight_s, 0.0101);
  // Nothing heard (a dropout, a detour beyond the window): nothing reported.
  EXPECT_EQ(air.Detect(p, {kNaN})[0].kind, Detection::Kind::kNone);
  EXPECT_EQ(air.Detect(p, {0.031})[0].kind, Detection::Kind::kNone);
}

TEST(AirChannel, TwoCloseFiringsCorruptEachOther) {
  AirChannel air(0.05, 0.03);
  // Beacon 1 fires at 0, heard after 10 ms; beacon 2 fires 5 ms later, its
  // pulse arrives after 3 ms: at 8 ms, before beacon 1's.
  const AirPulse a = Pulse(1'000'000, 1, 0, 0.010);
  const AirPulse b = Pulse(1'005'000, 2, 0, 0.003);
  air.Add(a);
  air.Add(b);
  const Detection da = air.Detect(a, {0.010})[0];
  EXPECT_EQ(da.kind, Detection::Kind::kEarly);
  EXPECT_NEAR(da.time_of_flight_s, 0.008,
              kMicrosecondRoundingS);  // beacon 2's arrival, taken for beacon 1's
  EXPECT_EQ(da.interferer_beacon_id, 2);
  // Beacon 2's receiver was armed at 5 ms with nothing above threshold yet,
  // so it hears its own pulse at 3 ms (8 ms).
  EXPECT_EQ(air.Detect(b, {0.003})[0].kind, Detection::Kind::kOwn);
  // Beacon 2 firing 12 ms after beacon 1: armed inside beacon 1's tail.
  AirChannel air2(0.05, 0.03);
  const AirPulse b2 = Pulse(1'012'000, 2, 0, 0.003);
  air2.Add(a);
  air2.Add(b2);
  EXPECT_EQ(air2.Detect(a, {0.010})[0].kind, Detection::Kind::kOwn);
  const Detection db = air2.Detect(b2, {0.003})[0];
  EXPECT_EQ(db.kind, Detection::Kind::kArmedInTail);
  EXPECT_EQ(db.interferer_beacon_id, 1);
  EXPECT_TRUE(db.corrupted());
}

TEST(AirChannel, APulseWhoseTailHasDiedDoesNotMatter) {
  AirChannel air(0.05, 0.03);
  const AirPulse a = Pulse(1'000'000, 1, 0, 0.010);
  // Beacon 1's pulse arrived at 10 ms and held the receiver to 60 ms; a
  // firing armed at 61 ms is clean; one armed at 59 ms is not.
  const AirPulse late = Pulse(1'061'000, 2, 0, 0.004);
  const AirPulse early = Pulse(1'059'000, 3, 0, 0.004);
  air.Add(a);
  air.Add(late);
  EXPECT_EQ(air.Detect(late, {0.004})[0].kind, Detection::Kind::kOwn);
  air.Add(early);
  EXPECT_EQ(air.Detect(early, {0.004})[0].kind, Detection::Kind::kArmedInTail);
}

TEST(AirChannel, OneBeaconFiringTooFastHitsItsOwnTail) {
  AirChannel air(0.05, 0.03);
  const AirPulse first = Pulse(1'000'000, 1, 0, 0.010);
  const AirPulse second = Pulse(1'040'000, 1, 1, 0.010);  // 25 Hz: 40 ms apart
  air.Add(first);
  air.Add(second);
  EXPECT_EQ(air.Detect(second, {0.010})[0].kind, Detection::Kind::kArmedInTail);
}

TEST(AirChannel, ForgetsOnlyPulsesWhoseTailIsOver) {
  AirChannel air(0.05, 0.03);
  air.Add(Pulse(1'000'000, 1, 0, 0.010));
  air.ForgetBefore(1'059'000);
  EXPECT_EQ(air.size(), 1u);  // its tail lasts to 1'060'000
  air.ForgetBefore(1'061'000);
  EXPECT_EQ(air.size(), 0u);
}

TEST(FiringPlanner, TdmaKeepsEveryBeaconInItsSlotDespiteDrift) {
  FiringPlanOptions o;
  o.slot_s = 0.1;
  o.rate_hz = 10.0;
  o.clock_ppm = 50.0;
  o.sync_jitter_s = 20e-6;
  const std::vector<int> slots = {0, 1, 2, 3, 4, 5, 6, 7};
  FiringPlanner plan(slots, 8, o);
  EXPECT_NEAR(plan.frame_s(), 0.8, kExactS);
  std::vector<int64_t> times;
  std::vector<size_t> order;
  for (int k = 0; k < 8 * 600; ++k) {  // 480 s
    order.push_back(plan.NextBeacon());
    times.push_back(plan.NextUtime());
    plan.Fire(/*announced=*/true);
  }
  // Consecutive firings are one slot apart, to within the sync jitter and
  // one slot's drift (100 ppm of 0.1 s = 10 us) -- never overlapping.
  for (size_t k = 1; k < times.size(); ++k) {
    constexpr int64_t kSyncJitterUs = 20, kSlotDriftUs = 10;
    EXPECT_NEAR(times[k] - times[k - 1], 100'000, kSyncJitterUs + kSyncJitterUs + kSlotDriftUs)
        << k;
    EXPECT_EQ(order[k], (order[k - 1] + 1) % 8) << k;
  }
}

TEST(FiringPlanner, WithoutAnnouncementsTdmaDriftsApartAtTheCrystalsRate) {
  FiringPlanOptions o;
  o.slot_s = 0.1;
  o.clock_ppm = 50.0;
  FiringPlanner plan({0, 1}, 2, o);
  // Free of sync for 1000 frames (200 s), two beacons drift apart by their
  // crystals' difference times 200 s.
  std::vector<int64_t> last(2, 0);
  for (int k = 0; k < 2000; ++k) {
    last[plan.NextBeacon()] = plan.NextUtime();
    plan.Fire(/*announced=*/false);
  }
  const double drift_s = std::abs((last[1] - last[0]) * 1e-6 - 0.1);
  const double expected_s = 200.0 * std::abs(plan.clock_error(1) - plan.clock_error(0));
  constexpr double kOneFrameTimingS = 0.2e-3;  // one frame's worth of timing
  EXPECT_NEAR(drift_s, expected_s, kOneFrameTimingS);
}

TEST(FiringPlanner, FreeRunningBeaconsKeepTheirOwnRate) {
  FiringPlanOptions o;
  o.mode = FiringPlanOptions::Mode::kFreeRunning;
  o.rate_hz = 10.0;
  FiringPlanner plan({0, 0, 0}, 1, o);
  std::vector<int> count(3, 0);
  while (plan.NextUtime() < 100'000'000) {
    ++count[plan.NextBeacon()];
    plan.Fire(true);
  }
  // 100 s at 10 Hz; the last firing may fall either side of the 100 s end.
  constexpr int kOneFiring = 1;
  for (int n : count) EXPECT_NEAR(n, 1000, kOneFiring);
}

TEST(SiteAcoustics, ParsedAndValidated) {
  const std::string base = R"(name: t
room: {size_m: [4, 3], height_m: 3}
receivers:
  - {id: 1, address: "0x0013A20041000001", position_m: [0, 0, 2.5]}
  - {id: 2, address: "0x0013A20041000002", position_m: [4, 0, 2.5]}
  - {id: 3, address: "0x0013A20041000003", position_m: [4, 3, 2.5]}
)";
  Site site;
  std::string error;
  ASSERT_TRUE(ParseSite(base + "acoustics: {wall_absorption: 0.3, decay_s: 0.02}\n", "t.yaml", ".",
                        &site, &error))
      << error;
  EXPECT_DOUBLE_EQ(site.acoustics.wall_absorption, 0.3);
  ASSERT_TRUE(site.acoustics.decay_s.has_value());
  EXPECT_FALSE(ParseSite(base + "acoustics: {wall_absorption: 0}\n", "t.yaml", ".", &site, &error));
  EXPECT_NE(error.find("acoustics.wall_absorption"), std::string::npos) << error;
  EXPECT_FALSE(ParseSite(base + "acoustics: {decay: 0.1}\n", "t.yaml", ".", &site, &error));

  ASSERT_TRUE(ParseSite(base + "radios:\n  - {id: 1, device: /dev/ttyUSB0, receivers: [1, 2]}\n"
                               "  - {id: 2, receivers: [3]}\n",
                        "t.yaml", ".", &site, &error))
      << error;
  ASSERT_EQ(site.radios.size(), 2u);
  EXPECT_EQ(site.RadioOfReceiver(3)->id, 2);
  EXPECT_FALSE(
      ParseSite(base + "radios:\n  - {id: 1, receivers: [1, 2]}\n", "t.yaml", ".", &site, &error));
  EXPECT_NE(error.find("receiver 3 is on no radio"), std::string::npos) << error;
  EXPECT_FALSE(
      ParseSite(base + "radios:\n  - {id: 1, receivers: [1, 2, 3]}\n  - {id: 2, receivers: [3]}\n",
                "t.yaml", ".", &site, &error));
  EXPECT_NE(error.find("already on radios[0]"), std::string::npos) << error;
}

}  // namespace
}  // namespace roomfix
