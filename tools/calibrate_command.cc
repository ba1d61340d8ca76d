// roomfix calibrate: fits the camera model (and, for comparison, the
// reference's 9-region table) to marker correspondences from a CSV file
// and/or chessboards lying on the floor (detected with OpenCV), prints the
// residuals, writes the calibration YAML a site file can name, and draws the
// fit on the image.
#include <fmt/format.h>

#include <CLI/CLI.hpp>
#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <limits>
#include <map>
#include <memory>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "camera_io/image_file.h"
#include "core/calib/calibration_file.h"
#include "core/calib/camera_fit.h"
#include "core/calib/camera_start.h"
#include "core/calib/marker_projection.h"
#include "core/calib/region_model.h"
#include "core/vision/marker_detector.h"
#include "core/world/file_io.h"
#include "core/world/site.h"
#include "tools/calibrate_neighbour.h"
#include "tools/commands.h"
#include "tools/fixed_text.h"
#include "tools/flag_checks.h"

namespace roomfix {
namespace {

using calib::Calibration;
using calib::CameraFitSummary;
using calib::Correspondence;
using calib::RegionFitSummary;

struct CalibrateOptions {
  std::string points;
  // --shared-images, --neighbour: tools/calibrate_neighbour.h.
  std::string shared_images;
  std::string neighbour;
  std::vector<std::string> chessboards;
  std::string board;
  double square_m = 0.0;
  std::vector<std::string> board_origins;
  std::string board_axes = "x";
  double board_height_m = 0.0;
  std::string corners_csv;
  std::string marker_images;
  std::string robot_images;
  std::string marker_class;
  std::string out;
  std::string model = "full";
  std::string site;
  int camera_id = -1;
  std::string mount;
  double mount_sigma_m = 0.005;
  double fov_deg = 0.0;
  int distortion_terms = 2;
  std::string size;
  std::string image;
  std::string png;
  double outlier_px = 3.0;
  double pixel_sigma_px = 0.5;
  int max_iterations = 200;
  double max_rms_px = calib::kMaxFitRmsPx;
};

// The full model may leave out at most this fraction of the points as
// outliers, and never more than kMaxOutliers: a set with more is not one
// camera's view, and each outlier costs a refit (2 000 random points took
// 46 s when every point could be an outlier).
constexpr double kMaxOutlierFraction = 0.2;
constexpr int kMaxOutliers = 50;

// The most point rows a CSV may hold: each costs the fit work on every
// iteration and possibly a refit as an outlier (issue #28: 315 rows took
// 8.6 s, 3 000 were still running after 60 s). A calibration needs a few
// dozen points spread over the image; 500 is ten times the reference's 36
// with margin for several heights.
constexpr int kMaxPointRows = 500;
// Coordinates beyond these are no camera's pixels or room's metres: a
// value of 1e308 reached the fit and came out as "all points lie on a line".
constexpr double kMaxAbsPixel = 1e5;
constexpr double kMaxAbsMetres = 1e4;

// A step that fails returns false with a one-line reason
// (docs/development.md, "Style"); the command prints it and exits 1.
bool Refuse(std::string* error, std::string reason) {
  *error = std::move(reason);
  return false;
}

std::vector<std::string> SplitComma(const std::string& line) {
  std::vector<std::string> out;
  std::stringstream s(line);
  std::string field;
  while (std::getline(s, field, ',')) {
    const size_t a = field.find_first_not_of(" \t\r");
    const size_t b = field.find_last_not_of(" \t\r");
    out.push_back(a == std::string::npos ? "" : field.substr(a, b - a + 1));
  }
  return out;
}

bool ParseNumber(const std::string& text, double* value) {
  char* end = nullptr;
  *value = std::strtod(text.c_str(), &end);
  return !text.empty() && end == text.c_str() + text.size() && std::isfinite(*value);
}

// A CSV the command reads: a regular file under the configuration-file cap
// (file_io.h), so /dev/zero or a FIFO is refused at once.
bool ReadCsv(const std::string& path, std::istringstream* in, std::string* error) {
  std::string text;
  if (!ReadConfigFile(path, &text, error)) return false;
  in->str(text);
  return true;
}

// The CSV: a header naming u, v, x_m, y_m, height_m (any order), then one
// point per line. `lines` receives each point's line number for messages.
bool ReadPoints(const std::string& path, std::vector<Correspondence>* points,
                std::vector<int>* lines, std::string* error) {
  std::istringstream in;
  if (!ReadCsv(path, &in, error)) return false;
  const char* names[5] = {"u", "v", "x_m", "y_m", "height_m"};
  int column[5] = {-1, -1, -1, -1, -1};
  std::string line;
  int number = 0;
  size_t width = 0;
  while (std::getline(in, line)) {
    ++number;
    if (line.find_first_not_of(" \t\r") == std::string::npos || line[0] == '#') continue;
    const auto fields = SplitComma(line);
    if (width == 0) {
      for (size_t i = 0; i < fields.size(); ++i) {
        for (int k = 0; k < 5; ++k) {
          if (fields[i] == names[k]) column[k] = static_cast<int>(i);
        }
      }
      for (int k = 0; k < 5; ++k) {
        if (column[k] < 0) {
          return Refuse(error,
                        path + ":" + std::to_string(number) +
                            ": the header must name the columns u,v,x_m,y_m,height_m (missing " +
                            names[k] + ")");
        }
      }
      width = fields.size();
      continue;
    }
    if (fields.size() != width) {
      return Refuse(error, path + ":" + std::to_string(number) + ": expected " +
                               std::to_string(width) + " fields, got " +
                               std::to_string(fields.size()));
    }
    double v[5];
    for (int k = 0; k < 5; ++k) {
      if (!ParseNumber(fields[static_cast<size_t>(column[k])], &v[k])) {
        return Refuse(error, path + ":" + std::to_string(number) + ": " + names[k] +
                                 ": expected a number, got '" +
                                 fields[static_cast<size_t>(column[k])] + "'");
      }
    }
    for (int k = 0; k < 5; ++k) {
      const double limit = k < 2 ? kMaxAbsPixel : kMaxAbsMetres;
      if (std::abs(v[k]) > limit) {
        return Refuse(error, path + ":" + std::to_string(number) + ": " + names[k] + ": " +
                                 fields[static_cast<size_t>(column[k])] +
                                 " is out of range (at most " + Fixed(limit, 0) +
                                 (k < 2 ? " px" : " m") + " either way)");
      }
    }
    if (points->size() >= static_cast<size_t>(kMaxPointRows)) {
      return Refuse(error, path + ":" + std::to_string(number) + ": more than " +
                               std::to_string(kMaxPointRows) +
                               " points (the cap of a calibration CSV)");
    }
    points->push_back(Correspondence{v[0], v[1], v[2], v[3], v[4]});
    lines->push_back(number);
  }
  if (width == 0) return Refuse(error, path + ": empty (expected a header u,v,x_m,y_m,height_m)");
  return true;
}

bool ParseTriple(const std::string& text, const std::string& flag, std::array<double, 3>* out,
                 std::string* error) {
  const auto fields = SplitComma(text);
  if (fields.size() != 3 || !ParseNumber(fields[0], &(*out)[0]) ||
      !ParseNumber(fields[1], &(*out)[1]) || !ParseNumber(fields[2], &(*out)[2])) {
    return Refuse(error, flag + ": expected X,Y,Z in metres, got '" + text + "'");
  }
  return true;
}

// Inner corners of a chessboard, columns x rows in OpenCV's sense.
struct BoardSize {
  int cols = 0;
  int rows = 0;
  std::string Text() const { return std::to_string(cols) + "x" + std::to_string(rows); }
};

bool ParseBoard(const std::string& text, BoardSize* b, std::string* error) {
  char tail = 0;
  if (std::sscanf(text.c_str(), "%dx%d%c", &b->cols, &b->rows, &tail) != 2 || b->cols < 2 ||
      b->rows < 2) {
    return Refuse(error,
                  "--board: expected COLSxROWS inner corners (e.g. 9x6), got '" + text + "'");
  }
  return true;
}

// One detected corner: (i, j) = (column, row) index in OpenCV's order.
struct DetectedCorner {
  int i = 0;
  int j = 0;
  double u_px = 0.0;
  double v_px = 0.0;
};

// Where a board's rows (corner index i) and columns (index j) run in the
// room: "x" is +x+y, "y" is +y+x; a signed pair such as "+x-y" (rows along
// +x, columns along -y: a board seen from the ceiling with its first corner
// at the image's top-left) says both. Indices: 0 for x, 1 for y.
struct BoardAxes {
  int row_axis = 0;
  double row_sign = 1.0;
  int col_axis = 1;
  double col_sign = 1.0;
};

bool ParseBoardAxes(const std::string& text, BoardAxes* out) {
  BoardAxes a;
  if (text == "x") {
    a = BoardAxes{0, 1.0, 1, 1.0};
  } else if (text == "y") {
    a = BoardAxes{1, 1.0, 0, 1.0};
  } else if (text.size() == 4 && (text[0] == '+' || text[0] == '-') &&
             (text[2] == '+' || text[2] == '-') && (text[1] == 'x' || text[1] == 'y') &&
             (text[3] == 'x' || text[3] == 'y') && text[1] != text[3]) {
    a = BoardAxes{text[1] == 'x' ? 0 : 1, text[0] == '-' ? -1.0 : 1.0, text[3] == 'x' ? 0 : 1,
                  text[2] == '-' ? -1.0 : 1.0};
  } else {
    return false;
  }
  if (out != nullptr) *out = a;
  return true;
}

// An image from outside: a regular file, its size checked from its header
// before decoding (camera_io/image_file.h), OpenCV's exceptions caught.
bool ReadImage(const std::string& path, int flags, cv::Mat* image, std::string* error) {
  return camera::ReadImageChecked(path, camera::kMaxToolImageSidePx, camera::kMaxToolImageSidePx,
                                  flags, image, error);
}

// Finds the board's inner corners in the image, row by row as OpenCV
// orders them. The sector-based detector first: it copes with the strong
// distortion of a fisheye lens and is sub-pixel by itself; the classic
// detector with cornerSubPix is the fallback for images it misses.
bool DetectChessboard(const std::string& path, const BoardSize& board,
                      std::vector<DetectedCorner>* out, std::string* error) {
  cv::Mat gray;
  if (!ReadImage(path, cv::IMREAD_GRAYSCALE, &gray, error)) return false;
  const cv::Size pattern(board.cols, board.rows);
  std::vector<cv::Point2f> corners;
  bool found = cv::findChessboardCornersSB(
      gray, pattern, corners,
      cv::CALIB_CB_NORMALIZE_IMAGE | cv::CALIB_CB_EXHAUSTIVE | cv::CALIB_CB_ACCURACY);
  if (!found) {
    corners.clear();
    found = cv::findChessboardCorners(gray, pattern, corners,
                                      cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_NORMALIZE_IMAGE);
    if (found) {
      cv::cornerSubPix(gray, corners, cv::Size(5, 5), cv::Size(-1, -1),
                       cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 50, 0.01));
    }
  }
  if (!found || corners.size() != static_cast<size_t>(board.cols * board.rows)) {
    return Refuse(error, path + ": no " + board.Text() + " chessboard found");
  }
  // With cols + rows even the board looks the same turned by 180 degrees,
  // so which end of it OpenCV reports first is arbitrary (the two
  // detectors differ): make it the end nearer the image's top-left corner,
  // as cv::findChessboardCorners mostly does, so --board-origin names a
  // corner the user can find in the image.
  if ((board.cols + board.rows) % 2 == 0 &&
      corners.front().x + corners.front().y > corners.back().x + corners.back().y) {
    std::reverse(corners.begin(), corners.end());
  }
  out->reserve(corners.size());
  for (size_t k = 0; k < corners.size(); ++k) {
    const int index = static_cast<int>(k);
    out->push_back(
        DetectedCorner{index % board.cols, index / board.cols, corners[k].x, corners[k].y});
  }
  return true;
}

bool ParsePair(const std::string& text, const std::string& flag, std::array<double, 2>* out,
               std::string* error) {
  const auto fields = SplitComma(text);
  if (fields.size() != 2 || !ParseNumber(fields[0], &(*out)[0]) ||
      !ParseNumber(fields[1], &(*out)[1])) {
    return Refuse(error, flag + ": expected X,Y in metres, got '" + text + "'");
  }
  return true;
}

// Detects every --chessboard and appends its corners to `points` as room
// correspondences (and, with --corners-csv, writes them). `lines` gets 0
// for each: the corners have no CSV line.
bool AddChessboards(const CalibrateOptions& f, std::vector<Correspondence>* points,
                    std::vector<int>* lines, std::string* error) {
  if (f.chessboards.empty()) return true;
  BoardSize board;
  if (!ParseBoard(f.board, &board, error)) return false;
  const bool fitting = !f.out.empty();
  if (fitting) {
    // Unset (0): its value, when given, was checked with the flags.
    if (f.square_m == 0.0)
      return Refuse(error, "--square: expected the square size in metres (> 0)");
    if (f.board_origins.size() != f.chessboards.size()) {
      return Refuse(error, "--board-origin: expected one per --chessboard (" +
                               std::to_string(f.chessboards.size()) + "), got " +
                               std::to_string(f.board_origins.size()));
    }
    if (!ParseBoardAxes(f.board_axes, nullptr)) {
      return Refuse(error, "--board-axes: expected x, y or a signed pair such as +x-y, got '" +
                               f.board_axes + "'");
    }
  }
  // Written whole at the end, every step checked (WriteOutputFile).
  std::ostringstream csv;
  csv << "image,i,j,u_px,v_px\n";
  csv.precision(10);
  for (size_t b = 0; b < f.chessboards.size(); ++b) {
    std::vector<DetectedCorner> corners;
    if (!DetectChessboard(f.chessboards[b], board, &corners, error)) return false;
    std::cout << f.chessboards[b] << ": " << board.Text() << " chessboard, " << corners.size()
              << " corners\n";
    for (const DetectedCorner& c : corners) {
      if (!f.corners_csv.empty()) {
        csv << f.chessboards[b] << "," << c.i << "," << c.j << "," << c.u_px << "," << c.v_px
            << "\n";
      }
    }
    if (!fitting) continue;
    std::array<double, 2> origin{};
    if (!ParsePair(f.board_origins[b], "--board-origin", &origin, error)) return false;
    BoardAxes axes;
    ParseBoardAxes(f.board_axes, &axes);
    for (const DetectedCorner& c : corners) {
      std::array<double, 2> p = origin;
      p[axes.row_axis] += axes.row_sign * c.i * f.square_m;
      p[axes.col_axis] += axes.col_sign * c.j * f.square_m;
      points->push_back(Correspondence{c.u_px, c.v_px, p[0], p[1], f.board_height_m});
      lines->push_back(0);
    }
  }
  if (!f.corners_csv.empty()) {
    if (!WriteOutputFile(f.corners_csv, csv.str(), error)) return false;
    std::cout << "wrote " << f.corners_csv << "\n";
  }
  return true;
}

// The reference's tripod procedure: images of one marker placed at surveyed
// points, listed in a CSV `image,x_m,y_m,height_m` (image paths relative to
// the CSV). The marker is found by the same detector camera_proc runs, with
// the site camera's colour class; an image must show exactly one blob of it.
// A marker class's detector as calibration uses it: the class's HSV box,
// small blobs allowed, the lighting normalised.
vision::MarkerDetector CalibrationDetector(const MarkerClass& mc) {
  vision::ColourClass cls;
  cls.name = mc.name;
  cls.hsv_min = mc.hsv_min;
  cls.hsv_max = mc.hsv_max;
  cls.min_area_px = 20.0;
  vision::DetectorOptions options;
  options.lighting = vision::LightingMode::kNormalised;
  return vision::MarkerDetector({cls}, options);
}

// The one marker of `class_name` in the image at `path`; false with a
// reason naming the CSV line when the image cannot be read or does not
// show exactly one.
bool FindOneMarker(const vision::MarkerDetector& detector, const std::string& class_name,
                   const std::string& path, const std::string& where, vision::Blob* blob,
                   std::string* error) {
  cv::Mat image;
  std::string image_error;
  if (!camera::ReadImageChecked(path, camera::kMaxToolImageSidePx, camera::kMaxToolImageSidePx,
                                cv::IMREAD_COLOR, &image, &image_error)) {
    return Refuse(error, where + ": " + image_error);
  }
  const std::vector<vision::Blob> blobs = detector.Detect(image, vision::ImageWindow{});
  if (blobs.size() != 1) {
    std::string at;
    for (const vision::Blob& b : blobs)
      at += " (" + Fixed(b.u_px, 1) + ", " + Fixed(b.v_px, 1) + ")";
    return Refuse(error, path + ": expected one " + class_name + " marker, found " +
                             std::to_string(blobs.size()) + (at.empty() ? "" : " at" + at));
  }
  *blob = blobs[0];
  return true;
}

const MarkerClass* FindClass(const roomfix::Camera& camera, const std::string& name) {
  for (const MarkerClass& c : camera.marker_classes) {
    if (c.name == name) return &c;
  }
  return nullptr;
}

bool AddMarkerImages(const CalibrateOptions& f, std::vector<Correspondence>* points,
                     std::vector<int>* lines, std::string* error) {
  if (f.marker_images.empty()) return true;
  if (f.site.empty())
    return Refuse(error, "--marker-images needs --site (the marker's colour class)");
  Site site;
  if (!LoadSite(f.site, &site, error)) return false;
  const roomfix::Camera* camera = site.FindCameraOrFirst(f.camera_id);
  if (camera == nullptr) return Refuse(error, f.site + ": no such camera");
  std::string class_name = f.marker_class;
  if (class_name.empty() && !camera->robots.empty()) {
    class_name = camera->robots.front().position_marker;
  }
  const MarkerClass* mc = FindClass(*camera, class_name);
  if (mc == nullptr)
    return Refuse(error, "--marker-class: the camera has no class '" + class_name + "'");
  // The tripod carries a position marker: the code's position size when the
  // site has a marker code, else the class's own diameter. The fit maps the
  // disc's centre, as camera_proc does (calib::FitCameraToMarkers).
  const double disc_radius_m =
      0.5 *
      (camera->marker_code.enabled() ? camera->marker_code.position_diameter_m : mc->diameter_m);
  const vision::MarkerDetector detector = CalibrationDetector(*mc);

  std::istringstream in;
  if (!ReadCsv(f.marker_images, &in, error)) return false;
  const std::string dir = std::filesystem::path(f.marker_images).parent_path().string();
  std::string line;
  int line_no = 0;
  int used = 0;
  while (std::getline(in, line)) {
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty() || line[0] == '#') continue;
    const std::vector<std::string> cells = SplitComma(line);
    if (line_no == 1) {
      if (cells.size() != 4 || cells[0] != "image" || cells[1] != "x_m" || cells[2] != "y_m" ||
          cells[3] != "height_m") {
        return Refuse(error, f.marker_images + ":1: expected the header image,x_m,y_m,height_m");
      }
      continue;
    }
    double x = 0, y = 0, h = 0;
    if (cells.size() != 4 || !ParseNumber(cells[1], &x) || !ParseNumber(cells[2], &y) ||
        !ParseNumber(cells[3], &h)) {
      return Refuse(error, f.marker_images + ":" + std::to_string(line_no) +
                               ": expected image,x_m,y_m,height_m");
    }
    std::string path = cells[0];
    if (!path.empty() && path[0] != '/' && !dir.empty()) path = dir + "/" + path;
    vision::Blob blob;
    if (!FindOneMarker(detector, class_name, path, f.marker_images + ":" + std::to_string(line_no),
                       &blob, error)) {
      return false;
    }
    std::cout << path << ": " << class_name << " marker at (" << Fixed(blob.u_px, 2) << ", "
              << Fixed(blob.v_px, 2) << ") px for (" << Fixed(x, 3) << ", " << Fixed(y, 3) << ", "
              << Fixed(h, 3) << ") m\n";
    points->push_back(Correspondence{blob.u_px, blob.v_px, x, y, h, disc_radius_m});
    lines->push_back(line_no);
    ++used;
  }
  if (used == 0) return Refuse(error, f.marker_images + ": no images listed");
  return true;
}

