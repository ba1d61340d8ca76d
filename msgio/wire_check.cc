#include "msgio/wire_check.h"

#include <cstring>
#include <string>

#include "core/world/site.h"
#include "roomfix/detector_view_robot_t.hpp"
#include "roomfix/marker_pixels_t.hpp"
#include "roomfix/marker_t.hpp"
#include "roomfix/pose2d_t.hpp"
#include "roomfix/process_status_t.hpp"

namespace roomfix {

// The site refuses marker class names that every receiver would refuse.
static_assert(kMaxMarkerClassNameBytes + 1 == static_cast<size_t>(wire_cap::kColourClassBytes));
namespace wire {
namespace {

// The field tables, in .lcm order. LCM encodes big-endian with no padding:
// int8 and byte 1, int32 4, int64 and double 8 bytes; a fixed-size array is
// its elements back to back; a nested struct is its fields with no
// fingerprint. wire_check_test.cc checks each table against the generated
// encoder (the checked size of real messages equals getEncodedSize()). An
// enum's constants run from 0 without gaps in every .lcm file, so its largest
// constant bounds it; wire_check_test.cc reads lcmtypes/*.lcm and checks that
// every int8 with constants is a kEnum here with that bound.
constexpr FieldKind kFixed = FieldKind::kFixed;
constexpr FieldKind kString = FieldKind::kString;
constexpr FieldKind kCount = FieldKind::kCount;
constexpr FieldKind kStructArray = FieldKind::kStructArray;
constexpr FieldKind kByteArray = FieldKind::kByteArray;
constexpr FieldKind kEnum = FieldKind::kEnum;

constexpr Field kCounterFields[] = {
    {"name", kString, wire_cap::kNameBytes, nullptr},
    {"count", kFixed, 8, nullptr},
};
constexpr Layout kCounter{"counter_t", kCounterFields, 2};

constexpr Field kMarkerFields[] = {
    {"colour_class", kString, wire_cap::kColourClassBytes, nullptr},
    {"robot_id", kFixed, 4, nullptr},
    {"role", kEnum, marker_t::ROLE_HEADING, nullptr},
    // u_px, v_px, radius_px, circularity, area_px
    {"u_px..area_px", kFixed, 5 * 8, nullptr},
};
constexpr Layout kMarker{"marker_t", kMarkerFields, 4};

constexpr Field kRangeFields[] = {
    {"receiver_id", kFixed, 4, nullptr},
    {"receiver_position_m", kFixed, 3 * 8, nullptr},
    // time_of_flight_us, range_m, arrival_utime
    {"time_of_flight_us..arrival_utime", kFixed, 3 * 8, nullptr},
};
constexpr Layout kRange{"range_t", kRangeFields, 3};

constexpr Field kPoseFields[] = {
    {"utime", kFixed, 8, nullptr},
    {"source", kEnum, pose2d_t::SOURCE_GROUND_TRUTH, nullptr},
    // camera_id 4, robot_id 4, measurement_seq 8, x_m y_m z_m heading_rad
    // 4*8, covariance 9*8, residual_m 8, num_measurements 4.
    {"camera_id..num_measurements", kFixed, 4 + 4 + 8 + 4 * 8 + 9 * 8 + 8 + 4, nullptr},
    {"status", kEnum, pose2d_t::STATUS_LOST, nullptr},
    {"latency_us", kFixed, 8, nullptr},
};
constexpr Layout kPose{"pose2d_t", kPoseFields, 5};

constexpr Field kRangeSetFields[] = {
    // utime 8, beacon_id 4, firing_seq 8, speed_of_sound_mps 8,
    // temperature_c 8, num_expected 4
    {"utime..num_expected", kFixed, 8 + 4 + 8 + 8 + 8 + 4, nullptr},
    {"num_ranges", kCount, wire_cap::kRangesPerSet, nullptr},
    {"ranges", kStructArray, 0, &kRange},
};
constexpr Layout kRangeSet{"range_set_t", kRangeSetFields, 3};

constexpr Field kMarkerPixelsFields[] = {
    // utime 8, camera_id 4, frame_seq 8, width_px 4, height_px 4
    {"utime..height_px", kFixed, 8 + 4 + 8 + 4 + 4, nullptr},
    {"search_mode", kEnum, marker_pixels_t::SEARCH_REGION_OF_INTEREST, nullptr},
    {"processing_time_us", kFixed, 4, nullptr},
    {"num_markers", kCount, wire_cap::kMarkersPerFrame, nullptr},
    {"markers", kStructArray, 0, &kMarker},
};
constexpr Layout kMarkerPixels{"marker_pixels_t", kMarkerPixelsFields, 5};

constexpr Field kImageFields[] = {
    // utime 8, camera_id 4, frame_seq 8, width_px, height_px,
    // source_width_px, source_height_px 4 each
    {"utime..source_height_px", kFixed, 8 + 4 + 8 + 4 * 4, nullptr},
    {"format", kString, wire_cap::kImageFormatBytes, nullptr},
    {"num_bytes", kCount, wire_cap::kPreviewBytes, nullptr},
    {"data", kByteArray, 0, nullptr},
};
constexpr Layout kImage{"image_t", kImageFields, 4};

constexpr Field kDetectorViewRobotFields[] = {
    {"robot_id", kFixed, 4, nullptr},
    {"reason", kEnum, detector_view_robot_t::REASON_NO_BLOB, nullptr},
    {"colour_class", kString, wire_cap::kColourClassBytes, nullptr},
    {"value..limit", kFixed, 2 * 8, nullptr},
    {"text", kString, wire_cap::kDetectorViewTextBytes, nullptr},
};
constexpr Layout kDetectorViewRobot{"detector_view_robot_t", kDetectorViewRobotFields, 5};

constexpr Field kDetectorViewFields[] = {
    // utime 8, camera_id 4, frame_seq 8, then 9 int32: width_px,
    // height_px, source_width_px, source_height_px, the region's four and
    // scale
    {"utime..scale", kFixed, 8 + 4 + 8 + 9 * 4, nullptr},
    {"format", kString, wire_cap::kImageFormatBytes, nullptr},
    {"num_bytes", kCount, wire_cap::kDetectorViewBytes, nullptr},
    {"data", kByteArray, 0, nullptr},
    {"num_robots", kCount, wire_cap::kDetectorViewRobots, nullptr},
    {"robots", kStructArray, 0, &kDetectorViewRobot},
};
constexpr Layout kDetectorView{"detector_view_t", kDetectorViewFields, 6};

constexpr Field kDetectorViewRequestFields[] = {
    // utime 8, camera_id 4, the region's four int32, rate_hz 8, duration_s 8
    {"utime..duration_s", kFixed, 8 + 4 + 4 * 4 + 8 + 8, nullptr},
};
constexpr Layout kDetectorViewRequest{"detector_view_request_t", kDetectorViewRequestFields, 1};

constexpr Field kProcessStatusFields[] = {
    {"utime", kFixed, 8, nullptr},
    {"process", kString, wire_cap::kNameBytes, nullptr},
    {"host", kString, wire_cap::kNameBytes, nullptr},
    {"pid..uptime_us", kFixed, 4 + 8, nullptr},
    {"state", kEnum, process_status_t::STATE_FAILED, nullptr},
    {"inputs..dropped", kFixed, 3 * 8, nullptr},
    {"num_rejected", kCount, wire_cap::kStatusCounters, nullptr},
    {"rejected", kStructArray, 0, &kCounter},
    {"num_counters", kCount, wire_cap::kStatusCounters, nullptr},
    {"counters", kStructArray, 0, &kCounter},
    {"last_error", kString, wire_cap::kLastErrorBytes, nullptr},
    {"last_error_utime", kFixed, 8, nullptr},
};
constexpr Layout kProcessStatus{"process_status_t", kProcessStatusFields, 12};

constexpr Field kSiteFileFields[] = {
    {"name", kString, wire_cap::kPathBytes, nullptr},
    {"text", kString, wire_cap::kSiteFileBytes, nullptr},
};
constexpr Layout kSiteFile{"site_file_t", kSiteFileFields, 2};

constexpr Field kSiteFields[] = {
    {"utime", kFixed, 8, nullptr},
    {"site_name", kString, wire_cap::kNameBytes, nullptr},
    {"site_path", kString, wire_cap::kPathBytes, nullptr},
    {"site_text", kString, wire_cap::kSiteTextBytes, nullptr},
    {"num_files", kCount, wire_cap::kSiteFiles, nullptr},
    {"files", kStructArray, 0, &kSiteFile},
    {"missing", kString, wire_cap::kPathBytes, nullptr},
    {"content_hash", kString, wire_cap::kHashBytes, nullptr},
    {"roomfix_version", kString, wire_cap::kVersionBytes, nullptr},
    {"process", kString, wire_cap::kNameBytes, nullptr},
    {"host", kString, wire_cap::kNameBytes, nullptr},
    {"pid", kFixed, 4, nullptr},
};
constexpr Layout kSite{"site_t", kSiteFields, 12};

// The fewest bytes one element can take: what a count must be paid for with
// before anything is walked, so a huge count fails in constant time.
int64_t MinEncodedSize(const Layout& layout) {
  int64_t n = 0;
  for (int i = 0; i < layout.num_fields; ++i) {
    const Field& f = layout.fields[i];
    if (f.kind == kFixed) n += f.limit;
    if (f.kind == kEnum) n += 1;
    if (f.kind == kString) n += 4 + 1;
    if (f.kind == kCount) n += 4;
  }
  return n;
}

class Walker {
 public:
  // Walks data[start, size).
  Walker(const uint8_t* data, int start, int size, std::string* detail)
      : data_(data), size_(size), pos_(start), detail_(detail) {}

