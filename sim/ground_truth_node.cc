#include "sim/ground_truth_node.h"

#include <cmath>
#include <limits>

#include "msgio/message_conversions.h"

namespace roomfix {

bool GroundTruthNodeOptions::IsValid(std::string* error) const {
  if (!std::isfinite(rate_hz) || rate_hz <= 0.0 || rate_hz > 10000.0) {
    *error = "rate_hz must be in (0, 10000]";
    return false;
  }
  return true;
}

GroundTruthNode::GroundTruthNode(const Site& site, Bus* bus, const GroundTruthNodeOptions& options)
    : site_(site), bus_(bus), options_(options), status_("roomfix_sim", options.start_utime) {
  status_.SetState(process_status_t::STATE_RUNNING);
}

void GroundTruthNode::Tick(int64_t now_utime) {
  const double period_us = 1e6 / options_.rate_hz;
  auto sample_utime = [&](int64_t k) {
    return options_.start_utime + static_cast<int64_t>(std::llround(k * period_us));
  };
  if (sample_utime(next_sample_) <= now_utime) {
    // The newest sample at or before now.
    int64_t k = static_cast<int64_t>(std::floor((now_utime - options_.start_utime) / period_us));
    while (sample_utime(k) > now_utime) --k;
    while (sample_utime(k + 1) <= now_utime) ++k;
    if (k > next_sample_) status_.Count("late_samples", k - next_sample_);
    const int64_t utime = sample_utime(k);
    const double t_s = (utime - options_.start_utime) * 1e-6;
    for (const SimulatedRobot& robot : site_.simulation.robots) {
      const GroundTruthPose truth = robot.trajectory->PoseAt(t_s);
      Pose2d msg;
      msg.utime = utime;
      msg.source = PoseSource::kGroundTruth;
      msg.camera_id = kNoCameraId;
      msg.robot_id = robot.robot_id;
      msg.measurement_seq = k;
      msg.x_m = truth.x_m;
      msg.y_m = truth.y_m;
      msg.z_m = 0.0;
      msg.heading_rad = truth.heading_rad;
      // Ground truth is exact by definition.
      for (auto& row : msg.covariance) {
        for (double& v : row) v = 0.0;
      }
      msg.residual_m = 0.0;
      msg.num_measurements = 0;
      msg.status = PoseStatus::kOk;
      msg.latency_us = now_utime - utime;
      if (bus_->Publish(kGroundTruthPoseChannel, ToMessage(msg))) {
        status_.AddOutputs();
      } else {
        status_.AddDropped();
      }
    }
    next_sample_ = k + 1;
  }
  status_.MaybePublish(bus_, now_utime);
}

void GroundTruthNode::Stop(int64_t now_utime) {
  status_.SetState(process_status_t::STATE_STOPPING);
  status_.Publish(bus_, now_utime);
}

}  // namespace roomfix
