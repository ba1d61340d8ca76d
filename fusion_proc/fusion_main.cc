// fusion_proc: camera and ultrasound poses (POSE_CAMERA, POSE_ULTRASOUND) to
// fused poses (POSE_FUSED), one extended Kalman filter per robot.
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <iostream>

#include "fusion_proc/fusion_flags.h"
#include "fusion_proc/fusion_node.h"
#include "msgio/process.h"

int main(int argc, char** argv) {
  roomfix::ProcessOptions process;
  roomfix::FusionNodeOptions options;
  roomfix::fusion::PoseFilterOptions& filter = options.filter;
  CLI::App app{
      "fusion_proc: fuses POSE_CAMERA and POSE_ULTRASOUND into POSE_FUSED (an extended Kalman "
      "filter per robot)"};
  roomfix::AddProcessFlags(&app, &process, /*config_required=*/true);
  roomfix::AddFusionFlags(&app, "", &options);
  CLI11_PARSE(app, argc, argv);

  std::string error;
  if (!options.IsValid(&error)) return roomfix::PrintFailure("fusion_proc", error);
  auto ctx = roomfix::StartProcess("fusion_proc", process, &error);
  if (ctx == nullptr) return roomfix::PrintFailure("fusion_proc", error);
  if (process.check) {
    std::cout << "fusion_proc: ok: " << options.camera_channel << " + "
              << options.ultrasound_channel << " -> " << options.fused_channel << ", q_accel "
              << filter.q_accel_m_per_s1_5 << " m/s^1.5, lost after " << filter.lost_after_s
              << " s, "
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