// Marker images shared with an already calibrated neighbour camera
// (tools/calibrate_neighbour.h); the marker class as for --marker-images.
bool AddNeighbourPoints(const CalibrateOptions& f, std::vector<Correspondence>* points,
                        std::vector<int>* lines, std::string* error) {
  if (f.shared_images.empty() != f.neighbour.empty()) {
    return Refuse(error, "--shared-images and --neighbour go together");
  }
  if (f.shared_images.empty()) return true;
  if (f.site.empty())
    return Refuse(error, "--shared-images needs --site (the marker's colour class)");
  Site site;
  Calibration neighbour;
  if (!LoadSite(f.site, &site, error)) return false;
  const roomfix::Camera* camera = f.camera_id < 0
                                      ? (site.cameras.empty() ? nullptr : &site.cameras.front())
                                      : site.FindCamera(f.camera_id);
  if (camera == nullptr) return Refuse(error, f.site + ": no such camera");
  std::string class_name = f.marker_class;
  if (class_name.empty() && !camera->robots.empty()) {
    class_name = camera->robots.front().position_marker;
  }
  return calib::LoadCalibration(f.neighbour, &neighbour, error) &&
         AddSharedImagePoints(f.shared_images, neighbour, *camera, class_name, points, lines,
                              error);
}

