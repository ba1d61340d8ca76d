// roomfix_sim: the simulator. Publishes the simulated robots' ground truth
// from the site file's `simulation` section.
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <iostream>

#include "msgio/process.h"
#include "sim/ground_truth_node.h"
#include "sim/ranges_node.h"

int main(int argc, char** argv) {
  roomfix::ProcessOptions process;
  roomfix::GroundTruthNodeOptions options;
  roomfix::SimRangesNodeOptions ranges;
  bool publish_ranges = false;
  double duration_s = 0.0;
  CLI::App app{"roomfix_sim: publishes simulated robots' true poses on POSE_GROUND_TRUTH"};
  roomfix::AddProcessFlags(&app, &process, /*config_required=*/true);
  app.add_option("--rate-hz", options.rate_hz, "Ground-truth samples per second")
      ->capture_default_str();
  app.add_option("--duration", duration_s, "Stop after this many seconds (0: until a signal)")
      ->capture_default_str();
  app.add_flag("--ranges", publish_ranges,
               "Also publish range sets on RANGES directly (an ideal radio, bypassing the "
               "virtual wall devices and zigbee_bridge)");
  app.add_option("--ranges-rate-hz", ranges.rate_hz, "Firings per second of each beacon")
      ->capture_default_str();
  app.add_option("--range-noise", ranges.noise.sigma_m, "Gaussian range noise, m")
      ->capture_default_str();
  app.add_option("--nlos-probability", ranges.noise.nlos_probability,
                 "Share of ranges that take a reflected path (+0.3 to +1.0 m)")
      ->capture_default_str();
  app.add_option("--dropout-probability", ranges.noise.dropout_probability,
                 "Share of receivers that miss a firing")
      ->capture_default_str();
  app.add_option("--seed", ranges.seed, "Noise generator seed")->capture_default_str();
  CLI11_PARSE(app, argc, argv);

  std::string error;
  if (!options.IsValid(&error)) {
    std::cerr << "roomfix_sim: --rate-hz: " << error << "\n";
    return 1;
  }
  if (!ranges.IsValid(&error)) {
    std::cerr << "roomfix_sim: ranges: " << error << "\n";
    return 1;
  }
  auto ctx = roomfix::StartProcess("roomfix_sim", process, &error);
  if (ctx == nullptr) {
    std::cerr << "roomfix_sim: " << error << "\n";
    return 1;
  }
  if (ctx->site.simulation.robots.empty()) {
    std::cerr << "roomfix_sim: " << process.config_path
              << ": simulation.robots is empty; nothing to simulate\n";
    return 1;
  }
  for (const auto& robot : ctx->site.simulation.robots) {
    spdlog::info("robot {}: {}", robot.robot_id, robot.trajectory->Describe());
  }
  if (process.check) {
    std::cout << "roomfix_sim: ok: " << ctx->site.simulation.robots.size() << " robot(s) at "
              << options.rate_hz << " Hz on " << process.lcm_url << "\n";
    return 0;
  }

  options.start_utime = roomfix::NowUtime();
  roomfix::GroundTruthNode node(ctx->site, ctx->bus.get(), options);
  ranges.start_utime = options.start_utime;
  roomfix::SimRangesNode ranges_node(ctx->site, ctx->bus.get(), ranges);
  roomfix::RunLoopOptions loop;
  loop.duration_s = duration_s;
  const int rc = roomfix::RunLoop(
      ctx->bus.get(),
      [&](int64_t now) {
        node.Tick(now);
        if (publish_ranges) ranges_node.Tick(now);
      },
      loop);
  node.Stop(roomfix::NowUtime());
  spdlog::info("stopped after {} samples", node.samples_published());
  return rc;
}
