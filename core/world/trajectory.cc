#include "core/world/trajectory.h"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <utility>

namespace roomfix {
namespace {

constexpr double kPi = 3.14159265358979323846;

bool AllFinite(std::initializer_list<double> values) {
  for (double v : values) {
    if (!std::isfinite(v)) return false;
  }
  return true;
}

bool Fail(std::string* error, const std::string& message) {
  if (error != nullptr) *error = message;
  return false;
}

// Heading of a velocity; when the robot stands still the heading is kept at
// the value the caller passes (there is no direction of travel to take).
double HeadingOf(double vx, double vy, double fallback_rad) {
  if (vx == 0.0 && vy == 0.0) return fallback_rad;
  return std::atan2(vy, vx);
}

class StaticTrajectory final : public Trajectory {
 public:
  explicit StaticTrajectory(const StaticTrajectoryOptions& o) : o_(o) {}
  GroundTruthPose PoseAt(double /*t_s*/) const override {
    return {o_.x_m, o_.y_m, o_.heading_rad, 0.0, 0.0};
  }
  std::string Describe() const override {
    std::ostringstream s;
    s << "static at (" << o_.x_m << ", " << o_.y_m << ") m, heading " << o_.heading_rad << " rad";
    return s.str();
  }

 private:
  StaticTrajectoryOptions o_;
};

class CircleTrajectory final : public Trajectory {
 public:
  explicit CircleTrajectory(const CircleTrajectoryOptions& o) : o_(o) {}
  GroundTruthPose PoseAt(double t_s) const override {
    const double angle = o_.angular_speed_radps * t_s + o_.phase_rad;
    const double c = std::cos(angle);
    const double s = std::sin(angle);
    GroundTruthPose p;
    p.x_m = o_.cx_m + o_.drift_x_mps * t_s + o_.radius_m * c;
    p.y_m = o_.cy_m + o_.drift_y_mps * t_s + o_.radius_m * s;
    // d/dt of the position: drift plus r w (-sin, cos).
    p.vx_mps = o_.drift_x_mps - o_.radius_m * o_.angular_speed_radps * s;
    p.vy_mps = o_.drift_y_mps + o_.radius_m * o_.angular_speed_radps * c;
    p.heading_rad = HeadingOf(p.vx_mps, p.vy_mps, 0.0);
    return p;
  }
  std::string Describe() const override {
    std::ostringstream s;
    s << "circle r " << o_.radius_m << " m, centre (" << o_.cx_m << ", " << o_.cy_m
      << ") m drifting (" << o_.drift_x_mps << ", " << o_.drift_y_mps << ") m/s, "
      << o_.angular_speed_radps << " rad/s, phase " << o_.phase_rad << " rad";
    return s.str();
  }

 private:
  CircleTrajectoryOptions o_;
};

class WaypointTrajectory final : public Trajectory {
 public:
  explicit WaypointTrajectory(const WaypointTrajectoryOptions& o) : o_(o) {
    // Legs between consecutive points (and back to the first when looping),
    // with the path length at the start of each.
    const size_t n = o_.points_m.size();
    const size_t legs = o_.loop ? n : n - 1;
    for (size_t i = 0; i < legs; ++i) {
      const auto& a = o_.points_m[i];
      const auto& b = o_.points_m[(i + 1) % n];
      const double length = std::hypot(b.first - a.first, b.second - a.second);
      if (length == 0.0) continue;  // A repeated point adds no leg.
      legs_.push_back({a, b, length, total_length_m_});
      total_length_m_ += length;
    }
  }

  GroundTruthPose PoseAt(double t_s) const override {
    double s = std::max(0.0, t_s) * o_.speed_mps;
    bool stopped = false;
    if (o_.loop) {
      s = std::fmod(s, total_length_m_);
    } else if (s >= total_length_m_) {
      s = total_length_m_;
      stopped = true;
    }
    // Legs are few (a hand-written path), so a linear scan is cheapest.
    size_t i = 0;
    while (i + 1 < legs_.size() && s >= legs_[i + 1].start_m) ++i;
    const Leg& leg = legs_[i];
    const double f = std::min(1.0, (s - leg.start_m) / leg.length_m);
    const double dx = leg.b.first - leg.a.first;
    const double dy = leg.b.second - leg.a.second;
    GroundTruthPose p;
    p.x_m = leg.a.first + f * dx;
    p.y_m = leg.a.second + f * dy;
    p.heading_rad = std::atan2(dy, dx);
    const bool moving = t_s >= 0.0 && !stopped;
    p.vx_mps = moving ? o_.speed_mps * dx / leg.length_m : 0.0;
    p.vy_mps = moving ? o_.speed_mps * dy / leg.length_m : 0.0;
    return p;
  }