// Each robot's own pixel sigma, held out from the fit: images of the robot
// itself at surveyed points (CSV image,x_m,y_m,height_m,robot_id; `roomfix
// render-camera --tripod-robots` writes them), its position marker found in
// each, and the centroid compared with where the fitted lens images that
// disc (the centre's projection plus the disc offset, as camera_proc maps
// it). With n images and residuals d_i the sigma per axis is
// sqrt(sum |d_i|^2 / 2n): nothing was fitted to these images, so no degrees
// of freedom are lost, and the lens's own error at those places is in it, as
// it will be in operation. A robot needs kMinRobotImages images.
constexpr int kMinRobotImages = 5;

bool RobotPixelSigmas(const CalibrateOptions& f, const calib::CameraModel& lens,
                      std::map<int, double>* sigmas_out, std::string* error) {
  std::map<int, double>& sigmas = *sigmas_out;
  if (f.robot_images.empty()) return true;
  if (f.site.empty()) return Refuse(error, "--robot-images needs --site (the robots' markers)");
  Site site;
  if (!LoadSite(f.site, &site, error)) return false;
  const roomfix::Camera* camera = site.FindCameraOrFirst(f.camera_id);
  if (camera == nullptr) return Refuse(error, f.site + ": no such camera");
  std::istringstream in;
  if (!ReadCsv(f.robot_images, &in, error)) return false;
  const std::string dir = std::filesystem::path(f.robot_images).parent_path().string();
  std::map<int, std::pair<int, double>> sums;  // robot: images, sum |d|^2 px^2
  std::map<int, double> floor_sums;            // robot: sum of squared floor errors, m^2
  std::map<std::string, vision::MarkerDetector> detectors;  // by class
  std::string line;
  int line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty() || line[0] == '#') continue;
    const std::vector<std::string> cells = SplitComma(line);
    const std::string where = f.robot_images + ":" + std::to_string(line_no);
    if (line_no == 1) {
      if (cells != std::vector<std::string>{"image", "x_m", "y_m", "height_m", "robot_id"}) {
        return Refuse(error, where + ": expected the header image,x_m,y_m,height_m,robot_id");
      }
      continue;
    }
    double x = 0, y = 0, h = 0, id = 0;
    if (cells.size() != 5 || !ParseNumber(cells[1], &x) || !ParseNumber(cells[2], &y) ||
        !ParseNumber(cells[3], &h) || !ParseNumber(cells[4], &id) || id != std::floor(id)) {
      return Refuse(error, where + ": expected image,x_m,y_m,height_m,robot_id");
    }
    const auto robot = std::find_if(camera->robots.begin(), camera->robots.end(),
                                    [&](const CameraRobot& r) { return r.robot_id == id; });
    if (robot == camera->robots.end()) {
      return Refuse(error,
                    where + ": camera " + std::to_string(camera->id) + " has no robot " + cells[4]);
    }
    const MarkerClass* mc = FindClass(*camera, robot->position_marker);
    if (mc == nullptr) return Refuse(error, where + ": no class '" + robot->position_marker + "'");
    std::string path = cells[0];
    if (!path.empty() && path[0] != '/' && !dir.empty()) path = dir + "/" + path;
    auto detector = detectors.find(mc->name);
    if (detector == detectors.end()) {
      detector = detectors.emplace(mc->name, CalibrationDetector(*mc)).first;
    }
    vision::Blob blob;
    if (!FindOneMarker(detector->second, robot->position_marker, path, where, &blob, error)) {
      return false;
    }
    const double radius_m = PositionMarkerDiameterM(*camera, *robot) / 2.0;
    const Eigen::Vector3d centre(x, y, h);
    Eigen::Vector2d image_px, offset_px = Eigen::Vector2d::Zero();
    double fx = 0, fy = 0;
    if (!lens.ProjectToPixel(centre, &image_px.x(), &image_px.y()) ||
        (radius_m > 0.0 && !calib::DiscCentroidOffset(lens, centre, radius_m, &offset_px)) ||
        !calib::DiscCentroidToFloor(lens, blob.u_px, blob.v_px, radius_m, h, &fx, &fy)) {
      return Refuse(error, where + ": the point is outside the fitted lens's view");
    }
    const Eigen::Vector2d d = Eigen::Vector2d(blob.u_px, blob.v_px) - image_px - offset_px;
    auto& [n, sum_px2] = sums[robot->robot_id];
    ++n;
    sum_px2 += d.squaredNorm();
    floor_sums[robot->robot_id] += std::pow(fx - x, 2) + std::pow(fy - y, 2);
  }
  for (const auto& [id, entry] : sums) {
    const auto [n, sum_px2] = entry;
    if (n < kMinRobotImages) {
      return Refuse(error, f.robot_images + ": robot " + std::to_string(id) + " has " +
                               std::to_string(n) + " images; a held-out sigma needs at least " +
                               std::to_string(kMinRobotImages));
    }
    sigmas[id] = std::sqrt(sum_px2 / (2.0 * n));
    std::cout << "robot " << id << ": " << n << " held-out images, pixel sigma "
              << Fixed(sigmas[id], 4) << " px per axis, floor RMS "
              << Fixed(1e3 * std::sqrt(floor_sums[id] / n), 2) << " mm\n";
  }
  if (sigmas.empty()) return Refuse(error, f.robot_images + ": no images listed");
  return true;
}

