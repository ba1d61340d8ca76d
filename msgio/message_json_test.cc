#include "msgio/message_json.h"

#include <gtest/gtest.h>

#include <climits>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <nlohmann/json.hpp>

#include "roomfix/image_t.hpp"
#include "roomfix/marker_pixels_t.hpp"
#include "roomfix/pose2d_t.hpp"
#include "roomfix/process_status_t.hpp"
#include "roomfix/range_set_t.hpp"
#include "roomfix/site_t.hpp"
#include "tests/testing/test_messages.h"
#include "tests/testing/wire_test_messages.h"

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
  EXPECT_NE(json.find("\"ranges\":[{\"receiver_id\":3,\"receiver_position_m\":[4.0,0.0,0.0]"),
            std::string::npos)
      << json;
}

// Strings are a publisher's bytes: quotes, control bytes and bytes that are
// not UTF-8 still give one line of valid JSON that reads back to the text
// (with U+FFFD for the byte that is no UTF-8). The newline is written "\n"
// (nlohmann's escape; the hand-written writer wrote "\u000a", the same JSON).
TEST(MessageJson, EscapesStringsInAStatus) {
  process_status_t s{};
  s.process = "trilat_proc";
  s.last_error = "bad \"range\"\n\x01 \xff";
  counter_t c{};
  c.name = "negative_range";
  c.count = 3;
  s.rejected.push_back(c);
  s.num_rejected = 1;
  const auto bytes = Encode(s);
  std::string json, error;
  ASSERT_TRUE(MessageToJson(bytes.data(), static_cast<int>(bytes.size()), &json, &error));
  EXPECT_NE(json.find("\"rejected\":{\"negative_range\":3}"), std::string::npos) << json;
  EXPECT_NE(json.find("\"last_error\":\"bad \\\"range\\\"\\n\\u0001 "), std::string::npos) << json;
  EXPECT_EQ(json.find('\n'), std::string::npos) << "one line";
  const auto parsed = nlohmann::json::parse(json);
  EXPECT_EQ(parsed["last_error"], "bad \"range\"\n\x01 \xef\xbf\xbd");
}

