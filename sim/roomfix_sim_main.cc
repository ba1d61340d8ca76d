// roomfix_sim: the simulator. Publishes the simulated robots' ground truth
// from the site file's `simulation` section and, on request, plays the wall
// devices on a pseudo-terminal (for zigbee_bridge) or publishes ideal range
// sets directly. Flags here; the run is in sim_app.h.
#include <CLI/CLI.hpp>
#include <array>
#include <iostream>

#include "msgio/process.h"
#include "sim/sim_app.h"

namespace {

// The radio faults with a flag each; --faults all sets them all at once and
// a flag given beside it overrides its value.
struct FaultFlag {
  const char* flag;
  double roomfix::RadioFaults::*probability;
  const char* help;
};
constexpr std::array<FaultFlag, 9> kFaultFlags = {{
    {"--delay-announcement", &roomfix::RadioFaults::announcement_delay_probability,
     "Probability that the beacon's module delays an announcement by up to 30 ms (it may "
     "arrive after reports)"},
    {"--lost-report", &roomfix::RadioFaults::lost_report_probability,
     "Probability that the radio loses a report"},
    {"--lost-announcement", &roomfix::RadioFaults::lost_announcement_probability,
     "Probability that the radio loses a firing announcement"},
    {"--buffering", &roomfix::RadioFaults::buffer_probability,
     "Probability that a receiver's module starts holding reports back and releases them "
     "in a burst"},
    {"--reorder", &roomfix::RadioFaults::reorder_probability,
     "Probability that a report is delayed by 1-3 firing periods"},
    {"--duplicate", &roomfix::RadioFaults::duplicate_probability,
     "Probability that a report is sent twice"},
    {"--foreign", &roomfix::RadioFaults::foreign_probability,
     "Probability per firing of a report from a module not in the site"},
    {"--corrupt-byte", &roomfix::RadioFaults::corrupt_byte_probability,
     "Probability per serial byte of a flipped bit"},
    {"--garbage", &roomfix::RadioFaults::garbage_probability,
     "Probability per frame of random bytes before it"},
}};

// The options as the flags give them, before they are mapped onto SimAppOptions.
struct SimMainOptions {
  roomfix::SimAppOptions sim;
  std::string schedule = "tdma";
  double clock_ppm = 50.0;
  bool no_collisions = false;
  int api_mode = 2;
  std::string frame_type = "zigbee";
  double restart_every_s = 0.0;
  std::array<double, kFaultFlags.size()> fault_overrides = {};
  bool air_bench = false;
  int bench_seeds = 10;
};

void AddRangeFlags(CLI::App* app, SimMainOptions* f) {
  roomfix::SimAppOptions& s = f->sim;
  app->add_option("--rate-hz", s.ground_truth.rate_hz, "Ground-truth samples per second")
      ->capture_default_str();
  app->add_option("--duration", s.duration_s, "Stop after this many seconds (0: until a signal)")
      ->capture_default_str();
  app->add_flag("--ranges", s.publish_ranges,
                "Also publish range sets on RANGES directly (an ideal radio, bypassing the "
                "virtual wall devices and zigbee_bridge)");
  app->add_option("--ranges-rate-hz", s.ranges.rate_hz, "Firings per second of each beacon")
      ->capture_default_str();
  app->add_option("--range-noise", s.ranges.noise.sigma_m, "Gaussian range noise, m")
      ->capture_default_str();
  app->add_option("--nlos-probability", s.ranges.noise.nlos_probability,
                  "Share of ranges that take a reflected path (+0.3 to +1.0 m)")
      ->capture_default_str();
  app->add_option("--dropout-probability", s.ranges.noise.dropout_probability,
                  "Share of receivers that miss a firing")
      ->capture_default_str();
  app->add_option("--seed", s.ranges.seed, "Noise generator seed")->capture_default_str();
  app->add_option("--start-utime", s.start_utime,
                  "The simulation's t = 0, microseconds since the Unix epoch (default: now); give "
                  "camera_proc's synthetic camera the same so both see the robot in one place");
}

void AddRadioFlags(CLI::App* app, SimMainOptions* f) {
  roomfix::SimAppOptions& s = f->sim;
  auto* radio = app->add_option_group("Virtual wall devices (--radio-pty)");
  radio->add_flag("--radio-pty", s.radio_pty,
                  "Play the beacon and the wall receivers: write the coordinator's XBee API "
                  "frames to a pseudo-terminal whose path is printed on stdout");
  radio
      ->add_option("--devices", s.devices,
                   "What plays the devices: behavioural (a model of what they send) or firmware "
                   "(the beacon's and receivers' firmware run in simavr, one ATmega328P each, "
                   "with an XBee and an acoustic model; docs/devices_simulation.md)")
      ->capture_default_str()
      ->check(CLI::IsMember({"behavioural", "firmware"}));
  radio->add_option("--firmware-dir", s.firmware_dir,
                    "Folder of beacon.elf and receiver.elf for --devices firmware (default: the "
                    "build tree's firmware/)");
  radio->add_option("--pty-link", s.pty_link,
                    "Also make this symlink to the pseudo-terminal (a stable path for "
                    "zigbee_bridge --port across restarts)");
  radio->add_option("--api-mode", f->api_mode, "XBee API mode: 1 (unescaped) or 2 (escaped)")
      ->capture_default_str()
      ->check(CLI::IsMember({1, 2}));
  radio
      ->add_option("--frame-type", f->frame_type,
                   "zigbee (0x90 receive packets) or 802.15.4 (0x80, 64-bit source)")
      ->capture_default_str()
      ->check(CLI::IsMember({"zigbee", "802.15.4"}));
  radio->add_option("--radio-rate-hz", s.wall.rate_hz, "Firings per second of each beacon")
      ->capture_default_str();
  radio
      ->add_option("--faults", s.faults_preset,
                   "none, or all (every fault below at a high rate); the flags below override")
      ->capture_default_str()
      ->check(CLI::IsMember({"none", "all"}));
  for (size_t i = 0; i < kFaultFlags.size(); ++i) {
    radio->add_option(kFaultFlags[i].flag, f->fault_overrides[i], kFaultFlags[i].help);
  }
  radio
      ->add_option("--buffer-hold", s.wall.faults.buffer_hold_max_s,
                   "Longest a buffering module holds reports back, s")
      ->capture_default_str();
  radio
      ->add_option("--restart-every", f->restart_every_s,
                   "Switch the beacon off for 1 s every this many seconds; it comes back "
                   "counting from 0 (0: never)")
      ->capture_default_str();
}

void AddAirFlags(CLI::App* app, SimMainOptions* f) {
  auto* air = app->add_option_group("The beacons' shared air (both range paths)");
  air->add_option("--schedule", f->schedule,
                  "tdma (the site's firing table, docs/radio_protocol.md) or free (each beacon "
                  "at the rate on its own clock)")
      ->capture_default_str()
      ->check(CLI::IsMember({"tdma", "free"}));
  air->add_option("--beacon-clock-ppm", f->clock_ppm, "Beacon crystal error, +- ppm")
      ->capture_default_str();
  air->add_flag("--no-collisions", f->no_collisions,
                "Each receiver hears only the beacon it times (no overlap of pulses)");
  air->add_flag("--air-bench", f->air_bench,
                "Print the room's decay, slot and, for 1-12 beacons, the rate per beacon and "
                "the corrupted-range share with and without the TDMA table; then exit "
                "(--duration: seconds per run, default 60)");
  air->add_option("--bench-seeds", f->bench_seeds, "Runs per row of --air-bench")
      ->capture_default_str();
}

// Maps the parsed flags onto both range paths' options: the air flags serve
// both, the fault preset comes first and the flags given beside it win.
void ApplyFlags(const CLI::App& app, SimMainOptions* f) {
  roomfix::SimRangesNodeOptions& ranges = f->sim.ranges;
  roomfix::WallDevicesOptions& wall = f->sim.wall;
  const auto mode = f->schedule == "tdma" ? roomfix::FiringPlanOptions::Mode::kTdma
                                          : roomfix::FiringPlanOptions::Mode::kFreeRunning;
  ranges.schedule = wall.schedule = mode;
  ranges.clock_ppm = wall.clock_ppm = f->clock_ppm;
  ranges.collisions = wall.collisions = !f->no_collisions;
  const bool all = f->sim.faults_preset == "all";
  if (all) {
    const double hold_s = wall.faults.buffer_hold_max_s;
    wall.faults = roomfix::RadioFaults::All();
    wall.faults.buffer_hold_max_s = hold_s;
  }
  wall.faults.restart_every_s = f->restart_every_s;
  // A simulator runs for hours; only tests need the record of every firing.
  wall.keep_ledger = false;
  for (size_t i = 0; i < kFaultFlags.size(); ++i) {
    if (app.count(kFaultFlags[i].flag) > 0) {
      wall.faults.*kFaultFlags[i].probability = f->fault_overrides[i];
    }
  }
  // The ultrasound flags serve both range paths; --faults all sets its own
  // unless they are given.
  roomfix::UltrasoundNoise& ultrasound = wall.faults.ultrasound;
  if (!all || app.count("--range-noise") > 0) ultrasound.sigma_m = ranges.noise.sigma_m;
  if (!all || app.count("--nlos-probability") > 0) {
    ultrasound.nlos_probability = ranges.noise.nlos_probability;
  }
  if (!all || app.count("--dropout-probability") > 0) {
    ultrasound.dropout_probability = ranges.noise.dropout_probability;
  }
  wall.api_mode =
      f->api_mode == 1 ? roomfix::radio::ApiMode::kUnescaped : roomfix::radio::ApiMode::kEscaped;
  wall.frame_type = f->frame_type == "zigbee" ? roomfix::radio::kZigbeeRxFrameType
                                              : roomfix::radio::kRx64FrameType;
  wall.seed = ranges.seed;
}

constexpr char kProcessName[] = "roomfix_sim";

}  // namespace