// The reprojection of room point `p` at its height under the chosen model.
bool Reproject(const Calibration& c, const Correspondence& p, double* u, double* v) {
  std::string ignored;
  return c.FloorToPixel(p.x_m, p.y_m, p.height_m, u, v, &ignored);
}

struct Stats {
  double rms_mm = 0, rms_px = 0, worst_mm = 0, worst_px = 0;
  int worst = -1;
};

bool Render(const CalibrateOptions& f, const Calibration& c,
            const std::vector<Correspondence>& points, const std::vector<bool>& outlier,
            const std::array<double, 4>& room_xy_m, double grid_m, std::string* error) {
  cv::Mat image;
  if (!f.image.empty()) {
    if (!ReadImage(f.image, cv::IMREAD_COLOR, &image, error)) return false;
    if (image.cols != c.width_px() || image.rows != c.height_px()) {
      return Refuse(error, f.image + ": the image is " + std::to_string(image.cols) + " x " +
                               std::to_string(image.rows) + " px, the camera " +
                               std::to_string(c.width_px()) + " x " +
                               std::to_string(c.height_px()));
    }
  } else {
    image = cv::Mat(c.height_px(), c.width_px(), CV_8UC3, cv::Scalar(48, 48, 48));
  }
  double height_m = 0;
  for (const auto& p : points) height_m += p.height_m / static_cast<double>(points.size());
  if (c.model == Calibration::Model::kRegions) height_m = c.regions.calibration_height_m;
  // Grid lines at the calibration height, sampled every 2 cm so that the
  // lens's curvature shows.
  const cv::Scalar grid_colour(255, 200, 0);
  auto draw_line = [&](double x0, double y0, double x1, double y1) {
    const double length = std::hypot(x1 - x0, y1 - y0);
    const int n = std::max(1, static_cast<int>(length / 0.02));
    std::vector<cv::Point> run;
    for (int i = 0; i <= n; ++i) {
      const double t = static_cast<double>(i) / n;
      double u, v;
      Correspondence q{0, 0, x0 + t * (x1 - x0), y0 + t * (y1 - y0), height_m};
      if (Reproject(c, q, &u, &v)) {
        run.emplace_back(static_cast<int>(std::lround(u)), static_cast<int>(std::lround(v)));
      } else if (!run.empty()) {
        cv::polylines(image, run, false, grid_colour, 1, cv::LINE_AA);
        run.clear();
      }
    }
    if (run.size() > 1) cv::polylines(image, run, false, grid_colour, 1, cv::LINE_AA);
  };
  const double eps = 1e-9;
  for (double x = room_xy_m[0]; x <= room_xy_m[2] + eps; x += grid_m) {
    draw_line(x, room_xy_m[1], x, room_xy_m[3]);
  }
  for (double y = room_xy_m[1]; y <= room_xy_m[3] + eps; y += grid_m) {
    draw_line(room_xy_m[0], y, room_xy_m[2], y);
  }
  if (c.model == Calibration::Model::kRegions) {
    const cv::Scalar boundary(128, 128, 128);
    for (double u : c.regions.u_boundaries_px) {
      cv::line(image, cv::Point(static_cast<int>(u), 0), cv::Point(static_cast<int>(u), image.rows),
               boundary, 1);
    }
    for (double v : c.regions.v_boundaries_px) {
      cv::line(image, cv::Point(0, static_cast<int>(v)), cv::Point(image.cols, static_cast<int>(v)),
               boundary, 1);
    }
  }
  // Residual arrows from the measured pixel towards the reprojection,
  // magnified: sub-pixel residuals would not show otherwise.
  constexpr double kArrowScale = 20.0;
  for (size_t i = 0; i < points.size(); ++i) {
    const Correspondence& p = points[i];
    const cv::Point measured(static_cast<int>(std::lround(p.u_px)),
                             static_cast<int>(std::lround(p.v_px)));
    cv::circle(image, measured, 4, cv::Scalar(0, 255, 0), 1, cv::LINE_AA);
    double u, v;
    if (Reproject(c, p, &u, &v)) {
      const cv::Point tip(static_cast<int>(std::lround(p.u_px + kArrowScale * (u - p.u_px))),
                          static_cast<int>(std::lround(p.v_px + kArrowScale * (v - p.v_px))));
      cv::arrowedLine(image, measured, tip, cv::Scalar(0, 0, 255), 2, cv::LINE_AA, 0, 0.2);
    }
    if (outlier[i]) cv::circle(image, measured, 12, cv::Scalar(255, 0, 255), 2, cv::LINE_AA);
    cv::putText(image, std::to_string(i), measured + cv::Point(6, -6), cv::FONT_HERSHEY_SIMPLEX,
                0.4, cv::Scalar(255, 255, 255), 1, cv::LINE_AA);
  }
  cv::putText(image,
              std::string(c.model == Calibration::Model::kFull ? "full model" : "9-region model") +
                  ": grid every " + std::to_string(grid_m).substr(0, 4) +
                  " m, residual arrows x20, outliers circled",
              cv::Point(10, 24), cv::FONT_HERSHEY_SIMPLEX, 0.6, cv::Scalar(255, 255, 255), 1,
              cv::LINE_AA);
  return camera::WriteImageChecked(f.png, image, error);
}

