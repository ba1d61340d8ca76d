#include "core/trilat/trilateration.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <random>
#include <sstream>

#include "core/world/site.h"
#include "tests/testing/exact_ranges.h"
#include "tests/testing/test_paths.h"

namespace roomfix::trilat {
namespace {

// Zero-noise problems are solved to rounding: Gauss-Newton's last step is
// below 1e-10 m and convergence is quadratic.
constexpr double kExact_m = 1e-9;
// Nelder-Mead stops when its simplex is below 1e-7 m; the vertex it returns
// is within a few simplex sizes of the minimum.
constexpr double kSimplex_m = 1e-5;
// With noisy ranges Levenberg-Marquardt converges linearly and stops after a
// step below 1e-7 m; two starts agree to within a few such steps.
constexpr double kConverged_m = 1e-6;

// The reference installation: receivers in the corners of the 4 x 3 m floor
// at 2.5 m, beacon at 1.3 m.
std::vector<Eigen::Vector3d> Corners(double z = 2.5) {
  return {{0, 0, z}, {4, 0, z}, {4, 3, z}, {0, 3, z}};
}

using testing::ExactRanges;

SolverOptions FixedHeight(Method method, double height_m = 1.3) {
  SolverOptions o;
  o.method = method;
  o.dimension = Dimension::kFixedHeight2D;
  o.fixed_height_m = height_m;
  return o;
}

TEST(Solve, RecoversTheExactPointAnywhereOnTheFloor) {
  for (Method method : {Method::kDefault, Method::kRobust, Method::kNelderMead}) {
    const double tolerance = method == Method::kNelderMead ? kSimplex_m : kExact_m;
    for (double x = 0.1; x < 4.0; x += 0.45) {
      for (double y = 0.1; y < 3.0; y += 0.35) {
        const Eigen::Vector3d beacon(x, y, 1.3);
        const Fix fix = Solve(ExactRanges(Corners(), beacon), FixedHeight(method));
        ASSERT_EQ(fix.status, FixStatus::kOk)
            << MethodName(method) << " " << DescribeFlags(fix.flags);
        EXPECT_NEAR((fix.position_m - beacon).norm(), 0.0, tolerance)
            << MethodName(method) << " at (" << x << ", " << y << ")";
        EXPECT_NEAR(fix.residual_rms_m, 0.0, tolerance);
        EXPECT_EQ(fix.used, (std::vector<int>{1, 2, 3, 4}));
        EXPECT_TRUE(fix.rejected.empty());
      }
    }
  }
}

TEST(Solve, RecoversTheExactPointInPlanar2D) {
  SolverOptions o;
  o.dimension = Dimension::kPlanar2D;
  const std::vector<Eigen::Vector3d> receivers = {{0, 0, 0}, {5, 0, 0}, {5, 4, 0}};
  const Eigen::Vector3d beacon(1.7, 2.9, 0);
  const Fix fix = Solve(ExactRanges(receivers, beacon), o);
  ASSERT_EQ(fix.status, FixStatus::kOk);
  EXPECT_NEAR((fix.position_m - beacon).norm(), 0.0, kExact_m);
}

TEST(Solve, RecoversTheExactPointIn3DWithReceiversAtSeveralHeights) {
  SolverOptions o;
  o.dimension = Dimension::k3D;
  const std::vector<Eigen::Vector3d> receivers = {
      {0, 0, 2.5}, {4, 0, 1.0}, {4, 3, 2.5}, {0, 3, 1.0}, {2, 0, 2.9}};
  const Eigen::Vector3d beacon(2.6, 1.1, 0.4);
  const Fix fix = Solve(ExactRanges(receivers, beacon), o);
  ASSERT_EQ(fix.status, FixStatus::kOk) << DescribeFlags(fix.flags);
  EXPECT_NEAR((fix.position_m - beacon).norm(), 0.0, kExact_m);
  EXPECT_EQ(fix.flags & kMirrorResolved, 0u);
}

TEST(Solve, ChoosesTheRoomSideWhenReceiversAreCoplanarIn3D) {
  SolverOptions o;
  o.dimension = Dimension::k3D;
  const Eigen::Vector3d beacon(1.2, 2.2, 1.3);
  const Fix fix = Solve(ExactRanges(Corners(), beacon), o);
  ASSERT_TRUE(fix.has_position()) << DescribeFlags(fix.flags);
  EXPECT_NE(fix.flags & kMirrorResolved, 0u);
  // Below the receivers' plane at 2.5 m, not its mirror image at 3.7 m.
  EXPECT_NEAR((fix.position_m - beacon).norm(), 0.0, kExact_m);

  // With the room above the receivers (a floor-level ring), the other side.
  o.room_side_point_m = {2, 1.5, 5.0};
  const Fix above = Solve(ExactRanges(Corners(), beacon), o);
  EXPECT_NEAR((above.position_m - Eigen::Vector3d(1.2, 2.2, 3.7)).norm(), 0.0, kExact_m);
}

// The paper: equal errors on all receivers cancel (by symmetry at the
// centre of the rectangle the position does not move).
TEST(Solve, EqualRangeErrorsOnAllReceiversCancelAtTheCentre) {
  const Eigen::Vector3d centre(2.0, 1.5, 1.3);
  auto ranges = ExactRanges(Corners(), centre);
  for (auto& r : ranges) r.range_m += 0.10;
  const Fix fix = Solve(ranges, FixedHeight(Method::kDefault));
  EXPECT_NEAR((fix.position_m - centre).head<2>().norm(), 0.0, kExact_m);
}

// The paper: +10 cm on two adjacent receivers and -10 cm on the other two
// is the worst case, near 20 cm of position error.
TEST(Solve, OppositeErrorsOnAdjacentPairsGiveTheWorstCaseNear20cm) {
  const Eigen::Vector3d centre(2.0, 1.5, 1.3);
  double worst = 0.0;
  for (int first = 0; first < 4; ++first) {
    auto ranges = ExactRanges(Corners(), centre);
    for (int k = 0; k < 4; ++k) {
      const bool plus = k == first || k == (first + 1) % 4;
      ranges[k].range_m += plus ? 0.10 : -0.10;
    }
    const Fix fix = Solve(ranges, FixedHeight(Method::kDefault));
    worst = std::max(worst, (fix.position_m - centre).norm());
  }
  // Any other +-10 cm pattern does no worse.
  double others = 0.0;
  for (int mask = 0; mask < 16; ++mask) {
    auto ranges = ExactRanges(Corners(), centre);
    for (int k = 0; k < 4; ++k) ranges[k].range_m += (mask >> k) & 1 ? 0.10 : -0.10;
    others =
        std::max(others, (Solve(ranges, FixedHeight(Method::kDefault)).position_m - centre).norm());
  }
  EXPECT_GT(worst, 0.15);
  EXPECT_LT(worst, 0.25);
  // The worst of all 16 patterns is one of the four adjacent-pair ones: the
  // same solves, equal but for rounding.
  constexpr double kSameSolveM = 1e-12;
  EXPECT_NEAR(others, worst, kSameSolveM);
}

TEST(Solve, WarmStartGivesTheSameFixAsTheLinearStart) {
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 0.02);
  const Eigen::Vector3d beacon(3.1, 0.6, 1.3);
  auto ranges = ExactRanges(Corners(), beacon);
  for (auto& r : ranges) r.range_m += noise(rng);
  const Fix cold = Solve(ranges, FixedHeight(Method::kDefault));
  const Eigen::Vector3d previous(3.0, 0.7, 1.3);
  const Fix warm = Solve(ranges, FixedHeight(Method::kDefault), &previous);
  EXPECT_NEAR((cold.position_m - warm.position_m).norm(), 0.0, kConverged_m);
}

// The covariance is the Gauss-Newton one, sigma^2 (J^T J)^-1; with small
// Gaussian noise the scatter of the fixes must match it. 4000 trials put the
// sampling error of a variance near 2.2% (sqrt(2/4000)), so 8% is 3.5 sigma.
TEST(Solve, CovarianceMatchesTheScatterOfNoisyFixes) {
  constexpr double kVarianceTolerance = 0.08;
  const double sigma = 0.02;
  const Eigen::Vector3d beacon(1.0, 2.2, 1.3);
  SolverOptions o = FixedHeight(Method::kDefault);
  o.range_sigma_m = sigma;
  std::mt19937 rng(42);
  std::normal_distribution<double> noise(0.0, sigma);
  Eigen::Matrix2d scatter = Eigen::Matrix2d::Zero();
  const int n = 4000;
  Eigen::Matrix3d reported;
  for (int t = 0; t < n; ++t) {
    auto ranges = ExactRanges(Corners(), beacon);
    for (auto& r : ranges) r.range_m += noise(rng);
    const Fix fix = Solve(ranges, o);
    const Eigen::Vector2d e = (fix.position_m - beacon).head<2>();
    scatter += e * e.transpose() / n;
    reported = fix.covariance_m2;
  }
  EXPECT_NEAR(scatter(0, 0) / reported(0, 0), 1.0, kVarianceTolerance);
  EXPECT_NEAR(scatter(1, 1) / reported(1, 1), 1.0, kVarianceTolerance);
  EXPECT_EQ(reported(2, 2), 0.0);  // z is fixed, not estimated.
}

TEST(CramerRao, EqualsSigmaAtTheCentreOfASquareInPlanar2D) {
  // Four unit vectors at 45 degrees: I = 2 / sigma^2 times the identity, so
  // trace(I^-1) = sigma^2 and the bound is sigma itself.
  const std::vector<Eigen::Vector3d> square = {{0, 0, 0}, {2, 0, 0}, {2, 2, 0}, {0, 2, 0}};
  constexpr double kClosedFormRoundOffM = 1e-15;  // a 2 x 2 inverse of exact entries
  EXPECT_NEAR(CramerRaoRmse(square, {1, 1, 0}, 0.05, Dimension::kPlanar2D), 0.05,
              kClosedFormRoundOffM);
  EXPECT_TRUE(
      std::isinf(CramerRaoRmse({{0, 0, 0}, {1, 0, 0}}, {0.5, 0, 0}, 0.05, Dimension::kPlanar2D)));
}

TEST(Solve, RobustModeRejectsANonLineOfSightRangeAndNamesIt) {
  const std::vector<Eigen::Vector3d> six = {{0, 0, 2.5}, {4, 0, 2.5}, {4, 3, 2.5},
                                            {0, 3, 2.5}, {2, 0, 2.5}, {2, 3, 2.5}};
  const Eigen::Vector3d beacon(1.4, 1.9, 1.3);
  auto ranges = ExactRanges(six, beacon);
  ranges[2].range_m += 0.6;  // A reflection: receiver 3 heard a longer path.
  const Fix robust = Solve(ranges, FixedHeight(Method::kRobust));
  ASSERT_EQ(robust.status, FixStatus::kDegraded);
  EXPECT_NE(robust.flags & kOutliersRejected, 0u);
  ASSERT_EQ(robust.rejected.size(), 1u);
  EXPECT_EQ(robust.rejected[0].receiver_id, 3);
  EXPECT_EQ(robust.rejected[0].reason, RangeRejection::kOutlier);
  EXPECT_EQ(robust.used, (std::vector<int>{1, 2, 4, 5, 6}));
  EXPECT_NEAR((robust.position_m - beacon).norm(), 0.0, kExact_m);
  // The plain least-squares fix is pulled by centimetres.
  const Fix plain = Solve(ranges, FixedHeight(Method::kDefault));
  EXPECT_GT((plain.position_m - beacon).norm(), 0.05);
}

TEST(Solve, RobustModeRejectsTwoOutliersAmongSix) {
  const std::vector<Eigen::Vector3d> six = {{0, 0, 2.5}, {4, 0, 2.5}, {4, 3, 2.5},
                                            {0, 3, 2.5}, {2, 0, 2.5}, {2, 3, 2.5}};
  const Eigen::Vector3d beacon(2.9, 0.8, 1.3);
  auto ranges = ExactRanges(six, beacon);
  ranges[0].range_m += 0.45;
  ranges[5].range_m += 0.9;
  const Fix fix = Solve(ranges, FixedHeight(Method::kRobust));
  EXPECT_EQ(fix.used, (std::vector<int>{2, 3, 4, 5}));
  EXPECT_NEAR((fix.position_m - beacon).norm(), 0.0, kExact_m);
}

// Three ranges in 2D leave one degree of redundancy: enough to see that a
// range is wrong, not which. The fix is kept but flagged. (Where the three
// circles can still nearly meet, as at (2.5, 1.5) here, even that is
// invisible: a fourth receiver is what makes outliers detectable everywhere.)
TEST(Solve, FlagsRangesThatDisagreeWhenTheOutlierCannotBeIdentified) {
  auto ranges = ExactRanges({{0, 0, 2.5}, {4, 0, 2.5}, {4, 3, 2.5}}, {0.5, 1.5, 1.3});
  ranges[1].range_m += 0.6;
  for (Method method : {Method::kDefault, Method::kRobust}) {
    const Fix fix = Solve(ranges, FixedHeight(method));
    EXPECT_EQ(fix.status, FixStatus::kDegraded) << MethodName(method);
    EXPECT_EQ(fix.flags, static_cast<uint32_t>(kInconsistentRanges)) << DescribeFlags(fix.flags);
    EXPECT_TRUE(fix.rejected.empty());
  }
}

// n receivers scattered over the 4 x 3 m ceiling, each with a range drawn
// at random: no two agree on a position, so no consensus exists.
std::vector<RangeMeasurement> InconsistentRanges(int n) {
  std::mt19937 rng(15);
  std::uniform_real_distribution<double> x(0.0, 4.0), y(0.0, 3.0), d(1.0, 5.0);
  std::vector<RangeMeasurement> out;
  for (int i = 0; i < n; ++i) out.push_back({i + 1, {x(rng), y(rng), 2.5}, d(rng)});
  return out;
}

TEST(Solve, RefusesMoreRangesThanMaxRangesBeforeAnyWork) {
  SolverOptions o = FixedHeight(Method::kRobust);
  o.max_ranges = 64;
  const Fix fix = Solve(InconsistentRanges(800), o);
  EXPECT_EQ(fix.status, FixStatus::kFailed);
  EXPECT_EQ(fix.flags, static_cast<uint32_t>(kTooManyRanges)) << DescribeFlags(fix.flags);
  EXPECT_EQ(fix.range_evaluations, 0);
  EXPECT_TRUE(fix.used.empty());
  EXPECT_EQ(DescribeFlags(fix.flags), "too_many_ranges");
}

// Whatever a caller lets through, the consensus search stops after
// max_consensus_solves subsets. Without the cap, 800 ranges and 2 outliers
// are C(800, 1) + C(800, 2) = 320 400 subset solves, about 2.6e9 range
// evaluations (32 s); the bound below is under 2e7.
TEST(Solve, RobustConsensusWorkIsBoundedHoweverManyRangesArrive) {
  for (int n : {400, 800}) {
    SolverOptions o = FixedHeight(Method::kRobust);
    // The consensus forced on sets it is never used for by default.
    o.max_consensus_ranges = 1000;
    const std::vector<RangeMeasurement> ranges = InconsistentRanges(n);
    const auto start = std::chrono::steady_clock::now();
    const Fix fix = Solve(ranges, o);
    const double elapsed_ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    // Printed for the record (issue #15: 4.7 s and 32 s before the cap); the
    // assertions are on the machine-independent evaluation count.
    std::printf("robust solve of %d inconsistent ranges: %lld range evaluations, %.1f ms\n", n,
                static_cast<long long>(fix.range_evaluations), elapsed_ms);
    // Each subset solve evaluates every range at most max_iterations + 5
    // times (linear start twice, each Levenberg-Marquardt step once, the
    // residual check and the cost); the first fit and the final covariance
    // add two more solves' worth.
    const int64_t bound = static_cast<int64_t>(o.max_consensus_solves + 3) * n *
                          static_cast<int64_t>(o.max_iterations + 6);
    EXPECT_LE(fix.range_evaluations, bound) << n << " ranges";
    EXPECT_GT(fix.range_evaluations, 0);
    EXPECT_EQ(fix.consensus_solves, o.max_consensus_solves);
    EXPECT_NE(fix.flags & kConsensusBudgetExhausted, 0u) << DescribeFlags(fix.flags);
    EXPECT_NE(fix.flags & kInconsistentRanges, 0u) << DescribeFlags(fix.flags);
    EXPECT_EQ(fix.status, FixStatus::kDegraded);
  }
}

// Above max_consensus_ranges the robust solver reweights with a one-sided
// loss instead of searching subsets: its work is linear in the ranges, so a
// hostile set of 800 mutually inconsistent ranges is answered (degraded: the
// ranges disagree), never refused and never searched.
TEST(Solve, RobustWorkIsLinearAboveTheConsensusSize) {
  for (int n : {400, 800}) {
    const SolverOptions o = FixedHeight(Method::kRobust);
    const Fix fix = Solve(InconsistentRanges(n), o);
    std::printf("robust solve of %d inconsistent ranges: %lld range evaluations\n", n,
                static_cast<long long>(fix.range_evaluations));
    // 20 rounds of at most 20 Levenberg-Marquardt iterations (each evaluates
    // every range at most twice) and two excess passes, the first fit, the
    // final refit and the covariance: under 60 max_iterations-long solves.
    const int64_t linear_bound = static_cast<int64_t>(60) * n * (o.max_iterations + 6);
    EXPECT_LE(fix.range_evaluations, linear_bound) << n << " ranges";
    EXPECT_EQ(fix.consensus_solves, 0);
    EXPECT_NE(fix.flags & kInconsistentRanges, 0u) << DescribeFlags(fix.flags);
    EXPECT_EQ(fix.status, FixStatus::kDegraded);
  }
}

// An external trilateration suite's large case: 100 anchors over a 20 x 20 m
// hall's ceiling (3 m), the tag at 1 m, 2 cm noise, and 14 of the ranges
// reflected (+0.3 to +1.0 m). The robust solver answers it (no refusal),
// rejects the reflections and lands within the noise; least squares is
// pulled by them.
TEST(Solve, RobustAnswersAHundredRangesWithReflectionsAmongThem) {
  std::mt19937 rng(100);
  std::uniform_real_distribution<double> xy(0.0, 20.0), detour(0.3, 1.0);
  std::normal_distribution<double> noise(0.0, 0.02);
  const Eigen::Vector3d truth(8.3, 11.7, 1.0);
  std::vector<RangeMeasurement> ranges;
  for (int i = 0; i < 100; ++i) {
    const Eigen::Vector3d a(xy(rng), xy(rng), 3.0);
    double d = (a - truth).norm() + noise(rng);
    if (i % 7 == 3) d += detour(rng);  // 14 of the 100
    ranges.push_back({i + 1, a, d});
  }
  const Fix robust = Solve(ranges, FixedHeight(Method::kRobust, 1.0));
  const Fix plain = Solve(ranges, FixedHeight(Method::kDefault, 1.0));
  ASSERT_TRUE(robust.has_position()) << DescribeFlags(robust.flags);
  // 86 good ranges of 2 cm from all around: the Cramer-Rao bound is about
  // 2 cm x sqrt(2 / 86) = 3 mm; 1 cm is over three times that.
  constexpr double kHundredRangeTolerance_m = 0.01;
  EXPECT_LT((robust.position_m - truth).norm(), kHundredRangeTolerance_m);
  EXPECT_EQ(robust.rejected.size(), 14u);
  for (const RejectedRange& r : robust.rejected) EXPECT_EQ(r.receiver_id % 7, 4);
  EXPECT_EQ(robust.status, FixStatus::kDegraded);  // outliers were rejected
  EXPECT_GT((plain.position_m - truth).norm(), 2.0 * (robust.position_m - truth).norm());
}

TEST(Solve, TheConsensusBudgetLeavesTheExhaustiveSearchOfARoomIntact) {
  // Six receivers and two outliers: 6 + 15 = 21 subsets, far below the
  // default budget, so the search is exhaustive and finds the two.
  const std::vector<Eigen::Vector3d> six = {{0, 0, 2.5}, {4, 0, 2.5}, {4, 3, 2.5},
                                            {0, 3, 2.5}, {2, 0, 2.5}, {2, 3, 2.5}};
  auto ranges = ExactRanges(six, {2.9, 0.8, 1.3});
  ranges[0].range_m += 0.45;
  ranges[5].range_m += 0.9;
  SolverOptions o = FixedHeight(Method::kRobust);
  const Fix fix = Solve(ranges, o);
  EXPECT_EQ(fix.used, (std::vector<int>{2, 3, 4, 5}));
  EXPECT_EQ(fix.flags & kConsensusBudgetExhausted, 0u);
  EXPECT_LE(fix.consensus_solves, 21);
  // With too small a budget the search stops short and says so; the
  // one-sided reweighting it falls back on (linear cost) still finds the
  // same two echoes, which stand out from four ranges that agree.
  o.max_consensus_solves = 3;
  const Fix short_budget = Solve(ranges, o);
  EXPECT_EQ(short_budget.consensus_solves, 3);
  EXPECT_NE(short_budget.flags & kConsensusBudgetExhausted, 0u);
  EXPECT_EQ(short_budget.status, FixStatus::kDegraded);
  EXPECT_EQ(short_budget.used, (std::vector<int>{2, 3, 4, 5}));
}

TEST(Solve, GivesNoPositionWithFewerRangesThanTheModeNeeds) {
  const auto ranges = ExactRanges({{0, 0, 2.5}, {4, 0, 2.5}}, {1, 1, 1.3});
  const Fix fix = Solve(ranges, FixedHeight(Method::kDefault));
  EXPECT_EQ(fix.status, FixStatus::kFailed);
  EXPECT_EQ(fix.flags, static_cast<uint32_t>(kTooFewRanges));
  EXPECT_TRUE(std::isnan(fix.position_m.x()));
  SolverOptions o3;
  o3.dimension = Dimension::k3D;
  const auto two = ExactRanges({{0, 0, 2.5}, {4, 0, 2.5}}, {1, 1, 1.3});
  EXPECT_EQ(Solve(two, o3).flags, static_cast<uint32_t>(kTooFewRanges));
}

// Three receivers in 3D fix the beacon up to its mirror image through their
// plane; the room side is chosen and the fix says it could not be checked.
TEST(Solve, ThreeReceiversIn3DAreSolvedOnTheRoomSideAndFlagged) {
  SolverOptions o;
  o.dimension = Dimension::k3D;
  const Eigen::Vector3d beacon(1.0, 1.2, 1.3);
  const Fix fix = Solve(ExactRanges({{0, 0, 2.5}, {4, 0, 2.5}, {4, 3, 2.5}}, beacon), o);
  ASSERT_EQ(fix.status, FixStatus::kDegraded);
  EXPECT_EQ(fix.flags, static_cast<uint32_t>(kMirrorResolved | kUnchecked))
      << DescribeFlags(fix.flags);
  EXPECT_EQ(fix.redundant_ranges, 0);
  EXPECT_NEAR((fix.position_m - beacon).norm(), 0.0, kExact_m);
  // Three receivers on a line leave a circle of solutions: refused, in 2D
  // and 3D alike.
  const std::vector<Eigen::Vector3d> line = {{0, 0, 2.5}, {2, 0, 2.5}, {4, 0, 2.5}};
  EXPECT_EQ(Solve(ExactRanges(line, beacon), o).flags, static_cast<uint32_t>(kCollinearReceivers));
  EXPECT_EQ(Solve(ExactRanges(line, beacon), FixedHeight(Method::kRobust)).flags,
            static_cast<uint32_t>(kCollinearReceivers));
}

// The case measured in issue #16: one range long by 0.71 m and three long by
// 2 cm. Explaining a good range as too short is physically impossible, so
// the long one is excluded even though another subset fits as tightly.
TEST(Solve, ConsensusExcludesOnlyRangesThatAreLong) {
  const Eigen::Vector3d beacon(1.6, 1.1, 1.3);
  for (int bad = 0; bad < 4; ++bad) {
    auto ranges = ExactRanges(Corners(), beacon);
    for (int i = 0; i < 4; ++i) ranges[i].range_m += i == bad ? 0.71 : 0.02;
    const Fix fix = Solve(ranges, FixedHeight(Method::kRobust));
    ASSERT_EQ(fix.rejected.size(), 1u) << bad;
    EXPECT_EQ(fix.rejected[0].receiver_id, bad + 1);
    // The three kept ranges, all 2 cm long, put the fix within a few cm.
    constexpr double kThreeLongBy2cm_m = 0.05;
    EXPECT_LT((fix.position_m - beacon).norm(), kThreeLongBy2cm_m) << bad;
  }
}

TEST(Solve, DropsNonFiniteNegativeAndOverlongRangesAndSaysWhich) {
  const std::vector<Eigen::Vector3d> six = {{0, 0, 2.5}, {4, 0, 2.5}, {4, 3, 2.5},
                                            {0, 3, 2.5}, {2, 0, 2.5}, {2, 3, 2.5}};
  const Eigen::Vector3d beacon(1.0, 1.0, 1.3);
  auto ranges = ExactRanges(six, beacon);
  ranges[0].range_m = NAN;
  ranges[1].range_m = -0.5;
  ranges[2].range_m = 40.0;
  SolverOptions o = FixedHeight(Method::kDefault);
  o.max_range_m = 6.0;  // The room's diagonal plus a margin.
  const Fix fix = Solve(ranges, o);
  ASSERT_EQ(fix.status, FixStatus::kDegraded);
  EXPECT_EQ(fix.flags, static_cast<uint32_t>(kBadRangesDropped));
  ASSERT_EQ(fix.rejected.size(), 3u);
  EXPECT_EQ(fix.rejected[0].reason, RangeRejection::kNonFinite);
  EXPECT_EQ(fix.rejected[1].reason, RangeRejection::kNegative);
  EXPECT_EQ(fix.rejected[2].reason, RangeRejection::kTooLong);
  EXPECT_EQ(fix.used, (std::vector<int>{4, 5, 6}));
  EXPECT_NEAR((fix.position_m - beacon).norm(), 0.0, kExact_m);
}

TEST(Solve, DropsEveryCopyOfADuplicateReceiver) {
  auto ranges = ExactRanges(Corners(), {1, 1, 1.3});
  ranges.push_back(ranges[1]);
  ranges.back().range_m += 0.3;
  const Fix fix = Solve(ranges, FixedHeight(Method::kDefault));
  ASSERT_EQ(fix.rejected.size(), 2u);
  EXPECT_EQ(fix.rejected[0].receiver_id, 2);
  EXPECT_EQ(fix.rejected[0].reason, RangeRejection::kDuplicateReceiver);
  EXPECT_EQ(fix.used, (std::vector<int>{1, 3, 4}));
}

TEST(Solve, RefusesCollinearReceivers) {
  const auto ranges =
      ExactRanges({{0, 0, 2.5}, {2, 0, 2.5}, {4, 0, 2.5}, {3, 0, 2.5}}, {1, 1, 1.3});
  const Fix fix = Solve(ranges, FixedHeight(Method::kDefault));
  EXPECT_EQ(fix.status, FixStatus::kFailed);
  EXPECT_EQ(fix.flags, static_cast<uint32_t>(kCollinearReceivers));
}

TEST(Solve, FlagsPoorGeometryFromTheCovariance) {
  // Receivers 5 cm off one line and the beacon close to it, 1.2 m below:
  // moving the beacon across the line barely changes any range, so that
  // coordinate is hardly constrained.
  SolverOptions o = FixedHeight(Method::kDefault);
  o.range_sigma_m = 0.05;
  const auto ranges = ExactRanges({{0, 0, 2.5}, {0.05, 1.5, 2.5}, {0, 3, 2.5}}, {0.1, 1.0, 1.3});
  const Fix fix = Solve(ranges, o);
  EXPECT_EQ(fix.status, FixStatus::kDegraded) << fix.covariance_m2;
  EXPECT_NE(fix.flags & kPoorGeometry, 0u);
  EXPECT_GT(std::sqrt(fix.covariance_m2(0, 0)), o.max_position_sigma_m);
}

TEST(SolverOptions, RejectsNonsense) {
  std::string error;
  SolverOptions o;
  o.range_sigma_m = 0;
  EXPECT_FALSE(o.IsValid(&error));
  EXPECT_EQ(error, "range_sigma_m must be positive");
  o = SolverOptions();
  o.fixed_height_m = NAN;
  EXPECT_FALSE(o.IsValid(&error));
  o = SolverOptions();
  o.max_ranges = 0;
  EXPECT_FALSE(o.IsValid(&error));
  EXPECT_EQ(error, "max_ranges must be at least 1");
  o = SolverOptions();
  o.max_consensus_solves = -1;
  EXPECT_FALSE(o.IsValid(&error));
  EXPECT_TRUE(SolverOptions().IsValid(&error));
}

// ---------------------------------------------------------------------------
// Real data: ../shared/data/uwb_lias_planar, static sessions, per-file
// median ranges, fixed-height 2D with the tag height the dataset gives.

struct StaticCase {
  std::string session;
  Eigen::Vector2d truth;
  double height_m;
  std::vector<double> ranges;  // per anchor, NaN when missing
};

std::vector<StaticCase> ReadStaticMedians(const std::string& path) {
  std::vector<StaticCase> out;
  std::ifstream in(path);
  std::string line;
  std::getline(in, line);
  while (std::getline(in, line)) {
    std::vector<std::string> f;
    std::stringstream s(line);
    std::string cell;
    while (std::getline(s, cell, ',')) f.push_back(cell);
    StaticCase c;
    c.session = f[0];
    c.truth = {std::stod(f[4]), std::stod(f[5])};
    c.height_m = std::stod(f[6]);
    for (int a = 0; a < 8; ++a) c.ranges.push_back(f[8 + a].empty() ? NAN : std::stod(f[8 + a]));
    out.push_back(c);
  }
  return out;
}

struct ErrorStats {
  double mean = 0, max = 0;
  int n = 0;
};

ErrorStats SolveAll(const std::vector<StaticCase>& cases, const std::string& session,
                    const Site& site, const std::vector<double>& bias, Method method) {
  ErrorStats s;
  for (const auto& c : cases) {
    if (c.session != session) continue;
    std::vector<RangeMeasurement> ranges;
    for (int a = 0; a < 8; ++a) {
      ranges.push_back({a,
                        Eigen::Map<const Eigen::Vector3d>(site.FindReceiver(a)->position_m.data()),
                        c.ranges[a] - bias[a]});
    }
    SolverOptions o = FixedHeight(method, c.height_m);
    o.range_sigma_m = 0.05;
    const Fix fix = Solve(ranges, o);
    const double e = (fix.position_m.head<2>() - c.truth).norm();
    s.mean += e;
    s.max = std::max(s.max, e);
    ++s.n;
  }
  s.mean /= s.n;
  return s;
}

TEST(RealData, LiasPlanarStaticMediansAgreeWithMotionCapture) {
  const std::string data = testing::SharedDataDir();
  if (data.empty()) GTEST_SKIP() << "../shared/data is absent: real-data check skipped";
  const auto cases = ReadStaticMedians(data + "/uwb_lias_planar/static_median_ranges.csv");
  ASSERT_EQ(cases.size(), 126u);
  // The dataset's README: about 0.35 m on raw medians and 0.15 m after the
  // per-anchor bias is removed are the tolerances its geometry supports.
  constexpr double kRawMax_m = 0.35;
  constexpr double kUnbiasedMax_m = 0.15;
  // Issue 16: with the surveyed offsets removed, keep the published 5.3 cm
  // (8.14) and 4.9 cm (8.20) mean or better. Those figures are rounded to the
  // millimetre, so a mean that printed as them may be up to half a millimetre
  // above; anything more is a regression.
  constexpr double kPublishedRounding_m = 0.0005;
  for (const std::string session : {"8.14", "8.20"}) {
    const double published_unbiased_mean_m = session == "8.14" ? 0.053 : 0.049;
    Site site;
    std::string error;
    const std::string name = session == "8.14" ? "lias_planar_814" : "lias_planar_820";
    ASSERT_TRUE(LoadSite(testing::SourceDir() + "/config/sites/" + name + ".yaml", &site, &error))
        << error;
    // Each anchor's bias: the mean of (median range - true distance) over the
    // session's poses, as the ranges are uniformly long by 4-27 cm.
    std::vector<double> bias(8, 0.0);
    std::vector<int> count(8, 0);
    for (const auto& c : cases) {
      if (c.session != session) continue;
      for (int a = 0; a < 8; ++a) {
        const Eigen::Vector3d p(c.truth.x(), c.truth.y(), c.height_m);
        const Eigen::Vector3d anchor =
            Eigen::Map<const Eigen::Vector3d>(site.FindReceiver(a)->position_m.data());
        bias[a] += c.ranges[a] - (p - anchor).norm();
        ++count[a];
      }
    }
    for (int a = 0; a < 8; ++a) bias[a] /= count[a];
    const std::vector<double> none(8, 0.0);
    for (Method m : {Method::kDefault, Method::kRobust, Method::kNelderMead}) {
      const ErrorStats raw = SolveAll(cases, session, site, none, m);
      const ErrorStats unbiased = SolveAll(cases, session, site, bias, m);
      std::printf(
          "[ RESULT   ] session %s %-11s raw: mean %.4f max %.4f m; bias removed: mean %.4f max "
          "%.4f m (n=%d)\n",
          session.c_str(), MethodName(m), raw.mean, raw.max, unbiased.mean, unbiased.max, raw.n);
      EXPECT_LT(unbiased.max, kUnbiasedMax_m) << session << " " << MethodName(m);
      EXPECT_LT(unbiased.mean, raw.mean);
      EXPECT_LE(unbiased.mean, published_unbiased_mean_m + kPublishedRounding_m)
          << session << " " << MethodName(m);
      // On raw ranges every anchor reads long, by a different 4-27 cm: a
      // level they share (about 17 cm on 8.14, 10 cm on 8.20) plus a
      // scatter. Least squares cannot absorb the level at a fixed height
      // and is pulled 15.0 / 10.4 cm off on average; the robust solver
      // estimates the level with the position (kSharedLevel) and is never
      // worse: 9.33 / 9.10 cm mean, 22.2 / 16.0 cm max (measured). Held to
      // least squares' own figures so that a regression to them fails, and
      // to the measured means plus 5 mm so that a slide back shows.
      const ErrorStats plain = SolveAll(cases, session, site, none, Method::kDefault);
      if (m == Method::kRobust) {
        constexpr double kMeasuredMargin_m = 0.005;
        const double measured_mean_m = session == "8.14" ? 0.0933 : 0.0910;
        EXPECT_LE(raw.mean, measured_mean_m + kMeasuredMargin_m) << session;
        EXPECT_LT(raw.mean, plain.mean) << session;
        EXPECT_LT(raw.max, plain.max) << session;
      } else {
        // The other methods are least squares, from different starts: the
        // same fix to the convergence step.
        constexpr double kConvergence_m = 1e-6;
        EXPECT_LE(raw.mean, plain.mean + kConvergence_m) << session << " " << MethodName(m);
      }
      EXPECT_LT(raw.max, kRawMax_m) << session << " " << MethodName(m);
    }
  }
}

// Single epochs of the same data (no medians: each epoch's raw ranges, with
// their dropouts and outliers), static and moving, per set: the robust
// solver against least squares.
struct EpochCase {
  Eigen::Vector2d truth;
  double height_m = 0.0;
  std::vector<double> ranges;  // per anchor, NaN when missing
};

std::vector<EpochCase> ReadEpochs(const std::string& path, const std::string& session,
                                  const std::string& height_column) {
  std::ifstream in(path);
  std::string line;
  std::getline(in, line);
  if (!line.empty() && line.back() == '\r') line.pop_back();
  std::vector<std::string> header;
  {
    std::stringstream s(line);
    std::string cell;
    while (std::getline(s, cell, ',')) header.push_back(cell);
  }
  auto column = [&](const std::string& name) {
    return static_cast<size_t>(std::find(header.begin(), header.end(), name) - header.begin());
  };
  const size_t session_col = column("session"), x_col = column("gt_x_m"), y_col = column("gt_y_m"),
               z_col = column(height_column), r0_col = column("r_a0_m");
  std::vector<EpochCase> out;
  while (std::getline(in, line)) {
    // The moving file has CRLF line ends: an empty last field is then "\r".
    if (!line.empty() && line.back() == '\r') line.pop_back();
    std::vector<std::string> f;
    std::stringstream s(line);
    std::string cell;
    while (std::getline(s, cell, ',')) f.push_back(cell);
    f.resize(header.size());
    if (session_col < header.size() && f[session_col] != session) continue;
    EpochCase c;
    c.truth = {std::stod(f[x_col]), std::stod(f[y_col])};
    c.height_m = std::stod(f[z_col]);
    for (size_t a = 0; a < 8; ++a) {
      c.ranges.push_back(f[r0_col + a].empty() ? NAN : std::stod(f[r0_col + a]));
    }
    out.push_back(c);
  }
  return out;
}

struct EpochStats {
  double mean = 0, median = 0, p95 = 0, max = 0;
};

EpochStats SolveEpochs(const std::vector<EpochCase>& cases, const Site& site, Method method) {
  std::vector<double> errors;
  std::vector<RangeMeasurement> ranges;
  Fix fix;
  for (const auto& c : cases) {
    ranges.clear();
    for (int a = 0; a < 8; ++a) {
      if (!(c.ranges[a] > 0.0)) continue;  // a dropout
      ranges.push_back({a,
                        Eigen::Map<const Eigen::Vector3d>(site.FindReceiver(a)->position_m.data()),
                        c.ranges[a]});
    }
    SolverOptions o = FixedHeight(method, c.height_m);
    o.range_sigma_m = 0.05;
    Solve(ranges, o, nullptr, &fix);
    if (!fix.has_position()) continue;
    errors.push_back((fix.position_m.head<2>() - c.truth).norm());
  }
  EpochStats s;
  if (errors.empty()) return s;
  std::sort(errors.begin(), errors.end());
  for (double e : errors) s.mean += e;
  s.mean /= errors.size();
  s.median = errors[errors.size() / 2];
  s.p95 = errors[errors.size() * 95 / 100];
  s.max = errors.back();
  return s;
}

TEST(RealData, LiasPlanarSingleEpochsRobustBeatsLeastSquaresWhereRangesReadLong) {
  const std::string data = testing::SharedDataDir();
  if (data.empty()) GTEST_SKIP() << "../shared/data is absent: real-data check skipped";
  const std::string dir = data + "/uwb_lias_planar/";
  struct Set {
    const char* name;
    std::string file, session, height_column, site;
    // The robust maximum's known excess over least squares (0: none).
    double known_max_excess_m;
  };
  // 8.14 static: five epochs of one pose where four anchors read 33-38 cm
  // long and four 0-19 cm: the consensus takes the short group's longest
  // range for an echo and the fix moves 40 cm off where least squares is 36
  // (measured). Held to that by name, not hidden.
  const std::vector<Set> sets = {
      {"static 8.14", dir + "static_ranges_sample.csv", "8.14", "gt_z_nominal_m", "lias_planar_814",
       0.045},
      {"static 8.20", dir + "static_ranges_sample.csv", "8.20", "gt_z_nominal_m", "lias_planar_820",
       0.0},
      {"moving 8.15", dir + "dynamic_mid_sample.csv", "", "centroid_z_m", "lias_planar_814", 0.0},
  };
  for (const Set& set : sets) {
    Site site;
    std::string error;
    ASSERT_TRUE(
        LoadSite(testing::SourceDir() + "/config/sites/" + set.site + ".yaml", &site, &error))
        << error;
    const auto cases = ReadEpochs(set.file, set.session, set.height_column);
    ASSERT_GT(cases.size(), 1000u) << set.name;
    const EpochStats plain = SolveEpochs(cases, site, Method::kDefault);
    const EpochStats robust = SolveEpochs(cases, site, Method::kRobust);
    std::printf(
        "[ RESULT   ] %s, %zu epochs: least squares mean %.3f median %.3f p95 %.3f max %.3f m; "
        "robust mean %.3f median %.3f p95 %.3f max %.3f m\n",
        set.name, cases.size(), plain.mean, plain.median, plain.p95, plain.max, robust.mean,
        robust.median, robust.p95, robust.max);
    // Every anchor reads long here, so robust must be clearly better in the
    // bulk: at most 90 % of least squares' mean, median and p95 (measured
    // 64 / 87 / 63 % of the mean on the three sets).
    constexpr double kClearlyBetter = 0.9;
    EXPECT_LT(robust.mean, kClearlyBetter * plain.mean) << set.name;
    EXPECT_LT(robust.median, kClearlyBetter * plain.median) << set.name;
    EXPECT_LT(robust.p95, plain.p95) << set.name;
    EXPECT_LE(robust.max, plain.max + set.known_max_excess_m) << set.name;
  }
}

}  // namespace
}  // namespace roomfix::trilat
