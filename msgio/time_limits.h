#ifndef ROOMFIX_MSGIO_TIME_LIMITS_H_
#define ROOMFIX_MSGIO_TIME_LIMITS_H_

#include <cstdint>
#include <limits>

namespace roomfix {

// A message's utime (its measurement time) more than kMaxUtimeSkewUs before
// the time it was received (live: the host clock; replay: the log event's
// time), or more than kMaxUtimeAheadUs after it, is refused as
// `utime_out_of_range`.
//
// The past side is one hour, three orders of magnitude above any real delay
// (radio buffering and fusion's history are seconds), so it never refuses a
// slow or late publisher, yet it catches what would poison per-robot state
// for good: an unset clock (1970), a publisher on another day, garbage and
// wrapped values (INT64_MIN), and it keeps every utime difference a node
// computes far from int64 overflow.
inline constexpr int64_t kMaxUtimeSkewUs = int64_t{3600} * 1000000;

// The future side is tight. A measurement is stamped before it is sent (a
// frame's capture, a firing's announcement), so it can only look ahead of
// its receive time by the offset between the two hosts' clocks: well under
// 1 ms with PTP and a few ms with NTP on a LAN (docs/security.md, "Time").
// 100 ms is ten times the worst NTP offset of a healthy LAN host and still
// shorter than a camera frame's or a firing's own age when it is fused, so a
// message dated further ahead is a wrong clock or a forgery: issue #28 had a
// range set dated +3 590 s give a pose an hour ahead with latency -3.59e9 us.
inline constexpr int64_t kMaxUtimeAheadUs = 100'000;

// True when utime is at most max_behind_us before reference_utime and at
// most max_ahead_us after it, computed without overflow for any two int64
// values.
inline bool UtimeNear(int64_t utime, int64_t reference_utime,
                      int64_t max_behind_us = kMaxUtimeSkewUs,
                      int64_t max_ahead_us = kMaxUtimeAheadUs) {
  int64_t diff = 0;
  if (__builtin_sub_overflow(utime, reference_utime, &diff)) return false;
  return diff >= -max_behind_us && diff <= max_ahead_us;
}

// later - earlier, saturated at the int64 limits instead of wrapping (signed
// overflow is undefined behaviour). Negative only when `later` really is
// earlier: a latency measured so.
inline int64_t SaturatingDifferenceUs(int64_t later, int64_t earlier) {
  int64_t diff = 0;
  if (!__builtin_sub_overflow(later, earlier, &diff)) return diff;
  return later > earlier ? std::numeric_limits<int64_t>::max()
                         : std::numeric_limits<int64_t>::min();
}

// The latency a node publishes: now - measurement time, never negative. A
// measurement admitted by UtimeNear may be dated up to kMaxUtimeAheadUs
// ahead of this host's clock (the other host's clock offset); its age is then
// unknown below that offset, and 0 is the only latency that is not a lie.
inline int64_t LatencyUs(int64_t now_utime, int64_t measurement_utime) {
  const int64_t diff = SaturatingDifferenceUs(now_utime, measurement_utime);
  return diff < 0 ? 0 : diff;
}

}  // namespace roomfix

#endif  // ROOMFIX_MSGIO_TIME_LIMITS_H_
