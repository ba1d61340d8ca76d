#include "msgio/trilat_conversions.h"

#include "core/world/site.h"
#include "msgio/message_conversions.h"
#include "msgio/time_limits.h"

namespace roomfix {

void RangesFromMessage(const range_set_t& set, std::vector<trilat::RangeMeasurement>* out) {
  out->clear();
  for (const range_t& r : set.ranges) {
    trilat::RangeMeasurement m;
    m.receiver_id = r.receiver_id;
    m.receiver_m = {r.receiver_position_m[0], r.receiver_position_m[1], r.receiver_position_m[2]};
    m.range_m = r.range_m;
    out->push_back(m);
  }
}

pose2d_t PoseFromFix(const trilat::Fix& fix, const range_set_t& set, int32_t robot_id,
                     int64_t publish_utime) {
  Pose2d p;
  p.utime = set.utime;
  p.source = PoseSource::kUltrasound;
  p.camera_id = kNoCameraId;
  p.robot_id = robot_id;
  p.measurement_seq = set.firing_seq;
  p.x_m = fix.position_m.x();
  p.y_m = fix.position_m.y();
  p.z_m = fix.position_m.z();
  // The heading, and its rows and columns of the covariance, stay unknown.
  for (int r = 0; r < 2; ++r) {
    for (int c = 0; c < 2; ++c) p.covariance[r][c] = fix.covariance_m2(r, c);
  }
  p.residual_m = fix.residual_rms_m;
  p.num_measurements = static_cast<int32_t>(fix.used.size());
  switch (fix.status) {
    case trilat::FixStatus::kOk:
      p.status = PoseStatus::kOk;
      break;
    case trilat::FixStatus::kDegraded:
      p.status = PoseStatus::kDegraded;
      break;
    case trilat::FixStatus::kFailed:
      p.status = PoseStatus::kLost;
      break;
  }
  p.latency_us = LatencyUs(publish_utime, set.utime);
  return ToMessage(p);
}

}  // namespace roomfix
