#include "tests/testing/demo_site.h"

#include <fmt/format.h>

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

std::string DemoSiteTextWithReceivers(size_t extra) {
  std::string text = ReadFile(DemoSitePath());
  const std::string last =
      "  - {id: 4, address: \"0x0013A20041000004\", position_m: [0.0, 3.0, 2.5], "
      "range_offset_m: 0.0}\n";
  const size_t at = text.find(last);
  if (at == std::string::npos) return "";
  std::string more;
  for (size_t i = 0; i < extra; ++i) {
    more += fmt::format(
        "  - {{id: {}, address: \"0x0013A20043{:06X}\", position_m: [{:.1f}, {:.1f}, 2.5], "
        "range_offset_m: 0.0}}\n",
        1001 + i, i, 0.1 * static_cast<double>(i % 40), 0.1 * static_cast<double>((i / 40) % 30));
  }
  text.insert(at + last.size(), more);
  return text;
}

}  // namespace roomfix::testing
