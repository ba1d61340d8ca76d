// roomfix_sim: the simulator. Publishes the simulated robots' ground truth
// from the site file's `simulation` section and, on request, plays the wall
// devices on a pseudo-terminal (for zigbee_bridge) or publishes ideal range
// sets directly.
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <cstdio>
#include <iostream>

#include "msgio/process.h"
#include "sim/ground_truth_node.h"
#include "sim/pseudo_terminal.h"
#include "sim/ranges_node.h"
#include "sim/shared_air.h"
#include "sim/wall_devices.h"

namespace {

// `--air-bench`: the room's decay and slot, then, for 1 to 12 beacons, the
// rate each gets and the share of ranges corrupted, with the TDMA table and
// with free-running beacons (docs/trilateration.md, "Sharing the air").
int RunAirBench(const roomfix::Site& site, double duration_s, int seeds, double rate_hz,
                double clock_ppm) {
  const roomfix::RoomDecay d = roomfix::ComputeRoomDecay(site, site.simulation.temperature_c);
  std::printf("Air of %s: %.1f x %.1f x %.1f m, %.1f degC, %.0f%% RH, walls absorb %.2f\n",
              site.name.c_str(), site.room.size_x_m, site.room.size_y_m, site.room.height_m,
              site.simulation.temperature_c, site.acoustics.humidity_percent,
              site.acoustics.wall_absorption);
  std::printf(
      "  air absorption %.2f dB/m at %.0f kHz, T60 %.3f s, longest path %.2f m (%.1f ms)\n"
      "  pulse at 1 m %.1f dB over threshold, tail starts %.1f dB over, decay %.1f ms%s\n"
      "  slot = flight %.1f ms + decay %.1f ms + clock %.1f ms = %.1f ms\n",
      d.air_absorption_db_per_m, site.acoustics.frequency_hz / 1000.0, d.reverberation_time_s,
      d.max_range_m, d.max_time_of_flight_s * 1e3, d.level_at_1m_db, d.tail_start_db,
      d.decay_s * 1e3, d.decay_from_site ? " (site's acoustics.decay_s)" : "",
      d.max_time_of_flight_s * 1e3, d.decay_s * 1e3, site.acoustics.clock_uncertainty_s * 1e3,
      d.slot_s * 1e3);
  std::printf("%d s x %d seeds per row, beacons at random places, crystals +-%.0f ppm\n",
              static_cast<int>(duration_s), seeds, clock_ppm);
  std::printf("%8s | %-13s | %12s | %18s | %16s | %14s\n", "beacons", "schedule", "Hz/beacon",
              "corrupted ranges", "corrupted sets", "clean Hz/beacon");
  for (int n : {1, 2, 4, 8, 12}) {
    for (auto mode : {roomfix::FiringPlanOptions::Mode::kTdma,
                      roomfix::FiringPlanOptions::Mode::kFreeRunning}) {
      int64_t corrupted = 0, pairs = 0, bad_sets = 0, firings = 0;
      double rate = 0.0, clean = 0.0;
      for (int s = 1; s <= seeds; ++s) {
        roomfix::SharedAirOptions o;
        o.mode = mode;
        o.rate_hz = rate_hz;
        o.clock_ppm = clock_ppm;
        o.seed = static_cast<uint64_t>(s);
        const roomfix::AirBenchRow row = roomfix::MeasureAir(site, n, o, duration_s);
        corrupted += row.counters.corrupted();
        pairs += row.counters.pairs;
        bad_sets += row.corrupted_firings;
        firings += row.counters.firings;
        rate = row.rate_per_beacon_hz;
        clean += row.clean_rate_per_beacon_hz / seeds;
      }
      std::printf("%8d | %-13s | %12.2f | %9.1f%% %7lld | %7.1f%% %7lld | %14.2f\n", n,
                  mode == roomfix::FiringPlanOptions::Mode::kTdma ? "tdma" : "free-running", rate,
                  pairs ? 100.0 * corrupted / pairs : 0.0, static_cast<long long>(corrupted),
                  firings ? 100.0 * bad_sets / firings : 0.0, static_cast<long long>(bad_sets),
                  clean);
    }
  }
  return 0;
}

}  // namespace

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
  auto* air = app.add_option_group("The beacons' shared air (both range paths)");
  std::string schedule = "tdma";
  double clock_ppm = 50.0;
  bool no_collisions = false;
  bool air_bench = false;
  int bench_seeds = 10;
  air->add_option("--schedule", schedule,
                  "tdma (the site's firing table, docs/radio_protocol.md) or free (each beacon "
                  "at the rate on its own clock)")
      ->capture_default_str()
      ->check(CLI::IsMember({"tdma", "free"}));
  air->add_option("--beacon-clock-ppm", clock_ppm, "Beacon crystal error, +- ppm")
      ->capture_default_str();
  air->add_flag("--no-collisions", no_collisions,
                "Each receiver hears only the beacon it times (no overlap of pulses)");
  air->add_flag("--air-bench", air_bench,
                "Print the room's decay, slot and, for 1-12 beacons, the rate per beacon and "
                "the corrupted-range share with and without the TDMA table; then exit "
                "(--duration: seconds per run, default 60)");
  air->add_option("--bench-seeds", bench_seeds, "Runs per row of --air-bench")
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  const auto mode = schedule == "tdma" ? roomfix::FiringPlanOptions::Mode::kTdma
                                       : roomfix::FiringPlanOptions::Mode::kFreeRunning;
  ranges.schedule = mode;
  wall.schedule = mode;
  ranges.clock_ppm = clock_ppm;
  wall.clock_ppm = clock_ppm;
  ranges.collisions = !no_collisions;
  wall.collisions = !no_collisions;

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
  if (air_bench) {
    roomfix::Site site;
    if (!roomfix::LoadSite(process.config_path, &site, &error)) {
      std::cerr << "roomfix_sim: " << error << "\n";
      return 1;
    }
    if (bench_seeds < 1 || bench_seeds > 1000) {
      std::cerr << "roomfix_sim: --bench-seeds must be in [1, 1000]\n";
      return 1;
    }
    return RunAirBench(site, duration_s > 0.0 ? duration_s : 60.0, bench_seeds, ranges.rate_hz,
                       clock_ppm);
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

  // One pseudo-terminal per coordinator: the site's radios, or one for all.
  std::vector<int> radio_ids;
  for (const auto& r : ctx->site.radios) radio_ids.push_back(r.id);
  if (radio_ids.empty()) radio_ids.push_back(0);
  std::vector<std::unique_ptr<roomfix::PseudoTerminal>> ptys;
  if (radio_pty) {
    for (int id : radio_ids) {
      // Several radios: --pty-link L makes L-<radio id> for each.
      const std::string link =
          pty_link.empty() || id == 0 ? pty_link : pty_link + "-" + std::to_string(id);
      ptys.push_back(roomfix::PseudoTerminal::Open(link, &error));
      if (ptys.back() == nullptr) {
        std::cerr << "roomfix_sim: " << error << "\n";
        return 1;
      }
      // The line a script reads to find the device for zigbee_bridge (one per
      // radio, in the site's order).
      std::cout << (link.empty() ? ptys.back()->device_path() : link) << std::endl;
      spdlog::info("wall devices{} on {}{}", id == 0 ? "" : " of radio " + std::to_string(id),
                   ptys.back()->device_path(), link.empty() ? "" : " (link " + link + ")");
    }
  }

  options.start_utime = start_utime > 0 ? start_utime : roomfix::NowUtime();
  roomfix::GroundTruthNode node(ctx->site, ctx->bus.get(), options);
  ranges.start_utime = options.start_utime;
  roomfix::SimRangesNode ranges_node(ctx->site, ctx->bus.get(), ranges);
  wall.start_utime = options.start_utime;
  // Each coordinator's devices run the same schedule (same seed) and hear
  // the same announcements; each writes its own receivers' reports.
  std::vector<std::unique_ptr<roomfix::VirtualWallDevices>> devices;
  for (size_t k = 0; k < ptys.size(); ++k) {
    roomfix::WallDevicesOptions w = wall;
    w.radio_id = radio_ids[k];
    devices.push_back(std::make_unique<roomfix::VirtualWallDevices>(ctx->site, w));
  }
  std::vector<uint8_t> bytes;
  int64_t write_failures = 0;
  roomfix::RunLoopOptions loop;
  loop.duration_s = duration_s;
  // The radio's timing (bursts, latencies of a few ms) needs a finer tick
  // than the ground truth does.
  if (radio_pty) loop.tick_period_ms = 1;
  if (!ptys.empty() && ptys.size() != devices.size()) return 1;
  const int rc = roomfix::RunLoop(
      ctx->bus.get(),
      [&](int64_t now) {
        node.Tick(now);
        if (publish_ranges) ranges_node.Tick(now);
        for (size_t k = 0; k < ptys.size(); ++k) {
          bytes.clear();
          devices[k]->Advance(now, &bytes);
          if (!bytes.empty() && !ptys[k]->Write(bytes.data(), bytes.size(), &error)) {
            if (write_failures++ % 100 == 0) spdlog::warn("{}", error);
          }
        }
      },
      loop);
  for (size_t k = 0; k < devices.size(); ++k) {
    const roomfix::AirCounters& a = devices[k]->air().counters();
    spdlog::info(
        "wall devices{}: {} firings, {} frames, {} writes failed; air: {} ranges, {} corrupted "
        "({} early, {} armed in a tail)",
        radio_ids[k] == 0 ? "" : " of radio " + std::to_string(radio_ids[k]), devices[k]->firings(),
        devices[k]->frames_written(), write_failures, a.pairs, a.corrupted(), a.early,
        a.armed_in_tail);
  }
  if (publish_ranges) {
    const roomfix::AirCounters& a = ranges_node.air().counters();
    spdlog::info("ranges: {} firings at {:.2f} Hz per beacon; air: {} ranges, {} corrupted",
                 a.firings, ranges_node.air().rate_hz(), a.pairs, a.corrupted());
  }
  node.Stop(roomfix::NowUtime());
  spdlog::info("stopped after {} samples", node.samples_published());
  return rc;
}
