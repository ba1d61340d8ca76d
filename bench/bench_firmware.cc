// roomfix_bench firmware: how fast the firmware-in-the-loop simulator runs
// (sim/firmware/firmware_world.h), in simulated seconds per wall-clock
// second, for the demo room's devices (1 beacon, 4 receivers) and the
// hall's. The baseline, measured in the same run: the same cores with the
// same firmware and EEPROM images advanced by simavr alone, each to the same
// simulated time in one call (no lockstep quanta, no radio, no sound), which
// is as fast as simavr runs these images. The ratio is the world's cost.
#include <fmt/format.h>

#include <CLI/CLI.hpp>
#include <chrono>
#include <cstdio>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "bench/commands.h"
#include "core/radio/device_config.h"
#include "core/world/site.h"
#include "msgio/install_paths.h"
#include "sim/firmware/firmware_world.h"
#include "sim/firmware/site_devices.h"

namespace roomfix {

namespace {

struct BenchFirmwareOptions {
  double seconds = 3.0;
  std::string firmware_dir = firmware::DefaultFirmwareDir();
  bool json = false;
};

struct Row {
  std::string name;
  size_t beacons = 0;
  size_t receivers = 0;
  double sim_s = 0.0;
  double world_wall_s = 0.0;
  double baseline_wall_s = 0.0;
  int64_t instructions = 0;
  int64_t pulses = 0;
  int64_t frames = 0;
  int64_t late = 0;
};

double Seconds(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
}

bool MeasureSite(const std::string& name, const std::string& path,
                 const BenchFirmwareOptions& options, Row* row, std::string* error) {
  Site site;
  if (!LoadSite(path, &site, error)) return false;
  firmware::FirmwareWorldOptions world_options;
  if (!firmware::ConfigureFirmwareForSite(site, radio::DeviceConfigOptions{}, options.firmware_dir,
                                          &world_options, error)) {
    return false;
  }
  auto world = firmware::FirmwareWorld::Create(site, world_options, error);
  if (world == nullptr) return false;
  row->name = name;
  for (const auto& d : world->devices()) {
    (d.role == firmware::FirmwareWorld::Device::Role::kBeacon ? row->beacons : row->receivers)++;
  }
  row->sim_s = options.seconds;
  auto t0 = std::chrono::steady_clock::now();
  world->AdvanceTo(options.seconds);
  row->world_wall_s = Seconds(t0);
  row->instructions = world->instructions();
  row->pulses = world->counters().pulses;
  row->frames = world->counters().frames_from_devices;
  row->late = world->counters().late_events;

  // The baseline: the same images on bare cores, in one run each.
  std::vector<std::unique_ptr<firmware::AvrCore>> cores;
  for (const auto& d : world->devices()) {
    firmware::AvrCoreOptions o;
    const bool beacon = d.role == firmware::FirmwareWorld::Device::Role::kBeacon;
    o.elf_path = beacon ? world_options.beacon_elf : world_options.receiver_elf;
    if (beacon) {
      o.eeprom = world_options.beacon_eeprom(*site.FindBeacon(d.id));
    } else {
      o.eeprom = world_options.receiver_eeprom(*site.FindReceiver(d.id));
    }
    cores.push_back(firmware::AvrCore::Create(o, error));
    if (cores.back() == nullptr) return false;
  }
  const auto cycles = static_cast<uint64_t>(options.seconds * world_options.frequency_hz);
  t0 = std::chrono::steady_clock::now();
  for (auto& core : cores) core->RunUntil(cycles);
  row->baseline_wall_s = Seconds(t0);
  return true;
}

int RunFirmwareBench(const BenchFirmwareOptions& options) {
  const std::vector<std::pair<std::string, std::string>> sites = {
      {"demo_room", DataFile("config/sites/demo_room.yaml")},
      {"hall", DataFile("config/sites/hall.yaml")}};
  std::vector<Row> rows;
  for (const auto& [name, path] : sites) {
    Row row;
    std::string error;
    if (!MeasureSite(name, path, options, &row, &error)) {
      fmt::print(stderr, "roomfix_bench firmware: {}: {}\n", name.c_str(), error.c_str());
      return 1;
    }
    rows.push_back(row);
  }
  if (options.json) {
    nlohmann::json out = nlohmann::json::array();
    for (const Row& r : rows) {
      out.push_back({{"site", r.name},
                     {"beacons", r.beacons},
                     {"receivers", r.receivers},
                     {"simulated_s", r.sim_s},
                     {"world_wall_s", r.world_wall_s},
                     {"baseline_wall_s", r.baseline_wall_s},
                     {"simulated_s_per_wall_s", r.sim_s / r.world_wall_s},
                     {"baseline_simulated_s_per_wall_s", r.sim_s / r.baseline_wall_s},
                     {"instructions", r.instructions},
                     {"pulses", r.pulses},
                     {"device_frames", r.frames},
                     {"late_events", r.late}});
    }
    fmt::print("{}\n", out.dump(2).c_str());
    return 0;
  }
  fmt::print("Firmware in the loop: ATmega328P at 16 MHz per device, {:.1f} simulated s\n",
             options.seconds);
  fmt::print("{:<10} {:>8} {:>10} | {:>14} {:>14} {:>8} | {:>10} {:>8} {:>7}\n", "site", "beacons",
             "receivers", "sim s / wall s", "simavr alone", "ratio", "MIPS", "pulses", "frames");
  for (const Row& r : rows) {
    const double world_rate = r.sim_s / r.world_wall_s;
    const double base_rate = r.sim_s / r.baseline_wall_s;
    fmt::print("{:<10} {:8} {:10} | {:14.3f} {:14.3f} {:8.2f} | {:10.1f} {:8} {:7}\n",
               r.name.c_str(), r.beacons, r.receivers, world_rate, base_rate,
               base_rate / world_rate, r.instructions / r.world_wall_s / 1e6,
               static_cast<long long>(r.pulses), static_cast<long long>(r.frames));
  }
  fmt::print(
      "sim s / wall s above 1: the simulator keeps up with real time (roomfix_sim --devices "
      "firmware); ratio: the world's time over simavr's alone on the same images\n");
  return 0;
}

}  // namespace

void AddBenchFirmwareCommand(CLI::App* bench, int* exit_code) {
  auto options = std::make_shared<BenchFirmwareOptions>();
  auto* cmd = bench->add_subcommand(
      "firmware",
      "roomfix_sim --devices firmware: simulated seconds per wall-clock second for the demo "
      "room's and the hall's devices, against simavr alone on the same images");
  cmd->add_option("--seconds", options->seconds, "Simulated time per site, s")
      ->capture_default_str()
      ->check(CLI::Range(0.1, 600.0));
  cmd->add_option("--firmware-dir", options->firmware_dir, "Folder of beacon.elf and receiver.elf")
      ->capture_default_str();
  cmd->add_flag("--json", options->json, "Print one JSON array instead of a table");
  cmd->callback([options, exit_code] { *exit_code = RunFirmwareBench(*options); });
}

}  // namespace roomfix
