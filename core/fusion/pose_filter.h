#ifndef ROOMFIX_CORE_FUSION_POSE_FILTER_H_
#define ROOMFIX_CORE_FUSION_POSE_FILTER_H_

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <deque>
#include <limits>
#include <string>
#include <vector>

#include "core/world/pose_source.h"

namespace roomfix {
namespace fusion {

// One pose measurement as the filter takes it.
struct Measurement {
  // When the measurement is valid (frame capture, beacon firing), microseconds.
  int64_t utime = 0;
  // Which sensor: kCamera or kUltrasound (any other is kInvalid).
  PoseSource source = PoseSource::kCamera;
  // Which camera measured it (the site's camera id; -1 for ultrasound).
  // Several cameras each count as their own measurement; when two see the
  // robot at the same instant (synchronised frames) the id orders them, so
  // any arrival order still gives one result.
  int camera_id = -1;
  // Passed through to the estimate (frame or firing number, -1 for none).
  int64_t seq = -1;
  // Position in the room frame, m.
  Eigen::Vector2d position_m = Eigen::Vector2d::Zero();
  // Covariance of position_m, m^2. Must be finite and symmetric; the
  // filter inflates it and floors its eigenvalues (see PoseFilterOptions).
  Eigen::Matrix2d position_cov_m2 = Eigen::Matrix2d::Identity();
  // Camera only: one sigma per axis, m, of the part of position_cov_m2 that
  // is the robot's slowly varying camera error (its tilt: marker height x
  // tilt sigma, the term camera_proc adds, docs/camera.md), not new noise
  // in every frame. The filter takes it out of the measurement's white
  // noise and models it as the bias state instead (PoseFilterOptions::
  // camera_bias_sigma_m); it removes at most that sigma. 0: all white.
  double correlated_sigma_m = 0.0;
  // Heading, radians, and its variance, rad^2; either one NaN (or a
  // non-positive variance) means the heading is unknown and only the
  // position is used.
  double heading_rad = std::numeric_limits<double>::quiet_NaN();
  double heading_var_rad2 = std::numeric_limits<double>::quiet_NaN();
};

struct PoseFilterOptions {
  // Process noise of the coordinated-turn model: white acceleration of
  // power spectral density q_accel^2 (m^2/s^3) on each position axis, white
  // angular acceleration of density q_turn^2 (rad^2/s^3) on the heading.
  // Chosen on the reference circle and the live simulator (docs/fusion.md);
  // larger values follow sudden starts better and smooth the camera less.
  // Units: a density of q^2 m^2/s^3 makes q itself m/s^1.5 (m/s^2/sqrt(Hz)),
  // rad/s^1.5 for the turn; not an acceleration, whatever the flag says.
  double q_accel_m_per_s1_5 = 0.03;
  double q_turn_rad_per_s1_5 = 0.3;

  // Measurement noise. Each covariance is multiplied by the source's
  // inflation factor, then its eigenvalues are raised to at least the
  // floor's square. Both sources' covariances are calibrated against ground
  // truth (camera: its calibration's measured pixel error; trilateration:
  // docs/trilateration.md), so the factors are 1 and the floors only guard
  // against a degenerate covariance, below either source's noise (camera
  // 0.12 mm, ultrasound 1-2 cm in the demo; docs/fusion.md).
  double camera_inflation = 1.0;
  double camera_sigma_floor_m = 0.00005;
  // Several cameras: the error of each camera's calibration, m, added in
  // quadrature to every camera position's covariance (before inflation and
  // floor). A camera's covariance is its pixel noise through the mapping
  // only; the calibration's own error is the same for every frame, so two
  // cameras seeing a robot in their overlap disagree by it (about 1 mm for
  // config/sites/two_cameras.yaml, 0.35 to 0.56 mm each from the truth), and
  // without it the second camera's poses are gated while the first holds
  // the track. 0 (the default) leaves one camera's covariance as it is.
  double camera_calibration_sigma_m = 0.0;

