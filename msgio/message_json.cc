#include "msgio/message_json.h"

#include <cmath>
#include <cstring>
#include <sstream>

#include "msgio/wire_check.h"
#include "roomfix/image_t.hpp"
#include "roomfix/marker_pixels_t.hpp"
#include "roomfix/pose2d_t.hpp"
#include "roomfix/process_status_t.hpp"
#include "roomfix/range_set_t.hpp"
#include "roomfix/site_t.hpp"

namespace roomfix {
namespace {

// A minimal JSON writer: enough for flat objects, arrays and numbers.
class Json {
 public:
  Json& Key(const char* key) {
    Comma();
    String(key);
    out_ << ':';
    fresh_ = true;
    return *this;
  }
  Json& Num(double v) {
    Comma();
    if (std::isfinite(v)) {
      out_.precision(17);
      out_ << v;
    } else {
      out_ << "null";
    }
    return *this;
  }
  Json& Int(int64_t v) {
    Comma();
    out_ << v;
    return *this;
  }
  Json& Str(const std::string& v) {
    Comma();
    String(v);
    return *this;
  }
  Json& Open(char c) {
    Comma();
    out_ << c;
    fresh_ = true;
    return *this;
  }
  Json& Close(char c) {
    out_ << c;
    fresh_ = false;
    return *this;
  }
  std::string str() const { return out_.str(); }

