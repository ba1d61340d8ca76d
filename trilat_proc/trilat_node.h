#ifndef ROOMFIX_TRILAT_PROC_TRILAT_NODE_H_
#define ROOMFIX_TRILAT_PROC_TRILAT_NODE_H_

#include <cstdint>
#include <limits>
#include <string>
#include <unordered_map>
#include <vector>

#include "core/trilat/beacon_prior.h"
#include "core/trilat/nlos_belief.h"
#include "core/trilat/trilateration.h"
#include "core/world/site.h"
#include "msgio/bus.h"
#include "msgio/channels.h"
#include "msgio/lcm_types_fwd.h"
#include "msgio/process.h"
#include "msgio/subscriptions.h"
#include "trilat_proc/range_set_merger.h"

namespace roomfix {

struct TrilatNodeOptions {
  // Method, dimension and noise model. In kFixedHeight2D the height of each
  // beacon comes from the site file (fixed_height_m is ignored).
  trilat::SolverOptions solver;
  // The previous fix of a beacon seeds the next solve when it is at most
  // this old (by firing time); a robot moves little in half a second.
  double warm_start_max_age_s = 0.5;
  // Height for beacons the site file does not list; NaN refuses them
  // (counted as unknown_beacon).
  double unknown_beacon_height_m = std::numeric_limits<double>::quiet_NaN();
  // A beacon's warm-start state is forgotten after this long without a range
  // set from it (receive clock), so ids that stop cost nothing.
  double forget_after_s = 10.0;
  // The temporal prior per beacon (core/trilat/beacon_prior.h);
  // max_speed_mps is replaced by the site's robots[].max_speed_mps for the
  // robot carrying the beacon. use_prior false solves each set alone.
  trilat::BeaconPriorOptions prior;
  bool use_prior = true;
  // The NLOS belief per beacon and receiver (core/trilat/nlos_belief.h);
  // max_excess_m is replaced by the room's diagonal and range_sigma_m by
  // the solver's. use_nlos_belief false solves without it.
  trilat::NlosBeliefOptions nlos_belief;
  bool use_nlos_belief = true;
  // A firing's parts from several coordinators' bridges (zigbee_bridge
  // --radio) are joined before solving; a part whose siblings have not all
  // come this long after it is solved with what came.
  // The default covers a bridge that publishes at its own 50 ms deadline
  // while the other part came at once, plus the network.
  double merge_deadline_s = 0.1;

  bool IsValid(std::string* error) const;
};

// Turns each range_set_t on RANGES into a pose2d_t on POSE_ULTRASOUND.
//
// Time is the messages' own: the pose is valid at the firing time, the
// warm start's age is measured between firings, and "now" is the receive
// time of the range set, so replaying a log gives the recorded poses bit for
// bit. Every range set gets a pose, a lost one (NaN position) when it could
// not be solved; why is counted in STATUS: per range ("negative_range",
// "outlier", ...) and per set ("too_few_ranges", "collinear_receivers",
// "unknown_beacon", ...).
//
// Limits (docs/trilateration.md, "Limits"): a set whose utime is more than
// kMaxUtimeSkewUs from its receive time, or with a non-finite speed of sound
// or temperature, is refused whole (utime_out_of_range, non_finite), as is a
// set with more ranges than the site has receivers (too_many_ranges), so the
// solver's work per message is bounded by the site. A range from a receiver
// the site does not list (unknown_receiver) or with a non-finite field
// (non_finite) is dropped and the pose is at best DEGRADED. A fix outside
// the room (kOutsideRoomMargin_m) or without a finite covariance is
// published LOST with the reason (outside_room, non_finite_fix).
//
// Receiver positions are the site's, by receiver id: a position carried in
// the message that differs from the site's by more than a centimetre is
// counted (receiver_position_mismatch) and not used.
//
// Each beacon has a temporal prior (core/trilat/beacon_prior.h) that the
// robust solver uses to identify long ranges; which ranges were excluded is
// counted per receiver (outlier_receiver_<id>), and the prior's resets are
// counted (prior_resets). Each beacon also has an NLOS belief per receiver
// (core/trilat/nlos_belief.h): the receivers it suspects are handed to the
// solver, and each set a receiver was suspected in is counted
// (suspected_receiver_<id>).
//
// Range sets from bridges that each read one of several coordinators
// (num_expected below the site's receiver count) are parts: RangeSetMerger
// joins a firing's parts by (beacon, firing number, time) before solving,
// counted as merge_parts, merge_complete, merge_deadline,
// merge_duplicate_receiver, with merge_open the parts waiting.
class TrilatNode {
 public:
  TrilatNode(const Site& site, Bus* bus, const TrilatNodeOptions& options, int64_t start_utime);