  // The camera's correlated error (docs/fusion.md, "Correlated camera
  // error"): a robot's tilt moves its marker over the floor by marker height
  // x tilt, the same in consecutive frames, which frame averaging cannot
  // remove. The filter models it as a bias b (x, y) seen by every camera
  // measurement (z = position + b + white noise) and not by the ultrasound:
  // a first-order Gauss-Markov process, stationary sigma
  // camera_bias_sigma_m per axis, correlation time camera_bias_time_s
  // (b' = e^(-dt/tau) b, added variance sigma^2 (1 - e^(-2 dt/tau))).
  // The sigma comes from the site (FusionNode: the robot's marker height x
  // tilt sigma); 0 (or a time of 0) leaves the bias out: every camera error
  // white, the filter of before. The time: a robot's tilt changes as it
  // rolls over the floor's unevenness and as it speeds up, slows and turns,
  // all on the time it takes to drive its own length (~1 s at 0.2 m/s);
  // a still robot's lean does not change at all. The shortest of these is
  // the cautious choice: a longer time lets the ultrasound average the bias
  // over longer than it stays.
  double camera_bias_sigma_m = 0.0;
  double camera_bias_time_s = 1.0;
  double ultrasound_inflation = 1.0;
  double ultrasound_sigma_floor_m = 0.005;
  double heading_sigma_floor_rad = 0.001;

  // Initial uncertainty of what a measurement does not give.
  double initial_speed_sigma_mps = 0.5;
  double initial_turn_rate_sigma_radps = 1.0;

  // Gating: a position whose squared Mahalanobis innovation exceeds the
  // 2-dof chi-square quantile is rejected with its heading; a heading whose
  // own innovation exceeds the 1-dof quantile is not used (the position
  // is). The defaults are the 99.9 % quantiles. After reopen_after_rejections
  // consecutive heading rejections the heading restarts from the
  // measurement (a robot turning on the spot).
  double gate_chi2_2dof = 13.82;
  double gate_chi2_1dof = 10.83;
  // The gate reopens (the filter re-initialises from the measurement) after
  // this many consecutive rejections of one source: of the camera at once,
  // of the ultrasound only when no camera measurement came for lost_after_s
  // (the camera is preferred).
  int reopen_after_rejections = 5;
  // Or after at least two consecutive rejections of one source spanning
  // this long (measurement time), whichever comes first: five frames are
  // 0.13 s at 30 fps but 0.5 to 1.5 s at the 3 to 10 fps a loaded hall
  // leaves (docs/fusion.md, "The hall"), long enough for the robot to be
  // lost. 0: the count alone.
  double reopen_after_s = 0.15;
  // The track is lost, and the next measurement re-initialises it, when no
  // measurement was accepted for lost_after_s or when the predicted position
  // standard deviation (largest axis) exceeds lost_sigma_m.
  double lost_after_s = 1.0;
  double lost_sigma_m = 0.5;

  // Status of an estimate: degraded when no camera measurement was accepted
  // for degraded_after_s (ultrasound only) or when the position standard
  // deviation exceeds degraded_sigma_m.
  double degraded_after_s = 0.5;
  double degraded_sigma_m = 0.1;
  // The heading is reported unknown (NaN) while its standard deviation
  // exceeds this.
  double heading_unknown_sigma_rad = 0.5;

  // Late measurements: the filter keeps this much history (by measurement
  // time, behind the newest) and re-filters from a late measurement's place;
  // one older than the history is refused as too late. A measurement more
  // than max_future_s ahead of the caller's clock is refused.
  double history_s = 1.0;
  double max_future_s = 1.0;

