#ifndef ROOMFIX_MSGIO_WIRE_CHECK_H_
#define ROOMFIX_MSGIO_WIRE_CHECK_H_

// Bounds check of a message's LCM encoding before any generated decoder runs.
//
// LCM 1.3.1's generated C++ decoders trust the lengths they read: a string
// length of INT32_MIN becomes std::string::assign(p, SIZE_MAX) (SIGSEGV), and
// an array count of 2^24 resizes the vector (about 1 GB zero-filled) before
// the missing bytes are noticed. Everything that decodes bytes from outside
// (the bus, logs, tools) therefore calls DecodeChecked(), which walks the
// encoded form against a table of the type's fields and refuses it with a
// reason unless every length and count is non-negative, within a per-type cap
// (docs/messages.md) and within the bytes present, every string is
// NUL-terminated with no NUL inside (as LCM encodes it), every enum-valued
// field holds one of its .lcm constants, and no byte trails.
// Only then does the generated decoder run; it can then allocate at most a
// small multiple of the message's size.

#include <cstdint>
#include <map>
#include <string>

#include "msgio/lcm_types_fwd.h"

namespace roomfix {

// Why an encoded message was refused; names are lower_case_with_underscores
// and appear in STATUS as `rejected[]` entries `<CHANNEL>.<reason>`.
namespace wire_refusal {
// Fewer bytes than the fields need (including a message under 8 bytes).
inline constexpr char kTruncated[] = "truncated";
// The 8-byte fingerprint is not the expected type's.
inline constexpr char kWrongType[] = "wrong_type";
// A string length or array count below zero.
inline constexpr char kNegativeLength[] = "negative_length";
// A string length above the field's cap.
inline constexpr char kStringOverCap[] = "string_over_cap";
// An array count above the field's cap.
inline constexpr char kCountOverCap[] = "count_over_cap";
// A string of length 0, not ending in NUL, or with a NUL inside.
inline constexpr char kBadString[] = "bad_string";
// Bytes after the end of the message.
inline constexpr char kTrailingBytes[] = "trailing_bytes";
// An enum-valued int8 (a pose's source or status, a marker's role, a
// search mode, a process state) outside the constants its .lcm file lists.
// Decoded, it would be cast to a roomfix enum no switch handles and read as
// whatever its comparisons fall through to (a status of 7 as "not lost").
inline constexpr char kEnumOutOfRange[] = "enum_out_of_range";
// Passed the check but the generated decoder still failed: a disagreement
// between the field table and the .lcm file, i.e. a roomfix bug.
inline constexpr char kUndecodable[] = "undecodable";
}  // namespace wire_refusal

// Per-type caps (docs/messages.md says why each is what it is). String caps
// count the terminating NUL, as LCM's length field does.
namespace wire_cap {
inline constexpr int32_t kRangesPerSet = 256;         // range_set_t.num_ranges
inline constexpr int32_t kMarkersPerFrame = 1024;     // marker_pixels_t.num_markers
inline constexpr int32_t kPreviewBytes = 16 << 20;    // image_t.num_bytes
inline constexpr int32_t kStatusCounters = 1024;      // process_status_t.num_rejected, num_counters
inline constexpr int32_t kNameBytes = 256;            // counter_t.name, process, host
inline constexpr int32_t kLastErrorBytes = 4096;      // process_status_t.last_error
inline constexpr int32_t kColourClassBytes = 64;      // marker_t.colour_class
inline constexpr int32_t kImageFormatBytes = 16;      // image_t.format
inline constexpr int32_t kSiteTextBytes = 1 << 20;    // site_t.site_text
inline constexpr int32_t kSiteFiles = 16;             // site_t.num_files
inline constexpr int32_t kSiteFileBytes = 256 << 10;  // site_file_t.text
inline constexpr int32_t kPathBytes = 4096;           // site_t.site_path, missing; site_file_t.name
inline constexpr int32_t kHashBytes = 65;             // site_t.content_hash: 64 hex digits
inline constexpr int32_t kVersionBytes = 64;          // site_t.roomfix_version
inline constexpr int32_t kDetectorViewBytes = 4 << 20;  // detector_view_t.num_bytes
inline constexpr int32_t kDetectorViewRobots = 256;     // detector_view_t.num_robots
inline constexpr int32_t kDetectorViewTextBytes = 512;  // detector_view_robot_t.text
}  // namespace wire_cap

namespace wire {

// The encoded form of one LCM struct, field by field in .lcm order.
enum class FieldKind : uint8_t {
  kFixed,        // `size` bytes of scalars or fixed-size arrays
  kString,       // int32 length (NUL included) then the bytes; `limit` caps the length
  kCount,        // int32 count of the next array field; `limit` caps it
  kStructArray,  // `element` structs (no fingerprints), as many as the last count
  kByteArray,    // bytes, as many as the last count
  kEnum,         // one int8 that must lie in 0..`limit` (the .lcm's constants)
};

struct Layout;

struct Field {
  const char* name;
  FieldKind kind;
  int32_t limit;  // kFixed: size in bytes; kString, kCount: cap; kEnum: largest value
  const Layout* element;
};

struct Layout {
  const char* type_name;  // "roomfix.range_set_t"
  const Field* fields;
  int num_fields;
};

// The layout of each roomfix type (lcmtypes/*.lcm).
const Layout& LayoutOf(const counter_t*);
const Layout& LayoutOf(const detector_view_request_t*);
const Layout& LayoutOf(const detector_view_robot_t*);
const Layout& LayoutOf(const detector_view_t*);
const Layout& LayoutOf(const image_t*);
const Layout& LayoutOf(const marker_pixels_t*);
const Layout& LayoutOf(const marker_t*);
const Layout& LayoutOf(const pose2d_t*);
const Layout& LayoutOf(const process_status_t*);
const Layout& LayoutOf(const range_set_t*);
const Layout& LayoutOf(const range_t*);
const Layout& LayoutOf(const site_file_t*);
const Layout& LayoutOf(const site_t*);

// Checks `size` bytes at `data` as a whole encoded message (8-byte fingerprint
// then the fields). nullptr when it may be decoded; otherwise the reason (one
// of wire_refusal::*), with one line for humans in *detail when non-null
// ("range_set_t.num_ranges 16777216 over cap 256"). Reads only the bytes
// given, allocates only for *detail, and takes time linear in `size`.
const char* CheckEncoded(const Layout& layout, int64_t fingerprint, const void* data, int size,
                         std::string* detail);

}  // namespace wire

// The check for one roomfix type: nullptr or the reason, as above.
template <class Msg>
const char* CheckEncoded(const void* data, int size, std::string* detail = nullptr) {
  return wire::CheckEncoded(wire::LayoutOf(static_cast<const Msg*>(nullptr)), Msg::getHash(), data,
                            size, detail);
}

// Refusal counts as tools print them on stderr: "3 count_over_cap, 1
// truncated" (map order); empty for an empty map.
std::string RefusalCounts(const std::map<std::string, int64_t>& count_by_reason);

// The one way roomfix decodes bytes from outside: checks, then decodes into
// *msg. False with the reason (wire_refusal::*) in *reason and a line for
// humans in *detail (either may be null); *msg is then unspecified.
template <class Msg>
bool DecodeChecked(const void* data, int size, Msg* msg, std::string* reason,
                   std::string* detail = nullptr) {
  const char* refusal = CheckEncoded<Msg>(data, size, detail);
  if (refusal == nullptr && msg->decode(data, 0, size) != size) {
    refusal = wire_refusal::kUndecodable;
    if (detail != nullptr) {
      *detail = std::string(Msg::getTypeName()) + " passed the wire check but did not decode";
    }
  }
  if (refusal == nullptr) return true;
  if (reason != nullptr) *reason = refusal;
  return false;
}

}  // namespace roomfix

#endif  // ROOMFIX_MSGIO_WIRE_CHECK_H_
