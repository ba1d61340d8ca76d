#include "core/world/trajectory.h"

#include <gtest/gtest.h>

#include <cmath>

namespace roomfix {
namespace {

constexpr double kPi = 3.14159265358979323846;
// Positions are closed-form; only rounding separates them from the maths.
constexpr double kExact_m = 1e-12;
// Central differences with h = 1e-4 s have O(h^2) error on these smooth paths.
constexpr double kFiniteDifference_mps = 1e-6;
// Headings are atan2 of closed-form velocities: double rounding.
constexpr double kExact_rad = 1e-12;
constexpr double kExact_mps = 1e-12;
// The circle's phase advanced by atan2 of two positions 0.1 m apart, each
// rounded to ~1e-16 m, over 300 s of drift: far below 1e-9 rad.
constexpr double kPhaseStep_rad = 1e-9;
// Waypoint positions reached after legs summed over time: the rounding of
// time x speed along several legs (and of sqrt(13) on the way back), a few
// ulps of metres with a wide margin.
constexpr double kAccumulated_m = 1e-9;
// The circle's speed at t = 0 is r |w| plus the centre's slow drift
// (CircleTrajectoryOptions' drift, under a millimetre per second).
constexpr double kDriftSpeed_mps = 1e-3;

double AngleDiff(double a, double b) { return std::remainder(a - b, 2 * kPi); }

// The velocity each trajectory reports is the derivative of its position,
// and the heading is the direction of that velocity.
void ExpectConsistentVelocityAndHeading(const Trajectory& t, double t0, double t1) {
  const double h = 1e-4;
  for (double s = t0; s <= t1; s += (t1 - t0) / 97) {
    const GroundTruthPose p = t.PoseAt(s);
    const GroundTruthPose a = t.PoseAt(s - h);
    const GroundTruthPose b = t.PoseAt(s + h);
    EXPECT_NEAR(p.vx_mps, (b.x_m - a.x_m) / (2 * h), kFiniteDifference_mps) << "t = " << s;
    EXPECT_NEAR(p.vy_mps, (b.y_m - a.y_m) / (2 * h), kFiniteDifference_mps) << "t = " << s;
    if (std::hypot(p.vx_mps, p.vy_mps) > 1e-3) {
      EXPECT_NEAR(AngleDiff(p.heading_rad, std::atan2(p.vy_mps, p.vx_mps)), 0.0, kExact_rad);
    }
  }
}

TEST(CircleTrajectory, DefaultsAreTheReferenceDrive) {
  std::string error;
  auto t = MakeCircleTrajectory(CircleTrajectoryOptions(), &error);
  ASSERT_NE(t, nullptr) << error;
  // At t = 0: centre (1.911, 1.496) m plus 0.419 m at the phase 3.163 rad.
  const GroundTruthPose p0 = t->PoseAt(0.0);
  EXPECT_NEAR(p0.x_m, 1.911 + 0.419 * std::cos(3.163), kExact_m);
  EXPECT_NEAR(p0.y_m, 1.496 + 0.419 * std::sin(3.163), kExact_m);
  // Speed on the circle: r |w| = 0.419 * 0.439 = 0.184 m/s (plus the drift).
  EXPECT_NEAR(std::hypot(p0.vx_mps, p0.vy_mps), 0.419 * 0.439, kDriftSpeed_mps);
}

TEST(CircleTrajectory, StaysOnTheDriftingCircleAndTurnsClockwise) {
  std::string error;
  const CircleTrajectoryOptions o;
  auto t = MakeCircleTrajectory(o, &error);
  ASSERT_NE(t, nullptr);
  double previous_angle = 0;
  for (int i = 0; i <= 600; ++i) {
    const double s = i * 0.5;
    const GroundTruthPose p = t->PoseAt(s);
    const double cx = o.cx_m + o.drift_x_mps * s;
    const double cy = o.cy_m + o.drift_y_mps * s;
    EXPECT_NEAR(std::hypot(p.x_m - cx, p.y_m - cy), o.radius_m, kExact_m);
    const double angle = std::atan2(p.y_m - cy, p.x_m - cx);
    if (i > 0) {
      // Half a second at -0.439 rad/s.
      EXPECT_NEAR(AngleDiff(angle, previous_angle), -0.439 * 0.5, kPhaseStep_rad);
    }
    previous_angle = angle;
  }
  ExpectConsistentVelocityAndHeading(*t, -5, 60);
}

TEST(CircleTrajectory, RejectsNonPositiveRadiusAndNonFiniteValues) {
  std::string error;
  CircleTrajectoryOptions o;
  o.radius_m = 0.0;
  EXPECT_EQ(MakeCircleTrajectory(o, &error), nullptr);
  EXPECT_EQ(error, "circle trajectory: radius_m must be positive");
  o = CircleTrajectoryOptions();
  o.angular_speed_radps = NAN;
  EXPECT_EQ(MakeCircleTrajectory(o, &error), nullptr);
}

TEST(StaticTrajectory, NeverMoves) {
  std::string error;
  auto t = MakeStaticTrajectory({1.25, 0.75, 0.5}, &error);
  ASSERT_NE(t, nullptr);
  for (double s : {-10.0, 0.0, 3.3, 1e6}) {
    const GroundTruthPose p = t->PoseAt(s);
    EXPECT_EQ(p.x_m, 1.25);
    EXPECT_EQ(p.y_m, 0.75);
    EXPECT_EQ(p.heading_rad, 0.5);
    EXPECT_EQ(p.vx_mps, 0.0);
    EXPECT_EQ(p.vy_mps, 0.0);
  }
}

TEST(WaypointTrajectory, VisitsEachPointAtItsTimeAndLoops) {
  std::string error;
  WaypointTrajectoryOptions o;
  o.points_m = {{0.5, 0.5}, {3.5, 0.5}, {3.5, 2.5}};
  o.speed_mps = 0.5;
  o.loop = true;
  auto t = MakeWaypointTrajectory(o, &error);
  ASSERT_NE(t, nullptr) << error;
  // Legs of 3 m, 2 m and sqrt(13) m back to the start.
  const double loop_s = (3.0 + 2.0 + std::sqrt(13.0)) / 0.5;
  auto at = [&](double s) { return t->PoseAt(s); };
  EXPECT_NEAR(at(0).x_m, 0.5, kExact_m);
  EXPECT_NEAR(at(6).x_m, 3.5, kAccumulated_m);
  EXPECT_NEAR(at(6).y_m, 0.5, kAccumulated_m);
  EXPECT_NEAR(at(10).y_m, 2.5, kAccumulated_m);
  EXPECT_NEAR(at(loop_s).x_m, 0.5, kAccumulated_m);
  EXPECT_NEAR(at(loop_s + 3).x_m, 2.0, kAccumulated_m);
  // Heading along the first leg is +x, along the second +y.
  EXPECT_NEAR(at(3).heading_rad, 0.0, kExact_rad);
  EXPECT_NEAR(at(8).heading_rad, kPi / 2, kExact_rad);
  EXPECT_NEAR(at(3).vx_mps, 0.5, kExact_mps);
}

TEST(WaypointTrajectory, StopsAtTheLastPointWithoutLoop) {
  std::string error;
  WaypointTrajectoryOptions o;
  o.points_m = {{0.0, 0.0}, {1.0, 0.0}};
  o.speed_mps = 0.25;
  o.loop = false;
  auto t = MakeWaypointTrajectory(o, &error);
  ASSERT_NE(t, nullptr);
  EXPECT_NEAR(t->PoseAt(100).x_m, 1.0, kExact_m);
  EXPECT_EQ(t->PoseAt(100).vx_mps, 0.0);
  EXPECT_NEAR(t->PoseAt(-3).x_m, 0.0, kExact_m);
}

TEST(WaypointTrajectory, RejectsASinglePlaceAndZeroSpeed) {
  std::string error;
  WaypointTrajectoryOptions o;
  o.points_m = {{1.0, 1.0}, {1.0, 1.0}};
  EXPECT_EQ(MakeWaypointTrajectory(o, &error), nullptr);
  EXPECT_EQ(error, "waypoint trajectory: needs at least two distinct points");
  o.points_m = {{0.0, 0.0}, {1.0, 1.0}};
  o.speed_mps = 0.0;
  EXPECT_EQ(MakeWaypointTrajectory(o, &error), nullptr);
}

TEST(FigureEightTrajectory, CrossesItsCentreTwicePerPeriod) {
  std::string error;
  FigureEightTrajectoryOptions o;
  auto t = MakeFigureEightTrajectory(o, &error);
  ASSERT_NE(t, nullptr);
  for (double s : {0.0, o.period_s / 2, o.period_s}) {
    EXPECT_NEAR(t->PoseAt(s).x_m, o.cx_m, kExact_m);
    EXPECT_NEAR(t->PoseAt(s).y_m, o.cy_m, kExact_m);
  }
  EXPECT_NEAR(t->PoseAt(o.period_s / 4).x_m, o.cx_m + o.half_width_m, kExact_m);
  ExpectConsistentVelocityAndHeading(*t, 0, o.period_s);
}

}  // namespace
}  // namespace roomfix
