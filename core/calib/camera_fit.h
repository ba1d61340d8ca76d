#ifndef ROOMFIX_CORE_CALIB_CAMERA_FIT_H_
#define ROOMFIX_CORE_CALIB_CAMERA_FIT_H_

#include <array>
#include <optional>
#include <string>
#include <vector>

#include "core/calib/fisheye_camera.h"

namespace roomfix::calib {

// One calibration point: a marker at room (x, y, height) seen at pixel
// (u, v).
struct Correspondence {
  double u_px = 0.0;
  double v_px = 0.0;
  double x_m = 0.0;
  double y_m = 0.0;
  double height_m = 0.0;
  // 0: (u, v) is the image of the point itself (a chessboard corner, a
  // listed pixel). Otherwise (u, v) is the area centroid of the image of a
  // horizontal disc of this radius centred on the point (a detected marker),
  // which is not the image of its centre (marker_projection.h):
  // FitCameraToMarkers fits the lens to the centres.
  double disc_radius_m = 0.0;
};

struct CameraFitOptions {
  int max_iterations = 200;
  // Fit k1..k4; false keeps the initial model's k.
  bool fit_distortion = true;
  // With fit_distortion: fit k1..k_n for n = distortion_terms (1..4); the
  // higher terms keep the initial model's values. The high powers of theta
  // only matter far off axis: points that all lie within 40 degrees of the
  // axis cannot tell k3 and k4 from k1, k2 and the focal length.
  int distortion_terms = 4;
  // Fit one focal length for both axes (square pixels: every camera this
  // project uses); fy keeps the initial model's fy / fx, 1 for NominalCamera. Removes the fx/fy
  // freedom that a single planar view barely constrains.
  bool equal_focal_lengths = false;
  // A point whose reprojection residual exceeds this is flagged as an
  // outlier and left out of the final fit (worst first, one at a time, while
  // at least kMinPoints remain).
  double outlier_px = 3.0;
  // At most this many points may be left out as outliers; negative: no
  // limit. When more than this are over outlier_px after a fit, the fit is
  // refused at once ("the points do not fit one camera") instead of
  // refitting once per outlier, which on 2 000 random points took minutes.
  int max_outliers = -1;
  // 0: none. Otherwise a soft Gaussian prior (this standard deviation, per
  // axis) pulling the camera position to the initial model's, weighted
  // against pixel residuals of standard deviation `pixel_sigma_px`. This is
  // how a site's measured mount height enters; see FitCamera on why it
  // matters.
  double position_prior_sigma_m = 0.0;
  // Where the prior pulls the camera: the measured mount. Unset: the
  // initial model's position (NominalCamera at the mount). Set when the fit
  // starts from FindCameraStart's camera (camera_start.h), whose position
  // comes from the points, while the prior still states the mount.
  std::optional<std::array<double, 3>> prior_position_m;
  // The expected pixel noise; only weights the position prior.
  double pixel_sigma_px = 0.5;

  bool IsValid(std::string* error) const;
};

struct CameraFitSummary {
  // False: `model` is the initial model and `message` says why.
  bool usable = false;
  // One line: why not usable, or what happened (outliers left out).
  std::string message;
  CameraModel model;
  // Over the points used (not the outliers), pixels.
  double rms_px = 0.0;
  double max_px = 0.0;
  int iterations = 0;
  // Per input point, against the final model (outliers included).
  std::vector<double> residual_px;
  std::vector<bool> outlier;
};

// Fewest points FitCamera accepts: 2 x 10 = 20 residuals for at most 14
// parameters, so that at least 6 degrees of freedom are left to detect an
// outlier with.
constexpr int kMinPoints = 10;

// Fits the camera model to the correspondences: nonlinear least squares
//
//   min sum_i |Project(model, (x_i, y_i, h_i)) - (u_i, v_i)|^2
//         [+ sum_axes (pixel_sigma / prior_sigma)^2 (c - c_initial)^2]
//
// over fx, fy (or one f), cx, cy, k1..k4 (when fit_distortion), the camera
// orientation (a rotation-vector perturbation w: R = R_initial exp([w]x))
// and position c, starting from `initial`: FindCameraStart's camera
// (camera_start.h: from the points alone), or NominalCamera at a measured
// mount. GSL's trust-region Levenberg-Marquardt with a central-difference
// Jacobian.
//
// Identifiability. From one view of points on ONE plane the mapping of that
// plane is well determined, but the camera's height above it is not: moving
// the camera up and lengthening f (k1, k2 bending to match) reproduces the
// plane's pixels within the noise. Measured (camera_fit_test, 20 points at
// 0.2 m spread over the 4 x 3 m floor, 0.3 px noise): with all 14
// parameters free the fit lands 2.2 m off in height; the calibration plane
// still maps to 1.8 mm RMS, but the planes at 0.0 and 0.5 m to 270 and
// 480 mm. Fixing fx = fy and k3 = k4 = 0 conditions the fit (the points lie
// within 40 degrees of the axis, where k3 and k4 are below the noise) but
// leaves the height free (1.4 m off). A marker plane at height h is then
// mapped wrong by about dz (h - h_cal) / (camera height above h) times the
// distance from the nadir: at 2.5 m from it and 0.3 m off the calibration
// height, 1 cm of height error costs about 1 mm. So the height must come
// from outside one plane:
//  - the site's measured mount position as `position_prior_sigma_m` (5 mm,
//    with fx = fy and distortion_terms = 2: 1.2-1.9 mm RMS at 0.0, 0.2 and
//    0.5 m; a 2 cm prior around a mount 3 cm off gives 2-3 mm), or
//  - markers at two heights (0.0 and 0.5 m alternating, no prior:
//    1.1-1.5 mm RMS at all three heights).
// The points must also surround the floor: the same 20 points on a central
// 0.5 m grid (2 x 1.5 m) extrapolate to the corners at 16-24 mm RMS.
// The worst errors are always in the corners (5-12 mm), outside the grid.
//
// Rejected (usable false, one-line message): an invalid option; fewer than
// kMinPoints points; non-finite values; all points on a line (the smaller
// principal standard deviation of their (x, y) below 1 cm); a pixel outside
// the image (more than CameraModel::kPixelMarginPx); a height that is
// negative, not finite, or not below the initial camera (nor below the
// prior's mount, when one is given); a point at or
// behind the initial camera; GSL's solver failing or reaching
// max_iterations; a non-finite result; more than max_outliers points over
// outlier_px.
CameraFitSummary FitCamera(const std::vector<Correspondence>& points, const CameraModel& initial,
                           const CameraFitOptions& options);

}  // namespace roomfix::calib

#endif  // ROOMFIX_CORE_CALIB_CAMERA_FIT_H_
