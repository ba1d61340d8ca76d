#include "core/radio/device_config.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "core/world/ultrasound_model.h"
#include "tests/testing/demo_site.h"

namespace roomfix::radio {
namespace {

DeviceConfig SampleBeacon() {
  DeviceConfig c;
  c.role = DeviceRole::kBeacon;
  c.id = 7;
  c.own_address = 0x0013A20042000007ull;
  c.coordinator_address = 0x0013A20040000001ull;
  c.slot_index = 1;
  c.slot_count = 3;
  c.slot_us = 40000;
  c.frame_us = 120000;
  c.fire_delay_us = 3000;
  c.burst_cycles = 16;
  c.radio_latency_us = 1616;
  c.window_open_us = 884;
  c.window_close_us = 22000;
  c.report_delay_us = 0;
  c.tof_offset_ns = -123456;  // negative: a fire delay below the latency
  c.sound_speed_mm_s = 331300;
  c.max_range_cm = 510;
  c.slot_beacon_ids = {2, 7, 9};
  return c;
}

TEST(DeviceConfig, RoundTripsEveryField) {
  const DeviceConfig c = SampleBeacon();
  ASSERT_TRUE(c.IsValid(nullptr));
  const std::vector<uint8_t> image = EncodeDeviceConfig(c);
  ASSERT_EQ(image.size(), kDeviceConfigBytes);
  DeviceConfig back;
  std::string error;
  ASSERT_TRUE(DecodeDeviceConfig(image.data(), image.size(), &back, &error)) << error;
  EXPECT_EQ(EncodeDeviceConfig(back), image);
  EXPECT_EQ(back.tof_offset_ns, -123456);
  EXPECT_EQ(back.own_address, 0x0013A20042000007ull);
  EXPECT_EQ(back.slot_beacon_ids[2], 9);
}

TEST(DeviceConfig, StartsWithTheDocumentedBytes) {
  // firmware/INTERFACE.md: "RF", layout 1, role, id, flags, own address.
  const std::vector<uint8_t> image = EncodeDeviceConfig(SampleBeacon());
  const std::vector<uint8_t> head = {0x52, 0x46, 0x01, 0x01, 0x07, 0x00, 0x00,
                                     0x13, 0xA2, 0x00, 0x42, 0x00, 0x00, 0x07};
  EXPECT_EQ(std::vector<uint8_t>(image.begin(), image.begin() + 14), head);
}

TEST(DeviceConfig, EverySingleBitErrorIsRefused) {
  const std::vector<uint8_t> good = EncodeDeviceConfig(SampleBeacon());
  for (size_t bit = 0; bit < good.size() * 8; ++bit) {
    std::vector<uint8_t> bad = good;
    bad[bit / 8] ^= static_cast<uint8_t>(1u << (bit % 8));
    DeviceConfig c;
    std::string error;
    EXPECT_FALSE(DecodeDeviceConfig(bad.data(), bad.size(), &c, &error)) << "bit " << bit;
    EXPECT_FALSE(error.empty());
  }
}

TEST(DeviceConfig, AnErasedEepromSaysNoConfiguration) {
  const std::vector<uint8_t> erased(kDeviceConfigBytes, 0xFF);
  DeviceConfig c;
  std::string error;
  EXPECT_FALSE(DecodeDeviceConfig(erased.data(), erased.size(), &c, &error));
  EXPECT_NE(error.find("no configuration"), std::string::npos) << error;
}

TEST(DeviceConfig, IsValidRefusesABeaconOutsideItsTable) {
  DeviceConfig c = SampleBeacon();
  c.slot_beacon_ids[1] = 8;
  std::string error;
  EXPECT_FALSE(c.IsValid(&error));
  EXPECT_NE(error.find("slot table"), std::string::npos) << error;
  c = SampleBeacon();
  c.fire_delay_us = kMaxFireDelayUs + 1;
  EXPECT_FALSE(c.IsValid(&error));
}

TEST(IntelHex, RoundTripsAnImageAsAvrdudeReadsIt) {
  const std::vector<uint8_t> image = EncodeDeviceConfig(SampleBeacon());
  const std::string text = EncodeIntelHex(image);
  // 72 bytes: four full 16-byte records, one of 8, and the end record.
  EXPECT_EQ(std::count(text.begin(), text.end(), '\n'), 6);
  EXPECT_EQ(text.substr(0, 9), ":10000000");
  EXPECT_EQ(text.substr(text.size() - 12), ":00000001FF\n");
  std::vector<uint8_t> back;
  std::string error;
  ASSERT_TRUE(DecodeIntelHex(text, &back, &error)) << error;
  EXPECT_EQ(back, image);
}

TEST(IntelHex, RefusesADamagedRecord) {
  std::string text = EncodeIntelHex(EncodeDeviceConfig(SampleBeacon()));
  text[12] = text[12] == '0' ? '1' : '0';  // a data digit of the first record
  std::vector<uint8_t> back;
  std::string error;
  EXPECT_FALSE(DecodeIntelHex(text, &back, &error));
  EXPECT_NE(error.find("line 1: bad checksum"), std::string::npos) << error;
  EXPECT_FALSE(DecodeIntelHex(":10000000\n", &back, &error));
  EXPECT_FALSE(DecodeIntelHex(":00000001FF\n:0100000000FF\n", &back, &error));
  EXPECT_FALSE(DecodeIntelHex(":0100000000FF\n", &back, &error));  // no end record
}

TEST(NominalRadioLatency, AddsTheDocumentedTerms) {
  // 100 + 128 + 192 + 33 x 32 + 100 + 40 us (docs/devices.md's budget).
  constexpr double kSumRoundingUs = 1e-9;  // sums of exact binary fractions
  EXPECT_EQ(AirFrameBytes(10), 33u);
  EXPECT_NEAR(NominalRadioLatencyUs(10), 1616.0, kSumRoundingUs);
}

TEST(DeviceConfigsForSite, GivesTheDemoRoomsDevicesTheirTable) {
  Site site;
  std::string error;
  ASSERT_TRUE(LoadSite(testing::DemoSitePath(), &site, &error)) << error;
  std::vector<DeviceImage> images;
  ASSERT_TRUE(DeviceConfigsForSite(site, {}, &images, &error)) << error;
  ASSERT_EQ(images.size(), 5u);
  const DeviceConfig& beacon = images[0].config;
  EXPECT_EQ(images[0].name, "beacon-1");
  EXPECT_EQ(beacon.role, DeviceRole::kBeacon);
  EXPECT_EQ(beacon.own_address, 0x0013A20042000001ull);
  EXPECT_EQ(beacon.slot_count, 1);
  EXPECT_EQ(beacon.slot_beacon_ids[0], 1);
  // One beacon: a frame of one slot, or 100 ms (10 Hz) if that is longer.
  EXPECT_GT(beacon.slot_us, 0u);
  EXPECT_EQ(beacon.frame_us, std::max(beacon.slot_us, 100000u));
  EXPECT_EQ(beacon.radio_latency_us, 1616);
  // The offset: fire delay 3000 - latency 1616 + detector 50 us.
  EXPECT_EQ(beacon.tof_offset_ns, 1434000);
  // The window covers the room's longest flight at 0 degC.
  const double flight_us = beacon.max_range_cm * 1e4 / SpeedOfSound(0.0);
  EXPECT_GT(beacon.window_close_us, 1384 + flight_us);
  for (size_t i = 1; i < images.size(); ++i) {
    EXPECT_EQ(images[i].config.role, DeviceRole::kReceiver);
    EXPECT_EQ(images[i].config.report_delay_us, (i - 1) * 2000u);
    EXPECT_TRUE(images[i].config.IsValid(&error)) << error;
  }
  EXPECT_EQ(images[4].config.own_address, 0x0013A20041000004ull);
}

TEST(DeviceConfigsForSite, RefusesReportsThatDoNotFitBeforeTheNextFiring) {
  Site site;
  std::string error;
  ASSERT_TRUE(LoadSite(testing::DemoSitePath(), &site, &error)) << error;
  DeviceConfigOptions options;
  // Four reports 20 ms apart after a 20 ms window: longer than the demo
  // room's slot of about 100 ms.
  options.report_spacing_us = 20000;
  std::vector<DeviceImage> images;
  EXPECT_FALSE(DeviceConfigsForSite(site, options, &images, &error));
  EXPECT_NE(error.find("busy"), std::string::npos) << error;
}

}  // namespace
}  // namespace roomfix::radio
