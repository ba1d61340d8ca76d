// The real firmware images (build/firmware/*.elf), run instruction by
// instruction in simavr on a simulated ATmega328P at 16 MHz, one device at a
// time: bytes in and out of the UART with their cycle, the beacon's drive
// pins watched, the receiver's detector pins driven. What comes out is read
// with the bridge's own decoders (core/radio). The many-device world with
// the radio and acoustic models is the simulator's (sim/, `--devices
// firmware`).
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

#include "core/radio/device_config.h"
#include "core/radio/wall_payload.h"
#include "core/radio/xbee_frame.h"
#include "core/world/file_io.h"
#include "tests/firmware/avr_device.h"
#include "tests/testing/demo_site.h"
#include "tests/testing/test_paths.h"

namespace roomfix::testing {
namespace {

using radio::DeviceConfig;
using radio::DeviceRole;
constexpr uint64_t kUs = AvrDevice::kCyclesPerUs;
constexpr uint64_t kMs = 1000 * kUs;
constexpr uint64_t kByte = AvrDevice::kCyclesPerUartByte;

std::string ElfPath(const std::string& name) { return BuildDir() + "/firmware/" + name + ".elf"; }

bool HaveElf(const std::string& name) {
  struct stat st {};
  return stat(ElfPath(name).c_str(), &st) == 0;
}

#define REQUIRE_ELF(name)                                                                  \
  if (!HaveElf(name))                                                                      \
  GTEST_SKIP() << ElfPath(name) << " is missing: the firmware needs avr-gcc and avr-libc " \
               << "(apt-get install gcc-avr binutils-avr avr-libc)"

// The demo room's images, as `roomfix devices` writes them.
std::vector<radio::DeviceImage> DemoImages() {
  Site site;
  std::string error;
  EXPECT_TRUE(LoadSite(DemoSitePath(), &site, &error)) << error;
  std::vector<radio::DeviceImage> images;
  EXPECT_TRUE(radio::DeviceConfigsForSite(site, {}, &images, &error)) << error;
  return images;
}

DeviceConfig DemoBeacon() { return DemoImages().at(0).config; }
DeviceConfig DemoReceiver() { return DemoImages().at(1).config; }

// A TX request the firmware sent, with the cycle of its last byte.
struct TxFrame {
  uint64_t last_cycle = 0;
  std::vector<uint8_t> wire;  // the bytes on the UART
  std::vector<uint8_t> data;  // frame data, type first
  uint8_t type() const { return data.at(0); }
  // RF data after the TX request's header (0x01: 5 bytes, 0x00: 11).
  std::vector<uint8_t> payload() const {
    const size_t header = type() == 0x01 ? 5 : 11;
    return std::vector<uint8_t>(data.begin() + header, data.end());
  }
};

class TxCollector : public radio::FrameSink {
 public:
  void OnFrame(const uint8_t* data, size_t size, uint64_t) override {
    TxFrame f;
    f.data.assign(data, data + size);
    frames.push_back(f);
  }
  void OnFrameError(const radio::FrameErrorInfo&) override { ++errors; }
  std::vector<TxFrame> frames;
  int errors = 0;
};

// Decodes the device's UART output with the bridge's frame decoder.
std::vector<TxFrame> Frames(const AvrDevice& device, int* errors = nullptr) {
  radio::FrameDecoder decoder;
  TxCollector sink;
  std::vector<uint8_t> wire;
  for (const AvrDevice::Byte& b : device.uart_out()) {
    const size_t before = sink.frames.size();
    if (b.value == radio::kStartDelimiter) wire.clear();
    wire.push_back(b.value);
    decoder.Feed(&b.value, 1, &sink);
    if (sink.frames.size() > before) {
      sink.frames.back().last_cycle = b.cycle;
      sink.frames.back().wire = wire;
    }
  }
  if (errors) *errors = sink.errors;
  return sink.frames;
}

std::vector<uint8_t> AnnouncementFrame(uint8_t beacon, uint16_t seq, uint64_t address) {
  radio::WallMessage m;
  m.type = radio::PayloadType::kFiring;
  m.beacon_id = beacon;
  m.firing_seq = seq;
  radio::ReceivePacket p;
  p.frame_type = radio::kRx64FrameType;
  p.has_address64 = true;
  p.address64 = address;
  p.has_rssi = true;
  p.rssi_dbm = -40;
  p.payload = radio::EncodeWallMessage(m);
  const std::vector<uint8_t> data = radio::EncodeReceivePacket(p);
  return radio::EncodeFrame(data.data(), data.size(), radio::ApiMode::kEscaped);
}

std::vector<AvrDevice::Edge> EdgesOf(const AvrDevice& d, int pin) {
  std::vector<AvrDevice::Edge> out;
  for (const auto& e : d.edges()) {
    if (e.pin == pin) out.push_back(e);
  }
  return out;
}

void Boot(AvrDevice* d, const std::string& elf, const std::vector<uint8_t>& eeprom) {
  std::string error;
  ASSERT_TRUE(d->Load(ElfPath(elf), eeprom, &error)) << error;
}

// ---------------------------------------------------------------- beacon

TEST(BeaconFirmware, AnnouncesEachFiringAsTheBridgeDecodesIt) {
  REQUIRE_ELF("beacon");
  const DeviceConfig config = DemoBeacon();
  AvrDevice d;
  Boot(&d, "beacon", radio::EncodeDeviceConfig(config));
  // It listens for one frame, then fires every frame: 3 firings.
  ASSERT_TRUE(d.RunUntil(4 * config.frame_us * kUs));
  int errors = 0;
  const std::vector<TxFrame> frames = Frames(d, &errors);
  EXPECT_EQ(errors, 0);
  ASSERT_EQ(frames.size(), 3u);
  for (size_t i = 0; i < frames.size(); ++i) {
    const TxFrame& f = frames[i];
    // TX request 16-bit: frame id 0, broadcast 0xFFFF, options 0.
    ASSERT_EQ(f.data.size(), 5u + radio::kFiringPayloadBytes);
    EXPECT_EQ(f.type(), 0x01);
    EXPECT_EQ(f.data[1], 0x00);
    EXPECT_EQ(f.data[2], 0xFF);
    EXPECT_EQ(f.data[3], 0xFF);
    EXPECT_EQ(f.data[4], 0x00);
    // Bit for bit the bridge's encoding of the same announcement...
    radio::WallMessage expected;
    expected.type = radio::PayloadType::kFiring;
    expected.beacon_id = config.id;
    expected.firing_seq = static_cast<uint16_t>(i);
    EXPECT_EQ(f.payload(), radio::EncodeWallMessage(expected));
    EXPECT_EQ(f.wire, radio::EncodeFrame(f.data.data(), f.data.size(), radio::ApiMode::kEscaped));
    // ...and decoded by the bridge's payload decoder.
    radio::WallMessage m;
    const std::vector<uint8_t> payload = f.payload();
    ASSERT_EQ(radio::DecodeWallMessage(payload.data(), payload.size(), &m),
              radio::PayloadError::kOk);
    EXPECT_EQ(m.type, radio::PayloadType::kFiring);
    EXPECT_EQ(m.beacon_id, 1);
    EXPECT_EQ(m.firing_seq, i);
    EXPECT_FALSE(m.has_temperature());
  }
}

TEST(BeaconFirmware, BurstsAt40kHzAFixedDelayAfterEachAnnouncement) {
  REQUIRE_ELF("beacon");
  const DeviceConfig config = DemoBeacon();
  AvrDevice d;
  Boot(&d, "beacon", radio::EncodeDeviceConfig(config));
  ASSERT_TRUE(d.RunUntil(3 * config.frame_us * kUs + 10 * kMs));
  const std::vector<TxFrame> frames = Frames(d);
  const auto pb1 = EdgesOf(d, 1);
  const auto pb2 = EdgesOf(d, 2);
  const size_t per_burst = 2u * config.burst_cycles;
  ASSERT_EQ(frames.size(), 3u);
  ASSERT_EQ(pb1.size(), 3 * per_burst);
  ASSERT_EQ(pb2.size(), 3 * per_burst);
  // The half period of 40 kHz at 16 MHz, exactly: the compare unit toggles
  // the pin in hardware, whatever the ISR's latency.
  constexpr uint64_t kHalfPeriod = 200;
  std::vector<int64_t> after_last_byte;
  for (size_t burst = 0; burst < 3; ++burst) {
    for (size_t i = 0; i < per_burst; ++i) {
      const auto& e1 = pb1[burst * per_burst + i];
      const auto& e2 = pb2[burst * per_burst + i];
      EXPECT_EQ(e1.high, i % 2 == 0) << "PB1 starts rising and ends low";
      EXPECT_EQ(e2.high, i % 2 == 0) << "PB2 too, half a period later";
      // simavr reports a pin change at the end of the instruction in
      // progress when the compare unit toggled it (up to 4 cycles).
      constexpr double kInstructionCycles = 4;
      EXPECT_NEAR(static_cast<double>(e1.cycle),
                  static_cast<double>(pb1[burst * per_burst].cycle + i * kHalfPeriod),
                  kInstructionCycles);
      EXPECT_NEAR(static_cast<double>(e2.cycle), static_cast<double>(e1.cycle + kHalfPeriod),
                  kInstructionCycles);
    }
    // Over the burst those quantisations do not add up: the compare unit's
    // schedule is exact, so the mean half period is 200 cycles to within
    // one instruction over 2N - 1 half periods.
    const double mean_half =
        static_cast<double>(pb1[(burst + 1) * per_burst - 1].cycle - pb1[burst * per_burst].cycle) /
        static_cast<double>(per_burst - 1);
    EXPECT_NEAR(mean_half, 200.0, 4.0 / static_cast<double>(per_burst - 1));
    after_last_byte.push_back(static_cast<int64_t>(pb1[burst * per_burst].cycle) -
                              static_cast<int64_t>(frames[burst].last_cycle) -
                              static_cast<int64_t>(config.fire_delay_us * kUs));
  }
  // simavr raises TXC one byte time (640 cycles) after the last byte is
  // written; the firmware's polling loop and its 32-bit read of Timer1 add
  // a fixed few tens of cycles. The constant is in tof_offset_ns's
  // calibration; what matters is its spread, one polling loop (5 cycles).
  constexpr int64_t kTxcAfterWrite = 640;
  constexpr int64_t kReadCycles = 128;  // 8 us: bound on the poll and the read (75)
  constexpr int64_t kPollJitter = 5;    // sbrs/rjmp/lds: one loop pass
  for (int64_t delay : after_last_byte) {
    EXPECT_GE(delay, kTxcAfterWrite);
    EXPECT_LE(delay, kTxcAfterWrite + kReadCycles);
  }
  const auto [lo, hi] = std::minmax_element(after_last_byte.begin(), after_last_byte.end());
  EXPECT_LE(*hi - *lo, kPollJitter);
  // Bursts a frame apart on the crystal; the start of sending is polled in
  // the main loop (a pass is a few us), and each burst is TXC-relative.
  constexpr int64_t kMainLoopCycles = 64;  // 4 us: one pass of the wait loop
  for (size_t burst = 1; burst < 3; ++burst) {
    const int64_t period = static_cast<int64_t>(pb1[burst * per_burst].cycle) -
                           static_cast<int64_t>(pb1[(burst - 1) * per_burst].cycle);
    EXPECT_NEAR(period, static_cast<int64_t>(config.frame_us * kUs), kMainLoopCycles);
  }
}

// This beacon (id 1) sharing the air with beacon 5: two slots, ours
// `own_slot`, in a frame of `frame_slots` slots (more than two when the
// rate bounds the frame).
DeviceConfig TwoSlotBeacon(uint8_t own_slot, uint32_t frame_slots) {
  DeviceConfig config = DemoBeacon();
  config.slot_count = 2;
  config.slot_index = own_slot;
  config.slot_beacon_ids = own_slot == 0 ? std::array<uint8_t, radio::kDeviceMaxSlots>{1, 5}
                                         : std::array<uint8_t, radio::kDeviceMaxSlots>{5, 1};
  config.frame_us = frame_slots * config.slot_us;
  return config;
}

TEST(BeaconFirmware, TakesItsSlotFromAnotherBeaconsAnnouncement) {
  REQUIRE_ELF("beacon");
  // Two beacons: id 5 in slot 0, this one (id 1) in slot 1.
  const DeviceConfig config = TwoSlotBeacon(1, 2);
  ASSERT_TRUE(config.IsValid(nullptr));
  AvrDevice d;
  Boot(&d, "beacon", radio::EncodeDeviceConfig(config));
  ASSERT_TRUE(d.RunUntil(20 * kMs));  // still listening: a frame is 200 ms
  const uint64_t sent = d.cycle();
  d.SendBytes(AnnouncementFrame(5, 77, 0x0013A20042000005ull));
  ASSERT_TRUE(d.RunUntil(sent + config.slot_us * kUs + 20 * kMs));
  const auto pb1 = EdgesOf(d, 1);
  ASSERT_FALSE(pb1.empty());
  // Beacon 5 burst at its stamp - latency + fire delay; ours one slot later.
  // The stamp is the 0x7E's receive interrupt: one byte time after the
  // bytes were queued, plus the ISR's entry (a fixed few cycles).
  const uint64_t stamp = sent + kByte;
  const int64_t expected = static_cast<int64_t>(
      stamp + (config.fire_delay_us - config.radio_latency_us) * kUs + config.slot_us * kUs);
  // Our announcement starts a fire delay and its own length (n bytes of
  // 640 cycles) before that burst; the wait for that start is polled in the
  // main loop and the stamp is read in the ISR: a few us in all, against a
  // slot guard of 1 ms.
  const std::vector<TxFrame> frames = Frames(d);
  ASSERT_EQ(frames.size(), 1u);
  const int64_t n = static_cast<int64_t>(frames[0].wire.size());
  const int64_t expected_start =
      expected - static_cast<int64_t>(config.fire_delay_us * kUs) - n * static_cast<int64_t>(kByte);
  constexpr int64_t kScheduleCycles = 256;  // 16 us: ISR entry and polling
  EXPECT_NEAR(static_cast<int64_t>(d.uart_out().front().cycle),
              expected_start + kScheduleCycles / 2, kScheduleCycles / 2);
  // The burst is tied to the frame's end, as in every firing.
  const int64_t after_last_byte = static_cast<int64_t>(pb1[0].cycle) -
                                  static_cast<int64_t>(frames[0].last_cycle) -
                                  static_cast<int64_t>(config.fire_delay_us * kUs);
  EXPECT_GE(after_last_byte, 640);
  EXPECT_LE(after_last_byte, 640 + 128);
  // Its announcement numbers its own firings from 0.
  const std::vector<uint8_t> payload = frames[0].payload();
  ASSERT_EQ(payload.size(), radio::kFiringPayloadBytes);
  EXPECT_EQ(payload[2], 1);  // beacon id
  EXPECT_EQ(payload[4], 0);  // firing number, low byte
}

// The first burst of a beacon that hears nobody, with a frame longer than
// its slots (the rate bounds it): its own slot of the listening frame.
// And a beacon joining in an earlier slot than the one it hears fires a
// frame less the slots between after it, not (k - j) mod n slots (which
// holds only for a frame of exactly n slots).
TEST(BeaconFirmware, AJoiningBeaconInAnEarlierSlotFiresAFrameLessTheSlotsBetweenLater) {
  REQUIRE_ELF("beacon");
  // This one (id 1) in slot 0 of 2, beacon 5 in slot 1; a frame of 3 slots.
  const DeviceConfig config = TwoSlotBeacon(0, 3);
  ASSERT_TRUE(config.IsValid(nullptr));
  AvrDevice d;
  Boot(&d, "beacon", radio::EncodeDeviceConfig(config));
  ASSERT_TRUE(d.RunUntil(20 * kMs));
  const uint64_t sent = d.cycle();
  d.SendBytes(AnnouncementFrame(5, 9, 0x0013A20042000005ull));
  ASSERT_TRUE(d.RunUntil(sent + config.frame_us * kUs));
  const std::vector<TxFrame> frames = Frames(d);
  ASSERT_EQ(frames.size(), 1u);
  const uint64_t stamp = sent + kByte;
  const int64_t their_burst =
      static_cast<int64_t>(stamp + (config.fire_delay_us - config.radio_latency_us) * kUs);
  const int64_t expected =
      their_burst + static_cast<int64_t>((config.frame_us - config.slot_us) * kUs);
  // As in TakesItsSlotFromAnotherBeaconsAnnouncement: the announcement
  // starts a fire delay and its own n bytes before that burst (the burst
  // then follows its last byte); the start is polled in the main loop and
  // the stamp read in the ISR: 16 us of slack against a 1 ms slot guard.
  // The old rule put it a whole slot (100 ms) earlier.
  const int64_t n = static_cast<int64_t>(frames[0].wire.size());
  const int64_t expected_start =
      expected - static_cast<int64_t>(config.fire_delay_us * kUs) - n * static_cast<int64_t>(kByte);
  constexpr int64_t kScheduleCycles = 256;
  EXPECT_NEAR(static_cast<int64_t>(d.uart_out().front().cycle),
              expected_start + kScheduleCycles / 2, kScheduleCycles / 2);
}

// Once it fires, a beacon follows only beacons in earlier slots: the lowest
// slot heard keeps its own crystal. Two beacons that burst together (booted
// together, or one reset) would otherwise each move to the other's time
// plus one slot and, with two slots in the frame, stay together for ever.
TEST(BeaconFirmware, AFiringBeaconIgnoresALaterSlotsAnnouncement) {
  REQUIRE_ELF("beacon");
  const DeviceConfig config = TwoSlotBeacon(0, 2);
  ASSERT_TRUE(config.IsValid(nullptr));
  AvrDevice d;
  Boot(&d, "beacon", radio::EncodeDeviceConfig(config));
  // Its first burst: after the listening frame, in slot 0.
  ASSERT_TRUE(d.RunUntil(config.frame_us * kUs + 40 * kMs));
  const auto first = EdgesOf(d, 1);
  ASSERT_FALSE(first.empty());
  const uint64_t first_burst = first.front().cycle;
  // Beacon 5 announces 30 ms after our burst, out of its slot; the old
  // rule moved our next burst to a slot after it.
  d.SendBytes(AnnouncementFrame(5, 3, 0x0013A20042000005ull));
  ASSERT_TRUE(d.RunUntil(first_burst + config.frame_us * kUs + 20 * kMs));
  const std::vector<TxFrame> frames = Frames(d);
  ASSERT_EQ(frames.size(), 2u);
  const auto pb1 = EdgesOf(d, 1);
  const size_t per_burst = 2 * config.burst_cycles;
  ASSERT_GE(pb1.size(), 2 * per_burst);
  // The second burst a frame after the first, on our crystal, as if
  // nothing had been heard (the main loop polls the start: 4 us).
  constexpr int64_t kMainLoopCycles = 64;
  EXPECT_NEAR(static_cast<int64_t>(pb1[per_burst].cycle - first_burst),
              static_cast<int64_t>(config.frame_us * kUs), kMainLoopCycles);
}

TEST(BeaconFirmware, CountsFromZeroAgainAfterAReset) {
  REQUIRE_ELF("beacon");
  const DeviceConfig config = DemoBeacon();
  AvrDevice d;
  Boot(&d, "beacon", radio::EncodeDeviceConfig(config));
  ASSERT_TRUE(d.RunUntil(3 * config.frame_us * kUs));
  ASSERT_EQ(Frames(d).size(), 2u);
  d.Reset();
  d.ClearOutput();
  ASSERT_TRUE(d.RunFor(2 * config.frame_us * kUs + 10 * kMs));
  const std::vector<TxFrame> frames = Frames(d);
  ASSERT_GE(frames.size(), 1u);
  radio::WallMessage m;
  const std::vector<uint8_t> payload = frames[0].payload();
  ASSERT_EQ(radio::DecodeWallMessage(payload.data(), payload.size(), &m), radio::PayloadError::kOk);
  EXPECT_EQ(m.firing_seq, 0);
}

// A hung beacon is restarted by its watchdog (250 ms, firmware/beacon.c):
// an upset that stops Timer1 (TCCR1B = 0) leaves its main loop either
// asleep for an overflow that never comes (mid-frame) or spinning in the
// polled stretch before a burst (just before it). The loop pets the
// watchdog only while its clock moves (fw_watchdog_pet), so either way the
// watchdog resets it and it boots, listens for a frame and fires again
// from firing 0 (which the bridge's restart detection handles). Petting
// on every pass, as the firmware first did, kept the spinning one hung.
TEST(BeaconFirmware, ItsWatchdogRestartsItWhenItsTimerStopsAsleepOrSpinning) {
  REQUIRE_ELF("beacon");
  const DeviceConfig config = DemoBeacon();
  // Upset at 2.5 frames (asleep: the next burst is half a frame away) and
  // at 3 frames (the polled stretch: the burst at 3 frames + lead is
  // within FW_WAKE_TICKS).
  for (const double frames_before_upset : {2.5, 3.0}) {
    SCOPED_TRACE(frames_before_upset);
    AvrDevice d;
    Boot(&d, "beacon", radio::EncodeDeviceConfig(config));
    ASSERT_TRUE(d.RunUntil(static_cast<uint64_t>(frames_before_upset * config.frame_us) * kUs));
    ASSERT_EQ(Frames(d).size(), 2u);
    ASSERT_EQ(d.resets(), 0);
    constexpr uint16_t kTccr1b = 0x81;  // ATmega328P datasheet, register summary
    ASSERT_TRUE(d.UpsetRegister(kTccr1b, 0));
    const uint64_t upset = d.cycle();
    d.ClearOutput();
    // The watchdog's period is 250 ms nominal (its own 128 kHz oscillator,
    // datasheet table 10-3; simavr runs it exact from the last pet, at most
    // a loop pass before the upset). Within it no burst and no
    // announcement; past it, one reset.
    constexpr uint64_t kWatchdogUs = 250000;
    constexpr uint64_t kMarginUs = 10000;
    ASSERT_TRUE(d.RunUntil(upset + (kWatchdogUs - kMarginUs) * kUs));
    EXPECT_TRUE(Frames(d).empty());
    EXPECT_EQ(d.resets(), 0);
    ASSERT_TRUE(d.RunUntil(upset + (kWatchdogUs + kMarginUs) * kUs));
    EXPECT_EQ(d.resets(), 1);
    // Then it fires again, counting from 0, after its listening frame and
    // lead: well within two frames.
    ASSERT_TRUE(d.RunUntil(upset + kWatchdogUs * kUs + 2 * config.frame_us * kUs));
    const std::vector<TxFrame> frames = Frames(d);
    ASSERT_GE(frames.size(), 1u);
    radio::WallMessage m;
    const std::vector<uint8_t> payload = frames[0].payload();
    ASSERT_EQ(radio::DecodeWallMessage(payload.data(), payload.size(), &m),
              radio::PayloadError::kOk);
    EXPECT_EQ(m.firing_seq, 0);
    EXPECT_FALSE(EdgesOf(d, 1).empty());
  }
}

// The device status payloads a device sent, and its fault codes.
std::vector<uint8_t> FaultsSent(const AvrDevice& d) {
  std::vector<uint8_t> faults;
  for (const TxFrame& f : Frames(d)) {
    const std::vector<uint8_t> p = f.payload();
    if (f.type() != 0x01 || p.size() != radio::kDeviceStatusBytes || p[1] != 0x03) continue;
    if (radio::Crc16CcittFalse(p.data(), 6) != ((p[6] << 8) | p[7])) continue;
    faults.push_back(p[3]);
  }
  return faults;
}

TEST(BeaconFirmware, RefusesToFireWithACorruptConfigurationAndSaysSo) {
  REQUIRE_ELF("beacon");
  std::vector<uint8_t> image = radio::EncodeDeviceConfig(DemoBeacon());
  image[30] ^= 0x04;  // a bit of frame_us: the CRC no longer matches
  AvrDevice d;
  Boot(&d, "beacon", image);
  ASSERT_TRUE(d.RunUntil(2500 * kMs));
  // A status every second from boot: at 0, 1 and 2 s; never a burst or an
  // announcement.
  const std::vector<uint8_t> expected = {2, 2, 2};  // FW_FAULT_CONFIG_CRC
  EXPECT_EQ(FaultsSent(d), expected);
  EXPECT_TRUE(d.edges().empty());
  EXPECT_EQ(Frames(d).size(), 3u);
}

TEST(BeaconFirmware, AnErasedEepromIsAMissingConfiguration) {
  REQUIRE_ELF("beacon");
  AvrDevice d;
  Boot(&d, "beacon", {});
  ASSERT_TRUE(d.RunUntil(500 * kMs));
  EXPECT_EQ(FaultsSent(d), std::vector<uint8_t>{1});  // FW_FAULT_CONFIG_MISSING
  EXPECT_TRUE(d.edges().empty());
}

// -------------------------------------------------------------- receiver

struct Report {
  radio::WallMessage message;
  uint64_t destination = 0;
};

std::vector<Report> Reports(const AvrDevice& d) {
  std::vector<Report> out;
  for (const TxFrame& f : Frames(d)) {
    if (f.type() != 0x00) continue;
    Report r;
    for (int i = 0; i < 8; ++i) r.destination = (r.destination << 8) | f.data[2 + i];
    const std::vector<uint8_t> p = f.payload();
    EXPECT_EQ(radio::DecodeWallMessage(p.data(), p.size(), &r.message), radio::PayloadError::kOk);
    out.push_back(r);
  }
  return out;
}

// Announces firing `seq` now and raises the detector (and, when `strong`,
// the second comparator) about `echo_after_stamp` cycles after the stamp's
// nominal cycle (the 0x7E's byte time after the bytes were queued). Returns
// the edge's cycle less that nominal stamp, exactly: simavr stops between
// instructions, so the edge comes up to a few cycles after the target.
int64_t Fire(AvrDevice* d, uint16_t seq, int64_t echo_after_stamp, bool strong) {
  const uint64_t stamp = d->cycle() + kByte;
  d->SendBytes(AnnouncementFrame(1, seq, 0x0013A20042000001ull));
  if (echo_after_stamp < 0) return -1;
  EXPECT_TRUE(d->RunUntil(stamp + static_cast<uint64_t>(echo_after_stamp)));
  const int64_t edge = static_cast<int64_t>(d->cycle() - stamp);
  d->SetPin('B', 0, true);
  if (strong) d->SetPin('D', 2, true);
  EXPECT_TRUE(d->RunFor(100 * kUs));
  d->SetPin('B', 0, false);
  d->SetPin('D', 2, false);
  return edge;
}

TEST(ReceiverFirmware, ReportsTheEchoToTheTick) {
  REQUIRE_ELF("receiver");
  const DeviceConfig config = DemoReceiver();
  AvrDevice d;
  Boot(&d, "receiver", radio::EncodeDeviceConfig(config));
  ASSERT_TRUE(d.RunUntil(5 * kMs));
  // Two firings, the second's echo 1234 cycles (77.125 us) later.
  const int64_t target = (config.fire_delay_us - config.radio_latency_us) * kUs + 8 * kMs;
  const int64_t echo1 = Fire(&d, 300, target, true);
  ASSERT_TRUE(d.RunFor(config.window_close_us * kUs + 5 * kMs));
  const int64_t echo2 = Fire(&d, 301, target + 1234, true);
  ASSERT_TRUE(d.RunFor(config.window_close_us * kUs + 5 * kMs));
  const std::vector<Report> reports = Reports(d);
  ASSERT_EQ(reports.size(), 2u);
  for (size_t i = 0; i < 2; ++i) {
    EXPECT_EQ(reports[i].destination, config.coordinator_address);
    EXPECT_EQ(reports[i].message.type, radio::PayloadType::kRangeReport);
    EXPECT_EQ(reports[i].message.beacon_id, 1);
    EXPECT_EQ(reports[i].message.firing_seq, 300 + i);
    EXPECT_EQ(reports[i].message.flags, 0) << "a strong echo: no flag";
  }
  // The difference is the edges' difference, to the tick (62.5 ns), give
  // or take the stamp's one jitter term: the receive interrupt waits for
  // the instruction in progress (1 to 4 cycles; 250 ns is 0.09 mm of sound).
  constexpr double kTruncationNs = 0.5;  // 62.5 x odd counts truncates 0.5 ns
  constexpr double kIsrEntryJitterNs = 4 * 62.5;
  const double t1 = reports[0].message.time_of_flight_ns;
  const double t2 = reports[1].message.time_of_flight_ns;
  EXPECT_NEAR(t2 - t1, static_cast<double>(echo2 - echo1) * 62.5,
              kIsrEntryJitterNs + 2 * kTruncationNs);
  // The absolute value: the edge's cycle from the 0x7E's receive interrupt,
  // less the configured offset. The stamp is read at the ISR's entry, a
  // fixed number of cycles after the byte (vector, prologue); both firings
  // give the same.
  const double stamp_delay_1 = echo1 - (t1 + config.tof_offset_ns) / 62.5;
  const double stamp_delay_2 = echo2 - (t2 + config.tof_offset_ns) / 62.5;
  // The vector and the ISR prologue (17 instructions before TCNT1 is read,
  // about 40 cycles) and simavr's own delivery of the byte: 102 cycles
  // measured, a constant that the offset calibration absorbs.
  constexpr double kIsrEntryMaxCycles = 128;
  EXPECT_GE(stamp_delay_1, 0.0);
  EXPECT_LE(stamp_delay_1, kIsrEntryMaxCycles);
  EXPECT_NEAR(stamp_delay_1, stamp_delay_2, (kIsrEntryJitterNs + 2 * kTruncationNs) / 62.5);
}

TEST(ReceiverFirmware, FlagsAWeakEchoAndANoEcho) {
  REQUIRE_ELF("receiver");
  const DeviceConfig config = DemoReceiver();
  AvrDevice d;
  Boot(&d, "receiver", radio::EncodeDeviceConfig(config));
  ASSERT_TRUE(d.RunUntil(5 * kMs));
  const int64_t echo = (config.fire_delay_us - config.radio_latency_us) * kUs + 5 * kMs;
  Fire(&d, 10, echo, false);  // only the low threshold: weak
  ASSERT_TRUE(d.RunFor(config.window_close_us * kUs + 5 * kMs));
  Fire(&d, 11, -1, false);  // nothing: no echo
  ASSERT_TRUE(d.RunFor(config.window_close_us * kUs + 5 * kMs));
  // An edge before the window opens (the tail of something else) is not
  // the echo: the later one is.
  Fire(&d, 12, 10 * kUs, false);
  ASSERT_TRUE(d.RunFor(echo - 10 * kUs - 100 * kUs));
  d.SetPin('B', 0, true);
  ASSERT_TRUE(d.RunFor(config.window_close_us * kUs + 5 * kMs));
  const std::vector<Report> reports = Reports(d);
  ASSERT_EQ(reports.size(), 3u);
  EXPECT_EQ(reports[0].message.flags, radio::kFlagWeakEcho);
  EXPECT_GT(reports[0].message.time_of_flight_ns, 4'000'000u);
  EXPECT_EQ(reports[1].message.flags, radio::kFlagNoEcho);
  EXPECT_EQ(reports[1].message.time_of_flight_ns, 0u);
  EXPECT_EQ(reports[2].message.firing_seq, 12);
  EXPECT_EQ(reports[2].message.flags, radio::kFlagWeakEcho);
  constexpr double kLoopCycles = 64;  // the test's own RunFor overshoot, 4 us
  EXPECT_NEAR(reports[2].message.time_of_flight_ns, reports[0].message.time_of_flight_ns,
              kLoopCycles * 62.5);
}

TEST(ReceiverFirmware, WithoutAConfigurationSaysSoAndNeverReports) {
  REQUIRE_ELF("receiver");
  std::vector<uint8_t> image = radio::EncodeDeviceConfig(DemoReceiver());
  image[2] = 9;  // a layout this firmware does not read...
  const uint16_t crc = radio::Crc16CcittFalse(image.data(), image.size() - 2);
  image[image.size() - 2] = static_cast<uint8_t>(crc >> 8);  // ...correctly checksummed
  image[image.size() - 1] = static_cast<uint8_t>(crc);
  AvrDevice d;
  Boot(&d, "receiver", image);
  ASSERT_TRUE(d.RunUntil(5 * kMs));
  Fire(&d, 1, 5 * kMs, true);
  ASSERT_TRUE(d.RunUntil(1500 * kMs));
  EXPECT_TRUE(Reports(d).empty());
  const std::vector<uint8_t> expected = {3, 3};  // FW_FAULT_CONFIG_VERSION at 0 and 1 s
  EXPECT_EQ(FaultsSent(d), expected);
}

// ------------------------------------------------ roomfix devices, end to end

std::string ReadText(const std::string& path) {
  std::string text;
  std::string error;
  EXPECT_TRUE(ReadConfigFile(path, &text, &error)) << error;
  return text;
}

TEST(DevicesCommand, ItsImagesRunTheFirmwareAndACorruptOneIsRefusedByBoth) {
  REQUIRE_ELF("receiver");
  const std::string roomfix = BinDir() + "/roomfix";
  struct stat st {};
  if (stat(roomfix.c_str(), &st) != 0) GTEST_SKIP() << roomfix << " is not built";
  TempDir dir;
  ChildProcess write({roomfix, "devices", "--config", DemoSitePath(), "--out", dir.File("devices"),
                      "--coordinator-address", "0x0013A20040000001"},
                     dir.File("devices.txt"));
  ASSERT_EQ(write.Wait(60), 0) << ReadText(dir.File("devices.txt"));
  // It tells the bridge's deadline: the fourth receiver reports 3 x 2 ms
  // after its window closes at 23.308 ms, and its frame reaches the
  // coordinator the radio's 1.616 ms later: 30.9 ms; 40 ms more for a
  // buffering module, rounded up to 10 ms.
  const std::string printed = ReadText(dir.File("devices.txt"));
  EXPECT_NE(printed.find("the last report reaches the coordinator about 30.9 ms after the "
                         "announcement"),
            std::string::npos)
      << printed;
  EXPECT_NE(printed.find("e.g. 80 "), std::string::npos) << printed;
  // The receiver's file as avrdude would write it, read back from the hex.
  const std::string path = dir.File("devices/receiver-1.eep.hex");
  std::vector<uint8_t> image;
  std::string error;
  ASSERT_TRUE(radio::DecodeIntelHex(ReadText(path), &image, &error)) << error;
  EXPECT_EQ(image, radio::EncodeDeviceConfig([] {
              DeviceConfig c = DemoReceiver();
              c.coordinator_address = 0x0013A20040000001ull;
              return c;
            }()));
  {
    AvrDevice d;
    Boot(&d, "receiver", image);
    ASSERT_TRUE(d.RunUntil(5 * kMs));
    const DeviceConfig config = DemoReceiver();
    Fire(&d, 5, (config.fire_delay_us - config.radio_latency_us) * kUs + 3 * kMs, true);
    ASSERT_TRUE(d.RunFor(config.window_close_us * kUs + 5 * kMs));
    const std::vector<Report> reports = Reports(d);
    ASSERT_EQ(reports.size(), 1u);
    EXPECT_EQ(reports[0].destination, 0x0013A20040000001ull);
    EXPECT_EQ(reports[0].message.firing_seq, 5);
  }
  // One data digit changed and the record's checksum fixed up, as a bad
  // copy or a hand edit would leave it: the tool refuses it...
  std::vector<uint8_t> corrupt = image;
  corrupt[40] ^= 0x10;  // window_close_us
  const std::string bad_path = dir.File("bad.eep.hex");
  ASSERT_TRUE(WriteOutputFile(bad_path, radio::EncodeIntelHex(corrupt), &error)) << error;
  ChildProcess show({roomfix, "devices", "show", bad_path}, dir.File("show.txt"));
  EXPECT_EQ(show.Wait(60), 2);
  // ...and so does the firmware: a status frame with fault 2, no report.
  AvrDevice d;
  Boot(&d, "receiver", corrupt);
  ASSERT_TRUE(d.RunUntil(5 * kMs));
  Fire(&d, 6, 3 * kMs, true);
  ASSERT_TRUE(d.RunUntil(500 * kMs));
  EXPECT_TRUE(Reports(d).empty());
  EXPECT_EQ(FaultsSent(d), std::vector<uint8_t>{2});
}

}  // namespace
}  // namespace roomfix::testing
