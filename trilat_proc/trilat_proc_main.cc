// trilat_proc: range sets (RANGES) to ultrasonic poses (POSE_ULTRASOUND).
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <iostream>

#include "msgio/process.h"
#include "trilat_proc/trilat_node.h"
#include "trilat_proc/trilat_options.h"

int main(int argc, char** argv) {
  roomfix::ProcessOptions process;
  roomfix::TrilatNodeOptions options;
  roomfix::TrilatOptions flags;
  CLI::App app{"trilat_proc: trilaterates each range set on RANGES into a pose on POSE_ULTRASOUND"};
  roomfix::AddProcessFlags(&app, &process, /*config_required=*/true);
  roomfix::AddTrilatFlags(&app, "", &options, &flags);
  CLI11_PARSE(app, argc, argv);
  std::string error;
  if (!roomfix::ApplyTrilatFlags(flags, &options, &error))
    return roomfix::PrintFailure("trilat_proc", error);
  const std::string& method = flags.method;
  const std::string& dimension = flags.dimension;
  if (!options.IsValid(&error)) return roomfix::PrintFailure("trilat_proc", error);
  auto ctx = roomfix::StartProcess("trilat_proc", process, &error);
  if (ctx == nullptr) return roomfix::PrintFailure("trilat_proc", error);
  if (process.check) {
    std::cout << "trilat_proc: ok: " << method << " solver, " << dimension << ", "
              << ctx->site.receivers.size() << " receivers, " << ctx->site.beacons.size()
              << " beacons, on " << process.lcm_url << "\n";
    return 0;
  }
  roomfix::TrilatNode node(ctx->site, ctx->bus.get(), options, roomfix::NowUtime());
  spdlog::info("{} solver, {}; listening on {}", method, dimension, roomfix::kRangesChannel);
  const int rc = roomfix::RunLoop(ctx->bus.get(), [&](int64_t now) { node.Tick(now); }, {});
  node.Stop(roomfix::NowUtime());
  return rc;
}
