#include "sim/ranges_node.h"

#include <cmath>

#include "roomfix/range_set_t.hpp"

namespace roomfix {

bool SimRangesNodeOptions::IsValid(std::string* error) const {
  if (!(rate_hz > 0.0 && rate_hz <= 1000.0)) {
    *error = "rate_hz must be in (0, 1000]";
    return false;
  }
  if (!(publish_delay_s >= 0.0)) {
    *error = "publish_delay_s must not be negative";
    return false;
  }
  return noise.IsValid(error);
}

SimRangesNode::SimRangesNode(const Site& site, Bus* bus, const SimRangesNodeOptions& options)
    : site_(site), bus_(bus), options_(options), rng_(options.seed) {
  for (const SimulatedRobot& sr : site.simulation.robots) {
    const Robot* robot = site.FindRobot(sr.robot_id);
    if (robot == nullptr || !robot->beacon_id) continue;
    firers_.push_back({sr.robot_id, site.FindBeacon(*robot->beacon_id), sr.trajectory.get(), 0});
  }
  const double period_us = 1e6 / options_.rate_hz;
  for (size_t k = 0; k < firers_.size(); ++k) {
    firers_[k].offset_us = static_cast<int64_t>(period_us * k / firers_.size());
  }
}

void SimRangesNode::Tick(int64_t now_utime) {
  const double period_us = 1e6 / options_.rate_hz;
  const int64_t delay_us = static_cast<int64_t>(options_.publish_delay_s * 1e6);
  const double c = SpeedOfSound(site_.simulation.temperature_c);
  for (Firer& f : firers_) {
    while (true) {
      const int64_t fire_utime = options_.start_utime + f.offset_us +
                                 static_cast<int64_t>(std::llround(f.next_seq * period_us));
      if (fire_utime + delay_us > now_utime) break;
      const double t_s = (fire_utime - options_.start_utime) * 1e-6;
      const GroundTruthPose truth = f.trajectory->PoseAt(t_s);
      const auto ranges = SimulateRanges(site_, {truth.x_m, truth.y_m, f.beacon->height_m},
                                         site_.simulation.temperature_c, options_.noise, &rng_);
      range_set_t set{};
      set.utime = fire_utime;
      set.beacon_id = f.beacon->id;
      set.firing_seq = f.next_seq;
      set.speed_of_sound_mps = c;
      set.temperature_c = site_.simulation.temperature_c;
      set.num_expected = static_cast<int32_t>(site_.receivers.size());
      for (const SimulatedRange& s : ranges) {
        const Receiver* r = site_.FindReceiver(s.receiver_id);
        range_t out{};
        out.receiver_id = s.receiver_id;
        for (int k = 0; k < 3; ++k) out.receiver_position_m[k] = r->position_m[k];
        out.time_of_flight_us = s.measured_m / c * 1e6;
        out.range_m = s.measured_m - r->range_offset_m;
        out.arrival_utime = fire_utime + static_cast<int64_t>(out.time_of_flight_us) + 5000;
        set.ranges.push_back(out);
      }
      set.num_ranges = static_cast<int32_t>(set.ranges.size());
      bus_->Publish("RANGES", set);
      ++f.next_seq;
      ++firings_;
    }
  }
}

}  // namespace roomfix