 private:
  void Comma() {
    if (!fresh_) out_ << ',';
    fresh_ = false;
  }
  void String(const std::string& v) {
    out_ << '"';
    for (unsigned char c : v) {
      if (c == '"' || c == '\\') {
        out_ << '\\' << c;
      } else if (c < 0x20) {
        char buffer[8];
        std::snprintf(buffer, sizeof(buffer), "\\u%04x", c);
        out_ << buffer;
      } else {
        out_ << c;
      }
    }
    out_ << '"';
  }
  std::ostringstream out_;
  bool fresh_ = true;
};

int64_t FingerprintOf(const void* data, int size) {
  if (size < 8) return 0;
  const auto* b = static_cast<const uint8_t*>(data);
  uint64_t v = 0;
  for (int i = 0; i < 8; ++i) v = (v << 8) | b[i];
  return static_cast<int64_t>(v);
}

void Counters(Json* j, const char* key, const std::vector<counter_t>& counters) {
  j->Key(key).Open('{');
  for (const auto& c : counters) j->Key(c.name.c_str()).Int(c.count);
  j->Close('}');
}

std::string ToJson(const pose2d_t& m) {
  Json j;
  j.Open('{').Key("type").Str("roomfix.pose2d_t").Key("utime").Int(m.utime);
  j.Key("source").Int(m.source).Key("camera_id").Int(m.camera_id);
  j.Key("robot_id").Int(m.robot_id).Key("measurement_seq").Int(m.measurement_seq);
  j.Key("x_m").Num(m.x_m).Key("y_m").Num(m.y_m).Key("z_m").Num(m.z_m);
  j.Key("heading_rad").Num(m.heading_rad).Key("covariance").Open('[');
  for (const auto& row : m.covariance) {
    for (double v : row) j.Num(v);
  }
  j.Close(']').Key("residual_m").Num(m.residual_m);
  j.Key("num_measurements").Int(m.num_measurements).Key("status").Int(m.status);
  j.Key("latency_us").Int(m.latency_us).Close('}');
  return j.str();
}

std::string ToJson(const marker_pixels_t& m) {
  Json j;
  j.Open('{').Key("type").Str("roomfix.marker_pixels_t").Key("utime").Int(m.utime);
  j.Key("camera_id").Int(m.camera_id).Key("frame_seq").Int(m.frame_seq);
  j.Key("width_px").Int(m.width_px).Key("height_px").Int(m.height_px);
  j.Key("search_mode").Int(m.search_mode).Key("processing_time_us").Int(m.processing_time_us);
  j.Key("markers").Open('[');
  for (const auto& k : m.markers) {
    j.Open('{').Key("colour_class").Str(k.colour_class).Key("robot_id").Int(k.robot_id);
    j.Key("role").Int(k.role).Key("u_px").Num(k.u_px).Key("v_px").Num(k.v_px);
    j.Key("radius_px").Num(k.radius_px).Key("circularity").Num(k.circularity);
    j.Key("area_px").Num(k.area_px).Close('}');
  }
  j.Close(']').Close('}');
  return j.str();
}

std::string ToJson(const range_set_t& m) {
  Json j;
  j.Open('{').Key("type").Str("roomfix.range_set_t").Key("utime").Int(m.utime);
  j.Key("beacon_id").Int(m.beacon_id).Key("firing_seq").Int(m.firing_seq);
  j.Key("speed_of_sound_mps").Num(m.speed_of_sound_mps).Key("temperature_c").Num(m.temperature_c);
  j.Key("num_expected").Int(m.num_expected).Key("ranges").Open('[');
  for (const auto& r : m.ranges) {
    j.Open('{').Key("receiver_id").Int(r.receiver_id).Key("receiver_position_m").Open('[');
    for (double v : r.receiver_position_m) j.Num(v);
    j.Close(']').Key("time_of_flight_us").Num(r.time_of_flight_us);
    j.Key("range_m").Num(r.range_m).Key("arrival_utime").Int(r.arrival_utime).Close('}');
  }
  j.Close(']').Close('}');
  return j.str();
}

std::string ToJson(const process_status_t& m) {
  Json j;
  j.Open('{').Key("type").Str("roomfix.process_status_t").Key("utime").Int(m.utime);
  j.Key("process").Str(m.process).Key("host").Str(m.host).Key("pid").Int(m.pid);
  j.Key("uptime_us").Int(m.uptime_us).Key("state").Int(m.state);
  j.Key("inputs").Int(m.inputs).Key("outputs").Int(m.outputs).Key("dropped").Int(m.dropped);
  Counters(&j, "rejected", m.rejected);
  Counters(&j, "counters", m.counters);
  j.Key("last_error").Str(m.last_error).Key("last_error_utime").Int(m.last_error_utime);
  j.Close('}');
  return j.str();
}

// The image bytes are summarised, not dumped: a preview is tens of KB.
std::string ToJson(const image_t& m) {
  Json j;
  j.Open('{').Key("type").Str("roomfix.image_t").Key("utime").Int(m.utime);
  j.Key("camera_id").Int(m.camera_id).Key("frame_seq").Int(m.frame_seq);
  j.Key("width_px").Int(m.width_px).Key("height_px").Int(m.height_px);
  j.Key("source_width_px").Int(m.source_width_px).Key("source_height_px").Int(m.source_height_px);
  j.Key("format").Str(m.format).Key("num_bytes").Int(m.num_bytes).Close('}');
  return j.str();
}

// The texts are summarised by size: the site and its files are kilobytes,
// and `content_hash` names them exactly.
std::string ToJson(const site_t& m) {
  Json j;
  j.Open('{').Key("type").Str("roomfix.site_t").Key("utime").Int(m.utime);
  j.Key("site_name").Str(m.site_name).Key("site_path").Str(m.site_path);
  j.Key("site_text_bytes").Int(static_cast<int64_t>(m.site_text.size())).Key("files").Open('[');
  for (const auto& f : m.files) {
    j.Open('{').Key("name").Str(f.name).Key("bytes").Int(static_cast<int64_t>(f.text.size()));
    j.Close('}');
  }
  j.Close(']').Key("missing").Str(m.missing).Key("content_hash").Str(m.content_hash);
  j.Key("roomfix_version").Str(m.roomfix_version).Key("process").Str(m.process);
  j.Key("host").Str(m.host).Key("pid").Int(m.pid).Close('}');
  return j.str();
}

template <class Msg>
bool Decode(const void* data, int size, std::string* json, std::string* error,
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
  return nullptr;
}

int64_t RoomfixTypeFingerprint(const std::string& type_name) {
  if (type_name == "roomfix.pose2d_t") return pose2d_t::getHash();
  if (type_name == "roomfix.marker_pixels_t") return marker_pixels_t::getHash();
  if (type_name == "roomfix.range_set_t") return range_set_t::getHash();
  if (type_name == "roomfix.process_status_t") return process_status_t::getHash();
  if (type_name == "roomfix.image_t") return image_t::getHash();
  if (type_name == "roomfix.site_t") return site_t::getHash();
  return 0;
}

bool MessageToJson(const void* data, int size, std::string* json, std::string* error,
                   std::string* reason) {
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
  if (error != nullptr) *error = "not a roomfix message (unknown fingerprint)";
  if (reason != nullptr) *reason = kUnknownTypeReason;
  return false;
}

}  // namespace roomfix
