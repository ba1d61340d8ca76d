// fusion_proc: camera and ultrasound poses (POSE_CAMERA, POSE_ULTRASOUND) to
// fused poses (POSE_FUSED), one extended Kalman filter per robot.
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <iostream>

#include "fusion/fusion_node.h"
#include "msgio/process.h"

int main(int argc, char** argv) {
  roomfix::ProcessOptions process;
  roomfix::FusionNodeOptions options;
  roomfix::fusion::PoseFilterOptions& filter = options.filter;
  CLI::App app{
      "fusion_proc: fuses POSE_CAMERA and POSE_ULTRASOUND into POSE_FUSED (an extended Kalman "
      "filter per robot)"};
  roomfix::AddProcessFlags(&app, &process, /*config_required=*/true);
  app.add_option("--camera-channel", options.camera_channel, "Camera poses")->capture_default_str();
  app.add_option("--ultrasound-channel", options.ultrasound_channel, "Ultrasonic poses")
      ->capture_default_str();
  app.add_option("--fused-channel", options.fused_channel, "Fused poses")->capture_default_str();
  app.add_option("--rate", options.rate_hz,
                 "Also publish each robot's prediction to now at this rate, Hz (0: only at "
                 "measurements)")
      ->capture_default_str();
  app.add_option("--forget-after", options.forget_after_s,
                 "Drop a robot's track after this long without a measurement, s")
      ->capture_default_str();
  app.add_option("--lost-after", filter.lost_after_s,
                 "A robot is lost when no measurement was accepted for this long, s")
      ->capture_default_str();
  app.add_option("--q-accel", filter.q_accel_mps2,
                 "Process noise: white acceleration density, m/s^2/sqrt(Hz)")
      ->capture_default_str();
  app.add_option("--q-turn", filter.q_turn_radps2,
                 "Process noise: white angular acceleration density, rad/s^2/sqrt(Hz)")
      ->capture_default_str();
  app.add_option("--ultrasound-sigma-floor", filter.ultrasound_sigma_floor_m,
                 "Smallest standard deviation granted to an ultrasonic position, m")
      ->capture_default_str();
  app.add_option("--ultrasound-inflation", filter.ultrasound_inflation,
                 "Factor on the ultrasonic covariances")
      ->capture_default_str();
  app.add_option("--camera-sigma-floor", filter.camera_sigma_floor_m,
                 "Smallest standard deviation granted to a camera position, m")
      ->capture_default_str();
  app.add_option("--gate", filter.gate_chi2_2dof,
                 "Gate on the squared Mahalanobis distance of a position (chi-square, 2 dof)")
      ->capture_default_str();
  app.add_option("--reopen-after", filter.reopen_after_rejections,
                 "Consecutive rejections after which the gate reopens")
      ->capture_default_str();
  app.add_option("--history", filter.history_s,
                 "How far back a late measurement is still applied at its time, s")
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);

  std::string error;
  if (!options.IsValid(&error)) {
    std::cerr << "fusion_proc: " << error << "\n";
    return 1;
  }
  auto ctx = roomfix::StartProcess("fusion_proc", process, &error);
  if (ctx == nullptr) {
    std::cerr << "fusion_proc: " << error << "\n";
    return 1;
  }
  if (process.check) {
    std::cout << "fusion_proc: ok: " << options.camera_channel << " + "
              << options.ultrasound_channel << " -> " << options.fused_channel << ", q_accel "
              << filter.q_accel_mps2 << " m/s^2, lost after " << filter.lost_after_s << " s, "
              << (options.rate_hz > 0.0 ? "rate " + std::to_string(options.rate_hz) + " Hz"
                                        : std::string("per measurement"))
              << ", on " << process.lcm_url << "\n";
    return 0;
  }
  roomfix::FusionNode node(ctx->site, ctx->bus.get(), options, roomfix::NowUtime());
  spdlog::info("fusing {} and {} into {}", options.camera_channel, options.ultrasound_channel,
               options.fused_channel);
  const int rc = roomfix::RunLoop(ctx->bus.get(), [&](int64_t now) { node.Tick(now); }, {});
  node.Stop(roomfix::NowUtime());
  return rc;
}
