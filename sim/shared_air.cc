#include "sim/shared_air.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/world/ultrasound_model.h"

namespace roomfix {

bool SharedAirOptions::IsValid(std::string* error) const {
  if (!(rate_hz > 0.0 && rate_hz <= 1000.0)) {
    *error = "firing rate must be in (0, 1000] Hz";
    return false;
  }
  if (!(clock_ppm >= 0.0 && clock_ppm <= 10000.0)) {
    *error = "beacon clock error must be in [0, 10000] ppm";
    return false;
  }
  if (!(sync_jitter_s >= 0.0 && sync_jitter_s <= 0.01)) {
    *error = "sync jitter must be in [0, 0.01] s";
    return false;
  }
  if (!(sync_loss_probability >= 0.0 && sync_loss_probability <= 1.0)) {
    *error = "sync loss probability must be in [0, 1]";
    return false;
  }
  return true;
}

std::vector<int> TdmaSlots(const Site& site, const std::vector<int>& beacon_ids) {
  std::vector<int> slots;
  for (int id : beacon_ids) {
    int slot = 0;
    for (size_t k = 0; k < site.beacons.size(); ++k) {
      if (site.beacons[k].id == id) slot = static_cast<int>(k);
    }
    slots.push_back(slot);
  }
  return slots;
}

namespace {

FiringPlanOptions PlanOptions(const SharedAirOptions& options, const RoomDecay& decay,
                              size_t site_beacons) {
  FiringPlanOptions plan;
  plan.mode = options.mode;
  plan.rate_hz = options.rate_hz;
  // Without collisions (an ideal air, for load tests at many times the real
  // rate) the beacons only take turns within the period, as before the
  // model: the slot no longer bounds the rate.
  plan.slot_s =
      options.collisions
          ? decay.slot_s
          : 1.0 / (options.rate_hz * static_cast<double>(std::max<size_t>(1, site_beacons)));
  plan.clock_ppm = options.clock_ppm;
  plan.sync_jitter_s = options.sync_jitter_s;
  // The planner's generator is its own, so that the schedule does not move
  // the noise draws of the radio paths.
  plan.seed = options.seed * 0x9E3779B97F4A7C15ull + 7;
  plan.start_utime = options.start_utime;
  return plan;
}

}  // namespace

SharedAir::SharedAir(const Site& site, const std::vector<int>& beacon_ids, PositionFn position,
                     const SharedAirOptions& options)
    : site_(site),
      position_(std::move(position)),
      options_(options),
      decay_(ComputeRoomDecay(site, site.simulation.temperature_c)),
      beacon_ids_(beacon_ids),
      planner_(TdmaSlots(site, beacon_ids), static_cast<int>(site.beacons.size()),
               PlanOptions(options, decay_, site.beacons.size())),
      channel_(decay_.decay_s, decay_.listen_s),
      rng_(options.seed ^ 0x5A17A11ull),
      skipped_(beacon_ids.size(), 0) {}

namespace {

std::vector<int> BeaconIds(const std::vector<CarriedBeacon>& beacons) {
  std::vector<int> ids;
  for (const CarriedBeacon& b : beacons) ids.push_back(b.beacon->id);
  return ids;
}

}  // namespace

SharedAir::SharedAir(const Site& site, std::vector<CarriedBeacon> beacons,
                     const SharedAirOptions& options)
    : SharedAir(
          site, BeaconIds(beacons),
          [beacons, start_utime = options.start_utime](size_t firer,
                                                       int64_t utime) -> std::array<double, 3> {
            const CarriedBeacon& b = beacons[firer];
            const GroundTruthPose p = b.trajectory->PoseAt((utime - start_utime) * 1e-6);
            return {p.x_m, p.y_m, b.beacon->height_m};
          },
          options) {}

std::vector<CarriedBeacon> CarriedBeacons(const Site& site) {
  std::vector<CarriedBeacon> beacons;
  for (const SimulatedRobot& sr : site.simulation.robots) {
    const Robot* robot = site.FindRobot(sr.robot_id);
    if (robot == nullptr || !robot->beacon_id) continue;
    beacons.push_back({sr.robot_id, site.FindBeacon(*robot->beacon_id), sr.trajectory.get()});
  }
  return beacons;
}

void SharedAir::PlanUntil(int64_t utime, const std::function<bool(size_t, int64_t)>& silent) {
  const double c = SpeedOfSound(site_.simulation.temperature_c);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  while (!beacon_ids_.empty() && planner_.NextUtime() <= utime) {
    Firing f;
    f.firer = planner_.NextBeacon();
    f.fire_utime = planner_.NextUtime();
    f.skipped_before = skipped_[f.firer];
    skipped_[f.firer] = 0;
    f.silent = silent && silent(f.firer, f.fire_utime);
    f.pulse.fire_utime = f.fire_utime;
    f.pulse.beacon_id = beacon_ids_[f.firer];
    // Identifies the pulse in the channel (a firing is not its own
    // interferer); unique over the run.
    f.pulse.seq = next_pulse_seq_++;
    const std::array<double, 3> at = position_(f.firer, f.fire_utime);
    for (const Receiver& r : site_.receivers) {
      f.pulse.arrival_s.push_back(
          std::hypot(r.position_m[0] - at[0], r.position_m[1] - at[1], r.position_m[2] - at[2]) /
          c);
    }
    if (!f.silent && options_.collisions) channel_.Add(f.pulse);
    const bool heard = !f.silent && !(options_.sync_loss_probability > 0.0 &&
                                      unit(rng_) < options_.sync_loss_probability);
    planner_.Fire(heard);
    planned_.push_back(std::move(f));
  }
}

std::vector<SharedAir::Firing> SharedAir::TakeDue(
    int64_t now_utime, const std::function<bool(size_t, int64_t)>& silent) {
  // A beacon that was not running (a start time in the past, a process
  // stopped and continued) does not replay every firing it missed in one
  // burst: it resumes within half a second of now.
  constexpr int64_t kMaxCatchUpUs = 500'000;
  const std::vector<int64_t> skipped = planner_.CatchUp(now_utime, kMaxCatchUpUs);
  for (size_t k = 0; k < skipped.size(); ++k) skipped_[k] += skipped[k];
  // A firing's detections depend on every pulse fired up to its listening
  // window's end: plan that far ahead.
  PlanUntil(now_utime + static_cast<int64_t>(std::ceil(decay_.listen_s * 1e6)), silent);
  std::vector<Firing> due;
  while (!planned_.empty() && planned_.front().fire_utime <= now_utime) {
    due.push_back(std::move(planned_.front()));
    planned_.pop_front();
  }
  return due;
}

std::vector<Detection> SharedAir::Detect(const Firing& firing,
                                         const std::vector<double>& own_tof_s) {
  std::vector<Detection> out;
  if (options_.collisions) {
    out = channel_.Detect(firing.pulse, own_tof_s);
    channel_.ForgetBefore(firing.fire_utime);
  } else {
    out.resize(own_tof_s.size());
    for (size_t i = 0; i < own_tof_s.size(); ++i) {
      if (std::isfinite(own_tof_s[i])) {
        out[i].kind = Detection::Kind::kOwn;
        out[i].time_of_flight_s = own_tof_s[i];
      }
    }
  }
  ++counters_.firings;
  for (const Detection& d : out) {
    ++counters_.pairs;
    switch (d.kind) {
      case Detection::Kind::kOwn:
        ++counters_.own;
        break;
      case Detection::Kind::kEarly:
        ++counters_.early;
        break;
      case Detection::Kind::kArmedInTail:
        ++counters_.armed_in_tail;
        break;
      case Detection::Kind::kNone:
        ++counters_.none;
        break;
    }
  }
  return out;
}

AirBenchRow MeasureAir(const Site& site, int beacons, const SharedAirOptions& options,
                       double duration_s) {
  Site bench = site;
  bench.beacons.clear();
  const double height_m = site.beacons.empty() ? 1.0 : site.beacons[0].height_m;
  std::mt19937_64 place(options.seed * 31 + static_cast<uint64_t>(beacons));
  std::uniform_real_distribution<double> ux(site.room.min_x_m,
                                            site.room.min_x_m + site.room.size_x_m);
  std::uniform_real_distribution<double> uy(site.room.min_y_m,
                                            site.room.min_y_m + site.room.size_y_m);
  std::vector<int> ids;
  std::vector<std::array<double, 3>> at;
  for (int k = 0; k < beacons; ++k) {
    Beacon b;
    b.id = k + 1;
    b.address = 0x0013A20050000000ull + static_cast<uint64_t>(k);
    b.height_m = height_m;
    bench.beacons.push_back(b);
    ids.push_back(b.id);
    at.push_back({ux(place), uy(place), height_m});
  }
  SharedAir air(
      bench, ids, [&](size_t firer, int64_t) { return at[firer]; }, options);
  AirBenchRow row;
  row.beacons = beacons;
  row.mode = options.mode;
  row.rate_per_beacon_hz = air.rate_hz();
  int64_t clean = 0;
  const int64_t end_utime = options.start_utime + static_cast<int64_t>(duration_s * 1e6);
  // In steps of 0.1 s, as a running simulator ticks (a jump of more than
  // 0.5 s would count as a stopped process and skip firings).
  for (int64_t now = options.start_utime; now < end_utime;) {
    now = std::min(end_utime - 1, now + 100'000);
    for (const SharedAir::Firing& f : air.TakeDue(now)) {
      const std::vector<Detection> d = air.Detect(f, f.pulse.arrival_s);
      bool bad = false;
      for (const Detection& x : d) bad = bad || x.corrupted();
      if (bad) {
        ++row.corrupted_firings;
      } else {
        ++clean;
      }
    }
    if (now == end_utime - 1) break;
  }
  row.counters = air.counters();
  row.clean_rate_per_beacon_hz = beacons > 0 ? clean / (duration_s * beacons) : 0.0;
  return row;
}

}  // namespace roomfix
