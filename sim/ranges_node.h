#ifndef ROOMFIX_SIM_RANGES_NODE_H_
#define ROOMFIX_SIM_RANGES_NODE_H_

#include <cstdint>
#include <random>
#include <string>

#include "core/world/site.h"
#include "core/world/ultrasound_model.h"
#include "msgio/bus.h"
#include "msgio/process.h"
#include "sim/shared_air.h"

namespace roomfix {

struct SimRangesNodeOptions {
  // Firings per second of each beacon (the reference fired at 10 Hz); under
  // the TDMA schedule at most one per frame of (site beacons x slot).
  double rate_hz = 10.0;
  // As the virtual wall devices: the schedule, the beacons' crystals and the
  // room's collisions (core/world/air_model.h).
  FiringPlanOptions::Mode schedule = FiringPlanOptions::Mode::kTdma;
  double clock_ppm = 50.0;
  bool collisions = true;
  UltrasoundNoise noise;
  // Time from a firing to its range set being published: the last echo's
  // flight plus the radio's delivery.
  double publish_delay_s = 0.03;
  uint64_t seed = 1;
  int64_t start_utime = 0;

  bool IsValid(std::string* error) const;
};

// An ideal radio side: publishes, for each simulated robot that carries a
// beacon, one range_set_t per firing on RANGES, with ranges from the
// ground-truth trajectory, the site geometry and the noise model. It stands
// in for the virtual wall devices and zigbee_bridge until those exist, and
// lets trilat_proc run end to end on any machine.
//
// Beacons fire on the site's TDMA table (docs/radio_protocol.md, "Firing
// schedule") or free-running, and their pulses collide in the room's air as
// for the virtual wall devices: a receiver that timed another beacon's pulse
// gives a wrong range (kept: trilat_proc must cope), one armed inside a tail
// reads a time of flight near 0, which the bridge would refuse (dropped
// here too). Counted in air().counters().
class SimRangesNode {
 public:
  SimRangesNode(const Site& site, Bus* bus, const SimRangesNodeOptions& options);
  void Tick(int64_t now_utime);
  int64_t firings() const { return firings_; }
  const SharedAir& air() const { return air_; }

 private:
  struct Firer {
    int robot_id;
    const Beacon* beacon;
    const Trajectory* trajectory;
    int64_t next_seq = 0;
  };
  static std::vector<Firer> MakeFirers(const Site& site);
  const Site& site_;
  Bus* bus_;
  SimRangesNodeOptions options_;
  std::vector<Firer> firers_;
  SharedAir air_;
  std::mt19937_64 rng_;
  int64_t firings_ = 0;
};

}  // namespace roomfix

#endif  // ROOMFIX_SIM_RANGES_NODE_H_
