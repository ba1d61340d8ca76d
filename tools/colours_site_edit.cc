#include "tools/colours_site_edit.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <filesystem>
#include <iostream>
#include <sstream>
#include <utility>

#include "core/world/file_io.h"

namespace roomfix {
namespace {

std::string FlowList(const std::array<int, 3>& v) {
  return "[" + std::to_string(v[0]) + ", " + std::to_string(v[1]) + ", " + std::to_string(v[2]) +
         "]";
}

// The byte range of a flow list starting at `pos` ('[' to its ']').
bool FlowRange(const std::string& text, size_t pos, size_t* end) {
  if (pos >= text.size() || text[pos] != '[') return false;
  *end = text.find(']', pos);
  return *end != std::string::npos;
}

}  // namespace

bool ReplaceClassBoxes(const std::string& site_text, int camera_id,
                       const std::vector<vision::LearnedClass>& classes, std::string* out,
                       std::string* error) {
  YAML::Node root;
  try {
    root = YAML::Load(site_text);
  } catch (const YAML::Exception& e) {
    *error = std::string("not YAML: ") + e.what();
    return false;
  }
  YAML::Node entries;
  for (const YAML::Node& camera : root["cameras"]) {
    if (camera["id"] && camera["id"].as<int>(-1) == camera_id) entries = camera["marker_classes"];
  }
  if (!entries || !entries.IsSequence()) {
    *error = "camera " + std::to_string(camera_id) + " has no marker_classes list";
    return false;
  }
  // (start, end, replacement), applied from the back so positions hold.
  std::vector<std::tuple<size_t, size_t, std::string>> edits;
  for (const vision::LearnedClass& c : classes) {
    bool found = false;
    for (const YAML::Node& entry : entries) {
      if (!entry["name"] || entry["name"].as<std::string>("") != c.name) continue;
      found = true;
      for (const auto& [key, value] :
           {std::make_pair("hsv_min", c.hsv_min), std::make_pair("hsv_max", c.hsv_max)}) {
        size_t end = 0;
        const YAML::Node node = entry[key];
        if (!node || !FlowRange(site_text, node.Mark().pos, &end)) {
          *error = "class '" + c.name + "': " + key +
                   " is not written as a flow list [h, s, v] (line " +
                   std::to_string(entry.Mark().line + 1) + "); write it so and run again";
          return false;
        }
        edits.emplace_back(node.Mark().pos, end + 1, FlowList(value));
      }
    }
    if (!found) {
      *error = "camera " + std::to_string(camera_id) + " has no class '" + c.name + "'";
      return false;
    }
  }
  std::sort(edits.begin(), edits.end());
  *out = site_text;
  for (auto it = edits.rbegin(); it != edits.rend(); ++it) {
    out->replace(std::get<0>(*it), std::get<1>(*it) - std::get<0>(*it), std::get<2>(*it));
  }
  return true;
}

int WriteClasses(const std::string& site_path, const std::string& out_path, const Camera& camera,
                 const std::vector<vision::LearnedClass>& classes) {
  constexpr char kName[] = "roomfix colours: ";
  for (const MarkerClass& m : camera.marker_classes) {
    const bool learned =
        std::any_of(classes.begin(), classes.end(),
                    [&](const vision::LearnedClass& c) { return c.name == m.name; });
    if (!learned) {
      std::cout << "note: no marker of class '" << m.name
                << "' was in view: it keeps the site's box\n";
    }
  }
  if (out_path.empty()) {
    std::cout << "# cameras[id " << camera.id << "].marker_classes, learned boxes:\n";
    for (const vision::LearnedClass& c : classes) {
      std::cout << "- {name: " << c.name << ", hsv_min: " << FlowList(c.hsv_min)
                << ", hsv_max: " << FlowList(c.hsv_max) << "}\n";
    }
    return 0;
  }
  std::string text, edited, error;
  if (!ReadConfigFile(site_path, &text, &error) ||
      !ReplaceClassBoxes(text, camera.id, classes, &edited, &error)) {
    std::cerr << kName << site_path << ": " << error << "\n";
    return 1;
  }
  // Relative paths in the copy (the calibration) resolve against its own
  // folder: checked there, as camera_proc will read it.
  const std::string out_dir = std::filesystem::path(out_path).parent_path().string();
  Site check;
  if (!ParseSite(edited, out_path, out_dir.empty() ? "." : out_dir, &check, &error)) {
    std::cerr << kName << "the learned boxes do not make a valid site: " << error << "\n";
    return 1;
  }
  const Camera* copy = check.FindCamera(camera.id);
  if (copy != nullptr && !copy->calibration_file.empty() &&
      !std::filesystem::exists(copy->calibration_file)) {
    std::cerr << kName << "warning: " << out_path << " names calibration " << copy->calibration_file
              << ", which does not exist beside it: copy the calibration there or write the copy "
                 "beside the site file\n";
  }
  if (!WriteOutputFile(out_path, edited, &error)) {
    std::cerr << kName << error << "\n";
    return 1;
  }
  std::cout << "wrote " << out_path << " (" << classes.size() << " class(es) learned)\n";
  return 0;
}

}  // namespace roomfix
