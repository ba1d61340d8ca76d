#include "trilat_proc/trilat_node.h"

#include <algorithm>
#include <cmath>
#include <iterator>
#include <limits>

#include "msgio/received.h"
#include "msgio/time_limits.h"
#include "msgio/trilat_conversions.h"
#include "roomfix/pose2d_t.hpp"
#include "roomfix/range_set_t.hpp"

namespace roomfix {

// Longer than any path in the room: its diagonal plus a margin for a
// receiver mounted on the outside of a wall and for calibration offsets.
constexpr double kRangeMargin_m = 0.5;
// A beacon rides on a robot, whose body keeps it at least its radius (over
// 0.1 m) from any wall, and a fix's noise is a few centimetres: a fix more
// than this beyond the walls (or below the floor, above the ceiling in 3D)
// is wrong, and is published LOST rather than steer anything there.
constexpr double kOutsideRoomMargin_m = 0.2;
// Beacons the site does not list are accepted only with
// unknown_beacon_height_m (a test bench); their warm-start state is then
// capped at this many ids, so a flood of invented ids cannot grow it.
constexpr size_t kMaxBeaconTracks = 256;
// Receiver positions in a message are copies of the site's (zigbee_bridge
// fills them in); more than this apart is a stale or foreign configuration.
constexpr double kReceiverPositionTolerance_m = 0.01;

bool TrilatNodeOptions::IsValid(std::string* error) const {
  if (!(warm_start_max_age_s >= 0.0)) {
    *error = "warm_start_max_age_s must not be negative";
    return false;
  }
  if (!(forget_after_s >= warm_start_max_age_s) || !std::isfinite(forget_after_s)) {
    *error = "forget_after_s must be finite and at least warm_start_max_age_s";
    return false;
  }
  if (use_prior && !prior.IsValid(error)) return false;
  if (use_nlos_belief && !nlos_belief.IsValid(error)) return false;
  if (!(merge_deadline_s > 0.0 && merge_deadline_s <= 10.0)) {
    *error = "merge_deadline_s must be in (0, 10]";
    return false;
  }
  trilat::SolverOptions probe = solver;
  probe.fixed_height_m = 0.0;  // Set per beacon.
  return probe.IsValid(error);
}

TrilatNode::TrilatNode(const Site& site, Bus* bus, const TrilatNodeOptions& options,
                       int64_t start_utime)
    : site_(site),
      bus_(bus),
      options_(options),
      status_("trilat_proc", start_utime),
      merger_(MergerOptions(site, options)) {
  const Room& room = site.room;
  max_range_m_ = std::sqrt(room.size_x_m * room.size_x_m + room.size_y_m * room.size_y_m +
                           room.height_m * room.height_m) +
                 kRangeMargin_m;
  options_.solver.max_range_m = std::min(options_.solver.max_range_m, max_range_m_);
  options_.nlos_belief.max_excess_m = max_range_m_;
  options_.nlos_belief.range_sigma_m = options_.solver.range_sigma_m;
  // A set never holds more ranges than the site has receivers (refused
  // before the solver), so the solver's own cap must not be lower.
  options_.solver.max_ranges =
      std::max(options_.solver.max_ranges, static_cast<int>(site.receivers.size()));
  subscriptions_.Add(bus_->Subscribe<range_set_t>(
      kRangesChannel,
      [this](const range_set_t& set, const MessageInfo& info) { OnRangeSet(set, info); }));
  status_.SetState(process_status_t::STATE_RUNNING);
}

bool TrilatNode::OutsideRoom(const Eigen::Vector3d& p) const {
  const Room& room = site_.room;
  const double m = kOutsideRoomMargin_m;
  const bool xy_out = !(p.x() >= room.min_x_m - m && p.x() <= room.min_x_m + room.size_x_m + m &&
                        p.y() >= room.min_y_m - m && p.y() <= room.min_y_m + room.size_y_m + m);
  const bool z_out = options_.solver.dimension == trilat::Dimension::k3D &&
                     !(p.z() >= -m && p.z() <= room.height_m + m);
  return xy_out || z_out;
}

void TrilatNode::OnRangeSet(const range_set_t& set, const MessageInfo& info) {
  status_.AddInputs();
  ranges_watch_.Seen(info.recv_utime, &status_);
  // The checks that need only the set itself run before it can enter a
  // merge, so a hostile part is refused before it holds any state; Solve
  // repeats them on what the merger releases.
  if (!Admissible(set, info)) return;
  ready_.clear();
  merger_.Add(set, info.recv_utime, &ready_);
  SolveReady();
}

RangeSetMergerOptions TrilatNode::MergerOptions(const Site& site,
                                                const TrilatNodeOptions& options) {
  RangeSetMergerOptions merger;
  merger.deadline_s = options.merge_deadline_s;
  merger.site_receivers = static_cast<int>(site.receivers.size());
  for (const RadioNetwork& radio : site.radios) {
    for (int id : radio.receiver_ids) merger.radio_of_receiver[id] = radio.id;
  }
  return merger;
}

bool TrilatNode::Admissible(const range_set_t& set, const MessageInfo& info) {
  std::string why;
  InputProblem problem = InputProblem::kNone;
  if (CheckRangeSet(set, site_, info.recv_utime, &why, &problem)) return true;
  status_.Reject(InputProblemCounter(problem));
  status_.SetError("range set from beacon " + std::to_string(set.beacon_id) + ": " + why,
                   info.recv_utime);
  return false;
}

void TrilatNode::SolveReady() {
  for (const RangeSetMerger::Ready& r : ready_) {
    MessageInfo info;
    info.channel = kRangesChannel;
    info.recv_utime = r.recv_utime;
    Solve(r.set, info);
  }
  ready_.clear();
  // Only a site fed by several bridges has parts; one bridge's STATUS (and
  // a replayed log's) stays as it was.
  if (merger_.counters().at("parts") == 0) return;
  for (const auto& [name, value] : merger_.counters()) status_.SetCounter("merge_" + name, value);
  status_.SetCounter("merge_open", static_cast<int64_t>(merger_.open()));
}

bool TrilatNode::ResolveBeacon(const range_set_t& set, const MessageInfo& info, SolveSetup* setup) {
  setup->solver = options_.solver;
  setup->robot_id = set.beacon_id;
  setup->prior = options_.prior;
  if (const Beacon* beacon = site_.FindBeacon(set.beacon_id)) {
    setup->solver.fixed_height_m = beacon->height_m;
    for (const Robot& robot : site_.robots) {
      if (robot.beacon_id && *robot.beacon_id == set.beacon_id) {
        setup->robot_id = robot.id;
        setup->prior.max_speed_mps = robot.max_speed_mps;
      }
    }
    return true;
  }
  if (std::isfinite(options_.unknown_beacon_height_m)) {
    setup->solver.fixed_height_m = options_.unknown_beacon_height_m;
    return true;
  }
  status_.Reject("unknown_beacon");
  status_.SetError("range set from beacon " + std::to_string(set.beacon_id) +
                       ", which the site file does not list",
                   info.recv_utime);
  return false;
}

bool TrilatNode::KeepUsableRanges(const range_set_t& set, const MessageInfo& info) {
  RangesFromMessage(set, &ranges_);
  // Ranges the node drops itself; the solver sees only the rest and drops
  // (and counts) its own: negative, too long, duplicate receiver.
  bool dropped_range = false;
  size_t kept = 0;
  for (size_t i = 0; i < ranges_.size(); ++i) {
    std::string why;
    InputProblem problem = InputProblem::kNone;
    const Receiver* receiver = CheckRange(set.ranges[i], site_, &why, &problem);
    if (receiver == nullptr) {
      status_.Reject(InputProblemCounter(problem));
      // A non-finite range is counted only; an unknown receiver is a site
      // that differs from the bridge's, worth the last error.
      if (problem == InputProblem::kUnknownReceiver) {
        status_.SetError("range set from beacon " + std::to_string(set.beacon_id) + ": " + why,
                         info.recv_utime);
      }
      dropped_range = true;
      continue;
    }
    // The site is the authority on where its receivers are; the message's
    // copy is only checked.
    const Eigen::Vector3d site_m(receiver->position_m[0], receiver->position_m[1],
                                 receiver->position_m[2]);
    if ((site_m - ranges_[i].receiver_m).norm() > kReceiverPositionTolerance_m) {
      status_.Count("receiver_position_mismatch");
    }
    ranges_[kept] = ranges_[i];
    ranges_[kept++].receiver_m = site_m;
  }
  ranges_.resize(kept);
  return dropped_range;
}

TrilatNode::BeaconTrack* TrilatNode::TrackOf(int beacon_id,
                                             const trilat::BeaconPriorOptions& prior) {
  auto found = tracks_.find(beacon_id);
  if (found == tracks_.end() && tracks_.size() < kMaxBeaconTracks) {
    found = tracks_.emplace(beacon_id, BeaconTrack()).first;
    found->second.prior = trilat::BeaconPrior(prior);
    found->second.belief = trilat::NlosBelief(options_.nlos_belief);
  }
  return found == tracks_.end() ? nullptr : &found->second;
}

void TrilatNode::SolveWithTrack(const range_set_t& set, const trilat::SolverOptions& solver,
                                BeaconTrack* track) {
  const bool warm = track != nullptr && track->has_fix && set.utime >= track->last_fix_utime &&
                    SaturatingDifferenceUs(set.utime, track->last_fix_utime) * 1e-6 <=
                        options_.warm_start_max_age_s;
  const trilat::PositionPrior* prior = nullptr;
  if (track != nullptr && options_.use_prior) {
    prior = track->prior.At(set.utime);
  }
  const std::vector<trilat::NlosSuspicion>* suspected = nullptr;
  if (track != nullptr && options_.use_nlos_belief) {
    suspected = &track->belief.Suspected(set.utime);
    for (const auto& s : *suspected) {
      status_.Count("suspected_receiver_" + std::to_string(s.receiver_id));
    }
  }
  trilat::Solve(ranges_, solver, warm ? &track->last_position_m : nullptr, prior, suspected, &fix_);
  if (warm) status_.Count("warm_starts");
}

void TrilatNode::CountFix() {
  for (const trilat::RejectedRange& r : fix_.rejected) {
    status_.Reject(trilat::RangeRejectionName(r.reason));
  }
  for (uint32_t bit = 1; bit <= trilat::kLastFixFlag; bit <<= 1) {
    if ((fix_.flags & bit) == 0) continue;
    const char* name = trilat::FixFlagName(static_cast<trilat::FixFlag>(bit));
    if (fix_.status == trilat::FixStatus::kFailed) {
      status_.Reject(name);
    } else if (bit != trilat::kBadRangesDropped) {  // Already counted per range.
      status_.Count(name);
    }
  }
}

const char* TrilatNode::LoseUnusableFix(const range_set_t& set, const MessageInfo& info) {
  if (!fix_.has_position()) return nullptr;
  const char* lost_reason = nullptr;
  if (!fix_.position_m.allFinite() || !fix_.covariance_m2.topLeftCorner<2, 2>().allFinite()) {
    lost_reason = "non_finite_fix";
  } else if (OutsideRoom(fix_.position_m)) {
    lost_reason = "outside_room";
  }
  if (lost_reason == nullptr) return nullptr;
  status_.Reject(lost_reason);
  status_.SetError(
      "beacon " + std::to_string(set.beacon_id) + " firing " + std::to_string(set.firing_seq) +
          ": fix at (" + std::to_string(fix_.position_m.x()) + ", " +
          std::to_string(fix_.position_m.y()) + ") published lost (" + lost_reason + ")",
      info.recv_utime);
  fix_.status = trilat::FixStatus::kFailed;
  fix_.position_m.setConstant(std::numeric_limits<double>::quiet_NaN());
  fix_.covariance_m2.setConstant(std::numeric_limits<double>::quiet_NaN());
  fix_.residual_rms_m = std::numeric_limits<double>::quiet_NaN();
  fix_.used.clear();
  return lost_reason;
}

void TrilatNode::Solve(const range_set_t& set, const MessageInfo& info) {
  // The merger released a set of parts that each passed; the merged set is
  // checked again as a whole (its count of ranges above all).
  if (!Admissible(set, info)) return;
  SolveSetup setup;
  if (!ResolveBeacon(set, info, &setup)) return;
  const bool dropped_range = KeepUsableRanges(set, info);
  BeaconTrack* track = TrackOf(set.beacon_id, setup.prior);
  SolveWithTrack(set, setup.solver, track);
  if (track != nullptr) track->last_recv_utime = info.recv_utime;
  if (dropped_range && fix_.status == trilat::FixStatus::kOk) {
    fix_.status = trilat::FixStatus::kDegraded;
  }
  if (dropped_range) fix_.flags |= trilat::kBadRangesDropped;
  CountFix();
  // What is published must be a finite position inside the room: anything
  // else goes out LOST, with the reason counted and in words.
  const char* lost_reason = LoseUnusableFix(set, info);
  // The beacon's state learns from what is published, a lost fix included.
  if (track != nullptr && options_.use_nlos_belief) track->belief.Observe(set.utime, ranges_, fix_);
  if (track != nullptr && options_.use_prior) {
    const trilat::BeaconPrior::Outcome outcome = track->prior.Observe(set.utime, fix_);
    if (outcome == trilat::BeaconPrior::Outcome::kReset) {
      status_.Count(trilat::BeaconPriorOutcomeName(outcome));
    }
  }
  if (fix_.has_position()) {
    for (const trilat::RejectedRange& r : fix_.rejected) {
      if (r.reason == trilat::RangeRejection::kOutlier) {
        status_.Count("outlier_receiver_" + std::to_string(r.receiver_id));
      }
    }
    if (track != nullptr) {
      track->has_fix = true;
      track->last_fix_utime = set.utime;
      track->last_position_m = fix_.position_m;
    }
    status_.AddOutputs();
  } else if (lost_reason == nullptr) {
    status_.SetError("beacon " + std::to_string(set.beacon_id) + " firing " +
                         std::to_string(set.firing_seq) + ": no position (" +
                         trilat::DescribeFlags(fix_.flags) + ")",
                     info.recv_utime);
  }
  if (!bus_->Publish(kUltrasoundPoseChannel,
                     PoseFromFix(fix_, set, setup.robot_id, info.recv_utime))) {
    status_.AddDropped();
  }
}

void TrilatNode::Tick(int64_t now_utime) {
  ready_.clear();
  merger_.Expire(now_utime, &ready_);
  if (!ready_.empty()) SolveReady();
  const auto forget_us = static_cast<int64_t>(options_.forget_after_s * 1e6);
  for (auto it = tracks_.begin(); it != tracks_.end();) {
    it = SaturatingDifferenceUs(now_utime, it->second.last_recv_utime) > forget_us
             ? tracks_.erase(it)
             : std::next(it);
  }
  status_.SetCounter("beacon_tracks", static_cast<int64_t>(tracks_.size()));
  // A new gap is reported at once, not at the next heartbeat.
  if (ranges_watch_.Check(now_utime, &status_)) {
    status_.Publish(bus_, now_utime);
    return;
  }
  status_.MaybePublish(bus_, now_utime);
}

void TrilatNode::Stop(int64_t now_utime) {
  ready_.clear();
  merger_.Flush(now_utime, &ready_);
  SolveReady();
  status_.SetState(process_status_t::STATE_STOPPING);
  status_.Publish(bus_, now_utime);
}

}  // namespace roomfix
