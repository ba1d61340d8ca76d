#include "core/world/air_model.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/world/ultrasound_model.h"

namespace roomfix {

double AirAbsorptionDbPerM(double frequency_hz, double temperature_c, double humidity_percent) {
  // ISO 9613-1:1993 at the reference pressure (pa / pr = 1): T0 = 293.15 K,
  // T01 = 273.16 K (triple point), molar concentration of water vapour h
  // from the relative humidity and the saturation pressure, relaxation
  // frequencies of oxygen frO and nitrogen frN.
  const double t_k = temperature_c + 273.15;
  const double tr = t_k / 293.15;
  const double psat_ratio = std::pow(10.0, -6.8346 * std::pow(273.16 / t_k, 1.261) + 4.6151);
  const double h = humidity_percent * psat_ratio;
  const double fr_o = 24.0 + 4.04e4 * h * (0.02 + h) / (0.391 + h);
  const double fr_n =
      std::pow(tr, -0.5) * (9.0 + 280.0 * h * std::exp(-4.170 * (std::cbrt(1.0 / tr) - 1.0)));
  const double f2 = frequency_hz * frequency_hz;
  const double classical = 1.84e-11 * std::sqrt(tr);
  const double relaxation =
      std::pow(tr, -2.5) * (0.01275 * std::exp(-2239.1 / t_k) / (fr_o + f2 / fr_o) +
                            0.1068 * std::exp(-3352.0 / t_k) / (fr_n + f2 / fr_n));
  return 8.686 * f2 * (classical + relaxation);
}

RoomDecay ComputeRoomDecay(const Site& site, double temperature_c) {
  const Room& room = site.room;
  const Acoustics& a = site.acoustics;
  const double c = SpeedOfSound(temperature_c);
  RoomDecay d;
  d.air_absorption_db_per_m =
      AirAbsorptionDbPerM(a.frequency_hz, temperature_c, a.humidity_percent);
  const double volume_m3 = room.size_x_m * room.size_y_m * room.height_m;
  const double surface_m2 = 2.0 * (room.size_x_m * room.size_y_m + room.size_x_m * room.height_m +
                                   room.size_y_m * room.height_m);
  // 10 log10(e) = 4.343 dB per neper of intensity.
  const double m_per_m = d.air_absorption_db_per_m / (10.0 * std::log10(std::exp(1.0)));
  d.reverberation_time_s = 24.0 * std::log(10.0) * volume_m3 /
                           (c * (surface_m2 * a.wall_absorption + 4.0 * m_per_m * volume_m3));
  for (const Receiver& r : site.receivers) {
    for (int corner = 0; corner < 8; ++corner) {
      const double x = room.min_x_m + ((corner & 1) ? room.size_x_m : 0.0);
      const double y = room.min_y_m + ((corner & 2) ? room.size_y_m : 0.0);
      const double z = (corner & 4) ? room.height_m : 0.0;
      d.max_range_m = std::max(
          d.max_range_m, std::hypot(x - r.position_m[0], y - r.position_m[1], z - r.position_m[2]));
    }
  }
  d.max_range_m = std::max(d.max_range_m, 1.0);
  d.max_time_of_flight_s = d.max_range_m / c;
  d.level_at_1m_db = 20.0 * std::log10(d.max_range_m) + d.air_absorption_db_per_m * d.max_range_m +
                     a.detection_margin_db;
  d.tail_start_db = d.level_at_1m_db + 10.0 * std::log10(4.0 * M_PI * c * a.pulse_s / volume_m3);
  if (a.decay_s) {
    d.decay_s = *a.decay_s;
    d.decay_from_site = true;
  } else {
    d.decay_s = a.pulse_s + std::max(0.0, d.tail_start_db) / 60.0 * d.reverberation_time_s;
  }
  d.slot_s = d.max_time_of_flight_s + d.decay_s + a.clock_uncertainty_s;
  d.listen_s = d.max_time_of_flight_s + 0.005;
  return d;
}

const char* DetectionKindName(Detection::Kind kind) {
  switch (kind) {
    case Detection::Kind::kOwn:
      return "own";
    case Detection::Kind::kEarly:
      return "early";
    case Detection::Kind::kArmedInTail:
      return "armed_in_tail";
    case Detection::Kind::kNone:
      return "none";
  }
  return "?";
}

AirChannel::AirChannel(double decay_s, double listen_s) : decay_s_(decay_s), listen_s_(listen_s) {}

void AirChannel::Add(const AirPulse& pulse) {
  // Kept in firing order, so that ForgetBefore drops from the front.
  auto at = std::upper_bound(pulses_.begin(), pulses_.end(), pulse.fire_utime,
                             [](int64_t utime, const AirPulse& p) { return utime < p.fire_utime; });
  pulses_.insert(at, pulse);
}

std::vector<Detection> AirChannel::Detect(const AirPulse& pulse,
                                          const std::vector<double>& own_tof_s) const {
  std::vector<Detection> out(own_tof_s.size());
  for (size_t i = 0; i < own_tof_s.size(); ++i) {
    Detection& det = out[i];
    const double own = own_tof_s[i];
    const double limit = std::isfinite(own) ? std::min(own, listen_s_) : listen_s_;
    double earliest = std::numeric_limits<double>::infinity();
    int earliest_beacon = 0;
    bool in_tail = false;
    for (const AirPulse& q : pulses_) {
      if (q.beacon_id == pulse.beacon_id && q.seq == pulse.seq) continue;
      if (i >= q.arrival_s.size()) continue;
      const double arrive_s = (q.fire_utime - pulse.fire_utime) * 1e-6 + q.arrival_s[i];
      if (arrive_s <= 0.0 && arrive_s + decay_s_ > 0.0) {
        in_tail = true;
        det.interferer_beacon_id = q.beacon_id;
        break;
      }
      if (arrive_s > 0.0 && arrive_s < limit && arrive_s < earliest) {
        earliest = arrive_s;
        earliest_beacon = q.beacon_id;
      }
    }
    if (in_tail) {
      det.kind = Detection::Kind::kArmedInTail;
      det.time_of_flight_s = 0.0;
    } else if (std::isfinite(earliest)) {
      det.kind = Detection::Kind::kEarly;
      det.time_of_flight_s = earliest;
      det.interferer_beacon_id = earliest_beacon;
    } else if (std::isfinite(own) && own <= listen_s_) {
      det.kind = Detection::Kind::kOwn;
      det.time_of_flight_s = own;
    }
  }
  return out;
}

void AirChannel::ForgetBefore(int64_t utime) {
  while (!pulses_.empty()) {
    const AirPulse& p = pulses_.front();
    double longest_s = 0.0;
    for (double a : p.arrival_s) longest_s = std::max(longest_s, a);
    const double until_s = longest_s + decay_s_;
    if (p.fire_utime + static_cast<int64_t>(until_s * 1e6) + 1 >= utime) break;
    pulses_.pop_front();
  }
}

bool FiringPlanOptions::IsValid(std::string* error) const {
  if (!(rate_hz > 0.0 && rate_hz <= 1000.0)) {
    *error = "firing rate must be in (0, 1000] Hz";
    return false;
  }
  if (!(slot_s > 0.0 && slot_s <= 10.0)) {
    *error = "slot must be in (0, 10] s";
    return false;
  }
  if (!(clock_ppm >= 0.0 && clock_ppm <= 10000.0)) {
    *error = "clock error must be in [0, 10000] ppm";
    return false;
  }
  if (!(sync_jitter_s >= 0.0 && sync_jitter_s <= 0.1)) {
    *error = "sync jitter must be in [0, 0.1] s";
    return false;
  }
  return true;
}

FiringPlanner::FiringPlanner(const std::vector<int>& slots, int slot_count,
                             const FiringPlanOptions& options)
    : options_(options), slot_count_(std::max(1, slot_count)), rng_(options.seed) {
  const double period_s = 1.0 / options_.rate_hz;
  frame_s_ = options_.mode == FiringPlanOptions::Mode::kTdma
                 ? std::max(period_s, slot_count_ * options_.slot_s)
                 : period_s;
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (int slot : slots) {
    State s;
    s.slot = slot;
    s.clock_error = (2.0 * unit(rng_) - 1.0) * options_.clock_ppm * 1e-6;
    const double phase_s = options_.mode == FiringPlanOptions::Mode::kTdma ? slot * options_.slot_s
                                                                           : unit(rng_) * period_s;
    s.next_utime = options_.start_utime + phase_s * 1e6 / (1.0 + s.clock_error);
    beacons_.push_back(s);
  }
}

size_t FiringPlanner::NextBeacon() const {
  size_t best = 0;
  for (size_t k = 1; k < beacons_.size(); ++k) {
    if (beacons_[k].next_utime < beacons_[best].next_utime) best = k;
  }
  return best;
}

int64_t FiringPlanner::NextUtime() const {
  if (beacons_.empty()) return std::numeric_limits<int64_t>::max();
  return static_cast<int64_t>(std::llround(beacons_[NextBeacon()].next_utime));
}

void FiringPlanner::Fire(bool announced) {
  if (beacons_.empty()) return;
  const size_t b = NextBeacon();
  State& fired = beacons_[b];
  const double t_us = fired.next_utime;
  // A beacon measures intervals on its own crystal: an interval of D on its
  // clock lasts D / (1 + error) of true time.
  fired.next_utime = t_us + frame_s_ * 1e6 / (1.0 + fired.clock_error);
  if (options_.mode != FiringPlanOptions::Mode::kTdma || !announced) return;
  std::uniform_real_distribution<double> jitter(-options_.sync_jitter_s, options_.sync_jitter_s);
  for (size_t k = 0; k < beacons_.size(); ++k) {
    if (k == b) continue;
    State& s = beacons_[k];
    double delay_s = (s.slot - fired.slot) * options_.slot_s;
    if (delay_s <= 0.0) delay_s += frame_s_;
    s.next_utime = t_us + (jitter(rng_) + delay_s / (1.0 + s.clock_error)) * 1e6;
  }
}

std::vector<int64_t> FiringPlanner::CatchUp(int64_t now_utime, int64_t max_behind_us) {
  std::vector<int64_t> skipped(beacons_.size(), 0);
  for (size_t k = 0; k < beacons_.size(); ++k) {
    State& s = beacons_[k];
    const double period_us = frame_s_ * 1e6 / (1.0 + s.clock_error);
    const double behind_us = now_utime - max_behind_us - s.next_utime;
    if (behind_us <= 0.0) continue;
    const int64_t n = static_cast<int64_t>(std::floor(behind_us / period_us)) + 1;
    s.next_utime += n * period_us;
    skipped[k] = n;
  }
  return skipped;
}

}  // namespace roomfix
