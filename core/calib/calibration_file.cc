#include "core/calib/calibration_file.h"

#include <fmt/format.h>
#include <yaml-cpp/yaml.h>

#include <Eigen/Geometry>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <iomanip>
#include <sstream>
#include <stdexcept>

#include "core/world/file_io.h"
#include "core/world/yaml_reader.h"

namespace roomfix::calib {
namespace {

using Reader = YamlReader;

void ParseFull(const Reader& r, const YAML::Node& root, Calibration* c) {
  r.OnlyKeys(
      root, "",
      {"model", "intrinsics", "pose", "fit_rms_px", "pixel_sigma_px", "robot_pixel_sigma_px"});
  const YAML::Node in = r.Required(root, "", "intrinsics");
  r.ExpectMap(in, "intrinsics");
  r.OnlyKeys(in, "intrinsics", {"width_px", "height_px", "fx_px", "fy_px", "cx_px", "cy_px", "k"});
  FisheyeIntrinsics& i = c->camera.intrinsics;
  for (auto [name, field] : {std::pair{"width_px", &i.width_px}, {"height_px", &i.height_px}}) {
    const YAML::Node n = r.Required(in, "intrinsics", name);
    *field = r.Int(n, std::string("intrinsics.") + name);
    if (*field <= 0) r.Fail(n, std::string("intrinsics.") + name, "must be positive");
  }
  i.fx_px = r.Positive(r.Required(in, "intrinsics", "fx_px"), "intrinsics.fx_px");
  i.fy_px = r.Positive(r.Required(in, "intrinsics", "fy_px"), "intrinsics.fy_px");
  i.cx_px = r.Double(r.Required(in, "intrinsics", "cx_px"), "intrinsics.cx_px");
  i.cy_px = r.Double(r.Required(in, "intrinsics", "cy_px"), "intrinsics.cy_px");
  i.k = r.Doubles<4>(r.Required(in, "intrinsics", "k"), "intrinsics.k");

  const YAML::Node pose = r.Required(root, "", "pose");
  r.ExpectMap(pose, "pose");
  r.OnlyKeys(pose, "pose", {"position_m", "rotation_matrix", "rotation_vector"});
  const auto p = r.Doubles<3>(r.Required(pose, "pose", "position_m"), "pose.position_m");
  c->camera.pose.position_m = Eigen::Vector3d(p[0], p[1], p[2]);
  const YAML::Node matrix = pose["rotation_matrix"];
  const YAML::Node vector = pose["rotation_vector"];
  if (matrix.IsDefined() == vector.IsDefined()) {
    r.Fail(pose, "pose", "give exactly one of rotation_matrix and rotation_vector");
  }
  if (matrix.IsDefined()) {
    if (!matrix.IsSequence() || matrix.size() != 3) {
      r.Fail(matrix, "pose.rotation_matrix", "expected a list of 3 rows of 3 numbers");
    }
    Eigen::Matrix3d R;
    for (size_t row = 0; row < 3; ++row) {
      const auto values = r.Doubles<3>(matrix[row], Reader::Index("pose.rotation_matrix", row));
      for (size_t col = 0; col < 3; ++col) {
        R(static_cast<int>(row), static_cast<int>(col)) = values[col];
      }
    }
    // A typo in one entry must not pass as a (non-rigid) rotation.
    const double orthonormal = (R.transpose() * R - Eigen::Matrix3d::Identity()).norm();
    if (orthonormal > 1e-6 || std::abs(R.determinant() - 1.0) > 1e-6) {
      r.Fail(matrix, "pose.rotation_matrix",
             "not a rotation (R^T R must be the identity and det R = +1, to 1e-6)");
    }
    c->camera.pose.R_room_from_camera = R;
  } else {
    const auto w = r.Doubles<3>(vector, "pose.rotation_vector");
    const Eigen::Vector3d axis(w[0], w[1], w[2]);
    const double angle = axis.norm();
    c->camera.pose.R_room_from_camera =
        angle > 0 ? Eigen::AngleAxisd(angle, axis / angle).toRotationMatrix()
                  : Eigen::Matrix3d::Identity();
  }
}

RegionAxis ParseAxis(const Reader& r, const YAML::Node& node, const std::string& key,
                     double metres_per_unit) {
  r.ExpectMap(node, key);
  r.OnlyKeys(node, key, {"os1", "C_calib", "os2"});
  RegionAxis a;
  a.os1_px = r.Double(r.Required(node, key, "os1"), key + ".os1");
  const YAML::Node c = r.Required(node, key, "C_calib");
  const double c_per_unit = r.Double(c, key + ".C_calib");
  if (c_per_unit == 0.0) r.Fail(c, key + ".C_calib", "must not be zero");
  // C is pixels per unit: pixels per metre = C / (metres per unit).
  a.c_px_per_m = c_per_unit / metres_per_unit;
  a.os2_m = r.Double(r.Required(node, key, "os2"), key + ".os2") * metres_per_unit;
  return a;
}

void ParseRegions(const Reader& r, const YAML::Node& root, Calibration* c) {
  r.OnlyKeys(
      root, "",
      {"model", "fit_rms_px", "pixel_sigma_px", "robot_pixel_sigma_px", "length_unit", "width_px",
       "height_px", "calibration_height_m", "u_boundaries_px", "v_boundaries_px", "regions"});
  double metres_per_unit = 1.0;
  if (root["length_unit"]) {
    const std::string unit = r.String(root["length_unit"], "length_unit");
    if (unit == "cm") {
      metres_per_unit = 0.01;
    } else if (unit != "m") {
      r.Fail(root["length_unit"], "length_unit", "expected m or cm, got '" + unit + "'");
    }
  }
  int size[2];
  const char* names[2] = {"width_px", "height_px"};
  for (int k = 0; k < 2; ++k) {
    const YAML::Node n = r.Required(root, "", names[k]);
    size[k] = r.Int(n, names[k]);
    if (size[k] <= 0) r.Fail(n, names[k], "must be positive");
  }
  RegionModel m = ThirdsRegionModel(size[0], size[1]);
  m.calibration_height_m =
      r.Double(r.Required(root, "", "calibration_height_m"), "calibration_height_m");
  if (m.calibration_height_m < 0.0) {
    r.Fail(root["calibration_height_m"], "calibration_height_m", "must not be negative");
  }
  if (root["u_boundaries_px"]) {
    m.u_boundaries_px = r.Doubles<2>(root["u_boundaries_px"], "u_boundaries_px");
  }
  if (root["v_boundaries_px"]) {
    m.v_boundaries_px = r.Doubles<2>(root["v_boundaries_px"], "v_boundaries_px");
  }
  const YAML::Node regions = r.Required(root, "", "regions");
  if (!regions.IsSequence() || regions.size() != 9) {
    r.Fail(regions, "regions", "expected a list of 9 regions (3 rows x 3 columns)");
  }
  bool seen[9] = {};
  for (size_t i = 0; i < 9; ++i) {
    const std::string key = Reader::Index("regions", i);
    const YAML::Node node = regions[i];
    r.ExpectMap(node, key);
    r.OnlyKeys(node, key, {"row", "col", "x", "y"});
    const YAML::Node row_node = r.Required(node, key, "row");
    const YAML::Node col_node = r.Required(node, key, "col");
    const int row = r.Int(row_node, key + ".row");
    const int col = r.Int(col_node, key + ".col");
    if (row < 0 || row > 2) r.Fail(row_node, key + ".row", "must be 0, 1 or 2");
    if (col < 0 || col > 2) r.Fail(col_node, key + ".col", "must be 0, 1 or 2");
    const size_t index = static_cast<size_t>(3 * row + col);
    if (seen[index]) {
      r.Fail(node, key,
             "region row " + std::to_string(row) + ", col " + std::to_string(col) + " repeated");
    }
    seen[index] = true;
    m.regions[index].x = ParseAxis(r, r.Required(node, key, "x"), key + ".x", metres_per_unit);
    m.regions[index].y = ParseAxis(r, r.Required(node, key, "y"), key + ".y", metres_per_unit);
  }
  std::string why;
  if (!m.IsValid(&why)) r.Fail(root, "regions", why);
  c->regions = m;
}

std::string G(double v) {
  std::ostringstream s;
  s << std::setprecision(17) << v;
  return s.str();
}

}  // namespace

double Calibration::PixelSigmaFor(int robot_id) const {
  const auto it = robot_pixel_sigma_px.find(robot_id);
  return it != robot_pixel_sigma_px.end() ? it->second : pixel_sigma_px;
}

int Calibration::width_px() const {
  return model == Model::kFull ? camera.intrinsics.width_px : regions.width_px;
}

int Calibration::height_px() const {
  return model == Model::kFull ? camera.intrinsics.height_px : regions.height_px;
}

bool Calibration::PixelToFloor(double u_px, double v_px, double height_m, double* x_m, double* y_m,
                               std::string* error) const {
  if (model == Model::kRegions) return regions.MapAtHeight(u_px, v_px, height_m, x_m, y_m, error);
  if (!camera.PixelToFloor(u_px, v_px, height_m, x_m, y_m)) {
    *error = "pixel (" + G(u_px) + ", " + G(v_px) + ") does not map to the floor at height " +
             G(height_m) + " m (outside the image, beyond the lens, or not finite)";
    return false;
  }
  return true;
}

bool Calibration::FloorToPixel(double x_m, double y_m, double height_m, double* u_px, double* v_px,
                               std::string* error) const {
  if (model == Model::kRegions) {
    return regions.InverseAtHeight(x_m, y_m, height_m, u_px, v_px, error);
  }
  double u, v;
  const double margin = CameraModel::kPixelMarginPx;
  if (!camera.ProjectToPixel(Eigen::Vector3d(x_m, y_m, height_m), &u, &v) || u < -margin ||
      v < -margin || u > camera.intrinsics.width_px + margin ||
      v > camera.intrinsics.height_px + margin) {
    *error = "point (" + G(x_m) + ", " + G(y_m) + ", " + G(height_m) +
             ") m is not seen in the image (outside it, behind the camera, or not finite)";
    return false;
  }
  *u_px = u;
  *v_px = v;
  return true;
}

bool ParseCalibration(const std::string& yaml_text, const std::string& name,
                      Calibration* calibration, std::string* error) {
  Calibration parsed;
  const bool ok = ParseYamlDocument(
      yaml_text, name,
      [&](const YamlReader& r, const YAML::Node& root) {
        const YAML::Node model = r.Required(root, "", "model");
        const std::string kind = r.String(model, "model");
        if (kind == "full") {
          parsed.model = Calibration::Model::kFull;
          ParseFull(r, root, &parsed);
        } else if (kind == "regions") {
          parsed.model = Calibration::Model::kRegions;
          ParseRegions(r, root, &parsed);
        } else {
          r.Fail(model, "model", "expected full or regions, got '" + kind + "'");
        }
        if (const YAML::Node fit = root["fit_rms_px"]) {
          parsed.fit_rms_px = r.Double(fit, "fit_rms_px");
          if (parsed.fit_rms_px < 0.0) r.Fail(fit, "fit_rms_px", "must not be negative");
        }
        if (const YAML::Node sigma = root["pixel_sigma_px"]) {
          parsed.pixel_sigma_px = r.Double(sigma, "pixel_sigma_px");
          if (!(parsed.pixel_sigma_px > 0.0)) r.Fail(sigma, "pixel_sigma_px", "must be positive");
        }
        if (const YAML::Node robots = root["robot_pixel_sigma_px"]) {
          r.ExpectMap(robots, "robot_pixel_sigma_px");
          for (const auto& entry : robots) {
            const int id = r.Int(entry.first, "robot_pixel_sigma_px");
            // A repeated id is refused by the reader (duplicated key).
            parsed.robot_pixel_sigma_px[id] =
                r.Positive(entry.second, "robot_pixel_sigma_px." + std::to_string(id));
          }
        }
      },
      error);
  if (!ok) return false;
  *calibration = parsed;
  return true;
}

bool LoadCalibration(const std::string& path, Calibration* calibration, std::string* error) {
  std::string text;
  if (!ReadConfigFile(path, &text, error)) return false;
  return ParseCalibration(text, path, calibration, error);
}

double PixelSigmaFromFit(double rms_px, int points, int parameters) {
  const double n2 = 2.0 * points;
  if (!(n2 > parameters) || !(rms_px >= 0.0) || parameters < 0) return -1.0;
  const double noise2 = rms_px * rms_px * points / (n2 - parameters);
  return std::sqrt(noise2 * (1.0 + parameters / n2));
}

std::string CheckFitResidual(const Calibration& calibration, double max_rms_px) {
  if (calibration.fit_rms_px < 0.0 || calibration.fit_rms_px <= max_rms_px) return "";
  // Residual and tolerance to 4 significant digits, as the file writes
  // fit_rms_px: its precision is not that of the model.
  return fmt::format(
      "fit_rms_px: the fit's RMS residual {:.4g} px is over the {:.4g} px tolerance (recalibrate: "
      "check the points and the mount)",
      calibration.fit_rms_px, max_rms_px);
}

namespace {

// A flow sequence of doubles, [a, b, c]: a vector reads as one line.
template <class... T>
void FlowSeq(YAML::Emitter* out, T... values) {
  *out << YAML::Flow << YAML::BeginSeq;
  (*out << ... << values);
  *out << YAML::EndSeq;
}

void EmitFull(const CameraModel& camera, YAML::Emitter* out) {
  const FisheyeIntrinsics& i = camera.intrinsics;
  const Eigen::Matrix3d& R = camera.pose.R_room_from_camera;
  const Eigen::Vector3d& p = camera.pose.position_m;
  *out << YAML::Key << "model" << YAML::Value << "full";
  *out << YAML::Key << "intrinsics" << YAML::Value << YAML::BeginMap;
  *out << YAML::Key << "width_px" << YAML::Value << i.width_px;
  *out << YAML::Key << "height_px" << YAML::Value << i.height_px;
  *out << YAML::Key << "fx_px" << YAML::Value << i.fx_px;
  *out << YAML::Key << "fy_px" << YAML::Value << i.fy_px;
  *out << YAML::Key << "cx_px" << YAML::Value << i.cx_px;
  *out << YAML::Key << "cy_px" << YAML::Value << i.cy_px;
  *out << YAML::Key << "k" << YAML::Value;
  FlowSeq(out, i.k[0], i.k[1], i.k[2], i.k[3]);
  *out << YAML::EndMap;
  *out << YAML::Key << "pose" << YAML::Value << YAML::BeginMap;
  *out << YAML::Key << "position_m" << YAML::Value;
  FlowSeq(out, p.x(), p.y(), p.z());
  // On its own line, as the files have always had it (errors name lines).
  *out << YAML::Newline << YAML::Comment("room from camera: p_room = R p_camera + position_m");
  *out << YAML::Key << "rotation_matrix" << YAML::Value << YAML::BeginSeq;
  for (int row = 0; row < 3; ++row) FlowSeq(out, R(row, 0), R(row, 1), R(row, 2));
  *out << YAML::EndSeq << YAML::EndMap;
}

void EmitRegions(const RegionModel& m, YAML::Emitter* out) {
  *out << YAML::Key << "model" << YAML::Value << "regions";
  *out << YAML::Key << "length_unit" << YAML::Value << "m";
  *out << YAML::Key << "width_px" << YAML::Value << m.width_px;
  *out << YAML::Key << "height_px" << YAML::Value << m.height_px;
  *out << YAML::Key << "calibration_height_m" << YAML::Value << m.calibration_height_m;
  *out << YAML::Key << "u_boundaries_px" << YAML::Value;
  FlowSeq(out, m.u_boundaries_px[0], m.u_boundaries_px[1]);
  *out << YAML::Key << "v_boundaries_px" << YAML::Value;
  FlowSeq(out, m.v_boundaries_px[0], m.v_boundaries_px[1]);
  *out << YAML::Newline
       << YAML::Comment("x_m = (u_px - os1) / C_calib + os2, y_m = (v_px - os1) / C_calib + os2");
  *out << YAML::Key << "regions" << YAML::Value << YAML::BeginSeq;
  for (int i = 0; i < 9; ++i) {
    const Region& r = m.regions[static_cast<size_t>(i)];
    *out << YAML::BeginMap << YAML::Key << "row" << YAML::Value << i / 3;
    *out << YAML::Key << "col" << YAML::Value << i % 3;
    for (auto [name, a] : {std::pair{"x", &r.x}, {"y", &r.y}}) {
      *out << YAML::Key << name << YAML::Value << YAML::Flow << YAML::BeginMap;
      *out << YAML::Key << "os1" << YAML::Value << a->os1_px;
      *out << YAML::Key << "C_calib" << YAML::Value << a->c_px_per_m;
      *out << YAML::Key << "os2" << YAML::Value << a->os2_m << YAML::EndMap;
    }
    *out << YAML::EndMap;
  }
  *out << YAML::EndSeq;
}

}  // namespace

// yaml-cpp writes every double to 17 significant digits (its default
// precision, std::numeric_limits<double>::max_digits10), so a file reads
// back to the same bits; the two pixel errors are given to 4 digits, the
// precision of a fit residual.
std::string FormatCalibration(const Calibration& c, const std::string& header_comment) {
  YAML::Emitter out;
  if (!header_comment.empty()) out << YAML::Comment(header_comment);
  out << YAML::BeginMap;
  if (c.fit_rms_px >= 0.0) {
    out << YAML::Key << "fit_rms_px" << YAML::Value << YAML::Precision(4) << c.fit_rms_px;
  }
  if (c.pixel_sigma_px > 0.0) {
    out << YAML::Key << "pixel_sigma_px" << YAML::Value << YAML::Precision(4) << c.pixel_sigma_px;
  }
  if (!c.robot_pixel_sigma_px.empty()) {
    out << YAML::Key << "robot_pixel_sigma_px" << YAML::Value << YAML::Flow << YAML::BeginMap;
    for (const auto& [id, sigma] : c.robot_pixel_sigma_px) {
      out << YAML::Key << id << YAML::Value << YAML::Precision(4) << sigma;
    }
    out << YAML::EndMap;
  }
  if (c.model == Calibration::Model::kFull) {
    EmitFull(c.camera, &out);
  } else {
    EmitRegions(c.regions, &out);
  }
  out << YAML::EndMap;
  return std::string(out.c_str()) + "\n";
}

bool SaveCalibration(const std::string& path, const Calibration& calibration,
                     const std::string& header_comment, std::string* error) {
  return WriteOutputFile(path, FormatCalibration(calibration, header_comment), error);
}

}  // namespace roomfix::calib