// For a refused full model: the point worst off the last fit tried, by its
// CSV line (0 for a chessboard corner), since one wrong row can pull every
// point off the fit; "" when the fit gave no residuals.
std::string WorstPoint(const CameraFitSummary& fit, const std::vector<int>& lines) {
  size_t worst = fit.residual_px.size();
  for (size_t i = 0; i < fit.residual_px.size() && i < lines.size(); ++i) {
    if (std::isfinite(fit.residual_px[i]) &&
        (worst == fit.residual_px.size() || fit.residual_px[i] > fit.residual_px[worst])) {
      worst = i;
    }
  }
  if (worst == fit.residual_px.size()) return "";
  return "; the worst is point " + std::to_string(worst) + " (line " +
         std::to_string(lines[worst]) + "), " + Fixed(fit.residual_px[worst], 1) +
         " px off: check that row first";
}

// Which inputs were given, and whether they make a run.
bool CheckSources(const CalibrateOptions& f, std::string* error) {
  if (f.points.empty() && f.chessboards.empty() && f.marker_images.empty() &&
      f.shared_images.empty()) {
    return Refuse(error,
                  "no points: give --points CSV, --chessboard IMAGE and/or --marker-images CSV");
  }
  if (!f.chessboards.empty() && f.board.empty()) {
    return Refuse(error, "--chessboard needs --board COLSxROWS (inner corners)");
  }
  // --corners-csv alone only detects: no fit, so no --out.
  if (f.out.empty() && (f.corners_csv.empty() || f.chessboards.empty() || !f.points.empty())) {
    return Refuse(error,
                  "--out is required (only --chessboard with --corners-csv runs without it)");
  }
  return true;
}

// Every point of every source, each with its CSV line (`lines`, 0 where
// there is none).
bool ReadAllPoints(const CalibrateOptions& f, std::vector<Correspondence>* points,
                   std::vector<int>* lines, std::string* error) {
  if (!f.points.empty()) {
    if (!ReadPoints(f.points, points, lines, error)) return false;
    if (points->empty()) return Refuse(error, f.points + ": no points");
  }
  return AddChessboards(f, points, lines, error) && AddMarkerImages(f, points, lines, error) &&
         AddNeighbourPoints(f, points, lines, error);
}

// Camera size, field of view and mount, and the room drawn: flags over the
// site's camera.
struct CameraGeometry {
  int width_px = 0;
  int height_px = 0;
  double fov_deg = 120.0;
  std::optional<std::array<double, 3>> mount;
  std::array<double, 4> room_xy_m{};
  double grid_m = 0.5;
};

