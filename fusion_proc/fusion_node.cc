#include "fusion_proc/fusion_node.h"

#include <algorithm>
#include <cmath>
#include <iterator>
#include <limits>
#include <string>

#include "msgio/message_conversions.h"
#include "msgio/received.h"
#include "msgio/time_limits.h"

namespace roomfix {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

PoseStatus StatusOf(fusion::TrackStatus status) {
  switch (status) {
    case fusion::TrackStatus::kOk:
      return PoseStatus::kOk;
    case fusion::TrackStatus::kDegraded:
      return PoseStatus::kDegraded;
    case fusion::TrackStatus::kLost:
      break;
  }
  return PoseStatus::kLost;
}

}  // namespace

bool FusionNodeOptions::IsValid(std::string* error) const {
  if (!filter.IsValid(error)) return false;
  if (!std::isfinite(rate_hz) || rate_hz < 0.0) {
    *error = "rate_hz must be finite and not negative";
    return false;
  }
  if (!std::isfinite(forget_after_s) || !(forget_after_s >= filter.lost_after_s)) {
    *error = "forget_after_s must be finite and at least lost_after_s";
    return false;
  }
  if (camera_channel.empty() || ultrasound_channel.empty() || fused_channel.empty()) {
    *error = "channel names must not be empty";
    return false;
  }
  return true;
}

FusionNode::FusionNode(const Site& site, Bus* bus, const FusionNodeOptions& options,
                       int64_t start_utime)
    : site_(site), bus_(bus), options_(options), status_("fusion_proc", start_utime) {
  for (const Camera& camera : site.cameras) {
    site_cameras_.insert(camera.id);
    for (const CameraRobot& robot : camera.robots) {
      // As core/calib/pose_covariance: a tilt theta moves the marker h theta.
      const double sigma_m = robot.marker_height_m * robot.tilt_sigma_deg * M_PI / 180.0;
      if (!(std::isfinite(sigma_m) && sigma_m > 0.0)) continue;
      tilt_sigma_m_[{camera.id, robot.robot_id}] = sigma_m;
      double& bias = robot_bias_sigma_m_[robot.robot_id];
      bias = std::max(bias, sigma_m);
    }
  }
  subscriptions_.Add(bus_->Subscribe<pose2d_t>(
      options_.camera_channel, [this](const pose2d_t& pose, const MessageInfo& info) {
        OnPose(pose, info, PoseSource::kCamera);
      }));
  subscriptions_.Add(bus_->Subscribe<pose2d_t>(
      options_.ultrasound_channel, [this](const pose2d_t& pose, const MessageInfo& info) {
        OnPose(pose, info, PoseSource::kUltrasound);
      }));
  status_.SetState(process_status_t::STATE_RUNNING);
}

const fusion::PoseFilter* FusionNode::filter(int robot_id) const {
  auto it = tracks_.find(robot_id);
  return it == tracks_.end() ? nullptr : &it->second.filter;
}

void FusionNode::OnPose(const pose2d_t& msg, const MessageInfo& info, PoseSource source) {
  const std::string name = PoseSourceName(source);
  status_.AddInputs();
  status_.Count("inputs_" + name);
  // Per-camera counters, for the site's cameras only (a sender can invent
  // ids; the counter list must stay bounded): camera_<id>_inputs,
  // camera_<id>_accepted (initialisations included), camera_<id>_gated.
  std::string per_camera;
  if (source == PoseSource::kCamera) {
    if (site_cameras_.count(msg.camera_id) != 0) {
      per_camera = "camera_" + std::to_string(msg.camera_id) + "_";
      status_.Count(per_camera + "inputs");
    } else {
      status_.Count("camera_unlisted_inputs");
    }
  }
  Pose2d pose;
  std::string why;
  InputProblem problem = InputProblem::kNone;
  if (!ReceivePose(msg, site_, info.recv_utime, &pose, &why, &problem)) {
    status_.Reject(InputProblemCounter(problem));
    status_.SetError(name + " pose of robot " + std::to_string(msg.robot_id) + ": " + why,
                     info.recv_utime);
    return;
  }
  if (pose.status == PoseStatus::kLost) {
    // The sensor saw nothing: not a measurement, and not an error.
    status_.Count("lost_input_" + name);
    return;
  }
  Track& track = TrackOf(pose.robot_id);
  track.last_recv_utime = info.recv_utime;
  const bool was_initialised = track.filter.initialised();
  fusion::Estimate estimate;
  const fusion::Outcome outcome =
      track.filter.Add(MeasurementOf(pose, source), info.recv_utime, &estimate);
  // Only a measurement the filter took says how late this source runs: a
  // refused one (too late, from the future, invalid, gated) may be a stale
  // log replayed onto the bus or a hostile datagram, and would stretch or
  // erase the delay that "lost" is judged by (JudgedUtime).
  if (outcome != fusion::Outcome::kGated && outcome != fusion::Outcome::kTooLate &&
      outcome != fusion::Outcome::kFromFuture && outcome != fusion::Outcome::kInvalid) {
    const auto src = static_cast<size_t>(source);
    track.delay_us[src] = std::max<int64_t>(0, SaturatingDifferenceUs(info.recv_utime, pose.utime));
    track.delay_recv_utime[src] = info.recv_utime;
  }
  if (!CountOutcome(outcome, was_initialised, name, pose, info.recv_utime)) return;
  if (!per_camera.empty()) {
    status_.Count(per_camera + (outcome == fusion::Outcome::kGated ? "gated" : "accepted"));
  }
  if (outcome != fusion::Outcome::kGated) {
    track.lost_reported = false;
    if (std::isfinite(pose.z_m)) track.z_m = pose.z_m;
  }
  Publish(pose.robot_id, estimate, track.z_m, info.recv_utime);
}

