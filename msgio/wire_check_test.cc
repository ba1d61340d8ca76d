#include "msgio/wire_check.h"

#include <gtest/gtest.h>
#include <sys/resource.h>

#include <algorithm>
#include <cctype>
#include <climits>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "msgio/install_paths.h"
#include "tests/testing/wire_test_messages.h"

namespace roomfix {
namespace {

using testing::Encode;
using testing::PutInt32;

template <class Msg>
const char* Check(const std::vector<uint8_t>& bytes, std::string* detail = nullptr) {
  return CheckEncoded<Msg>(bytes.data(), static_cast<int>(bytes.size()), detail);
}

// Reason as a string, "ok" when accepted, so failures print the reason.
template <class Msg>
std::string Verdict(const std::vector<uint8_t>& bytes) {
  const char* reason = Check<Msg>(bytes);
  return reason == nullptr ? "ok" : reason;
}

// Every real message passes, decodes, and re-encodes to its own bytes; every
// shorter prefix is truncated and one more byte is trailing. Together these
// pin each field table to the generated encoder byte for byte.
template <class Msg>
void ExpectTableMatchesEncoder(const Msg& msg) {
  SCOPED_TRACE(Msg::getTypeName());
  const std::vector<uint8_t> bytes = Encode(msg);
  EXPECT_EQ(Verdict<Msg>(bytes), "ok");
  Msg decoded{};
  std::string reason = "unset";
  ASSERT_TRUE(DecodeChecked(bytes.data(), static_cast<int>(bytes.size()), &decoded, &reason));
  EXPECT_EQ(reason, "unset") << "an accepted message must leave the reason alone";
  EXPECT_EQ(Encode(decoded), bytes);
  for (size_t n = 0; n < bytes.size(); ++n) {
    const std::vector<uint8_t> prefix(bytes.begin(), bytes.begin() + static_cast<long>(n));
    ASSERT_EQ(Verdict<Msg>(prefix), "truncated") << "prefix of " << n << " bytes";
  }
  std::vector<uint8_t> longer = bytes;
  longer.push_back(0);
  EXPECT_EQ(Verdict<Msg>(longer), "trailing_bytes");
}

TEST(WireCheck, AcceptsARealMessageOfEveryTypeAndNoPrefixOfIt) {
  ExpectTableMatchesEncoder(testing::MakeTestCounter("RANGES.count_over_cap", 3));
  ExpectTableMatchesEncoder(testing::MakeTestImage());
  ExpectTableMatchesEncoder(testing::MakeTestDetectorView());
  ExpectTableMatchesEncoder(
      testing::MakeTestDetectorViewRobot(3, detector_view_robot_t::REASON_NO_BLOB));
  ExpectTableMatchesEncoder(testing::MakeTestDetectorViewRequest());
  ExpectTableMatchesEncoder(testing::MakeTestMarkerPixels());
  ExpectTableMatchesEncoder(testing::MakeTestMarker("orange", 2));
  ExpectTableMatchesEncoder(testing::MakeTestPose(1700000000000000, 3, 1.25, 2.5));
  ExpectTableMatchesEncoder(testing::MakeTestStatus());
  ExpectTableMatchesEncoder(testing::MakeTestRangeSet(4));
  ExpectTableMatchesEncoder(testing::MakeTestRange(2, 1.75));
  ExpectTableMatchesEncoder(testing::MakeTestSiteFile());
  ExpectTableMatchesEncoder(testing::MakeTestSite());
}

TEST(WireCheck, AcceptsEmptyArraysAndEmptyStrings) {
  process_status_t status{};  // every string "", every list empty
  EXPECT_EQ(Verdict<process_status_t>(Encode(status)), "ok");
  EXPECT_EQ(Verdict<range_set_t>(Encode(testing::MakeTestRangeSet(0))), "ok");
}

// The audit's crash: LCM 1.3.1's decoder assigns length - 1 characters, so
// INT32_MIN reads far past the buffer.
TEST(WireCheck, RefusesAStringLengthOfInt32MinInStatusMarkersAndPreview) {
  std::vector<uint8_t> status = Encode(testing::MakeTestStatus());
  PutInt32(&status, testing::kStatusProcessLengthOffset, INT32_MIN);
  EXPECT_EQ(Verdict<process_status_t>(status), "negative_length");

  std::vector<uint8_t> pixels = Encode(testing::MakeTestMarkerPixels());
  PutInt32(&pixels, testing::kMarkerPixelsFirstColourLengthOffset, INT32_MIN);
  std::string detail;
  EXPECT_STREQ(Check<marker_pixels_t>(pixels, &detail), "negative_length");
  EXPECT_EQ(detail, "marker_t.colour_class length -2147483648 at byte 49 of " +
                        std::to_string(pixels.size()));

  std::vector<uint8_t> preview = Encode(testing::MakeTestImage());
  PutInt32(&preview, testing::kImageFormatLengthOffset, INT32_MIN);
  EXPECT_EQ(Verdict<image_t>(preview), "negative_length");
}

TEST(WireCheck, RefusesANegativeCount) {
  std::vector<uint8_t> ranges = Encode(testing::MakeTestRangeSet(2));
  PutInt32(&ranges, testing::kRangeSetNumRangesOffset, -1);
  EXPECT_EQ(Verdict<range_set_t>(ranges), "negative_length");
}

// Stands in for range_set_t and records whether its decoder ran.
struct RangeSetDecoderSpy : range_set_t {
  static inline int decode_calls = 0;
  int decode(const void* buf, int offset, int maxlen) {
    ++decode_calls;
    return range_set_t::decode(buf, offset, maxlen);
  }
};

// The audit's bloat: a 52-byte RANGES message (no ranges at all) claiming
// 2^24 of them made the generated decoder zero-fill 16777216 range_t (about
// 925 MB) before finding the bytes missing.
TEST(WireCheck, RefusesA2To24CountIn52BytesBeforeTheDecoderRuns) {
  std::vector<uint8_t> bytes = Encode(testing::MakeTestRangeSet(0));
  ASSERT_EQ(bytes.size(), 52u);
  PutInt32(&bytes, testing::kRangeSetNumRangesOffset, 1 << 24);

  rusage before{};
  getrusage(RUSAGE_SELF, &before);
  RangeSetDecoderSpy::decode_calls = 0;
  RangeSetDecoderSpy msg;
  std::string reason;
  std::string detail;
  EXPECT_FALSE(DecodeChecked(bytes.data(), 52, &msg, &reason, &detail));
  EXPECT_EQ(reason, "count_over_cap");
  EXPECT_EQ(detail, "range_set_t.num_ranges 16777216 over cap 256 at byte 52 of 52");
  EXPECT_EQ(RangeSetDecoderSpy::decode_calls, 0);
  EXPECT_TRUE(msg.ranges.empty());
  rusage after{};
  getrusage(RUSAGE_SELF, &after);
  // Peak resident set, KiB: the unchecked decode would add ~925 MB; the
  // check allocates only the detail string. 8 MB allows for the allocator.
  constexpr long kMaxPeakGrowthKib = 8 << 10;
  EXPECT_LT(after.ru_maxrss - before.ru_maxrss, kMaxPeakGrowthKib);
}

TEST(WireCheck, RefusesACountWithinItsCapThatTheBytesCannotHold) {
  // 200 ranges need 200 * 52 bytes; the message has none. Refused before
  // walking a single element.
  std::vector<uint8_t> bytes = Encode(testing::MakeTestRangeSet(0));
  PutInt32(&bytes, testing::kRangeSetNumRangesOffset, 200);
  std::string detail;
  EXPECT_STREQ(Check<range_set_t>(bytes, &detail), "truncated");
  EXPECT_EQ(detail, "range_set_t.ranges 200 elements cannot fit in 0 bytes at byte 52 of 52");

  std::vector<uint8_t> preview = Encode(testing::MakeTestImage());
  PutInt32(&preview, testing::kImageFormatLengthOffset + 4 + 5, 14);  // 13 bytes follow
  EXPECT_EQ(Verdict<image_t>(preview), "truncated");
}

TEST(WireCheck, AcceptsCountsAtTheirCapsAndRefusesOneMore) {
  EXPECT_EQ(Verdict<range_set_t>(Encode(testing::MakeTestRangeSet(wire_cap::kRangesPerSet))), "ok");
  EXPECT_EQ(Verdict<range_set_t>(Encode(testing::MakeTestRangeSet(wire_cap::kRangesPerSet + 1))),
            "count_over_cap");

  marker_pixels_t pixels = testing::MakeTestMarkerPixels();
  pixels.markers.assign(wire_cap::kMarkersPerFrame + 1, testing::MakeTestMarker("orange", -1));
  pixels.num_markers = wire_cap::kMarkersPerFrame + 1;
  EXPECT_EQ(Verdict<marker_pixels_t>(Encode(pixels)), "count_over_cap");

  image_t preview = testing::MakeTestImage();
  preview.data.assign(static_cast<size_t>(wire_cap::kPreviewBytes), 0);
  preview.num_bytes = wire_cap::kPreviewBytes;
  EXPECT_EQ(Verdict<image_t>(Encode(preview)), "ok");
  preview.data.push_back(0);
  preview.num_bytes += 1;
  EXPECT_EQ(Verdict<image_t>(Encode(preview)), "count_over_cap");

  process_status_t status = testing::MakeTestStatus();
  status.counters.assign(wire_cap::kStatusCounters + 1, testing::MakeTestCounter("x", 1));
  status.num_counters = wire_cap::kStatusCounters + 1;
  EXPECT_EQ(Verdict<process_status_t>(Encode(status)), "count_over_cap");
}

// String caps count LCM's length field, which includes the NUL.
TEST(WireCheck, AcceptsStringsAtTheirCapsAndRefusesOneByteMore) {
  process_status_t status = testing::MakeTestStatus();
  status.process.assign(wire_cap::kNameBytes - 1, 'p');
  status.last_error.assign(wire_cap::kLastErrorBytes - 1, 'e');
  EXPECT_EQ(Verdict<process_status_t>(Encode(status)), "ok");
  status.process.push_back('p');
  EXPECT_EQ(Verdict<process_status_t>(Encode(status)), "string_over_cap");
  status.process.pop_back();
  status.last_error.push_back('e');
  EXPECT_EQ(Verdict<process_status_t>(Encode(status)), "string_over_cap");

  marker_pixels_t pixels = testing::MakeTestMarkerPixels();
  pixels.markers[1].colour_class.assign(wire_cap::kColourClassBytes, 'c');
  EXPECT_EQ(Verdict<marker_pixels_t>(Encode(pixels)), "string_over_cap");

  image_t preview = testing::MakeTestImage();
  preview.format.assign(wire_cap::kImageFormatBytes, 'f');
  EXPECT_EQ(Verdict<image_t>(Encode(preview)), "string_over_cap");

  site_t site = testing::MakeTestSite();
  site.site_text.assign(wire_cap::kSiteTextBytes - 1, 's');
  site.files[0].text.assign(wire_cap::kSiteFileBytes - 1, 'c');
  EXPECT_EQ(Verdict<site_t>(Encode(site)), "ok");
  site.site_text.push_back('s');
  EXPECT_EQ(Verdict<site_t>(Encode(site)), "string_over_cap");
  site.site_text.pop_back();
  site.files[0].text.push_back('c');
  EXPECT_EQ(Verdict<site_t>(Encode(site)), "string_over_cap");
}

TEST(WireCheck, AcceptsSiteFilesAtTheirCapAndRefusesOneMore) {
  site_t site = testing::MakeTestSite();
  site.files.assign(wire_cap::kSiteFiles, testing::MakeTestSiteFile());
  site.num_files = wire_cap::kSiteFiles;
  EXPECT_EQ(Verdict<site_t>(Encode(site)), "ok");
  site.files.push_back(testing::MakeTestSiteFile());
  site.num_files = wire_cap::kSiteFiles + 1;
  EXPECT_EQ(Verdict<site_t>(Encode(site)), "count_over_cap");
}

TEST(WireCheck, RefusesStringsLcmWouldNeverWrite) {
  const std::vector<uint8_t> good = Encode(testing::MakeTestStatus());
  const size_t length_at = testing::kStatusProcessLengthOffset;
  const size_t text_at = length_at + 4;  // "trilat_proc" and its NUL: 12 bytes

  // Length 0: the decoder would assign SIZE_MAX characters.
  std::vector<uint8_t> empty(good.begin(), good.begin() + static_cast<long>(length_at));
  empty.resize(empty.size() + 4, 0);
  empty.insert(empty.end(), good.begin() + static_cast<long>(text_at + 12), good.end());
  EXPECT_EQ(Verdict<process_status_t>(empty), "bad_string");

  std::vector<uint8_t> unterminated = good;
  unterminated[text_at + 11] = 'x';
  EXPECT_EQ(Verdict<process_status_t>(unterminated), "bad_string");

  std::vector<uint8_t> nul_inside = good;
  nul_inside[text_at + 3] = 0;
  EXPECT_EQ(Verdict<process_status_t>(nul_inside), "bad_string");
}

TEST(WireCheck, RefusesAnotherTypesFingerprint) {
  const std::vector<uint8_t> pose = Encode(testing::MakeTestPose(1, 1, 1, 1));
  std::string detail;
  EXPECT_STREQ(Check<range_set_t>(pose, &detail), "wrong_type");
  EXPECT_EQ(detail, "not a range_set_t (fingerprint)");
  EXPECT_EQ(Verdict<process_status_t>(pose), "wrong_type");
  // A nested type's fingerprint differs from its container's.
  EXPECT_EQ(Verdict<range_t>(Encode(testing::MakeTestRangeSet(1))), "wrong_type");
}

TEST(WireCheck, RefusesFewerThanTheFingerprintsEightBytes) {
  const uint8_t bytes[7] = {};
  EXPECT_STREQ(CheckEncoded<pose2d_t>(bytes, 7), "truncated");
  EXPECT_STREQ(CheckEncoded<pose2d_t>(nullptr, 0), "truncated");
  EXPECT_STREQ(CheckEncoded<pose2d_t>(bytes, -5), "truncated");
}

// Every enum-valued int8 a roomfix message carries, encoded by the generated
// encoder with each value an int8 can hold: exactly the .lcm's constants pass;
// every other value is refused before decoding, with the field and value
// named, however the rest of the message looks.
template <class Msg, class Set>
void ExpectOnlyConstantsPass(const Msg& good, Set set, int8_t largest, const std::string& field) {
  SCOPED_TRACE(field);
  for (int v = INT8_MIN; v <= INT8_MAX; ++v) {
    Msg msg = good;
    set(&msg, static_cast<int8_t>(v));
    const std::vector<uint8_t> bytes = Encode(msg);
    Msg decoded{};
    std::string reason;
    std::string detail;
    const bool accepted =
        DecodeChecked(bytes.data(), static_cast<int>(bytes.size()), &decoded, &reason, &detail);
    if (v >= 0 && v <= largest) {
      EXPECT_TRUE(accepted) << v << ": " << detail;
      continue;
    }
    ASSERT_FALSE(accepted) << "value " << v << " passed";
    EXPECT_EQ(reason, "enum_out_of_range");
    EXPECT_EQ(detail.rfind(field + " " + std::to_string(v) + " outside 0.." +
                               std::to_string(largest) + " at byte ",
                           0),
              0u)
        << detail;
  }
}

TEST(WireCheck, AcceptsOnlyTheConstantsOfEveryEnumField) {
  const pose2d_t pose = testing::MakeTestPose(1700000000000000, 3, 1.25, 2.5);
  ExpectOnlyConstantsPass(
      pose, [](pose2d_t* m, int8_t v) { m->status = v; }, pose2d_t::STATUS_LOST, "pose2d_t.status");
  ExpectOnlyConstantsPass(
      pose, [](pose2d_t* m, int8_t v) { m->source = v; }, pose2d_t::SOURCE_GROUND_TRUTH,
      "pose2d_t.source");
  const marker_pixels_t pixels = testing::MakeTestMarkerPixels();
  ExpectOnlyConstantsPass(
      pixels, [](marker_pixels_t* m, int8_t v) { m->search_mode = v; },
      marker_pixels_t::SEARCH_REGION_OF_INTEREST, "marker_pixels_t.search_mode");
  // The second marker's role: a bad element inside an array is found too.
  ExpectOnlyConstantsPass(
      pixels, [](marker_pixels_t* m, int8_t v) { m->markers[1].role = v; }, marker_t::ROLE_HEADING,
      "marker_t.role");
  ExpectOnlyConstantsPass(
      testing::MakeTestStatus(), [](process_status_t* m, int8_t v) { m->state = v; },
      process_status_t::STATE_FAILED, "process_status_t.state");
}

// The .lcm lines this test reads, as tokens: "int8_t status;" is
// {"int8_t", "status", ";"}, "const int8_t OK = 0;" is {"const", "int8_t",
// "OK", "=", "0", ";"}. Tokenised by hand rather than with std::regex, whose
// std::function internals GCC 12 under AddressSanitizer reports as
// -Wmaybe-uninitialized (a false positive, GCC bug 105616), which stopped
// `make test SANITIZE=1` here (issue #28).
std::vector<std::string> LcmTokens(const std::string& line) {
  std::string spaced;
  for (const char c : line) {
    if (c == ';' || c == '=') {
      spaced += ' ';
      spaced += c;
      spaced += ' ';
    } else {
      spaced += c;
    }
  }
  std::istringstream in(spaced);
  std::vector<std::string> tokens;
  for (std::string t; in >> t;) tokens.push_back(t);
  return tokens;
}

bool IsIdentifier(const std::string& t) {
  if (t.empty() || std::isdigit(static_cast<unsigned char>(t[0]))) return false;
  return std::all_of(t.begin(), t.end(), [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) || c == '_';
  });
}

bool IsInteger(const std::string& t) {
  const size_t start = !t.empty() && t[0] == '-' ? 1 : 0;
  return t.size() > start && std::all_of(t.begin() + static_cast<long>(start), t.end(), [](char c) {
           return std::isdigit(static_cast<unsigned char>(c));
         });
}

// The field tables against lcmtypes/*.lcm: every int8 field followed by
// `const int8_t` constants is an enum, and its table entry is a kEnum bounded
// by the largest constant, the constants running 0, 1, 2 ... without a gap
// (the range check relies on that). A constant added to a .lcm file without
// its table fails here.
TEST(WireCheck, EveryEnumOfTheLcmFilesIsCheckedWithItsLargestConstant) {
  const std::map<std::string, const wire::Layout*> layouts = {
      {"marker_pixels_t", &wire::LayoutOf(static_cast<const marker_pixels_t*>(nullptr))},
      {"marker_t", &wire::LayoutOf(static_cast<const marker_t*>(nullptr))},
      {"pose2d_t", &wire::LayoutOf(static_cast<const pose2d_t*>(nullptr))},
      {"process_status_t", &wire::LayoutOf(static_cast<const process_status_t*>(nullptr))},
      {"counter_t", &wire::LayoutOf(static_cast<const counter_t*>(nullptr))},
      {"image_t", &wire::LayoutOf(static_cast<const image_t*>(nullptr))},
      {"detector_view_t", &wire::LayoutOf(static_cast<const detector_view_t*>(nullptr))},
      {"detector_view_robot_t",
       &wire::LayoutOf(static_cast<const detector_view_robot_t*>(nullptr))},
      {"detector_view_request_t",
       &wire::LayoutOf(static_cast<const detector_view_request_t*>(nullptr))},
      {"range_set_t", &wire::LayoutOf(static_cast<const range_set_t*>(nullptr))},
      {"range_t", &wire::LayoutOf(static_cast<const range_t*>(nullptr))},
      {"site_file_t", &wire::LayoutOf(static_cast<const site_file_t*>(nullptr))},
      {"site_t", &wire::LayoutOf(static_cast<const site_t*>(nullptr))},
  };
  int enums_found = 0;
  for (const auto& [type, layout] : layouts) {
    const std::string path = DataFile("lcmtypes/" + type + ".lcm");
    std::ifstream in(path);
    ASSERT_TRUE(in.good()) << path;
    // Field name -> its constants, in file order.
    std::map<std::string, std::vector<int>> constants;
    std::string field;
    for (std::string line; std::getline(in, line);) {
      line = line.substr(0, line.find("//"));
      const std::vector<std::string> t = LcmTokens(line);
      if (t.size() == 3 && t[0] == "int8_t" && IsIdentifier(t[1]) && t[2] == ";") {
        field = t[1];
      } else if (t.size() == 6 && t[0] == "const" && t[1] == "int8_t" && IsIdentifier(t[2]) &&
                 t[3] == "=" && IsInteger(t[4]) && t[5] == ";") {
        ASSERT_FALSE(field.empty()) << path << ": a constant before any int8 field";
        constants[field].push_back(std::stoi(t[4]));
      } else if (line.find(';') != std::string::npos) {
        field.clear();  // another field: constants after it are not this enum's
      }
    }
    for (const auto& [name, values] : constants) {
      SCOPED_TRACE(type + "." + name);
      ++enums_found;
      for (size_t i = 0; i < values.size(); ++i) EXPECT_EQ(values[i], static_cast<int>(i));
      const wire::Field* entry = nullptr;
      for (int i = 0; i < layout->num_fields; ++i) {
        if (layout->fields[i].name == name) entry = &layout->fields[i];
      }
      ASSERT_NE(entry, nullptr) << "no field table entry";
      EXPECT_EQ(entry->kind, wire::FieldKind::kEnum);
      EXPECT_EQ(entry->limit, static_cast<int32_t>(values.size()) - 1);
    }
  }
  // pose2d_t source and status, marker_t role, marker_pixels_t search_mode,
  // process_status_t state, detector_view_robot_t reason: a parser that
  // found none would pass vacuously.
  EXPECT_EQ(enums_found, 6);
}

}  // namespace
}  // namespace roomfix
