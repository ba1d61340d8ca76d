#ifndef ROOMFIX_CORE_ANALYSIS_CIRCLE_FIT_H_
#define ROOMFIX_CORE_ANALYSIS_CIRCLE_FIT_H_

#include <string>
#include <vector>

namespace roomfix::analysis {

struct TimedPoint {
  double t_s = 0.0;
  double x_m = 0.0;
  double y_m = 0.0;
};

// The reference paper's two fits of a robot driving in a circle, by
// nonlinear least squares (GSL's trust-region Levenberg-Marquardt with
// analytic Jacobians). Each reports its parameters with standard deviations
// from s^2 (J^T J)^-1, s^2 the residual variance, and a usable flag; when
// unusable, `message` says why (too few points, no convergence, degenerate).

// (a) Radius with a drifting centre: residual per point
//   r - sqrt((x0 + vx t - x)^2 + (y0 + vy t - y)^2).
// Reference: r 41.9 cm, centre (191.1, 149.6) cm, drift (0.264, -0.096) mm/s,
// std 0.633 cm.
// The circle both fits share: radius, centre at t = 0 and the centre's
// drift, each with its standard deviation.
struct DriftingCircle {
  double radius_m = 0, cx_m = 0, cy_m = 0, vx_mps = 0, vy_mps = 0;
  double radius_sigma_m = 0, cx_sigma_m = 0, cy_sigma_m = 0, vx_sigma_mps = 0, vy_sigma_mps = 0;
};

struct DriftingCircleFit : DriftingCircle {
  bool usable = false;
  std::string message;
  // Standard deviation of the radial residual.
  double residual_std_m = 0;
  int iterations = 0;
};
DriftingCircleFit FitDriftingCircle(const std::vector<TimedPoint>& points);

// (b) The full motion with constant angular speed w and phase phi:
//   p(t) = (x0 + vx t, y0 + vy t) + r (cos(w t + phi), sin(w t + phi)),
// fitted to x and y. Reference: w -0.439 rad/s, phase 3.163 rad, mean error
// 2.8 cm, std 1.8 cm. The start for w and phi comes from a line fitted to
// the unwrapped angle about fit (a)'s centre, so the samples must be dense
// enough that the robot turns less than half a circle between two of them.
struct CircularMotionFit : DriftingCircle {
  bool usable = false;
  std::string message;
  double angular_speed_radps = 0, phase_rad = 0;
  double angular_speed_sigma_radps = 0, phase_sigma_rad = 0;
  // Distance from each point to the model's position at its time.
  double mean_error_m = 0, std_error_m = 0;
  int iterations = 0;
};
CircularMotionFit FitCircularMotion(const std::vector<TimedPoint>& points);

}  // namespace roomfix::analysis

#endif  // ROOMFIX_CORE_ANALYSIS_CIRCLE_FIT_H_
