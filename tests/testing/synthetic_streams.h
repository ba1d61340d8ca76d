#ifndef ROOMFIX_TESTS_TESTING_SYNTHETIC_STREAMS_H_
#define ROOMFIX_TESTS_TESTING_SYNTHETIC_STREAMS_H_

// Test support (header only): camera and ultrasound measurement streams of a
// robot on a trajectory, with noise, latency, outliers and outages, for the
// fusion tests of the filter and of the node.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "core/fusion/pose_filter.h"
#include "core/world/trajectory.h"

namespace roomfix {
namespace fusion {
namespace synthetic {

// 2023-11-14T22:13:20Z: any fixed epoch time.
inline constexpr int64_t kStartUtime = 1700000000000000;

struct StreamOptions {
  double duration_s = 40.0;
  int robot_id = 1;
  uint32_t seed = 1;

  // The ceiling camera: frame rate, noise (what it reports is what it has),
  // capture-to-receive latency.
  double camera_hz = 30.0;
  double camera_sigma_m = 0.001;
  double camera_heading_sigma_rad = 0.02;
  double camera_latency_s = 0.040;
  // The camera's correlated error (a robot's tilt: docs/fusion.md,
  // "Correlated camera error"): a bias on both axes, a first-order
  // Gauss-Markov process of stationary sigma camera_bias_sigma_m per axis
  // and correlation time camera_bias_time_s, plus a constant lean of
  // camera_bias_lean_m in a random direction (a still robot's tilt, which
  // never decorrelates). Every camera position carries it; the reported
  // covariance is camera_sigma_m^2 + camera_bias_sigma_m^2 +
  // camera_bias_lean_m^2 / 2 per axis (what camera_proc reports: its tilt
  // term), and Measurement::correlated_sigma_m says the correlated part, as
  // fusion_proc does from the site. Drawn from their own generator, so the
  // other noise does not depend on them.
  double camera_bias_sigma_m = 0.0;
  double camera_bias_time_s = 1.0;
  double camera_bias_lean_m = 0.0;

  // The ultrasound: firing rate, true noise, the sigma the trilateration
  // reports (calibrated, as trilat_proc's covariance is: set it lower for an
  // optimistic one), latency from firing to receive with a uniform
  // jitter on top, and outliers (a fraction of the firings off by
  // outlier_m in a random direction).
  double ultrasound_hz = 10.0;
  double ultrasound_sigma_m = 0.025;
  double ultrasound_reported_sigma_m = 0.025;
  double ultrasound_latency_s = 0.030;
  double ultrasound_latency_jitter_s = 0.040;
  double outlier_fraction = 0.02;
  double outlier_m = 0.30;

  // Outages [start, end) in seconds from the start: no camera frames, no
  // radio reports (so no ultrasound poses).
  double camera_outage_start_s = -1.0;
  double camera_outage_end_s = -1.0;
  double radio_outage_start_s = -1.0;
  double radio_outage_end_s = -1.0;

