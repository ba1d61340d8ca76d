#include "core/analysis/fix_quality.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace roomfix::analysis {
namespace {

// Exact arithmetic on a few values: only rounding.
constexpr double kTight = 1e-9;

TEST(Chi2Quantile2Dof, IsTheClosedFormOfTheTwoDofQuantile) {
  EXPECT_NEAR(Chi2Quantile2Dof(0.95), 5.991464547, kTight);
  EXPECT_NEAR(Chi2Quantile2Dof(0.5), 2.0 * std::log(2.0), kTight);  // 1.386
}

TEST(SquaredMahalanobis2D, WeighsEachDirectionByItsVarianceAndRefusesSingularCovariances) {
  // Sigma = diag(1 cm^2, 4 cm^2): 1 cm along x and 2 cm along y are 1 each.
  EXPECT_NEAR(SquaredMahalanobis2D(0.01, 0.0, 1e-4, 0.0, 4e-4), 1.0, kTight);
  EXPECT_NEAR(SquaredMahalanobis2D(0.0, 0.02, 1e-4, 0.0, 4e-4), 1.0, kTight);
  // Correlated: Sigma = [2 1; 1 2], Sigma^-1 = [2 -1; -1 2] / 3; e = (1, 1)
  // lies along the long axis (eigenvalue 3): d2 = 2 / 3.
  EXPECT_NEAR(SquaredMahalanobis2D(1.0, 1.0, 2.0, 1.0, 2.0), 2.0 / 3.0, kTight);
  EXPECT_TRUE(std::isnan(SquaredMahalanobis2D(1.0, 0.0, 1.0, 1.0, 1.0)));  // det 0
  EXPECT_TRUE(std::isnan(SquaredMahalanobis2D(1.0, 0.0, NAN, 0.0, 1.0)));
  EXPECT_TRUE(std::isnan(SquaredMahalanobis2D(1.0, 0.0, -1.0, 0.0, -1.0)));
}

std::vector<TimedPosition> StillReference() {
  std::vector<TimedPosition> reference;
  for (int k = 0; k <= 100; ++k) reference.push_back({k * 10000, 1.0, 2.0});
  return reference;
}

TEST(AssessFixes, CountsStatusSharesWorstOkFixAndOwnEllipseCoverage) {
  const auto reference = StillReference();
  // Each fix has sigma 1 cm per axis; errors along x of 1, 2, 3 and 5 cm
  // give d2 = 1, 4, 9, 25: the first two inside the 95 % ellipse (5.99).
  std::vector<RatedFix> fixes = {
      {10000, 1.01, 2.0, false, 1e-4, 0.0, 1e-4},
      {20000, 1.02, 2.0, false, 1e-4, 0.0, 1e-4},
      {30000, 1.03, 2.0, true, 1e-4, 0.0, 1e-4},
      {40000, 1.05, 2.0, true, 1e-4, 0.0, 1e-4},
      // No covariance: in the accuracy, not in the coverage.
      {50000, 1.0, 2.04, false, NAN, NAN, NAN},
      // No reference at its time: counted in the shares only.
      {5000000, 9.0, 9.0, false, 1e-4, 0.0, 1e-4},
  };
  const FixQuality q = AssessFixes(fixes, /*lost=*/2, reference, 20000);
  EXPECT_EQ(q.fixes, 8);
  EXPECT_EQ(q.ok, 4);
  EXPECT_EQ(q.degraded, 2);
  EXPECT_EQ(q.lost, 2);
  EXPECT_NEAR(q.share_ok, 0.5, kTight);
  EXPECT_NEAR(q.share_degraded, 0.25, kTight);
  EXPECT_NEAR(q.share_lost, 0.25, kTight);
  EXPECT_EQ(q.compared, 5);
  EXPECT_NEAR(q.max_m, 0.05, kTight);
  // The 5 cm fix is degraded: the worst ok one is the 4 cm fix.
  EXPECT_NEAR(q.worst_ok_m, 0.04, kTight);
  EXPECT_NEAR(q.rmse_m, std::sqrt((1 + 4 + 9 + 25 + 16) * 1e-4 / 5), kTight);
  EXPECT_NEAR(q.p99_m, 0.05, kTight);
  EXPECT_EQ(q.with_covariance, 4);
  EXPECT_EQ(q.without_covariance, 1);
  EXPECT_EQ(q.inside_95, 2);
  EXPECT_NEAR(q.share_inside_95, 0.5, kTight);
  EXPECT_NEAR(q.median_d2, 4.0, kTight);  // nearest rank of {1, 4, 9, 25}
}

TEST(AssessFixes, FindsNinetyFivePercentInsideForACalibratedGaussianAndLessForAnOptimisticOne) {
  const auto reference = StillReference();
  std::mt19937 rng(7);
  std::normal_distribution<double> normal(0.0, 1.0);
  // Errors drawn from Sigma = [4 1.5; 1.5 1] cm^2 (Cholesky factor L).
  const double l11 = 0.02, l21 = 0.0075, l22 = std::sqrt(1e-4 - l21 * l21);
  std::vector<RatedFix> honest, optimistic;
  for (int k = 0; k < 4000; ++k) {
    const double n1 = normal(rng), n2 = normal(rng);
    const double dx = l11 * n1, dy = l21 * n1 + l22 * n2;
    const int64_t t = 1000 + (k % 900) * 1000;
    honest.push_back({t, 1.0 + dx, 2.0 + dy, false, 4e-4, 1.5e-4, 1e-4});
    // Reporting a quarter of the variance: the 95 % ellipse shrinks to the
    // true 52 % one (1 - exp(-5.991 / 8)).
    optimistic.push_back({t, 1.0 + dx, 2.0 + dy, false, 1e-4, 0.375e-4, 0.25e-4});
  }
  // 4000 draws: the binomial standard deviation of a 95 % share is 0.34 %;
  // 1.5 % is more than four of them.
  constexpr double kShareTolerance = 0.015;
  const FixQuality h = AssessFixes(honest, 0, reference, 20000);
  EXPECT_NEAR(h.share_inside_95, 0.95, kShareTolerance);
  // Median of chi-square(2) is 1.386; its sampling spread over 4000 draws
  // is about 0.04: 0.1 is two and a half of it. A quarter of the variance
  // reported makes every d2 (and the spread) four times larger.
  constexpr double kMedianTolerance = 0.1;
  constexpr double kOptimisticMedianTolerance = 0.4;
  EXPECT_NEAR(h.median_d2, 1.386, kMedianTolerance);
  const FixQuality o = AssessFixes(optimistic, 0, reference, 20000);
  EXPECT_NEAR(o.share_inside_95, 1.0 - std::exp(-5.991 / 8.0), kShareTolerance);
  EXPECT_NEAR(o.median_d2, 4.0 * 1.386, kOptimisticMedianTolerance);
}

}  // namespace
}  // namespace roomfix::analysis
