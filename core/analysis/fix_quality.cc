#include "core/analysis/fix_quality.h"

#include <algorithm>
#include <cmath>

namespace roomfix::analysis {

double Chi2Quantile2Dof(double p) { return -2.0 * std::log1p(-p); }

double SquaredMahalanobis2D(double dx_m, double dy_m, double cov_xx_m2, double cov_xy_m2,
                            double cov_yy_m2) {
  const double det = cov_xx_m2 * cov_yy_m2 - cov_xy_m2 * cov_xy_m2;
  if (!std::isfinite(det) || !(cov_xx_m2 > 0.0) || !(det > 0.0)) {
    return std::numeric_limits<double>::quiet_NaN();
  }
  // Sigma^-1 = [yy, -xy; -xy, xx] / det.
  return (cov_yy_m2 * dx_m * dx_m - 2.0 * cov_xy_m2 * dx_m * dy_m + cov_xx_m2 * dy_m * dy_m) / det;
}

FixQuality AssessFixes(const std::vector<RatedFix>& fixes, int lost,
                       const std::vector<TimedPosition>& reference, int64_t max_gap_us) {
  FixQuality q;
  q.lost = std::max(0, lost);
  q.fixes = static_cast<int>(fixes.size()) + q.lost;
  std::vector<double> errors;
  std::vector<double> d2s;
  double sum2 = 0.0;
  const double limit_95 = Chi2Quantile2Dof(0.95);
  for (const RatedFix& f : fixes) {
    (f.degraded ? q.degraded : q.ok) += 1;
    double x = 0.0, y = 0.0;
    if (!std::isfinite(f.x_m) || !std::isfinite(f.y_m) ||
        !InterpolateTrack(reference, f.utime, max_gap_us, &x, &y)) {
      continue;
    }
    const double dx = f.x_m - x, dy = f.y_m - y;
    const double error = std::hypot(dx, dy);
    errors.push_back(error);
    sum2 += error * error;
    q.max_m = std::max(q.max_m, error);
    if (!f.degraded) {
      q.worst_ok_m = std::isnan(q.worst_ok_m) ? error : std::max(q.worst_ok_m, error);
    }
    const double d2 = SquaredMahalanobis2D(dx, dy, f.cov_xx_m2, f.cov_xy_m2, f.cov_yy_m2);
    if (std::isnan(d2)) {
      ++q.without_covariance;
      continue;
    }
    d2s.push_back(d2);
    q.inside_95 += d2 <= limit_95 ? 1 : 0;
  }
  if (q.fixes > 0) {
    q.share_ok = static_cast<double>(q.ok) / q.fixes;
    q.share_degraded = static_cast<double>(q.degraded) / q.fixes;
    q.share_lost = static_cast<double>(q.lost) / q.fixes;
  }
  q.compared = static_cast<int>(errors.size());
  if (q.compared > 0) {
    q.rmse_m = std::sqrt(sum2 / q.compared);
    q.p99_m = Percentile(errors, 0.99);
  }
  q.with_covariance = static_cast<int>(d2s.size());
  if (q.with_covariance > 0) {
    q.share_inside_95 = static_cast<double>(q.inside_95) / q.with_covariance;
    q.median_d2 = Percentile(d2s, 0.5);
  }
  return q;
}

}  // namespace roomfix::analysis
