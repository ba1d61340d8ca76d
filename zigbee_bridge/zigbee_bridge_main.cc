// zigbee_bridge: the ZigBee coordinator's serial port to range sets on RANGES.
// Flags here; the run is in bridge_app.h.
#include <CLI/CLI.hpp>
#include <iostream>

#include "msgio/process.h"
#include "zigbee_bridge/bridge_app.h"

namespace {

void AddFlags(CLI::App* app, roomfix::BridgeAppOptions* options, int* api_mode,
              double* deadline_ms) {
  roomfix::SerialLinkOptions& link = options->link;
  app->add_option("--port", link.port,
                  "Serial device of the coordinator (/dev/ttyUSB0, or a pseudo-terminal)")
      ->required();
  app->add_option("--baud", link.baud, "Baud rate")->capture_default_str();
  app->add_option("--api-mode", *api_mode, "XBee API mode: 1 (unescaped) or 2 (escaped, AP=2)")
      ->capture_default_str()
      ->check(CLI::IsMember({1, 2}));
  app->add_option("--deadline-ms", *deadline_ms,
                  "Publish a firing's set this long after its first packet even if a receiver "
                  "has not answered")
      ->capture_default_str();
  app->add_option("--temperature", options->node.assembler.default_temperature_c,
                  "Air temperature when no device reports one, degC")
      ->capture_default_str();
  app->add_option("--range-margin", options->node.assembler.range_margin_m,
                  "Tolerance on the ranges the room allows, m")
      ->capture_default_str();
  app->add_option("--reopen-max", link.reopen_max_s,
                  "Longest wait between attempts to reopen a lost device, s")
      ->capture_default_str();
  app->add_option("--duration", options->duration_s,
                  "Stop after this many seconds (0: until a signal)")
      ->capture_default_str();
  app->add_option("--radio", options->radio_id,
                  "The coordinator this bridge reads (site radios[].id): its range sets hold and "
                  "expect only that radio's receivers, and trilat_proc merges the parts "
                  "(0: the site has one coordinator for every receiver)")
      ->capture_default_str();
}

constexpr char kProcessName[] = "zigbee_bridge";

}  // namespace

int main(int argc, char** argv) {
  roomfix::ProcessOptions process;
  roomfix::BridgeAppOptions options;
  int api_mode = 2;
  double deadline_ms = options.node.assembler.deadline_s * 1e3;
  CLI::App app{
      "zigbee_bridge: reads the ZigBee coordinator (XBee API frames) on a serial port and "
      "publishes one range set per beacon firing on RANGES"};
  roomfix::AddProcessFlags(&app, &process, /*config_required=*/true);
  AddFlags(&app, &options, &api_mode, &deadline_ms);
  CLI11_PARSE(app, argc, argv);
  options.node.api_mode =
      api_mode == 1 ? roomfix::radio::ApiMode::kUnescaped : roomfix::radio::ApiMode::kEscaped;
  options.node.assembler.deadline_s = deadline_ms * 1e-3;
  std::string error;
  if (!options.IsValid(&error)) return roomfix::PrintFailure(kProcessName, error);
  auto ctx = roomfix::StartProcess("zigbee_bridge", process, &error);
  if (ctx == nullptr) return roomfix::PrintFailure(kProcessName, error);
  const int rc = roomfix::RunBridge(ctx.get(), options, &error);
  if (rc != 0 && !error.empty()) roomfix::PrintFailure(kProcessName, error);
  return rc;
}