bool FindCameraGeometry(const CalibrateOptions& f, const std::vector<Correspondence>& points,
                        CameraGeometry* g, std::string* error) {
  bool have_room = false;
  if (!f.site.empty()) {
    Site site;
    if (!LoadSite(f.site, &site, error)) return false;
    const roomfix::Camera* camera = site.FindCameraOrFirst(f.camera_id);
    if (camera == nullptr) {
      return Refuse(error,
                    f.site + ": no camera " +
                        (f.camera_id < 0 ? std::string("at all") : std::to_string(f.camera_id)));
    }
    g->width_px = camera->width_px;
    g->height_px = camera->height_px;
    g->fov_deg = camera->field_of_view_deg;
    g->mount = camera->mount_position_m;
    g->room_xy_m = {site.room.min_x_m, site.room.min_y_m, site.room.min_x_m + site.room.size_x_m,
                    site.room.min_y_m + site.room.size_y_m};
    g->grid_m = site.room.grid_m;
    have_room = true;
  }
  if (!f.size.empty()) {
    if (std::sscanf(f.size.c_str(), "%dx%d", &g->width_px, &g->height_px) != 2 ||
        g->width_px <= 0 || g->height_px <= 0) {
      return Refuse(error, "--size: expected WIDTHxHEIGHT in pixels, got '" + f.size + "'");
    }
  }
  if (g->width_px <= 0 && !f.image.empty()) {
    cv::Mat image;
    if (!ReadImage(f.image, cv::IMREAD_UNCHANGED, &image, error)) return false;
    g->width_px = image.cols;
    g->height_px = image.rows;
  }
  if (g->width_px <= 0) {
    return Refuse(error, "the image size is unknown: give --size WxH, --image FILE or --site FILE");
  }
  if (f.fov_deg > 0) g->fov_deg = f.fov_deg;
  if (!f.mount.empty()) {
    std::array<double, 3> mount{};
    if (!ParseTriple(f.mount, "--mount", &mount, error)) return false;
    g->mount = mount;
  }
  if (!have_room) {
    // The points' extent rounded out to the grid.
    const double grid_m = g->grid_m;
    g->room_xy_m = {INFINITY, INFINITY, -INFINITY, -INFINITY};
    for (const auto& p : points) {
      g->room_xy_m[0] = std::min(g->room_xy_m[0], std::floor(p.x_m / grid_m) * grid_m);
      g->room_xy_m[1] = std::min(g->room_xy_m[1], std::floor(p.y_m / grid_m) * grid_m);
      g->room_xy_m[2] = std::max(g->room_xy_m[2], std::ceil(p.x_m / grid_m) * grid_m);
      g->room_xy_m[3] = std::max(g->room_xy_m[3], std::ceil(p.y_m / grid_m) * grid_m);
    }
  }
  return true;
}

// Both models fitted to the points; `full_why` says why the full one was
// not (empty when it was tried).
struct ModelFits {
  CameraFitSummary full;
  std::string full_why;
  RegionFitSummary regions;
};

ModelFits FitModels(const CalibrateOptions& f, const std::vector<Correspondence>& points,
                    const CameraGeometry& g) {
  // The full model, started from the points alone (camera_start.h: the
  // nominal lens's undistorted pixels through a planar pose solver); a
  // measured mount, when given, enters as a prior, because points at one
  // height do not fix the camera's height (camera_fit.h). Points that cannot
  // give a start (too small a patch of the image) still fit from the
  // nominal camera at the mount, as before; mirrored axes never do.
  ModelFits fits;
  const calib::CameraModel nominal = calib::NominalCamera(
      g.mount.value_or(std::array<double, 3>{0.0, 0.0, 1.0}), g.fov_deg, g.width_px, g.height_px);
  const calib::CameraStart start = calib::FindCameraStart(points, nominal);
  if (start.usable) {
    std::cout << start.message << "\n";
  } else if (g.mount && !start.mirrored) {
    std::cout << "start from the mount (not from the points: " << start.message << ")\n";
  } else {
    fits.full_why = start.message;
  }
  if (fits.full_why.empty()) {
    calib::CameraFitOptions options;
    options.equal_focal_lengths = true;
    options.distortion_terms = f.distortion_terms;
    if (g.mount) {
      options.position_prior_sigma_m = f.mount_sigma_m;
      options.prior_position_m = *g.mount;
    }
    options.pixel_sigma_px = f.pixel_sigma_px;
    options.outlier_px = f.outlier_px;
    options.max_iterations = f.max_iterations;
    options.max_outliers = std::min(
        kMaxOutliers, static_cast<int>(kMaxOutlierFraction * static_cast<double>(points.size())));
    fits.full = calib::FitCameraToMarkers(points, start.usable ? start.model : nominal, options);
    if (!fits.full.usable) fits.full_why = fits.full.message;
  }
  fits.regions = calib::FitRegions(points, calib::ThirdsRegionModel(g.width_px, g.height_px));
  return fits;
}

// The residuals of both models over the points (outliers of the full
// model left out of its figures).
struct Residuals {
  Stats full, regions;
  int n_full = 0;
};

// The residual table: floor distance of the mapped pixel from the marker
// (mm) and pixel distance of the reprojected marker from its pixel (px).
Residuals PrintResidualTable(const std::vector<Correspondence>& points,
                             const std::vector<int>& lines, const ModelFits& fits,
                             const Calibration& full_cal, const std::vector<bool>& outlier) {
  Residuals r;
  Stats& fs = r.full;
  Stats& rs = r.regions;
  std::cout << "point line        u_px        v_px     x_m     y_m  height_m | full_mm  full_px "
               "| regions_mm regions_px\n";
  for (size_t i = 0; i < points.size(); ++i) {
    const Correspondence& p = points[i];
    std::string ignored;
    double fmm = NAN, fpx = NAN, rmm = NAN, rpx = NAN, x, y;
    if (fits.full.usable) {
      // A marker is mapped as camera_proc maps it: its disc's centre.
      const bool mapped = p.disc_radius_m > 0.0
                              ? calib::DiscCentroidToFloor(fits.full.model, p.u_px, p.v_px,
                                                           p.disc_radius_m, p.height_m, &x, &y)
                              : full_cal.PixelToFloor(p.u_px, p.v_px, p.height_m, &x, &y, &ignored);
      if (mapped) {
        fmm = 1e3 * std::hypot(x - p.x_m, y - p.y_m);
      }
      fpx = fits.full.residual_px[i];
      if (!outlier[i]) {
        ++r.n_full;
        fs.rms_mm += fmm * fmm;
        fs.rms_px += fpx * fpx;
        if (fs.worst < 0 || fpx > fs.worst_px) {
          fs.worst = static_cast<int>(i);
          fs.worst_px = fpx;
          fs.worst_mm = fmm;
        }
      }
    }
    if (fits.regions.usable) {
      rmm = 1e3 * fits.regions.residual_m[i];
      rpx = fits.regions.residual_px[i];
      rs.rms_mm += rmm * rmm;
      rs.rms_px += rpx * rpx;
      if (rs.worst < 0 || rmm > rs.worst_mm) {
        rs.worst = static_cast<int>(i);
        rs.worst_px = rpx;
        rs.worst_mm = rmm;
      }
    }
    std::cout << fmt::format(
        "{:5} {:4} {:11.3f} {:11.3f} {:7.3f} {:7.3f} {:9.3f} | {:>7} {:>8} | {:>10} {:>10}{}\n", i,
        lines[i], p.u_px, p.v_px, p.x_m, p.y_m, p.height_m, Fixed(fmm, 2), Fixed(fpx, 3),
        Fixed(rmm, 2), Fixed(rpx, 3), outlier[i] ? "  OUTLIER" : "");
  }
  return r;
}

