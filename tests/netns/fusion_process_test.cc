// The fusion issue's targets on the simulator, with the real processes over
// multicast in a private network namespace: roomfix_sim (ground truth and
// range sets), camera_proc on the demo's simulated webcam, trilat_proc and
// fusion_proc. The fused track must be no worse than the camera's alone at
// the combined rate, and keep a bounded error through a 5 s camera outage
// and a 5 s radio outage (each process frozen with SIGSTOP, as a hung
// device would leave it).
#include <gtest/gtest.h>
#include <signal.h>

#include <chrono>
#include <cmath>
#include <thread>

#include "core/analysis/track_error.h"
#include "msgio/bus.h"
#include "msgio/process.h"
#include "roomfix/pose2d_t.hpp"
#include "tests/testing/demo_site.h"
#include "tests/testing/test_paths.h"

namespace roomfix {
namespace {

using testing::BinDir;
using testing::ChildProcess;
using testing::DemoSitePath;

// Measured in three runs (2026-11-29, a shared 2-core machine at load 12
// to 13, where the simulated webcam kept 26 to 28 frames/s): camera 2.72 to
// 2.79 mm and fused 2.65 to 2.72 mm RMSE in the normal stretch (the robot's
// lean and rocking, as in make demo); through a 5 s camera outage, the
// ultrasound carrying the track, 6.77 to 6.94 mm; through a 5 s radio
// outage, the camera alone, 2.48 to 2.54 mm. Each bound is 1.5x the
// largest figure: the runs spread by 3 %, and a busier machine skips more frames.
constexpr double kMargin = 1.5;
constexpr double kCameraOutageRmseM = 0.00694 * kMargin;
constexpr double kRadioOutageRmseM = 0.00254 * kMargin;
// "No worse than the camera alone": measured 0.97 to 0.99 of the camera's
// RMSE; 1.1 for the two estimates' sampling noise over the same 6 s (the
// lean changes over about a second, so a few independent samples).
constexpr double kFusedOverCameraMax = 1.1;

// Ground truth comes at 30 Hz; a longer gap is a stall, not a sample.
constexpr int64_t kMaxTruthGapUs = 200'000;

struct Window {
  int64_t begin_utime;
  int64_t end_utime;
};

class FusionProcess : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string error;
    bus_ = LcmBus::Create(kDefaultLcmUrl, &error);
    ASSERT_NE(bus_, nullptr) << error;
    bus_->Subscribe<pose2d_t>("POSE_.*", [this](const pose2d_t& p, const MessageInfo& info) {
      if (info.channel == "POSE_GROUND_TRUTH") truth_.push_back(p);
      if (info.channel == "POSE_CAMERA") camera_.push_back(p);
      if (info.channel == "POSE_FUSED") fused_.push_back(p);
    });
  }

  void Listen(double seconds) {
    const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
    while (std::chrono::steady_clock::now() < until) bus_->Handle(50);
  }

  // RMSE of a track's ok/degraded poses in a window against the ground
  // truth interpolated to each pose's time, and their rate.
  std::pair<double, double> Score(const std::vector<pose2d_t>& track, const Window& w) const {
    std::vector<analysis::TimedPosition> estimates, reference;
    for (const pose2d_t& p : track) {
      if (p.utime < w.begin_utime || p.utime > w.end_utime) continue;
      if (p.status != pose2d_t::STATUS_LOST) estimates.push_back({p.utime, p.x_m, p.y_m});
    }
    for (const pose2d_t& p : truth_) reference.push_back({p.utime, p.x_m, p.y_m});
    const analysis::ErrorSummary e =
        analysis::CompareToReference(estimates, reference, kMaxTruthGapUs);
    const double span_s = (w.end_utime - w.begin_utime) * 1e-6;
    return {e.compared > 0 ? e.rmse_m : NAN, estimates.size() / span_s};
  }

  std::unique_ptr<LcmBus> bus_;
  std::vector<pose2d_t> truth_, camera_, fused_;
};

TEST_F(FusionProcess, FusedIsNoWorseThanTheCameraAndRidesOutEachSensorsOutage) {
  ChildProcess sim({BinDir() + "/roomfix_sim", "--config", DemoSitePath(), "--ranges",
                    "--range-noise", "0.01", "--log-level", "warn"});
  ChildProcess trilat({BinDir() + "/trilat_proc", "--config", DemoSitePath(), "--method", "robust",
                       "--log-level", "warn"});
  // fusion_proc and camera_proc as `make demo` runs them (scripts/demo.sh):
  // fusion with its default flags, so the robot's tilt the site states is a
  // bias state (docs/fusion.md, "Correlated camera error"), and camera_proc
  // on the site's own device, the simulated webcam that renders that tilt,
  // with the calibration of the lens it renders through.
  ChildProcess fusion(
      {BinDir() + "/fusion_proc", "--config", DemoSitePath(), "--log-level", "warn"});
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  ChildProcess camera({BinDir() + "/camera_proc", "--config", DemoSitePath(), "--calibration",
                       testing::SourceDir() + "/config/calibration/demo_room_webcam.yaml",
                       "--log-level", "warn"});
  Listen(3.0);  // start-up and the filter's first second
  auto now = [] { return NowUtime(); };

  Window normal{now(), 0};
  Listen(6.0);
  normal.end_utime = now();

  camera.Signal(SIGSTOP);
  Window camera_out{now() + 300'000, 0};
  Listen(5.0);
  camera_out.end_utime = now();
  camera.Signal(SIGCONT);
  Listen(2.0);

  trilat.Signal(SIGSTOP);
  Window radio_out{now() + 300'000, 0};
  Listen(5.0);
  radio_out.end_utime = now();
  trilat.Signal(SIGCONT);
  Listen(1.0);

  const auto [camera_rmse, camera_hz] = Score(camera_, normal);
  const auto [fused_rmse, fused_hz] = Score(fused_, normal);
  const auto [outage_rmse, outage_hz] = Score(fused_, camera_out);
  const auto [radio_rmse, radio_hz] = Score(fused_, radio_out);
  std::printf(
      "normal: camera %.3f mm at %.1f Hz, fused %.3f mm at %.1f Hz\n"
      "camera outage: fused %.2f mm at %.1f Hz\n"
      "radio outage: fused %.3f mm at %.1f Hz\n",
      camera_rmse * 1e3, camera_hz, fused_rmse * 1e3, fused_hz, outage_rmse * 1e3, outage_hz,
      radio_rmse * 1e3, radio_hz);
  EXPECT_LE(fused_rmse, camera_rmse * kFusedOverCameraMax);
  // At the combined rate: the camera's frames plus the 10 Hz firings.
  EXPECT_GT(fused_hz, camera_hz + 5.0);
  EXPECT_LT(outage_rmse, kCameraOutageRmseM);
  EXPECT_GT(outage_hz, 5.0) << "the ultrasound alone keeps the fused track going";
  EXPECT_LT(radio_rmse, kRadioOutageRmseM);

  for (ChildProcess* p : {&camera, &fusion, &trilat, &sim}) p->Signal(SIGINT);
  EXPECT_EQ(fusion.Wait(5), 0);
}

}  // namespace
}  // namespace roomfix