  int pos() const { return pos_; }
  int left() const { return size_ - pos_; }

  // Reads a big-endian int32 (LCM's length and count fields).
  bool ReadInt32(int32_t* value) {
    if (left() < 4) return false;
    const uint8_t* p = data_ + pos_;
    *value =
        static_cast<int32_t>(static_cast<uint32_t>(p[0]) << 24 | static_cast<uint32_t>(p[1]) << 16 |
                             static_cast<uint32_t>(p[2]) << 8 | static_cast<uint32_t>(p[3]));
    pos_ += 4;
    return true;
  }

  const char* Fail(const char* reason, const Layout& layout, const Field& field,
                   const std::string& what) {
    if (detail_ != nullptr) {
      *detail_ = std::string(layout.type_name) + "." + field.name + " " + what + " at byte " +
                 std::to_string(pos_) + " of " + std::to_string(size_);
    }
    return reason;
  }

  const char* Walk(const Layout& layout) {
    int32_t count = 0;
    for (int i = 0; i < layout.num_fields; ++i) {
      const Field& f = layout.fields[i];
      switch (f.kind) {
        case kFixed:
          if (left() < f.limit) {
            return Fail(wire_refusal::kTruncated, layout, f,
                        "needs " + std::to_string(f.limit) + " bytes");
          }
          pos_ += f.limit;
          break;
        case kEnum: {
          if (left() < 1) return Fail(wire_refusal::kTruncated, layout, f, "needs 1 byte");
          const auto value = static_cast<int8_t>(data_[pos_]);
          if (value < 0 || value > f.limit) {
            return Fail(wire_refusal::kEnumOutOfRange, layout, f,
                        std::to_string(value) + " outside 0.." + std::to_string(f.limit));
          }
          ++pos_;
          break;
        }
        case kString: {
          int32_t length = 0;
          if (!ReadInt32(&length)) {
            return Fail(wire_refusal::kTruncated, layout, f, "length missing");
          }
          const auto length_text = [length] { return "length " + std::to_string(length); };
          if (length < 0) return Fail(wire_refusal::kNegativeLength, layout, f, length_text());
          if (length > f.limit) {
            return Fail(wire_refusal::kStringOverCap, layout, f,
                        length_text() + " over cap " + std::to_string(f.limit));
          }
          if (length > left()) {
            return Fail(wire_refusal::kTruncated, layout, f, length_text() + " runs past the end");
          }
          // LCM writes strlen + 1 bytes: the NUL is last and only last. A
          // length of 0 would make the decoder assign SIZE_MAX characters.
          const uint8_t* s = data_ + pos_;
          if (length == 0 || s[length - 1] != 0 || std::memchr(s, 0, length - 1) != nullptr) {
            return Fail(wire_refusal::kBadString, layout, f,
                        length_text() + ": not one NUL-terminated string");
          }
          pos_ += length;
          break;
        }
        case kCount: {
          if (!ReadInt32(&count)) return Fail(wire_refusal::kTruncated, layout, f, "missing");
          if (count < 0) {
            return Fail(wire_refusal::kNegativeLength, layout, f, std::to_string(count));
          }
          if (count > f.limit) {
            return Fail(wire_refusal::kCountOverCap, layout, f,
                        std::to_string(count) + " over cap " + std::to_string(f.limit));
          }
          break;
        }
        case kByteArray:
          if (count > left()) {
            return Fail(wire_refusal::kTruncated, layout, f,
                        std::to_string(count) + " bytes run past the end");
          }
          pos_ += count;
          break;
        case kStructArray: {
          if (static_cast<int64_t>(count) * MinEncodedSize(*f.element) > left()) {
            return Fail(wire_refusal::kTruncated, layout, f,
                        std::to_string(count) + " elements cannot fit in " +
                            std::to_string(left()) + " bytes");
          }
          for (int32_t k = 0; k < count; ++k) {
            if (const char* refusal = Walk(*f.element)) return refusal;
          }
          break;
        }
      }
    }
    return nullptr;
  }