// Each model's RMS and worst point, and the outliers left out.
void PrintFitSummaries(const CalibrateOptions& f, const std::vector<Correspondence>& points,
                       const std::vector<int>& lines, const ModelFits& fits, const Residuals& r,
                       const std::vector<bool>& outlier) {
  const Stats& fs = r.full;
  const Stats& rs = r.regions;
  if (fits.full.usable) {
    std::cout << "full model: RMS " << Fixed(std::sqrt(fs.rms_mm / r.n_full), 2) << " mm, "
              << Fixed(std::sqrt(fs.rms_px / r.n_full), 3) << " px over " << r.n_full
              << " points; worst point " << fs.worst << " (line "
              << lines[static_cast<size_t>(fs.worst)] << "): " << Fixed(fs.worst_mm, 2) << " mm, "
              << Fixed(fs.worst_px, 3) << " px; " << fits.full.message << "\n";
  } else {
    std::cout << "full model: not fitted: " << fits.full_why << "\n";
  }
  if (fits.regions.usable) {
    const double n = static_cast<double>(points.size());
    std::cout << "9-region model: RMS " << Fixed(std::sqrt(rs.rms_mm / n), 2) << " mm, "
              << Fixed(std::sqrt(rs.rms_px / n), 3) << " px over " << points.size()
              << " points; worst point " << rs.worst << " (line "
              << lines[static_cast<size_t>(rs.worst)] << "): " << Fixed(rs.worst_mm, 2) << " mm, "
              << Fixed(rs.worst_px, 3) << " px; valid only at "
              << fits.regions.model.calibration_height_m << " m\n";
  } else {
    std::cout << "9-region model: not fitted: " << fits.regions.message << "\n";
  }
  for (size_t i = 0; i < points.size(); ++i) {
    if (outlier[i]) {
      std::cout << "outlier: point " << i << " (line " << lines[i] << ") is "
                << Fixed(fits.full.residual_px[i], 2) << " px off the fit (over " << f.outlier_px
                << " px), left out of it: check the marker's position or its pixel\n";
    }
  }
}

// The calibration file's header: where the points came from and how well
// the chosen model fits them.
std::string CalibrationHeader(const CalibrateOptions& f, size_t n_points, const ModelFits& fits,
                              const Residuals& r) {
  std::ostringstream header;
  std::vector<std::string> sources;
  if (!f.points.empty()) sources.push_back(f.points);
  if (!f.chessboards.empty()) {
    sources.push_back(std::to_string(f.chessboards.size()) + " chessboard image(s)");
  }
  if (!f.marker_images.empty()) sources.push_back("the marker images in " + f.marker_images);
  if (!f.robot_images.empty()) {
    sources.push_back("(robot_pixel_sigma_px) the robot images in " + f.robot_images);
  }
  std::string from;
  for (size_t i = 0; i < sources.size(); ++i) from += (i > 0 ? " and " : "") + sources[i];
  header << "Written by roomfix calibrate from " << from << " (" << n_points << " points), model "
         << f.model << ".\n";
  if (f.model == "full") {
    header << "RMS " << Fixed(std::sqrt(r.full.rms_mm / r.n_full), 2) << " mm / "
           << Fixed(std::sqrt(r.full.rms_px / r.n_full), 3) << " px over the points; "
           << fits.full.message;
  } else {
    header << "Valid only for markers at " << fits.regions.model.calibration_height_m
           << " m (the 9-region model knows one height).";
  }
  return header.str();
}

// parse (CLI11, CheckSources) -> load (the points, the camera) -> compute
// (both fits, their residuals) -> report (the table, the PNG, the YAML).
bool Run(const CalibrateOptions& f, std::string* error) {
  std::vector<int> lines;
  std::vector<Correspondence> points;
  if (!CheckSources(f, error) || !ReadAllPoints(f, &points, &lines, error)) return false;
  if (f.out.empty()) return true;
  CameraGeometry geometry;
  if (!FindCameraGeometry(f, points, &geometry, error)) return false;
  const ModelFits fits = FitModels(f, points, geometry);
  const bool want_full = f.model == "full";
  if (want_full && !fits.full.usable) {
    return Refuse(error, "full model: " + fits.full_why + WorstPoint(fits.full, lines));
  }
  if (!want_full && !fits.regions.usable) {
    return Refuse(error, "9-region model: " + fits.regions.message);
  }

  Calibration full_cal, region_cal;
  full_cal.model = Calibration::Model::kFull;
  full_cal.camera = fits.full.model;
  region_cal.model = Calibration::Model::kRegions;
  region_cal.regions = fits.regions.model;
  std::vector<bool> outlier =
      fits.full.usable ? fits.full.outlier : std::vector<bool>(points.size(), false);
  const Residuals r = PrintResidualTable(points, lines, fits, full_cal, outlier);
  PrintFitSummaries(f, points, lines, fits, r, outlier);

  // The fit must reproduce its points: a calibration that misses them by
  // more than the tolerance would misplace every marker by as much.
  const double rms_px =
      want_full ? std::sqrt(r.full.rms_px / r.n_full) : std::sqrt(r.regions.rms_px / points.size());
  if (!(rms_px <= f.max_rms_px)) {
    return Refuse(error, std::string(want_full ? "full model" : "9-region model") + ": RMS " +
                             (std::isfinite(rms_px)
                                  ? Fixed(rms_px, 2) + " px"
                                  : std::string("not finite (points it cannot reproject)")) +
                             " over the points is over the " + Fixed(f.max_rms_px, 2) +
                             " px tolerance (--max-rms-px); not written");
  }
  full_cal.fit_rms_px = want_full ? rms_px : -1.0;
  // The full fit's parameters: one focal length, the principal point, k1
  // to k_n, the rotation and the position (the options above).
  const int kFullModelParameters = 1 + 2 + f.distortion_terms + 3 + 3;
  full_cal.pixel_sigma_px =
      want_full ? calib::PixelSigmaFromFit(rms_px, r.n_full, kFullModelParameters) : -1.0;
  if (!f.robot_images.empty()) {
    if (!want_full) return Refuse(error, "--robot-images needs the full model");
    if (!RobotPixelSigmas(f, fits.full.model, &full_cal.robot_pixel_sigma_px, error)) {
      return false;
    }
  }
  region_cal.fit_rms_px = want_full ? -1.0 : rms_px;
  const Calibration& chosen = want_full ? full_cal : region_cal;
  const std::string header = CalibrationHeader(f, points.size(), fits, r);
  // The residual picture first and the calibration last, each whole or
  // absent (WriteOutputFile): a run that fails never leaves a calibration
  // beside a picture that stops short, and a new calibration file means the
  // run finished (issue #28: a full disk left a complete YAML and a partial
  // PNG).
  if (!Render(f, chosen, points, outlier, geometry.room_xy_m, geometry.grid_m, error) ||
      !calib::SaveCalibration(f.out, chosen, header, error)) {
    return false;
  }
  std::cout << "wrote " << f.png << "\n";
  std::cout << "wrote " << f.out << "\n";
  return true;
}

}  // namespace

