#include "core/analysis/track_stats.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>

namespace roomfix::analysis {
namespace {

// A statistic drawn from random samples must be within this many of its own
// standard errors of the truth: a correct estimator fails about once in
// 16 000 checks, a wrong one (a missing n - 1, a wrong axis) at once.
constexpr double kSigmas = 4.0;

// Standard error of a sample mean and of a sample standard deviation of n
// Gaussian values (the latter to first order, sigma / sqrt(2 (n - 1))).
double StdErrorOfMean(double sigma, int n) { return sigma / std::sqrt(n); }
double StdErrorOfStd(double sigma, int n) { return sigma / std::sqrt(2.0 * (n - 1)); }

// Arithmetic on exactly constructed inputs only rounds.
constexpr double kRoundingTol = 1e-9;

int64_t Sum(const std::vector<int64_t>& counts) {
  return std::accumulate(counts.begin(), counts.end(), int64_t{0});
}

// The reference's static test: 1172 fixes of a robot standing at (1.911,
// 1.496) m, Gaussian scatter of 3.8 mm in x and 4.9 mm in y.
constexpr int kStaticFixes = 1172;
constexpr double kSigmaXM = 0.0038;
constexpr double kSigmaYM = 0.0049;
std::vector<TimedPosition> StaticRobot(int n, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> nx(1.911, kSigmaXM), ny(1.496, kSigmaYM);
  std::vector<TimedPosition> fixes;
  for (int i = 0; i < n; ++i) fixes.push_back({i * 236000, nx(rng), ny(rng)});
  return fixes;
}

TEST(Histogram, BinsAreHalfOpenAndCountWhatFallsOutside) {
  const Histogram h = MakeHistogram(
      {0.0, 0.5, 0.99, 1.0, 2.5, 2.999, 3.0, -0.001, NAN, INFINITY, -INFINITY}, 0.0, 3.0, 1.0);
  EXPECT_EQ(h.lo, 0.0);
  EXPECT_EQ(h.bin_width, 1.0);
  EXPECT_EQ(h.counts, (std::vector<int64_t>{3, 1, 2}));
  EXPECT_EQ(h.below, 2);  // -0.001 and -inf.
  EXPECT_EQ(h.above, 2);  // 3.0 (the upper edge is open) and +inf.
}

TEST(Histogram, RoundsTheRangeUpToWholeBins) {
  EXPECT_EQ(MakeHistogram({2.7}, 0.0, 2.5, 1.0).counts, (std::vector<int64_t>{0, 0, 1}));
  // 0.1 + 0.2 is 3.0000000000000004 bins of 0.1: rounding error, not a
  // fourth bin.
  EXPECT_EQ(MakeHistogram({}, 0.0, 0.1 + 0.2, 0.1).counts.size(), 3u);
}

TEST(Histogram, IsEmptyForADegenerateRangeOrBinWidth) {
  const std::vector<double> values = {0.5, 1.5};
  for (const Histogram& h : {MakeHistogram(values, 0, 2, 0), MakeHistogram(values, 0, 2, -1),
                             MakeHistogram(values, 0, 2, NAN), MakeHistogram(values, 2, 2, 1),
                             MakeHistogram(values, 2, 0, 1), MakeHistogram(values, NAN, 2, 1),
                             MakeHistogram(values, 0, 1e9, 1e-3)}) {  // 10^12 bins.
    EXPECT_TRUE(h.counts.empty());
    EXPECT_EQ(h.below + h.above, 0);
  }
}

TEST(Histogram2D, CountsRowMajorYThenX) {
  const Histogram2D h =
      MakeHistogram2D({0.5, 1.5, 0.5, 5.0, NAN}, {0.5, 0.5, 1.5, 0.5, 0.0}, 0, 2, 0, 3, 1);
  ASSERT_EQ(h.nx, 2);
  ASSERT_EQ(h.ny, 3);
  EXPECT_EQ(h.counts, (std::vector<int64_t>{1, 1, 1, 0, 0, 0}));
  EXPECT_EQ(h.outside, 1);  // x = 5; the NaN point is not counted.
}

TEST(Histogram2D, IsEmptyForMismatchedOrDegenerateInput) {
  EXPECT_EQ(MakeHistogram2D({0.5, 1.5}, {0.5}, 0, 2, 0, 2, 1).nx, 0);
  EXPECT_TRUE(MakeHistogram2D({0.5}, {0.5}, 0, 2, 0, 2, 0).counts.empty());
  EXPECT_TRUE(MakeHistogram2D({0.5}, {0.5}, 0, 2, 2, 0, 1).counts.empty());
  EXPECT_EQ(MakeHistogram2D({0.5}, {0.5}, 0, 2, 2, 0, 1).outside, 0);
}

TEST(Repeatability, RecoversTheSpreadOfAStaticRobot) {
  const auto fixes = StaticRobot(kStaticFixes, 7);
  const Repeatability r = ComputeRepeatability(fixes);
  ASSERT_EQ(r.n, kStaticFixes);
  EXPECT_EQ(r.tolerance_m, 0.015);
  EXPECT_NEAR(r.mean_x_m, 1.911, kSigmas * StdErrorOfMean(kSigmaXM, kStaticFixes));
  EXPECT_NEAR(r.mean_y_m, 1.496, kSigmas * StdErrorOfMean(kSigmaYM, kStaticFixes));
  EXPECT_NEAR(r.std_x_m, kSigmaXM, kSigmas * StdErrorOfStd(kSigmaXM, kStaticFixes));
  EXPECT_NEAR(r.std_y_m, kSigmaYM, kSigmas * StdErrorOfStd(kSigmaYM, kStaticFixes));

  // Independent axes: P(outside) = 1 - (1 - erfc(t / (sx sqrt 2))) (1 -
  // erfc(t / (sy sqrt 2))) = 0.23% for t = 1.5 cm, about 2.7 of 1172 fixes.
  // The count is binomial, so the share's standard error is
  // sqrt(p (1 - p) / n).
  const double t = r.tolerance_m;
  const double p_outside = 1.0 - (1.0 - std::erfc(t / (kSigmaXM * std::sqrt(2.0)))) *
                                     (1.0 - std::erfc(t / (kSigmaYM * std::sqrt(2.0))));
  // The golden 0.23 % printed to three digits.
  constexpr double kThreeDigits = 0.00001;
  EXPECT_NEAR(p_outside, 0.00228, kThreeDigits);
  const double share_tol = kSigmas * std::sqrt(p_outside * (1.0 - p_outside) / kStaticFixes);
  EXPECT_NEAR(r.share_outside, p_outside, share_tol);
  EXPECT_EQ(r.share_outside > 0.0, r.max_deviation_m > t);

  // The 2D histogram covers mean +- 3 cm on a millimetre grid, and every fix
  // is in it: 3 cm is more than 6 sigma in y.
  const Histogram2D& h = r.histogram;
  EXPECT_EQ(h.bin_m, 0.001);
  EXPECT_LE(h.x_lo, r.mean_x_m - 2 * t);
  EXPECT_GE(h.x_lo + h.nx * h.bin_m, r.mean_x_m + 2 * t);
  EXPECT_LE(h.y_lo, r.mean_y_m - 2 * t);
  EXPECT_GE(h.y_lo + h.ny * h.bin_m, r.mean_y_m + 2 * t);
  EXPECT_LE(h.nx, 61);
  EXPECT_LE(h.ny, 61);
  EXPECT_NEAR(h.x_lo / h.bin_m, std::round(h.x_lo / h.bin_m), kRoundingTol);
  EXPECT_EQ(h.outside, 0);
  EXPECT_EQ(Sum(h.counts), kStaticFixes);
}

TEST(Repeatability, CountsAFixOutsideWhenEitherAxisIsOut) {
  // Mean exactly (0, 0). The diagonal fixes are 2 cm from the mean but
  // within 1.5 cm on each axis: inside the square.
  const std::vector<TimedPosition> fixes = {
      {0, 0.02, 0.0},     {1, -0.02, 0.0},    {2, 0.0, 0.02},
      {3, 0.0, -0.02},    {4, 0.014, 0.014},  {5, -0.014, -0.014},
      {6, 0.014, -0.014}, {7, -0.014, 0.014}, {8, NAN, NAN}};
  const Repeatability r = ComputeRepeatability(fixes, 0.015);
  EXPECT_EQ(r.n, 8);
  EXPECT_EQ(r.mean_x_m, 0.0);
  EXPECT_EQ(r.mean_y_m, 0.0);
  EXPECT_EQ(r.share_outside, 0.5);
  EXPECT_NEAR(r.max_deviation_m, 0.02, kRoundingTol);
  EXPECT_EQ(Sum(r.histogram.counts) + r.histogram.outside, 8);
}

TEST(Repeatability, HandlesNoFixesOneFixAndNoTolerance) {
  const Repeatability none = ComputeRepeatability({{0, NAN, 1.0}});
  EXPECT_EQ(none.n, 0);
  EXPECT_EQ(none.share_outside, 0.0);
  EXPECT_TRUE(none.histogram.counts.empty());

  const Repeatability one = ComputeRepeatability({{0, 1.0, 2.0}});
  EXPECT_EQ(one.n, 1);
  EXPECT_EQ(one.mean_x_m, 1.0);
  EXPECT_EQ(one.std_x_m, 0.0);
  EXPECT_EQ(one.share_outside, 0.0);
  EXPECT_EQ(Sum(one.histogram.counts), 1);

  EXPECT_TRUE(ComputeRepeatability(StaticRobot(10, 1), 0.0).histogram.counts.empty());
}

TEST(LooksStatic, AcceptsAStillRobotWithAFewMisdetections) {
  auto fixes = StaticRobot(1000, 3);
  EXPECT_TRUE(LooksStatic(fixes));
  // 50 of 1050 (4.8%) a metre away: under the 10% allowed.
  for (int i = 0; i < 50; ++i) fixes.push_back({0, 2.9, 1.5});
  EXPECT_TRUE(LooksStatic(fixes));
  fixes.push_back({0, NAN, NAN});
  EXPECT_TRUE(LooksStatic(fixes));
}

TEST(LooksStatic, RejectsADriveTooManyOutliersAndNoFixes) {
  std::vector<TimedPosition> circle;
  for (int i = 0; i < 200; ++i) {
    const double a = 0.1 * i;
    circle.push_back({i, 1.9 + 0.419 * std::cos(a), 1.5 + 0.419 * std::sin(a)});
  }
  EXPECT_FALSE(LooksStatic(circle));

  auto fixes = StaticRobot(1000, 4);
  for (int i = 0; i < 200; ++i) fixes.push_back({0, 2.9, 1.5});  // 16.7%.
  EXPECT_FALSE(LooksStatic(fixes));

  EXPECT_FALSE(LooksStatic({}));
  EXPECT_FALSE(LooksStatic({{0, NAN, NAN}}));
  EXPECT_TRUE(LooksStatic({{0, 1.0, 1.0}}));
}

TEST(Timing, IsExactForAConstructedSequence) {
  // Unsorted on purpose: intervals 100, 200, 300 ms once sorted.
  const Timing t = ComputeTiming({600000, 0, 300000, 100000});
  EXPECT_EQ(t.intervals, 3);
  EXPECT_NEAR(t.mean_ms, 200.0, kRoundingTol);
  EXPECT_NEAR(t.std_ms, 100.0, kRoundingTol);  // sqrt((100^2 + 0 + 100^2) / 2).
  EXPECT_EQ(t.min_ms, 100.0);
  EXPECT_EQ(t.max_ms, 300.0);
  EXPECT_EQ(t.median_ms, 200.0);
  EXPECT_NEAR(t.rate_hz, 5.0, kRoundingTol);
  EXPECT_NEAR(t.frame_period_ms, 1000.0 / 30.0, kRoundingTol);

  ASSERT_EQ(t.interval_ms.counts.size(), 301u);  // Up to the bin holding 300 ms.
  EXPECT_EQ(t.interval_ms.counts[100] + t.interval_ms.counts[200] + t.interval_ms.counts[300], 3);
  // 3, 6 and 9 frames of 33.3 ms; 10 bins, the minimum.
  ASSERT_EQ(t.interval_frames.counts.size(), 10u);
  EXPECT_EQ(t.interval_frames.counts, (std::vector<int64_t>{0, 0, 0, 1, 0, 0, 1, 0, 0, 1}));
}

TEST(Timing, CountsWholeCameraFramesExactly) {
  // The reference's camera cycle: mostly 7 frames (236 ms), sometimes one
  // more or one less. Each fix time is a whole frame plus up to 5 ms of
  // jitter, so every interval is within 10 ms (under half a frame) of a
  // whole number of frames and rounds to exactly what was drawn.
  std::mt19937_64 rng(11);
  std::discrete_distribution<int> extra({0.1, 0.75, 0.15});  // 6, 7, 8 frames.
  std::uniform_int_distribution<int64_t> jitter_us(-5000, 5000);
  std::vector<int64_t> drawn(10, 0);
  std::vector<int64_t> utimes;
  int64_t frame = 1000;
  for (int i = 0; i < kStaticFixes; ++i) {
    if (i > 0) {
      const int frames = 6 + extra(rng);
      ++drawn[frames];
      frame += frames;
    }
    utimes.push_back(std::llround(frame * 1e6 / 30.0) + jitter_us(rng));
  }
  std::shuffle(utimes.begin(), utimes.end(), rng);
  const Timing t = ComputeTiming(utimes, 30.0);
  EXPECT_EQ(t.intervals, kStaticFixes - 1);
  EXPECT_EQ(t.interval_frames.counts, drawn);
  EXPECT_EQ(t.interval_frames.below + t.interval_frames.above, 0);
  EXPECT_EQ(Sum(t.interval_ms.counts) + t.interval_ms.above, kStaticFixes - 1);
  // Intervals telescope: the mean is the span over the count.
  const auto [first, last] = std::minmax_element(utimes.begin(), utimes.end());
  EXPECT_NEAR(t.mean_ms, (*last - *first) * 1e-3 / (kStaticFixes - 1), kRoundingTol);
}

TEST(Timing, LeavesARareDropoutOutOfTheFigure) {
  // 999 intervals of 7 frames and one of 100 frames: the figure stops at the
  // 99.5th percentile's bin, the dropout is `above`, the statistics keep it.
  std::vector<int64_t> utimes;
  int64_t frame = 0;
  for (int i = 0; i <= 1000; ++i) {
    utimes.push_back(std::llround(frame * 1e6 / 30.0));
    frame += i == 500 ? 100 : 7;
  }
  const Timing t = ComputeTiming(utimes);
  ASSERT_EQ(t.interval_ms.counts.size(), 234u);  // 7 frames = 233.3 ms.
  EXPECT_EQ(t.interval_ms.counts[233], 999);
  EXPECT_EQ(t.interval_ms.above, 1);
  ASSERT_EQ(t.interval_frames.counts.size(), 10u);
  EXPECT_EQ(t.interval_frames.counts[7], 999);
  EXPECT_EQ(t.interval_frames.above, 1);
  constexpr double kWholeMicrosecondMs = 0.001;  // Utimes are rounded to 1 us.
  EXPECT_NEAR(t.max_ms, 100 * 1000.0 / 30.0, kWholeMicrosecondMs);
}

TEST(Timing, HandlesFewerThanTwoFixesRepeatedTimesAndABadFrameRate) {
  EXPECT_EQ(ComputeTiming({}).intervals, 0);
  const Timing one = ComputeTiming({5});
  EXPECT_EQ(one.intervals, 0);
  EXPECT_EQ(one.rate_hz, 0.0);
  EXPECT_TRUE(one.interval_ms.counts.empty());

  const Timing same = ComputeTiming({5, 5, 5});
  EXPECT_EQ(same.intervals, 2);
  EXPECT_EQ(same.mean_ms, 0.0);
  EXPECT_EQ(same.rate_hz, 0.0);
  EXPECT_EQ(same.interval_ms.counts[0], 2);

  const Timing no_camera = ComputeTiming({0, 100000}, 0.0);
  EXPECT_EQ(no_camera.frame_period_ms, 0.0);
  EXPECT_TRUE(no_camera.interval_frames.counts.empty());
  EXPECT_EQ(no_camera.mean_ms, 100.0);
  EXPECT_TRUE(ComputeTiming({0, 100000}, -30.0).interval_frames.counts.empty());
}

TEST(SummariseLatency, IgnoresNaNAndKeepsNegativeLatencies) {
  const LatencySummary s = SummariseLatency({10, NAN, 30, 20, -5});
  EXPECT_EQ(s.n, 4);
  EXPECT_NEAR(s.mean_ms, 13.75, kRoundingTol);
  EXPECT_EQ(s.median_ms, 10);  // Nearest rank: the 2nd of 4.
  EXPECT_EQ(s.p95_ms, 30);
  EXPECT_EQ(s.max_ms, 30);
  const LatencySummary none = SummariseLatency({NAN});
  EXPECT_EQ(none.n, 0);
  EXPECT_EQ(none.max_ms, 0.0);
}

TEST(Motion, RecoversDistanceAndSpeedOnACircle) {
  // The reference drive: radius 41.9 cm at 0.439 rad/s (18.4 cm/s), sampled
  // at the reference camera's 4.26 Hz, so theta = 0.103 rad per step.
  constexpr double kRadiusM = 0.419, kOmegaRadps = 0.439;
  constexpr int64_t kDtUs = 234742;
  constexpr int kSteps = 1000;
  std::vector<TimedPosition> track;
  for (int i = 0; i <= kSteps; ++i) {
    const double a = kOmegaRadps * i * kDtUs * 1e-6;
    track.push_back({i * kDtUs, 1.9 + kRadiusM * std::cos(a), 1.5 + kRadiusM * std::sin(a)});
  }
  const Motion m = ComputeMotion(track);
  const double theta = kOmegaRadps * kDtUs * 1e-6;
  const double chord_m = 2.0 * kRadiusM * std::sin(theta / 2.0);
  EXPECT_EQ(m.steps, kSteps);
  EXPECT_NEAR(m.duration_s, kSteps * kDtUs * 1e-6, kRoundingTol);
  EXPECT_NEAR(m.distance_m, kSteps * chord_m, kRoundingTol);
  EXPECT_NEAR(m.mean_speed_mps, chord_m / (kDtUs * 1e-6), kRoundingTol);
  EXPECT_NEAR(m.std_speed_mps, 0.0, kRoundingTol);
  EXPECT_NEAR(m.max_speed_mps, m.mean_speed_mps, kRoundingTol);
  // Chords cut corners by less than theta^2 / 24 of the arc (0.044% here).
  const double arc_m = kRadiusM * kOmegaRadps * kSteps * kDtUs * 1e-6;
  const double shortfall = theta * theta / 24.0;
  EXPECT_NEAR(m.distance_m, arc_m, arc_m * shortfall);
  EXPECT_NEAR(m.mean_speed_mps, kRadiusM * kOmegaRadps, kRadiusM * kOmegaRadps * shortfall);
}

TEST(Motion, SkipsFixesThatDoNotAdvanceInTimeOrAreLost) {
  const Motion m = ComputeMotion({{0, 0.0, 0.0},
                                  {1000000, 1.0, 0.0},
                                  {1000000, 5.0, 5.0},  // Same time.
                                  {500000, 9.0, 9.0},   // Out of order.
                                  {1500000, NAN, NAN},  // Lost.
                                  {2000000, 1.0, 1.0}});
  EXPECT_EQ(m.steps, 2);
  EXPECT_EQ(m.distance_m, 2.0);
  EXPECT_EQ(m.duration_s, 2.0);
  EXPECT_EQ(m.mean_speed_mps, 1.0);
  EXPECT_EQ(m.std_speed_mps, 0.0);
  EXPECT_EQ(m.max_speed_mps, 1.0);
}

TEST(Motion, IsZeroForNoFixOrOne) {
  EXPECT_EQ(ComputeMotion({}).steps, 0);
  const Motion one = ComputeMotion({{7, 1.0, 1.0}});
  EXPECT_EQ(one.steps, 0);
  EXPECT_EQ(one.distance_m, 0.0);
  EXPECT_EQ(one.duration_s, 0.0);
  EXPECT_EQ(one.mean_speed_mps, 0.0);
}

// A reference moving at (0.2, 0.1) m/s, sampled every 100 ms for 10 s
// except for a hole from 5 to 6 s, newest first (a log need not be sorted).
// Linear motion makes the interpolated reference exact.
std::vector<TimedPosition> LineReference() {
  std::vector<TimedPosition> reference;
  for (int k = 100; k >= 0; --k) {
    if (k > 50 && k < 60) continue;
    const int64_t utime = k * 100000;
    reference.push_back({utime, 0.2 * utime * 1e-6, 0.1 * utime * 1e-6});
  }
  return reference;
}
constexpr int64_t kMaxGapUs = 150000;

TEST(ErrorsOverTime, GivesTheSignedErrorAtEachEstimatesOwnTime) {
  std::vector<TimedPosition> estimates;
  int expected = 0;
  for (int64_t utime = 37000; utime < 10000000; utime += 250000) {
    estimates.push_back({utime, 0.2 * utime * 1e-6 + 0.02, 0.1 * utime * 1e-6 - 0.01});
    if (utime <= 5000000 || utime >= 6000000) ++expected;
  }
  estimates.push_back({11000000, 0.0, 0.0});  // After the reference ends.
  estimates.push_back({2000000, NAN, 0.4});   // A lost fix.
  const auto errors = ErrorsOverTime(estimates, LineReference(), kMaxGapUs);
  ASSERT_EQ(static_cast<int>(errors.size()), expected);
  for (size_t i = 1; i < errors.size(); ++i) EXPECT_GT(errors[i].utime, errors[i - 1].utime);
  for (const ErrorSample& e : errors) {
    EXPECT_FALSE(e.utime > 5000000 && e.utime < 6000000) << e.utime;
    EXPECT_NEAR(e.dx_m, 0.02, kRoundingTol);
    EXPECT_NEAR(e.dy_m, -0.01, kRoundingTol);
    EXPECT_NEAR(e.error_m, std::hypot(0.02, 0.01), kRoundingTol);
  }
  EXPECT_TRUE(ErrorsOverTime(estimates, {}, kMaxGapUs).empty());
}

TEST(CompareTracks, RecoversAConstantOffsetUnderNoise) {
  // Ultrasound 3 cm east and 2 cm south of the camera, with 5 mm of noise
  // per axis, at times between the camera's fixes.
  constexpr double kOffsetXM = 0.03, kOffsetYM = -0.02, kNoiseM = 0.005;
  std::mt19937_64 rng(5);
  std::normal_distribution<double> noise(0.0, kNoiseM);
  std::vector<TimedPosition> track;
  for (int64_t utime = 13000; utime < 5000000; utime += 2500) {
    track.push_back({utime, 0.2 * utime * 1e-6 + kOffsetXM + noise(rng),
                     0.1 * utime * 1e-6 + kOffsetYM + noise(rng)});
  }
  const int n = static_cast<int>(track.size());
  track.push_back({20000000, 0.0, 0.0});  // No reference there.
  track.push_back({1000000, NAN, NAN});

  const TrackOffset o = CompareTracks(track, LineReference(), kMaxGapUs);
  ASSERT_EQ(o.matched, n);
  EXPECT_NEAR(o.mean_dx_m, kOffsetXM, kSigmas * StdErrorOfMean(kNoiseM, n));
  EXPECT_NEAR(o.mean_dy_m, kOffsetYM, kSigmas * StdErrorOfMean(kNoiseM, n));
  EXPECT_NEAR(o.std_dx_m, kNoiseM, kSigmas * StdErrorOfStd(kNoiseM, n));
  EXPECT_NEAR(o.std_dy_m, kNoiseM, kSigmas * StdErrorOfStd(kNoiseM, n));
  // With the offset removed only the noise is left: the distance error of
  // 2D Gaussian noise has rms sigma sqrt(2), and the rms of n of them a
  // standard error of sigma / sqrt(2 n) (the delta method on mean r^2,
  // whose variance is 4 sigma^4).
  EXPECT_EQ(o.error_after_offset.compared, n);
  EXPECT_EQ(o.error_after_offset.unmatched, 2);
  EXPECT_NEAR(o.error_after_offset.rmse_m, kNoiseM * std::sqrt(2.0),
              kSigmas * kNoiseM / std::sqrt(2.0 * n));
}

TEST(CompareTracks, IsEmptyWithoutOverlap) {
  const TrackOffset o = CompareTracks({{0, 1.0, 1.0}, {1, 2.0, 2.0}}, {}, kMaxGapUs);
  EXPECT_EQ(o.matched, 0);
  EXPECT_EQ(o.mean_dx_m, 0.0);
  EXPECT_EQ(o.std_dy_m, 0.0);
  EXPECT_EQ(o.error_after_offset.compared, 0);
  EXPECT_EQ(o.error_after_offset.unmatched, 2);
}

}  // namespace
}  // namespace roomfix::analysis
