// Fuzz target: the wire check and decode of every roomfix LCM type
// (DecodeChecked, msgio/wire_check.h), the one path by which bytes from the
// bus or a log reach a generated decoder.
//
// The input is tried twice for each of the 10 types: as a whole encoded
// message (so real messages are seeds as they are), and, when it is at least
// 1 byte long, with that type's fingerprint put in front of the bytes after
// the first (so mutations explore the fields of every type, not just the
// fingerprint check). Invariants (abort() on violation):
//  - the generated decoder never fails on input the check accepted
//    (refusal `undecodable`);
//  - an accepted message is exactly what LCM would encode: re-encoding gives
//    the same bytes, so nothing was skipped or read twice;
//  - a refusal is one of the documented reasons.
// ASan catches a read past the input or a wild allocation if the check lets
// one through (the crash inputs of issue #15 are in the corpus).
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <set>
#include <string>
#include <vector>

#include "msgio/wire_check.h"
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

namespace {

void Fail(const char* type_name, const std::string& what) {
  std::fprintf(stderr, "lcm_message_fuzz: %s: %s\n", type_name, what.c_str());
  std::abort();
}

template <class Msg>
void CheckThenDecode(const uint8_t* data, size_t size) {
  if (size > static_cast<size_t>(INT32_MAX)) return;
  const int n = static_cast<int>(size);
  Msg msg{};
  std::string reason;
  std::string detail;
  if (!roomfix::DecodeChecked(data, n, &msg, &reason, &detail)) {
    static const std::set<std::string> kReasons = {
        roomfix::wire_refusal::kTruncated,      roomfix::wire_refusal::kWrongType,
        roomfix::wire_refusal::kNegativeLength, roomfix::wire_refusal::kStringOverCap,
        roomfix::wire_refusal::kCountOverCap,   roomfix::wire_refusal::kBadString,
        roomfix::wire_refusal::kTrailingBytes,  roomfix::wire_refusal::kEnumOutOfRange};
    if (kReasons.count(reason) == 0) Fail(Msg::getTypeName(), reason + ": " + detail);
    return;
  }
  if (msg.getEncodedSize() != n) Fail(Msg::getTypeName(), "accepted size differs from encoding");
  std::vector<uint8_t> again(size);
  if (msg.encode(again.data(), 0, n) != n || std::memcmp(again.data(), data, size) != 0) {
    Fail(Msg::getTypeName(), "accepted bytes do not re-encode to themselves");
  }
}

template <class Msg>
void AsIsAndWithFingerprint(const uint8_t* data, size_t size, std::vector<uint8_t>* scratch) {
  CheckThenDecode<Msg>(data, size);
  if (size < 1) return;
  scratch->assign(8, 0);
  const auto hash = static_cast<uint64_t>(Msg::getHash());
  for (int i = 0; i < 8; ++i) (*scratch)[i] = static_cast<uint8_t>(hash >> (56 - 8 * i));
  scratch->insert(scratch->end(), data + 1, data + size);
  CheckThenDecode<Msg>(scratch->data(), scratch->size());
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  std::vector<uint8_t> scratch;
  AsIsAndWithFingerprint<roomfix::counter_t>(data, size, &scratch);
  AsIsAndWithFingerprint<roomfix::detector_view_request_t>(data, size, &scratch);
  AsIsAndWithFingerprint<roomfix::detector_view_robot_t>(data, size, &scratch);
  AsIsAndWithFingerprint<roomfix::detector_view_t>(data, size, &scratch);
  AsIsAndWithFingerprint<roomfix::image_t>(data, size, &scratch);
  AsIsAndWithFingerprint<roomfix::marker_pixels_t>(data, size, &scratch);
  AsIsAndWithFingerprint<roomfix::marker_t>(data, size, &scratch);
  AsIsAndWithFingerprint<roomfix::pose2d_t>(data, size, &scratch);
  AsIsAndWithFingerprint<roomfix::process_status_t>(data, size, &scratch);
  AsIsAndWithFingerprint<roomfix::range_set_t>(data, size, &scratch);
  AsIsAndWithFingerprint<roomfix::range_t>(data, size, &scratch);
  AsIsAndWithFingerprint<roomfix::site_file_t>(data, size, &scratch);
  AsIsAndWithFingerprint<roomfix::site_t>(data, size, &scratch);
  return 0;
}
