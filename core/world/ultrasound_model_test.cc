#include "core/world/ultrasound_model.h"

#include <gtest/gtest.h>

#include <cmath>

#include "tests/testing/demo_site.h"
#include "tests/testing/test_paths.h"

namespace roomfix {
namespace {

// Tolerances, each for its reason.
// c(T) = 331.3 + 0.606 T m/s: at 0 degC the constant itself; at 20 degC a
// product and a sum of doubles, rounding of ~3e2 (~6e-14) with a margin.
constexpr double kExactMps = 1e-12;
constexpr double kClosedFormMps = 1e-9;
// Noise-free ranges and times of flight: a sqrt and a division of doubles.
constexpr double kExactM = 1e-12;
constexpr double kExactS = 1e-15;

class UltrasoundModelTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string error;
    ASSERT_TRUE(LoadSite(testing::DemoSitePath(), &site_, &error));
  }
  Site site_;
};

TEST(SpeedOfSound, Is343MetresPerSecondAt20Celsius) {
  EXPECT_NEAR(SpeedOfSound(20.0), 343.42, kClosedFormMps);
  EXPECT_NEAR(SpeedOfSound(0.0), 331.3, kExactMps);
}

TEST_F(UltrasoundModelTest, WithoutNoiseEachRangeIsTheTrueDistance) {
  UltrasoundNoise noise;
  noise.sigma_m = 0.0;
  std::mt19937_64 rng(1);
  const auto ranges = SimulateRanges(site_, {1.0, 2.0, 1.3}, 20.0, noise, &rng);
  ASSERT_EQ(ranges.size(), 4u);
  // Receiver 1 at (0, 0, 2.5): sqrt(1 + 4 + 1.44).
  EXPECT_EQ(ranges[0].receiver_id, 1);
  EXPECT_NEAR(ranges[0].measured_m, std::sqrt(6.44), kExactM);
  EXPECT_NEAR(ranges[0].time_of_flight_s, std::sqrt(6.44) / SpeedOfSound(20.0), kExactS);
}

TEST_F(UltrasoundModelTest, NoiseHasTheConfiguredSpreadAndOutliersOnlyLengthen) {
  UltrasoundNoise noise;
  noise.sigma_m = 0.02;
  std::mt19937_64 rng(3);
  double sum2 = 0;
  int n = 0;
  for (int i = 0; i < 5000; ++i) {
    for (const auto& r : SimulateRanges(site_, {2.0, 1.5, 1.3}, 20.0, noise, &rng)) {
      const double e = r.measured_m - std::sqrt(4.0 + 2.25 + 1.44);
      sum2 += e * e;
      ++n;
    }
  }
  // 20000 samples: the standard deviation is known to about 0.5 %
  // (sigma / sqrt(2 N)); 2.5 % of 0.02 m is five of those.
  constexpr double kSampleSigmaM = 0.0005;
  EXPECT_NEAR(std::sqrt(sum2 / n), 0.02, kSampleSigmaM);

  noise.sigma_m = 0.0;
  noise.nlos_probability = 1.0;
  for (const auto& r : SimulateRanges(site_, {2.0, 1.5, 1.3}, 20.0, noise, &rng)) {
    const double extra = r.measured_m - std::sqrt(4.0 + 2.25 + 1.44);
    EXPECT_GE(extra, 0.3);
    EXPECT_LE(extra, 1.0);
  }
  noise.dropout_probability = 1.0;
  EXPECT_TRUE(SimulateRanges(site_, {2.0, 1.5, 1.3}, 20.0, noise, &rng).empty());
}

}  // namespace
}  // namespace roomfix
