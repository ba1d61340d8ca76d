#include "tests/testing/demo_site.h"

#include <filesystem>
#include <system_error>

namespace roomfix::testing {

std::string DemoSitePath() { return SourceDir() + "/config/sites/demo_room.yaml"; }

std::string WriteDemoSiteVariant(const TempDir& dir, const std::string& name,
                                 const std::string& from, const std::string& to,
                                 std::string* error) {
  std::string text = ReadFile(DemoSitePath());
  const size_t at = text.find(from);
  if (at == std::string::npos) {
    *error = "'" + from + "' is not in " + DemoSitePath();
    return "";
  }
  text.replace(at, from.size(), to);
  std::error_code ec;
  std::filesystem::create_directories(dir.File("sites"), ec);
  if (!ec) std::filesystem::create_directories(dir.File("calibration"), ec);
  if (!ec) {
    std::filesystem::copy_file(SourceDir() + "/config/calibration/demo_room_camera.yaml",
                               dir.File("calibration/demo_room_camera.yaml"),
                               std::filesystem::copy_options::overwrite_existing, ec);
  }
  const std::string path = dir.File("sites/" + name + ".yaml");
  if (ec || !WriteFile(path, text)) {
    *error = "cannot write " + path + (ec ? ": " + ec.message() : "");
    return "";
  }
  return path;
}

}  // namespace roomfix::testing
