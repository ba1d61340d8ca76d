#ifndef ROOMFIX_TESTS_TESTING_HOSTILE_TRAFFIC_H_
#define ROOMFIX_TESTS_TESTING_HOSTILE_TRAFFIC_H_

// The attacker of issue #15: raw UDP datagrams in LCM's multicast wire format
// and LCM payloads that are well-formed datagrams but lie (lengths, counts,
// ids, times, values). Each function makes one class of input a hostile or
// broken publisher on the lab network can send; tests/netns/
// hostile_traffic_test.cc sends them to the real processes, and
// `roomfix_hostile` (tests/testing/hostile_publisher.cc) sends them by hand.
//
// LCM's UDP multicast format (lcm_udpm.c, big-endian):
//   short message, whole in one datagram: "LC02", u32 sequence number,
//     channel NUL-terminated, payload;
//   fragment of a long message: "LC03", u32 sequence number, u32 total
//     payload size, u32 offset of this fragment's data in the payload,
//     u16 fragment number, u16 fragment count; fragment 0 carries the
//     channel NUL-terminated before its data.
// A payload of a generated type starts with its 8-byte fingerprint.

#include <cstdint>
#include <string>
#include <vector>

#include "roomfix/pose2d_t.hpp"
#include "roomfix/range_set_t.hpp"

namespace roomfix::hostile {

using Bytes = std::vector<uint8_t>;

// The LCM wire format.
Bytes ShortDatagram(uint32_t seqno, const std::string& channel, const Bytes& payload);
Bytes FragmentDatagram(uint32_t seqno, uint32_t total_size, uint32_t offset, uint16_t fragment_no,
                       uint16_t fragment_count, const std::string& channel, const Bytes& data);

template <class Msg>
Bytes Encode(const Msg& msg) {
  Bytes out(static_cast<size_t>(msg.getEncodedSize()));
  msg.encode(out.data(), 0, static_cast<int>(out.size()));
  return out;
}

// Sends datagrams to an LCM udpm:// URL's group and port with the URL's ttl
// (0 when absent: nothing leaves the host). Raw sendto, no liblcm, so
// anything can be sent.
class Sender {
 public:
  explicit Sender(const std::string& lcm_url);
  ~Sender();
  Sender(const Sender&) = delete;
  Sender& operator=(const Sender&) = delete;
  bool ok() const { return fd_ >= 0; }
  const std::string& error() const { return error_; }
  bool Send(const Bytes& datagram);
  bool SendAll(const std::vector<Bytes>& datagrams);
  // A whole, valid LCM message (fragmented as liblcm would when over 1400
  // bytes), with this sender's own sequence numbers.
  bool Publish(const std::string& channel, const Bytes& payload);
  uint32_t NextSeqno() { return seqno_++; }

 private:
  int fd_ = -1;
  std::string error_;
  uint32_t seqno_ = 0x40000000;
  uint8_t addr_[16] = {};
};

// Good traffic for the demo site (config/sites/demo_room.yaml): beacon 1 on
// robot 1 standing at (2.0, 1.5) with the beacon 1.3 m up, heard by all four
// corner receivers.
inline constexpr double kGoodX_m = 2.0;
inline constexpr double kGoodY_m = 1.5;
range_set_t GoodRanges(int64_t firing_seq, int64_t utime);
pose2d_t GoodPose(int8_t source, int64_t measurement_seq, int64_t utime);

// --- The classes of hostile input (issue #15's table), one function each. ---

// Two LC03 fragments of one message whose total sizes disagree: fragment 0
// declares a small message, fragment 1 a large one with its data far past
// the first's end (the heap overflow in msgio/udpm_bus.cc).
std::vector<Bytes> ConflictingTotalFragments(uint32_t seqno, const std::string& channel);

// A first fragment declaring a 64 MiB message that never completes.
Bytes HugeFirstFragment(uint32_t seqno, const std::string& channel);
inline constexpr uint32_t kHugeMessageBytes = 64u << 20;

// A string length of INT32_MIN in the first string of a STATUS
// (process_status_t.process), MARKER_PIXELS (markers[0].colour_class) or
// CAMERA_PREVIEW (image_t.format) or CAMERA_DETECTOR_VIEW
// (detector_view_t.format) payload; otherwise a valid encoding.
Bytes StatusWithNegativeStringLength();
Bytes MarkerPixelsWithNegativeStringLength();
Bytes CameraPreviewWithNegativeStringLength();
Bytes DetectorViewWithNegativeStringLength();

// CAMERA_DETECTOR_VIEW_REQUEST payloads camera_proc must refuse, each for
// its own reason: NaN and infinite rates and durations, a duration of a
// year, a negative or zero rate, a region outside any frame, one of
// INT32_MIN/INT32_MAX sizes, a camera id below -1. `utime` is now.
std::vector<Bytes> HostileDetectorViewRequests(int64_t utime);

// A 52-byte range_set_t (no ranges) whose num_ranges says `count`.
Bytes RangesClaimingCount(int32_t count);
inline constexpr int32_t kHugeRangeCount = 1 << 24;

// n mutually inconsistent ranges for beacon 1: receiver ids 1..n (the first
// four the site's, the rest unknown), positions scattered over and beyond the
// room, ranges drawn at random. Deterministic for a seed.
range_set_t InconsistentRanges(int n, int64_t firing_seq, int64_t utime, uint32_t seed);

// An LC02 datagram whose channel is the empty string (LCM's log reader
// refuses an event with an empty channel).
Bytes EmptyChannelDatagram(uint32_t seqno);

// A valid pose for a robot the site does not have (ids from 1000 up).
pose2d_t PoseForNewRobot(int8_t source, int32_t robot_id, int64_t utime);

// Non-finite values where the type allows them: a range set with a NaN
// range, an infinite receiver position and a NaN speed of sound; poses with
// NaN or infinite coordinates and covariance.
range_set_t NonFiniteRanges(int64_t firing_seq, int64_t utime);
std::vector<pose2d_t> NonFinitePoses(int8_t source, int64_t utime);

// A time absurdly far from now: about 100 years ahead, and far before 1970.
inline constexpr int64_t kFarFutureOffsetUs = 100LL * 365 * 86400 * 1'000'000;
std::vector<int64_t> AbsurdUtimes(int64_t now_utime);

}  // namespace roomfix::hostile

#endif  // ROOMFIX_TESTS_TESTING_HOSTILE_TRAFFIC_H_
