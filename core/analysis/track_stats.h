#ifndef ROOMFIX_CORE_ANALYSIS_TRACK_STATS_H_
#define ROOMFIX_CORE_ANALYSIS_TRACK_STATS_H_

// The statistics behind `roomfix analyze`: the reference paper's static
// repeatability (Fig. 7), camera cycle timing (Figs. 3 and 4), latency,
// motion, error over time and the offset between two sources on one robot.
// Pure functions of their arguments. Non-finite values (a lost fix) are
// ignored everywhere unless said otherwise; standard deviations are sample
// standard deviations (divide by n - 1), 0 for fewer than two values;
// percentiles and medians are nearest rank (Percentile in track_error.h).

#include <cstdint>
#include <vector>

#include "core/analysis/track_error.h"

namespace roomfix::analysis {

// Bin k counts values in [lo + k bin_width, lo + (k + 1) bin_width). The
// requested upper end is rounded up to a whole bin, so every bin has the
// same width; values from lo + counts.size() bin_width up are `above`.
struct Histogram {
  double lo = 0.0, bin_width = 0.0;
  std::vector<int64_t> counts;
  int64_t below = 0, above = 0;
};

inline constexpr int64_t kMaxHistogramBins = int64_t{1} << 22;

// NaN is neither binned nor counted; -inf is below, +inf above. No bins and
// nothing counted when bin_width <= 0, hi <= lo, any of them is not finite,
// or the range would need more than kMaxHistogramBins bins (a unit mistake,
// not a figure).
Histogram MakeHistogram(const std::vector<double>& values, double lo, double hi, double bin_width);

// Square bins of bin_m: counts[iy * nx + ix] counts points with x in
// [x_lo + ix bin_m, x_lo + (ix + 1) bin_m) and the same for y. Both upper
// ends are rounded up to whole bins. A point with either coordinate NaN is
// ignored; a finite or infinite point outside the grid is `outside`. Empty
// (nx = ny = 0, nothing counted) for the fail-safe cases of MakeHistogram,
// or when xs and ys differ in length.
struct Histogram2D {
  double x_lo = 0.0, y_lo = 0.0, bin_m = 0.0;
  int nx = 0, ny = 0;
  std::vector<int64_t> counts;  // Row-major: y, then x.
  int64_t outside = 0;
};
Histogram2D MakeHistogram2D(const std::vector<double>& xs, const std::vector<double>& ys,
                            double x_lo, double x_hi, double y_lo, double y_hi, double bin_m);

// Scatter of the fixes of a robot that does not move. A fix is outside the
// tolerance when |x - mean_x| > tolerance_m OR |y - mean_y| > tolerance_m
// (a square, as the reference drew it, not a circle). Reference (Fig. 7):
// 1172 fixes, std 0.38 cm in x and 0.49 cm in y, tolerance 1.5 cm.
struct Repeatability {
  int n = 0;
  double mean_x_m = 0.0, mean_y_m = 0.0, std_x_m = 0.0, std_y_m = 0.0;
  double share_outside = 0.0;  // Of n, in [0, 1].
  double tolerance_m = 0.0;
  // The largest per-axis deviation from the mean, max(|dx|, |dy|), so
  // share_outside is 0 exactly when max_deviation_m <= tolerance_m.
  double max_deviation_m = 0.0;
  // Spans mean +- 2 tolerance_m per axis, widened outward to multiples of
  // bin_m (bin edges on a fixed grid, whatever the mean); fixes beyond it
  // are `outside`. Empty with no fixes, tolerance_m <= 0 or bin_m <= 0.
  Histogram2D histogram;
};
Repeatability ComputeRepeatability(const std::vector<TimedPosition>& samples,
                                   double tolerance_m = 0.015, double bin_m = 0.001);

// Whether a recording is of a robot standing still, so its spread is
// repeatability and not motion: true when the 90% of fixes nearest the
// median position (per-axis median) lie within max_extent_m of it. Up to
// 10% of the fixes may be anywhere (mis-detections); a robot that moves
// more than max_extent_m for more than 10% of the recording is not static.
// False with no finite fixes.
bool LooksStatic(const std::vector<TimedPosition>& samples, double max_extent_m = 0.05);

// Intervals between successive fix times (the camera cycle). Reference:
// mean 236 ms, std 22.9 ms, in whole camera frames of 33.3 ms (30 Hz).
struct Timing {
  int intervals = 0;
  double mean_ms = 0.0, std_ms = 0.0, min_ms = 0.0, max_ms = 0.0, median_ms = 0.0;
  // Bins of 1 ms from 0 up to the 99.5th percentile's bin, at least 10
  // bins: a rare long gap (a dropout) would otherwise squeeze the frame
  // peaks into a few pixels; it is counted in `above` (about 0.5%).
  Histogram interval_ms;
  // Intervals rounded to the nearest whole frame: counts[k] is the number
  // of intervals of k frames (lo = 0, bins of 1 frame), up to the 99.5th
  // percentile's frame count, at least 10 bins. Empty when frame_rate_hz
  // is not positive and finite.
  Histogram interval_frames;
  double frame_period_ms = 0.0;  // 1000 / frame_rate_hz; 0 when invalid.
  double rate_hz = 0.0;          // 1000 / mean_ms; 0 when mean_ms is 0.
};
// `utimes` in any order (a sorted copy is used). Equal utimes give intervals
// of 0 ms, kept: they are in the data. Fewer than two utimes: no intervals,
// zero statistics and empty histograms.
Timing ComputeTiming(const std::vector<int64_t>& utimes, double frame_rate_hz = 30.0);

// Negative latencies are kept: they show clocks that disagree. All zero for
// no finite values.
struct LatencySummary {
  int n = 0;
  double mean_ms = 0.0, median_ms = 0.0, p95_ms = 0.0, max_ms = 0.0;
};
LatencySummary SummariseLatency(const std::vector<double>& latencies_ms);

// Path along the track in its given order. A step runs from the last used
// fix to the next one whose utime is later; a fix with a utime not after the
// last used one (a duplicate or out of order) or a non-finite position is
// skipped. Speed of a step = length / dt; mean and std are over steps
// (unweighted; distance_m / duration_s is the time-weighted mean, the same
// for regular sampling). Failure modes: chords cut corners, so a curve
// sampled every theta radians is shortened by about theta^2 / 24; and
// position noise adds path, so a static robot with noise sigma per axis
// shows steps of about sigma sqrt(pi) and a speed that is not zero.
struct Motion {
  int steps = 0;
  double distance_m = 0.0, duration_s = 0.0;
  double mean_speed_mps = 0.0, std_speed_mps = 0.0, max_speed_mps = 0.0;
};
Motion ComputeMotion(const std::vector<TimedPosition>& track);

// Error of one estimate against the reference at the estimate's own time;
// dx_m, dy_m = estimate - reference.
struct ErrorSample {
  int64_t utime = 0;
  double error_m = 0.0;
  double dx_m = 0.0, dy_m = 0.0;
};
// One sample per estimate that CompareToReference would compare (finite,
// and InterpolateTrack finds the reference there), in the estimates' order.
// `reference` in any order (a sorted copy is used when it is not sorted).
std::vector<ErrorSample> ErrorsOverTime(const std::vector<TimedPosition>& estimates,
                                        const std::vector<TimedPosition>& reference,
                                        int64_t max_gap_us);

// The constant offset between two sources on one robot (the reference used
// the camera as the reference for ultrasound): mean and std of
// track - reference over the matched fixes (as in ErrorsOverTime), and
// CompareToReference of the track with the mean offset removed, which is
// what is left once a mounting offset or a misaligned frame is corrected.
// A std_dx_m or std_dy_m well above the two sources' noise means the offset
// is not constant (a rotation or scale between the frames, or a time
// offset while moving), which this does not model.
struct TrackOffset {
  int matched = 0;
  double mean_dx_m = 0.0, mean_dy_m = 0.0, std_dx_m = 0.0, std_dy_m = 0.0;
  ErrorSummary error_after_offset;
};
TrackOffset CompareTracks(const std::vector<TimedPosition>& track,
                          const std::vector<TimedPosition>& reference, int64_t max_gap_us);

}  // namespace roomfix::analysis

#endif  // ROOMFIX_CORE_ANALYSIS_TRACK_STATS_H_
