#include <CLI/CLI.hpp>
#include <iostream>
#include <string>
#include <vector>

#include "core/calib/calibration_file.h"
#include "core/world/site.h"
#include "tools/commands.h"

namespace roomfix {
namespace {

// What camera_proc would refuse in a camera's calibration file: unreadable
// (missing, a folder, over the size cap), invalid, for another image size,
// or a fit whose stored residual is over tolerance. "" when it would load.
std::string CalibrationProblem(const Camera& camera, size_t index) {
  const std::string& path = camera.calibration_file;
  // camera_proc's convention: no file, or "none", runs without one.
  if (path.empty() || path == "none") return "";
  const std::string key = "cameras[" + std::to_string(index) + "].calibration: ";
  calib::Calibration c;
  std::string error;
  if (!calib::LoadCalibration(path, &c, &error)) return key + error;
  if (c.width_px() != camera.width_px || c.height_px() != camera.height_px) {
    return key + path + " is for " + std::to_string(c.width_px()) + "x" +
           std::to_string(c.height_px()) + " px, the camera delivers " +
           std::to_string(camera.width_px) + "x" + std::to_string(camera.height_px);
  }
  const std::string fit = calib::CheckFitResidual(c);
  if (!fit.empty()) return key + path + ": " + fit;
  return "";
}

}  // namespace

void AddCheckConfigCommand(CLI::App* app, int* exit_code) {
  auto* cmd = app->add_subcommand(
      "check-config",
      "Validate site files and the calibration files they name; one line each, the error naming "
      "file, line and key");
  auto files = std::make_shared<std::vector<std::string>>();
  auto ids = std::make_shared<std::string>();
  cmd->add_option("FILE", *files, "Site files (YAML)")->required();
  // For scripts that start one process per camera or radio (scripts/demo.sh,
  // the hall test): the ids alone, one per line, instead of the summary.
  cmd->add_option("--ids", *ids,
                  "Print only the ids of the valid site's cameras or radios, one per line")
      ->check(CLI::IsMember({"cameras", "radios"}));
  cmd->callback([files, ids, exit_code] {
    *exit_code = 0;
    for (const std::string& path : *files) {
      Site site;
      std::string error;
      if (!LoadSite(path, &site, &error)) {
        std::cerr << error << "\n";
        *exit_code = 1;
        continue;
      }
      std::string problem;
      for (size_t i = 0; i < site.cameras.size() && problem.empty(); ++i) {
        problem = CalibrationProblem(site.cameras[i], i);
      }
      if (!problem.empty()) {
        std::cerr << path << ": " << problem << "\n";
        *exit_code = 1;
        continue;
      }
      if (*ids == "cameras") {
        for (const Camera& c : site.cameras) std::cout << c.id << "\n";
        continue;
      }
      if (*ids == "radios") {
        for (const RadioNetwork& r : site.radios) std::cout << r.id << "\n";
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