fusion::Measurement FusionNode::MeasurementOf(const Pose2d& pose, PoseSource source) const {
  fusion::Measurement m;
  m.utime = pose.utime;
  m.source = source;
  m.camera_id = source == PoseSource::kCamera ? pose.camera_id : kNoCameraId;
  m.seq = pose.measurement_seq;
  m.position_m = {pose.x_m, pose.y_m};
  m.position_cov_m2 << pose.covariance[0][0], pose.covariance[0][1], pose.covariance[1][0],
      pose.covariance[1][1];
  m.heading_rad = pose.heading_rad;
  m.heading_var_rad2 = pose.covariance[2][2];
  if (source == PoseSource::kCamera) {
    auto tilt = tilt_sigma_m_.find({pose.camera_id, pose.robot_id});
    if (tilt != tilt_sigma_m_.end()) m.correlated_sigma_m = tilt->second;
  }
  return m;
}

FusionNode::Track& FusionNode::TrackOf(int32_t robot_id) {
  auto it = tracks_.find(robot_id);
  if (it == tracks_.end()) {
    // The robot's camera bias from the site, unless the options turned the
    // model off (a correlation time of 0).
    fusion::PoseFilterOptions filter_options = options_.filter;
    auto bias = robot_bias_sigma_m_.find(robot_id);
    if (bias != robot_bias_sigma_m_.end() && filter_options.camera_bias_sigma_m == 0.0) {
      filter_options.camera_bias_sigma_m = bias->second;
    }
    it = tracks_.emplace(robot_id, Track(filter_options)).first;
  }
  return it->second;
}

bool FusionNode::CountOutcome(fusion::Outcome outcome, bool was_initialised,
                              const std::string& name, const Pose2d& pose, int64_t recv_utime) {
  switch (outcome) {
    case fusion::Outcome::kAccepted:
      break;
    case fusion::Outcome::kInitialised:
      status_.Count(was_initialised ? "reinitialised" : "initialised");
      break;
    case fusion::Outcome::kReinitialised:
      status_.Count("reinitialised");
      break;
    case fusion::Outcome::kCameraTakeover:
      status_.Count("camera_takeover");
      break;
    case fusion::Outcome::kGated:
      status_.Reject("gated_" + name);
      break;
    case fusion::Outcome::kTooLate:
      status_.Reject("too_late");
      return false;
    case fusion::Outcome::kFromFuture:
      status_.Reject("from_future");
      status_.SetError(name + " pose of robot " + std::to_string(pose.robot_id) + " is " +
                           std::to_string((pose.utime - recv_utime) / 1000) +
                           " ms ahead of the clock",
                       recv_utime);
      return false;
    case fusion::Outcome::kInvalid:
      status_.Reject("invalid_" + name);
      return false;
  }
  return true;
}

