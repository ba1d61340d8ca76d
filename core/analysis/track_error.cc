#include "core/analysis/track_error.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace roomfix::analysis {

bool InterpolateTrack(const std::vector<TimedPosition>& track, int64_t utime, int64_t max_gap_us,
                      double* x_m, double* y_m) {
  auto after = std::lower_bound(track.begin(), track.end(), utime,
                                [](const TimedPosition& p, int64_t t) { return p.utime < t; });
  if (after == track.end()) return false;
  if (after->utime == utime) {
    *x_m = after->x_m;
    *y_m = after->y_m;
    return true;
  }
  if (after == track.begin()) return false;
  const auto before = after - 1;
  const int64_t gap = after->utime - before->utime;
  if (gap > max_gap_us) return false;
  const double f = static_cast<double>(utime - before->utime) / static_cast<double>(gap);
  *x_m = before->x_m + f * (after->x_m - before->x_m);
  *y_m = before->y_m + f * (after->y_m - before->y_m);
  return true;
}

double Percentile(std::vector<double> values, double q) {
  if (values.empty()) return 0.0;
  std::sort(values.begin(), values.end());
  const double rank = std::ceil(q * static_cast<double>(values.size()));
  const size_t k = static_cast<size_t>(std::max(1.0, rank)) - 1;
  return values[std::min(k, values.size() - 1)];
}

ErrorSummary CompareToReference(const std::vector<TimedPosition>& estimates,
                                const std::vector<TimedPosition>& reference, int64_t max_gap_us) {
  ErrorSummary s;
  std::vector<double> errors;
  double sum = 0.0, sum2 = 0.0;
  for (const TimedPosition& e : estimates) {
    double x = 0.0, y = 0.0;
    if (!std::isfinite(e.x_m) || !std::isfinite(e.y_m) ||
        !InterpolateTrack(reference, e.utime, max_gap_us, &x, &y)) {
      ++s.unmatched;
      continue;
    }
    const double err = std::hypot(e.x_m - x, e.y_m - y);
    errors.push_back(err);
    sum += err;
    sum2 += err * err;
    s.max_m = std::max(s.max_m, err);
  }
  s.compared = static_cast<int>(errors.size());
  if (s.compared > 0) {
    s.mean_m = sum / s.compared;
    s.rmse_m = std::sqrt(sum2 / s.compared);
    s.p95_m = Percentile(errors, 0.95);
  }
  return s;
}

}  // namespace roomfix::analysis
