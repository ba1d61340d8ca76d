#include "sim/ranges_node.h"

#include <cmath>

#include "msgio/channels.h"
#include "msgio/radio_conversions.h"

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

std::vector<SimRangesNode::Firer> SimRangesNode::MakeFirers(const Site& site) {
  std::vector<Firer> firers;
  for (const CarriedBeacon& b : CarriedBeacons(site)) {
    firers.push_back({b.robot_id, b.beacon, b.trajectory});
  }
  return firers;
}

namespace {

SharedAirOptions AirOptions(const SimRangesNodeOptions& o) {
  SharedAirOptions air;
  air.mode = o.schedule;
  air.rate_hz = o.rate_hz;
  air.clock_ppm = o.clock_ppm;
  air.collisions = o.collisions;
  air.seed = o.seed;
  air.start_utime = o.start_utime;
  return air;
}

}  // namespace

SimRangesNode::SimRangesNode(const Site& site, Bus* bus, const SimRangesNodeOptions& options)
    : site_(site),
      bus_(bus),
      options_(options),
      firers_(MakeFirers(site)),
      air_(site, CarriedBeacons(site), AirOptions(options)),
      rng_(options.seed) {}

void SimRangesNode::Tick(int64_t now_utime) {
  const int64_t delay_us = static_cast<int64_t>(options_.publish_delay_s * 1e6);
  const double c = SpeedOfSound(site_.simulation.temperature_c);
  for (const SharedAir::Firing& firing : air_.TakeDue(now_utime - delay_us)) {
    Firer& f = firers_[firing.firer];
    f.next_seq += firing.skipped_before;
    const int64_t fire_utime = firing.fire_utime;
    const double t_s = (fire_utime - options_.start_utime) * 1e-6;
    const GroundTruthPose truth = f.trajectory->PoseAt(t_s);
    const auto ranges = SimulateRangesAt(site_, t_s, {truth.x_m, truth.y_m, f.beacon->height_m},
                                         site_.simulation.temperature_c, options_.noise, &rng_);
    // Site receiver order; a receiver that dropped out hears nothing.
    std::vector<double> own_tof_s(site_.receivers.size(), std::nan(""));
    for (const SimulatedRange& s : ranges) {
      const Receiver* r = site_.FindReceiver(s.receiver_id);
      own_tof_s[static_cast<size_t>(r - site_.receivers.data())] = s.time_of_flight_s;
    }
    const std::vector<Detection> detections = air_.Detect(firing, own_tof_s);
    // As the bridge assembles a firing from the radio, so that one
    // conversion makes every RANGES message.
    radio::AssembledSet set;
    set.fire_utime = fire_utime;
    set.beacon_id = f.beacon->id;
    set.firing_seq = f.next_seq;
    set.speed_of_sound_mps = c;
    set.temperature_c = site_.simulation.temperature_c;
    set.num_expected = static_cast<int>(site_.receivers.size());
    for (size_t i = 0; i < site_.receivers.size(); ++i) {
      const Detection& d = detections[i];
      if (d.kind != Detection::Kind::kOwn && d.kind != Detection::Kind::kEarly) continue;
      const Receiver& r = site_.receivers[i];
      // The timer reads the flight plus the receiver's own offset.
      const double measured_m = d.time_of_flight_s * c + r.range_offset_m;
      radio::AssembledRange out;
      out.receiver_id = r.id;
      for (int k = 0; k < 3; ++k) out.receiver_position_m[k] = r.position_m[k];
      out.time_of_flight_us = measured_m / c * 1e6;
      out.range_m = measured_m - r.range_offset_m;
      out.arrival_utime = fire_utime + static_cast<int64_t>(out.time_of_flight_us) + 5000;
      set.ranges.push_back(out);
    }
    bus_->Publish(kRangesChannel, RangeSetFromAssembled(set));
    ++f.next_seq;
    ++firings_;
  }
}

}  // namespace roomfix
