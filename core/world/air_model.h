#ifndef ROOMFIX_CORE_WORLD_AIR_MODEL_H_
#define ROOMFIX_CORE_WORLD_AIR_MODEL_H_

#include <cstdint>
#include <deque>
#include <random>
#include <string>
#include <vector>

#include "core/world/site.h"

namespace roomfix {

// Several beacons sharing the air of one room (docs/trilateration.md,
// "Sharing the air"): how long a pulse keeps the receivers busy, what a
// receiver measures when pulses overlap, and when each beacon fires.

// Absorption of sound by air, dB/m, at standard pressure (ISO 9613-1:1993,
// the pure-tone attenuation coefficient from oxygen and nitrogen relaxation
// plus the classical term). At 40 kHz and 20 degC it is 1.07 dB/m at 30%
// relative humidity, 1.32 dB/m at 50% and 1.29 dB/m at 70%.
double AirAbsorptionDbPerM(double frequency_hz, double temperature_c, double humidity_percent);

// How a room lets an ultrasonic pulse die away. All levels are dB above the
// receivers' detection threshold.
struct RoomDecay {
  double air_absorption_db_per_m = 0.0;
  // Sabine's reverberation time with the air's absorption:
  //   T60 = 24 ln(10) V / (c (S a + 4 m V)),
  // V the volume, S the surface, a the mean wall absorption, m = alpha /
  // (10 log10 e) the air's intensity attenuation per metre. Air alone bounds
  // it by 60 dB / (c alpha): 0.13 s at 1.3 dB/m, whatever the room's size.
  double reverberation_time_s = 0.0;
  // The longest direct path in the room (a receiver to the farthest corner)
  // and its time of flight.
  double max_range_m = 0.0;
  double max_time_of_flight_s = 0.0;
  // Level of the direct pulse 1 m from the beacon: the threshold sits
  // detection_margin_db below the weakest direct arrival, which has lost
  // 20 log10(r) by spreading and alpha r to the air at r = max_range_m.
  double level_at_1m_db = 0.0;
  // Level of the diffuse tail once the burst is over: the burst's energy P
  // tau spread over the volume, against the direct energy density P / (4 pi
  // c) at 1 m, i.e. level_at_1m_db + 10 log10(4 pi c tau / V).
  double tail_start_db = 0.0;
  // How long after a pulse's direct arrival a receiver stays above its
  // threshold: the burst, then the tail falling at 60 dB per T60 from
  // tail_start_db to 0 dB. The site's acoustics.decay_s replaces the
  // computed value when given.
  double decay_s = 0.0;
  bool decay_from_site = false;
  // A firing slot: the longest flight, the decay, the clock uncertainty.
  double slot_s = 0.0;
  // How long a receiver listens after the announcement: the longest flight
  // plus 5 ms (1.7 m of detours).
  double listen_s = 0.0;
};

RoomDecay ComputeRoomDecay(const Site& site, double temperature_c);

// What a receiver's detector reports for one firing.
//
// The model: a receiver arms its timer on the firing's announcement and
// reports the first time its envelope crosses the threshold. A pulse (any
// beacon's, the same beacon's earlier ones included) holds a receiver above
// threshold from its direct arrival for RoomDecay::decay_s. So, for a firing
// armed at t0 whose own pulse would arrive at t0 + tof:
//  - armed while another pulse still holds the receiver (its tail): the
//    diffuse tail's envelope fluctuates by several dB about its mean and
//    crosses the threshold at once: a time of flight near 0, which the
//    bridge drops as a range the room cannot hold (kArmedInTail);
//  - otherwise another pulse's direct arrival in [t0, t0 + tof): that
//    arrival is taken for this firing's: a wrong, early range (kEarly);
//  - otherwise its own arrival (kOwn), or nothing in the listening window
//    (kNone). Later arrivals do not matter: the detector has latched.
// Two firings close in time corrupt each other: the later one arms in the
// earlier one's tail, the earlier one takes the later one's pulse if it
// arrives first. Modelled for the direct path only (a detour's arrival
// carries less energy than the direct one) and with every pulse above the
// threshold at every receiver (the threshold's margin makes it so).
struct Detection {
  enum class Kind { kOwn, kEarly, kArmedInTail, kNone };
  Kind kind = Kind::kNone;
  // What the receiver's timer reads, s (meaningful unless kNone).
  double time_of_flight_s = 0.0;
  // The beacon whose pulse caused a kEarly or kArmedInTail.
  int interferer_beacon_id = 0;
  bool corrupted() const { return kind == Kind::kEarly || kind == Kind::kArmedInTail; }
};
const char* DetectionKindName(Detection::Kind kind);

// One firing's sound in the room: when it left and when its direct path
// reaches each receiver (site receiver order).
struct AirPulse {
  int64_t fire_utime = 0;
  int beacon_id = 0;
  int64_t seq = 0;
  // Direct-path time of flight to each receiver, s.
  std::vector<double> arrival_s;
};

// The pulses in the air, and what each receiver makes of a firing among
// them. Pure: the caller adds every pulse fired up to at least fire_utime +
// listen_s before asking about a firing at fire_utime.
class AirChannel {
 public:
  AirChannel(double decay_s, double listen_s);
  void Add(const AirPulse& pulse);
  // Receiver i alone would measure own_tof_s[i] (noise and detours; NaN when
  // it hears nothing); returns what it reports with the other pulses around.
  std::vector<Detection> Detect(const AirPulse& pulse, const std::vector<double>& own_tof_s) const;
  // Drops pulses that can no longer touch a firing at or after utime.
  void ForgetBefore(int64_t utime);
  size_t size() const { return pulses_.size(); }

