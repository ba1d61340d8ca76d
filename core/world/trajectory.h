#ifndef ROOMFIX_CORE_WORLD_TRAJECTORY_H_
#define ROOMFIX_CORE_WORLD_TRAJECTORY_H_

#include <memory>
#include <string>
#include <vector>

namespace roomfix {

// A robot's ground-truth pose on the floor at one instant, room frame.
struct GroundTruthPose {
  double x_m = 0.0;
  double y_m = 0.0;
  // Heading from +x towards +y, radians in (-pi, pi].
  double heading_rad = 0.0;
  // Velocity of the position point, metres per second.
  double vx_mps = 0.0;
  double vy_mps = 0.0;
};

// A robot's motion as a pure function of time: t_s is seconds since the
// simulation started (the caller maps its clock onto it, so a replay or a test
// sees the same poses). Every implementation is defined for all finite t_s,
// including negative ones, and is continuous in position.
class Trajectory {
 public:
  virtual ~Trajectory() = default;
  virtual GroundTruthPose PoseAt(double t_s) const = 0;
  // One line naming the kind and its parameters, for logs and reports.
  virtual std::string Describe() const = 0;
};

// Standing still at a point.
struct StaticTrajectoryOptions {
  double x_m = 0.0;
  double y_m = 0.0;
  double heading_rad = 0.0;
};

// A circle whose centre drifts at a constant velocity, with constant angular
// speed:
//   centre(t) = (cx_m, cy_m) + t (drift_x_mps, drift_y_mps)
//   p(t)      = centre(t) + radius_m (cos(w t + phase), sin(w t + phase))
// with w = angular_speed_radps (negative is clockwise seen from above). The
// defaults are the fit the reference paper reports for its test drive:
// r = 41.9 cm, centre (191.1, 149.6) cm drifting at (0.264, -0.096) mm/s,
// w = -0.439 rad/s, phase 3.163 rad. The heading is the direction of travel.
struct CircleTrajectoryOptions {
  double radius_m = 0.419;
  double cx_m = 1.911;
  double cy_m = 1.496;
  double drift_x_mps = 0.264e-3;
  double drift_y_mps = -0.096e-3;
  double angular_speed_radps = -0.439;
  double phase_rad = 3.163;
};

// Straight lines between waypoints at a constant speed, turning on the spot
// (heading jumps at each waypoint). With loop, the last waypoint leads back to
// the first and the path repeats; without, the robot stops at the last one.
// Before t = 0 the robot waits at the first waypoint.
struct WaypointTrajectoryOptions {
  std::vector<std::pair<double, double>> points_m;
  double speed_mps = 0.2;
  bool loop = true;
};

// A figure eight (lemniscate of Gerono):
//   x(t) = cx_m + half_width_m  sin(2 pi t / period_s)
//   y(t) = cy_m + half_height_m sin(2 pi t / period_s) cos(2 pi t / period_s)
// crossing itself at the centre twice per period.
struct FigureEightTrajectoryOptions {
  double cx_m = 2.0;
  double cy_m = 1.5;
  double half_width_m = 1.2;
  double half_height_m = 0.8;
  double period_s = 40.0;
};

// Constructors. Each validates its options and returns nullptr with a reason
// in *error when they cannot describe a motion (non-finite numbers, negative
// radius, fewer than two distinct waypoints, non-positive speed or period).
std::unique_ptr<Trajectory> MakeStaticTrajectory(const StaticTrajectoryOptions& options,
                                                 std::string* error);
std::unique_ptr<Trajectory> MakeCircleTrajectory(const CircleTrajectoryOptions& options,
                                                 std::string* error);
std::unique_ptr<Trajectory> MakeWaypointTrajectory(const WaypointTrajectoryOptions& options,
                                                   std::string* error);
std::unique_ptr<Trajectory> MakeFigureEightTrajectory(const FigureEightTrajectoryOptions& options,
                                                      std::string* error);

}  // namespace roomfix

#endif  // ROOMFIX_CORE_WORLD_TRAJECTORY_H_
