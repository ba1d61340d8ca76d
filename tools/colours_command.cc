// roomfix colours: a camera's colour classes learned from its own frames
// (core/vision/colour_learning.h; docs/camera.md, "Colours from frames").
#include <fmt/format.h>
#include <yaml-cpp/yaml.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <opencv2/imgcodecs.hpp>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "camera_io/image_file.h"
#include "core/calib/calibration_file.h"
#include "core/calib/fisheye_camera.h"
#include "core/vision/colour_learning.h"
#include "core/world/file_io.h"
#include "core/world/site.h"
#include "tools/colours_site_edit.h"
#include "tools/commands.h"

namespace roomfix {
namespace {

namespace fs = std::filesystem;
constexpr char kName[] = "roomfix colours: ";

struct ColoursOptions {
  std::string site;
  std::optional<int> camera_id;
  std::vector<std::string> frames;
  std::vector<std::string> check;
  std::string known_pixels;
  std::vector<std::string> names;
  std::string out;
  double heading_reach_m = 0.25;
  vision::ColourLearningOptions learning;
};

// The frames of one set: image files, or every image of a folder (sorted).
struct FrameSet {
  std::vector<cv::Mat> frames;
  std::vector<std::string> paths;  // each frame's file, as found
  std::vector<std::string> folders;
};

// The frame a CSV row names: `image` relative to the CSV's folder (a
// tripod folder's points.csv), or for --known-pixels also a path as given
// or a file name that only one frame has. -1 when none; -2 when ambiguous.
int FrameIndex(const FrameSet& set, const std::string& folder, const std::string& image) {
  const fs::path wanted = fs::path(folder) / image;
  int by_name = -1, names = 0;
  for (size_t i = 0; i < set.paths.size(); ++i) {
    const fs::path have(set.paths[i]);
    if (have.lexically_normal() == wanted.lexically_normal()) return static_cast<int>(i);
    if (folder.empty() && have == fs::path(image)) return static_cast<int>(i);
    if (folder.empty() && have.filename() == fs::path(image).filename()) {
      by_name = static_cast<int>(i);
      ++names;
    }
  }
  return names > 1 ? -2 : by_name;
}

bool IsImageName(const fs::path& p) {
  std::string ext = p.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return std::tolower(c); });
  return ext == ".jpg" || ext == ".jpeg" || ext == ".png" || ext == ".bmp" || ext == ".ppm";
}

bool ReadFrameSet(const std::vector<std::string>& paths, const Camera& camera, FrameSet* set,
                  std::string* error) {
  std::vector<std::string> files;
  for (const std::string& path : paths) {
    std::error_code ec;
    if (fs::is_directory(path, ec)) {
      std::vector<std::string> in_folder;
      for (const auto& entry : fs::directory_iterator(path, ec)) {
        if (entry.is_regular_file() && IsImageName(entry.path())) in_folder.push_back(entry.path());
      }
      if (ec) {
        *error = path + ": " + ec.message();
        return false;
      }
      std::sort(in_folder.begin(), in_folder.end());
      if (in_folder.empty()) {
        *error = path + ": no image file (.jpg, .png, .bmp, .ppm) in the folder";
        return false;
      }
      files.insert(files.end(), in_folder.begin(), in_folder.end());
      set->folders.push_back(path);
    } else {
      files.push_back(path);
    }
  }
  for (const std::string& file : files) {
    cv::Mat image;
    // Frames of the camera: at most its size (a larger file is another
    // camera's, or hostile), and exactly it (another size is another mode
    // or camera, whose colours and places are not this camera's).
    if (!camera::ReadImageChecked(file, std::max(camera.width_px, 1), std::max(camera.height_px, 1),
                                  cv::IMREAD_COLOR, &image, error)) {
      return false;
    }
    if (image.cols != camera.width_px || image.rows != camera.height_px) {
      *error = file + ": " + std::to_string(image.cols) + "x" + std::to_string(image.rows) +
               ", not camera " + std::to_string(camera.id) + "'s " +
               std::to_string(camera.width_px) + "x" + std::to_string(camera.height_px) +
               ": grab the frames from the camera itself (roomfix grab)";
      return false;
    }
    set->frames.push_back(image);
    set->paths.push_back(file);
  }
  return true;
}

