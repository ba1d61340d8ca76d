#include "core/radio/wall_payload.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>

namespace roomfix::radio {
namespace {

TEST(Crc16CcittFalse, MatchesTheStandardCheckValue) {
  const char* text = "123456789";
  EXPECT_EQ(Crc16CcittFalse(reinterpret_cast<const uint8_t*>(text), std::strlen(text)), 0x29B1);
}

TEST(WallMessage, RangeReportHasTheDocumentedBytes) {
  WallMessage m;
  m.type = PayloadType::kRangeReport;
  m.beacon_id = 3;
  m.firing_seq = 0x1234;
  m.time_of_flight_ns = 12'345'678;  // 0x00BC614E: 12.3 ms, about 4.2 m
  m.temperature_centi_c = 2150;      // 21.50 degC = 0x0866
  m.flags = kFlagWeakEcho;
  const std::vector<uint8_t> bytes = EncodeWallMessage(m);
  ASSERT_EQ(bytes.size(), kRangeReportPayloadBytes);
  const std::vector<uint8_t> head = {0x01, 0x02, 0x03, 0x12, 0x34, 0x00,
                                     0xBC, 0x61, 0x4E, 0x08, 0x66, 0x01};
  EXPECT_EQ(std::vector<uint8_t>(bytes.begin(), bytes.begin() + 12), head);
  const uint16_t crc = Crc16CcittFalse(head.data(), head.size());
  EXPECT_EQ(bytes[12], crc >> 8);
  EXPECT_EQ(bytes[13], crc & 0xFF);
}

TEST(WallMessage, FiringAnnouncementHasTheDocumentedBytes) {
  WallMessage m;
  m.type = PayloadType::kFiring;
  m.beacon_id = 1;
  m.firing_seq = 65535;
  m.temperature_centi_c = kNoTemperature;
  const std::vector<uint8_t> bytes = EncodeWallMessage(m);
  ASSERT_EQ(bytes.size(), kFiringPayloadBytes);
  const std::vector<uint8_t> head = {0x01, 0x01, 0x01, 0xFF, 0xFF, 0x80, 0x00, 0x00};
  EXPECT_EQ(std::vector<uint8_t>(bytes.begin(), bytes.begin() + 8), head);
}

TEST(WallMessage, RoundTripsEveryField) {
  for (PayloadType type : {PayloadType::kFiring, PayloadType::kRangeReport}) {
    WallMessage m;
    m.type = type;
    m.beacon_id = 255;
    m.firing_seq = 40000;
    m.time_of_flight_ns = type == PayloadType::kRangeReport ? 4'000'000'000u : 0;
    m.temperature_centi_c = -1234;
    m.flags = 0xFF;
    const std::vector<uint8_t> bytes = EncodeWallMessage(m);
    WallMessage back;
    ASSERT_EQ(DecodeWallMessage(bytes.data(), bytes.size(), &back), PayloadError::kOk);
    EXPECT_EQ(back.type, m.type);
    EXPECT_EQ(back.beacon_id, m.beacon_id);
    EXPECT_EQ(back.firing_seq, m.firing_seq);
    EXPECT_EQ(back.time_of_flight_ns, m.time_of_flight_ns);
    EXPECT_EQ(back.temperature_centi_c, m.temperature_centi_c);
    EXPECT_EQ(back.flags, m.flags);
  }
}

std::vector<uint8_t> ValidReport() {
  WallMessage m;
  m.beacon_id = 1;
  m.firing_seq = 7;
  m.time_of_flight_ns = 9'000'000;
  m.temperature_centi_c = 2000;
  return EncodeWallMessage(m);
}

TEST(DecodeWallMessage, RejectsEachMalformedPayloadWithItsReason) {
  WallMessage m;
  std::string detail;
  EXPECT_EQ(DecodeWallMessage(nullptr, 0, &m, &detail), PayloadError::kEmpty);

  std::vector<uint8_t> bytes = ValidReport();
  bytes[0] = 2;
  EXPECT_EQ(DecodeWallMessage(bytes.data(), bytes.size(), &m, &detail),
            PayloadError::kUnsupportedVersion);
  EXPECT_NE(detail.find("version 2"), std::string::npos) << detail;

  bytes = ValidReport();
  bytes[1] = 0x07;
  EXPECT_EQ(DecodeWallMessage(bytes.data(), bytes.size(), &m, &detail), PayloadError::kUnknownType);

  bytes = ValidReport();
  bytes.pop_back();
  EXPECT_EQ(DecodeWallMessage(bytes.data(), bytes.size(), &m, &detail), PayloadError::kBadLength);

  bytes = ValidReport();
  bytes.push_back(0);
  EXPECT_EQ(DecodeWallMessage(bytes.data(), bytes.size(), &m, &detail), PayloadError::kBadLength);

  WallMessage zero;
  zero.beacon_id = 0;
  bytes = EncodeWallMessage(zero);
  EXPECT_EQ(DecodeWallMessage(bytes.data(), bytes.size(), &m, &detail), PayloadError::kBadBeaconId);
}

TEST(DecodeWallMessage, CrcCatchesEverySingleBitError) {
  const std::vector<uint8_t> good = ValidReport();
  int caught = 0;
  int total = 0;
  // Bits of the version and type bytes fail earlier checks; every other bit
  // flip must be caught by the CRC.
  for (size_t byte = 2; byte < good.size(); ++byte) {
    for (int bit = 0; bit < 8; ++bit) {
      std::vector<uint8_t> bad = good;
      bad[byte] ^= static_cast<uint8_t>(1 << bit);
      WallMessage m;
      ++total;
      if (DecodeWallMessage(bad.data(), bad.size(), &m) == PayloadError::kBadCrc) ++caught;
    }
  }
  EXPECT_EQ(caught, total);
}

TEST(DecodeWallMessage, CrcCatchesASwappedFiringNumberThatAnEightBitSumMisses) {
  // Swapping the two bytes of the firing number keeps an 8-bit sum (the XBee
  // checksum) unchanged; it must not pass as another firing.
  WallMessage m;
  m.beacon_id = 1;
  m.firing_seq = 0x0102;
  m.time_of_flight_ns = 5'000'000;
  std::vector<uint8_t> bytes = EncodeWallMessage(m);
  std::swap(bytes[3], bytes[4]);
  WallMessage out;
  EXPECT_EQ(DecodeWallMessage(bytes.data(), bytes.size(), &out), PayloadError::kBadCrc);
}

TEST(WireUnits, TimeOfFlightRoundsToNanosecondsAndSaturates) {
  EXPECT_EQ(TimeOfFlightToNs(0.0123456784), 12'345'678u);
  EXPECT_EQ(TimeOfFlightToNs(-1.0), 0u);
  EXPECT_EQ(TimeOfFlightToNs(10.0), UINT32_MAX);
  EXPECT_EQ(TimeOfFlightToNs(std::nan("")), 0u);
}

TEST(WireUnits, TemperatureRoundsToHundredthsAndKeepsTheSentinelForNaN) {
  EXPECT_EQ(TemperatureToCentiC(21.456), 2146);
  EXPECT_EQ(TemperatureToCentiC(-5.0), -500);
  EXPECT_EQ(TemperatureToCentiC(1e6), INT16_MAX);
  EXPECT_EQ(TemperatureToCentiC(-1e6), INT16_MIN + 1);
  EXPECT_EQ(TemperatureToCentiC(std::nan("")), kNoTemperature);
}

}  // namespace
}  // namespace roomfix::radio
