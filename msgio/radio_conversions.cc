#include "msgio/radio_conversions.h"

namespace roomfix {

range_set_t RangeSetFromAssembled(const radio::AssembledSet& set) {
  range_set_t out{};
  out.utime = set.fire_utime;
  out.beacon_id = set.beacon_id;
  out.firing_seq = set.firing_seq;
  out.speed_of_sound_mps = set.speed_of_sound_mps;
  out.temperature_c = set.temperature_c;
  out.num_expected = set.num_expected;
  out.ranges.reserve(set.ranges.size());
  for (const radio::AssembledRange& r : set.ranges) {
    range_t range{};
    range.receiver_id = r.receiver_id;
    for (int k = 0; k < 3; ++k) range.receiver_position_m[k] = r.receiver_position_m[k];
    range.time_of_flight_us = r.time_of_flight_us;
    range.range_m = r.range_m;
    range.arrival_utime = r.arrival_utime;
    out.ranges.push_back(range);
  }
  out.num_ranges = static_cast<int32_t>(out.ranges.size());
  return out;
}

}  // namespace roomfix