// Markers at known places: robots.csv or points.csv of `roomfix
// render-camera --tripod-grid` (or a lab's own, same columns) in a frame
// folder, projected through the camera's calibration (the nominal lens
// without one), and --known-pixels (image,u_px,v_px,class).
struct Projector {
  calib::CameraModel lens;
  bool Pixel(double x, double y, double z, double* u, double* v) const {
    return lens.ProjectToPixel(Eigen::Vector3d(x, y, z), u, v);
  }
};

// The rows of a small CSV, read by the checked reader (a regular file of
// at most 4 MiB: a FIFO or /dev/zero is refused, not read forever).
bool ReadCsv(const std::string& path, std::string* header,
             std::vector<std::vector<std::string>>* out, std::string* error) {
  std::string text;
  if (!ReadConfigFile(path, &text, error)) return false;
  std::vector<std::vector<std::string>>& rows = *out;
  std::istringstream in(text);
  std::string line;
  if (!std::getline(in, *header)) {
    *error = path + ": empty";
    return false;
  }
  while (std::getline(in, line)) {
    if (line.empty()) continue;
    std::vector<std::string> cells;
    std::stringstream ss(line);
    std::string cell;
    while (std::getline(ss, cell, ',')) cells.push_back(cell);
    rows.push_back(cells);
  }
  return true;
}

bool ParseNumber(const std::string& text, double* value) {
  try {
    size_t used = 0;
    *value = std::stod(text, &used);
    return used == text.size() && std::isfinite(*value);
  } catch (const std::exception&) {
    return false;
  }
}

// A robot's two markers at a surveyed spot (x, y) with its marker height:
// the position marker where it stands, the heading marker the nearest
// other disc within heading_reach_m of it.
void AddRobotMarkers(const Camera& camera, const CameraRobot& robot, const Projector& p, int frame,
                     double x, double y, double height_m, double heading_reach_m,
                     std::vector<vision::KnownMarker>* known) {
  double u = 0, v = 0, u1 = 0, v1 = 0;
  if (!p.Pixel(x, y, height_m, &u, &v) || !p.Pixel(x + heading_reach_m, y, height_m, &u1, &v1)) {
    return;
  }
  const double reach_px = std::hypot(u1 - u, v1 - v);
  const double radius_m = 0.5 * PositionMarkerDiameterM(camera, robot);
  const double radius_px = std::max(3.0, reach_px * radius_m / heading_reach_m);
  known->push_back({frame, u, v, radius_px, 0.0, robot.position_marker});
  known->push_back({frame, u, v, reach_px, 1.5 * radius_px, robot.heading_marker});
}

// A robot id: an integer the camera has.
const CameraRobot* RobotOf(const Camera& camera, const std::string& text) {
  try {
    size_t used = 0;
    const long id = std::stol(text, &used);
    if (used != text.size()) return nullptr;
    for (const CameraRobot& r : camera.robots) {
      if (r.robot_id == id) return &r;
    }
  } catch (const std::exception&) {
  }
  return nullptr;
}

// robots.csv (image,x_m,y_m,height_m,robot_id) and points.csv
// (image,x_m,y_m,height_m: the camera's first robot's markers, as `roomfix
// grab --tripod` and `render-camera --tripod-grid` write it) in a frame
// folder; image names are relative to the folder.
bool ReadKnownFromFolder(const std::string& folder, const FrameSet& set, const Camera& camera,
                         const Projector& p, double heading_reach_m,
                         std::vector<vision::KnownMarker>* known, std::string* error) {
  for (const std::string file : {"robots.csv", "points.csv"}) {
    const std::string path = folder + "/" + file;
    if (!fs::exists(path)) continue;
    if (camera.robots.empty()) {
      *error = path + ": camera " + std::to_string(camera.id) +
               " has no robot whose markers it could place";
      return false;
    }
    std::string header;
    std::vector<std::vector<std::string>> rows;
    if (!ReadCsv(path, &header, &rows, error)) return false;
    const bool with_robot = file == "robots.csv";
    for (size_t i = 0; i < rows.size(); ++i) {
      const auto& r = rows[i];
      const std::string where = path + ":" + std::to_string(i + 2) + ": ";
      double x = 0, y = 0, h = 0;
      if (r.size() != (with_robot ? 5u : 4u) || !ParseNumber(r[1], &x) || !ParseNumber(r[2], &y) ||
          !ParseNumber(r[3], &h)) {
        *error = where + "expected " +
                 (with_robot ? "image,x_m,y_m,height_m,robot_id" : "image,x_m,y_m,height_m");
        return false;
      }
      const CameraRobot* robot = with_robot ? RobotOf(camera, r[4]) : &camera.robots.front();
      if (robot == nullptr) {
        *error =
            where + "robot '" + r[4] + "' is not a robot of camera " + std::to_string(camera.id);
        return false;
      }
      const int frame = FrameIndex(set, folder, r[0]);
      if (frame < 0) continue;  // an image not among the frames
      AddRobotMarkers(camera, *robot, p, frame, x, y, h, heading_reach_m, known);
    }
  }
  return true;
}

