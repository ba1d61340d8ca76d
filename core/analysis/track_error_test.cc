#include "core/analysis/track_error.h"

#include <gtest/gtest.h>

#include <cmath>

namespace roomfix::analysis {
namespace {

TEST(InterpolateTrack, IsLinearBetweenSamplesAndRefusesGapsAndEnds) {
  const std::vector<TimedPosition> track = {{0, 0.0, 0.0}, {100, 1.0, 2.0}, {1000, 5.0, 5.0}};
  double x = 0, y = 0;
  ASSERT_TRUE(InterpolateTrack(track, 25, 200, &x, &y));
  EXPECT_DOUBLE_EQ(x, 0.25);
  EXPECT_DOUBLE_EQ(y, 0.5);
  ASSERT_TRUE(InterpolateTrack(track, 100, 200, &x, &y));
  EXPECT_DOUBLE_EQ(x, 1.0);
  EXPECT_FALSE(InterpolateTrack(track, 500, 200, &x, &y));  // 900 us gap.
  EXPECT_FALSE(InterpolateTrack(track, -1, 200, &x, &y));
  EXPECT_FALSE(InterpolateTrack(track, 1001, 200, &x, &y));
}

TEST(CompareToReference, MeasuresTheErrorAtEachEstimatesOwnTime) {
  // The reference moves along x at 1 m/s; estimates sit 3 cm off in y and
  // are valid at times between reference samples.
  std::vector<TimedPosition> reference;
  for (int k = 0; k <= 100; ++k) reference.push_back({k * 10000, k * 0.01, 0.0});
  std::vector<TimedPosition> estimates;
  for (int k = 0; k < 20; ++k)
    estimates.push_back({k * 45000 + 3000, (k * 45000 + 3000) * 1e-6, 0.03});
  estimates.push_back({5000000, 0, 0});    // After the reference ends.
  estimates.push_back({50000, NAN, NAN});  // A lost fix.
  const ErrorSummary s = CompareToReference(estimates, reference, 20000);
  EXPECT_EQ(s.compared, 20);
  EXPECT_EQ(s.unmatched, 2);
  EXPECT_NEAR(s.rmse_m, 0.03, 1e-12);
  EXPECT_NEAR(s.p95_m, 0.03, 1e-12);
  EXPECT_NEAR(s.max_m, 0.03, 1e-12);
}

TEST(CovarianceCoverage, CountsErrorsInsideTheEstimatesOwn95PercentEllipse) {
  const std::vector<TimedPosition> truth = {{0, 0.0, 0.0}, {1000000, 0.0, 0.0}};
  // sigma 1 cm in x, 2 cm in y, uncorrelated: the 95% ellipse reaches
  // 2.448 sigma along each axis.
  const double xx = 1e-4, yy = 4e-4;
  const std::vector<CovariantPosition> estimates = {
      {100000, 0.024, 0.0, xx, 0.0, yy, true},    // 2.4 sigma in x: inside
      {200000, 0.0, 0.048, xx, 0.0, yy, false},   // 2.4 sigma in y: inside
      {300000, 0.026, 0.0, xx, 0.0, yy, true},    // 2.6 sigma: outside
      {400000, 0.0, 0.01, 0.0, 0.0, 0.0, false},  // no covariance: outside
      {5000000, 9.0, 9.0, xx, 0.0, yy, true},     // no reference then: skipped
  };
  const CoverageSummary s = CovarianceCoverage(estimates, truth, 2000000);
  EXPECT_EQ(s.compared, 4);
  EXPECT_EQ(s.inside_95, 2);
  EXPECT_DOUBLE_EQ(s.share_inside_95, 0.5);
  EXPECT_DOUBLE_EQ(s.worst_ok_m, 0.026);
}

TEST(Percentile, TakesTheNearestRank) {
  EXPECT_EQ(Percentile({5, 1, 4, 2, 3}, 0.5), 3);
  EXPECT_EQ(Percentile({5, 1, 4, 2, 3}, 0.95), 5);
  EXPECT_EQ(Percentile({}, 0.5), 0);
}

}  // namespace
}  // namespace roomfix::analysis