int main(int argc, char** argv) {
  roomfix::ProcessOptions process;
  SimMainOptions flags;
  CLI::App app{"roomfix_sim: publishes simulated robots' true poses on POSE_GROUND_TRUTH"};
  roomfix::AddProcessFlags(&app, &process, /*config_required=*/true);
  AddRangeFlags(&app, &flags);
  AddRadioFlags(&app, &flags);
  AddAirFlags(&app, &flags);
  CLI11_PARSE(app, argc, argv);
  ApplyFlags(app, &flags);
  std::string error;
  if (!flags.sim.IsValid(&error)) return roomfix::PrintFailure(kProcessName, error);
  if (flags.air_bench) {
    roomfix::SharedAirOptions air;
    air.rate_hz = flags.sim.ranges.rate_hz;
    air.clock_ppm = flags.clock_ppm;
    const double run_s = flags.sim.duration_s > 0.0 ? flags.sim.duration_s : 60.0;
    return roomfix::RunAirBench(process.config_path, air, run_s, flags.bench_seeds, &error) == 0
               ? 0
               : roomfix::PrintFailure(kProcessName, error);
  }
  auto ctx = roomfix::StartProcess("roomfix_sim", process, &error);
  if (ctx == nullptr) return roomfix::PrintFailure(kProcessName, error);
  const int rc = roomfix::RunSimulator(ctx.get(), flags.sim, &error);
  if (rc != 0 && !error.empty()) roomfix::PrintFailure(kProcessName, error);
  return rc;
}