  // From this time on the robot is 2 m further along +x (carried away).
  double jump_at_s = -1.0;
  double jump_x_m = 2.0;
};

struct StreamItem {
  Measurement measurement;
  int64_t recv_utime = 0;
  int robot_id = 1;
  double truth_x_m = 0.0;
  double truth_y_m = 0.0;
  double truth_heading_rad = 0.0;
  bool outlier = false;
};

inline double SecondsSinceStart(int64_t utime) {
  return static_cast<double>(utime - kStartUtime) * 1e-6;
}

inline int64_t UtimeAt(double t_s) { return kStartUtime + std::llround(t_s * 1e6); }

// Ground truth of the stream's robot at t_s (with the jump).
inline GroundTruthPose TruthAt(const Trajectory& trajectory, const StreamOptions& o, double t_s) {
  GroundTruthPose pose = trajectory.PoseAt(t_s);
  if (o.jump_at_s >= 0.0 && t_s >= o.jump_at_s) pose.x_m += o.jump_x_m;
  return pose;
}

// Both streams, sorted by receive time.
inline std::vector<StreamItem> MakeStream(const Trajectory& trajectory, const StreamOptions& o) {
  std::mt19937 rng(o.seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  std::vector<StreamItem> items;
  auto in = [](double t, double a, double b) { return a >= 0.0 && t >= a && t < b; };

  // The bias's own generator and distributions (a normal distribution keeps
  // a spare draw, which must not pass between the generators).
  std::mt19937 bias_rng(o.seed + 7919u);
  std::normal_distribution<double> bias_normal(0.0, 1.0);
  std::uniform_real_distribution<double> bias_uniform(0.0, 1.0);
  const double lean_angle = 2.0 * 3.14159265358979 * bias_uniform(bias_rng);
  const Eigen::Vector2d lean =
      o.camera_bias_lean_m * Eigen::Vector2d(std::cos(lean_angle), std::sin(lean_angle));
  Eigen::Vector2d bias;
  bias.x() = o.camera_bias_sigma_m * bias_normal(bias_rng);  // one draw per line: a fixed order
  bias.y() = o.camera_bias_sigma_m * bias_normal(bias_rng);
  const double bias_decay =
      o.camera_bias_time_s > 0.0 ? std::exp(-1.0 / (o.camera_hz * o.camera_bias_time_s)) : 0.0;
  const double bias_step_sigma_m = o.camera_bias_sigma_m * std::sqrt(1.0 - bias_decay * bias_decay);
  const double correlated_var_m2 = o.camera_bias_sigma_m * o.camera_bias_sigma_m +
                                   0.5 * o.camera_bias_lean_m * o.camera_bias_lean_m;
  const int frames = static_cast<int>(o.duration_s * o.camera_hz);
  for (int k = 0; k < frames; ++k) {
    const double t = k / o.camera_hz;
    if (k > 0) {
      const double step_x = bias_normal(bias_rng);
      const double step_y = bias_normal(bias_rng);
      bias = bias_decay * bias + bias_step_sigma_m * Eigen::Vector2d(step_x, step_y);
    }
    const double cam_n1 = normal(rng), cam_n2 = normal(rng), cam_n3 = normal(rng);
    if (in(t, o.camera_outage_start_s, o.camera_outage_end_s)) continue;
    const GroundTruthPose truth = TruthAt(trajectory, o, t);
    StreamItem item;
    item.robot_id = o.robot_id;
    Measurement& m = item.measurement;
    m.utime = UtimeAt(t);
    m.source = PoseSource::kCamera;
    m.seq = k;
    m.position_m = {truth.x_m + o.camera_sigma_m * cam_n1, truth.y_m + o.camera_sigma_m * cam_n2};
    m.position_cov_m2 = Eigen::Matrix2d::Identity() * o.camera_sigma_m * o.camera_sigma_m;
    if (correlated_var_m2 > 0.0) {
      m.position_m += bias + lean;
      m.position_cov_m2 += Eigen::Matrix2d::Identity() * correlated_var_m2;
      m.correlated_sigma_m = std::sqrt(correlated_var_m2);
    }
    m.heading_rad = WrapAngle(truth.heading_rad + o.camera_heading_sigma_rad * cam_n3);
    m.heading_var_rad2 = o.camera_heading_sigma_rad * o.camera_heading_sigma_rad;
    item.recv_utime = m.utime + std::llround(o.camera_latency_s * 1e6);
    item.truth_x_m = truth.x_m;
    item.truth_y_m = truth.y_m;
    item.truth_heading_rad = truth.heading_rad;
    items.push_back(item);
  }
  const int firings = static_cast<int>(o.duration_s * o.ultrasound_hz);
  for (int k = 0; k < firings; ++k) {
    // Offset from the camera frames so no two measurements share a time.
    const double t = 0.0137 + k / o.ultrasound_hz;
    const double n1 = normal(rng), n2 = normal(rng), u1 = uniform(rng), u2 = uniform(rng),
                 u3 = uniform(rng);
    if (in(t, o.radio_outage_start_s, o.radio_outage_end_s)) continue;
    const GroundTruthPose truth = TruthAt(trajectory, o, t);
    StreamItem item;
    item.robot_id = o.robot_id;
    Measurement& m = item.measurement;
    m.utime = UtimeAt(t);
    m.source = PoseSource::kUltrasound;
    m.seq = k;
    m.position_m = {truth.x_m + o.ultrasound_sigma_m * n1, truth.y_m + o.ultrasound_sigma_m * n2};
    if (u1 < o.outlier_fraction) {
      const double angle = 2.0 * 3.14159265358979 * u2;
      m.position_m += o.outlier_m * Eigen::Vector2d(std::cos(angle), std::sin(angle));
      item.outlier = true;
    }
    m.position_cov_m2 =
        Eigen::Matrix2d::Identity() * o.ultrasound_reported_sigma_m * o.ultrasound_reported_sigma_m;
    item.recv_utime =
        m.utime + std::llround((o.ultrasound_latency_s + o.ultrasound_latency_jitter_s * u3) * 1e6);
    item.truth_x_m = truth.x_m;
    item.truth_y_m = truth.y_m;
    item.truth_heading_rad = truth.heading_rad;
    items.push_back(item);
  }
  std::stable_sort(items.begin(), items.end(), [](const StreamItem& a, const StreamItem& b) {
    return a.recv_utime < b.recv_utime;
  });
  return items;
}

// Merges streams (several robots) by receive time.
inline std::vector<StreamItem> Merge(std::vector<StreamItem> a, const std::vector<StreamItem>& b) {
  a.insert(a.end(), b.begin(), b.end());
  std::stable_sort(a.begin(), a.end(), [](const StreamItem& x, const StreamItem& y) {
    return x.recv_utime < y.recv_utime;
  });
  return a;
}

// Root mean square of a list of errors (0 for none).
inline double Rms(const std::vector<double>& errors) {
  if (errors.empty()) return 0.0;
  double sum = 0.0;
  for (double e : errors) sum += e * e;
  return std::sqrt(sum / static_cast<double>(errors.size()));
}

}  // namespace synthetic
}  // namespace fusion
}  // namespace roomfix

#endif  // ROOMFIX_TESTS_TESTING_SYNTHETIC_STREAMS_H_
