#ifndef ROOMFIX_CORE_ANALYSIS_TRACK_ERROR_H_
#define ROOMFIX_CORE_ANALYSIS_TRACK_ERROR_H_

#include <cstdint>
#include <vector>

namespace roomfix::analysis {

struct TimedPosition {
  int64_t utime = 0;
  double x_m = 0.0;
  double y_m = 0.0;
};

// The reference track's position at utime, linearly interpolated between the
// samples either side. False when utime is outside the track or the two
// samples are more than max_gap_us apart (no reference there). `track` must
// be sorted by utime.
bool InterpolateTrack(const std::vector<TimedPosition>& track, int64_t utime, int64_t max_gap_us,
                      double* x_m, double* y_m);

struct ErrorSummary {
  int compared = 0;
  // Estimates with no reference at their time.
  int unmatched = 0;
  double mean_m = 0.0;
  double rmse_m = 0.0;
  double p95_m = 0.0;
  double max_m = 0.0;
};

// Horizontal error of each estimate against the reference at the estimate's
// own time (the time it is valid at, not when it arrived).
ErrorSummary CompareToReference(const std::vector<TimedPosition>& estimates,
                                const std::vector<TimedPosition>& reference, int64_t max_gap_us);

// The value below which a share q of `values` lies (nearest rank); 0 for none.
double Percentile(std::vector<double> values, double q);

}  // namespace roomfix::analysis

#endif  // ROOMFIX_CORE_ANALYSIS_TRACK_ERROR_H_
