#include "core/calib/pose_covariance.h"

namespace roomfix::calib {

Eigen::Matrix2d MarkerRelativeCovariance(const PoseNoiseInputs& in) {
  const double s2 = in.pixel_sigma_px * in.pixel_sigma_px;
  Eigen::Matrix2d cov = s2 * in.floor_per_px * in.floor_per_px.transpose();
  // k |v| T u u^T scaled: (k T)^2 v v^T is the same matrix without dividing by |v|.
  if (in.blur_sigma_fraction > 0.0 && in.exposure_s > 0.0) {
    const double kt = in.blur_sigma_fraction * in.exposure_s;
    cov += kt * kt * in.velocity_mps * in.velocity_mps.transpose();
  }
  return cov;
}

Eigen::Matrix2d PositionCovariance(const PoseNoiseInputs& in) {
  Eigen::Matrix2d cov = MarkerRelativeCovariance(in);
  if (in.timing_sigma_s > 0.0) {
    const double st2 = in.timing_sigma_s * in.timing_sigma_s;
    cov += st2 * in.velocity_mps * in.velocity_mps.transpose();
  }
  if (in.tilt_sigma_rad > 0.0) {
    const double lever_m = in.marker_height_m * in.tilt_sigma_rad;
    cov += lever_m * lever_m * Eigen::Matrix2d::Identity();
  }
  return cov;
}

}  // namespace roomfix::calib