  bool IsValid(std::string* error) const;
};

// What the filter did with a measurement.
enum class Outcome {
  kAccepted,
  // Started the track (first measurement, or after it was lost).
  kInitialised,
  // The gate reopened: consecutive rejections re-initialised the track here.
  kReinitialised,
  // A camera position, inside the gate, of a track that no camera had
  // updated for lost_after_s (held by the ultrasound alone): the track
  // restarts from it instead of being updated (PoseFilter::Apply says why).
  kCameraTakeover,
  // Inconsistent with the track: not used.
  kGated,
  // Older than the history: dropped.
  kTooLate,
  // Further ahead of the clock than max_future_s: dropped.
  kFromFuture,
  // Non-finite position or covariance, or a source that is neither the
  // camera nor the ultrasound: dropped.
  kInvalid,
};
const char* OutcomeName(Outcome outcome);
// True when the measurement entered the history (accepted, initialised,
// reinitialised or gated); then there is an estimate at its time.
bool Entered(Outcome outcome);

enum class TrackStatus { kOk, kDegraded, kLost };

// State vector layout: [x, y, vx, vy, heading, heading_rate, bias_x,
// bias_y] in m, m/s, rad, rad/s, m. The bias is the camera's correlated
// error (PoseFilterOptions::camera_bias_sigma_m); x, y are the robot's
// position (the marker's floor point), which the output reports.
inline constexpr int kStateSize = 8;
using StateVector = Eigen::Matrix<double, kStateSize, 1>;
using StateCovariance = Eigen::Matrix<double, kStateSize, kStateSize>;
inline constexpr int kX = 0, kY = 1, kVx = 2, kVy = 3, kHeading = 4, kTurnRate = 5, kBiasX = 6,
                     kBiasY = 7;

// The filter's belief at one time.
struct Estimate {
  // False before the first measurement: nothing else is meaningful.
  bool valid = false;
  int64_t utime = 0;
  StateVector state = StateVector::Zero();
  StateCovariance covariance = StateCovariance::Zero();
  // False while the heading's standard deviation exceeds
  // heading_unknown_sigma_rad.
  bool heading_known = false;
  TrackStatus status = TrackStatus::kLost;
  // Measurements accepted in the second up to utime (within the history).
  int num_measurements = 0;
  // Norm of the position innovation of the measurement at utime, m (NaN for
  // predictions and initialisations).
  double innovation_m = std::numeric_limits<double>::quiet_NaN();
  int64_t seq = -1;
};

// An extended Kalman filter for one robot's planar pose.
//
// Model: rigid-body motion at constant speed and turn rate (coordinated
// turn): the velocity of the tracked point turns at the heading rate, which
// holds for any point of the body (the marker need not sit on the wheel axis,
// the robot may reverse); the direction of travel is not forced onto the
// heading. F is the transition's Jacobian; process noise is white
// acceleration on each position axis and white angular acceleration on the
// heading. With an unknown heading rate (ultrasound only) the turn rate stays
// near zero and the model is constant velocity. Heading and its innovation
// are wrapped to (-pi, pi].
// Measurements: h(x) = (x, y) (ultrasound), (x + bias_x, y + bias_y) or
// that and the heading (camera; the bias is the robot's tilt, which moves
// both markers alike and so not the heading).
//
// Each measurement is applied at its own time: the filter keeps the
// measurements of the last history_s, each with the state after it, ordered
// by time; a late one is inserted at its place and the later ones are
// applied again, so any arrival order within the history gives the same
// result as time order (bit for bit). The filter reads no clock: the
// caller's "now" is an argument.
class PoseFilter {
 public:
  explicit PoseFilter(const PoseFilterOptions& options);

  // Applies a measurement received at now_utime. Never throws; the outcome
  // says what happened to it. When it entered the history (Entered(outcome))
  // and after is given, *after is the estimate right after it, at its time.
  Outcome Add(const Measurement& measurement, int64_t now_utime, Estimate* after = nullptr);

  // The newest estimate predicted to utime (never backwards: an earlier
  // utime gives the newest estimate at its own time).
  Estimate Predict(int64_t utime) const;
  // The newest estimate, at the newest measurement's time.
  Estimate Latest() const;
  // The estimates after each measurement still in the history, oldest
  // first.
  std::vector<Estimate> History() const;

  bool initialised() const;
  // Measurement time of the newest accepted measurement (0 when none).
  int64_t last_accepted_utime() const;
  const PoseFilterOptions& options() const { return options_; }

 private:
  struct State {
    bool initialised = false;
    int64_t utime = 0;
    StateVector x = StateVector::Zero();
    StateCovariance p = StateCovariance::Zero();
    int64_t last_accept_utime = 0;
    int64_t last_camera_accept_utime = 0;
    int64_t last_camera_seen_utime = 0;
    bool camera_seen = false;
    bool camera_accepted = false;
    std::array<int, kNumPoseSources> consecutive_rejections{};
    // Measurement time of the first of those rejections.
    std::array<int64_t, kNumPoseSources> first_rejection_utime{};
    int heading_rejections = 0;
    double innovation_m = std::numeric_limits<double>::quiet_NaN();
    int64_t seq = -1;
  };
  struct Entry {
    Measurement measurement;
    Outcome outcome = Outcome::kAccepted;
    State after;
  };

  // Applies one measurement to the state before it.
  Outcome Apply(const Measurement& m, State* state) const;
  void Initialise(const Measurement& m, State* state) const;
  void PredictState(int64_t utime, State* state) const;
  Estimate MakeEstimate(const State& state, size_t entries_end) const;
  const State& Newest() const;

  PoseFilterOptions options_;
  // State after the newest measurement that left the history.
  State base_;
  std::deque<Entry> history_;
};

// Wraps an angle to (-pi, pi].
double WrapAngle(double angle_rad);

}  // namespace fusion
}  // namespace roomfix

#endif  // ROOMFIX_CORE_FUSION_POSE_FILTER_H_
