#ifndef ROOMFIX_CORE_TRILAT_TRILATERATION_H_
#define ROOMFIX_CORE_TRILAT_TRILATERATION_H_

#include <Eigen/Core>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

namespace roomfix::trilat {

// Position from ranges to receivers at known positions: the point p that
// minimises
//
//   F(p) = sum_i (|a_i - p| - d_i)^2
//
// over the receivers a_i that answered, with ranges d_i (metres, room frame).
//
// Dimensions:
//  - kFixedHeight2D: p = (x, y, h) with the beacon height h known (the usual
//    case: the beacon rides at a fixed height on its robot). Unknowns x, y.
//  - kPlanar2D: anchors and point in one plane; the anchors' z is ignored.
//  - k3D: x, y, z free. When the receivers are coplanar (all on one height,
//    the common installation), p and its mirror image through their plane fit
//    equally well; the solution on the room side is chosen and the fix says so.
//    Three receivers (always coplanar) are then enough: the fix is exactly
//    determined (flagged unchecked) and mirror-resolved.
enum class Dimension { kFixedHeight2D, kPlanar2D, k3D };

// kNelderMead: GSL's simplex (nmsimplex2) on F, as the reference paper did;
//   the baseline every benchmark compares against.
// kDefault: closed-form linear least-squares start (the range equations
//   |p|^2 - 2 a_i.p + |a_i|^2 = d_i^2 minus their mean, which removes |p|^2),
//   refined by Levenberg-Marquardt with the analytic Jacobian; warm-started
//   from a given point when there is one.
// kRobust: kDefault plus outlier rejection by consensus over receiver
//   subsets (see SolverOptions::outlier_threshold_m), for reflections and
//   non-line-of-sight paths, which only ever make a range longer.
// kCauchy: the M-estimator alternative to kRobust: kDefault's start, then
//   iteratively reweighted least squares with the Cauchy loss. Kept so the
//   benchmark can show which outlier strategy works better.
enum class Method { kNelderMead, kDefault, kRobust, kCauchy };

const char* MethodName(Method method);
bool ParseMethod(const std::string& name, Method* method);

struct RangeMeasurement {
  int receiver_id = 0;
  Eigen::Vector3d receiver_m = Eigen::Vector3d::Zero();
  double range_m = 0.0;
};

struct SolverOptions {
  Method method = Method::kDefault;
  Dimension dimension = Dimension::kFixedHeight2D;
  // Beacon height for kFixedHeight2D.
  double fixed_height_m = 0.0;
  // Standard deviation of a range, for the covariance and the default
  // outlier threshold.
  double range_sigma_m = 0.02;
  // Ranges above this are impossible in the room (its diagonal plus a
  // margin) and rejected as input errors.
  double max_range_m = std::numeric_limits<double>::infinity();
  // kRobust: a range whose residual exceeds this is an outlier. 0 means
  // 4 range_sigma_m, floored at 5 cm.
  double outlier_threshold_m = 0.0;
  // kRobust: at most this many ranges are rejected as outliers, and always
  // few enough that the rest still over-determine the position.
  int max_outliers = 2;
  // Work limits, so that one message costs a bounded time whatever it holds.
  // A set with more ranges than max_ranges fails at once (kTooManyRanges): a
  // room has a handful of receivers, and each range costs every solve. The
  // kRobust consensus search tries at most max_consensus_solves receiver
  // subsets (the exhaustive search over 2 outliers among 19 ranges is 190);
  // when it runs out it keeps the best consistent subset found so far, or
  // flags kConsensusBudgetExhausted. So a solve evaluates at most about
  // (max_consensus_solves + 9) * n * (max_iterations + 6) range residuals
  // plus the one-sided fallback's 20 rounds of 20 iterations (20 * 22 n):
  // the shared level and the NLOS belief add a few refits each, all linear
  // in n.
  //
  // Above max_consensus_ranges ranges kRobust does not search subsets at
  // all but reweights with a one-sided loss (ReweightOneSided in
  // trilateration.cc: a reflection only lengthens a range), whose work is
  // linear in the ranges, so no well-posed set is refused for its size:
  // max_ranges only bounds the memory one set may claim (an external test
  // suite's 100 anchors are fine, a hostile 800 solve in milliseconds).
  // 19 is where the exhaustive search over 2 outliers (190 subsets) still
  // fits max_consensus_solves.
  int max_ranges = 4096;
  int max_consensus_ranges = 19;
  int max_consensus_solves = 200;
  // A fix whose position standard deviation (the covariance's largest
  // eigenvalue, square-rooted) exceeds this is flagged: poor geometry.
  double max_position_sigma_m = 0.5;
  int max_iterations = 100;
  // k3D with coplanar receivers: a point on the room side of their plane.
  // NaN (the default) takes the floor below the receivers' centroid.
  Eigen::Vector3d room_side_point_m =
      Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());

