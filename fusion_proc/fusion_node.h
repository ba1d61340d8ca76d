#ifndef ROOMFIX_FUSION_PROC_FUSION_NODE_H_
#define ROOMFIX_FUSION_PROC_FUSION_NODE_H_

#include <array>
#include <cstdint>
#include <map>
#include <set>
#include <string>
#include <utility>

#include "core/fusion/pose_filter.h"
#include "core/world/site.h"
#include "msgio/bus.h"
#include "msgio/channels.h"
#include "msgio/lcm_types_fwd.h"
#include "msgio/messages.h"
#include "msgio/process.h"
#include "msgio/subscriptions.h"

namespace roomfix {

struct FusionNodeOptions {
  fusion::PoseFilterOptions filter;
  std::string camera_channel = kCameraPoseChannel;
  std::string ultrasound_channel = kUltrasoundPoseChannel;
  std::string fused_channel = kFusedPoseChannel;
  // Besides one pose per measurement, publish every robot's newest estimate
  // predicted to "now" at this rate, Hz (0: only per measurement). A lost
  // robot then gets a lost pose at every tick.
  double rate_hz = 0.0;
  // A robot's track (its filter and history) is dropped after this long
  // without a measurement (receive clock); a later one starts it afresh.
  double forget_after_s = 10.0;

  bool IsValid(std::string* error) const;
};

// Fuses POSE_CAMERA and POSE_ULTRASOUND into POSE_FUSED: one extended
// Kalman filter (core/fusion/pose_filter.h) per robot id seen in the
// messages.
//
// Every measurement that enters the filter gets a fused pose at its own time
// (utime = the measurement time, latency_us = receive time - utime), also
// when it was gated or arrived late (then the pose is the filter's
// re-filtered estimate at that time). When a robot's track becomes lost (no
// accepted measurement for lost_after_s, judged on the receive clock) one
// lost pose is published, or one per tick with rate_hz. "Now" is always the
// receive time of a message or the tick's argument, so a replay is
// deterministic. STATUS counters: inputs_<source>, rejected gated_<source>,
// too_late, from_future, invalid_<source>, lost_input_<source>; counters
// initialised, reinitialised, lost.
//
// Limits: only the robots the site lists get a track (others are refused as
// unknown_robot, so no message can make the node keep state for an invented
// id); a pose whose utime is more than kMaxUtimeSkewUs from its receive time
// is refused (utime_out_of_range); a pose with an infinite value, or a NaN
// position or position covariance while not LOST, is refused (non_finite); a
// track is forgotten after forget_after_s without measurements. Nothing
// non-finite is published as a position: such an estimate goes out LOST
// (counter non_finite_estimate).
class FusionNode {
 public:
  FusionNode(const Site& site, Bus* bus, const FusionNodeOptions& options, int64_t start_utime);

  void Tick(int64_t now_utime);
  void Stop(int64_t now_utime);
  const StatusReporter& status() const { return status_; }
  // The filter of a robot, or nullptr before its first measurement.
  const fusion::PoseFilter* filter(int robot_id) const;
  // Robots with a track now.
  size_t tracks() const { return tracks_.size(); }

 private:
  struct Track {
    explicit Track(const fusion::PoseFilterOptions& options) : filter(options) {}
    fusion::PoseFilter filter;
    bool lost_reported = false;
    double z_m = 0.0;
    int64_t last_recv_utime = 0;
    // Per source, the newest measurement's delay (receive time minus
    // measurement time, us, at least 0) and when it arrived: Tick judges
    // the track on the measurement clock (JudgedUtime).
    std::array<int64_t, kNumPoseSources> delay_us{};
    std::array<int64_t, kNumPoseSources> delay_recv_utime{};
  };

  // The time, on the measurement clock, at which a track's status is judged
  // at receive time now: now less the largest delay of a source heard from
  // within lost_after_s (docs/fusion.md, "Lost").
  int64_t JudgedUtime(const Track& track, int64_t now_utime) const;

  // A pose from the channel of `source`: checked (ReceivePose), fused,
  // counted and published.
  void OnPose(const pose2d_t& msg, const MessageInfo& info, PoseSource source);
  // The steps of OnPose. A checked pose as the filter's measurement, with
  // the camera's correlated error from the site.
  fusion::Measurement MeasurementOf(const Pose2d& pose, PoseSource source) const;
  // The robot's track, created with its camera bias on its first pose.
  Track& TrackOf(int32_t robot_id);
  // Counts what the filter did with the pose; false when it was dropped
  // (too late, from the future, invalid) and nothing is published.
  bool CountOutcome(fusion::Outcome outcome, bool was_initialised, const std::string& name,
                    const Pose2d& pose, int64_t recv_utime);
  void Publish(int32_t robot_id, const fusion::Estimate& estimate, double z_m, int64_t now_utime);

  // A copy: what ReceivePose checks a pose's robot against.
  Site site_;
  Bus* bus_;
  FusionNodeOptions options_;
  StatusReporter status_;
  std::set<int32_t> site_cameras_;
  // The camera's correlated error (docs/fusion.md, "Correlated camera
  // error"), m per axis: of each (camera, robot) the site lists, its marker
  // height x tilt sigma (the term camera_proc adds to its poses); of each
  // robot the largest over the cameras, its filter's bias sigma.
  std::map<std::pair<int32_t, int32_t>, double> tilt_sigma_m_;
  std::map<int32_t, double> robot_bias_sigma_m_;
  std::map<int32_t, Track> tracks_;
  int64_t next_rate_utime_ = 0;
  // Last: ended first, before anything the handlers use.
  Subscriptions subscriptions_{bus_};
};

}  // namespace roomfix

#endif  // ROOMFIX_FUSION_PROC_FUSION_NODE_H_
