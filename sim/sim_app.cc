#include "sim/sim_app.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <iostream>
#include <memory>
#include <vector>

#include "sim/firmware_devices.h"
#include "sim/pseudo_terminal.h"
#include "sim/shared_air.h"

namespace roomfix {

bool SimAppOptions::IsValid(std::string* error) const {
  std::string why;
  if (!ground_truth.IsValid(&why)) {
    *error = "--rate-hz: " + why;
    return false;
  }
  if (!ranges.IsValid(&why)) {
    *error = "ranges: " + why;
    return false;
  }
  if (publish_ranges && radio_pty) {
    *error =
        "--ranges and --radio-pty exclude each other: the ideal radio publishes RANGES itself, "
        "the virtual devices feed zigbee_bridge";
    return false;
  }
  if (devices != "behavioural" && devices != "firmware") {
    *error = "--devices must be behavioural or firmware";
    return false;
  }
  if (devices == "firmware" && !radio_pty) {
    *error = "--devices firmware plays the devices behind --radio-pty; give it too";
    return false;
  }
  if (!wall.IsValid(&why)) {
    *error = "wall devices: " + why;
    return false;
  }
  return true;
}

namespace {

// " of radio N", or "" for the single coordinator (id 0), in log lines.
std::string OfRadio(int radio_id) {
  return radio_id == 0 ? "" : " of radio " + std::to_string(radio_id);
}

// One pseudo-terminal per coordinator: the site's radios, or one (id 0) for
// every receiver when the site names none.
struct Coordinators {
  std::vector<int> radio_ids;
  std::vector<std::unique_ptr<PseudoTerminal>> ptys;
};

bool OpenPseudoTerminals(const Site& site, const std::string& pty_link, Coordinators* out,
                         std::string* error) {
  for (const auto& r : site.radios) out->radio_ids.push_back(r.id);
  if (out->radio_ids.empty()) out->radio_ids.push_back(0);
  for (int id : out->radio_ids) {
    // Several radios: --pty-link L makes L-<radio id> for each.
    const std::string link =
        pty_link.empty() || id == 0 ? pty_link : pty_link + "-" + std::to_string(id);
    out->ptys.push_back(PseudoTerminal::Open(link, error));
    if (out->ptys.back() == nullptr) return false;
    // The line a script reads to find the device for zigbee_bridge (one per
    // radio, in the site's order).
    std::cout << (link.empty() ? out->ptys.back()->device_path() : link) << std::endl;
    spdlog::info("wall devices{} on {}{}", OfRadio(id), out->ptys.back()->device_path(),
                 link.empty() ? "" : " (link " + link + ")");
  }
  return true;
}

void PrintCheckLine(const ProcessContext& ctx, const SimAppOptions& options) {
  std::cout << "roomfix_sim: ok: " << ctx.site.simulation.robots.size() << " robot(s) at "
            << options.ground_truth.rate_hz << " Hz on " << ctx.options.lcm_url;
  if (options.radio_pty) {
    std::cout << ", wall devices (" << options.devices << ") on a pseudo-terminal (faults "
              << options.faults_preset << ")";
  }
  std::cout << "\n";
}

// The firmware devices' tick: run them to now (at most 50 ms of simulated
// time a tick, so the bus is still served on a machine too slow for real
// time, which is logged), and write their coordinator's bytes to every
// pseudo-terminal: the reports are broadcasts every coordinator hears, and
// each bridge (--radio) keeps its own receivers'.
void TickFirmware(FirmwareDevices* firmware,
                  const std::vector<std::unique_ptr<PseudoTerminal>>& ptys, int64_t now,
                  int64_t start_utime, std::vector<uint8_t>* bytes, int64_t* write_failures) {
  constexpr double kMaxStepS = 0.05;
  constexpr double kBehindWarnS = 1.0;
  static double warned_at_s = 0.0;
  bytes->clear();
  firmware->Advance(now, kMaxStepS, bytes);
  const double behind_s = (now - start_utime) * 1e-6 - firmware->simulated_s();
  if (behind_s > kBehindWarnS && firmware->simulated_s() - warned_at_s > 10.0) {
    warned_at_s = firmware->simulated_s();
    spdlog::warn("firmware devices {:.1f} s behind real time (this machine simulates slower)",
                 behind_s);
  }
  std::string write_error;
  for (const auto& pty : ptys) {
    if (!bytes->empty() && !pty->Write(bytes->data(), bytes->size(), &write_error)) {
      if ((*write_failures)++ % 100 == 0) spdlog::warn("{}", write_error);
    }
  }
}

}  // namespace

int RunSimulator(ProcessContext* ctx, const SimAppOptions& options, std::string* error) {
  const Site& site = ctx->site;
  if (site.simulation.robots.empty()) {
    *error = ctx->options.config_path + ": simulation.robots is empty; nothing to simulate";
    return 1;
  }
  for (const auto& robot : site.simulation.robots) {
    spdlog::info("robot {}: {}", robot.robot_id, robot.trajectory->Describe());
  }
  if (ctx->options.check) {
    PrintCheckLine(*ctx, options);
    return 0;
  }
  Coordinators coordinators;
  if (options.radio_pty && !OpenPseudoTerminals(site, options.pty_link, &coordinators, error)) {
    return 1;
  }

  const int64_t start_utime = options.start_utime > 0 ? options.start_utime : NowUtime();
  GroundTruthNodeOptions truth_options = options.ground_truth;
  truth_options.start_utime = start_utime;
  GroundTruthNode node(site, ctx->bus.get(), truth_options);
  SimRangesNodeOptions ranges_options = options.ranges;
  ranges_options.start_utime = start_utime;
  SimRangesNode ranges_node(site, ctx->bus.get(), ranges_options);
  // Each coordinator's devices run the same schedule (same seed) and hear
  // the same announcements; each writes its own receivers' reports.
  const std::vector<std::unique_ptr<PseudoTerminal>>& ptys = coordinators.ptys;
  std::vector<std::unique_ptr<VirtualWallDevices>> devices;
  std::unique_ptr<FirmwareDevices> firmware;
  if (options.devices == "firmware") {
    FirmwareDevicesOptions f;
    f.firmware_dir = options.firmware_dir;
    f.faults = options.wall.faults;
    f.seed = options.wall.seed;
    f.start_utime = start_utime;
    firmware = FirmwareDevices::Create(site, f, error);
    if (firmware == nullptr) return 1;
    spdlog::info("wall devices: the firmware in simavr ({})", firmware->Summary());
  }
  for (size_t k = 0; k < ptys.size() && firmware == nullptr; ++k) {
    WallDevicesOptions w = options.wall;
    w.start_utime = start_utime;
    w.radio_id = coordinators.radio_ids[k];
    devices.push_back(std::make_unique<VirtualWallDevices>(site, w));
  }
  std::vector<uint8_t> bytes;
  int64_t write_failures = 0;
  std::string write_error;
  RunLoopOptions loop;
  loop.duration_s = options.duration_s;
  // The radio's timing (bursts, latencies of a few ms) needs a finer tick
  // than the ground truth does.
  if (options.radio_pty) loop.tick_period_ms = 1;
  const int rc = RunLoop(
      ctx->bus.get(),
      [&](int64_t now) {
        node.Tick(now);
        if (options.publish_ranges) ranges_node.Tick(now);
        if (firmware != nullptr) {
          TickFirmware(firmware.get(), ptys, now, start_utime, &bytes, &write_failures);
          return;
        }
        for (size_t k = 0; k < ptys.size(); ++k) {
          bytes.clear();
          devices[k]->Advance(now, &bytes);
          if (!bytes.empty() && !ptys[k]->Write(bytes.data(), bytes.size(), &write_error)) {
            if (write_failures++ % 100 == 0) spdlog::warn("{}", write_error);
          }
        }
      },
      loop);
  if (firmware != nullptr) spdlog::info("wall devices (firmware): {}", firmware->Summary());
  for (size_t k = 0; k < devices.size(); ++k) {
    const AirCounters& a = devices[k]->air().counters();
    spdlog::info(
        "wall devices{}: {} firings, {} frames, {} writes failed; air: {} ranges, {} corrupted "
        "({} early, {} armed in a tail)",
        OfRadio(coordinators.radio_ids[k]), devices[k]->firings(), devices[k]->frames_written(),
        write_failures, a.pairs, a.corrupted(), a.early, a.armed_in_tail);
  }
  if (options.publish_ranges) {
    const AirCounters& a = ranges_node.air().counters();
    spdlog::info("ranges: {} firings at {:.2f} Hz per beacon; air: {} ranges, {} corrupted",
                 a.firings, ranges_node.air().rate_hz(), a.pairs, a.corrupted());
  }
  node.Stop(NowUtime());
  spdlog::info("stopped after {} samples", node.samples_published());
  return rc;
}

int RunAirBench(const std::string& config_path, const SharedAirOptions& air, double duration_s,
                int seeds, std::string* error) {
  Site site;
  if (!LoadSite(config_path, &site, error)) return 1;
  // A row is the mean of its runs; a thousand runs of a minute are already
  // a day.
  if (seeds < 1 || seeds > 1000) {
    *error = "--bench-seeds must be in [1, 1000]";
    return 1;
  }
  const RoomDecay d = ComputeRoomDecay(site, site.simulation.temperature_c);
  fmt::print(
      "Air of {}: {:.1f} x {:.1f} x {:.1f} m, {:.1f} degC, {:.0f}% RH, walls absorb {:.2f}\n",
      site.name.c_str(), site.room.size_x_m, site.room.size_y_m, site.room.height_m,
      site.simulation.temperature_c, site.acoustics.humidity_percent,
      site.acoustics.wall_absorption);
  fmt::print(
      "  air absorption {:.2f} dB/m at {:.0f} kHz, T60 {:.3f} s, longest path {:.2f} m ({:.1f} "
      "ms)\n"
      "  pulse at 1 m {:.1f} dB over threshold, tail starts {:.1f} dB over, decay {:.1f} ms{}\n"
      "  slot = flight {:.1f} ms + decay {:.1f} ms + clock {:.1f} ms = {:.1f} ms\n",
      d.air_absorption_db_per_m, site.acoustics.frequency_hz / 1000.0, d.reverberation_time_s,
      d.max_range_m, d.max_time_of_flight_s * 1e3, d.level_at_1m_db, d.tail_start_db,
      d.decay_s * 1e3, d.decay_from_site ? " (site's acoustics.decay_s)" : "",
      d.max_time_of_flight_s * 1e3, d.decay_s * 1e3, site.acoustics.clock_uncertainty_s * 1e3,
      d.slot_s * 1e3);
  fmt::print("{} s x {} seeds per row, beacons at random places, crystals +-{:.0f} ppm\n",
             static_cast<int>(duration_s), seeds, air.clock_ppm);
  fmt::print("{:>8} | {:<13} | {:>12} | {:>18} | {:>16} | {:>14}\n", "beacons", "schedule",
             "Hz/beacon", "corrupted ranges", "corrupted sets", "clean Hz/beacon");
  for (int n : {1, 2, 4, 8, 12}) {
    for (auto mode : {FiringPlanOptions::Mode::kTdma, FiringPlanOptions::Mode::kFreeRunning}) {
      int64_t corrupted = 0, pairs = 0, bad_sets = 0, firings = 0;
      double rate = 0.0, clean = 0.0;
      for (int s = 1; s <= seeds; ++s) {
        SharedAirOptions o = air;
        o.mode = mode;
        o.seed = static_cast<uint64_t>(s);
        const AirBenchRow row = MeasureAir(site, n, o, duration_s);
        corrupted += row.counters.corrupted();
        pairs += row.counters.pairs;
        bad_sets += row.corrupted_firings;
        firings += row.counters.firings;
        rate = row.rate_per_beacon_hz;
        clean += row.clean_rate_per_beacon_hz / seeds;
      }
      fmt::print("{:8} | {:<13} | {:12.2f} | {:9.1f}% {:7} | {:7.1f}% {:7} | {:14.2f}\n", n,
                 mode == FiringPlanOptions::Mode::kTdma ? "tdma" : "free-running", rate,
                 pairs ? 100.0 * corrupted / pairs : 0.0, static_cast<long long>(corrupted),
                 firings ? 100.0 * bad_sets / firings : 0.0, static_cast<long long>(bad_sets),
                 clean);
    }
  }
  return 0;
}

}  // namespace roomfix