 private:
  const uint8_t* data_;
  int size_;
  int pos_;
  std::string* detail_;
};

}  // namespace

const Layout& LayoutOf(const counter_t*) { return kCounter; }
const Layout& LayoutOf(const image_t*) { return kImage; }
const Layout& LayoutOf(const detector_view_t*) { return kDetectorView; }
const Layout& LayoutOf(const detector_view_robot_t*) { return kDetectorViewRobot; }
const Layout& LayoutOf(const detector_view_request_t*) { return kDetectorViewRequest; }
const Layout& LayoutOf(const marker_pixels_t*) { return kMarkerPixels; }
const Layout& LayoutOf(const marker_t*) { return kMarker; }
const Layout& LayoutOf(const pose2d_t*) { return kPose; }
const Layout& LayoutOf(const process_status_t*) { return kProcessStatus; }
const Layout& LayoutOf(const range_set_t*) { return kRangeSet; }
const Layout& LayoutOf(const range_t*) { return kRange; }
const Layout& LayoutOf(const site_file_t*) { return kSiteFile; }
const Layout& LayoutOf(const site_t*) { return kSite; }

const char* CheckEncoded(const Layout& layout, int64_t fingerprint, const void* data, int size,
                         std::string* detail) {
  constexpr int kFingerprintBytes = 8;
  if (data == nullptr || size < kFingerprintBytes) {
    if (detail != nullptr) {
      *detail = std::string(layout.type_name) + ": " + std::to_string(size < 0 ? 0 : size) +
                " bytes, fewer than the 8-byte fingerprint";
    }
    return wire_refusal::kTruncated;
  }
  const auto* bytes = static_cast<const uint8_t*>(data);
  uint64_t found = 0;
  for (int i = 0; i < kFingerprintBytes; ++i) found = found << 8 | bytes[i];
  if (static_cast<int64_t>(found) != fingerprint) {
    if (detail != nullptr) *detail = std::string("not a ") + layout.type_name + " (fingerprint)";
    return wire_refusal::kWrongType;
  }
  Walker walker(bytes, kFingerprintBytes, size, detail);
  if (const char* refusal = walker.Walk(layout)) return refusal;
  if (walker.left() > 0) {
    if (detail != nullptr) {
      *detail = std::string(layout.type_name) + ": " + std::to_string(walker.left()) +
                " bytes after the end of the message";
    }
    return wire_refusal::kTrailingBytes;
  }
  return nullptr;
}

}  // namespace wire

std::string RefusalCounts(const std::map<std::string, int64_t>& count_by_reason) {
  std::string text;
  for (const auto& [reason, count] : count_by_reason) {
    if (!text.empty()) text += ", ";
    text += std::to_string(count) + " " + reason;
  }
  return text;
}

}  // namespace roomfix