bool ReadKnownPixels(const std::string& path, const FrameSet& set,
                     std::vector<vision::KnownMarker>* known, std::string* error) {
  std::string header;
  std::vector<std::vector<std::string>> rows;
  if (!ReadCsv(path, &header, &rows, error)) return false;
  for (size_t i = 0; i < rows.size(); ++i) {
    const auto& r = rows[i];
    const std::string where = path + ":" + std::to_string(i + 2) + ": ";
    double u = 0, v = 0, radius = 10.0;
    if (r.size() < 4 || r.size() > 5 || !ParseNumber(r[1], &u) || !ParseNumber(r[2], &v) ||
        (r.size() == 5 && (!ParseNumber(r[4], &radius) || radius <= 0.0)) || r[3].empty()) {
      *error = where + "expected image,u_px,v_px,class[,radius_px]";
      return false;
    }
    const int frame = FrameIndex(set, "", r[0]);
    if (frame < 0) {
      *error = where + "image '" + r[0] + "' is " +
               (frame == -2 ? "the name of several frames: give its path" : "not among the frames");
      return false;
    }
    known->push_back({frame, u, v, 0.5 * radius, 0.0, r[3]});
  }
  return true;
}

bool LoadLens(const Camera& camera, Projector* p, std::string* error) {
  if (camera.calibration_file.empty()) {
    p->lens = calib::NominalCamera(camera.mount_position_m, camera.field_of_view_deg,
                                   camera.width_px, camera.height_px);
    return true;
  }
  calib::Calibration c;
  if (!calib::LoadCalibration(camera.calibration_file, &c, error)) return false;
  if (c.model != calib::Calibration::Model::kFull) {
    p->lens = calib::NominalCamera(camera.mount_position_m, camera.field_of_view_deg,
                                   camera.width_px, camera.height_px);
    return true;
  }
  p->lens = c.camera;
  return true;
}

// --name colour_1=red ...: applied all at once (so red=green with
// green=red swaps them); "-" drops a colour that is no marker of the site
// (its box was cut apart from the others all the same, so they keep clear
// of it). Every class left must be one of the site camera's.
bool ApplyNames(const std::vector<std::string>& names, const Camera& camera,
                std::vector<vision::LearnedClass>* classes, std::string* error) {
  std::map<std::string, std::string> rename;
  for (const std::string& n : names) {
    const size_t eq = n.find('=');
    if (eq == std::string::npos || eq == 0 || eq + 1 == n.size()) {
      *error = "--name " + n + ": expected CLUSTER=CLASS, e.g. colour_1=red";
      return false;
    }
    const std::string from = n.substr(0, eq);
    if (std::none_of(classes->begin(), classes->end(),
                     [&](const vision::LearnedClass& c) { return c.name == from; })) {
      *error = "--name " + n + ": no cluster is called '" + from + "'";
      return false;
    }
    if (!rename.emplace(from, n.substr(eq + 1)).second) {
      *error = "--name " + n + ": '" + from + "' is named twice";
      return false;
    }
  }
  for (vision::LearnedClass& c : *classes) {
    if (rename.count(c.name) > 0) c.name = rename[c.name];
  }
  classes->erase(std::remove_if(classes->begin(), classes->end(),
                                [](const vision::LearnedClass& c) { return c.name == "-"; }),
                 classes->end());
  for (size_t a = 0; a < classes->size(); ++a) {
    for (size_t b = a + 1; b < classes->size(); ++b) {
      if ((*classes)[a].name == (*classes)[b].name) {
        *error = "two clusters are named '" + (*classes)[a].name + "'";
        return false;
      }
    }
  }
  std::string site_names, unknown;
  for (const MarkerClass& m : camera.marker_classes) {
    site_names += (site_names.empty() ? "" : ", ") + m.name;
  }
  for (const vision::LearnedClass& c : *classes) {
    const bool known = std::any_of(camera.marker_classes.begin(), camera.marker_classes.end(),
                                   [&](const MarkerClass& m) { return m.name == c.name; });
    if (!known) unknown += (unknown.empty() ? "" : ", ") + c.name;
  }
  if (!unknown.empty()) {
    *error = "which of the site's classes (" + site_names + ") is each of " + unknown +
             "? Say it with --name, e.g. --name " + unknown.substr(0, unknown.find(',')) + "=" +
             camera.marker_classes.front().name + " (or =- for a colour that is no marker)";
    return false;
  }
  return true;
}

