#ifndef ROOMFIX_MSGIO_TIME_LIMITS_H_
#define ROOMFIX_MSGIO_TIME_LIMITS_H_

#include <cstdint>
#include <limits>

namespace roomfix {

// A message's utime (its measurement time) farther than this from the time
// it was received (live: the host clock; replay: the log event's time) is
// refused as `utime_out_of_range`. One hour is three orders of magnitude
// above any real delay (radio buffering and fusion's history are seconds),
// so it never refuses a slow or late publisher, yet it catches what would
// poison per-robot state for good: an unset clock (1970), a publisher on
// another day, garbage and wrapped values (INT64_MIN), and it keeps every
// utime difference a node computes far from int64 overflow.
inline constexpr int64_t kMaxUtimeSkewUs = int64_t{3600} * 1000000;

// True when |utime - reference_utime| <= max_skew_us, computed without
// overflow for any two int64 values.
inline bool UtimeNear(int64_t utime, int64_t reference_utime,
                      int64_t max_skew_us = kMaxUtimeSkewUs) {
  int64_t diff = 0;
  if (__builtin_sub_overflow(utime, reference_utime, &diff)) return false;
  return diff >= -max_skew_us && diff <= max_skew_us;
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

}  // namespace roomfix

#endif  // ROOMFIX_MSGIO_TIME_LIMITS_H_
