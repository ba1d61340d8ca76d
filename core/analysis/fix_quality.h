#ifndef ROOMFIX_CORE_ANALYSIS_FIX_QUALITY_H_
#define ROOMFIX_CORE_ANALYSIS_FIX_QUALITY_H_

#include <cstdint>
#include <limits>
#include <vector>

#include "core/analysis/track_error.h"

namespace roomfix::analysis {

// The squared Mahalanobis distance below which a share p of a 2D Gaussian
// error lies: chi-square with 2 degrees of freedom, whose quantile has the
// closed form -2 ln(1 - p). 95 %: 5.991; the median (p = 0.5): 2 ln 2 =
// 1.386.
double Chi2Quantile2Dof(double p);

// One published fix as a consumer sees it: position, the status it was
// flagged with, and its position covariance.
struct RatedFix {
  int64_t utime = 0;
  double x_m = 0.0;
  double y_m = 0.0;
  // pose2d_t::STATUS_DEGRADED; lost fixes have no position and are counted
  // apart (AssessFixes' `lost`).
  bool degraded = false;
  // Position covariance, m^2; NaN when the fix has none.
  double cov_xx_m2 = std::numeric_limits<double>::quiet_NaN();
  double cov_xy_m2 = std::numeric_limits<double>::quiet_NaN();
  double cov_yy_m2 = std::numeric_limits<double>::quiet_NaN();
};

// What a user of a pose stream needs to know to trust it, against ground
// truth:
// - accuracy: RMSE, p99 and max of the horizontal error; the worst error of
//   a fix flagged ok (what a consumer that only filters on status gets);
// - honesty of the status: shares of ok, degraded and lost fixes;
// - honesty of the covariance: the share of errors e inside the fix's own
//   95 % ellipse, e^T Sigma^-1 e <= 5.991, and the median of e^T Sigma^-1 e.
//   For a calibrated Gaussian model the share is 0.95 and the median 1.386;
//   a median of m means the variances are about 1.386 / m times too large
//   (m < 1.386: pessimistic, m > 1.386: optimistic). The share is the robust
//   figure when the errors have heavy tails (outliers), the median tells by
//   how much the bulk is off.
// Failure modes: the ground truth is linearly interpolated at the fix's time
// (InterpolateTrack), so a reference sampled at 30 Hz on a 0.4 m circle at
// 0.2 m/s adds about 0.01 mm: invisible next to the camera's 0.2 mm. A fix
// whose covariance is not positive definite (or missing) is not counted in
// the coverage (`without_covariance`).
struct FixQuality {
  int fixes = 0;  // with a position, plus lost
  int ok = 0, degraded = 0, lost = 0;
  double share_ok = 0.0, share_degraded = 0.0, share_lost = 0.0;
  // Fixes with a position and a reference at their time.
  int compared = 0;
  double rmse_m = 0.0, p99_m = 0.0, max_m = 0.0;
  // The largest error among compared ok fixes; NaN when there is none.
  double worst_ok_m = std::numeric_limits<double>::quiet_NaN();
  // Compared fixes with a positive definite covariance.
  int with_covariance = 0;
  int without_covariance = 0;
  int inside_95 = 0;
  double share_inside_95 = std::numeric_limits<double>::quiet_NaN();
  double median_d2 = std::numeric_limits<double>::quiet_NaN();
};

// `reference` sorted by utime; `lost`: fixes published as lost.
FixQuality AssessFixes(const std::vector<RatedFix>& fixes, int lost,
                       const std::vector<TimedPosition>& reference, int64_t max_gap_us);

// e^T Sigma^-1 e for the 2x2 covariance (xx, xy, yy); NaN when it is not
// positive definite or not finite.
double SquaredMahalanobis2D(double dx_m, double dy_m, double cov_xx_m2, double cov_xy_m2,
                            double cov_yy_m2);

}  // namespace roomfix::analysis

#endif  // ROOMFIX_CORE_ANALYSIS_FIX_QUALITY_H_