void PrintClasses(const vision::ColourLearning& learned, const std::string& title) {
  int discs = 0, clipped = 0;
  for (const vision::FoundDisc& d : learned.discs) (d.clipped ? clipped : discs) += 1;
  std::cout << title << ": " << learned.frames << " frame(s), " << discs << " marker disc(s)"
            << (clipped > 0 ? " (" + std::to_string(clipped) + " more cut by the edge, not used)"
                            : std::string())
            << ", " << learned.background_pixels << " background pixels\n";
  for (const vision::LearnedClass& c : learned.classes) {
    std::cout << fmt::format(
        "  {:<10} H {:3d}..{:3d}  S {:3d}..{:3d}  V {:3d}..{:3d}   {} disc(s), median H {:.0f} S "
        "{:.0f} V {:.0f}\n",
        c.name.c_str(), c.hsv_min[0], c.hsv_max[0], c.hsv_min[1], c.hsv_max[1], c.hsv_min[2],
        c.hsv_max[2], c.discs, c.median_hsv[0], c.median_hsv[1], c.median_hsv[2]);
    if (!c.nearest_neighbour.empty()) {
      std::cout << fmt::format(
          "      nearest {}: {:.0f} {} units from its box (drift moves it {:.0f}); {:.3g} % of its "
          "pixels in that box\n",
          c.nearest_neighbour.c_str(), c.neighbour_gap_hsv, c.neighbour_channel.c_str(),
          c.neighbour_drift_hsv, 100.0 * c.own_in_neighbour_share);
    }
    std::cout << fmt::format(
        "      background: {:.0f} HSV units from the box, {:.3g} % of it inside; {:.3g} % of its "
        "own pixels outside\n",
        c.background_gap_hsv, 100.0 * c.background_share, 100.0 * c.own_outside_share);
    std::cout << "      "
              << (c.fragile.empty() ? "holds its drift budget" : "FRAGILE: " + c.fragile) << "\n";
  }
}

bool ReadSet(const ColoursOptions& f, const std::vector<std::string>& paths, const Camera& camera,
             const Projector& p, bool with_known_pixels, FrameSet* set,
             std::vector<vision::KnownMarker>* known, std::string* error) {
  if (!ReadFrameSet(paths, camera, set, error)) return false;
  for (const std::string& folder : set->folders) {
    if (!ReadKnownFromFolder(folder, *set, camera, p, f.heading_reach_m, known, error))
      return false;
  }
  return !with_known_pixels || f.known_pixels.empty() ||
         ReadKnownPixels(f.known_pixels, *set, known, error);
}

std::string CheckLine(const vision::ClassCheck& c) {
  const std::string counts = std::to_string(c.found) + " of " + std::to_string(c.discs) + " found";
  if (c.discs == 0) return "NOT SEEN: no marker of this colour found, so not checked";
  if (c.holds()) return "holds (" + counts + ")";
  return "FAILS: " + counts +
         (c.found_as_other > 0
              ? ", " + std::to_string(c.found_as_other) + " taken for another class"
              : std::string());
}