TEST(MessageJson, RefusesUnknownAndCorruptPayloads) {
  std::string json, error;
  const uint8_t junk[16] = {1};
  EXPECT_FALSE(MessageToJson(junk, 16, &json, &error));
  EXPECT_EQ(error, "not a roomfix message (unknown fingerprint)");
  auto bytes = Encode(testing::MakeTestPose(1, 1, 1, 1));
  std::string reason;
  EXPECT_FALSE(MessageToJson(bytes.data(), 20, &json, &error, &reason));
  EXPECT_EQ(error,
            "refused: pose2d_t.camera_id..num_measurements needs 132 bytes at byte 17 of 20");
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

// The doubles the bytes of a line depend on: short and long decimals,
// integers, powers of ten both ways, a negative zero, the smallest
// subnormal, and the non-finite values that become null.
constexpr double kAwkwardDoubles[] = {0.1,
                                      1.0 / 3.0,
                                      4.0,
                                      -2.5,
                                      1e-7,
                                      1e20,
                                      -0.0,
                                      4.9406564584124654e-324,
                                      1e300,
                                      123456789.125,
                                      std::numeric_limits<double>::quiet_NaN(),
                                      -std::numeric_limits<double>::infinity()};

template <class Msg>
std::string JsonOf(const Msg& m) {
  const auto bytes = Encode(m);
  std::string json, error;
  EXPECT_TRUE(MessageToJson(bytes.data(), static_cast<int>(bytes.size()), &json, &error)) << error;
  return json;
}

// One line per type, byte for byte as `roomfix listen` prints it: the keys
// in the message's field order, written by nlohmann's dump(). Doubles are
// printed in the shortest form that reads back to the same bits (0.1, not
// 0.10000000000000001; 4.0 and -0.0, not 4 and -0; exponents as 1e-07),
// NaN and infinities as null; integers without ".0".
TEST(MessageJson, KeepsEveryTypesBytes) {
  pose2d_t pose = testing::MakeTestPose(1700000000000001, 3, 0.1, 1.0 / 3.0);
  pose.camera_id = 2;
  pose.z_m = 4.0;
  pose.heading_rad = -2.5;
  for (int k = 0; k < 9; ++k) pose.covariance[k / 3][k % 3] = kAwkwardDoubles[k];
  pose.residual_m = kAwkwardDoubles[9];
  EXPECT_EQ(
      JsonOf(pose),
      R"({"type":"roomfix.pose2d_t","utime":1700000000000001,"source":2,"camera_id":2,"robot_id":3,"measurement_seq":17000000000,"x_m":0.1,"y_m":0.3333333333333333,"z_m":4.0,"heading_rad":-2.5,"covariance":[0.1,0.3333333333333333,4.0,-2.5,1e-07,1e+20,-0.0,5e-324,1e+300],"residual_m":123456789.125,"num_measurements":4,"status":0,"latency_us":1500})");

  marker_pixels_t pixels{};
  pixels.utime = 5;
  pixels.camera_id = 1;
  pixels.frame_seq = 99;
  pixels.width_px = 640;
  pixels.height_px = 480;
  pixels.search_mode = marker_pixels_t::SEARCH_REGION_OF_INTEREST;
  pixels.processing_time_us = 1234;
  marker_t marker{};
  marker.colour_class = "red";
  marker.robot_id = 7;
  marker.role = marker_t::ROLE_HEADING;
  marker.u_px = kAwkwardDoubles[0];
  marker.v_px = kAwkwardDoubles[9];
  marker.radius_px = kAwkwardDoubles[10];
  marker.circularity = kAwkwardDoubles[11];
  marker.area_px = kAwkwardDoubles[7];
  pixels.markers = {marker, marker};
  pixels.num_markers = 2;
  EXPECT_EQ(
      JsonOf(pixels),
      R"({"type":"roomfix.marker_pixels_t","utime":5,"camera_id":1,"frame_seq":99,"width_px":640,"height_px":480,"search_mode":1,"processing_time_us":1234,"markers":[{"colour_class":"red","robot_id":7,"role":2,"u_px":0.1,"v_px":123456789.125,"radius_px":null,"circularity":null,"area_px":5e-324},{"colour_class":"red","robot_id":7,"role":2,"u_px":0.1,"v_px":123456789.125,"radius_px":null,"circularity":null,"area_px":5e-324}]})");

  range_set_t set{};
  set.utime = 10;
  set.beacon_id = 2;
  set.firing_seq = 77;
  set.speed_of_sound_mps = 343.21;
  set.temperature_c = kAwkwardDoubles[6];
  set.num_expected = 4;
  range_t r{};
  r.receiver_id = 3;
  r.receiver_position_m[0] = kAwkwardDoubles[4];
  r.receiver_position_m[1] = kAwkwardDoubles[5];
  r.receiver_position_m[2] = kAwkwardDoubles[8];
  r.range_m = 2.5;
  r.time_of_flight_us = 2.5 / 343.21 * 1e6;
  r.arrival_utime = 11;
  set.ranges = {r};
  set.num_ranges = 1;
  EXPECT_EQ(
      JsonOf(set),
      R"({"type":"roomfix.range_set_t","utime":10,"beacon_id":2,"firing_seq":77,"speed_of_sound_mps":343.21,"temperature_c":-0.0,"num_expected":4,"ranges":[{"receiver_id":3,"receiver_position_m":[1e-07,1e+20,1e+300],"time_of_flight_us":7284.170041665453,"range_m":2.5,"arrival_utime":11}]})");

  process_status_t status{};
  status.utime = 12;
  status.process = "trilat_proc";
  status.host = "solver";
  status.pid = 4321;
  status.uptime_us = 1000000;
  status.state = 1;
  status.inputs = 10;
  status.outputs = 9;
  status.dropped = 1;
  counter_t c{};
  c.name = "negative_range";
  c.count = 3;
  status.rejected = {c};
  status.num_rejected = 1;
  c.name = "heartbeats";
  c.count = 40;
  status.counters = {c};
  c.name = "ranges_in";
  c.count = 41;
  status.counters.push_back(c);
  status.num_counters = 2;
  status.last_error = "range 7 refused";
  status.last_error_utime = 11;
  EXPECT_EQ(
      JsonOf(status),
      R"({"type":"roomfix.process_status_t","utime":12,"process":"trilat_proc","host":"solver","pid":4321,"uptime_us":1000000,"state":1,"inputs":10,"outputs":9,"dropped":1,"rejected":{"negative_range":3},"counters":{"heartbeats":40,"ranges_in":41},"last_error":"range 7 refused","last_error_utime":11})");

  image_t image{};
  image.utime = 13;
  image.camera_id = 1;
  image.frame_seq = 8;
  image.width_px = 320;
  image.height_px = 240;
  image.source_width_px = 640;
  image.source_height_px = 480;
  image.format = "jpeg";
  image.data.assign(5, 0xff);
  image.num_bytes = 5;
  EXPECT_EQ(
      JsonOf(image),
      R"({"type":"roomfix.image_t","utime":13,"camera_id":1,"frame_seq":8,"width_px":320,"height_px":240,"source_width_px":640,"source_height_px":480,"format":"jpeg","num_bytes":5})");

  site_t site{};
  site.utime = 14;
  site.site_name = "demo";
  site.site_path = "/etc/roomfix/demo.yaml";
  site.site_text = "name: demo\n";
  site_file_t file{};
  file.name = "camera0.yaml";
  file.text = "model: full\n";
  site.files = {file};
  site.num_files = 1;
  site.missing = "";
  site.content_hash = "abc123";
  site.roomfix_version = "0.9.0";
  site.process = "trilat_proc";
  site.host = "solver";
  site.pid = 4321;
  EXPECT_EQ(
      JsonOf(site),
      R"({"type":"roomfix.site_t","utime":14,"site_name":"demo","site_path":"/etc/roomfix/demo.yaml","site_text_bytes":11,"files":[{"name":"camera0.yaml","bytes":12}],"missing":"","content_hash":"abc123","roomfix_version":"0.9.0","process":"trilat_proc","host":"solver","pid":4321})");
}

uint64_t Bits(double d) {
  uint64_t bits;
  std::memcpy(&bits, &d, sizeof bits);
  return bits;
}

// The shortest form loses nothing: every finite double of a line parses
// back to the same bits, the sign of a zero included, and non-finite ones
// are null (as docs/python.md tells a reader of `roomfix listen`).
TEST(MessageJson, EveryDoubleReadsBackBitForBit) {
  const double doubles[] = {0.1,
                            1e-300,
                            123456789.123456789,
                            -0.0,
                            0.0,
                            1.0 / 3.0,
                            4.0,
                            -2.5,
                            1e-7,
                            1e20,
                            4.9406564584124654e-324,
                            2.2250738585072014e-308,
                            std::numeric_limits<double>::max(),
                            1e300,
                            123456789.125,
                            std::nextafter(1.0, 2.0),
                            2.5 / 343.21 * 1e6};
  for (const double d : doubles) {
    pose2d_t pose = testing::MakeTestPose(1, 3, d, -d);
    pose.covariance[1][2] = d;
    const nlohmann::json parsed = nlohmann::json::parse(JsonOf(pose));
    EXPECT_EQ(Bits(parsed["x_m"].get<double>()), Bits(d)) << parsed["x_m"];
    EXPECT_EQ(Bits(parsed["y_m"].get<double>()), Bits(-d)) << parsed["y_m"];
    EXPECT_EQ(Bits(parsed["covariance"][5].get<double>()), Bits(d)) << parsed["covariance"][5];
  }
  pose2d_t pose = testing::MakeTestPose(1, 3, std::numeric_limits<double>::quiet_NaN(),
                                        std::numeric_limits<double>::infinity());
  pose.z_m = -std::numeric_limits<double>::infinity();
  const nlohmann::json parsed = nlohmann::json::parse(JsonOf(pose));
  EXPECT_TRUE(parsed["x_m"].is_null());
  EXPECT_TRUE(parsed["y_m"].is_null());
  EXPECT_TRUE(parsed["z_m"].is_null());
}

}  // namespace
}  // namespace roomfix
