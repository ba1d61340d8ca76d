#ifndef ROOMFIX_CORE_CALIB_CALIBRATION_FILE_H_
#define ROOMFIX_CORE_CALIB_CALIBRATION_FILE_H_

#include <map>
#include <string>

#include "core/calib/fisheye_camera.h"
#include "core/calib/region_model.h"

namespace roomfix::calib {

// A camera calibration as a site file's cameras[].calibration names it:
// either the full model (fisheye_camera.h) or the reference's 9-region
// table (region_model.h).
//
// YAML, full model:
//
//   model: full
//   intrinsics: {width_px: 1920, height_px: 1080, fx_px: 917.0, fy_px: 917.0,
//                cx_px: 960.0, cy_px: 540.0, k: [0.0, 0.0, 0.0, 0.0]}
//   pose:
//     position_m: [2.0, 1.5, 3.1]
//     rotation_matrix: [[1, 0, 0], [0, -1, 0], [0, 0, -1]]  # room from camera
//     # or rotation_vector: [3.14159, 0, 0]  (axis * angle, radians)
//
// YAML, 9-region table (the reference's form; os1 in pixels, C_calib in
// pixels per length unit, os2 in the length unit):
//
//   model: regions
//   length_unit: m            # or cm: the reference's own table, unconverted
//   width_px: 1920
//   height_px: 1080
//   calibration_height_m: 0.2
//   u_boundaries_px: [640, 1280]   # optional, default thirds
//   v_boundaries_px: [360, 720]
//   regions:                  # 9, row-major, top row first
//     - {row: 0, col: 0, x: {os1: 320, C_calib: 400.1, os2: 0.6},
//                        y: {os1: 180, C_calib: -399.2, os2: 2.4}}
//
// The rotation matrix must be orthonormal with determinant +1 (to 1e-6).
//
// Either model may record how well it fitted the points it came from
// (roomfix calibrate writes it):
//
//   fit_rms_px: 0.047   # RMS reprojection residual of the fit, pixels
//
// and the one-sigma error, per pixel axis, of a marker's pixel mapped with
// it (roomfix calibrate derives it from the fit; camera_proc's position
// covariance is this through the mapping's Jacobian):
//
//   pixel_sigma_px: 0.0386
//
// and, per robot, the same measured on images of that robot's own markers
// that the fit did not use (roomfix calibrate --robot-images): a marker's
// centroid noise depends on its colours and on what surrounds it (in the
// hall's JPEG frames a green marker beside a blue one is 2.7 times as noisy
// as the red tripod marker the lens was fitted to), so one robot's figure
// is not another's:
//
//   robot_pixel_sigma_px: {1: 0.035, 4: 0.094}
//
// A calibration whose fit_rms_px is over kMaxFitRmsPx is refused by
// camera_proc and check-config (CheckFitResidual): it would place markers
// wrongly by that much everywhere.
inline constexpr double kMaxFitRmsPx = 2.0;

struct Calibration {
  enum class Model { kFull, kRegions };
  Model model = Model::kFull;
  CameraModel camera;   // kFull
  RegionModel regions;  // kRegions
  // The fit's RMS residual in pixels when the file states it (fit_rms_px),
  // otherwise negative.
  double fit_rms_px = -1.0;
  // One-sigma pixel error per axis of a marker mapped with this calibration
  // (pixel_sigma_px), otherwise negative. From N points fitted with p
  // parameters and residual norms r_i: the centroid noise per axis is
  // sigma^2 = sum r_i^2 / (2N - p) (the fit absorbed p of the 2N degrees of
  // freedom), and the fitted model's own error at a point adds on average
  // sigma^2 p / (2N) (the prediction variance of least squares), so
  // pixel_sigma^2 = sigma^2 (1 + p / (2N)) (PixelSigmaFromFit).
  double pixel_sigma_px = -1.0;
  // Per robot id: the one-sigma pixel error per axis of that robot's
  // markers, held out from the fit (robot_pixel_sigma_px); robots not
  // listed use pixel_sigma_px.
  std::map<int, double> robot_pixel_sigma_px;

  // robot_pixel_sigma_px's figure for the robot, else pixel_sigma_px
  // (negative when the file states neither).
  double PixelSigmaFor(int robot_id) const;
  int width_px() const;
  int height_px() const;
  // Pixel to floor at a marker height / floor to pixel. The full model
  // serves every height; the 9-region model refuses any but its own
  // (RegionModel::MapAtHeight). False with a one-line *error.
  bool PixelToFloor(double u_px, double v_px, double height_m, double* x_m, double* y_m,
                    std::string* error) const;
  bool FloorToPixel(double x_m, double y_m, double height_m, double* u_px, double* v_px,
                    std::string* error) const;
};

// The pixel_sigma_px of a least-squares fit of `parameters` parameters to
// `points` points whose residual norms have RMS `rms_px` (see
// Calibration::pixel_sigma_px); negative when there are no degrees of
// freedom left (2 points <= parameters).
double PixelSigmaFromFit(double rms_px, int points, int parameters);

// Reads a calibration file. On failure false and *error is one line
// "FILE:LINE: KEY: WHAT" (as LoadSite): YAML syntax, missing or unknown keys,
// wrong types, non-finite numbers, non-positive sizes or focal lengths, a
// rotation that is not a rotation, regions missing, repeated or out of
// range, a zero C_calib, boundaries out of order.
bool LoadCalibration(const std::string& path, Calibration* calibration, std::string* error);
// "" when the calibration states no fit residual or one at most
// `max_rms_px`; otherwise "fit_rms_px: the fit's RMS residual X px is over
// the Y px tolerance (recalibrate: ...)".
std::string CheckFitResidual(const Calibration& calibration, double max_rms_px = kMaxFitRmsPx);

// As LoadCalibration, from text; `name` stands for the file in messages.
bool ParseCalibration(const std::string& yaml_text, const std::string& name,
                      Calibration* calibration, std::string* error);

// The YAML text of a calibration (metres; full precision so that a reload
// maps the same to 1e-9), preceded by `header_comment` with "# " prefixed to
// each line.
std::string FormatCalibration(const Calibration& calibration, const std::string& header_comment);
bool SaveCalibration(const std::string& path, const Calibration& calibration,
                     const std::string& header_comment, std::string* error);

}  // namespace roomfix::calib

#endif  // ROOMFIX_CORE_CALIB_CALIBRATION_FILE_H_
