#include "msgio/message_json.h"

#include <gtest/gtest.h>

#include <climits>

#include "msgio/test_messages.h"
#include "msgio/wire_test_messages.h"
#include "roomfix/marker_pixels_t.hpp"
#include "roomfix/process_status_t.hpp"
#include "roomfix/range_set_t.hpp"

namespace roomfix {
namespace {

template <class Msg>
std::vector<uint8_t> Encode(const Msg& m) {
  std::vector<uint8_t> bytes(m.getEncodedSize());
  m.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
  return bytes;
}

TEST(MessageJson, NamesEveryRoomfixTypeByItsFingerprint) {
  EXPECT_STREQ(RoomfixTypeName(Encode(testing::MakeTestPose(1, 1, 1, 1)).data(), 200),
               "roomfix.pose2d_t");
  EXPECT_STREQ(RoomfixTypeName(Encode(range_set_t()).data(), 100), "roomfix.range_set_t");
  EXPECT_STREQ(RoomfixTypeName(Encode(marker_pixels_t()).data(), 100), "roomfix.marker_pixels_t");
  process_status_t status{};
  EXPECT_STREQ(RoomfixTypeName(Encode(status).data(), 100), "roomfix.process_status_t");
  const uint8_t junk[8] = {0};
  EXPECT_EQ(RoomfixTypeName(junk, 8), nullptr);
  EXPECT_EQ(RoomfixTypeName(junk, 3), nullptr);
}

TEST(MessageJson, WritesAPoseWithNanAsNull) {
  const auto bytes = Encode(testing::MakeTestPose(1700000000000000, 3, 1.5, -0.25));
  std::string json, error;
  ASSERT_TRUE(MessageToJson(bytes.data(), static_cast<int>(bytes.size()), &json, &error));
  EXPECT_NE(json.find("\"type\":\"roomfix.pose2d_t\""), std::string::npos) << json;
  EXPECT_NE(json.find("\"utime\":1700000000000000"), std::string::npos);
  EXPECT_NE(json.find("\"robot_id\":3"), std::string::npos);
  EXPECT_NE(json.find("\"x_m\":1.5"), std::string::npos);
  EXPECT_NE(json.find("\"y_m\":-0.25"), std::string::npos);
  EXPECT_NE(json.find("\"heading_rad\":null"), std::string::npos);
}

TEST(MessageJson, WritesARangeSetWithItsRanges) {
  range_set_t set{};
  set.utime = 10;
  set.beacon_id = 2;
  set.firing_seq = 77;
  set.speed_of_sound_mps = 343.0;
  set.num_expected = 4;
  range_t r{};
  r.receiver_id = 3;
  r.receiver_position_m[0] = 4;
  r.range_m = 2.5;
  r.time_of_flight_us = 2.5 / 343.0 * 1e6;
  set.ranges.push_back(r);
  set.num_ranges = 1;
  const auto bytes = Encode(set);
  std::string json, error;
  ASSERT_TRUE(MessageToJson(bytes.data(), static_cast<int>(bytes.size()), &json, &error));
  EXPECT_NE(json.find("\"firing_seq\":77"), std::string::npos) << json;
  EXPECT_NE(json.find("\"ranges\":[{\"receiver_id\":3,\"receiver_position_m\":[4,0,0]"),
            std::string::npos)
      << json;
}

TEST(MessageJson, EscapesStringsInAStatus) {
  process_status_t s{};
  s.process = "trilat_proc";
  s.last_error = "bad \"range\"\n";
  counter_t c{};
  c.name = "negative_range";
  c.count = 3;
  s.rejected.push_back(c);
  s.num_rejected = 1;
  const auto bytes = Encode(s);
  std::string json, error;
  ASSERT_TRUE(MessageToJson(bytes.data(), static_cast<int>(bytes.size()), &json, &error));
  EXPECT_NE(json.find("\"rejected\":{\"negative_range\":3}"), std::string::npos) << json;
  EXPECT_NE(json.find("\"last_error\":\"bad \\\"range\\\"\\u000a\""), std::string::npos) << json;
}

TEST(MessageJson, RefusesUnknownAndCorruptPayloads) {
  std::string json, error;
  const uint8_t junk[16] = {1};
  EXPECT_FALSE(MessageToJson(junk, 16, &json, &error));
  EXPECT_EQ(error, "not a roomfix message (unknown fingerprint)");
  auto bytes = Encode(testing::MakeTestPose(1, 1, 1, 1));
  std::string reason;
  EXPECT_FALSE(MessageToJson(bytes.data(), 20, &json, &error, &reason));
  EXPECT_EQ(error, "refused: pose2d_t.utime..latency_us needs 150 bytes at byte 8 of 20");
  EXPECT_EQ(reason, "truncated");
  EXPECT_FALSE(MessageToJson(junk, 16, &json, &error, &reason));
  EXPECT_EQ(reason, "unknown_type");
}

// `roomfix listen` and the log tools went down on this (LCM 1.3.1's decoder
// assigns length - 1 characters).
TEST(MessageJson, RefusesAStatusWithAStringLengthOfInt32Min) {
  std::vector<uint8_t> bytes = Encode(testing::MakeTestStatus());
  testing::PutInt32(&bytes, testing::kStatusProcessLengthOffset, INT32_MIN);
  std::string json, error, reason;
  EXPECT_FALSE(MessageToJson(bytes.data(), static_cast<int>(bytes.size()), &json, &error, &reason));
  EXPECT_EQ(reason, "negative_length");
  EXPECT_EQ(error, "refused: process_status_t.process length -2147483648 at byte 20 of " +
                       std::to_string(bytes.size()));
  EXPECT_TRUE(json.empty());
}

}  // namespace
}  // namespace roomfix