// Each --check set (other light) with the learned classes: which hold, and
// which were not seen there (so not checked). A set's markers at no known
// place are named by the nearest learned colour, for the boxes of every
// light. False only on unreadable input.
bool CheckSets(const ColoursOptions& f, const Camera& camera, const Projector& p,
               const std::vector<vision::LearnedClass>& classes, std::vector<FrameSet>* sets,
               std::vector<std::vector<vision::KnownMarker>>* known, std::string* error) {
  bool all_hold = true;
  for (const std::string& path : f.check) {
    FrameSet set;
    std::vector<vision::KnownMarker> k;
    if (!ReadSet(f, {path}, camera, p, false, &set, &k, error)) return false;
    std::cout << "under " << path << " (" << set.frames.size() << " frame(s)):\n";
    int unmatched = 0;
    for (const vision::ClassCheck& c :
         vision::CheckColours(set.frames, k, classes, f.learning, &unmatched)) {
      std::cout << "  " << c.name << ": " << CheckLine(c) << "\n";
      all_hold = all_hold && c.holds();
    }
    if (unmatched > 0) {
      std::cout << "  " << unmatched
                << " disc(s) of a colour near no learned class: a marker this light moved out "
                   "of reach, or something else in view\n";
      all_hold = false;
    }
    if (k.empty()) k = vision::LabelByNearestClass(set.frames, classes, f.learning);
    sets->push_back(std::move(set));
    known->push_back(std::move(k));
  }
  if (!f.check.empty()) {
    std::cout << (all_hold ? "every class holds under every light given\n"
                           : "not every class holds, or was seen, under every light given\n");
  }
  return true;
}

// --check: boxes learned from the frames of every light together, each
// cluster named as in the first set (the sets' markers are labelled); a
// colour that is none of the learned classes is left out, said.
bool LearnForEveryLight(const ColoursOptions& f, const FrameSet& base,
                        const std::vector<vision::KnownMarker>& known,
                        const std::vector<FrameSet>& sets,
                        const std::vector<std::vector<vision::KnownMarker>>& set_known,
                        vision::ColourLearning* learned, std::string* error) {
  std::vector<std::vector<cv::Mat>> all = {base.frames};
  std::vector<std::vector<vision::KnownMarker>> all_known = {known};
  if (known.empty()) {
    all_known.front() = vision::LabelByNearestClass(base.frames, learned->classes, f.learning);
  }
  for (size_t i = 0; i < sets.size(); ++i) {
    all.push_back(sets[i].frames);
    all_known.push_back(set_known[i]);
  }
  std::vector<MarkerClass> named;
  for (const vision::LearnedClass& c : learned->classes) {
    named.push_back({c.name, c.hsv_min, c.hsv_max, 0.0});
  }
  vision::ColourLearning every = vision::LearnColoursForAll(all, all_known, named, f.learning, 1);
  if (!every.refusal.empty()) {
    *error = "no boxes hold under every light: " + every.refusal;
    return false;
  }
  std::vector<vision::LearnedClass> kept;
  for (const vision::LearnedClass& c : every.classes) {
    const bool ours = std::any_of(named.begin(), named.end(),
                                  [&](const MarkerClass& m) { return m.name == c.name; });
    if (ours) {
      kept.push_back(c);
    } else {
      std::cout << "note: a colour seen (median H " << std::lround(c.median_hsv[0]) << " S "
                << std::lround(c.median_hsv[1]) << " V " << std::lround(c.median_hsv[2])
                << ") is none of the learned classes: left out\n";
    }
  }
  every.classes = kept;
  PrintClasses(every, "boxes for every light");
  *learned = every;
  return true;
}

