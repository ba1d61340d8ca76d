#include "core/trilat/nlos_belief.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <vector>

#include "core/trilat/trilateration.h"
#include "tests/testing/exact_ranges.h"

namespace roomfix::trilat {
namespace {

// Five ceiling receivers over a 4 x 3 m room: with one suspected, the other
// four still over-determine a fixed-height fix.
std::vector<Eigen::Vector3d> Five() {
  return {{0, 0, 2.5}, {4, 0, 2.5}, {4, 3, 2.5}, {0, 3, 2.5}, {2, 0, 2.5}};
}

std::vector<RangeMeasurement> ExactRanges(const Eigen::Vector3d& beacon) {
  return testing::ExactRanges(Five(), beacon);
}

SolverOptions Robust() {
  SolverOptions o;
  o.method = Method::kRobust;
  o.fixed_height_m = 1.3;
  o.range_sigma_m = 0.02;
  return o;
}

constexpr int64_t kFiring_us = 100'000;  // a 10 Hz beacon
const Eigen::Vector3d kBeacon(1.2, 1.4, 1.3);

// Receiver 3 reads an echo 1.5 m long, which the consensus excludes; the
// fix is checked, so the belief learns from it.
NlosBelief BeliefAfterOneEcho() {
  NlosBelief belief;
  auto ranges = ExactRanges(kBeacon);
  ranges[2].range_m += 1.5;
  const Fix fix = Solve(ranges, Robust());
  EXPECT_TRUE(belief.Observe(0, ranges, fix));
  return belief;
}

TEST(NlosBelief, AReceiverHeardOnAnEchoStaysSuspectedAcrossTheNextFirings) {
  NlosBelief belief = BeliefAfterOneEcho();
  // An echo 1.5 m long is 75 sigmas off its path: near certain, and the
  // blocking persists (2 s time constant): still above 0.9 a firing later.
  EXPECT_GT(belief.Probability(3, kFiring_us), 0.9);
  ASSERT_EQ(belief.Suspected(kFiring_us).size(), 1u);
  EXPECT_EQ(belief.Suspected(kFiring_us)[0].receiver_id, 3);
  // The others were on their paths: below the 5 % base.
  EXPECT_LT(belief.Probability(1, kFiring_us), 0.05);
  // Without news it relaxes to the base (5 %): after 10 s, 5 + 95 e^-5 %.
  constexpr double kRelaxed = 0.05 + 0.95 * 0.0068 + 1e-3;
  EXPECT_LT(belief.Probability(3, 10'000'000), kRelaxed);
  EXPECT_TRUE(belief.Suspected(10'000'000).empty());
}

TEST(NlosBelief, OneRangeOnItsPathClearsTheSuspicion) {
  NlosBelief belief = BeliefAfterOneEcho();
  const auto ranges = ExactRanges(kBeacon);
  const Fix fix = Solve(ranges, Robust());
  ASSERT_TRUE(belief.Observe(kFiring_us, ranges, fix));
  // The echo likelihood is one-sided: a range on its path is about 20 / 0.1
  // = 200 times likelier line-of-sight at 2 cm noise in a 5 m room (a little
  // less with the fix's own uncertainty added to the noise), so about 0.95
  // falls to about 0.1 in one firing, far below the suspicion's 0.5.
  EXPECT_LT(belief.Probability(3, kFiring_us), 0.15);
  EXPECT_TRUE(belief.Suspected(kFiring_us).empty());
}

// The radio may deliver a set late (trilat_proc admits sets up to an hour
// old): it updates the belief, but the next firing's relaxation still runs
// from the newest time, so one stale set does not wipe every suspicion.
TEST(NlosBelief, ASetDeliveredLateNeverMovesItsClockBack) {
  NlosBelief belief = BeliefAfterOneEcho();  // at t = 0
  auto ranges = ExactRanges(kBeacon);
  ranges[2].range_m += 1.5;
  const Fix fix = Solve(ranges, Robust());
  ASSERT_TRUE(belief.Observe(kFiring_us, ranges, fix));
  // A set from an hour ago arrives now.
  constexpr int64_t kHourAgo_us = -3'600'000'000;
  ASSERT_TRUE(belief.Observe(kHourAgo_us, ranges, fix));
  EXPECT_GT(belief.Probability(3, 2 * kFiring_us), 0.9);
}

// Only the ranges the fix judged teach it: a receiver heard twice (the
// solver drops every copy) is left alone.
TEST(NlosBelief, LearnsOnlyFromTheRangesTheFixUsedOrExcluded) {
  NlosBelief belief;
  auto ranges = ExactRanges(kBeacon);
  ranges.push_back(ranges[1]);
  ranges.back().range_m += 1.0;  // receiver 2 twice, one of them long
  const Fix fix = Solve(ranges, Robust());
  ASSERT_TRUE(belief.Observe(0, ranges, fix));
  EXPECT_NEAR(belief.Probability(2, 0), NlosBeliefOptions().base_probability, 1e-12);
  EXPECT_LT(belief.Probability(1, 0), NlosBeliefOptions().base_probability);
}

TEST(NlosBelief, AFixThatCannotJudgeItsRangesTeachesNothing) {
  NlosBelief belief;
  auto ranges = ExactRanges(kBeacon);
  ranges[2].range_m += 1.5;
  Fix fix = Solve(ranges, Robust());
  fix.flags |= kInconsistentRanges;
  EXPECT_FALSE(belief.Observe(0, ranges, fix));
  fix.flags = kUnchecked;
  EXPECT_FALSE(belief.Observe(0, ranges, fix));
  EXPECT_EQ(belief.receivers(), 0u);
  EXPECT_NEAR(belief.Probability(3, 0), NlosBeliefOptions().base_probability, 1e-12);
}

TEST(NlosBeliefInTheSolver, AShortEchoFromASuspectedReceiverPullsTheFixLess) {
  // A detour of 6 cm (3 sigma) is under the 8 cm outlier threshold: the
  // consensus cannot tell it from noise, and least squares over five ranges
  // moves the fix by centimetres. With receiver 3 suspected the one-sided
  // loss gives it little weight.
  auto ranges = ExactRanges(kBeacon);
  ranges[2].range_m += 0.06;
  const Fix blind = Solve(ranges, Robust());
  // As a 10 Hz beacon's belief stands a firing after an echo.
  const std::vector<NlosSuspicion> suspected = {{3, 0.95, 5.0}};
  Fix told;
  Solve(ranges, Robust(), nullptr, nullptr, &suspected, &told);
  const double blind_error_m = (blind.position_m - kBeacon).norm();
  const double told_error_m = (told.position_m - kBeacon).norm();
  std::printf("[ RESULT   ] 6 cm echo: error %.1f mm blind, %.1f mm with the belief\n",
              1e3 * blind_error_m, 1e3 * told_error_m);
  EXPECT_EQ(blind.flags & kNlosSuspected, 0u);
  EXPECT_NE(told.flags & kNlosSuspected, 0u);
  // Judged against the other four's fix, which predicts receiver 3's range
  // to about 1.3 sigma, a 6 cm detour keeps a fifth of its weight at
  // q = 0.95: measured 14.6 against 32.6 mm. At most half remains.
  EXPECT_GT(blind_error_m, 0.02);
  EXPECT_LT(told_error_m, blind_error_m / 2.0);
  // The down-weighted range informs the fix less: its covariance is larger.
  EXPECT_GT(told.covariance_m2.trace(), blind.covariance_m2.trace());
  // A suspected receiver that reads on its path keeps its full weight.
  Fix clean;
  Solve(ExactRanges(kBeacon), Robust(), nullptr, nullptr, &suspected, &clean);
  EXPECT_EQ(clean.flags & kNlosSuspected, 0u);
  EXPECT_NEAR((clean.position_m - kBeacon).norm(), 0.0, 1e-9);
}

// Exclusion stays the consensus's: a long echo from a suspected receiver is
// excluded as it would be blind (and named), and a suspected receiver that
// reads on its path is kept.
TEST(NlosBeliefInTheSolver, ExcludesNothingOnSuspicionAlone) {
  const std::vector<NlosSuspicion> suspected = {{3, 0.95, 5.0}, {5, 0.95, 5.0}};
  auto ranges = ExactRanges(kBeacon);
  ranges[2].range_m += 0.9;
  Fix fix;
  Solve(ranges, Robust(), nullptr, nullptr, &suspected, &fix);
  const Fix blind = Solve(ranges, Robust());
  EXPECT_EQ(fix.used, (std::vector<int>{1, 2, 4, 5}));
  EXPECT_EQ(blind.used, fix.used);
  ASSERT_EQ(fix.rejected.size(), 1u);
  EXPECT_EQ(fix.rejected[0].receiver_id, 3);
  EXPECT_NEAR((fix.position_m - kBeacon).norm(), 0.0, 1e-6);
}

TEST(NlosBeliefOptions, RejectsNonsense) {
  std::string error;
  NlosBeliefOptions o;
  EXPECT_TRUE(o.IsValid(&error));
  o.persistence_s = 0;
  EXPECT_FALSE(o.IsValid(&error));
  EXPECT_EQ(error, "persistence_s must be positive");
  o = NlosBeliefOptions();
  o.base_probability = 1.0;
  EXPECT_FALSE(o.IsValid(&error));
  o = NlosBeliefOptions();
  o.max_excess_m = NAN;
  EXPECT_FALSE(o.IsValid(&error));
}

}  // namespace
}  // namespace roomfix::trilat
