// FirmwareWorld on the project's firmware (firmware/beacon.c, receiver.c,
// built into build/firmware/ by avr-gcc) with the EEPROM images `roomfix
// devices` writes for the site: the times of flight the receivers report
// against the acoustic truth, two beacons sharing the air by the schedule,
// a receiver that reboots mid-run. Skipped when the firmware is not built.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

#include "core/radio/wall_payload.h"
#include "core/world/acoustic_paths.h"
#include "core/world/air_model.h"
#include "core/world/site.h"
#include "core/world/ultrasound_model.h"
#include "sim/firmware/firmware_world.h"
#include "sim/firmware/site_devices.h"
#include "tests/testing/demo_site.h"
#include "tests/testing/test_paths.h"

namespace roomfix::firmware {
namespace {

struct Report {
  int receiver_id = 0;
  uint64_t cycle = 0;
  radio::WallMessage message;
};

// The coordinator's frames that decode as range reports from a receiver of
// the site, and the announcements.
void Decode(const FirmwareWorld& world, const Site& site, std::vector<Report>* reports,
            std::vector<radio::WallMessage>* announcements) {
  for (const auto& f : world.coordinator_frames()) {
    radio::WallMessage m;
    if (radio::DecodeWallMessage(f.packet.payload.data(), f.packet.payload.size(), &m) !=
        radio::PayloadError::kOk) {
      continue;
    }
    if (m.type == radio::PayloadType::kFiring) {
      if (announcements != nullptr) announcements->push_back(m);
      continue;
    }
    const Receiver* r = site.FindReceiverByAddress(f.packet.address64);
    if (r != nullptr && reports != nullptr) reports->push_back({r->id, f.cycle, m});
  }
}

// Reported minus true time of flight (the truth: the path over the speed
// of sound), per report with an echo, with the path: a beacon's k-th pulse
// is its firing k (it counts from 0 at boot).
struct Error {
  int receiver_id;
  double path_m;
  double error_s;
};
std::vector<Error> TimeOfFlightErrors(const FirmwareWorld& world, const Site& site) {
  std::map<std::pair<int, int>, std::vector<PulseTruth>> truth;
  for (const PulseTruth& p : world.pulses()) truth[{p.beacon_id, p.receiver_id}].push_back(p);
  std::vector<Report> reports;
  Decode(world, site, &reports, nullptr);
  std::vector<Error> out;
  for (const Report& r : reports) {
    if (r.message.flags & radio::kFlagNoEcho) continue;
    const auto& t = truth[{r.message.beacon_id, r.receiver_id}];
    if (r.message.firing_seq >= t.size()) continue;
    const PulseTruth& p = t[r.message.firing_seq];
    out.push_back(
        {r.receiver_id, p.path_m, r.message.time_of_flight_ns * 1e-9 - p.time_of_flight_s});
  }
  return out;
}

std::string ReadFileOrEmpty(const std::string& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

void MeanAndSpread(const std::vector<double>& v, double* mean, double* sd) {
  double m = 0, s2 = 0;
  for (double x : v) m += x;
  m /= v.size();
  for (double x : v) s2 += (x - m) * (x - m);
  *mean = m;
  *sd = v.size() > 1 ? std::sqrt(s2 / (v.size() - 1)) : 0.0;
}

class ProjectFirmware : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string error;
    ASSERT_TRUE(LoadSite(testing::DemoSitePath(), &site_, &error)) << error;
    Configure();
  }
  void Configure() {
    std::string error;
    if (!ConfigureFirmwareForSite(site_, radio::DeviceConfigOptions{}, DefaultFirmwareDir(),
                                  &options_, &error)) {
      GTEST_SKIP() << "the project's firmware is not built: " << error;
    }
  }
  Site site_;
  FirmwareWorldOptions options_;
};

TEST_F(ProjectFirmware, TimeOfFlightAgainstTheAcousticTruthPerDistance) {
  std::string error;
  auto world = FirmwareWorld::Create(site_, options_, &error);
  ASSERT_NE(world, nullptr) << error;
  world->AdvanceTo(6.0);
  const std::vector<Error> errors = TimeOfFlightErrors(*world, site_);
  // 10 firings a second from the first frame on, four receivers each.
  constexpr size_t kMinRanges = 4 * 50;
  ASSERT_GE(errors.size(), kMinRanges);
  const double c = SpeedOfSound(site_.simulation.temperature_c);
  std::vector<double> all;
  for (const Error& e : errors) all.push_back(e.error_s);
  double bias_s, spread_s;
  MeanAndSpread(all, &bias_s, &spread_s);
  std::printf("all: %zu ranges, bias %+.2f mm, spread %.2f mm\n", all.size(), bias_s * c * 1e3,
              spread_s * c * 1e3);
  // The firmware subtracts the radio's nominal latency and a detector delay
  // of 50 us (DeviceConfigOptions::detector_delay_us); the model's detector
  // crosses its threshold one or two carrier half-periods (12.5 us) after
  // the arrival, 19-31 us: the constant left is what the survey's range
  // offsets absorb, and lies within that difference and the radio model's
  // processing spreads around their nominal means.
  constexpr double kConstantBiasMaxS = 50e-6;
  EXPECT_LT(std::abs(bias_s), kConstantBiasMaxS);
  std::map<int, std::vector<double>> bins;
  for (const Error& e : errors) bins[static_cast<int>(e.path_m / 0.5)].push_back(e.error_s);
  for (const auto& [bin, v] : bins) {
    double m, sd;
    MeanAndSpread(v, &m, &sd);
    std::printf("path %.1f-%.1f m: %zu ranges, bias %+.2f mm, spread %.2f mm\n", bin * 0.5,
                bin * 0.5 + 0.5, v.size(), m * c * 1e3, sd * c * 1e3);
    if (v.size() < 20) continue;
    // The radio's jitter: the sender's processing (50 us uniform, sd 14.4
    // us) and the receiver's (25 us, sd 7.2 us), 16.1 us together (5.5 mm
    // of sound), and the firmware's interrupt latencies (a few cycles).
    // Spread within 1.5x that.
    constexpr double kSpreadMaxS = 1.5 * 16.1e-6;
    EXPECT_LT(sd, kSpreadMaxS) << "bin " << bin;
    // A bin's mean differs from the overall bias by the detector's delay:
    // weaker (farther) echoes cross their threshold later, by up to two
    // carrier half-periods over this room's distances.
    constexpr double kDetectorSpanS = 2 * 12.5e-6;
    EXPECT_LT(std::abs(m - bias_s), kDetectorSpanS) << "bin " << bin;
  }
  EXPECT_EQ(world->counters().late_events, 0);
  for (const auto& d : world->devices()) EXPECT_EQ(d.core->counters().late_events, 0);
}

// Issue #30: non-line-of-sight from geometry in the firmware-in-the-loop
// acoustic model too. The pillar site (config/sites/demo_room_pillar.yaml)
// hides the robot from receiver 3 for much of each lap; receiver 3's
// firmware then times the echo off the far walls (a range long by the
// detour, to the same tick as a direct path) or, where no echo is above its
// threshold, reports no echo.
TEST_F(ProjectFirmware, APillarMakesReceiverThreeTimeTheEchoOrHearNothing) {
  std::string error;
  ASSERT_TRUE(
      LoadSite(testing::SourceDir() + "/config/sites/demo_room_pillar.yaml", &site_, &error))
      << error;
  Configure();
  auto world = FirmwareWorld::Create(site_, options_, &error);
  ASSERT_NE(world, nullptr) << error;
  // Half a lap of the reference circle (14 s a lap) from the start.
  world->AdvanceTo(8.0);
  std::map<std::pair<int, uint32_t>, PulseTruth> truth;  // (receiver, firing)
  std::map<int, int> firings_of_beacon;
  std::map<AudiblePath::Kind, int> kinds;
  for (const PulseTruth& p : world->pulses()) {
    const int k = firings_of_beacon[p.beacon_id * 100 + p.receiver_id]++;
    truth[{p.receiver_id, static_cast<uint32_t>(k)}] = p;
    if (p.receiver_id == 3) ++kinds[p.kind];
  }
  std::printf("receiver 3: %d direct, %d echoes, %d unheard pulses\n",
              kinds[AudiblePath::Kind::kDirect], kinds[AudiblePath::Kind::kReflected],
              kinds[AudiblePath::Kind::kNone]);
  ASSERT_GT(kinds[AudiblePath::Kind::kReflected] + kinds[AudiblePath::Kind::kNone], 10);
  std::vector<Report> reports;
  Decode(*world, site_, &reports, nullptr);
  const double c = SpeedOfSound(site_.simulation.temperature_c);
  int echoes_timed = 0, echoes_late = 0, unheard_reported = 0;
  for (const Report& r : reports) {
    const auto it = truth.find({r.receiver_id, r.message.firing_seq});
    if (it == truth.end()) continue;
    const PulseTruth& p = it->second;
    if (p.kind == AudiblePath::Kind::kNone) {
      EXPECT_NE(r.message.flags & radio::kFlagNoEcho, 0) << "firing " << r.message.firing_seq;
      ++unheard_reported;
    } else if (p.kind == AudiblePath::Kind::kReflected) {
      if ((r.message.flags & radio::kFlagNoEcho) != 0) {
        ++echoes_late;  // past the receiver's listening window
        continue;
      }
      // The detector's own crossing of the echo (weaker than a direct
      // path, it crosses its threshold later, up to hundreds of us), less
      // the 50 us detector delay the firmware subtracts, within the radio's
      // jitter (3 sd of the direct-path test's 1.5 x 16.1 us) and the radio
      // model's nominal mismatch (the direct paths' residual, a few us;
      // 20 us allowed). So the range reads long by at least the detour.
      ASSERT_GE(p.detector_rise_cycle, 0);
      const double detected_s = (p.detector_rise_cycle - p.fire_cycle) / 16e6;
      constexpr double kDetectorDelayS = 50e-6;
      constexpr double kToleranceS = 3 * 1.5 * 16.1e-6 + 20e-6;
      const double reported_s = r.message.time_of_flight_ns * 1e-9;
      EXPECT_NEAR(reported_s, detected_s - kDetectorDelayS, kToleranceS);
      EXPECT_GT(reported_s * c - p.direct_m, 0.5 * (p.path_m - p.direct_m));
      ++echoes_timed;
    }
  }
  std::printf(
      "receiver 3: %d echoes timed, %d past its listening window, %d unheard; reported as no "
      "echo: the last two\n",
      echoes_timed, echoes_late, unheard_reported);
  EXPECT_GT(echoes_timed + unheard_reported, 10);
}

TEST_F(ProjectFirmware, AReceiverRebootedMidRunComesBackAndTheOthersNeverMissAFiring) {
  // Receiver 2 (device index 1) loses power at 1.5 s.
  constexpr size_t kRebooted = 1;
  constexpr double kRebootS = 1.5;
  options_.reboots.push_back({kRebooted, kRebootS});
  std::string error;
  auto world = FirmwareWorld::Create(site_, options_, &error);
  ASSERT_NE(world, nullptr) << error;
  world->AdvanceTo(3.5);
  const int rebooted_id = world->devices()[kRebooted].id;
  EXPECT_EQ(world->devices()[kRebooted].core->counters().resets, 1);
  EXPECT_EQ(world->counters().reboots, 1);
  std::vector<Report> reports;
  std::vector<radio::WallMessage> announcements;
  Decode(*world, site_, &reports, &announcements);
  std::map<int, std::set<int>> receivers_of_firing;
  double last_before = -1, first_after = -1;
  for (const Report& r : reports) {
    receivers_of_firing[r.message.firing_seq].insert(r.receiver_id);
    if (r.receiver_id != rebooted_id) continue;
    const double t = r.cycle / 16e6;
    if (t < kRebootS) last_before = t;
    if (t > kRebootS && first_after < 0) first_after = t;
  }
  EXPECT_GT(last_before, kRebootS - 0.2);
  ASSERT_GT(first_after, kRebootS);
  // Back within its boot (self test, configuration) and one firing frame.
  constexpr double kBackWithinS = 0.5;
  EXPECT_LT(first_after - kRebootS, kBackWithinS);
  // Every announced firing but the last (still in flight) has the three
  // other receivers' reports.
  ASSERT_GE(announcements.size(), 30u);
  for (size_t k = 0; k + 1 < announcements.size(); ++k) {
    const auto& got = receivers_of_firing[announcements[k].firing_seq];
    for (const auto& d : world->devices()) {
      if (d.role == FirmwareWorld::Device::Role::kReceiver && d.id != rebooted_id) {
        EXPECT_EQ(got.count(d.id), 1u)
            << "firing " << announcements[k].firing_seq << " receiver " << d.id;
      }
    }
  }
}

// The demo site with a second robot carrying beacon 2, parked in the far
// quarter of the room; "" with *error when a file cannot be written.
std::string TwoBeaconSite(const testing::TempDir& dir, std::string* error) {
  const std::string path = testing::WriteDemoSiteVariant(
      dir, "two_beacons", "  - {id: 1, address: \"0x0013A20042000001\", height_m: 1.3}\n",
      "  - {id: 1, address: \"0x0013A20042000001\", height_m: 1.3}\n"
      "  - {id: 2, address: \"0x0013A20042000002\", height_m: 1.3}\n",
      error);
  if (path.empty()) return "";
  std::string text = ReadFileOrEmpty(path);
  auto replace = [&](const std::string& from, const std::string& to) {
    const size_t at = text.find(from);
    if (at == std::string::npos) {
      *error = "demo site has no \"" + from + "\"";
      return false;
    }
    text.replace(at, from.size(), to);
    return true;
  };
  if (!replace("  - {id: 1, name: robot1, beacon_id: 1}\n",
               "  - {id: 1, name: robot1, beacon_id: 1}\n"
               "  - {id: 2, name: robot2, beacon_id: 2}\n") ||
      !replace("      trajectory: {type: reference_circle}\n",
               "      trajectory: {type: reference_circle}\n"
               "    - robot_id: 2\n"
               "      trajectory: {type: static, position_m: [3.3, 2.5]}\n")) {
    return "";
  }
  std::ofstream(path) << text;
  return path;
}

// Two beacons switched on together (one power supply): each fires first in
// its own slot of the frame it listened through, and the later one follows
// the earlier (docs/radio_protocol.md 5a). The firmware's first schedule
// kept them together (152 of 160 arrivals within the decay of the other's).
TEST_F(ProjectFirmware, TwoBeaconsShareTheAirByTheScheduleWithoutACollision) {
  const testing::TempDir dir;
  std::string error;
  const std::string path = TwoBeaconSite(dir, &error);
  ASSERT_FALSE(path.empty()) << error;
  ASSERT_TRUE(LoadSite(path, &site_, &error)) << error;
  Configure();
  auto world = FirmwareWorld::Create(site_, options_, &error);
  ASSERT_NE(world, nullptr) << error;
  ASSERT_EQ(world->devices().size(), 6u);
  world->AdvanceTo(4.0);
  // Both beacons fire, in turn.
  std::map<int, int> pulses_of;
  for (const PulseTruth& p : world->pulses()) ++pulses_of[p.beacon_id];
  constexpr int kReceivers = 4;
  constexpr int kMinPulses = 4 * 15 * kReceivers;  // some of the first frame goes to listening
  EXPECT_GE(pulses_of[1], kMinPulses / 4);
  EXPECT_GE(pulses_of[2], kMinPulses / 4);
  // No receiver's detector rises while another beacon's pulse holds it:
  // two pulses from different beacons reach each receiver more than the
  // room's decay apart.
  const double decay_s = ComputeRoomDecay(site_, site_.simulation.temperature_c).decay_s;
  std::map<int, std::vector<std::pair<double, int>>> arrivals;
  for (const PulseTruth& p : world->pulses()) {
    arrivals[p.receiver_id].push_back({p.fire_cycle / 16e6 + p.time_of_flight_s, p.beacon_id});
  }
  int collisions = 0;
  for (auto& [receiver, a] : arrivals) {
    std::sort(a.begin(), a.end());
    for (size_t k = 1; k < a.size(); ++k) {
      if (a[k].second != a[k - 1].second && a[k].first - a[k - 1].first < decay_s) ++collisions;
    }
  }
  EXPECT_EQ(collisions, 0);
  // And every range reported is its own beacon's: within the radio's
  // jitter and the detector's delay of the truth.
  const std::vector<Error> errors = TimeOfFlightErrors(*world, site_);
  ASSERT_GE(errors.size(), 100u);
  constexpr double kOwnPulseS = 150e-6;  // 5 cm; another pulse is ms off
  for (const Error& e : errors) EXPECT_LT(std::abs(e.error_s), kOwnPulseS) << e.receiver_id;
}

}  // namespace
}  // namespace roomfix::firmware
