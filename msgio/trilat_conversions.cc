#include "msgio/trilat_conversions.h"

#include <cmath>
#include <limits>

#include "core/world/site.h"
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
  constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  pose2d_t p{};
  p.utime = set.utime;
  p.source = pose2d_t::SOURCE_ULTRASOUND;
  p.camera_id = kNoCameraId;
  p.robot_id = robot_id;
  p.measurement_seq = set.firing_seq;
  p.x_m = fix.position_m.x();
  p.y_m = fix.position_m.y();
  p.z_m = fix.position_m.z();
  p.heading_rad = kNaN;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c)
      p.covariance[r][c] = (r < 2 && c < 2) ? fix.covariance_m2(r, c) : kNaN;
  }
  p.residual_m = fix.residual_rms_m;
  p.num_measurements = static_cast<int32_t>(fix.used.size());
  switch (fix.status) {
    case trilat::FixStatus::kOk:
      p.status = pose2d_t::STATUS_OK;
      break;
    case trilat::FixStatus::kDegraded:
      p.status = pose2d_t::STATUS_DEGRADED;
      break;
    case trilat::FixStatus::kFailed:
      p.status = pose2d_t::STATUS_LOST;
      break;
  }
  p.latency_us = SaturatingDifferenceUs(publish_utime, set.utime);
  return p;
}

}  // namespace roomfix
