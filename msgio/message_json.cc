#include "msgio/message_json.h"

#include <nlohmann/json.hpp>

#include "msgio/wire_check.h"
#include "roomfix/detector_view_request_t.hpp"
#include "roomfix/detector_view_t.hpp"
#include "roomfix/image_t.hpp"
#include "roomfix/marker_pixels_t.hpp"
#include "roomfix/pose2d_t.hpp"
#include "roomfix/process_status_t.hpp"
#include "roomfix/range_set_t.hpp"
#include "roomfix/site_t.hpp"

namespace roomfix {
namespace {

using nlohmann::ordered_json;

int64_t FingerprintOf(const void* data, int size) {
  if (size < 8) return 0;
  const auto* b = static_cast<const uint8_t*>(data);
  uint64_t v = 0;
  for (int i = 0; i < 8; ++i) v = (v << 8) | b[i];
  return static_cast<int64_t>(v);
}

// A counter list as one object, name: count. Two counters of one name (a
// malformed status) keep the first's place and the last's count, as any
// JSON reader would have read the repeated key.
ordered_json Counters(const std::vector<counter_t>& counters) {
  ordered_json out = ordered_json::object();
  for (const auto& c : counters) out[c.name] = c.count;
  return out;
}

ordered_json ToJson(const pose2d_t& m) {
  ordered_json covariance = ordered_json::array();
  for (const auto& row : m.covariance) {
    for (double v : row) covariance.push_back(v);
  }
  return {{"type", "roomfix.pose2d_t"},
          {"utime", m.utime},
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

ordered_json ToJson(const marker_pixels_t& m) {
  ordered_json markers = ordered_json::array();
  for (const auto& k : m.markers) {
    markers.push_back({{"colour_class", k.colour_class},
                       {"robot_id", k.robot_id},
                       {"role", k.role},
                       {"u_px", k.u_px},
                       {"v_px", k.v_px},
                       {"radius_px", k.radius_px},
                       {"circularity", k.circularity},
                       {"area_px", k.area_px}});
  }
  return {{"type", "roomfix.marker_pixels_t"},
          {"utime", m.utime},
          {"camera_id", m.camera_id},
          {"frame_seq", m.frame_seq},
          {"width_px", m.width_px},
          {"height_px", m.height_px},
          {"search_mode", m.search_mode},
          {"processing_time_us", m.processing_time_us},
          {"markers", markers}};
}

ordered_json ToJson(const range_set_t& m) {
  ordered_json ranges = ordered_json::array();
  for (const auto& r : m.ranges) {
    ranges.push_back({{"receiver_id", r.receiver_id},
                      {"receiver_position_m", r.receiver_position_m},
                      {"time_of_flight_us", r.time_of_flight_us},
                      {"range_m", r.range_m},
                      {"arrival_utime", r.arrival_utime}});
  }
  return {{"type", "roomfix.range_set_t"},
          {"utime", m.utime},
          {"beacon_id", m.beacon_id},
          {"firing_seq", m.firing_seq},
          {"speed_of_sound_mps", m.speed_of_sound_mps},
          {"temperature_c", m.temperature_c},
          {"num_expected", m.num_expected},
          {"ranges", ranges}};
}

ordered_json ToJson(const process_status_t& m) {
  return {{"type", "roomfix.process_status_t"},
          {"utime", m.utime},
          {"process", m.process},
          {"host", m.host},
          {"pid", m.pid},
          {"uptime_us", m.uptime_us},
          {"state", m.state},
          {"inputs", m.inputs},
          {"outputs", m.outputs},
          {"dropped", m.dropped},
          {"rejected", Counters(m.rejected)},
          {"counters", Counters(m.counters)},
          {"last_error", m.last_error},
          {"last_error_utime", m.last_error_utime}};
}

// The image bytes are summarised, not dumped: a preview is tens of KB.
ordered_json ToJson(const image_t& m) {
  return {{"type", "roomfix.image_t"},
          {"utime", m.utime},
          {"camera_id", m.camera_id},
          {"frame_seq", m.frame_seq},
          {"width_px", m.width_px},
          {"height_px", m.height_px},
          {"source_width_px", m.source_width_px},
          {"source_height_px", m.source_height_px},
          {"format", m.format},
          {"num_bytes", m.num_bytes}};
}

// The image is summarised like a preview's; the robots' lines are whole.
ordered_json ToJson(const detector_view_t& m) {
  ordered_json robots = ordered_json::array();
  for (const detector_view_robot_t& r : m.robots) {
    robots.push_back({{"robot_id", r.robot_id},
                      {"reason", r.reason},
                      {"colour_class", r.colour_class},
                      {"value", r.value},
                      {"limit", r.limit},
                      {"text", r.text}});
  }
  return {{"type", "roomfix.detector_view_t"},
          {"utime", m.utime},
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
          {"robots", robots}};
}

ordered_json ToJson(const detector_view_request_t& m) {
  return {{"type", "roomfix.detector_view_request_t"},
          {"utime", m.utime},
          {"camera_id", m.camera_id},
          {"region_u_px", m.region_u_px},
          {"region_v_px", m.region_v_px},
          {"region_width_px", m.region_width_px},
          {"region_height_px", m.region_height_px},
          {"rate_hz", m.rate_hz},
          {"duration_s", m.duration_s}};
}

// The texts are summarised by size: the site and its files are kilobytes,
// and `content_hash` names them exactly.
ordered_json ToJson(const site_t& m) {
  ordered_json files = ordered_json::array();
  for (const auto& f : m.files) files.push_back({{"name", f.name}, {"bytes", f.text.size()}});
  return {{"type", "roomfix.site_t"},
          {"utime", m.utime},
          {"site_name", m.site_name},
          {"site_path", m.site_path},
          {"site_text_bytes", m.site_text.size()},
          {"files", files},
          {"missing", m.missing},
          {"content_hash", m.content_hash},
          {"roomfix_version", m.roomfix_version},
          {"process", m.process},
          {"host", m.host},
          {"pid", m.pid}};
}

template <class Msg>
bool Decode(const void* data, int size, ordered_json* json, std::string* error,
            std::string* reason) {
  Msg m{};
  std::string detail;
  if (!DecodeChecked(data, size, &m, reason, &detail)) {
    if (error != nullptr) *error = "refused: " + detail;
    return false;
  }
  *json = ToJson(m);
  return true;
}

}  // namespace

const char* RoomfixTypeName(const void* data, int size) {
  const int64_t fp = FingerprintOf(data, size);
  if (fp == 0) return nullptr;
  if (fp == pose2d_t::getHash()) return "roomfix.pose2d_t";
  if (fp == marker_pixels_t::getHash()) return "roomfix.marker_pixels_t";
  if (fp == range_set_t::getHash()) return "roomfix.range_set_t";
  if (fp == process_status_t::getHash()) return "roomfix.process_status_t";
  if (fp == image_t::getHash()) return "roomfix.image_t";
  if (fp == site_t::getHash()) return "roomfix.site_t";
  if (fp == detector_view_t::getHash()) return "roomfix.detector_view_t";
  if (fp == detector_view_request_t::getHash()) return "roomfix.detector_view_request_t";
  return nullptr;
}

int64_t RoomfixTypeFingerprint(const std::string& type_name) {
  if (type_name == "roomfix.pose2d_t") return pose2d_t::getHash();
  if (type_name == "roomfix.marker_pixels_t") return marker_pixels_t::getHash();
  if (type_name == "roomfix.range_set_t") return range_set_t::getHash();
  if (type_name == "roomfix.process_status_t") return process_status_t::getHash();
  if (type_name == "roomfix.image_t") return image_t::getHash();
  if (type_name == "roomfix.site_t") return site_t::getHash();
  if (type_name == "roomfix.detector_view_t") return detector_view_t::getHash();
  if (type_name == "roomfix.detector_view_request_t") return detector_view_request_t::getHash();
  return 0;
}

bool MessageToJson(const void* data, int size, std::string* json, std::string* error,
                   std::string* reason) {
  ordered_json value;
  if (!MessageToJsonValue(data, size, &value, error, reason)) return false;
  *json = value.dump(-1, ' ', false, ordered_json::error_handler_t::replace);
  return true;
}

bool MessageToJsonValue(const void* data, int size, nlohmann::ordered_json* json,
                        std::string* error, std::string* reason) {
  const int64_t fp = FingerprintOf(data, size);
  if (fp == pose2d_t::getHash()) return Decode<pose2d_t>(data, size, json, error, reason);
  if (fp == marker_pixels_t::getHash()) {
    return Decode<marker_pixels_t>(data, size, json, error, reason);
  }
  if (fp == range_set_t::getHash()) return Decode<range_set_t>(data, size, json, error, reason);
  if (fp == process_status_t::getHash()) {
    return Decode<process_status_t>(data, size, json, error, reason);
  }
  if (fp == image_t::getHash()) return Decode<image_t>(data, size, json, error, reason);
  if (fp == site_t::getHash()) return Decode<site_t>(data, size, json, error, reason);
  if (fp == detector_view_t::getHash()) {
    return Decode<detector_view_t>(data, size, json, error, reason);
  }
  if (fp == detector_view_request_t::getHash()) {
    return Decode<detector_view_request_t>(data, size, json, error, reason);
  }
  if (error != nullptr) *error = "not a roomfix message (unknown fingerprint)";
  if (reason != nullptr) *reason = kUnknownTypeReason;
  return false;
}

}  // namespace roomfix