  void Tick(int64_t now_utime);
  void Stop(int64_t now_utime);
  const StatusReporter& status() const { return status_; }
  // Beacons with warm-start state (expire after forget_after_s).
  size_t beacon_tracks() const { return tracks_.size(); }

 private:
  struct BeaconTrack {
    int64_t last_recv_utime = 0;
    int64_t last_fix_utime = 0;
    // Meaningful only when has_fix; zero rather than uninitialised, since a
    // new track is moved into the map (GCC 12 -O3: -Wmaybe-uninitialized).
    Eigen::Vector3d last_position_m = Eigen::Vector3d::Zero();
    bool has_fix = false;
    trilat::BeaconPrior prior;
    trilat::NlosBelief belief;
  };

  // What a set is solved with: the solver's and the prior's options for its
  // beacon, and the robot that carries it.
  struct SolveSetup {
    trilat::SolverOptions solver;
    trilat::BeaconPriorOptions prior;
    int32_t robot_id = -1;
  };

  void OnRangeSet(const range_set_t& set, const MessageInfo& info);
  // One set the merger released: checked, solved, counted and published.
  void Solve(const range_set_t& set, const MessageInfo& info);
  // The steps of Solve. The beacon's height and robot from the site (or
  // unknown_beacon_height_m); false, counted, when neither has it.
  bool ResolveBeacon(const range_set_t& set, const MessageInfo& info, SolveSetup* setup);
  // ranges_ = the set's usable ranges at the site's receiver positions;
  // true when any was dropped (counted per range).
  bool KeepUsableRanges(const range_set_t& set, const MessageInfo& info);
  // The beacon's warm-start state, created on first use; nullptr once
  // kMaxBeaconTracks beacons have one (the set is then solved cold).
  BeaconTrack* TrackOf(int beacon_id, const trilat::BeaconPriorOptions& prior);
  // fix_ = ranges_ solved, warm-started, with the track's prior and NLOS
  // suspicions when it has them.
  void SolveWithTrack(const range_set_t& set, const trilat::SolverOptions& solver,
                      BeaconTrack* track);
  // Counts the fix's rejected ranges and flags.
  void CountFix();
  // A fix that is not a finite position inside the room becomes LOST; the
  // reason (counted, and in the last error), or nullptr when it is usable.
  const char* LoseUnusableFix(const range_set_t& set, const MessageInfo& info);
  void SolveReady();
  // True when the fix is outside the room by more than the margin.
  bool OutsideRoom(const Eigen::Vector3d& position_m) const;

  const Site& site_;
  Bus* bus_;
  TrilatNodeOptions options_;
  StatusReporter status_;
  // RANGES come at 10 Hz per beacon: a second without any is a dead bridge.
  InputWatch ranges_watch_{"range sets on RANGES", 1.0};
  double max_range_m_ = 0.0;
  std::unordered_map<int, BeaconTrack> tracks_;
  static RangeSetMergerOptions MergerOptions(const Site& site, const TrilatNodeOptions& options);
  // The checks a set passes before it is merged or solved (refused and
  // counted otherwise).
  bool Admissible(const range_set_t& set, const MessageInfo& info);
  RangeSetMerger merger_;
  std::vector<RangeSetMerger::Ready> ready_;
  std::vector<trilat::RangeMeasurement> ranges_;
  trilat::Fix fix_;
  // Last: ended first, before anything the handlers use.
  Subscriptions subscriptions_{bus_};
};

}  // namespace roomfix

#endif  // ROOMFIX_TRILAT_PROC_TRILAT_NODE_H_
