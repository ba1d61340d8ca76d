// Fusion's covariance against ground truth: POSE_FUSED must be as uncertain
// as it says, 90-98 % of its errors inside its own 95 % ellipse, on the
// camera-less demo's recorded ultrasound and on simulated streams.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <vector>

#include "core/analysis/fix_quality.h"
#include "core/fusion/pose_filter.h"
#include "core/world/trajectory.h"
#include "msgio/pose_tracks.h"
#include "tests/testing/synthetic_streams.h"
#include "tests/testing/test_paths.h"

namespace roomfix {
namespace {

// Feeds a recorded source to the filter in receive order, as fusion_proc
// would, and assesses the estimate published after each measurement.
analysis::FixQuality ReplayIntoFilter(const PoseLogs& logs, const std::string& source,
                                      const fusion::PoseFilterOptions& options) {
  const PoseTrack& track = logs.tracks.at({source, 1});
  const PoseTrack& truth = logs.tracks.at({"ground_truth", 1});
  std::vector<PoseSample> samples = track.samples;
  std::stable_sort(samples.begin(), samples.end(), [](const PoseSample& a, const PoseSample& b) {
    return a.recv_utime < b.recv_utime;
  });
  fusion::PoseFilter filter(options);
  std::vector<analysis::RatedFix> fused;
  int lost = 0;
  for (const PoseSample& s : samples) {
    fusion::Measurement m;
    m.utime = s.utime;
    m.source = PoseSource::kUltrasound;
    m.position_m = {s.x_m, s.y_m};
    m.position_cov_m2 << s.cov_xx_m2, s.cov_xy_m2, s.cov_xy_m2, s.cov_yy_m2;
    fusion::Estimate e;
    if (!fusion::Entered(filter.Add(m, s.recv_utime, &e))) continue;
    if (e.status == fusion::TrackStatus::kLost) {
      ++lost;
      continue;
    }
    fused.push_back({e.utime, e.state[fusion::kX], e.state[fusion::kY],
                     e.status == fusion::TrackStatus::kDegraded, e.covariance(0, 0),
                     e.covariance(0, 1), e.covariance(1, 1)});
  }
  return analysis::AssessFixes(fused, lost, truth.Positions(), 200000);
}

// The fused estimates of simulated streams whose covariances are calibrated
// (each source reports the noise it has), pooled over four seeds; stream
// sets each seed's stream options (seed, robot and outages aside).
analysis::FixQuality FuseSimulated(const fusion::synthetic::StreamOptions& stream,
                                   const fusion::PoseFilterOptions& options, bool with_camera) {
  std::string error;
  const std::unique_ptr<Trajectory> circle =
      MakeCircleTrajectory(CircleTrajectoryOptions(), &error);
  std::vector<analysis::RatedFix> fused;
  std::vector<analysis::TimedPosition> truth;
  int lost = 0;
  for (uint32_t seed = 1; seed <= 4; ++seed) {
    fusion::synthetic::StreamOptions so = stream;
    so.seed = seed;
    so.robot_id = static_cast<int>(seed);
    if (!with_camera) {
      so.camera_outage_start_s = 0.0;
      so.camera_outage_end_s = so.duration_s + 1.0;
    }
    // Each seed in its own hour, so the pooled truth track has gaps between
    // runs rather than jumps.
    const int64_t offset_us = static_cast<int64_t>(seed) * 3600 * 1000000LL;
    fusion::PoseFilter filter{options};
    for (const fusion::synthetic::StreamItem& item : fusion::synthetic::MakeStream(*circle, so)) {
      fusion::Estimate e;
      if (!fusion::Entered(filter.Add(item.measurement, item.recv_utime, &e))) continue;
      if (e.status == fusion::TrackStatus::kLost) {
        ++lost;
        continue;
      }
      fused.push_back({e.utime + offset_us, e.state[fusion::kX], e.state[fusion::kY],
                       e.status == fusion::TrackStatus::kDegraded, e.covariance(0, 0),
                       e.covariance(0, 1), e.covariance(1, 1)});
    }
    for (double t = 0.0; t <= so.duration_s + 0.5; t += 0.005) {
      const GroundTruthPose g = circle->PoseAt(t);
      truth.push_back({fusion::synthetic::UtimeAt(t) + offset_us, g.x_m, g.y_m});
    }
  }
  return analysis::AssessFixes(fused, lost, truth, 20000);
}

// The issue's band for every pose source: 90-98 % of the errors inside the
// pose's own 95 % ellipse (a calibrated Gaussian: 95 %).
constexpr double kCoverageLow = 0.90;
constexpr double kCoverageHigh = 0.98;

TEST(FusionCalibration, SimulatedCameraAndUltrasoundFillTheirOwnEllipses) {
  // 4 x 1600 estimates. Consecutive estimates share most of their error (the
  // filter averages over many frames), so the pooled share still varies by
  // about a percent between seed sets; the band is the tolerance. Measured:
  // 97.8 % (the filter's white-acceleration model is somewhat pessimistic on
  // the smooth circle: its predicted manoeuvres do not happen).
  const analysis::FixQuality q = FuseSimulated({}, {}, /*with_camera=*/true);
  std::printf("camera + ultrasound: %d estimates, RMSE %.3f mm, %.1f %% inside, median d2 %.2f\n",
              q.with_covariance, q.rmse_m * 1e3, q.share_inside_95 * 100, q.median_d2);
  EXPECT_GE(q.share_inside_95, kCoverageLow);
  EXPECT_LE(q.share_inside_95, kCoverageHigh);
}

TEST(FusionCalibration, SimulatedUltrasoundAloneFillsItsOwnEllipses) {
  // 4 x 400 estimates, 2 % of the firings 30 cm outliers (gated). Measured:
  // 97.8 %.
  const analysis::FixQuality q = FuseSimulated({}, {}, /*with_camera=*/false);
  std::printf("ultrasound alone: %d estimates, RMSE %.2f cm, %.1f %% inside, median d2 %.2f\n",
              q.with_covariance, q.rmse_m * 1e2, q.share_inside_95 * 100, q.median_d2);
  EXPECT_GE(q.share_inside_95, kCoverageLow);
  EXPECT_LE(q.share_inside_95, kCoverageHigh);
}

// A camera whose error is mostly correlated from frame to frame, as the
// simulated webcam's (docs/fusion.md, "Correlated camera error"): 0.1 mm
// white per axis, a constant lean of 1.5 mm (0.5 degrees at 17 cm) and a
// varying tilt of 1.5 mm per axis with the given correlation time; the
// camera reports it all in its covariance (its tilt term) and says how much
// is correlated, as fusion_proc does from the site.
fusion::synthetic::StreamOptions CorrelatedCamera(double bias_time_s) {
  fusion::synthetic::StreamOptions so;
  so.camera_sigma_m = 0.0001;
  so.camera_bias_sigma_m = 0.0015;
  so.camera_bias_lean_m = 0.0015;
  so.camera_bias_time_s = bias_time_s;
  return so;
}

// The filter as fusion_proc makes it for such a camera: the bias sigma is the
// camera's correlated sigma (the site's marker height x tilt sigma), the
// correlation time the default.
fusion::PoseFilterOptions BiasFromSite(const fusion::synthetic::StreamOptions& so) {
  fusion::PoseFilterOptions options;
  options.camera_bias_sigma_m = std::sqrt(so.camera_bias_sigma_m * so.camera_bias_sigma_m +
                                          0.5 * so.camera_bias_lean_m * so.camera_bias_lean_m);
  return options;
}

TEST(FusionCalibration, CorrelatedCameraErrorFillsTheFusedEllipses) {
  // The filter's correlation time is 1 s; the camera's true one 0.3 s to
  // 3 s (and the lean, which never decorrelates): the model must hold for a
  // time it does not know exactly. Four seeds pooled each.
  for (const double true_time_s : {0.3, 1.0, 3.0}) {
    const fusion::synthetic::StreamOptions so = CorrelatedCamera(true_time_s);
    const analysis::FixQuality q = FuseSimulated(so, BiasFromSite(so), /*with_camera=*/true);
    std::printf(
        "correlated camera error, true time %.1f s: %d estimates, RMSE %.3f mm, %.1f %% inside, "
        "median d2 %.2f\n",
        true_time_s, q.with_covariance, q.rmse_m * 1e3, q.share_inside_95 * 100, q.median_d2);
    EXPECT_GE(q.share_inside_95, kCoverageLow) << true_time_s;
    EXPECT_LE(q.share_inside_95, kCoverageHigh) << true_time_s;
  }
}

TEST(FusionCalibration, WhiteCameraModelIsOverconfidentUnderCorrelatedError) {
  // The filter before the bias state (a correlation time of 0: every camera
  // error white) on the same streams: it averages frames whose errors are
  // the same and its covariance shrinks far below the error, as make demo
  // showed under the webcam (57.6 % inside). This is what the test above
  // would see without the model.
  constexpr double kFarBelowBand = 0.75;
  const fusion::synthetic::StreamOptions so = CorrelatedCamera(1.0);
  fusion::PoseFilterOptions white = BiasFromSite(so);
  white.camera_bias_time_s = 0.0;
  const analysis::FixQuality q = FuseSimulated(so, white, /*with_camera=*/true);
  std::printf("white camera model: %d estimates, RMSE %.3f mm, %.1f %% inside, median d2 %.2f\n",
              q.with_covariance, q.rmse_m * 1e3, q.share_inside_95 * 100, q.median_d2);
  EXPECT_LT(q.share_inside_95, kFarBelowBand);
}

TEST(FusionCalibration, CameralessDemoUltrasoundFusesWithinTheIssuesTargets) {
  // The camera-less demo's POSE_ULTRASOUND as trilat_proc published it (radio
  // faults, 5 % NLOS ranges; tests/data/README.md), replayed in receive
  // order. The issue's targets for POSE_FUSED: RMSE at most 1.5 cm, 90-98 %
  // inside, asserted as the issue states them. Measured on this recording
  // (re-recorded with the merged trilateration and fusion): 1.31 cm, 97.9 %
  // inside (381 of 389), so one more estimate inside would cross 98 %: one
  // 40 s run is about 40 independent samples of the share (the fused error
  // decorrelates over about a second), a binomial standard deviation of
  // 3.4 %, and a re-recording may land above the band by chance. Widen
  // nothing then: find out why, as the pooled simulated streams above carry
  // the band with thousands of estimates.
  constexpr double kTargetRmseM = 0.015;
  const PoseLogs logs =
      ReadPoseLogs({testing::SourceDir() + "/tests/data/ultrasound_demo_40s.lcm"});
  ASSERT_TRUE(logs.logs.front().error.empty()) << logs.logs.front().error;
  const analysis::FixQuality q = ReplayIntoFilter(logs, "ultrasound", fusion::PoseFilterOptions{});
  std::printf("recorded ultrasound: %d estimates, RMSE %.2f cm, %.2f %% inside, median d2 %.2f\n",
              q.with_covariance, q.rmse_m * 1e2, q.share_inside_95 * 100, q.median_d2);
  EXPECT_GT(q.compared, 350);
  EXPECT_LE(q.rmse_m, kTargetRmseM);
  EXPECT_GE(q.share_inside_95, kCoverageLow);
  EXPECT_LE(q.share_inside_95, kCoverageHigh);
}

}  // namespace
}  // namespace roomfix
