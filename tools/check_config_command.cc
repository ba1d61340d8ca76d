#include <CLI/CLI.hpp>
#include <iostream>
#include <string>
#include <vector>

#include "core/world/site.h"
#include "tools/commands.h"

namespace roomfix {

void AddCheckConfigCommand(CLI::App* app, int* exit_code) {
  auto* cmd = app->add_subcommand(
      "check-config", "Validate site files; one line each, the error naming file, line and key");
  auto files = std::make_shared<std::vector<std::string>>();
  cmd->add_option("FILE", *files, "Site files (YAML)")->required();
  cmd->callback([files, exit_code] {
    *exit_code = 0;
    for (const std::string& path : *files) {
      Site site;
      std::string error;
      if (!LoadSite(path, &site, &error)) {
        std::cerr << error << "\n";
        *exit_code = 1;
        continue;
      }
      std::cout << path << ": ok: site '" << site.name << "', " << site.room.size_x_m << " x "
                << site.room.size_y_m << " m, " << site.receivers.size() << " receivers, "
                << site.beacons.size() << " beacons, " << site.cameras.size() << " cameras, "
                << site.robots.size() << " robots, " << site.simulation.robots.size()
                << " simulated\n";
    }
  });
}

}  // namespace roomfix