 private:
  double decay_s_;
  double listen_s_;
  std::deque<AirPulse> pulses_;
};

// When each beacon fires.
//
// kTdma (the schedule roomfix uses, docs/radio_protocol.md, "Firing
// schedule"): the site's beacons in file order own consecutive slots of
// RoomDecay::slot_s in a frame of max(n slot, 1 / rate_hz). A beacon counts
// its slot from the last announcement it heard (any beacon's: the radio
// broadcast that starts the receivers' timers, timed to sync_jitter_s), on
// its own crystal; without announcements it keeps its own time, drifting by
// its crystal error.
// kFreeRunning: each beacon at rate_hz on its own crystal from a random
// phase, as the reference's beacons would if there were several.
struct FiringPlanOptions {
  enum class Mode { kTdma, kFreeRunning };
  Mode mode = Mode::kTdma;
  double rate_hz = 10.0;
  double slot_s = 0.05;
  // Each beacon's crystal is off by a uniform draw in +-clock_ppm.
  double clock_ppm = 50.0;
  // Error of a beacon's time stamp of a heard announcement, uniform +-, s.
  double sync_jitter_s = 20e-6;
  uint64_t seed = 1;
  int64_t start_utime = 0;

  bool IsValid(std::string* error) const;
};

class FiringPlanner {
 public:
  // `slots`: each beacon's slot index (kTdma), in [0, slot_count).
  FiringPlanner(const std::vector<int>& slots, int slot_count, const FiringPlanOptions& options);
  // The next firing: the beacon's index (as given) and its time.
  size_t NextBeacon() const;
  int64_t NextUtime() const;
  // Takes the next firing; `announced`: the other beacons heard its
  // announcement (kTdma resynchronises them on it).
  void Fire(bool announced);
  // A beacon whose next firing is more than max_behind_us before now skips
  // whole periods to the first at or after now - max_behind_us; returns how
  // many firings each beacon skipped.
  std::vector<int64_t> CatchUp(int64_t now_utime, int64_t max_behind_us);
  double frame_s() const { return frame_s_; }
  double clock_error(size_t beacon) const { return beacons_[beacon].clock_error; }

 private:
  struct State {
    int slot = 0;
    double clock_error = 0.0;
    double next_utime = 0.0;
  };
  FiringPlanOptions options_;
  int slot_count_;
  double frame_s_;
  std::mt19937_64 rng_;
  std::vector<State> beacons_;
};

}  // namespace roomfix

#endif  // ROOMFIX_CORE_WORLD_AIR_MODEL_H_
