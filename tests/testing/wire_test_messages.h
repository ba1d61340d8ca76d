#ifndef ROOMFIX_TESTS_TESTING_WIRE_TEST_MESSAGES_H_
#define ROOMFIX_TESTS_TESTING_WIRE_TEST_MESSAGES_H_

// A realistic message of every roomfix type with every array non-empty and
// every string set, and their encoded bytes: for the wire check's tests and
// the fuzz target's seeds.

#include <cstdint>
#include <string>
#include <vector>

#include "roomfix/counter_t.hpp"
#include "roomfix/detector_view_request_t.hpp"
#include "roomfix/detector_view_robot_t.hpp"
#include "roomfix/detector_view_t.hpp"
#include "roomfix/image_t.hpp"
#include "roomfix/marker_pixels_t.hpp"
#include "roomfix/marker_t.hpp"
#include "roomfix/pose2d_t.hpp"
#include "roomfix/process_status_t.hpp"
#include "roomfix/range_set_t.hpp"
#include "roomfix/range_t.hpp"
#include "roomfix/site_file_t.hpp"
#include "roomfix/site_t.hpp"
#include "tests/testing/test_messages.h"

namespace roomfix::testing {

template <class Msg>
std::vector<uint8_t> Encode(const Msg& msg) {
  std::vector<uint8_t> bytes(static_cast<size_t>(msg.getEncodedSize()));
  msg.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
  return bytes;
}

// Overwrites 4 bytes at `offset` with a big-endian int32, as LCM writes
// lengths and counts.
inline void PutInt32(std::vector<uint8_t>* bytes, size_t offset, int32_t value) {
  const auto u = static_cast<uint32_t>(value);
  (*bytes)[offset] = static_cast<uint8_t>(u >> 24);
  (*bytes)[offset + 1] = static_cast<uint8_t>(u >> 16);
  (*bytes)[offset + 2] = static_cast<uint8_t>(u >> 8);
  (*bytes)[offset + 3] = static_cast<uint8_t>(u);
}

inline counter_t MakeTestCounter(const std::string& name, int64_t count) {
  counter_t c{};
  c.name = name;
  c.count = count;
  return c;
}

inline range_t MakeTestRange(int32_t receiver_id, double range_m) {
  range_t r{};
  r.receiver_id = receiver_id;
  r.receiver_position_m[0] = 0.1 * receiver_id;
  r.receiver_position_m[1] = 3.0;
  r.receiver_position_m[2] = 2.5;
  r.time_of_flight_us = range_m / 343.2e-6;
  r.range_m = range_m;
  r.arrival_utime = 1700000000012345;
  return r;
}

inline range_set_t MakeTestRangeSet(int num_ranges) {
  range_set_t s{};
  s.utime = 1700000000000000;
  s.beacon_id = 11;
  s.firing_seq = 4242;
  s.speed_of_sound_mps = 343.2;
  s.temperature_c = 20.5;
  s.num_expected = 4;
  for (int i = 0; i < num_ranges; ++i) s.ranges.push_back(MakeTestRange(i + 1, 1.0 + 0.25 * i));
  s.num_ranges = static_cast<int32_t>(s.ranges.size());
  return s;
}

inline marker_t MakeTestMarker(const std::string& colour_class, int32_t robot_id) {
  marker_t m{};
  m.colour_class = colour_class;
  m.robot_id = robot_id;
  m.role = marker_t::ROLE_POSITION;
  m.u_px = 812.25;
  m.v_px = 431.5;
  m.radius_px = 14.0;
  m.circularity = 0.93;
  m.area_px = 615.8;
  return m;
}

inline marker_pixels_t MakeTestMarkerPixels() {
  marker_pixels_t m{};
  m.utime = 1700000000000000;
  m.camera_id = 1;
  m.frame_seq = 99;
  m.width_px = 1920;
  m.height_px = 1080;
  m.search_mode = marker_pixels_t::SEARCH_REGION_OF_INTEREST;
  m.processing_time_us = 4100;
  m.markers = {MakeTestMarker("orange", 1), MakeTestMarker("green", 1)};
  m.num_markers = static_cast<int32_t>(m.markers.size());
  return m;
}

inline image_t MakeTestImage() {
  image_t m{};
  m.utime = 1700000000000000;
  m.camera_id = 1;
  m.frame_seq = 99;
  m.width_px = 480;
  m.height_px = 270;
  m.source_width_px = 1920;
  m.source_height_px = 1080;
  m.format = "jpeg";
  m.data = {0xFF, 0xD8, 0xFF, 0xE0, 0x00, 0x10, 'J', 'F', 'I', 'F', 0x00, 0xFF, 0xD9};
  m.num_bytes = static_cast<int32_t>(m.data.size());
  return m;
}

inline detector_view_robot_t MakeTestDetectorViewRobot(int32_t robot_id, int8_t reason) {
  detector_view_robot_t m{};
  m.robot_id = robot_id;
  m.reason = reason;
  m.colour_class = "green";
  m.value = 40.0;
  m.limit = 120.0;
  m.text = "robot " + std::to_string(robot_id) + ": blob of class green too small";
  return m;
}

inline detector_view_t MakeTestDetectorView() {
  detector_view_t m{};
  m.utime = 1700000000000000;
  m.camera_id = 1;
  m.frame_seq = 99;
  m.width_px = 480;
  m.height_px = 270;
  m.source_width_px = 1920;
  m.source_height_px = 1080;
  m.region_u_px = 0;
  m.region_v_px = 0;
  m.region_width_px = 1920;
  m.region_height_px = 1080;
  m.scale = 4;
  m.format = "png";
  m.data = {0x89, 'P', 'N', 'G', 0x0D, 0x0A, 0x1A, 0x0A};
  m.num_bytes = static_cast<int32_t>(m.data.size());
  m.robots = {MakeTestDetectorViewRobot(1, detector_view_robot_t::REASON_FOUND),
              MakeTestDetectorViewRobot(2, detector_view_robot_t::REASON_TOO_SMALL)};
  m.num_robots = static_cast<int32_t>(m.robots.size());
  return m;
}

inline detector_view_request_t MakeTestDetectorViewRequest() {
  detector_view_request_t m{};
  m.utime = 1700000000000000;
  m.camera_id = -1;
  m.region_u_px = 100;
  m.region_v_px = 50;
  m.region_width_px = 640;
  m.region_height_px = 480;
  m.rate_hz = 1.0;
  m.duration_s = 10.0;
  return m;
}

inline process_status_t MakeTestStatus() {
  process_status_t s{};
  s.utime = 1700000000000000;
  s.process = "trilat_proc";
  s.host = "lab-pc";
  s.pid = 4321;
  s.uptime_us = 60000000;
  s.state = process_status_t::STATE_RUNNING;
  s.inputs = 600;
  s.outputs = 590;
  s.dropped = 2;
  s.rejected = {MakeTestCounter("RANGES.count_over_cap", 3), MakeTestCounter("unknown_beacon", 7)};
  s.num_rejected = static_cast<int32_t>(s.rejected.size());
  s.counters = {MakeTestCounter("warm_starts", 12)};
  s.num_counters = static_cast<int32_t>(s.counters.size());
  s.last_error = "range 3 is negative";
  s.last_error_utime = 1699999999000000;
  return s;
}

inline site_file_t MakeTestSiteFile() {
  site_file_t f{};
  f.name = "../calibration/demo_room_camera.yaml";
  f.text = "model: full\nfit_rms_px: 0.05\n";
  return f;
}

inline site_t MakeTestSite() {
  site_t s{};
  s.utime = 1700000000000000;
  s.site_name = "demo_room";
  s.site_path = "config/sites/demo_room.yaml";
  s.site_text = "name: demo_room\nroom: {size_m: [6, 4, 3]}\n";
  s.files = {MakeTestSiteFile()};
  s.num_files = static_cast<int32_t>(s.files.size());
  s.missing = "missing_camera.yaml";
  s.content_hash = std::string(64, 'a');
  s.roomfix_version = "0.1.0";
  s.process = "trilat_proc";
  s.host = "lab-pc";
  s.pid = 4321;
  return s;
}

// Byte offsets of length and count fields in the messages above (after the
// 8-byte fingerprint and the fixed fields before them; lcmtypes/*.lcm).
inline constexpr size_t kRangeSetNumRangesOffset = 8 + 40;
inline constexpr size_t kStatusProcessLengthOffset = 8 + 8;
inline constexpr size_t kImageFormatLengthOffset = 8 + 36;
inline constexpr size_t kMarkerPixelsNumMarkersOffset = 8 + 33;
inline constexpr size_t kMarkerPixelsFirstColourLengthOffset = kMarkerPixelsNumMarkersOffset + 4;

}  // namespace roomfix::testing

#endif  // ROOMFIX_TESTS_TESTING_WIRE_TEST_MESSAGES_H_