  bool IsValid(std::string* error) const;
  // The outlier threshold in effect.
  double OutlierThreshold() const;
};

// Why a range was not used.
enum class RangeRejection : uint8_t {
  kNonFinite,
  kNegative,
  kTooLong,
  kDuplicateReceiver,
  kNonFiniteReceiver,
  // Long against the consensus fix by more than the outlier threshold: a
  // reflected path (the only way a range is excluded as an outlier).
  kOutlier,
};
const char* RangeRejectionName(RangeRejection reason);

struct RejectedRange {
  int receiver_id = 0;
  RangeRejection reason = RangeRejection::kOutlier;
};

enum class FixStatus : uint8_t {
  kOk,
  // A position, with a warning in `flags`.
  kDegraded,
  // No position: `flags` says why.
  kFailed,
};

// What happened, as bits of Fix::flags. The names (FixFlagName) are the
// STATUS counter names.
enum FixFlag : uint32_t {
  kTooFewRanges = 1u << 0,        // failed: fewer valid ranges than needed
  kCollinearReceivers = 1u << 1,  // failed: receivers on one line
  kDegenerateGeometry = 1u << 2,  // failed: the normal equations are singular
  kBadRangesDropped = 1u << 3,    // degraded: some input ranges were invalid
  kOutliersRejected = 1u << 4,    // degraded: the robust solver dropped ranges
  kInconsistentRanges = 1u << 5,  // degraded: no consistent subset was found
  kPoorGeometry = 1u << 6,        // degraded: covariance above the limit
  kNotConverged = 1u << 7,        // degraded: iteration limit reached
  kMirrorResolved = 1u << 8,      // note: coplanar receivers, room side chosen
  kTooManyRanges = 1u << 9,       // failed: more ranges than max_ranges
  // degraded: the consensus search stopped at max_consensus_solves with no
  // consistent subset among those tried.
  kConsensusBudgetExhausted = 1u << 10,
  // note: the beacon's temporal prior chose among subsets that the ranges
  // alone could not tell apart (or allowed an exactly determined subset).
  kPriorIdentified = 1u << 11,
  // degraded: no redundant range (as many ranges as unknowns), so no range
  // could be checked against the others; the covariance is grown (see Fix).
  kUnchecked = 1u << 12,
  // degraded: the fix is further from the temporal prior than the robot can
  // have moved; the covariance is grown to cover the prior's position.
  kPriorDisagrees = 1u << 13,
  // note (kRobust): the kept ranges share a positive offset (uncalibrated
  // receivers all reading long), estimated with the position and removed;
  // Fix::shared_level_m holds it.
  kSharedLevel = 1u << 14,
  // degraded (kRobust with an NLOS belief): a range from a receiver the
  // belief suspects was long and is in the fix with a one-sided (reduced)
  // weight, so the fix is not from all its ranges in full.
  kNlosSuspected = 1u << 15,
};
// The highest bit in use, for loops over the flags.
inline constexpr uint32_t kLastFixFlag = kNlosSuspected;
const char* FixFlagName(FixFlag flag);
// "too_few_ranges,collinear_receivers" for the flags set.
std::string DescribeFlags(uint32_t flags);

