#include "tools/calibrate_neighbour.h"

#include <fmt/format.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <sstream>

#include "camera_io/image_file.h"
#include "core/calib/marker_projection.h"
#include "core/vision/marker_detector.h"
#include "core/world/file_io.h"

namespace roomfix {
namespace {

std::vector<std::string> SplitCells(const std::string& line) {
  std::vector<std::string> cells;
  std::stringstream s(line);
  std::string cell;
  while (std::getline(s, cell, ',')) {
    const size_t b = cell.find_first_not_of(" \t");
    const size_t e = cell.find_last_not_of(" \t\r");
    cells.push_back(b == std::string::npos ? std::string() : cell.substr(b, e - b + 1));
  }
  return cells;
}

}  // namespace

bool AddSharedImagePoints(const std::string& csv_path, const calib::Calibration& neighbour,
                          const Camera& camera, const std::string& class_name,
                          std::vector<calib::Correspondence>* points, std::vector<int>* lines,
                          std::string* error) {
  const MarkerClass* mc = nullptr;
  for (const MarkerClass& c : camera.marker_classes) {
    if (c.name == class_name) mc = &c;
  }
  if (mc == nullptr) {
    *error = "camera " + std::to_string(camera.id) + " has no marker class '" + class_name + "'";
    return false;
  }
  // The marker's disc, as in calibrate's --marker-images: both cameras map
  // its centre, as camera_proc does (calib/marker_projection.h).
  const double disc_radius_m =
      0.5 *
      (camera.marker_code.enabled() ? camera.marker_code.position_diameter_m : mc->diameter_m);
  vision::ColourClass cls;
  cls.name = mc->name;
  cls.hsv_min = mc->hsv_min;
  cls.hsv_max = mc->hsv_max;
  const vision::MarkerDetector detector({cls}, vision::DetectorOptions{});

  std::string text;
  if (!ReadConfigFile(csv_path, &text, error)) return false;
  std::istringstream in(text);
  const std::string dir = std::filesystem::path(csv_path).parent_path().string();
  const std::string name = csv_path + ":";
  // The one marker in an image, or false with the reason.
  auto find_marker = [&](const std::string& cell, int line_no, double* u, double* v) {
    std::string path = cell;
    if (!path.empty() && path[0] != '/' && !dir.empty()) path = dir + "/" + path;
    cv::Mat image;
    std::string image_error;
    if (!camera::ReadImageChecked(path, camera::kMaxToolImageSidePx, camera::kMaxToolImageSidePx,
                                  cv::IMREAD_COLOR, &image, &image_error)) {
      *error = name + std::to_string(line_no) + ": " + image_error;
      return false;
    }
    const std::vector<vision::Blob> blobs = detector.Detect(image, vision::ImageWindow{});
    if (blobs.size() != 1) {
      *error =
          path + ": expected one " + class_name + " marker, found " + std::to_string(blobs.size());
      return false;
    }
    *u = blobs[0].u_px;
    *v = blobs[0].v_px;
    return true;
  };

  std::string line;
  int line_no = 0;
  int used = 0;
  bool header = false;
  while (std::getline(in, line)) {
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty() || line[0] == '#') continue;
    const std::vector<std::string> cells = SplitCells(line);
    if (!header) {
      if (cells.size() != 3 || cells[0] != "image" || cells[1] != "neighbour_image" ||
          cells[2] != "height_m") {
        *error =
            name + std::to_string(line_no) + ": expected the header image,neighbour_image,height_m";
        return false;
      }
      header = true;
      continue;
    }
    char* end = nullptr;
    const double height_m = cells.size() == 3 ? std::strtod(cells[2].c_str(), &end) : 0.0;
    if (cells.size() != 3 || end == cells[2].c_str() || *end != '\0' || !std::isfinite(height_m)) {
      *error = name + std::to_string(line_no) + ": expected image,neighbour_image,height_m";
      return false;
    }
    double u = 0, v = 0, nu = 0, nv = 0, x = 0, y = 0;
    if (!find_marker(cells[0], line_no, &u, &v) || !find_marker(cells[1], line_no, &nu, &nv)) {
      return false;
    }
    std::string map_error;
    const bool mapped =
        neighbour.model == calib::Calibration::Model::kFull && disc_radius_m > 0.0
            ? calib::DiscCentroidToFloor(neighbour.camera, nu, nv, disc_radius_m, height_m, &x, &y)
            : neighbour.PixelToFloor(nu, nv, height_m, &x, &y, &map_error);
    if (!mapped) {
      *error = name + std::to_string(line_no) +
               fmt::format(
                   ": the neighbour's pixel ({:.2f}, {:.2f}) does not map to the floor: ", nu, nv) +
               map_error;
      return false;
    }
    std::cout << cells[0]
              << fmt::format(
                     ": marker at ({:.2f}, {:.2f}) px; the neighbour's at ({:.2f}, {:.2f}) "
                     "px maps to ({:.4f}, {:.4f}, {:.3f}) m\n",
                     u, v, nu, nv, x, y, height_m);
    points->push_back(calib::Correspondence{u, v, x, y, height_m, disc_radius_m});
    lines->push_back(line_no);
    ++used;
  }
  if (used == 0) {
    *error = csv_path + ": no image pairs listed";
    return false;
  }
  return true;
}

}  // namespace roomfix
