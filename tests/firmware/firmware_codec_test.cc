// The firmware's portable C code (firmware/common/fw_codec.c), compiled by
// the host's C compiler, against the bridge's own code in core/radio: the
// constants both sides must agree on, the CRC, the payloads and the XBee
// framing bit for bit, and the EEPROM image `roomfix devices` writes read
// by the firmware's parser. The same source file is what avr-gcc builds
// into the devices; avr-gcc's 16-bit int is the one difference, and every
// product in it that can pass 2^15 is written in 32-bit types.
#include <gtest/gtest.h>

#include <random>
#include <vector>

#include "core/radio/device_config.h"
#include "core/radio/range_assembler.h"
#include "core/radio/wall_payload.h"
#include "core/radio/xbee_frame.h"
#include "fw_codec.h"
#include "tests/testing/demo_site.h"

namespace roomfix::radio {
namespace {

TEST(FirmwareProtocol, ConstantsMatchTheBridge) {
  EXPECT_EQ(FW_PAYLOAD_VERSION, kPayloadVersion);
  EXPECT_EQ(FW_TYPE_FIRING, static_cast<int>(PayloadType::kFiring));
  EXPECT_EQ(FW_TYPE_RANGE_REPORT, static_cast<int>(PayloadType::kRangeReport));
  EXPECT_EQ(FW_TYPE_DEVICE_STATUS, kDeviceStatusType);
  EXPECT_EQ(FW_FIRING_BYTES, kFiringPayloadBytes);
  EXPECT_EQ(FW_REPORT_BYTES, kRangeReportPayloadBytes);
  EXPECT_EQ(FW_STATUS_BYTES, kDeviceStatusBytes);
  EXPECT_EQ(FW_FLAG_WEAK_ECHO, kFlagWeakEcho);
  EXPECT_EQ(FW_FLAG_NO_ECHO, kFlagNoEcho);
  EXPECT_EQ(static_cast<int16_t>(FW_NO_TEMPERATURE), kNoTemperature);
  EXPECT_EQ(FW_XBEE_START, kStartDelimiter);
  EXPECT_EQ(FW_XBEE_ESCAPE, kEscape);
  EXPECT_EQ(FW_XBEE_XON, kXon);
  EXPECT_EQ(FW_XBEE_XOFF, kXoff);
  EXPECT_EQ(FW_XBEE_ESCAPE_XOR, kEscapeXor);
  EXPECT_EQ(FW_XBEE_RX64, kRx64FrameType);
  EXPECT_EQ(FW_XBEE_RX16, kRx16FrameType);
  EXPECT_EQ(FW_XBEE_ZB_RX, kZigbeeRxFrameType);
  EXPECT_EQ(FW_CONFIG_BYTES, kDeviceConfigBytes);
  EXPECT_EQ(FW_CONFIG_LAYOUT_VERSION, kDeviceConfigLayoutVersion);
  EXPECT_EQ(FW_CONFIG_MAGIC0, kDeviceConfigMagic0);
  EXPECT_EQ(FW_CONFIG_MAGIC1, kDeviceConfigMagic1);
  EXPECT_EQ(FW_ROLE_BEACON, static_cast<int>(DeviceRole::kBeacon));
  EXPECT_EQ(FW_ROLE_RECEIVER, static_cast<int>(DeviceRole::kReceiver));
  EXPECT_EQ(FW_MAX_SLOTS, kDeviceMaxSlots);
  EXPECT_EQ(FW_MAX_FIRE_DELAY_US, kMaxFireDelayUs);
  EXPECT_EQ(FW_MIN_FIRE_DELAY_US, kMinFireDelayUs);
  EXPECT_EQ(FW_MAX_WINDOW_US, kMaxWindowUs);
  EXPECT_EQ(FW_MAX_BURST_CYCLES, kMaxBurstCycles);
  EXPECT_EQ(FW_FAULT_CONFIG_MISSING, static_cast<int>(DeviceFault::kConfigMissing));
  EXPECT_EQ(FW_FAULT_CONFIG_CRC, static_cast<int>(DeviceFault::kConfigCrc));
  EXPECT_EQ(FW_FAULT_CONFIG_VERSION, static_cast<int>(DeviceFault::kConfigVersion));
  EXPECT_EQ(FW_FAULT_CONFIG_INVALID, static_cast<int>(DeviceFault::kConfigInvalid));
  EXPECT_EQ(FW_FAULT_SELF_TEST, static_cast<int>(DeviceFault::kSelfTest));
  // 250 kb/s from 16 MHz: 64 cycles a bit, 640 a byte; 40 kHz: 200 a half.
  EXPECT_EQ(FW_TICKS_PER_UART_BYTE, 640u);
  EXPECT_EQ(FW_HALF_CARRIER_TICKS, 200u);
}

TEST(FirmwareCodec, CrcMatchesTheBridgesOnRandomData) {
  std::mt19937 rng(29);
  for (int trial = 0; trial < 500; ++trial) {
    std::vector<uint8_t> data(rng() % 100);
    for (uint8_t& b : data) b = static_cast<uint8_t>(rng());
    EXPECT_EQ(fw_crc16(data.data(), static_cast<uint8_t>(data.size())),
              Crc16CcittFalse(data.data(), data.size()));
  }
}

TEST(FirmwareCodec, AnnouncementsAndReportsAreTheBridgesBytes) {
  std::mt19937 rng(7);
  for (int trial = 0; trial < 1000; ++trial) {
    WallMessage m;
    m.type = PayloadType::kFiring;
    m.beacon_id = static_cast<uint8_t>(1 + rng() % 255);
    m.firing_seq = static_cast<uint16_t>(rng());
    m.temperature_centi_c = static_cast<int16_t>(rng());
    m.flags = static_cast<uint8_t>(rng());
    uint8_t firing[FW_FIRING_BYTES];
    fw_encode_firing(m.beacon_id, m.firing_seq, static_cast<uint16_t>(m.temperature_centi_c),
                     m.flags, firing);
    EXPECT_EQ(std::vector<uint8_t>(firing, firing + sizeof firing), EncodeWallMessage(m));
    uint8_t id = 0;
    uint16_t seq = 0;
    ASSERT_TRUE(fw_decode_firing(firing, sizeof firing, &id, &seq));
    EXPECT_EQ(id, m.beacon_id);
    EXPECT_EQ(seq, m.firing_seq);

    m.type = PayloadType::kRangeReport;
    m.time_of_flight_ns = static_cast<uint32_t>(rng());
    uint8_t report[FW_REPORT_BYTES];
    fw_encode_report(m.beacon_id, m.firing_seq, m.time_of_flight_ns,
                     static_cast<uint16_t>(m.temperature_centi_c), m.flags, report);
    EXPECT_EQ(std::vector<uint8_t>(report, report + sizeof report), EncodeWallMessage(m));
  }
}

TEST(FirmwareCodec, DecodeFiringRefusesEverySingleBitError) {
  uint8_t good[FW_FIRING_BYTES];
  fw_encode_firing(3, 300, FW_NO_TEMPERATURE, 0, good);
  for (unsigned bit = 0; bit < 8 * sizeof good; ++bit) {
    uint8_t bad[FW_FIRING_BYTES];
    std::copy(good, good + sizeof good, bad);
    bad[bit / 8] ^= static_cast<uint8_t>(1u << (bit % 8));
    uint8_t id = 0;
    uint16_t seq = 0;
    EXPECT_FALSE(fw_decode_firing(bad, sizeof bad, &id, &seq)) << "bit " << bit;
  }
}

TEST(FirmwareCodec, StatusPayloadIsTheDocumentedBytes) {
  uint8_t status[FW_STATUS_BYTES];
  fw_encode_status(4, FW_FAULT_CONFIG_CRC, 0x08, status);
  const std::vector<uint8_t> head = {0x01, 0x03, 0x04, 0x02, 0x08, FW_VERSION};
  EXPECT_EQ(std::vector<uint8_t>(status, status + 6), head);
  EXPECT_EQ((status[6] << 8) | status[7], Crc16CcittFalse(head.data(), head.size()));
  // The bridge refuses it as an unknown type (a counter), never a crash.
  WallMessage m;
  EXPECT_EQ(DecodeWallMessage(status, sizeof status, &m), PayloadError::kUnknownType);
}

TEST(FirmwareCodec, TheBridgeCountsADeviceStatusAndCarriesOn) {
  Site site;
  std::string error;
  ASSERT_TRUE(LoadSite(testing::DemoSitePath(), &site, &error)) << error;
  RangeAssembler assembler(site, {});
  uint8_t status[FW_STATUS_BYTES];
  fw_encode_status(1, FW_FAULT_CONFIG_MISSING, 0x01, status);
  RadioPacket p;
  p.has_address64 = true;
  p.address64 = site.receivers[0].address;
  p.payload = status;
  p.payload_size = sizeof status;
  p.arrival_utime = 1'700'000'000'000'000;
  std::vector<AssembledSet> closed;
  EXPECT_STREQ(assembler.OnPacket(p, &closed), "malformed_payload");
  EXPECT_NE(assembler.last_rejection().find("unknown message type 0x03"), std::string::npos)
      << assembler.last_rejection();
  EXPECT_EQ(assembler.open_firings(), 0);
}

class FrameCollector : public FrameSink {
 public:
  void OnFrame(const uint8_t* data, size_t size, uint64_t) override {
    frames.emplace_back(data, data + size);
  }
  void OnFrameError(const FrameErrorInfo&) override { ++errors; }
  std::vector<std::vector<uint8_t>> frames;
  int errors = 0;
};

TEST(FirmwareCodec, FramesAreTheBridgesApiMode2Bytes) {
  std::mt19937 rng(11);
  for (int trial = 0; trial < 500; ++trial) {
    // Random frame data, rich in the four bytes mode 2 escapes.
    std::vector<uint8_t> data(1 + rng() % 40);
    const uint8_t specials[] = {0x7E, 0x7D, 0x11, 0x13};
    for (uint8_t& b : data)
      b = (rng() % 3 == 0) ? specials[rng() % 4] : static_cast<uint8_t>(rng());
    uint8_t wire[2 * 48 + 8];
    const uint8_t n =
        fw_xbee_encode(data.data(), static_cast<uint8_t>(data.size()), wire, sizeof wire);
    ASSERT_GT(n, 0);
    EXPECT_EQ(std::vector<uint8_t>(wire, wire + n),
              EncodeFrame(data.data(), data.size(), ApiMode::kEscaped));
    // And the firmware's decoder reads what the bridge's encoder writes.
    fw_xbee_decoder decoder;
    fw_xbee_decoder_reset(&decoder);
    int frames = 0;
    for (uint8_t b : EncodeFrame(data.data(), data.size(), ApiMode::kEscaped)) {
      const int8_t r = fw_xbee_decode_byte(&decoder, b);
      ASSERT_GE(r, 0);
      if (r == FW_XBEE_FRAME) {
        ++frames;
        EXPECT_EQ(std::vector<uint8_t>(decoder.data, decoder.data + decoder.length), data);
      }
    }
    EXPECT_EQ(frames, 1);
  }
}

TEST(FirmwareCodec, DecoderResynchronisesOnTheNextStartDelimiter) {
  std::vector<uint8_t> frame = {0x80, 1, 2, 3, 4, 5, 6, 7, 8, 0x28, 0, 0x42};
  std::vector<uint8_t> stream = EncodeFrame(frame.data(), frame.size(), ApiMode::kEscaped);
  std::vector<uint8_t> bad = stream;
  bad[6] ^= 0x01;                                                // a data bit: bad checksum
  std::vector<uint8_t> cut(stream.begin(), stream.begin() + 7);  // truncated
  std::vector<uint8_t> all = {0x00, 0x55};                       // garbage
  for (const auto* part : {&bad, &cut, &stream}) all.insert(all.end(), part->begin(), part->end());
  fw_xbee_decoder decoder;
  fw_xbee_decoder_reset(&decoder);
  std::vector<int> results;
  for (uint8_t b : all) {
    const int8_t r = fw_xbee_decode_byte(&decoder, b);
    if (r != FW_XBEE_MORE) results.push_back(r);
  }
  const std::vector<int> expected = {FW_XBEE_GARBAGE, FW_XBEE_GARBAGE, FW_XBEE_BAD_CHECKSUM,
                                     FW_XBEE_TRUNCATED, FW_XBEE_FRAME};
  EXPECT_EQ(results, expected);
}

TEST(FirmwareCodec, FindsTheRfDataOfEveryReceiveFrame) {
  uint8_t payload[FW_FIRING_BYTES];
  fw_encode_firing(2, 9, FW_NO_TEMPERATURE, 0, payload);
  for (uint8_t type : {kRx64FrameType, kRx16FrameType, kZigbeeRxFrameType}) {
    ReceivePacket p;
    p.frame_type = type;
    p.has_address64 = type != kRx16FrameType;
    p.address64 = 0x0013A20042000002ull;
    p.has_address16 = type != kRx64FrameType;
    p.has_rssi = type != kZigbeeRxFrameType;
    p.rssi_dbm = -40;
    p.payload.assign(payload, payload + sizeof payload);
    const std::vector<uint8_t> data = EncodeReceivePacket(p);
    uint8_t offset = 0;
    ASSERT_EQ(fw_xbee_rf_data(data.data(), static_cast<uint8_t>(data.size()), &offset),
              static_cast<int8_t>(sizeof payload))
        << "frame type " << int{type};
    EXPECT_EQ(std::vector<uint8_t>(data.begin() + offset, data.end()), p.payload);
  }
  const uint8_t status[] = {0x8A, 0x00};  // modem status: not a receive frame
  uint8_t offset = 0;
  EXPECT_EQ(fw_xbee_rf_data(status, sizeof status, &offset), -1);
}

TEST(FirmwareCodec, TxRequestsHaveDigisLayout) {
  uint8_t payload[FW_REPORT_BYTES];
  fw_encode_report(1, 2, 3, FW_NO_TEMPERATURE, 0, payload);
  uint8_t out[48];
  const uint8_t coordinator[8] = {0x00, 0x13, 0xA2, 0x00, 0x40, 0x00, 0x00, 0x01};
  ASSERT_EQ(fw_tx64_request(coordinator, payload, sizeof payload, out, sizeof out), 11 + 14);
  const std::vector<uint8_t> head64 = {0x00, 0x00, 0x00, 0x13, 0xA2, 0x00,
                                       0x40, 0x00, 0x00, 0x01, 0x00};
  EXPECT_EQ(std::vector<uint8_t>(out, out + 11), head64);
  ASSERT_EQ(fw_tx16_request(0xFFFF, payload, 10, out, sizeof out), 5 + 10);
  const std::vector<uint8_t> head16 = {0x01, 0x00, 0xFF, 0xFF, 0x00};
  EXPECT_EQ(std::vector<uint8_t>(out, out + 5), head16);
  EXPECT_EQ(fw_tx16_request(0xFFFF, payload, 14, out, 18), 0);  // does not fit
}

TEST(FirmwareConfig, ReadsEveryImageRoomfixDevicesWritesForTheDemoRoom) {
  Site site;
  std::string error;
  ASSERT_TRUE(LoadSite(testing::DemoSitePath(), &site, &error)) << error;
  std::vector<DeviceImage> images;
  ASSERT_TRUE(DeviceConfigsForSite(site, {}, &images, &error)) << error;
  for (const DeviceImage& image : images) {
    const std::vector<uint8_t> bytes = EncodeDeviceConfig(image.config);
    fw_config c;
    ASSERT_EQ(fw_config_parse(bytes.data(), static_cast<uint8_t>(image.config.role), &c),
              FW_FAULT_NONE)
        << image.name;
    EXPECT_EQ(c.id, image.config.id);
    EXPECT_EQ(c.slot_us, image.config.slot_us);
    EXPECT_EQ(c.frame_us, image.config.frame_us);
    EXPECT_EQ(c.fire_delay_us, image.config.fire_delay_us);
    EXPECT_EQ(c.window_open_us, image.config.window_open_us);
    EXPECT_EQ(c.window_close_us, image.config.window_close_us);
    EXPECT_EQ(c.report_delay_us, image.config.report_delay_us);
    EXPECT_EQ(c.tof_offset_ns, image.config.tof_offset_ns);
    EXPECT_EQ(c.radio_latency_us, image.config.radio_latency_us);
    EXPECT_EQ(c.max_range_cm, image.config.max_range_cm);
    EXPECT_EQ(c.sound_speed_mm_s, image.config.sound_speed_mm_s);
    uint64_t coordinator = 0;
    for (uint8_t b : c.coordinator_address) coordinator = (coordinator << 8) | b;
    EXPECT_EQ(coordinator, image.config.coordinator_address);
    // The other role's firmware refuses it.
    const uint8_t other =
        image.config.role == DeviceRole::kBeacon ? FW_ROLE_RECEIVER : FW_ROLE_BEACON;
    EXPECT_EQ(fw_config_parse(bytes.data(), other, &c), FW_FAULT_CONFIG_INVALID);
  }
}

TEST(FirmwareConfig, RefusesEveryCorruptionWithItsFault) {
  Site site;
  std::string error;
  ASSERT_TRUE(LoadSite(testing::DemoSitePath(), &site, &error)) << error;
  std::vector<DeviceImage> images;
  ASSERT_TRUE(DeviceConfigsForSite(site, {}, &images, &error)) << error;
  const std::vector<uint8_t> good = EncodeDeviceConfig(images[0].config);
  fw_config c;
  for (size_t bit = 0; bit < 8 * good.size(); ++bit) {
    std::vector<uint8_t> bad = good;
    bad[bit / 8] ^= static_cast<uint8_t>(1u << (bit % 8));
    const uint8_t fault = fw_config_parse(bad.data(), FW_ROLE_BEACON, &c);
    EXPECT_TRUE(fault == FW_FAULT_CONFIG_CRC || fault == FW_FAULT_CONFIG_MISSING) << "bit " << bit;
  }
  const std::vector<uint8_t> erased(FW_CONFIG_BYTES, 0xFF);
  EXPECT_EQ(fw_config_parse(erased.data(), FW_ROLE_BEACON, &c), FW_FAULT_CONFIG_MISSING);
  // A newer layout, correctly checksummed, is a version fault.
  std::vector<uint8_t> newer = good;
  newer[2] = 2;
  const uint16_t crc = Crc16CcittFalse(newer.data(), newer.size() - 2);
  newer[newer.size() - 2] = static_cast<uint8_t>(crc >> 8);
  newer[newer.size() - 1] = static_cast<uint8_t>(crc);
  EXPECT_EQ(fw_config_parse(newer.data(), FW_ROLE_BEACON, &c), FW_FAULT_CONFIG_VERSION);
}

TEST(FirmwareTiming, TimeOfFlightIsSixtyTwoAndAHalfNanosecondsATick) {
  EXPECT_EQ(fw_time_of_flight_ns(0, 0), 0u);
  EXPECT_EQ(fw_time_of_flight_ns(2, 0), 125u);
  EXPECT_EQ(fw_time_of_flight_ns(3, 0), 187u);  // 187.5 truncated
  // 10 ms of ticks less a 1.434 ms offset.
  EXPECT_EQ(fw_time_of_flight_ns(160000, 1434000), 8566000u);
  // An echo before the offset says is not a negative distance.
  EXPECT_EQ(fw_time_of_flight_ns(100, 1434000), 0u);
  // A negative offset (fire delay below the latency) adds.
  EXPECT_EQ(fw_time_of_flight_ns(16, -1000), 2000u);
  // The largest window the configuration allows, 200 ms, is exact.
  EXPECT_EQ(fw_time_of_flight_ns(3200000, 0), 200000000u);
}

}  // namespace
}  // namespace roomfix::radio