void AddCalibrateCommand(CLI::App* app, int* exit_code) {
  auto* cmd = app->add_subcommand(
      "calibrate",
      "Fit the camera model to marker points (CSV u,v,x_m,y_m,height_m) and/or chessboards on "
      "the floor, from the points and the image size alone (the start is found from them; a "
      "measured mount is an optional prior); print residuals; write the calibration YAML and a "
      "PNG of the fit");
  auto f = std::make_shared<CalibrateOptions>();
  cmd->add_option("--points", f->points, "CSV with header u,v,x_m,y_m,height_m");
  cmd->add_option("--chessboard", f->chessboards,
                  "Image of one chessboard lying flat on the floor (repeatable)");
  cmd->add_option("--board", f->board, "Chessboard inner corners COLSxROWS, e.g. 9x6");
  cmd->add_option("--square", f->square_m, "Chessboard square size in metres")
      ->check(FiniteAbove(0.0, "the square size in metres (> 0)"));
  cmd->add_option("--board-origin", f->board_origins,
                  "Room X,Y (m) of the board's first detected corner, one per --chessboard");
  cmd->add_option("--board-axes", f->board_axes,
                  "Where the board's rows and columns run: x (+x+y), y (+y+x), or a signed "
                  "pair such as +x-y (seen from the ceiling, first corner at the image's "
                  "top-left)")
      ->capture_default_str();
  cmd->add_option("--board-height", f->board_height_m,
                  "Height of the board's top surface above the floor (m)")
      ->check(FiniteAtLeast(0.0, "metres >= 0"))
      ->capture_default_str();
  cmd->add_option("--corners-csv", f->corners_csv,
                  "Write the detected corners (image,i,j,u_px,v_px); with --chessboard and "
                  "--board but no --out: detect and write only, no fit");
  cmd->add_option("--marker-images", f->marker_images,
                  "CSV image,x_m,y_m,height_m: images of one marker placed at surveyed points "
                  "(the reference's tripod procedure); the marker is detected in each");
  cmd->add_option("--robot-images", f->robot_images,
                  "CSV image,x_m,y_m,height_m,robot_id: images of each robot at surveyed points, "
                  "not fitted: each robot's held-out pixel sigma (robot_pixel_sigma_px), the "
                  "noise of its own markers");
  cmd->add_option("--shared-images", f->shared_images,
                  "CSV image,neighbour_image,height_m: one marker seen by this camera and by a "
                  "calibrated neighbour (--neighbour), its floor position from the neighbour");
  cmd->add_option("--neighbour", f->neighbour, "The neighbour camera's calibration YAML");
  cmd->add_option("--marker-class", f->marker_class,
                  "Colour class of that marker in --site (default: the first robot's position "
                  "marker)");
  cmd->add_option("--out", f->out, "Calibration YAML to write (required unless only detecting)");
  cmd->add_option("--model", f->model, "full (the fisheye model) or regions (the reference's 9)")
      ->check(CLI::IsMember({"full", "regions"}))
      ->capture_default_str();
  cmd->add_option("--site", f->site,
                  "Site file: camera size, field of view, mount (a prior) and room; optional "
                  "with --size");
  cmd->add_option("--camera", f->camera_id, "Camera id in the site file (default: the first)");
  cmd->add_option("--mount", f->mount,
                  "Measured lens position X,Y,Z in metres (over the site's); optional: the fit "
                  "starts from the points alone, the mount is a prior on the camera's position");
  cmd->add_option("--mount-sigma", f->mount_sigma_m,
                  "How well the mount is known (m): the prior's standard deviation")
      ->check(FiniteAbove(0.0, "a positive number of metres"))
      ->capture_default_str();
  cmd->add_option("--fov", f->fov_deg,
                  "Nominal field of view across the width, degrees (default: the site's, else "
                  "120); only the fit's start, which searches 0.6-1.67 times its focal length")
      ->check(FiniteAtLeast(0.0, "degrees >= 0 (0: the site's)"));
  cmd->add_option("--distortion-terms", f->distortion_terms,
                  "Fisheye distortion terms fitted, k1..kN (1 to 4)")
      ->check(CLI::Range(1, 4))
      ->capture_default_str();
  cmd->add_option("--size", f->size, "Image size WIDTHxHEIGHT in pixels");
  cmd->add_option("--image", f->image, "Camera image to draw the fit on");
  cmd->add_option("--png", f->png, "PNG to write (default: --out with .png)");
  cmd->add_option("--outlier-px", f->outlier_px, "Residual above which a point is an outlier")
      ->check(FiniteAbove(0.0, "a positive number of pixels"))
      ->capture_default_str();
  cmd->add_option("--pixel-sigma", f->pixel_sigma_px, "Expected pixel noise (weights the prior)")
      ->check(FiniteAbove(0.0, "a positive number of pixels"))
      ->capture_default_str();
  cmd->add_option("--max-iterations", f->max_iterations, "Fit iterations before giving up")
      ->check(CLI::Range(1, 100000))
      ->capture_default_str();
  cmd->add_option("--max-rms-px", f->max_rms_px,
                  "Refuse (exit 1, nothing written) a fit whose RMS residual over its points "
                  "exceeds this many pixels; camera_proc refuses files over 2 px")
      ->check(FiniteAbove(0.0, "a positive number of pixels"))
      ->capture_default_str();
  cmd->callback([f, exit_code] {
    if (f->png.empty()) {
      const size_t dot = f->out.rfind('.');
      const size_t slash = f->out.rfind('/');
      f->png = (dot != std::string::npos && (slash == std::string::npos || dot > slash)
                    ? f->out.substr(0, dot)
                    : f->out) +
               ".png";
    }
    // OpenCV reports a failure by throwing: caught here, at the command's
    // edge, and said as the command's own refusals are.
    try {
      std::string error;
      *exit_code = Run(*f, &error) ? 0 : 1;
      if (*exit_code != 0) std::cerr << "roomfix calibrate: " << error << "\n";
    } catch (const cv::Exception& e) {
      std::cerr << "roomfix calibrate: OpenCV: " << e.msg << "\n";
      *exit_code = 1;
    }
  });
}

}  // namespace roomfix
