#ifndef ROOMFIX_SIM_SIM_APP_H_
#define ROOMFIX_SIM_SIM_APP_H_

// roomfix_sim around its nodes: which of them run (ground truth always, the
// ideal radio on --ranges, the virtual wall devices on --radio-pty), their
// pseudo-terminals, the run loop and the closing counts; and --air-bench.
// roomfix_sim_main.cc is its flags and calls to these.

#include <cstdint>
#include <string>

#include "core/world/site.h"
#include "msgio/process.h"
#include "sim/ground_truth_node.h"
#include "sim/ranges_node.h"
#include "sim/shared_air.h"
#include "sim/wall_devices.h"

namespace roomfix {

// What roomfix_sim's flags choose, once mapped onto the nodes' options.
struct SimAppOptions {
  GroundTruthNodeOptions ground_truth;
  // The ideal radio (--ranges): range sets published on RANGES directly.
  SimRangesNodeOptions ranges;
  bool publish_ranges = false;
  // The virtual wall devices (--radio-pty): XBee API frames on one
  // pseudo-terminal per coordinator, for zigbee_bridge.
  WallDevicesOptions wall;
  bool radio_pty = false;
  // What plays the wall devices behind the pseudo-terminal: "behavioural"
  // (VirtualWallDevices, the default) or "firmware" (the devices' firmware
  // in simavr, sim/firmware_devices.h; its images from firmware_dir, ""
  // for the build tree's).
  std::string devices = "behavioural";
  std::string firmware_dir;
  // Also a symlink to the pseudo-terminal; with several radios, LINK-<id>.
  std::string pty_link;
  // The --faults preset, named in --check's line only (its values are
  // already in wall.faults).
  std::string faults_preset = "none";
  // Stop after this long (0: until a signal).
  double duration_s = 0.0;
  // The simulation's t = 0 (0: now), shared by every node.
  int64_t start_utime = 0;

  // False with a reason led by what it concerns ("--rate-hz: ...",
  // "ranges: ...", "wall devices: ..."), or when --ranges and --radio-pty are
  // both asked for: both would publish range sets of the same firings.
  bool IsValid(std::string* error) const;
};

// Runs the simulator on a started process (ctx->site, ctx->bus): refuses a
// site with no simulation.robots, logs each robot's trajectory, and with
// ctx->options.check prints the one line "roomfix_sim: ok: ..." on stdout and
// returns 0. Otherwise opens the pseudo-terminals (printing each one's path,
// or its link, on stdout: what a script reads to find the device), ticks the
// nodes until a signal or the duration, logs what each published and
// returns RunLoop's status. 1 with *error set when a pseudo-terminal cannot
// be opened.
int RunSimulator(ProcessContext* ctx, const SimAppOptions& options, std::string* error);

// `--air-bench`: loads the site at config_path and prints the room's decay
// and slot, then, for 1 to 12 beacons at random places and each schedule, the
// rate each beacon gets and the share of ranges and sets corrupted, each row
// the mean of `seeds` runs of duration_s (docs/trilateration.md, "Sharing the
// air"). `air` gives the rate and the crystals; each run sets its own mode
// and seed. 1 with *error when the site does not load or seeds is outside
// [1, 1000] (in that order), else 0.
int RunAirBench(const std::string& config_path, const SharedAirOptions& air, double duration_s,
                int seeds, std::string* error);

}  // namespace roomfix

#endif  // ROOMFIX_SIM_SIM_APP_H_
