#include "core/radio/range_assembler.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "core/world/ultrasound_model.h"
#include "tests/testing/demo_site.h"
#include "tests/testing/test_paths.h"

namespace roomfix::radio {
namespace {

// Ranges are rebuilt from whole nanoseconds of flight: 1 ns is 0.34 um.
constexpr double kRangeTolM = 1e-6;
constexpr int64_t kT0 = 1'700'000'000'000'000;  // an arbitrary host time, us
constexpr uint64_t kForeignAddress = 0x0013A200DEADBEEFull;

class RangeAssemblerTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string error;
    ASSERT_TRUE(LoadSite(testing::DemoSitePath(), &site_, &error)) << error;
  }

  // The beacon at (2.0, 1.5) at its height: every receiver is 2.5 m away in
  // the floor plane and 1.2 m below, so 2.773 m.
  double TrueRangeM(int receiver_index) const {
    const auto& p = site_.receivers[static_cast<size_t>(receiver_index)].position_m;
    const double dx = p[0] - 2.0;
    const double dy = p[1] - 1.5;
    const double dz = p[2] - site_.beacons[0].height_m;
    return std::sqrt(dx * dx + dy * dy + dz * dz);
  }

  uint32_t TofNs(double range_m, double temperature_c = 20.0) const {
    return TimeOfFlightToNs(range_m / SpeedOfSound(temperature_c));
  }

  const char* Send(RangeAssembler* a, uint64_t address, const WallMessage& m, int64_t utime) {
    payloads_.push_back(EncodeWallMessage(m));
    RadioPacket p;
    p.has_address64 = true;
    p.address64 = address;
    p.payload = payloads_.back().data();
    p.payload_size = payloads_.back().size();
    p.arrival_utime = utime;
    return a->OnPacket(p, &closed_);
  }

  const char* Announce(RangeAssembler* a, uint16_t seq, int64_t utime) {
    WallMessage m;
    m.type = PayloadType::kFiring;
    m.beacon_id = 1;
    m.firing_seq = seq;
    return Send(a, site_.beacons[0].address, m, utime);
  }

  const char* Report(RangeAssembler* a, int receiver_index, uint16_t seq, uint32_t tof_ns,
                     int64_t utime, int16_t temperature_centi_c = 2000, uint8_t flags = 0) {
    WallMessage m;
    m.type = PayloadType::kRangeReport;
    m.beacon_id = 1;
    m.firing_seq = seq;
    m.time_of_flight_ns = tof_ns;
    m.temperature_centi_c = temperature_centi_c;
    m.flags = flags;
    return Send(a, site_.receivers[static_cast<size_t>(receiver_index)].address, m, utime);
  }

  Site site_;
  std::vector<std::vector<uint8_t>> payloads_;
  std::vector<AssembledSet> closed_;
};

