// FirmwareWorld on the tests' own AVR programs (avr/mini_beacon.c,
// avr/mini_receiver.c): the demo room's beacon and four receivers as
// firmware, the XBee model carrying their API frames, the acoustic model
// driving the receivers' input capture. The coordinator's frames are what
// zigbee_bridge would read.
#include "sim/firmware/firmware_world.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <map>

#include "core/radio/wall_payload.h"
#include "core/world/site.h"
#include "tests/testing/demo_site.h"

namespace roomfix::firmware {
namespace {

std::string Program(const char* name) {
  return std::string(ROOMFIX_AVR_TEST_PROGRAMS) + "/" + name + ".elf";
}

FirmwareWorldOptions MiniOptions(int32_t latency_ns) {
  FirmwareWorldOptions o;
  o.beacon_elf = Program("mini_beacon");
  o.receiver_elf = Program("mini_receiver");
  // The mini programs talk to their modules at 115200 baud and send their
  // reports to the coordinator's address 0.
  o.device_baud = 115200.0;
  o.coordinator_address = 0;
  o.beacon_eeprom = [](const Beacon& b) {
    return std::vector<uint8_t>{static_cast<uint8_t>(b.id)};
  };
  o.receiver_eeprom = [latency_ns](const Receiver&) {
    const auto u = static_cast<uint32_t>(latency_ns);
    return std::vector<uint8_t>{static_cast<uint8_t>(u >> 24), static_cast<uint8_t>(u >> 16),
                                static_cast<uint8_t>(u >> 8), static_cast<uint8_t>(u)};
  };
  return o;
}

struct Report {
  int receiver_id = 0;
  radio::WallMessage message;
};

std::vector<Report> ReportsOf(const FirmwareWorld& world, const Site& site) {
  std::vector<Report> out;
  for (const auto& f : world.coordinator_frames()) {
    radio::WallMessage m;
    if (radio::DecodeWallMessage(f.packet.payload.data(), f.packet.payload.size(), &m) !=
        radio::PayloadError::kOk) {
      continue;
    }
    if (m.type != radio::PayloadType::kRangeReport) continue;
    const Receiver* r = site.FindReceiverByAddress(f.packet.address64);
    if (r != nullptr) out.push_back({r->id, m});
  }
  return out;
}

// Reported minus true time of flight, per report with an echo, and the
// path length, matched by (beacon, firing number): the k-th pulse of a
// beacon is its firing k (the mini beacon counts from 0).
struct Error {
  double path_m;
  double error_s;
  bool weak;
};
std::vector<Error> TimeOfFlightErrors(const FirmwareWorld& world, const Site& site) {
  std::map<std::pair<int, int>, std::vector<PulseTruth>> by_receiver;
  for (const PulseTruth& p : world.pulses()) by_receiver[{p.beacon_id, p.receiver_id}].push_back(p);
  std::vector<Error> out;
  for (const Report& r : ReportsOf(world, site)) {
    if (r.message.flags & radio::kFlagNoEcho) continue;
    const auto& truths = by_receiver[{r.message.beacon_id, r.receiver_id}];
    if (r.message.firing_seq >= truths.size()) continue;
    const PulseTruth& t = truths[r.message.firing_seq];
    out.push_back({t.path_m, r.message.time_of_flight_ns * 1e-9 - t.time_of_flight_s,
                   (r.message.flags & radio::kFlagWeakEcho) != 0});
  }
  return out;
}

class MiniFirmware : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string error;
    ASSERT_TRUE(LoadSite(testing::DemoSitePath(), &site_, &error)) << error;
  }
  Site site_;
};

