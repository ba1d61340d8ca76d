#include "core/calib/pose_covariance.h"

#include <gtest/gtest.h>

#include <cmath>

namespace roomfix::calib {
namespace {

// A pixel straight below a 3.1 m ceiling lens: about 3 mm on the floor.
PoseNoiseInputs Below() {
  PoseNoiseInputs in;
  in.pixel_sigma_px = 0.05;
  in.floor_per_px << 0.003, 0.0, 0.0, 0.003;
  return in;
}

constexpr double kRelTol = 1e-12;  // the same sums in another order
// Variances of ~1e-7 m^2 built from the same few products in another order:
// rounding is ~1e-23 m^2, an added term worth testing is >= 1e-8 m^2.
constexpr double kSumsTolM2 = 1e-15;
// A term that must add nothing: equal to the 2.25e-8 m^2 base up to rounding.
constexpr double kNothingAddedM2 = 1e-18;

TEST(PoseCovariance, AnIdealCameraIsTheCalibratedPixelNoiseThroughTheJacobian) {
  const PoseNoiseInputs in = Below();
  const Eigen::Matrix2d expected =
      in.pixel_sigma_px * in.pixel_sigma_px * in.floor_per_px * in.floor_per_px.transpose();
  // Bit for bit: with no webcam term the published covariance is unchanged.
  EXPECT_TRUE(PositionCovariance(in) == expected);
  EXPECT_TRUE(MarkerRelativeCovariance(in) == expected);
}

TEST(PoseCovariance, TiltAddsMarkerHeightTimesTiltOnBothAxes) {
  PoseNoiseInputs in = Below();
  in.marker_height_m = 0.2;
  in.tilt_sigma_rad = M_PI / 180.0;
  const Eigen::Matrix2d cov = PositionCovariance(in) - MarkerRelativeCovariance(in);
  // 0.2 m x 1 degree = 3.49 mm per axis (the "3.5 mm per degree").
  // The golden value is 3.49066 mm printed to four digits: a micrometre
  // covers that rounding.
  constexpr double kFourDigitsM = 1e-6;
  EXPECT_NEAR(std::sqrt(cov(0, 0)), 0.003491, kFourDigitsM);
  EXPECT_NEAR(std::sqrt(cov(1, 1)), 0.003491, kFourDigitsM);
  EXPECT_NEAR(cov(0, 1), 0.0, kRelTol);
}

TEST(PoseCovariance, TimingAndStreakActAlongTheVelocityOnly) {
  PoseNoiseInputs in = Below();
  in.velocity_mps = Eigen::Vector2d(0.2, 0.0);
  in.timing_sigma_s = 0.002;
  in.exposure_s = 0.02;
  in.blur_sigma_fraction = 0.1;
  const Eigen::Matrix2d base = PositionCovariance(Below());
  const Eigen::Matrix2d cov = PositionCovariance(in);
  // 2 ms x 0.2 m/s = 0.4 mm; 0.1 x (0.2 m/s x 20 ms) = 0.4 mm.
  EXPECT_NEAR(cov(0, 0) - base(0, 0), 0.0004 * 0.0004 * 2, kSumsTolM2);
  EXPECT_NEAR(cov(1, 1), base(1, 1), kNothingAddedM2);
  // The heading sees the streak but not the shared timing error.
  const Eigen::Matrix2d rel = MarkerRelativeCovariance(in);
  EXPECT_NEAR(rel(0, 0) - base(0, 0), 0.0004 * 0.0004, kSumsTolM2);
}

}  // namespace
}  // namespace roomfix::calib