void FusionNode::Publish(int32_t robot_id, const fusion::Estimate& e, double z_m,
                         int64_t now_utime) {
  Pose2d p;
  p.utime = e.utime;
  p.source = PoseSource::kFused;
  p.camera_id = kNoCameraId;
  p.robot_id = robot_id;
  p.measurement_seq = e.seq;
  p.z_m = z_m;
  p.status = e.valid ? StatusOf(e.status) : PoseStatus::kLost;
  p.num_measurements = e.num_measurements;
  p.latency_us = LatencyUs(now_utime, e.utime);
  p.residual_m = std::isfinite(e.innovation_m) ? e.innovation_m : kNaN;
  // The filter only ever takes finite input, but its state is arithmetic on
  // it: an estimate that overflowed is not a position.
  if (p.status != PoseStatus::kLost &&
      !(std::isfinite(e.state[fusion::kX]) && std::isfinite(e.state[fusion::kY]) &&
        e.covariance.topLeftCorner<2, 2>().allFinite())) {
    status_.Count("non_finite_estimate");
    p.status = PoseStatus::kLost;
  }
  if (p.status == PoseStatus::kLost) {
    p.x_m = p.y_m = p.heading_rad = kNaN;
    for (auto& row : p.covariance) {
      for (double& v : row) v = kNaN;
    }
  } else {
    p.x_m = e.state[fusion::kX];
    p.y_m = e.state[fusion::kY];
    p.heading_rad = e.heading_known ? e.state[fusion::kHeading] : kNaN;
    const int index[3] = {fusion::kX, fusion::kY, fusion::kHeading};
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) {
        const bool heading = r == 2 || c == 2;
        p.covariance[r][c] = heading && !e.heading_known ? kNaN : e.covariance(index[r], index[c]);
      }
    }
  }
  if (bus_->Publish(options_.fused_channel, ToMessage(p))) {
    status_.AddOutputs();
  } else {
    status_.AddDropped();
  }
}

int64_t FusionNode::JudgedUtime(const Track& track, int64_t now_utime) const {
  const auto window_us = static_cast<int64_t>(options_.filter.lost_after_s * 1e6);
  int64_t delay_us = 0;
  for (size_t i = 0; i < track.delay_us.size(); ++i) {
    if (track.delay_recv_utime[i] != 0 &&
        SaturatingDifferenceUs(now_utime, track.delay_recv_utime[i]) <= window_us) {
      delay_us = std::max(delay_us, track.delay_us[i]);
    }
  }
  return now_utime - std::min(delay_us, window_us);
}

void FusionNode::Tick(int64_t now_utime) {
  bool rate_tick = false;
  if (options_.rate_hz > 0.0 && now_utime >= next_rate_utime_) {
    rate_tick = true;
    const int64_t period = std::llround(1e6 / options_.rate_hz);
    next_rate_utime_ = next_rate_utime_ == 0 || now_utime - next_rate_utime_ > period
                           ? now_utime + period
                           : next_rate_utime_ + period;
  }
  const auto forget_us = static_cast<int64_t>(options_.forget_after_s * 1e6);
  for (auto it = tracks_.begin(); it != tracks_.end();) {
    it = SaturatingDifferenceUs(now_utime, it->second.last_recv_utime) > forget_us
             ? tracks_.erase(it)
             : std::next(it);
  }
  status_.SetCounter("tracks", static_cast<int64_t>(tracks_.size()));
  for (auto& [robot_id, track] : tracks_) {
    if (!track.filter.initialised()) continue;
    fusion::Estimate e = track.filter.Predict(now_utime);
    // Lost and degraded are judged on the measurement clock: a frame that
    // spent 0.7 s in a loaded camera_proc has not yet had its chance to be
    // accepted (docs/fusion.md, "Lost").
    e.status = track.filter.Predict(JudgedUtime(track, now_utime)).status;
    const bool lost = e.status == fusion::TrackStatus::kLost;
    if (lost && !track.lost_reported) {
      track.lost_reported = true;
      status_.Count("lost");
      if (options_.rate_hz <= 0.0) {  // Else the rate ticks report it.
        e.utime = now_utime;
        Publish(robot_id, e, track.z_m, now_utime);
      }
    }
    if (rate_tick) {
      e.utime = now_utime;
      e.seq = -1;
      Publish(robot_id, e, track.z_m, now_utime);
    }
  }
  status_.MaybePublish(bus_, now_utime);
}

void FusionNode::Stop(int64_t now_utime) {
  status_.SetState(process_status_t::STATE_STOPPING);
  status_.Publish(bus_, now_utime);
}

}  // namespace roomfix