TEST_F(MiniFirmware, EveryFiringReachesTheCoordinatorAsAnnouncementAndFourReports) {
  std::string error;
  auto world = FirmwareWorld::Create(site_, MiniOptions(0), &error);
  ASSERT_NE(world, nullptr) << error;
  ASSERT_EQ(world->devices().size(), 5u);
  world->AdvanceTo(2.05);
  // The mini beacon fires every 100 ms from t = 0.1 s: 20 firings.
  constexpr int64_t kFirings = 20;
  EXPECT_EQ(world->counters().pulses, kFirings);
  int64_t announcements = 0;
  for (const auto& f : world->coordinator_frames()) {
    radio::WallMessage m;
    if (radio::DecodeWallMessage(f.packet.payload.data(), f.packet.payload.size(), &m) ==
            radio::PayloadError::kOk &&
        m.type == radio::PayloadType::kFiring) {
      ++announcements;
    }
  }
  EXPECT_EQ(announcements, kFirings);
  // The last firing's reports may still be on their way at 2.05 s.
  EXPECT_GE(static_cast<int64_t>(ReportsOf(*world, site_).size()), 4 * (kFirings - 1));
  EXPECT_EQ(world->counters().late_events, 0);
  for (const auto& d : world->devices()) EXPECT_EQ(d.core->counters().late_events, 0);
  EXPECT_EQ(world->counters().device_frame_errors, 0);
  EXPECT_EQ(world->counters().baud_mismatches, 0);
}

TEST_F(MiniFirmware, TimeOfFlightAgainstTheAcousticTruthPerDistance) {
  std::string error;
  auto world = FirmwareWorld::Create(site_, MiniOptions(0), &error);
  ASSERT_NE(world, nullptr) << error;
  world->AdvanceTo(10.0);
  const std::vector<Error> errors = TimeOfFlightErrors(*world, site_);
  ASSERT_GE(errors.size(), 300u);
  double sum = 0;
  for (const Error& e : errors) sum += e.error_s;
  const double bias_s = sum / errors.size();
  // The constant part: the radio path from the burst (started as the
  // announcement's last byte goes into UDR0) to the announcement's start
  // delimiter being readable at the receiver: the last byte on the wire
  // (87 us at 115200), the module's processing, CCA and turnaround, the
  // frame on the air, the other module's processing and the delimiter's
  // own byte. The mini receiver does not subtract it (latency 0); the
  // detector's threshold crossing (up to 60 us for the weakest echo) takes
  // from it.
  const XbeeTimingOptions timing;
  constexpr double kByteS = 10.0 / 115200.0;
  constexpr double kDetectorMaxS = 60e-6;
  const double fixed_s = 2 * kByteS + kCcaS + kTurnaroundS + AirTimeS(10, true);
  const double kRadioPathMinS =
      fixed_s + timing.tx_processing_min_s + timing.rx_processing_min_s - kDetectorMaxS;
  const double kRadioPathMaxS = fixed_s + timing.tx_processing_max_s + timing.rx_processing_max_s;
  EXPECT_LT(-bias_s, kRadioPathMaxS);
  EXPECT_GT(-bias_s, kRadioPathMinS);
  // Per half-metre of path: mean and spread about the overall bias.
  std::map<int, std::vector<double>> bins;
  for (const Error& e : errors)
    bins[static_cast<int>(e.path_m / 0.5)].push_back(e.error_s - bias_s);
  const double c = 331.3 + 0.606 * site_.simulation.temperature_c;
  for (const auto& [bin, v] : bins) {
    double m = 0, s2 = 0;
    for (double x : v) m += x;
    m /= v.size();
    for (double x : v) s2 += (x - m) * (x - m);
    const double sd = v.size() > 1 ? std::sqrt(s2 / (v.size() - 1)) : 0.0;
    std::printf("path %.1f-%.1f m: %zu ranges, bias %+.2f mm, spread %.2f mm\n", bin * 0.5,
                bin * 0.5 + 0.5, v.size(), m * c * 1e3, sd * c * 1e3);
    if (v.size() < 20) continue;
    // The jitter budget of the model's radio: the sender's processing
    // (50 us uniform, sd 14.4 us) and the receiver's (25 us, sd 7.2 us),
    // 16.1 us together, 5.5 mm; the detector's half-carrier steps add up to
    // 12.5 us between near and far echoes. Spread within 2x the jitter's.
    constexpr double kSpreadMaxS = 2 * 16.1e-6;
    EXPECT_LT(sd, kSpreadMaxS) << "bin " << bin;
    // A bin's mean differs from the overall bias by the detector's delay
    // (weaker echoes cross later: at most a few carrier half-periods).
    constexpr double kDetectorSpanS = 4 * 12.5e-6;
    EXPECT_LT(std::abs(m), kDetectorSpanS) << "bin " << bin;
  }
}

}  // namespace
}  // namespace roomfix::firmware
