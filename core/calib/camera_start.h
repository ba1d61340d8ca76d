#ifndef ROOMFIX_CORE_CALIB_CAMERA_START_H_
#define ROOMFIX_CORE_CALIB_CAMERA_START_H_

#include <string>
#include <vector>

#include "core/calib/camera_fit.h"
#include "core/calib/fisheye_camera.h"

namespace roomfix::calib {

struct CameraStart {
  // False: `message` says why (one line) and `model` is meaningless.
  bool usable = false;
  std::string message;
  // The starting camera: the nominal lens's principal point and k = 0, the
  // focal length the search chose, the pose PnP found.
  CameraModel model;
  // RMS pixel distance of the start's points (the plane it used, else all)
  // from their projection through `model`:
  // how well the equidistant lens with one focal length already explains
  // them (a few pixels for a real fisheye; the full fit does the rest).
  double rms_px = 0.0;
  // Set with usable false when the camera came out below the points (their
  // axes mirrored): wrong input, whatever else is known about the camera.
  bool mirrored = false;
};

// The points must span at least this angle of view (the smaller principal
// standard deviation of their directions through the nominal lens, i.e. of
// their pixels divided by the nominal focal length). Below it the view is
// almost affine: the camera's distance trades against the focal length and
// its tilt against the principal point, so a fit "converges" to a camera
// that reproduces the points and maps everything around them wrongly.
constexpr double kMinViewSpreadDeg = 3.0;

// A camera to start FitCamera from, found from the correspondences alone:
// no mount position, no orientation. `nominal` supplies the image size, the
// principal point (the image centre) and the nominal focal length (from the
// lens's field of view, NominalCamera); its pose is ignored.
//
// The maths. The nominal lens is equidistant (theta_d = theta, k = 0): a
// pixel at distance rho from the principal point is a ray theta = rho / f
// off the axis, i.e. the pinhole-normalised point
//   (a, b) = tan(theta) (u - cx, v - cy) / rho.
// For points on one plane (one height), (a, b) and the plane's (x, y) are
// related by a homography H ~ [r1 r2 t] (K = I); OpenCV's IPPE
// (cv::solvePnP, SOLVEPNP_IPPE: Collins and Bartoli 2014) decomposes it
// into the rotation and translation, taking the better of its two
// solutions. With points at several heights the start uses the largest
// group at one height (within 1 cm; at least 6 points, not on a line), so
// that one height entered wrong cannot drag it; without such a group all
// points go to SQPnP (SOLVEPNP_SQPNP), which is global for any
// configuration. Rays at 80 degrees or more off the axis
// are left out of the PnP (tan(theta) explodes there) but not out of the
// score. Since the real focal length may be 20-40 % off the nominal one
// (the field of view is a sales figure, and a fisheye's distortion moves
// it), the start is solved for focal lengths from 0.6 to 1.67 times the
// nominal one (21 steps, geometric) and the one whose camera reprojects
// the points best through the fisheye formula is kept; FitCamera then
// frees the focal length, principal point, distortion and pose.
//
// Refused (usable false, one line): fewer than kMinPoints points;
// non-finite values; a pixel outside the image; all points on a line (as
// FitCamera); points spanning less than kMinViewSpreadDeg of view; no
// focal length for which PnP succeeds; a point at or above the camera the
// rest place; a camera below the points: for points on one plane that is
// the mirror image
// of the real camera, which happens when the points' x and y axes are
// mirrored against the image (a left-handed pair, such as a chessboard
// entered with --board-axes x where +x-y was meant).
CameraStart FindCameraStart(const std::vector<Correspondence>& points, const CameraModel& nominal);

}  // namespace roomfix::calib

#endif  // ROOMFIX_CORE_CALIB_CAMERA_START_H_
