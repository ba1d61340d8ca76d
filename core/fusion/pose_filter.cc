#include "core/fusion/pose_filter.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <utility>

namespace roomfix {
namespace fusion {
namespace {

constexpr double kPi = 3.14159265358979323846;
// Variances the filter never lets grow past: an unknown heading is spread
// over the whole circle, a turn rate over two radians per second.
constexpr double kMaxHeadingVar_rad2 = kPi * kPi;
constexpr double kMaxTurnRateVar_rad2ps2 = 4.0;

double Micros(double seconds) { return seconds * 1e6; }

// Scales variable i so that its variance is at most max_var (P' = D P D,
// which keeps P positive semi-definite).
void CapVariance(int i, double max_var, StateCovariance* p) {
  const double var = (*p)(i, i);
  if (!(var > max_var)) return;
  const double s = std::sqrt(max_var / var);
  p->row(i) *= s;
  p->col(i) *= s;
}

bool IsPositiveDefinite(const Eigen::Matrix2d& m) {
  return m.allFinite() && m(0, 0) > 0.0 && m.determinant() > 0.0;
}

double PositionSigma(const StateCovariance& p) {
  const Eigen::Matrix2d block = p.topLeftCorner<2, 2>();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> solver(block, Eigen::EigenvaluesOnly);
  return std::sqrt(std::max(0.0, solver.eigenvalues().maxCoeff()));
}

// The measurement covariance after inflation and the floor.
Eigen::Matrix2d ConditionCovariance(const Eigen::Matrix2d& cov, double inflation, double floor_m) {
  const Eigen::Matrix2d symmetric = 0.5 * inflation * (cov + cov.transpose());
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> solver(symmetric);
  Eigen::Vector2d values = solver.eigenvalues();
  for (int i = 0; i < 2; ++i) values[i] = std::max(values[i], floor_m * floor_m);
  return solver.eigenvectors() * values.asDiagonal() * solver.eigenvectors().transpose();
}

bool BiasModelled(const PoseFilterOptions& o) {
  return o.camera_bias_sigma_m > 0.0 && o.camera_bias_time_s > 0.0;
}

}  // namespace

double WrapAngle(double angle_rad) {
  double a = std::remainder(angle_rad, 2.0 * kPi);  // [-pi, pi]
  if (a <= -kPi) a += 2.0 * kPi;
  return a;
}

const char* OutcomeName(Outcome outcome) {
  switch (outcome) {
    case Outcome::kAccepted:
      return "accepted";
    case Outcome::kInitialised:
      return "initialised";
    case Outcome::kReinitialised:
      return "reinitialised";
    case Outcome::kCameraTakeover:
      return "camera_takeover";
    case Outcome::kGated:
      return "gated";
    case Outcome::kTooLate:
      return "too_late";
    case Outcome::kFromFuture:
      return "from_future";
    case Outcome::kInvalid:
      return "invalid";
  }
  return "unknown";
}

bool Entered(Outcome outcome) {
  return outcome == Outcome::kAccepted || outcome == Outcome::kInitialised ||
         outcome == Outcome::kReinitialised || outcome == Outcome::kCameraTakeover ||
         outcome == Outcome::kGated;
}

bool PoseFilterOptions::IsValid(std::string* error) const {
  struct Check {
    double value;
    const char* name;
    bool allow_zero;
  };
  const Check checks[] = {
      {q_accel_m_per_s1_5, "q_accel_m_per_s1_5", false},
      {q_turn_rad_per_s1_5, "q_turn_rad_per_s1_5", false},
      {camera_inflation, "camera_inflation", false},
      {camera_sigma_floor_m, "camera_sigma_floor_m", false},
      {camera_calibration_sigma_m, "camera_calibration_sigma_m", true},
      {camera_bias_sigma_m, "camera_bias_sigma_m", true},
      {camera_bias_time_s, "camera_bias_time_s", true},
      {ultrasound_inflation, "ultrasound_inflation", false},
      {ultrasound_sigma_floor_m, "ultrasound_sigma_floor_m", false},
      {heading_sigma_floor_rad, "heading_sigma_floor_rad", false},
      {initial_speed_sigma_mps, "initial_speed_sigma_mps", false},
      {initial_turn_rate_sigma_radps, "initial_turn_rate_sigma_radps", false},
      {gate_chi2_2dof, "gate_chi2_2dof", false},
      {gate_chi2_1dof, "gate_chi2_1dof", false},
      {lost_after_s, "lost_after_s", false},
      {lost_sigma_m, "lost_sigma_m", false},
      {degraded_after_s, "degraded_after_s", true},
      {degraded_sigma_m, "degraded_sigma_m", false},
      {heading_unknown_sigma_rad, "heading_unknown_sigma_rad", false},
      {history_s, "history_s", true},
      {reopen_after_s, "reopen_after_s", true},
      {max_future_s, "max_future_s", true},
  };
  for (const Check& c : checks) {
    if (!std::isfinite(c.value) || c.value < 0.0 || (!c.allow_zero && c.value == 0.0)) {
      *error = std::string(c.name) + " must be finite and " +
               (c.allow_zero ? "not negative" : "positive");
      return false;
    }
  }
  // Times are turned into microseconds in int64_t: beyond a day they serve
  // no purpose and, near 9e12 s, would overflow.
  constexpr double kLongestTime_s = 86400.0;
  for (const auto& [value, name] :
       {std::pair{lost_after_s, "lost_after_s"}, std::pair{degraded_after_s, "degraded_after_s"},
        std::pair{history_s, "history_s"}, std::pair{reopen_after_s, "reopen_after_s"},
        std::pair{max_future_s, "max_future_s"},
        std::pair{camera_bias_time_s, "camera_bias_time_s"}}) {
    if (value > kLongestTime_s) {
      *error = std::string(name) + " must be at most a day (86400 s)";
      return false;
    }
  }
  if (reopen_after_rejections < 1) {
    *error = "reopen_after_rejections must be at least 1";
    return false;
  }
  return true;
}

PoseFilter::PoseFilter(const PoseFilterOptions& options) : options_(options) {
  base_.utime = std::numeric_limits<int64_t>::min();
}

bool PoseFilter::initialised() const { return Newest().initialised; }

int64_t PoseFilter::last_accepted_utime() const { return Newest().last_accept_utime; }

const PoseFilter::State& PoseFilter::Newest() const {
  return history_.empty() ? base_ : history_.back().after;
}

Outcome PoseFilter::Add(const Measurement& measurement, int64_t now_utime, Estimate* after) {
  // The filter models two sensors; a fused or ground-truth pose is no
  // measurement of it.
  if (measurement.source != PoseSource::kCamera && measurement.source != PoseSource::kUltrasound) {
    return Outcome::kInvalid;
  }
  if (!measurement.position_m.allFinite() || !IsPositiveDefinite(measurement.position_cov_m2)) {
    return Outcome::kInvalid;
  }
  if (static_cast<double>(measurement.utime) >
      static_cast<double>(now_utime) + Micros(options_.max_future_s)) {
    return Outcome::kFromFuture;
  }
  if (measurement.utime < base_.utime) return Outcome::kTooLate;

  // Condition the measurement once; the history keeps it conditioned.
  Measurement m = measurement;
  const bool camera = m.source == PoseSource::kCamera;
  if (camera) {
    // The correlated part goes into the bias state, so it leaves the white
    // noise: at most what the bias models (none when it is off), and the
    // floor below keeps what is left positive definite.
    const double correlated_m =
        BiasModelled(options_) && std::isfinite(m.correlated_sigma_m)
            ? std::clamp(m.correlated_sigma_m, 0.0, options_.camera_bias_sigma_m)
            : 0.0;
    m.correlated_sigma_m = correlated_m;
    m.position_cov_m2 += Eigen::Matrix2d::Identity() * (options_.camera_calibration_sigma_m *
                                                            options_.camera_calibration_sigma_m -
                                                        correlated_m * correlated_m);
  } else {
    m.correlated_sigma_m = 0.0;
  }
  m.position_cov_m2 = ConditionCovariance(
      m.position_cov_m2, camera ? options_.camera_inflation : options_.ultrasound_inflation,
      camera ? options_.camera_sigma_floor_m : options_.ultrasound_sigma_floor_m);
  if (std::isfinite(m.heading_rad) && std::isfinite(m.heading_var_rad2) &&
      m.heading_var_rad2 > 0.0) {
    m.heading_rad = WrapAngle(m.heading_rad);
    m.heading_var_rad2 = std::max(
        m.heading_var_rad2, options_.heading_sigma_floor_rad * options_.heading_sigma_floor_rad);
  } else {
    m.heading_rad = std::numeric_limits<double>::quiet_NaN();
    m.heading_var_rad2 = std::numeric_limits<double>::quiet_NaN();
  }

  // Insert after every entry that sorts before or equal to it, by (time,
  // source, camera): equal keys keep their arrival order.
  auto key_less = [](const Measurement& a, const Measurement& b) {
    if (a.utime != b.utime) return a.utime < b.utime;
    if (a.source != b.source) return static_cast<int>(a.source) < static_cast<int>(b.source);
    return a.camera_id < b.camera_id;
  };
  size_t index = history_.size();
  while (index > 0 && key_less(m, history_[index - 1].measurement)) --index;
  Entry entry;
  entry.measurement = m;
  history_.insert(history_.begin() + static_cast<std::ptrdiff_t>(index), entry);

  // Re-filter from the new measurement's place.
  State state = index == 0 ? base_ : history_[index - 1].after;
  for (size_t j = index; j < history_.size(); ++j) {
    history_[j].outcome = Apply(history_[j].measurement, &state);
    history_[j].after = state;
  }
  const Outcome outcome = history_[index].outcome;
  if (after != nullptr) *after = MakeEstimate(history_[index].after, index + 1);

  // Fold what fell out of the history into the base state.
  const double newest = static_cast<double>(history_.back().measurement.utime);
  while (!history_.empty() && static_cast<double>(history_.front().measurement.utime) <
                                  newest - Micros(options_.history_s)) {
    base_ = history_.front().after;
    history_.pop_front();
  }
  return outcome;
}

void PoseFilter::Initialise(const Measurement& m, State* state) const {
  const bool camera = m.source == PoseSource::kCamera;
  State s;
  s.initialised = true;
  s.utime = m.utime;
  s.x.setZero();
  s.x.head<2>() = m.position_m;
  s.p.setZero();
  s.p.topLeftCorner<2, 2>() = m.position_cov_m2;
  if (BiasModelled(options_)) {
    // The bias starts at its prior, 0 with its stationary variance. A camera
    // position is the robot's plus the bias: the robot's position is then
    // uncertain by both, and anti-correlated with the bias (x = z - b - w).
    const double b2 = options_.camera_bias_sigma_m * options_.camera_bias_sigma_m;
    s.p(kBiasX, kBiasX) = b2;
    s.p(kBiasY, kBiasY) = b2;
    if (camera) {
      s.p(kX, kX) += b2;
      s.p(kY, kY) += b2;
      s.p(kX, kBiasX) = s.p(kBiasX, kX) = -b2;
      s.p(kY, kBiasY) = s.p(kBiasY, kY) = -b2;
    }
  }
  const double v2 = options_.initial_speed_sigma_mps * options_.initial_speed_sigma_mps;
  s.p(kVx, kVx) = v2;
  s.p(kVy, kVy) = v2;
  if (std::isfinite(m.heading_rad)) {
    s.x[kHeading] = m.heading_rad;
    s.p(kHeading, kHeading) = m.heading_var_rad2;
  } else {
    s.p(kHeading, kHeading) = kMaxHeadingVar_rad2;
  }
  s.p(kTurnRate, kTurnRate) =
      std::min(kMaxTurnRateVar_rad2ps2,
               options_.initial_turn_rate_sigma_radps * options_.initial_turn_rate_sigma_radps);
  s.last_accept_utime = m.utime;
  s.camera_seen = state->camera_seen;
  s.last_camera_seen_utime = state->last_camera_seen_utime;
  s.camera_accepted = state->camera_accepted || camera;
  s.last_camera_accept_utime = camera ? m.utime : state->last_camera_accept_utime;
  s.seq = m.seq;
  *state = s;
}

void PoseFilter::PredictState(int64_t utime, State* state) const {
  const double dt = static_cast<double>(utime - state->utime) * 1e-6;
  if (!(dt > 0.0)) return;
  // Rigid-body motion at constant speed and turn rate: the velocity of any
  // point of the body (the marker, the beacon) turns at the body's turn
  // rate w. F is the Jacobian of that transition (with respect to w too).
  const double w = state->x[kTurnRate];
  const double th = w * dt;
  const double cos_th = std::cos(th), sin_th = std::sin(th);
  double s, c, ds_dw, dc_dw;
  if (std::abs(th) < 1e-6) {  // Series: no division by a vanishing w.
    s = dt - w * w * dt * dt * dt / 6.0;
    c = w * dt * dt / 2.0;
    ds_dw = -w * dt * dt * dt / 3.0;
    dc_dw = dt * dt / 2.0;
  } else {
    s = sin_th / w;
    c = (1.0 - cos_th) / w;
    ds_dw = (dt * cos_th * w - sin_th) / (w * w);
    dc_dw = (dt * sin_th * w - (1.0 - cos_th)) / (w * w);
  }
  const double vx = state->x[kVx], vy = state->x[kVy];
  StateCovariance f = StateCovariance::Identity();
  f(kX, kVx) = s;
  f(kX, kVy) = -c;
  f(kY, kVx) = c;
  f(kY, kVy) = s;
  f(kVx, kVx) = cos_th;
  f(kVx, kVy) = -sin_th;
  f(kVy, kVx) = sin_th;
  f(kVy, kVy) = cos_th;
  f(kX, kTurnRate) = vx * ds_dw - vy * dc_dw;
  f(kY, kTurnRate) = vx * dc_dw + vy * ds_dw;
  f(kVx, kTurnRate) = dt * (-sin_th * vx - cos_th * vy);
  f(kVy, kTurnRate) = dt * (cos_th * vx - sin_th * vy);
  f(kHeading, kTurnRate) = dt;
  StateVector next = state->x;
  next[kX] += s * vx - c * vy;
  next[kY] += c * vx + s * vy;
  next[kVx] = cos_th * vx - sin_th * vy;
  next[kVy] = sin_th * vx + cos_th * vy;
  next[kHeading] = WrapAngle(state->x[kHeading] + w * dt);
  // The camera bias decays towards 0 (first-order Gauss-Markov).
  double bias_decay = 1.0;
  if (BiasModelled(options_)) {
    bias_decay = std::exp(-dt / options_.camera_bias_time_s);
    f(kBiasX, kBiasX) = bias_decay;
    f(kBiasY, kBiasY) = bias_decay;
    next[kBiasX] *= bias_decay;
    next[kBiasY] *= bias_decay;
  }
  state->x = next;

  // Discretised white-acceleration noise for each (value, rate) pair.
  Eigen::Matrix2d block;
  block << dt * dt * dt / 3.0, dt * dt / 2.0, dt * dt / 2.0, dt;
  StateCovariance q = StateCovariance::Zero();
  const double qa = options_.q_accel_m_per_s1_5 * options_.q_accel_m_per_s1_5;
  const double qt = options_.q_turn_rad_per_s1_5 * options_.q_turn_rad_per_s1_5;
  const int pairs[3][2] = {{kX, kVx}, {kY, kVy}, {kHeading, kTurnRate}};
  for (int k = 0; k < 3; ++k) {
    const double density = k < 2 ? qa : qt;
    for (int r = 0; r < 2; ++r) {
      for (int col = 0; col < 2; ++col) {
        q(pairs[k][r], pairs[k][col]) = density * block(r, col);
      }
    }
  }
  if (BiasModelled(options_)) {
    // Keeps the bias's variance at its stationary value when unobserved.
    const double b2 = options_.camera_bias_sigma_m * options_.camera_bias_sigma_m;
    q(kBiasX, kBiasX) = b2 * (1.0 - bias_decay * bias_decay);
    q(kBiasY, kBiasY) = b2 * (1.0 - bias_decay * bias_decay);
  }
  state->p = f * state->p * f.transpose() + q;
  CapVariance(kHeading, kMaxHeadingVar_rad2, &state->p);
  CapVariance(kTurnRate, kMaxTurnRateVar_rad2ps2, &state->p);
  state->p = 0.5 * (state->p + state->p.transpose());
  state->utime = utime;
}

namespace {

// A Kalman update with the measurement h x + noise (covariance r); the
// heading component, if any (wrap_row >= 0), has its innovation wrapped.
// Returns false, changing nothing, when the squared Mahalanobis distance of
// the innovation exceeds gate. *innovation is the innovation's norm.
template <int N>
bool Update(const Eigen::Matrix<double, N, 1>& z, const Eigen::Matrix<double, N, kStateSize>& h,
            const Eigen::Matrix<double, N, N>& r, int wrap_row, double gate, StateVector* x,
            StateCovariance* p, double* innovation) {
  Eigen::Matrix<double, N, 1> y = z - h * (*x);
  if (wrap_row >= 0) y[wrap_row] = WrapAngle(y[wrap_row]);
  const Eigen::Matrix<double, N, N> s = h * (*p) * h.transpose() + r;
  const Eigen::LDLT<Eigen::Matrix<double, N, N>> ldlt(s);
  if (ldlt.info() != Eigen::Success) return false;
  const double d2 = y.dot(ldlt.solve(y));
  *innovation = y.norm();
  if (!(d2 <= gate)) return false;
  const Eigen::Matrix<double, kStateSize, N> k =
      (*p) * h.transpose() * ldlt.solve(Eigen::Matrix<double, N, N>::Identity());
  *x += k * y;
  (*x)[kHeading] = WrapAngle((*x)[kHeading]);
  const StateCovariance i_kh = StateCovariance::Identity() - k * h;
  *p = i_kh * (*p) * i_kh.transpose() + k * r * k.transpose();  // Joseph form.
  *p = 0.5 * (*p + p->transpose());
  return true;
}

}  // namespace

Outcome PoseFilter::Apply(const Measurement& m, State* state) const {
  const bool camera = m.source == PoseSource::kCamera;
  const int src = static_cast<int>(m.source);
  // Whether the ultrasound may reopen the gate: only when the camera, which
  // is preferred, has not spoken for lost_after_s.
  const bool camera_silent =
      !state->camera_seen ||
      static_cast<double>(m.utime - state->last_camera_seen_utime) > Micros(options_.lost_after_s);
  if (camera) {
    state->camera_seen = true;
    state->last_camera_seen_utime = m.utime;
  }
  if (!state->initialised ||
      static_cast<double>(m.utime - state->last_accept_utime) > Micros(options_.lost_after_s)) {
    Initialise(m, state);
    return Outcome::kInitialised;
  }
  PredictState(m.utime, state);
  if (PositionSigma(state->p) > options_.lost_sigma_m) {
    Initialise(m, state);
    return Outcome::kInitialised;
  }
  // Position first, gated on its own (2 degrees of freedom); then the
  // heading, gated on its own, so a robot turning on the spot or a
  // misread heading marker does not throw away a good position. With the
  // covariance block-diagonal this sequence equals the joint update.
  double innovation_m = std::numeric_limits<double>::quiet_NaN();
  Eigen::Matrix<double, 2, kStateSize> h_position = Eigen::Matrix<double, 2, kStateSize>::Zero();
  h_position(0, kX) = 1.0;
  h_position(1, kY) = 1.0;
  // A camera sees the robot's position plus the bias (zero and of zero
  // variance when the bias is not modelled); the ultrasound does not.
  if (camera) {
    h_position(0, kBiasX) = 1.0;
    h_position(1, kBiasY) = 1.0;
  }
  // A track the ultrasound alone has held (started by a firing, or no
  // camera accepted for lost_after_s) carries a velocity fitted to fixes
  // 10 to 100 times coarser than a camera's, and trilateration understates
  // a non-line-of-sight fix's error (the hall: a start 6 to 8 cm off with
  // a 1 cm sigma). Updated by the first camera frame, the whole innovation
  // (up to 19 cm, inside a gate widened by the 0.5 m/s velocity prior) goes
  // into a velocity then believed to 2 cm/s, and the next frames are gated
  // until the gate reopens (seen in the hall test: 0.5 to 1 s without a
  // fix at startup). A camera position inside the gate therefore restarts
  // such a track (the gate still refuses one far off, as before): all that
  // is lost is the ultrasound's velocity, which the next frames give 10 to
  // 100 times better.
  const bool camera_takes_over =
      camera &&
      (!state->camera_accepted || static_cast<double>(m.utime - state->last_camera_accept_utime) >
                                      Micros(options_.lost_after_s));
  StateVector x_updated = state->x;
  StateCovariance p_updated = state->p;
  const bool accepted = Update<2>(m.position_m, h_position, m.position_cov_m2, -1,
                                  options_.gate_chi2_2dof, &x_updated, &p_updated, &innovation_m);
  if (accepted && camera_takes_over) {
    Initialise(m, state);
    state->innovation_m = innovation_m;
    return Outcome::kCameraTakeover;
  }
  if (accepted) {
    state->x = x_updated;
    state->p = p_updated;
  }
  if (accepted && std::isfinite(m.heading_rad)) {
    Eigen::Matrix<double, 1, kStateSize> h_heading = Eigen::Matrix<double, 1, kStateSize>::Zero();
    h_heading(0, kHeading) = 1.0;
    double heading_innovation = 0.0;
    if (Update<1>(Eigen::Matrix<double, 1, 1>(m.heading_rad), h_heading,
                  Eigen::Matrix<double, 1, 1>(m.heading_var_rad2), 0, options_.gate_chi2_1dof,
                  &state->x, &state->p, &heading_innovation)) {
      state->heading_rejections = 0;
    } else if (++state->heading_rejections >= options_.reopen_after_rejections) {
      // The heading jumped (turn on the spot): restart it from the camera.
      state->heading_rejections = 0;
      state->x[kHeading] = m.heading_rad;
      state->x[kTurnRate] = 0.0;
      state->p.row(kHeading).setZero();
      state->p.col(kHeading).setZero();
      state->p.row(kTurnRate).setZero();
      state->p.col(kTurnRate).setZero();
      state->p(kHeading, kHeading) = m.heading_var_rad2;
      state->p(kTurnRate, kTurnRate) =
          std::min(kMaxTurnRateVar_rad2ps2,
                   options_.initial_turn_rate_sigma_radps * options_.initial_turn_rate_sigma_radps);
    }
  }
  state->innovation_m = innovation_m;
  state->seq = m.seq;
  if (accepted) {
    state->consecutive_rejections[src] = 0;
    state->last_accept_utime = m.utime;
    if (camera) {
      state->camera_accepted = true;
      state->last_camera_accept_utime = m.utime;
    }
    return Outcome::kAccepted;
  }
  if (state->consecutive_rejections[src]++ == 0) state->first_rejection_utime[src] = m.utime;
  // The time rule holds only for a run that no accepted measurement of any
  // source has interrupted: otherwise one stray camera pose gated long ago
  // and another now (misidentified or reflected, while the ultrasound holds
  // the track) would span reopen_after_s and restart the track on the
  // second. The count rule keeps counting across the other source's fixes,
  // as the camera's gate must reopen at a corner while the looser
  // ultrasound is still accepted.
  const bool long_enough = options_.reopen_after_s > 0.0 &&
                           state->consecutive_rejections[src] >= 2 &&
                           state->last_accept_utime < state->first_rejection_utime[src] &&
                           static_cast<double>(m.utime - state->first_rejection_utime[src]) >=
                               Micros(options_.reopen_after_s);
  if ((state->consecutive_rejections[src] >= options_.reopen_after_rejections || long_enough) &&
      (camera || camera_silent)) {
    Initialise(m, state);
    return Outcome::kReinitialised;
  }
  return Outcome::kGated;
}

Estimate PoseFilter::MakeEstimate(const State& state, size_t entries_end) const {
  Estimate e;
  e.valid = state.initialised;
  e.utime = state.utime;
  if (!e.valid) return e;
  e.state = state.x;
  e.covariance = state.p;
  e.innovation_m = state.innovation_m;
  e.seq = state.seq;
  e.heading_known = std::sqrt(state.p(kHeading, kHeading)) <= options_.heading_unknown_sigma_rad;
  const int64_t window_start = state.utime - 1000000;
  for (size_t j = 0; j < entries_end && j < history_.size(); ++j) {
    const Entry& entry = history_[j];
    if (entry.measurement.utime > window_start && entry.measurement.utime <= state.utime &&
        entry.outcome != Outcome::kGated) {
      ++e.num_measurements;
    }
  }
  const double sigma = PositionSigma(state.p);
  const double since_accept = static_cast<double>(state.utime - state.last_accept_utime);
  const double since_camera = static_cast<double>(state.utime - state.last_camera_accept_utime);
  if (since_accept > Micros(options_.lost_after_s) || sigma > options_.lost_sigma_m) {
    e.status = TrackStatus::kLost;
  } else if (!state.camera_accepted || since_camera > Micros(options_.degraded_after_s) ||
             sigma > options_.degraded_sigma_m) {
    e.status = TrackStatus::kDegraded;
  } else {
    e.status = TrackStatus::kOk;
  }
  return e;
}

Estimate PoseFilter::Predict(int64_t utime) const {
  State state = Newest();
  if (state.initialised && utime > state.utime) {
    PredictState(utime, &state);
    state.innovation_m = std::numeric_limits<double>::quiet_NaN();
  }
  return MakeEstimate(state, history_.size());
}

Estimate PoseFilter::Latest() const { return MakeEstimate(Newest(), history_.size()); }

std::vector<Estimate> PoseFilter::History() const {
  std::vector<Estimate> out;
  out.reserve(history_.size());
  for (size_t j = 0; j < history_.size(); ++j) {
    out.push_back(MakeEstimate(history_[j].after, j + 1));
  }
  return out;
}

}  // namespace fusion
}  // namespace roomfix