  std::string Describe() const override {
    std::ostringstream s;
    s << "waypoints (" << o_.points_m.size() << " points, " << total_length_m_ << " m"
      << (o_.loop ? ", looping" : "") << ") at " << o_.speed_mps << " m/s";
    return s.str();
  }

 private:
  struct Leg {
    std::pair<double, double> a, b;
    double length_m;
    double start_m;
  };
  WaypointTrajectoryOptions o_;
  std::vector<Leg> legs_;
  double total_length_m_ = 0.0;
};

class FigureEightTrajectory final : public Trajectory {
 public:
  explicit FigureEightTrajectory(const FigureEightTrajectoryOptions& o) : o_(o) {}
  GroundTruthPose PoseAt(double t_s) const override {
    const double w = 2.0 * kPi / o_.period_s;
    const double s = std::sin(w * t_s);
    const double c = std::cos(w * t_s);
    GroundTruthPose p;
    p.x_m = o_.cx_m + o_.half_width_m * s;
    // sin cos = sin(2wt) / 2, whose derivative is w cos(2wt).
    p.y_m = o_.cy_m + o_.half_height_m * s * c;
    p.vx_mps = o_.half_width_m * w * c;
    p.vy_mps = o_.half_height_m * w * std::cos(2.0 * w * t_s);
    p.heading_rad = HeadingOf(p.vx_mps, p.vy_mps, 0.0);
    return p;
  }
  std::string Describe() const override {
    std::ostringstream s;
    s << "figure eight centred (" << o_.cx_m << ", " << o_.cy_m << ") m, " << 2 * o_.half_width_m
      << " x " << 2 * o_.half_height_m << " m, period " << o_.period_s << " s";
    return s.str();
  }

 private:
  FigureEightTrajectoryOptions o_;
};

}  // namespace

std::unique_ptr<Trajectory> MakeStaticTrajectory(const StaticTrajectoryOptions& o,
                                                 std::string* error) {
  if (!AllFinite({o.x_m, o.y_m, o.heading_rad})) {
    Fail(error, "static trajectory: position and heading must be finite");
    return nullptr;
  }
  return std::make_unique<StaticTrajectory>(o);
}

std::unique_ptr<Trajectory> MakeCircleTrajectory(const CircleTrajectoryOptions& o,
                                                 std::string* error) {
  if (!AllFinite({o.radius_m, o.cx_m, o.cy_m, o.drift_x_mps, o.drift_y_mps, o.angular_speed_radps,
                  o.phase_rad})) {
    Fail(error, "circle trajectory: every parameter must be finite");
    return nullptr;
  }
  if (o.radius_m <= 0.0) {
    Fail(error, "circle trajectory: radius_m must be positive");
    return nullptr;
  }
  return std::make_unique<CircleTrajectory>(o);
}

std::unique_ptr<Trajectory> MakeWaypointTrajectory(const WaypointTrajectoryOptions& o,
                                                   std::string* error) {
  if (!std::isfinite(o.speed_mps) || o.speed_mps <= 0.0) {
    Fail(error, "waypoint trajectory: speed_mps must be positive and finite");
    return nullptr;
  }
  for (const auto& p : o.points_m) {
    if (!AllFinite({p.first, p.second})) {
      Fail(error, "waypoint trajectory: every point must be finite");
      return nullptr;
    }
  }
  bool moves = false;
  for (size_t i = 1; i < o.points_m.size(); ++i) {
    moves = moves || o.points_m[i] != o.points_m[0];
  }
  if (!moves) {
    Fail(error, "waypoint trajectory: needs at least two distinct points");
    return nullptr;
  }
  return std::make_unique<WaypointTrajectory>(o);
}

std::unique_ptr<Trajectory> MakeFigureEightTrajectory(const FigureEightTrajectoryOptions& o,
                                                      std::string* error) {
  if (!AllFinite({o.cx_m, o.cy_m, o.half_width_m, o.half_height_m, o.period_s})) {
    Fail(error, "figure eight trajectory: every parameter must be finite");
    return nullptr;
  }
  if (o.half_width_m <= 0.0 || o.half_height_m <= 0.0 || o.period_s <= 0.0) {
    Fail(error, "figure eight trajectory: sizes and period must be positive");
    return nullptr;
  }
  return std::make_unique<FigureEightTrajectory>(o);
}

}  // namespace roomfix
