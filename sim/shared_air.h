#ifndef ROOMFIX_SIM_SHARED_AIR_H_
#define ROOMFIX_SIM_SHARED_AIR_H_

#include <cstdint>
#include <deque>
#include <functional>
#include <random>
#include <string>
#include <vector>

#include "core/world/air_model.h"
#include "core/world/site.h"

namespace roomfix {

// The simulated beacons' firing times and the room's air they share: the
// glue between core/world/air_model.h and the two simulated radio paths
// (VirtualWallDevices, SimRangesNode), so both fire and collide alike.
struct SharedAirOptions {
  // kTdma: the site-file TDMA table, resynchronised on heard announcements;
  // kFreeRunning: each beacon at rate_hz on its own crystal.
  FiringPlanOptions::Mode mode = FiringPlanOptions::Mode::kTdma;
  // Each beacon's rate; under kTdma at most 1 / (beacons x slot).
  double rate_hz = 10.0;
  double clock_ppm = 50.0;
  double sync_jitter_s = 20e-6;
  // Probability that the other beacons miss a firing's announcement (they
  // keep their own time until the next).
  double sync_loss_probability = 0.0;
  // Pulses overlap as the room says (false: every receiver hears only its
  // own beacon, and the TDMA frame is the period shared out among the
  // beacons whatever the room's decay, as before the collision model).
  bool collisions = true;
  uint64_t seed = 1;
  int64_t start_utime = 0;

  bool IsValid(std::string* error) const;
};

// What the air counted, per (firing, receiver) pair.
struct AirCounters {
  int64_t firings = 0;
  int64_t pairs = 0;
  int64_t own = 0;
  int64_t early = 0;
  int64_t armed_in_tail = 0;
  int64_t none = 0;
  int64_t corrupted() const { return early + armed_in_tail; }
};

// A beacon a simulated robot carries: its emitter follows the robot's
// trajectory (t = 0 at SharedAirOptions::start_utime) at the beacon's height.
struct CarriedBeacon {
  int robot_id = 0;
  const Beacon* beacon = nullptr;
  const Trajectory* trajectory = nullptr;
};

// The site's simulated robots that carry a beacon, in the simulation's
// order: the firers of both simulated radio paths.
std::vector<CarriedBeacon> CarriedBeacons(const Site& site);

class SharedAir {
 public:
  // One firer per entry of beacon_ids (its slot is the beacon's position in
  // the site's beacons list); positions_m gives a firer's emitter at a time.
  using PositionFn = std::function<std::array<double, 3>(size_t firer, int64_t utime)>;
  SharedAir(const Site& site, const std::vector<int>& beacon_ids, PositionFn position,
            const SharedAirOptions& options);
  // One firer per carried beacon, in order, placed by its trajectory.
  SharedAir(const Site& site, std::vector<CarriedBeacon> beacons, const SharedAirOptions& options);

  struct Firing {
    size_t firer = 0;
    int64_t fire_utime = 0;
    // Firings the beacon skipped (a process stopped and resumed) before this.
    int64_t skipped_before = 0;
    // The beacon is switched off (a simulated restart): no sound, no radio.
    bool silent = false;
    AirPulse pulse;
  };
  // Firings whose time is at or before now_utime, in time order. `silent`
  // says which firings a beacon misses (restarts); may be empty.
  std::vector<Firing> TakeDue(int64_t now_utime,
                              const std::function<bool(size_t, int64_t)>& silent = nullptr);
  // What each receiver (site order) reports for a firing from TakeDue, given
  // what it would measure alone (NaN: nothing heard); counted.
  std::vector<Detection> Detect(const Firing& firing, const std::vector<double>& own_tof_s);

  const RoomDecay& decay() const { return decay_; }
  const AirCounters& counters() const { return counters_; }
  double frame_s() const { return planner_.frame_s(); }
  // Firings per second of each beacon.
  double rate_hz() const { return 1.0 / planner_.frame_s(); }

 private:
  void PlanUntil(int64_t utime, const std::function<bool(size_t, int64_t)>& silent);

  const Site& site_;
  PositionFn position_;
  SharedAirOptions options_;
  RoomDecay decay_;
  std::vector<int> beacon_ids_;
  FiringPlanner planner_;
  AirChannel channel_;
  std::mt19937_64 rng_;
  std::deque<Firing> planned_;
  std::vector<int64_t> skipped_;
  int64_t next_pulse_seq_ = 0;
  AirCounters counters_;
};

// The air of a site with n stationary beacons at random places (uniform
// over the floor, at the height of the site's first beacon or 1 m), fired
// for duration_s: what `roomfix_sim --air-bench` prints per row.
struct AirBenchRow {
  int beacons = 0;
  FiringPlanOptions::Mode mode = FiringPlanOptions::Mode::kTdma;
  double rate_per_beacon_hz = 0.0;
  AirCounters counters;
  // Firings with at least one corrupted range, and the clean ones per
  // second per beacon (every range its own beacon's).
  int64_t corrupted_firings = 0;
  double clean_rate_per_beacon_hz = 0.0;
  double corrupted_share() const {
    return counters.pairs > 0 ? static_cast<double>(counters.corrupted()) / counters.pairs : 0.0;
  }
};
AirBenchRow MeasureAir(const Site& site, int beacons, const SharedAirOptions& options,
                       double duration_s);

// The slot of each beacon id: its index in the site's beacons list.
std::vector<int> TdmaSlots(const Site& site, const std::vector<int>& beacon_ids);

}  // namespace roomfix

#endif  // ROOMFIX_SIM_SHARED_AIR_H_
