// roomfix_sim: the simulator. Publishes the simulated robots' ground truth
// from the site file's `simulation` section and, on request, plays the wall
// devices on a pseudo-terminal (for zigbee_bridge) or publishes ideal range
// sets directly.
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <iostream>

#include "msgio/process.h"
#include "sim/ground_truth_node.h"
#include "sim/pseudo_terminal.h"
#include "sim/ranges_node.h"
#include "sim/wall_devices.h"

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
  int64_t start_utime = 0;
  app.add_option("--start-utime", start_utime,
                 "The simulation's t = 0, microseconds since the Unix epoch (default: now); give "
                 "camera_proc's synthetic camera the same so both see the robot in one place");

  roomfix::WallDevicesOptions wall;
  bool radio_pty = false;
  std::string pty_link;
  std::string faults_preset = "none";
  int api_mode = 2;
  std::string frame_type = "zigbee";
  auto* radio = app.add_option_group("Virtual wall devices (--radio-pty)");
  radio->add_flag("--radio-pty", radio_pty,
                  "Play the beacon and the wall receivers: write the coordinator's XBee API "
                  "frames to a pseudo-terminal whose path is printed on stdout");
  radio->add_option("--pty-link", pty_link,
                    "Also make this symlink to the pseudo-terminal (a stable path for "
                    "zigbee_bridge --port across restarts)");
  radio->add_option("--api-mode", api_mode, "XBee API mode: 1 (unescaped) or 2 (escaped)")
      ->capture_default_str()
      ->check(CLI::IsMember({1, 2}));
  radio
      ->add_option("--frame-type", frame_type,
                   "zigbee (0x90 receive packets) or 802.15.4 (0x80, 64-bit source)")
      ->capture_default_str()
      ->check(CLI::IsMember({"zigbee", "802.15.4"}));
  radio->add_option("--radio-rate-hz", wall.rate_hz, "Firings per second of each beacon")
      ->capture_default_str();
  radio
      ->add_option("--faults", faults_preset,
                   "none, or all (every fault below at a high rate); the flags below override")
      ->capture_default_str()
      ->check(CLI::IsMember({"none", "all"}));
  double* fault_values[] = {&wall.faults.announcement_delay_probability,
                            &wall.faults.lost_report_probability,
                            &wall.faults.lost_announcement_probability,
                            &wall.faults.buffer_probability,
                            &wall.faults.reorder_probability,
                            &wall.faults.duplicate_probability,
                            &wall.faults.foreign_probability,
                            &wall.faults.corrupt_byte_probability,
                            &wall.faults.garbage_probability};
  const char* fault_flags[] = {
      "--delay-announcement", "--lost-report", "--lost-announcement", "--buffering", "--reorder",
      "--duplicate",          "--foreign",     "--corrupt-byte",      "--garbage"};
  const char* fault_help[] = {
      "Probability that the beacon's module delays an announcement by up to 30 ms (it may "
      "arrive after reports)",
      "Probability that the radio loses a report",
      "Probability that the radio loses a firing announcement",
      "Probability that a receiver's module starts holding reports back and releases them "
      "in a burst",
      "Probability that a report is delayed by 1-3 firing periods",
      "Probability that a report is sent twice",
      "Probability per firing of a report from a module not in the site",
      "Probability per serial byte of a flipped bit",
      "Probability per frame of random bytes before it"};
  constexpr int kFaultFlags = 9;
  double fault_overrides[kFaultFlags] = {};
  for (int i = 0; i < kFaultFlags; ++i) {
    radio->add_option(fault_flags[i], fault_overrides[i], fault_help[i]);
  }
  radio
      ->add_option("--buffer-hold", wall.faults.buffer_hold_max_s,
                   "Longest a buffering module holds reports back, s")
      ->capture_default_str();
  double restart_every_s = 0.0;
  radio
      ->add_option("--restart-every", restart_every_s,
                   "Switch the beacon off for 1 s every this many seconds; it comes back "
                   "counting from 0 (0: never)")
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);

  if (faults_preset == "all") {
    const double hold_s = wall.faults.buffer_hold_max_s;
    wall.faults = roomfix::RadioFaults::All();
    wall.faults.buffer_hold_max_s = hold_s;
  }
  wall.faults.restart_every_s = restart_every_s;
  // A simulator runs for hours; only tests need the record of every firing.
  wall.keep_ledger = false;
  for (int i = 0; i < kFaultFlags; ++i) {
    if (app.count(fault_flags[i]) > 0) *fault_values[i] = fault_overrides[i];
  }
  // The ultrasound flags serve both range paths; --faults all sets its own
  // unless they are given.
  if (faults_preset != "all" || app.count("--range-noise") > 0) {
    wall.faults.ultrasound.sigma_m = ranges.noise.sigma_m;
  }
  if (faults_preset != "all" || app.count("--nlos-probability") > 0) {
    wall.faults.ultrasound.nlos_probability = ranges.noise.nlos_probability;
  }
  if (faults_preset != "all" || app.count("--dropout-probability") > 0) {
    wall.faults.ultrasound.dropout_probability = ranges.noise.dropout_probability;
  }
  wall.api_mode =
      api_mode == 1 ? roomfix::radio::ApiMode::kUnescaped : roomfix::radio::ApiMode::kEscaped;
  wall.frame_type =
      frame_type == "zigbee" ? roomfix::radio::kZigbeeRxFrameType : roomfix::radio::kRx64FrameType;
  wall.seed = ranges.seed;

  std::string error;
  if (!options.IsValid(&error)) {
    std::cerr << "roomfix_sim: --rate-hz: " << error << "\n";
    return 1;
  }
  if (!ranges.IsValid(&error)) {
    std::cerr << "roomfix_sim: ranges: " << error << "\n";
    return 1;
  }
  if (publish_ranges && radio_pty) {
    // Both would put range sets of the same firings on RANGES.
    std::cerr << "roomfix_sim: --ranges and --radio-pty exclude each other: the ideal radio "
                 "publishes RANGES itself, the virtual devices feed zigbee_bridge\n";
    return 1;
  }
  if (!wall.IsValid(&error)) {
    std::cerr << "roomfix_sim: wall devices: " << error << "\n";
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
              << options.rate_hz << " Hz on " << process.lcm_url;
    if (radio_pty)
      std::cout << ", wall devices on a pseudo-terminal (faults " << faults_preset << ")";
    std::cout << "\n";
    return 0;
  }

  std::unique_ptr<roomfix::PseudoTerminal> pty;
  if (radio_pty) {
    pty = roomfix::PseudoTerminal::Open(pty_link, &error);
    if (pty == nullptr) {
      std::cerr << "roomfix_sim: " << error << "\n";
      return 1;
    }
    // The one line a script reads to find the device for zigbee_bridge.
    std::cout << (pty_link.empty() ? pty->device_path() : pty_link) << std::endl;
    spdlog::info("wall devices on {}{}", pty->device_path(),
                 pty_link.empty() ? "" : " (link " + pty_link + ")");
  }

  options.start_utime = start_utime > 0 ? start_utime : roomfix::NowUtime();
  roomfix::GroundTruthNode node(ctx->site, ctx->bus.get(), options);
  ranges.start_utime = options.start_utime;
  roomfix::SimRangesNode ranges_node(ctx->site, ctx->bus.get(), ranges);
  wall.start_utime = options.start_utime;
  roomfix::VirtualWallDevices devices(ctx->site, wall);
  std::vector<uint8_t> bytes;
  int64_t write_failures = 0;
  roomfix::RunLoopOptions loop;
  loop.duration_s = duration_s;
  // The radio's timing (bursts, latencies of a few ms) needs a finer tick
  // than the ground truth does.
  if (radio_pty) loop.tick_period_ms = 1;
  const int rc = roomfix::RunLoop(
      ctx->bus.get(),
      [&](int64_t now) {
        node.Tick(now);
        if (publish_ranges) ranges_node.Tick(now);
        if (pty != nullptr) {
          bytes.clear();
          devices.Advance(now, &bytes);
          if (!bytes.empty() && !pty->Write(bytes.data(), bytes.size(), &error)) {
            if (write_failures++ % 100 == 0) spdlog::warn("{}", error);
          }
        }
      },
      loop);
  if (pty != nullptr) {
    spdlog::info("wall devices: {} firings, {} frames, {} writes failed", devices.firings(),
                 devices.frames_written(), write_failures);
  }
  node.Stop(roomfix::NowUtime());
  spdlog::info("stopped after {} samples", node.samples_published());
  return rc;
}
