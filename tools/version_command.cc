#include <fmt/format.h>
#include <lcm/lcm.h>

#include <CLI/CLI.hpp>
#include <cstdio>
#include <iostream>

#include "msgio/message_json.h"
#include "tools/commands.h"

#ifndef ROOMFIX_VERSION
#define ROOMFIX_VERSION "unknown"
#endif

namespace roomfix {

void AddVersionCommand(CLI::App* app, int* exit_code) {
  auto* cmd = app->add_subcommand("version", "Print the version and the message types");
  cmd->callback([exit_code] {
    std::cout << "roomfix " << ROOMFIX_VERSION << " (LCM " << LCM_MAJOR_VERSION << "."
              << LCM_MINOR_VERSION << "." << LCM_MICRO_VERSION << ")\n";
    for (const char* type : {"roomfix.marker_pixels_t", "roomfix.range_set_t", "roomfix.pose2d_t",
                             "roomfix.process_status_t", "roomfix.image_t", "roomfix.site_t",
                             "roomfix.detector_view_t", "roomfix.detector_view_request_t"}) {
      std::cout << "  " << type << " fingerprint "
                << fmt::format("0x{:016x}", static_cast<uint64_t>(RoomfixTypeFingerprint(type)))
                << "\n";
    }
    *exit_code = 0;
  });
}

}  // namespace roomfix
