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
  // A linear reference interpolates exactly: every error is 3 cm but for
  // rounding.
  constexpr double kInterpolationRoundOffM = 1e-12;
  EXPECT_NEAR(s.rmse_m, 0.03, kInterpolationRoundOffM);
  EXPECT_NEAR(s.p95_m, 0.03, kInterpolationRoundOffM);
  EXPECT_NEAR(s.max_m, 0.03, kInterpolationRoundOffM);
}

TEST(Percentile, TakesTheNearestRank) {
  EXPECT_EQ(Percentile({5, 1, 4, 2, 3}, 0.5), 3);
  EXPECT_EQ(Percentile({5, 1, 4, 2, 3}, 0.95), 5);
  EXPECT_EQ(Percentile({}, 0.5), 0);
}

}  // namespace
}  // namespace roomfix::analysis
