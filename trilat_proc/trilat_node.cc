#include "trilat_proc/trilat_node.h"

#include <cmath>

#include "msgio/trilat_conversions.h"
#include "roomfix/pose2d_t.hpp"

namespace roomfix {

// Longer than any path in the room: its diagonal plus a margin for a
// receiver mounted on the outside of a wall and for calibration offsets.
constexpr double kRangeMargin_m = 0.5;

bool TrilatNodeOptions::IsValid(std::string* error) const {
  if (!(warm_start_max_age_s >= 0.0)) {
    *error = "warm_start_max_age_s must not be negative";
    return false;
  }
  trilat::SolverOptions probe = solver;
  probe.fixed_height_m = 0.0;  // Set per beacon.
  return probe.IsValid(error);
}

TrilatNode::TrilatNode(const Site& site, Bus* bus, const TrilatNodeOptions& options,
                       int64_t start_utime)
    : site_(site), bus_(bus), options_(options), status_("trilat_proc", start_utime) {
  const Room& room = site.room;
  max_range_m_ = std::sqrt(room.size_x_m * room.size_x_m + room.size_y_m * room.size_y_m +
                           room.height_m * room.height_m) +
                 kRangeMargin_m;
  options_.solver.max_range_m = std::min(options_.solver.max_range_m, max_range_m_);
  bus_->Subscribe<range_set_t>(
      kRangesChannel,
      [this](const range_set_t& set, const MessageInfo& info) { OnRangeSet(set, info); });
  status_.SetState(process_status_t::STATE_RUNNING);
}

void TrilatNode::OnRangeSet(const range_set_t& set, const MessageInfo& info) {
  status_.AddInputs();
  ranges_watch_.Seen(info.recv_utime, &status_);
  trilat::SolverOptions solver = options_.solver;
  int32_t robot_id = set.beacon_id;
  if (const Beacon* beacon = site_.FindBeacon(set.beacon_id)) {
    solver.fixed_height_m = beacon->height_m;
    for (const Robot& robot : site_.robots) {
      if (robot.beacon_id && *robot.beacon_id == set.beacon_id) robot_id = robot.id;
    }
  } else if (std::isfinite(options_.unknown_beacon_height_m)) {
    solver.fixed_height_m = options_.unknown_beacon_height_m;
  } else {
    status_.Reject("unknown_beacon");
    status_.SetError("range set from beacon " + std::to_string(set.beacon_id) +
                         ", which the site file does not list",
                     info.recv_utime);
    return;
  }

  RangesFromMessage(set, &ranges_);
  BeaconTrack& track = tracks_[set.beacon_id];
  const bool warm = track.has_fix && set.utime >= track.last_fix_utime &&
                    (set.utime - track.last_fix_utime) * 1e-6 <= options_.warm_start_max_age_s;
  trilat::Solve(ranges_, solver, warm ? &track.last_position_m : nullptr, &fix_);
  if (warm) status_.Count("warm_starts");

  for (const trilat::RejectedRange& r : fix_.rejected) {
    status_.Reject(trilat::RangeRejectionName(r.reason));
  }
  for (uint32_t bit = 1; bit <= trilat::kMirrorResolved; bit <<= 1) {
    if ((fix_.flags & bit) == 0) continue;
    const char* name = trilat::FixFlagName(static_cast<trilat::FixFlag>(bit));
    if (fix_.status == trilat::FixStatus::kFailed) {
      status_.Reject(name);
    } else if (bit != trilat::kBadRangesDropped) {  // Already counted per range.
      status_.Count(name);
    }
  }
  if (fix_.has_position()) {
    track.has_fix = true;
    track.last_fix_utime = set.utime;
    track.last_position_m = fix_.position_m;
    status_.AddOutputs();
  } else {
    status_.SetError("beacon " + std::to_string(set.beacon_id) + " firing " +
                         std::to_string(set.firing_seq) + ": no position (" +
                         trilat::DescribeFlags(fix_.flags) + ")",
                     info.recv_utime);
  }
  if (!bus_->Publish(kUltrasoundPoseChannel, PoseFromFix(fix_, set, robot_id, info.recv_utime))) {
    status_.AddDropped();
  }
}

void TrilatNode::Tick(int64_t now_utime) {
  // A new gap is reported at once, not at the next heartbeat.
  if (ranges_watch_.Check(now_utime, &status_)) {
    status_.Publish(bus_, now_utime);
    return;
  }
  status_.MaybePublish(bus_, now_utime);
}

void TrilatNode::Stop(int64_t now_utime) {
  status_.SetState(process_status_t::STATE_STOPPING);
  status_.Publish(bus_, now_utime);
}

}  // namespace roomfix
