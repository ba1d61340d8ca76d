#include "core/analysis/circle_fit.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "core/world/trajectory.h"

namespace roomfix::analysis {
namespace {

// A fitted parameter must be within this many of its own reported standard
// deviations of the truth: at 4 sigma a correct fit fails about once in
// 16 000 parameters, a wrong one (or a wrong sigma) fails at once.
constexpr double kSigmas = 4.0;
// A spread statistic of the drive's ~1020 points with 5 mm noise (residual
// std, Rayleigh mean and std): its sampling error is about
// 3-5 mm / sqrt(2 x 1020) ~ 0.1 mm; 0.5 mm is about 5 of those, 10 % of the
// noise.
constexpr double kNoiseStatisticTolM = 0.0005;

// The reference drive (core/world's defaults are the paper's fit), sampled
// as the reference camera did (4.26 Hz) for four minutes, with isotropic
// Gaussian noise of sigma_m on each coordinate.
std::vector<TimedPoint> ReferenceDrive(double sigma_m, uint64_t seed) {
  std::string error;
  auto circle = MakeCircleTrajectory(CircleTrajectoryOptions(), &error);
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0.0, sigma_m);
  std::vector<TimedPoint> points;
  for (double t = 0.0; t < 240.0; t += 1.0 / 4.26) {
    const GroundTruthPose p = circle->PoseAt(t);
    points.push_back({t, p.x_m + noise(rng), p.y_m + noise(rng)});
  }
  return points;
}

TEST(FitDriftingCircle, RecoversTheReferenceRadiusCentreAndDrift) {
  const CircleTrajectoryOptions truth;
  const auto points = ReferenceDrive(0.005, 1);
  const DriftingCircleFit fit = FitDriftingCircle(points);
  ASSERT_TRUE(fit.usable) << fit.message;
  EXPECT_NEAR(fit.radius_m, truth.radius_m, kSigmas * fit.radius_sigma_m);
  EXPECT_NEAR(fit.cx_m, truth.cx_m, kSigmas * fit.cx_sigma_m);
  EXPECT_NEAR(fit.cy_m, truth.cy_m, kSigmas * fit.cy_sigma_m);
  EXPECT_NEAR(fit.vx_mps, truth.drift_x_mps, kSigmas * fit.vx_sigma_mps);
  EXPECT_NEAR(fit.vy_mps, truth.drift_y_mps, kSigmas * fit.vy_sigma_mps);
  // The sigmas are small enough to mean something: the drift of 0.26 mm/s
  // is resolved.
  EXPECT_LT(fit.vx_sigma_mps, 0.05e-3);
  // The radial residual of 2D Gaussian noise has the per-axis sigma.
  EXPECT_NEAR(fit.residual_std_m, 0.005, kNoiseStatisticTolM);
}

TEST(FitCircularMotion, RecoversTheAngularSpeedAndPhase) {
  const CircleTrajectoryOptions truth;
  const auto points = ReferenceDrive(0.005, 2);
  const CircularMotionFit fit = FitCircularMotion(points);
  ASSERT_TRUE(fit.usable) << fit.message;
  EXPECT_NEAR(fit.angular_speed_radps, truth.angular_speed_radps,
              kSigmas * fit.angular_speed_sigma_radps);
  EXPECT_NEAR(fit.phase_rad, truth.phase_rad, kSigmas * fit.phase_sigma_rad);
  EXPECT_NEAR(fit.radius_m, truth.radius_m, kSigmas * fit.radius_sigma_m);
  EXPECT_NEAR(fit.cx_m, truth.cx_m, kSigmas * fit.cx_sigma_m);
  // The distance error of 2D Gaussian noise is Rayleigh: mean sigma
  // sqrt(pi/2) = 6.27 mm, std sigma sqrt(2 - pi/2) = 3.28 mm.
  EXPECT_NEAR(fit.mean_error_m, 0.00627, kNoiseStatisticTolM);
  EXPECT_NEAR(fit.std_error_m, 0.00328, kNoiseStatisticTolM);
}

TEST(FitDriftingCircle, SaysWhyItCannotFit) {
  const std::vector<TimedPoint> few = {{0, 0, 0}, {1, 1, 0}, {2, 0, 1}};
  EXPECT_FALSE(FitDriftingCircle(few).usable);
  EXPECT_EQ(FitDriftingCircle(few).message, "need at least 6 points for 5 parameters, got 3");
  std::vector<TimedPoint> line;
  for (int i = 0; i < 20; ++i) line.push_back({i * 1.0, i * 0.1, 0.5});
  const DriftingCircleFit fit = FitDriftingCircle(line);
  EXPECT_FALSE(fit.usable);
  EXPECT_EQ(fit.message, "degenerate: the points lie on a line");
  EXPECT_FALSE(FitCircularMotion(few).usable);
}

}  // namespace
}  // namespace roomfix::analysis
