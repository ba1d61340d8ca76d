#ifndef ROOMFIX_CORE_SURVEY_RECEIVER_SURVEY_H_
#define ROOMFIX_CORE_SURVEY_RECEIVER_SURVEY_H_

#include <Eigen/Core>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

namespace roomfix::survey {

// Receiver survey and range calibration. Each receiver i has a position p_i
// (room frame, metres), a range offset b_i and optionally a range scale s_i;
// a raw range (time of flight times the speed of sound, before any offset is
// subtracted) from a beacon at q is modelled as
//
//   d_ij = s_i |p_i - q_j| + b_i + noise.
//
// With a reference track (camera, ground truth) q_j is known at each firing
// by interpolation, and the unknowns are (p_i, b_i[, s_i]). Without one, q_j =
// (x_j, y_j, h) with the beacon height h known becomes an unknown too
// (self-calibration); the result is then defined only up to a rigid motion of
// the floor plane, which two receivers with surveyed (pinned) positions fix,
// and up to the mirror image through the line joining them (the solution
// nearest the starting values is kept).
//
// Both are solved by Levenberg-Marquardt on the sum of squared residuals with
// the analytic Jacobian, then made robust by rejecting ranges whose residual
// exceeds k times the MAD-based sigma and refitting until the inlier set is
// stable. Uncertainties are sigma^2 (J^T J)^-1 at the solution, with sigma^2
// the inliers' residual variance (n - parameters degrees of freedom). The
// solver never throws: failures are in SurveyResult::usable and message.

inline constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// The starting values and, for the "before" evaluation, the site file's.
struct ReceiverModel {
  int id = 0;
  Eigen::Vector3d position_m = Eigen::Vector3d::Zero();
  double range_offset_m = 0.0;
  double range_scale = 1.0;

  // The geometric range from a raw one: (raw - offset) / scale.
  double Correct(double raw_range_m) const { return (raw_range_m - range_offset_m) / range_scale; }
};

struct RangeObservation {
  int receiver_id = 0;
  // Raw range, metres: no offset subtracted.
  double raw_range_m = 0.0;
};

// One beacon firing.
struct Firing {
  int64_t utime = 0;
  // Height of the beacon above the floor (from the site file).
  double beacon_height_m = 0.0;
  // The beacon's reference position at the firing (x, y from the reference,
  // z = beacon_height_m); NaN until AlignToReference sets it.
  Eigen::Vector3d reference_m = Eigen::Vector3d::Constant(kNaN);
  std::vector<RangeObservation> ranges;

  bool has_reference() const { return reference_m.allFinite(); }
};

struct ReferenceSample {
  int64_t utime = 0;
  double x_m = 0.0;
  double y_m = 0.0;
};

struct AlignmentSummary {
  int aligned = 0;
  // Firings before the first or after the last reference sample.
  int outside_span = 0;
  // Firings between two samples more than max_gap_us apart.
  int in_gap = 0;
};

// Sets each firing's reference_m by linear interpolation of `track` (sorted
// by utime or not) at the firing time; firings outside the track's span or in
// a gap longer than max_gap_us get NaN. z is the firing's beacon height.
AlignmentSummary AlignToReference(const std::vector<ReferenceSample>& track, int64_t max_gap_us,
                                  std::vector<Firing>* firings);

enum class ScaleMode {
  kOff,
  kOn,
  // Fit without, then with, a scale per receiver; keep the scales when the
  // ranges span at least min_range_span_for_scale_m for every receiver and
  // some scale differs from 1 by more than 3 sigma (a significant speed-of-
  // sound or clock error); otherwise they are not supported by the data.
  kAuto,
};

struct SurveyOptions {
  bool estimate_positions = true;
  // Receiver heights: with a beacon at one height the data holds |z_i - h|
  // only through the spread of horizontal distances; false keeps the site z.
  bool estimate_heights = true;
  bool estimate_offsets = true;
  ScaleMode scale = ScaleMode::kOff;
  double min_range_span_for_scale_m = 1.0;
  // Robust rejection: |residual - median| > outlier_k * 1.4826 * MAD, with the
  // sigma floored at min_sigma_m (noise-free data would reject everything).
  double outlier_k = 4.0;
  double min_sigma_m = 0.002;
  int max_rejection_rounds = 10;
  int max_iterations = 200;
  // Raw ranges outside (0, max_range_m] are input errors, not used.
  double max_range_m = 50.0;
  // Self-calibration only: receivers whose positions are held at their
  // surveyed values (at least two), and at most this many firings (evenly
  // subsampled; every firing adds two unknowns).
  std::vector<int> pinned_ids;
  int max_self_calibration_firings = 600;
  // A parameter whose 1-sigma exceeds this is reported as not determined.
  double undetermined_sigma_m = 0.05;

