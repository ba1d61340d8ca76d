#ifndef ROOMFIX_CORE_CALIB_POSE_COVARIANCE_H_
#define ROOMFIX_CORE_CALIB_POSE_COVARIANCE_H_

#include <Eigen/Core>

namespace roomfix::calib {

// What makes a camera pose wrong, per robot and frame (docs/camera.md, "The
// position covariance"). Every term is independent of the others, so their
// covariances add.
struct PoseNoiseInputs {
  // The centroid's noise per image axis, pixels: the calibration's measured
  // pixel_sigma_px (its fit's residual under the camera's own JPEG and light,
  // plus the fit's model error).
  double pixel_sigma_px = 0.0;
  // d(x, y)/d(u, v) of the pixel-to-floor mapping at the marker, m/px.
  Eigen::Matrix2d floor_per_px = Eigen::Matrix2d::Zero();
  // The robot's velocity over the floor, m/s (zero when not known).
  Eigen::Vector2d velocity_mps = Eigen::Vector2d::Zero();
  // Exposure time, s: the marker streaks over |v| exposure_s.
  double exposure_s = 0.0;
  // The centroid's extra sigma along a streak as a fraction of the streak's
  // length (edge unmixing of the faint, noisy ends), fitted on the webcam
  // scenario (docs/camera.md).
  double blur_sigma_fraction = 0.0;
  // One sigma of the frame timestamp's unknown part (USB jitter), s.
  double timing_sigma_s = 0.0;
  // Marker height above the floor and one sigma of the robot's pitch and of
  // its roll (each), radians: tilting by theta moves the marker h theta.
  double marker_height_m = 0.0;
  double tilt_sigma_rad = 0.0;
};

// The floor covariance of the position marker, m^2:
//   Sigma = sigma_px^2 J J^T                       centroid noise and model
//         + (k |v| T_exp)^2 u u^T                  streak, u = v / |v|
//         + sigma_t^2 v v^T                        timestamp jitter
//         + (h sigma_tilt)^2 I                     pitch and roll
// With only the first term non-zero it is the calibrated covariance of an
// ideal camera (what camera_proc published before the webcam terms).
Eigen::Matrix2d PositionCovariance(const PoseNoiseInputs& in);

// The part of it that differs between the two markers of one robot (tilt and
// timing move both alike, so they do not turn the heading): the first two
// terms. The heading's variance is 2 sigma^2 / d^2 with sigma^2 the mean of
// this matrix's diagonal, for markers d apart.
Eigen::Matrix2d MarkerRelativeCovariance(const PoseNoiseInputs& in);

}  // namespace roomfix::calib

#endif  // ROOMFIX_CORE_CALIB_POSE_COVARIANCE_H_