TEST_F(RangeAssemblerTest, PublishesAsSoonAsEveryReceiverAnswered) {
  RangeAssembler a(site_, {});
  EXPECT_EQ(Announce(&a, 10, kT0), nullptr);
  for (int i = 0; i < 4; ++i) {
    ASSERT_TRUE(closed_.empty()) << "closed before receiver " << i;
    EXPECT_EQ(Report(&a, i, 10, TofNs(TrueRangeM(i)), kT0 + 12'000 + i * 1000), nullptr);
  }
  ASSERT_EQ(closed_.size(), 1u);
  const AssembledSet& set = closed_[0];
  EXPECT_EQ(set.close_reason, CloseReason::kComplete);
  EXPECT_EQ(set.close_utime, kT0 + 15'000);
  EXPECT_EQ(set.fire_utime, kT0);
  EXPECT_TRUE(set.fire_time_from_announcement);
  EXPECT_EQ(set.beacon_id, 1);
  EXPECT_EQ(set.firing_seq, 10);
  EXPECT_EQ(set.num_expected, 4);
  EXPECT_DOUBLE_EQ(set.temperature_c, 20.0);
  EXPECT_DOUBLE_EQ(set.speed_of_sound_mps, 331.3 + 0.606 * 20.0);
  ASSERT_EQ(set.ranges.size(), 4u);
  for (int i = 0; i < 4; ++i) {
    EXPECT_EQ(set.ranges[i].receiver_id, site_.receivers[i].id);
    EXPECT_NEAR(set.ranges[i].range_m, TrueRangeM(i), kRangeTolM);
    EXPECT_EQ(set.ranges[i].receiver_position_m, site_.receivers[i].position_m);
    EXPECT_EQ(set.ranges[i].arrival_utime, kT0 + 12'000 + i * 1000);
  }
  EXPECT_EQ(a.open_firings(), 0);
  EXPECT_EQ(a.counter("sets_complete"), 1);
}

TEST_F(RangeAssemblerTest, ClosesAtTheDeadlineWithTheReportsThatCame) {
  AssemblerOptions options;
  options.deadline_s = 0.05;
  RangeAssembler a(site_, options);
  Announce(&a, 1, kT0);
  Report(&a, 0, 1, TofNs(TrueRangeM(0)), kT0 + 10'000);
  Report(&a, 2, 1, TofNs(TrueRangeM(2)), kT0 + 11'000);
  EXPECT_EQ(a.NextDeadlineUtime(), kT0 + 50'000);
  a.Advance(kT0 + 49'999, &closed_);
  EXPECT_TRUE(closed_.empty());
  a.Advance(kT0 + 50'000, &closed_);
  ASSERT_EQ(closed_.size(), 1u);
  EXPECT_EQ(closed_[0].close_reason, CloseReason::kDeadline);
  ASSERT_EQ(closed_[0].ranges.size(), 2u);
  EXPECT_EQ(closed_[0].ranges[0].receiver_id, 1);
  EXPECT_EQ(closed_[0].ranges[1].receiver_id, 3);
  EXPECT_EQ(a.NextDeadlineUtime(), INT64_MAX);
  // The missing receiver's report, once the set is out, is late.
  EXPECT_STREQ(Report(&a, 1, 1, TofNs(TrueRangeM(1)), kT0 + 60'000), "late_report");
  EXPECT_EQ(a.rejected("late_report"), 1);
}

TEST_F(RangeAssemblerTest, NeverMixesFiringsDeliveredInAShuffledBurst) {
  // A buffering radio releases the reports of five firings at once, in any
  // order: each set must hold exactly its own firing's times of flight.
  RangeAssembler a(site_, {});
  struct Pending {
    int receiver;
    uint16_t seq;
    uint32_t tof_ns;
  };
  std::vector<Pending> burst;
  for (uint16_t seq = 100; seq < 105; ++seq) {
    Announce(&a, seq, kT0 + (seq - 100) * 100);
    for (int r = 0; r < 4; ++r) {
      burst.push_back({r, seq, static_cast<uint32_t>(8'000'000 + seq * 1000 + r)});
    }
  }
  std::mt19937 rng(7);
  std::shuffle(burst.begin(), burst.end(), rng);
  for (const Pending& p : burst) {
    ASSERT_EQ(Report(&a, p.receiver, p.seq, p.tof_ns, kT0 + 20'000), nullptr);
  }
  ASSERT_EQ(closed_.size(), 5u);
  for (const AssembledSet& set : closed_) {
    ASSERT_EQ(set.ranges.size(), 4u);
    for (const AssembledRange& r : set.ranges) {
      const uint32_t expected =
          static_cast<uint32_t>(8'000'000 + set.firing_seq * 1000 + (r.receiver_id - 1));
      // Whole nanoseconds to microseconds: exact but for the division.
      constexpr double kNsToUsRoundOffUs = 1e-9;
      EXPECT_NEAR(r.time_of_flight_us, expected * 1e-3, kNsToUsRoundOffUs)
          << "firing " << set.firing_seq << " receiver " << r.receiver_id;
    }
  }
}

TEST_F(RangeAssemblerTest, DropsReportFromUnknownAddress) {
  RangeAssembler a(site_, {});
  Announce(&a, 1, kT0);
  WallMessage m;
  m.beacon_id = 1;
  m.firing_seq = 1;
  m.time_of_flight_ns = TofNs(2.8);
  EXPECT_STREQ(Send(&a, kForeignAddress, m, kT0 + 1000), "unknown_address");
  EXPECT_EQ(a.rejected("unknown_address"), 1);
  EXPECT_NE(a.last_rejection().find("0x0013A200DEADBEEF"), std::string::npos) << a.last_rejection();
  a.Advance(kT0 + 100'000, &closed_);
  ASSERT_EQ(closed_.size(), 1u);
  EXPECT_TRUE(closed_[0].ranges.empty());
}

TEST_F(RangeAssemblerTest, RecognisesShortAddressesTheSiteLists) {
  site_.receivers[0].short_address = 0x0101;
  RangeAssembler a(site_, {});
  Announce(&a, 1, kT0);
  WallMessage m;
  m.beacon_id = 1;
  m.firing_seq = 1;
  m.time_of_flight_ns = TofNs(TrueRangeM(0));
  payloads_.push_back(EncodeWallMessage(m));
  RadioPacket p;
  p.has_address16 = true;
  p.address16 = 0x0101;
  p.payload = payloads_.back().data();
  p.payload_size = payloads_.back().size();
  p.arrival_utime = kT0 + 9000;
  EXPECT_EQ(a.OnPacket(p, &closed_), nullptr);
  p.address16 = 0x0202;
  EXPECT_STREQ(a.OnPacket(p, &closed_), "unknown_address");
  EXPECT_NE(a.last_rejection().find("short address 0x0202"), std::string::npos);
  a.Flush(kT0 + 20'000, &closed_);
  ASSERT_EQ(closed_.size(), 1u);
  ASSERT_EQ(closed_[0].ranges.size(), 1u);
  EXPECT_EQ(closed_[0].ranges[0].receiver_id, 1);
}

TEST_F(RangeAssemblerTest, DropsPacketsFromTheWrongKindOfDevice) {
  RangeAssembler a(site_, {});
  WallMessage report;
  report.beacon_id = 1;
  report.time_of_flight_ns = TofNs(2.8);
  EXPECT_STREQ(Send(&a, site_.beacons[0].address, report, kT0), "wrong_sender");
  WallMessage fire;
  fire.type = PayloadType::kFiring;
  fire.beacon_id = 1;
  EXPECT_STREQ(Send(&a, site_.receivers[0].address, fire, kT0), "wrong_sender");
  fire.beacon_id = 2;
  EXPECT_STREQ(Send(&a, site_.beacons[0].address, fire, kT0), "wrong_sender");
  EXPECT_EQ(a.rejected("wrong_sender"), 3);
  EXPECT_EQ(a.open_firings(), 0);
}

TEST_F(RangeAssemblerTest, DropsDuplicateReportKeepingTheFirst) {
  RangeAssembler a(site_, {});
  Announce(&a, 1, kT0);
  EXPECT_EQ(Report(&a, 0, 1, TofNs(2.80), kT0 + 10'000), nullptr);
  EXPECT_STREQ(Report(&a, 0, 1, TofNs(2.90), kT0 + 11'000), "duplicate_report");
  EXPECT_STREQ(Announce(&a, 1, kT0 + 12'000), "duplicate_report");
  a.Flush(kT0 + 20'000, &closed_);
  ASSERT_EQ(closed_.size(), 1u);
  ASSERT_EQ(closed_[0].ranges.size(), 1u);
  EXPECT_NEAR(closed_[0].ranges[0].range_m, 2.80, kRangeTolM);
  EXPECT_EQ(closed_[0].fire_utime, kT0);
}

TEST_F(RangeAssemblerTest, DropsRangesTheRoomDoesNotAllow) {
  // Receiver 1 sits 1.2 m above the beacon's plane; the far floor corner at
  // the beacon's height is sqrt(4^2 + 3^2 + 1.2^2) = 5.14 m away.
  RangeAssembler a(site_, {});
  Announce(&a, 1, kT0);
  EXPECT_STREQ(Report(&a, 0, 1, TofNs(0.5), kT0 + 5000), "tof_out_of_range");
  EXPECT_STREQ(Report(&a, 1, 1, TofNs(6.0), kT0 + 5000), "tof_out_of_range");
  EXPECT_EQ(Report(&a, 2, 1, TofNs(1.2), kT0 + 5000), nullptr);
  EXPECT_EQ(Report(&a, 3, 1, TofNs(5.14), kT0 + 5000), nullptr);
  ASSERT_EQ(closed_.size(), 1u) << "answered by all four, two without a usable range";
  EXPECT_EQ(closed_[0].num_answered, 4);
  EXPECT_EQ(closed_[0].ranges.size(), 2u);
  EXPECT_EQ(a.rejected("tof_out_of_range"), 2);
}

TEST_F(RangeAssemblerTest, CountsNoEchoAsAnAnswerWithoutARange) {
  RangeAssembler a(site_, {});
  Announce(&a, 1, kT0);
  for (int i = 0; i < 3; ++i) Report(&a, i, 1, TofNs(TrueRangeM(i)), kT0 + 9000);
  EXPECT_STREQ(Report(&a, 3, 1, 0, kT0 + 30'000, 2000, kFlagNoEcho), "no_echo");
  ASSERT_EQ(closed_.size(), 1u);
  EXPECT_EQ(closed_[0].close_reason, CloseReason::kComplete);
  EXPECT_EQ(closed_[0].ranges.size(), 3u);
}

TEST_F(RangeAssemblerTest, DropsMalformedAndUnsupportedPayloads) {
  RangeAssembler a(site_, {});
  std::vector<uint8_t> bytes =
      EncodeWallMessage(WallMessage{PayloadType::kRangeReport, 1, 1, TofNs(2.8), 2000, 0});
  bytes[6] ^= 0x10;
  RadioPacket p;
  p.has_address64 = true;
  p.address64 = site_.receivers[0].address;
  p.payload = bytes.data();
  p.payload_size = bytes.size();
  p.arrival_utime = kT0;
  EXPECT_STREQ(a.OnPacket(p, &closed_), "malformed_payload");
  EXPECT_NE(a.last_rejection().find("CRC"), std::string::npos) << a.last_rejection();
  bytes[0] = 9;
  EXPECT_STREQ(a.OnPacket(p, &closed_), "unsupported_version");
  p.payload_size = 3;
  bytes[0] = kPayloadVersion;
  EXPECT_STREQ(a.OnPacket(p, &closed_), "malformed_payload");
  EXPECT_EQ(a.open_firings(), 0);
}

TEST_F(RangeAssemblerTest, DropsReportsForAnUnknownBeacon) {
  RangeAssembler a(site_, {});
  WallMessage m;
  m.beacon_id = 9;
  m.time_of_flight_ns = TofNs(2.8);
  EXPECT_STREQ(Send(&a, site_.receivers[0].address, m, kT0), "unknown_beacon");
}

TEST_F(RangeAssemblerTest, DropsReportsForStaleFirings) {
  AssemblerOptions options;
  options.stale_window_firings = 8;
  options.max_open_firings = 4;
  RangeAssembler a(site_, options);
  Announce(&a, 100, kT0);
  EXPECT_STREQ(Report(&a, 0, 91, TofNs(2.8), kT0 + 1000), "stale_firing");
  EXPECT_EQ(Report(&a, 0, 92, TofNs(2.8), kT0 + 1000), nullptr) << "8 behind is still open";
}

TEST_F(RangeAssemblerTest, UnwrapsTheFiringNumberAcrossItsWrapAround) {
  RangeAssembler a(site_, {});
  const uint16_t raw[] = {65534, 65535, 0, 1};
  int64_t t = kT0;
  for (uint16_t seq : raw) {
    Announce(&a, seq, t);
    for (int i = 0; i < 4; ++i) Report(&a, i, seq, TofNs(TrueRangeM(i)), t + 10'000);
    t += 100'000;
  }
  ASSERT_EQ(closed_.size(), 4u);
  for (size_t k = 0; k < 4; ++k) EXPECT_EQ(closed_[k].firing_seq, 65534 + static_cast<int64_t>(k));
}

TEST_F(RangeAssemblerTest, KeepsNumbersIncreasingWhenTheBeaconRestarts) {
  RangeAssembler a(site_, {});
  Announce(&a, 5000, kT0);
  a.Advance(kT0 + 100'000, &closed_);
  ASSERT_EQ(closed_.size(), 1u);
  EXPECT_EQ(Announce(&a, 0, kT0 + 200'000), nullptr);
  EXPECT_EQ(Report(&a, 0, 0, TofNs(2.8), kT0 + 210'000), nullptr);
  EXPECT_EQ(Announce(&a, 1, kT0 + 300'000), nullptr);
  a.Flush(kT0 + 400'000, &closed_);
  ASSERT_EQ(closed_.size(), 3u);
  EXPECT_EQ(closed_[1].firing_seq, 5001);
  EXPECT_EQ(closed_[1].ranges.size(), 1u);
  EXPECT_EQ(closed_[2].firing_seq, 5002);
  EXPECT_EQ(a.counter("beacon_restarts"), 1);
  // Late packets of the old numbering must not reuse published numbers.
  EXPECT_STREQ(Report(&a, 1, 65534, TofNs(2.8), kT0 + 410'000), "stale_firing");
  EXPECT_STREQ(Announce(&a, 65535, kT0 + 420'000), "stale_firing");
}

TEST_F(RangeAssemblerTest, TakesAnOldNumberAfterASilenceAsARestart) {
  RangeAssembler a(site_, {});
  for (uint16_t seq = 0; seq < 10; ++seq) Announce(&a, seq, kT0 + seq * 100'000);
  a.Advance(kT0 + 1'000'000, &closed_);
  ASSERT_EQ(closed_.size(), 10u);
  // A late copy of an announcement while the beacon is still talking is
  // just late.
  EXPECT_STREQ(Announce(&a, 9, kT0 + 1'000'000), "late_report");
  EXPECT_EQ(Announce(&a, 0, kT0 + 2'500'000), nullptr) << "the beacon is back, counting from 0";
  a.Flush(kT0 + 3'000'000, &closed_);
  ASSERT_EQ(closed_.size(), 11u);
  EXPECT_EQ(closed_.back().firing_seq, 10);
  EXPECT_EQ(a.counter("beacon_restarts"), 1);
}

TEST_F(RangeAssemblerTest, AReportBeforeItsAnnouncementAfterAPauseIsNoRestart) {
  // The beacon paused for 2 s; the first report of its next firing beats
  // the announcement (a broadcast can be slower than a unicast).
  RangeAssembler a(site_, {});
  for (uint16_t seq = 0; seq < 5; ++seq) Announce(&a, seq, kT0 + seq * 100'000);
  a.Advance(kT0 + 1'000'000, &closed_);
  const int64_t t = kT0 + 3'000'000;
  EXPECT_EQ(Report(&a, 0, 5, TofNs(TrueRangeM(0)), t), nullptr);
  EXPECT_EQ(Announce(&a, 5, t + 1000), nullptr);
  for (int i = 1; i < 4; ++i) EXPECT_EQ(Report(&a, i, 5, TofNs(TrueRangeM(i)), t + 5000), nullptr);
  ASSERT_EQ(closed_.size(), 6u);
  EXPECT_EQ(closed_.back().firing_seq, 5);
  EXPECT_EQ(closed_.back().ranges.size(), 4u);
  EXPECT_EQ(a.counter("beacon_restarts"), 0);
}

TEST_F(RangeAssemblerTest, ABufferedReportFromBeforeARestartCannotDerailTheNewCount) {
  RangeAssembler a(site_, {});
  for (uint16_t seq = 0; seq < 100; ++seq) Announce(&a, seq, kT0 + seq * 100'000);
  int64_t t = kT0 + 10'000'000;
  a.Advance(t, &closed_);
  closed_.clear();
  // A quick power cycle: the count starts again at 0; then an old report
  // of firing 98 arrives, which unwraps 98 firings ahead of the new count.
  EXPECT_EQ(Announce(&a, 0, t + 100'000), nullptr);
  EXPECT_STREQ(Report(&a, 3, 98, TofNs(TrueRangeM(3)), t + 110'000), "future_firing");
  for (int i = 0; i < 4; ++i)
    EXPECT_EQ(Report(&a, i, 0, TofNs(TrueRangeM(i)), t + 120'000), nullptr);
  EXPECT_EQ(Announce(&a, 1, t + 200'000), nullptr);
  EXPECT_EQ(a.counter("beacon_restarts"), 1);
  ASSERT_EQ(closed_.size(), 1u);
  EXPECT_EQ(closed_[0].firing_seq, 100) << "numbering continues after the old newest (99)";
  EXPECT_EQ(closed_[0].ranges.size(), 4u);
}

TEST_F(RangeAssemblerTest, NoticesAQuickRestartOnceItIsFarBehindTheNewestAnnouncement) {
  RangeAssembler a(site_, {});
  for (uint16_t seq = 0; seq < 30; ++seq) Announce(&a, seq, kT0 + seq * 100'000);
  // Restarted 0.2 s later, well inside the silence that would give it away.
  EXPECT_EQ(Announce(&a, 0, kT0 + 3'100'000), nullptr);
  EXPECT_EQ(a.counter("beacon_restarts"), 1);
  EXPECT_EQ(Report(&a, 0, 0, TofNs(TrueRangeM(0)), kT0 + 3'110'000), nullptr);
}

TEST_F(RangeAssemblerTest, NeverTakesTheNetworkAddressOfAZigbeeFrameForAShortAddress) {
  // A 0x90 frame whose module does not know the 64-bit source: its 16-bit
  // network address is assigned by the coordinator and may equal a MY
  // address of the site by chance.
  site_.receivers[0].short_address = 0x0101;
  RangeAssembler a(site_, {});
  WallMessage m;
  m.beacon_id = 1;
  m.time_of_flight_ns = TofNs(2.8);
  payloads_.push_back(EncodeWallMessage(m));
  RadioPacket p;
  p.has_address64 = true;
  p.address64 = 0xFFFFFFFFFFFFFFFFull;
  p.has_address16 = true;
  p.address16 = 0x0101;
  p.payload = payloads_.back().data();
  p.payload_size = payloads_.back().size();
  EXPECT_STREQ(a.OnPacket(p, &closed_), "unknown_address");
}

TEST_F(RangeAssemblerTest, OneStrayReportCannotCarryTheCountFarAhead) {
  // Found by the fuzzer: with no announcement for a while, a single report
  // far ahead moved the newest firing, made the beacon's real announcements
  // stale and, the closed-firing memory being a ring, let a firing be
  // published twice.
  RangeAssembler a(site_, {});
  Announce(&a, 101, kT0);
  for (int i = 0; i < 4; ++i) Report(&a, i, 101, TofNs(TrueRangeM(i)), kT0 + 9000);
  ASSERT_EQ(closed_.size(), 1u);
  const int64_t t = kT0 + 1'000'000;  // no announcement for a second
  EXPECT_STREQ(Report(&a, 2, 3084, TofNs(TrueRangeM(2)), t), "future_firing");
  EXPECT_STREQ(Report(&a, 2, 3084, TofNs(TrueRangeM(2)), t + 1000), "future_firing")
      << "the same receiver again is no corroboration";
  EXPECT_STREQ(Announce(&a, 101, t + 2000), "late_report");
  EXPECT_EQ(Announce(&a, 102, t + 100'000), nullptr);
  for (int i = 0; i < 4; ++i) {
    EXPECT_EQ(Report(&a, i, 102, TofNs(TrueRangeM(i)), t + 110'000), nullptr);
  }
  ASSERT_EQ(closed_.size(), 2u);
  EXPECT_EQ(closed_[1].firing_seq, 102);
}

TEST_F(RangeAssemblerTest, TwoReceiversCarryTheCountAcrossALongRadioGap) {
  // The coordinator heard nothing of the beacon for 10 s (100 firings):
  // reports from two receivers agree on the new count.
  RangeAssembler a(site_, {});
  Announce(&a, 1, kT0);
  a.Advance(kT0 + 1'000'000, &closed_);
  const int64_t t = kT0 + 10'000'000;
  EXPECT_STREQ(Report(&a, 0, 101, TofNs(TrueRangeM(0)), t), "future_firing");
  EXPECT_EQ(Report(&a, 1, 101, TofNs(TrueRangeM(1)), t + 1000), nullptr);
  EXPECT_EQ(Report(&a, 2, 101, TofNs(TrueRangeM(2)), t + 2000), nullptr);
  EXPECT_EQ(Report(&a, 0, 102, TofNs(TrueRangeM(0)), t + 100'000), nullptr);
  a.Flush(t + 200'000, &closed_);
  ASSERT_EQ(closed_.size(), 3u);
  EXPECT_EQ(closed_[1].firing_seq, 101);
  EXPECT_EQ(closed_[1].ranges.size(), 2u);
}

TEST_F(RangeAssemblerTest, UsesTheMedianPlausibleTemperatureForTheSpeedOfSound) {
  RangeAssembler a(site_, {});
  Announce(&a, 1, kT0);
  const int16_t temps[] = {2500, 2400, 2600, 9000};  // 90 degC: a failed sensor
  for (int i = 0; i < 4; ++i) {
    Report(&a, i, 1, TofNs(TrueRangeM(i), 25.0), kT0 + 9000, temps[i]);
  }
  ASSERT_EQ(closed_.size(), 1u);
  EXPECT_DOUBLE_EQ(closed_[0].temperature_c, 25.0);
  EXPECT_DOUBLE_EQ(closed_[0].speed_of_sound_mps, 331.3 + 0.606 * 25.0);
  for (int i = 0; i < 4; ++i) EXPECT_NEAR(closed_[0].ranges[i].range_m, TrueRangeM(i), kRangeTolM);
  EXPECT_EQ(a.counter("implausible_temperature"), 1);
}

TEST_F(RangeAssemblerTest, SubtractsEachReceiversCalibratedOffset) {
  site_.receivers[2].range_offset_m = 0.07;
  RangeAssembler a(site_, {});
  Announce(&a, 1, kT0);
  for (int i = 0; i < 4; ++i) Report(&a, i, 1, TofNs(TrueRangeM(i) + (i == 2 ? 0.07 : 0.0)), kT0);
  ASSERT_EQ(closed_.size(), 1u);
  EXPECT_NEAR(closed_[0].ranges[2].range_m, TrueRangeM(2), kRangeTolM);
}

TEST_F(RangeAssemblerTest, EstimatesTheFiringTimeFromTheFirstEchoWithoutAnAnnouncement) {
  RangeAssembler a(site_, {});
  Report(&a, 0, 3, 8'000'000, kT0 + 10'000);  // 8 ms of flight
  Report(&a, 1, 3, 9'000'000, kT0 + 12'000);
  a.Advance(kT0 + 60'000, &closed_);
  ASSERT_EQ(closed_.size(), 1u);
  EXPECT_FALSE(closed_[0].fire_time_from_announcement);
  EXPECT_EQ(closed_[0].fire_utime, kT0 + 2000);
  EXPECT_EQ(a.counter("missing_announcement"), 1);
}

TEST_F(RangeAssemblerTest, EvictsTheOldestFiringWhenTooManyAreOpen) {
  AssemblerOptions options;
  options.max_open_firings = 3;
  RangeAssembler a(site_, options);
  for (uint16_t seq = 1; seq <= 4; ++seq) Announce(&a, seq, kT0 + seq);
  ASSERT_EQ(closed_.size(), 1u);
  EXPECT_EQ(closed_[0].firing_seq, 1);
  EXPECT_EQ(closed_[0].close_reason, CloseReason::kEvicted);
  EXPECT_EQ(a.open_firings(), 3);
}

TEST(UnwrapSequence, PicksTheNearestValueOnEitherSide) {
  EXPECT_EQ(UnwrapSequence(0, 65535), 65536);
  EXPECT_EQ(UnwrapSequence(65535, 65536), 65535);
  EXPECT_EQ(UnwrapSequence(10, 5), 10);
  EXPECT_EQ(UnwrapSequence(32767, 0), 32767);
  EXPECT_EQ(UnwrapSequence(32768, 0), -32768);
  EXPECT_EQ(UnwrapSequence(1, 3 * 65536 + 65530), 4 * 65536 + 1);
}

TEST(AssemblerOptions, RejectsImpossibleSettings) {
  std::string error;
  AssemblerOptions o;
  EXPECT_TRUE(o.IsValid(&error)) << error;
  o.deadline_s = 0;
  EXPECT_FALSE(o.IsValid(&error));
  o = {};
  o.stale_window_firings = 100000;
  EXPECT_FALSE(o.IsValid(&error));
  o = {};
  o.max_open_firings = 0;
  EXPECT_FALSE(o.IsValid(&error));
  o = {};
  o.default_temperature_c = std::nan("");
  EXPECT_FALSE(o.IsValid(&error));
}

}  // namespace
}  // namespace roomfix::radio
