// roomfix_lcm_samples [LOG...]: messages of every roomfix type as the C++
// side encodes them, one JSON line each, for tests/python/lcm_types_test.py
// to decode with the generated Python types:
//   {"origin": ..., "channel": ..., "type": "roomfix.pose2d_t",
//    "fingerprint": "<16 hex digits of getHash()>", "hex": "<encoded bytes>",
//    "fields": {every field of the message by its .lcm name}}
// First tests/testing/wire_test_messages.h's sample of each type (every array
// non-empty, every string set; the nested types encoded on their own too),
// then every roomfix event of each LOG, decoded with DecodeChecked.
//
// "fields" is written here field by field from the .lcm files, completely
// (no summary, unlike `roomfix listen`'s JSON): the Python test fails when a
// type gains a field this file does not write. The line is nlohmann's
// dump(): doubles in the shortest form that reads back to the same bits
// (-0.0 keeps its sign), NaN and infinities as null.
#include <fmt/format.h>

#include <cmath>
#include <cstdio>
#include <limits>
#include <nlohmann/json.hpp>
#include <string>

#include "msgio/log.h"
#include "msgio/message_json.h"
#include "msgio/wire_check.h"
#include "tests/testing/wire_test_messages.h"

namespace roomfix {
namespace {

using nlohmann::ordered_json;

ordered_json Fields(const counter_t& m) { return {{"name", m.name}, {"count", m.count}}; }

ordered_json Fields(const range_t& m) {
  return {{"receiver_id", m.receiver_id},
          {"receiver_position_m", m.receiver_position_m},
          {"time_of_flight_us", m.time_of_flight_us},
          {"range_m", m.range_m},
          {"arrival_utime", m.arrival_utime}};
}

ordered_json Fields(const marker_t& m) {
  return {{"colour_class", m.colour_class},
          {"robot_id", m.robot_id},
          {"role", m.role},
          {"u_px", m.u_px},
          {"v_px", m.v_px},
          {"radius_px", m.radius_px},
          {"circularity", m.circularity},
          {"area_px", m.area_px}};
}

ordered_json Fields(const detector_view_robot_t& m) {
  return {{"robot_id", m.robot_id}, {"reason", m.reason}, {"colour_class", m.colour_class},
          {"value", m.value},       {"limit", m.limit},   {"text", m.text}};
}

ordered_json Fields(const site_file_t& m) { return {{"name", m.name}, {"text", m.text}}; }

template <class T>
ordered_json List(const std::vector<T>& items) {
  ordered_json out = ordered_json::array();
  for (const T& item : items) out.push_back(Fields(item));
  return out;
}

ordered_json Fields(const pose2d_t& m) {
  ordered_json covariance = ordered_json::array();
  for (const auto& row : m.covariance) covariance.push_back(row);
  return {{"utime", m.utime},
          {"source", m.source},
          {"camera_id", m.camera_id},
          {"robot_id", m.robot_id},
          {"measurement_seq", m.measurement_seq},
          {"x_m", m.x_m},
          {"y_m", m.y_m},
          {"z_m", m.z_m},
          {"heading_rad", m.heading_rad},
          {"covariance", covariance},
          {"residual_m", m.residual_m},
          {"num_measurements", m.num_measurements},
          {"status", m.status},
          {"latency_us", m.latency_us}};
}

ordered_json Fields(const range_set_t& m) {
  return {{"utime", m.utime},
          {"beacon_id", m.beacon_id},
          {"firing_seq", m.firing_seq},
          {"speed_of_sound_mps", m.speed_of_sound_mps},
          {"temperature_c", m.temperature_c},
          {"num_expected", m.num_expected},
          {"num_ranges", m.num_ranges},
          {"ranges", List(m.ranges)}};
}

ordered_json Fields(const marker_pixels_t& m) {
  return {{"utime", m.utime},
          {"camera_id", m.camera_id},
          {"frame_seq", m.frame_seq},
          {"width_px", m.width_px},
          {"height_px", m.height_px},
          {"search_mode", m.search_mode},
          {"processing_time_us", m.processing_time_us},
          {"num_markers", m.num_markers},
          {"markers", List(m.markers)}};
}

ordered_json Fields(const process_status_t& m) {
  return {{"utime", m.utime},
          {"process", m.process},
          {"host", m.host},
          {"pid", m.pid},
          {"uptime_us", m.uptime_us},
          {"state", m.state},
          {"inputs", m.inputs},
          {"outputs", m.outputs},
          {"dropped", m.dropped},
          {"num_rejected", m.num_rejected},
          {"rejected", List(m.rejected)},
          {"num_counters", m.num_counters},
          {"counters", List(m.counters)},
          {"last_error", m.last_error},
          {"last_error_utime", m.last_error_utime}};
}

ordered_json Fields(const image_t& m) {
  return {{"utime", m.utime},
          {"camera_id", m.camera_id},
          {"frame_seq", m.frame_seq},
          {"width_px", m.width_px},
          {"height_px", m.height_px},
          {"source_width_px", m.source_width_px},
          {"source_height_px", m.source_height_px},
          {"format", m.format},
          {"num_bytes", m.num_bytes},
          {"data", m.data}};
}

ordered_json Fields(const detector_view_t& m) {
  return {{"utime", m.utime},
          {"camera_id", m.camera_id},
          {"frame_seq", m.frame_seq},
          {"width_px", m.width_px},
          {"height_px", m.height_px},
          {"source_width_px", m.source_width_px},
          {"source_height_px", m.source_height_px},
          {"region_u_px", m.region_u_px},
          {"region_v_px", m.region_v_px},
          {"region_width_px", m.region_width_px},
          {"region_height_px", m.region_height_px},
          {"scale", m.scale},
          {"format", m.format},
          {"num_bytes", m.num_bytes},
          {"data", m.data},
          {"num_robots", m.num_robots},
          {"robots", List(m.robots)}};
}

ordered_json Fields(const detector_view_request_t& m) {
  return {{"utime", m.utime},
          {"camera_id", m.camera_id},
          {"region_u_px", m.region_u_px},
          {"region_v_px", m.region_v_px},
          {"region_width_px", m.region_width_px},
          {"region_height_px", m.region_height_px},
          {"rate_hz", m.rate_hz},
          {"duration_s", m.duration_s}};
}

ordered_json Fields(const site_t& m) {
  return {{"utime", m.utime},
          {"site_name", m.site_name},
          {"site_path", m.site_path},
          {"site_text", m.site_text},
          {"num_files", m.num_files},
          {"files", List(m.files)},
          {"missing", m.missing},
          {"content_hash", m.content_hash},
          {"roomfix_version", m.roomfix_version},
          {"process", m.process},
          {"host", m.host},
          {"pid", m.pid}};
}

std::string Hex(const void* data, size_t size) {
  static const char kDigits[] = "0123456789abcdef";
  std::string out;
  const auto* b = static_cast<const uint8_t*>(data);
  for (size_t i = 0; i < size; ++i) {
    out += kDigits[b[i] >> 4];
    out += kDigits[b[i] & 15];
  }
  return out;
}

// The fingerprint as LCM writes it first in every message: 8 bytes,
// big-endian, here as 16 hex digits.
std::string FingerprintHex(uint64_t hash) { return fmt::format("{:016x}", hash); }

template <class Msg>
void Print(const std::string& origin, const std::string& channel, const Msg& msg, const void* bytes,
           size_t size) {
  const auto hash = static_cast<uint64_t>(Msg::getHash());
  const ordered_json line = {{"origin", origin},
                             {"channel", channel},
                             {"type", std::string("roomfix.") + Msg::getTypeName()},
                             {"fingerprint", FingerprintHex(hash)},
                             {"hex", Hex(bytes, size)},
                             {"fields", Fields(msg)}};
  std::printf("%s\n", line.dump(-1, ' ', false, ordered_json::error_handler_t::replace).c_str());
}

template <class Msg>
void PrintSample(const std::string& name, const Msg& msg) {
  const std::vector<uint8_t> bytes = testing::Encode(msg);
  Print("sample:" + name, "", msg, bytes.data(), bytes.size());
}

void PrintSamples() {
  const process_status_t status = testing::MakeTestStatus();
  PrintSample("process_status_t", status);
  PrintSample("counter_t", status.rejected[0]);
  process_status_t other = status;
  other.host = "labor-r\xc3\xa4um";  // UTF-8 beyond ASCII
  other.last_error = "";
  other.rejected.clear();
  other.num_rejected = 0;
  PrintSample("process_status_t_utf8_no_rejected", other);
  const range_set_t ranges = testing::MakeTestRangeSet(4);
  PrintSample("range_set_t", ranges);
  PrintSample("range_t", ranges.ranges[2]);
  PrintSample("range_set_t_empty", testing::MakeTestRangeSet(0));
  const marker_pixels_t pixels = testing::MakeTestMarkerPixels();
  PrintSample("marker_pixels_t", pixels);
  PrintSample("marker_t", pixels.markers[1]);
  PrintSample("image_t", testing::MakeTestImage());
  const detector_view_t view = testing::MakeTestDetectorView();
  PrintSample("detector_view_t", view);
  PrintSample("detector_view_robot_t", view.robots[1]);
  PrintSample("detector_view_request_t", testing::MakeTestDetectorViewRequest());
  const site_t site = testing::MakeTestSite();
  PrintSample("site_t", site);
  PrintSample("site_file_t", site.files[0]);
  // An ultrasound pose (heading NaN) and a camera pose at the extremes of
  // its integers and with doubles that print awkwardly.
  PrintSample("pose2d_t", testing::MakeTestPose(1700000000000001, 3, 0.1, 1.0 / 3.0));
  pose2d_t pose = testing::MakeTestPose(std::numeric_limits<int64_t>::max(), -7, -0.0, 1e300);
  pose.source = pose2d_t::SOURCE_CAMERA;
  pose.camera_id = std::numeric_limits<int32_t>::min();
  pose.measurement_seq = std::numeric_limits<int64_t>::min();
  pose.heading_rad = -3.141592653589793;
  for (int k = 0; k < 9; ++k) pose.covariance[k / 3][k % 3] = std::ldexp(1.0 + k / 9.0, -40 + k);
  pose.status = pose2d_t::STATUS_DEGRADED;
  PrintSample("pose2d_t_extremes", pose);
}

// Every roomfix event of a log; false when it cannot be opened.
bool PrintLog(const std::string& path) {
  std::string error;
  auto reader = LogReader::Open(path, &error);
  if (reader == nullptr) {
    std::fprintf(stderr, "roomfix_lcm_samples: %s\n", error.c_str());
    return false;
  }
  LogEvent e;
  while (reader->Next(&e)) {
    const std::string origin = "log:" + path + "#" + std::to_string(e.eventnum);
    const void* data = e.data.data();
    const int size = static_cast<int>(e.data.size());
    const char* type = RoomfixTypeName(data, size);
    const int64_t fp = type != nullptr ? RoomfixTypeFingerprint(type) : 0;
    auto print = [&](auto msg) {
      if (DecodeChecked(data, size, &msg, nullptr))
        Print(origin, e.channel, msg, data, e.data.size());
    };
    if (fp == pose2d_t::getHash()) print(pose2d_t{});
    if (fp == range_set_t::getHash()) print(range_set_t{});
    if (fp == marker_pixels_t::getHash()) print(marker_pixels_t{});
    if (fp == process_status_t::getHash()) print(process_status_t{});
    if (fp == image_t::getHash()) print(image_t{});
    if (fp == site_t::getHash()) print(site_t{});
    if (fp == detector_view_t::getHash()) print(detector_view_t{});
    if (fp == detector_view_request_t::getHash()) print(detector_view_request_t{});
  }
  return true;
}

}  // namespace
}  // namespace roomfix

int main(int argc, char** argv) {
  roomfix::PrintSamples();
  for (int i = 1; i < argc; ++i) {
    if (!roomfix::PrintLog(argv[i])) return 1;
  }
  return 0;
}