int RunColours(const ColoursOptions& f) {
  std::string error;
  if (!f.learning.IsValid(&error)) {
    std::cerr << kName << error << "\n";
    return 2;
  }
  Site site;
  if (!LoadSite(f.site, &site, &error)) {
    std::cerr << kName << error << "\n";
    return 1;
  }
  const Camera* camera = site.FindCameraOrFirst(f.camera_id.value_or(-1));
  if (camera == nullptr || camera->marker_classes.empty()) {
    std::cerr << kName << f.site << ": "
              << (camera == nullptr
                      ? "no camera" +
                            (f.camera_id ? " " + std::to_string(*f.camera_id) : std::string())
                      : "camera " + std::to_string(camera->id) + " has no marker_classes to learn")
              << "\n";
    return 1;
  }
  Projector p;
  FrameSet base;
  std::vector<vision::KnownMarker> known;
  if (!LoadLens(*camera, &p, &error) ||
      !ReadSet(f, f.frames, *camera, p, true, &base, &known, &error)) {
    std::cerr << kName << error << "\n";
    return 1;
  }
  std::cout << "camera " << camera->id << " of " << f.site << ": " << known.size()
            << " marker(s) at known places\n";
  vision::ColourLearning learned =
      vision::LearnColours(base.frames, known, camera->marker_classes, f.learning,
                           std::min<int>(2, static_cast<int>(camera->marker_classes.size())));
  if (!learned.refusal.empty()) {
    std::cerr << kName << "no classes proposed: " << learned.refusal << "\n";
    return 1;
  }
  if (!ApplyNames(f.names, *camera, &learned.classes, &error)) {
    PrintClasses(learned, "colours found");
    std::cerr << kName << error << "\n";
    return 3;
  }
  PrintClasses(learned, "learned from " + std::to_string(base.frames.size()) + " frame(s)");
  std::vector<FrameSet> sets;
  std::vector<std::vector<vision::KnownMarker>> set_known;
  if (!CheckSets(f, *camera, p, learned.classes, &sets, &set_known, &error) ||
      (!f.check.empty() &&
       !LearnForEveryLight(f, base, known, sets, set_known, &learned, &error))) {
    std::cerr << kName << error << "\n";
    return 1;
  }
  return WriteClasses(f.site, f.out, *camera, learned.classes);
}

}  // namespace

void AddColoursCommand(CLI::App* app, int* exit_code) {
  auto* cmd = app->add_subcommand(
      "colours",
      "Learn a camera's colour classes from its own frames: find the marker discs, cluster their "
      "colours, propose HSV boxes with margins for white balance, exposure and wear, and write "
      "them into a copy of the site file (docs/camera.md, \"Colours from frames\")");
  auto f = std::make_shared<ColoursOptions>();
  cmd->add_option("--site", f->site, "Site file")->required()->check(CLI::ExistingFile);
  cmd->add_option("--camera", f->camera_id, "Camera id in the site file (default: the first)");
  cmd->add_option("--frames", f->frames,
                  "Frames of the camera with the markers in view: image files or folders (a "
                  "folder's robots.csv or points.csv places the robots, as `roomfix "
                  "render-camera --tripod-grid` writes them)")
      ->required();
  cmd->add_option("--check", f->check,
                  "A folder (or file) of frames under other light: says which classes hold "
                  "there and proposes boxes that hold under every light (repeatable)");
  cmd->add_option("--known-pixels", f->known_pixels,
                  "CSV image,u_px,v_px,class[,radius_px]: markers at known pixels of the frames");
  cmd->add_option("--name", f->names,
                  "Name a cluster: CLUSTER=CLASS, e.g. colour_1=red; CLUSTER=- for a colour "
                  "that is no marker of the site");
  cmd->add_option("--out", f->out,
                  "Write a copy of the site file with the learned boxes (default: print them)");
  cmd->add_option("--heading-reach", f->heading_reach_m,
                  "A robot's heading marker lies within this distance of its position marker, m")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  auto& l = f->learning;
  cmd->add_option_function<std::string>(
         "--lighting",
         [f](const std::string& m) {
           f->learning.lighting = m == "fixed"        ? vision::LightingMode::kFixed
                                  : m == "normalised" ? vision::LightingMode::kNormalised
                                                      : vision::LightingMode::kAdaptive;
         },
         "camera_proc's --lighting: boxes are learned on the pixels it classifies (fixed, "
         "normalised or adaptive; default adaptive)")
      ->check(CLI::IsMember({"fixed", "normalised", "adaptive"}));
  cmd->add_option("--white-balance-drift", l.white_balance_drift,
                  "Red and blue gains' swing the boxes must survive (0.12: automatic white "
                  "balance; 0.03 with it fixed, docs/camera.md)")
      ->capture_default_str();
  cmd->add_option("--exposure-drift", l.exposure_drift,
                  "Brightness change the normalisation leaves, relative")
      ->capture_default_str();
  cmd->add_option("--saturation-loss", l.saturation_loss, "Share of saturation worn markers lose")
      ->capture_default_str();
  cmd->add_option("--min-radius", l.min_radius_px, "Smallest marker radius, pixels")
      ->capture_default_str();
  cmd->add_option("--max-radius", l.max_radius_px, "Largest marker radius, pixels")
      ->capture_default_str();
  cmd->callback([f, exit_code] { *exit_code = RunColours(*f); });
}

}  // namespace roomfix
