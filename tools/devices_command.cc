// roomfix devices: the beacons' and wall receivers' EEPROM configurations
// from the site file (docs/devices.md, "Configure"), one Intel hex image per
// device for avrdude, and `roomfix devices show` to read an image back as the
// firmware will (the same checks, the same fault).
#include <fmt/format.h>
#include <sys/stat.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include "core/radio/device_config.h"
#include "core/world/file_io.h"
#include "core/world/site.h"
#include "tools/commands.h"
#include "tools/flag_checks.h"

namespace roomfix {
namespace {

struct DevicesOptions {
  std::string site;
  std::string out;
  std::string coordinator = "0x000000000000FFFF";
  uint32_t fire_delay_us = 3000;
  unsigned burst_cycles = 16;
  double detector_delay_us = 50.0;
  double min_temperature_c = 0.0;
  double rate_hz = 10.0;
  uint32_t report_spacing_us = 2000;
  double radio_latency_us = 0.0;
  std::string show;
};

const char* RoleName(radio::DeviceRole role) {
  return role == radio::DeviceRole::kBeacon ? "beacon" : "receiver";
}

void PrintConfig(const radio::DeviceConfig& c) {
  fmt::print("  role {}, id {}, address {}\n", RoleName(c.role), c.id,
             FormatRadioAddress(c.own_address));
  if (c.role == radio::DeviceRole::kBeacon) {
    fmt::print("  slot {} of {}, slot {:.3f} ms, frame {:.3f} ms ({:.2f} Hz)\n", c.slot_index,
               c.slot_count, c.slot_us / 1e3, c.frame_us / 1e3, 1e6 / c.frame_us);
    fmt::print("  burst {} cycles at 40 kHz, {} us after the announcement's last byte\n",
               c.burst_cycles, c.fire_delay_us);
  } else {
    fmt::print("  reports to {}, {} us after the window closes\n",
               FormatRadioAddress(c.coordinator_address), c.report_delay_us);
  }
  fmt::print(
      "  window {:.3f} .. {:.3f} ms after the announcement, offset {:.3f} us "
      "(radio latency {} us), sized for {:.2f} m at {:.1f} m/s\n",
      c.window_open_us / 1e3, c.window_close_us / 1e3, c.tof_offset_ns / 1e3, c.radio_latency_us,
      c.max_range_cm / 100.0, c.sound_speed_mm_s / 1000.0);
}

int RunShow(const DevicesOptions& a) {
  // An EEPROM image's hex is under 300 bytes; 64 kB refuses a wrong file
  // (a log, /dev/zero) at once.
  constexpr size_t kImageFileCapBytes = 64 * 1024;
  std::string text;
  std::string read_error;
  if (!ReadConfigFile(a.show, &text, &read_error, kImageFileCapBytes)) {
    std::cerr << "roomfix devices show: " << read_error << "\n";
    return 1;
  }
  std::vector<uint8_t> image;
  std::string error;
  if (!radio::DecodeIntelHex(text, &image, &error)) {
    std::cerr << "roomfix devices show: " << a.show << ": " << error << "\n";
    return 2;
  }
  radio::DeviceConfig c;
  if (!radio::DecodeDeviceConfig(image.data(), image.size(), &c, &error) || !c.IsValid(&error)) {
    std::cerr << "roomfix devices show: " << a.show << ": refused (the device would say so "
              << "over the radio and neither fire nor report): " << error << "\n";
    return 2;
  }
  fmt::print("{}: layout {}, {} bytes, CRC good\n", a.show, radio::kDeviceConfigLayoutVersion,
             radio::kDeviceConfigBytes);
  PrintConfig(c);
  return 0;
}

int RunWrite(const DevicesOptions& a) {
  Site site;
  std::string error;
  if (!LoadSite(a.site, &site, &error)) {
    std::cerr << "roomfix devices: " << error << "\n";
    return 1;
  }
  radio::DeviceConfigOptions o;
  if (!ParseRadioAddress(a.coordinator, &o.coordinator_address)) {
    std::cerr << "roomfix devices: --coordinator-address: expected a 64-bit address such as "
                 "0x0013A20040000001, got \""
              << a.coordinator << "\"\n";
    return 1;
  }
  o.fire_delay_us = a.fire_delay_us;
  o.burst_cycles = static_cast<uint8_t>(std::min(a.burst_cycles, 255u));
  o.detector_delay_us = a.detector_delay_us;
  o.min_temperature_c = a.min_temperature_c;
  o.rate_hz = a.rate_hz;
  o.report_spacing_us = a.report_spacing_us;
  o.radio_latency_us = a.radio_latency_us;
  std::vector<radio::DeviceImage> images;
  if (!radio::DeviceConfigsForSite(site, o, &images, &error)) {
    std::cerr << "roomfix devices: " << a.site << ": " << error << "\n";
    return 1;
  }
  if (mkdir(a.out.c_str(), 0755) != 0 && errno != EEXIST) {
    std::cerr << "roomfix devices: cannot create " << a.out << "\n";
    return 1;
  }
  for (const radio::DeviceImage& image : images) {
    const std::string path = a.out + "/" + image.name + ".eep.hex";
    if (!WriteOutputFile(path, radio::EncodeIntelHex(radio::EncodeDeviceConfig(image.config)),
                         &error)) {
      std::cerr << "roomfix devices: " << error << "\n";
      return 1;
    }
    fmt::print("{}\n", path);
    PrintConfig(image.config);
  }
  // The bridge publishes a firing's set --deadline-ms after its first packet
  // (the announcement) whether or not every receiver has answered; with
  // these devices the last answer comes only after its listening window
  // and its report delay, plus the radio's latency. A deadline below that
  // loses the last receivers' ranges of every firing whose set is not
  // complete earlier; above it by what a buffering module may hold, none.
  double last_report_ms = 0.0;
  for (const radio::DeviceImage& image : images) {
    const radio::DeviceConfig& c = image.config;
    if (c.role != radio::DeviceRole::kReceiver) continue;
    last_report_ms = std::max(last_report_ms,
                              (c.window_close_us + c.report_delay_us + c.radio_latency_us) / 1e3);
  }
  if (last_report_ms > 0.0) {
    fmt::print(
        "zigbee_bridge: the last report reaches the coordinator about {:.1f} ms after the "
        "announcement; give --deadline-ms that plus what a buffering module may hold, "
        "e.g. {:.0f} (docs/devices.md, \"The bridge's deadline\")\n",
        last_report_ms, std::ceil((last_report_ms + 40.0) / 10.0) * 10.0);
  }
  if (o.coordinator_address == 0xFFFF) {
    fmt::print(
        "note: receivers broadcast their reports (no MAC acknowledgement or retry); "
        "give --coordinator-address for unicast\n");
  }
  return 0;
}

}  // namespace

void AddDevicesCommand(CLI::App* app, int* exit_code) {
  auto* devices = app->add_subcommand(
      "devices",
      "Write each beacon's and wall receiver's EEPROM configuration from the site file "
      "(Intel hex for avrdude: docs/devices.md)");
  auto a = std::make_shared<DevicesOptions>();
  devices->add_option("--config", a->site, "Site file")->check(CLI::ExistingFile);
  devices->add_option("--out", a->out, "Folder for the images, one DEVICE.eep.hex each");
  devices
      ->add_option("--coordinator-address", a->coordinator,
                   "64-bit address the receivers send their reports to (the coordinator's "
                   "SH/SL); 0x000000000000FFFF broadcasts")
      ->capture_default_str();
  devices
      ->add_option("--fire-delay-us", a->fire_delay_us,
                   "From the announcement's last byte to the burst (above the radio's "
                   "latency, at most 4000)")
      ->capture_default_str()
      ->check(CLI::Range(radio::kMinFireDelayUs, radio::kMaxFireDelayUs));
  devices->add_option("--burst-cycles", a->burst_cycles, "Carrier cycles per burst")
      ->capture_default_str()
      ->check(CLI::Range(1u, radio::kMaxBurstCycles));
  devices
      ->add_option("--detector-delay-us", a->detector_delay_us,
                   "Pulse arrival to the detector's threshold crossing")
      ->capture_default_str()
      ->check(FiniteAtLeast(0.0, "a delay of 0 us or more"));
  devices
      ->add_option("--min-temperature", a->min_temperature_c,
                   "Coldest air the listening window must cover, degC")
      ->capture_default_str()
      ->check(FiniteAtLeast(-20.0, "a temperature of -20 degC or more"));
  devices->add_option("--rate-hz", a->rate_hz, "Highest firing rate of a beacon")
      ->capture_default_str()
      ->check(FiniteAbove(0.0, "a rate above 0"));
  devices
      ->add_option("--report-spacing-us", a->report_spacing_us,
                   "Time between two receivers' reports")
      ->capture_default_str()
      ->check(CLI::Range(0u, 20000u));
  devices
      ->add_option("--radio-latency-us", a->radio_latency_us,
                   "Beacon's last byte to the receivers' first byte, as measured on the parts "
                   "(docs/devices.md, bring-up 6); 0: the nominal 1616 us")
      ->capture_default_str()
      ->check(FiniteAtLeast(0.0, "a latency of 0 us or more"));
  auto* show = devices->add_subcommand(
      "show", "Read an image back with the firmware's checks and print what the device will do");
  show->add_option("image", a->show, "DEVICE.eep.hex")->required();
  show->callback([a, exit_code] { *exit_code = RunShow(*a); });
  devices->callback([a, exit_code, devices, show] {
    if (show->parsed()) return;
    if (a->site.empty() || a->out.empty()) {
      std::cerr << "roomfix devices: --config and --out are required\n";
      *exit_code = 1;
      return;
    }
    *exit_code = RunWrite(*a);
  });
}

}  // namespace roomfix