  bool IsValid(std::string* error) const;
};

struct ReceiverEstimate {
  int id = 0;
  Eigen::Vector3d position_m = Eigen::Vector3d::Zero();
  // 1-sigma per coordinate; 0 for coordinates held fixed.
  Eigen::Vector3d position_sigma_m = Eigen::Vector3d::Zero();
  double range_offset_m = 0.0;
  double range_offset_sigma_m = 0.0;
  double range_scale = 1.0;
  double range_scale_sigma = 0.0;
  bool position_estimated = false;
  bool height_estimated = false;
  bool scale_estimated = false;
  bool pinned = false;
  int ranges_used = 0;
  int ranges_rejected = 0;

  ReceiverModel Model() const { return {id, position_m, range_offset_m, range_scale}; }
};

struct SurveyResult {
  bool usable = false;
  // Why not usable, or "ok".
  std::string message;
  std::vector<ReceiverEstimate> receivers;
  int firings_used = 0;
  int ranges_used = 0;
  int ranges_rejected = 0;
  // Ranges not used at all: unknown receiver, non-finite or out of range.
  int ranges_invalid = 0;
  int parameters = 0;
  // RMS of the inliers' residuals and the robust sigma used for rejection.
  double residual_rms_m = kNaN;
  double sigma_m = kNaN;
  int iterations = 0;
  // Of the column-scaled J^T J: ratio of its largest to smallest eigenvalue,
  // and the number of eigenvalues below 1e-12 of the largest (directions the
  // data does not determine).
  double condition_number = kNaN;
  int null_directions = 0;
  bool scale_estimated = false;
  // What was and was not determined, and why choices were made (one line
  // each).
  std::vector<std::string> notes;

  const ReceiverEstimate* Find(int id) const;
  std::vector<ReceiverModel> Models() const;
};

// Reference mode: every firing with has_reference() is used; the others are
// skipped. `initial` gives the receivers to estimate and their start values.
SurveyResult SurveyWithReference(const std::vector<ReceiverModel>& initial,
                                 const std::vector<Firing>& firings, const SurveyOptions& options);

// Self-calibration: the beacon positions (x, y at beacon_height_m) are
// unknowns, started from trilateration with the initial receivers; the
// receivers in options.pinned_ids keep their initial positions (their offsets
// are still estimated). Needs at least 4 receivers heard per firing.
SurveyResult SurveyWithoutReference(const std::vector<ReceiverModel>& initial,
                                    const std::vector<Firing>& firings,
                                    const SurveyOptions& options);

// Held-out split: firings are cut into blocks of block_s seconds from the
// first; every `period`-th block (the last of each period) is held out.
void SplitByTime(const std::vector<Firing>& firings, double block_s, int period,
                 std::vector<Firing>* fit, std::vector<Firing>* held_out);

struct TrilaterationError {
  int firings = 0;
  int fixes = 0;
  double rmse_m = kNaN;
  double median_m = kNaN;
  double p95_m = kNaN;
  double max_m = kNaN;
  double mean_m = kNaN;
};

// Horizontal error of core/trilat's fixed-height 2D solver (kDefault) on the
// firings with a reference, using `receivers` to correct the raw ranges.
TrilaterationError EvaluateTrilateration(const std::vector<ReceiverModel>& receivers,
                                         const std::vector<Firing>& firings);

}  // namespace roomfix::survey

#endif  // ROOMFIX_CORE_SURVEY_RECEIVER_SURVEY_H_