struct Fix {
  FixStatus status = FixStatus::kFailed;
  uint32_t flags = 0;
  // Room frame. For the 2D modes z is the fixed height (or 0 in kPlanar2D).
  Eigen::Vector3d position_m = Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
  // Covariance of (x, y, z), m^2, rows and columns of fixed coordinates
  // zero. From the range noise, sigma^2 (J^T J)^-1 at the solution, grown for
  // what the ranges could not check (docs/trilateration.md, "Covariance"):
  //  - unchecked (no redundant range): sigma^2 + t^2 / 3 per range, t the
  //    outlier threshold: a reflection shorter than t passes unseen, and
  //    uniform on [0, t] it has that mean square;
  //  - inconsistent ranges: scaled by (residual_rms / sigma)^2 when above 1,
  //    the a-posteriori variance factor;
  //  - prior disagrees: plus d^2 / 5.99 on the diagonal, d the distance to
  //    the prior, so that the prior's position is inside the 95% ellipse.
  Eigen::Matrix3d covariance_m2 = Eigen::Matrix3d::Zero();
  // The offset the kept ranges shared (kSharedLevel), m; 0 when none was
  // adopted. The ranges used were shortened by it.
  double shared_level_m = 0.0;
  // Ranges used minus unknowns: 0 is exactly determined (unchecked).
  int redundant_ranges = 0;
  // sqrt(F(p) / n) over the ranges used.
  double residual_rms_m = std::numeric_limits<double>::quiet_NaN();
  std::vector<int> used;
  std::vector<RejectedRange> rejected;
  int iterations = 0;
  // Range residuals evaluated (one |p - a_i| - d_i each): the solve's work,
  // independent of the machine, which is what its limits are tested in.
  int64_t range_evaluations = 0;
  // Subsets the kRobust consensus search solved.
  int consensus_solves = 0;

  bool has_position() const { return status != FixStatus::kFailed; }
};

// A fix is checked when its ranges over-determine it and agree, so that it
// can judge each of them: only such a fix may start or reset a beacon's
// prior or teach its NLOS belief.
bool IsCheckedFix(const Fix& fix);

// Where the beacon can be, from its own recent fixes (BeaconPrior): within
// radius_m of position_m.
struct PositionPrior {
  Eigen::Vector3d position_m = Eigen::Vector3d::Zero();
  double radius_m = 0.0;
};

// Solves one range set. `initial_guess`, when given (the previous fix of the
// same beacon), replaces the linear start. Never throws; every failure is in
// the returned Fix. `fix` is reused so that a caller in a loop does not
// allocate.
//
// `prior`, when given, only chooses (kRobust): among the range subsets the
// consensus admits it prefers those near the prior, it lets the search go
// down to exactly determined subsets (two long ranges among four in 2D, one
// among three), and a fix beyond it is flagged kPriorDisagrees. The position
// itself always comes from ranges alone.
void Solve(const std::vector<RangeMeasurement>& ranges, const SolverOptions& options,
           const Eigen::Vector3d* initial_guess, const PositionPrior* prior, Fix* fix);
// A receiver whose range the beacon's NlosBelief suspects to be an echo:
// the probability that it is, and the span its excess over the direct path
// is taken uniform on (the room's diagonal).
struct NlosSuspicion {
  int receiver_id = 0;
  double probability = 0.0;
  double echo_span_m = 5.0;
};

// `suspected_nlos`, when given (ascending receiver ids, from the beacon's
// NlosBelief), makes kRobust treat those receivers' ranges as probable
// echoes: a one-sided loss for them when they read long, and the subset
// without the long ones tried first (docs/trilateration.md, "NLOS belief").
void Solve(const std::vector<RangeMeasurement>& ranges, const SolverOptions& options,
           const Eigen::Vector3d* initial_guess, const PositionPrior* prior,
           const std::vector<NlosSuspicion>* suspected_nlos, Fix* fix);
void Solve(const std::vector<RangeMeasurement>& ranges, const SolverOptions& options,
           const Eigen::Vector3d* initial_guess, Fix* fix);
Fix Solve(const std::vector<RangeMeasurement>& ranges, const SolverOptions& options,
          const Eigen::Vector3d* initial_guess = nullptr);

// Cramer-Rao bound on the RMS position error of any unbiased estimator for
// a beacon at `position_m`, with independent Gaussian range noise of
// standard deviation sigma_m: sqrt(trace(I^-1)) with the Fisher information
// I = sum_i u_i u_i^T / sigma^2, u_i the unit vector from receiver i to the
// beacon restricted to the free coordinates of `dimension`. Infinite when I
// is singular.
double CramerRaoRmse(const std::vector<Eigen::Vector3d>& receivers_m,
                     const Eigen::Vector3d& position_m, double sigma_m, Dimension dimension);

}  // namespace roomfix::trilat

#endif  // ROOMFIX_CORE_TRILAT_TRILATERATION_H_
