#include "core/calib/camera_start.h"

#include <fmt/format.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>

namespace roomfix::calib {
namespace {

constexpr double kPi = 3.14159265358979323846;
// Rays this far off the axis are left out of the PnP: tan(theta) grows
// without bound towards 90 degrees, so one such point would outweigh the
// rest in the homography's least squares.
constexpr double kMaxPnpThetaRad = 80.0 * kPi / 180.0;
// The focal-length search: kSearchSteps values from kSearchLow to
// kSearchHigh times the nominal focal length, geometrically spaced.
constexpr double kSearchLow = 0.6;
constexpr double kSearchHigh = 1.0 / 0.6;
constexpr int kSearchSteps = 21;
// Heights within this of each other count as one plane for the start
// (IPPE); the full fit then uses every point at its own height.
constexpr double kSamePlaneM = 0.01;
// PnP needs at least this many points (IPPE: 4; SQPnP: 3, more for a
// unique answer).
constexpr int kMinPnpPoints = 6;

// The smaller principal standard deviation of 2-D points.
double SmallerSpread(const std::vector<Eigen::Vector2d>& p) {
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (const auto& q : p) mean += q;
  mean /= static_cast<double>(p.size());
  Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();
  for (const auto& q : p) cov += (q - mean) * (q - mean).transpose();
  cov /= static_cast<double>(p.size());
  return std::sqrt(
      std::max(0.0, Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(cov).eigenvalues()(0)));
}

// One candidate focal length: PnP on the points undistorted through the
// equidistant lens with focal length f, scored by the RMS pixel error of
// the resulting camera through the fisheye formula (all points; one behind
// the camera scores as infinitely far).
bool SolveForFocal(const std::vector<Correspondence>& points, const CameraModel& nominal,
                   double f_px, bool planar, double plane_height_m, CameraModel* out,
                   double* rms_px) {
  const double cx = nominal.intrinsics.cx_px, cy = nominal.intrinsics.cy_px;
  std::vector<cv::Point3d> object;
  std::vector<cv::Point2d> normalised;
  for (const Correspondence& c : points) {
    const double du = c.u_px - cx, dv = c.v_px - cy;
    const double rho = std::hypot(du, dv);
    const double theta = rho / f_px;
    if (theta >= kMaxPnpThetaRad) continue;
    const double s = rho > 1e-12 ? std::tan(theta) / rho : 1.0 / f_px;
    normalised.emplace_back(s * du, s * dv);
    // IPPE wants the plane at z = 0: heights are then all equal and
    // dropped, and added back to the camera's position below.
    object.emplace_back(c.x_m, c.y_m, planar ? 0.0 : c.height_m);
  }
  if (static_cast<int>(object.size()) < kMinPnpPoints) return false;
  cv::Mat rvec, tvec;
  bool ok = false;
  try {
    ok = cv::solvePnP(object, normalised, cv::Matx33d::eye(), cv::noArray(), rvec, tvec, false,
                      planar ? cv::SOLVEPNP_IPPE : cv::SOLVEPNP_SQPNP);
  } catch (const cv::Exception&) {
    return false;  // degenerate input (OpenCV asserts): no camera for this f
  }
  if (!ok || rvec.total() != 3 || tvec.total() != 3) return false;
  cv::Matx33d R;
  cv::Rodrigues(rvec, R);
  Eigen::Matrix3d R_camera_from_room;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) R_camera_from_room(i, j) = R(i, j);
  }
  const Eigen::Vector3d t(tvec.at<double>(0), tvec.at<double>(1), tvec.at<double>(2));
  CameraModel m = nominal;
  m.intrinsics.fx_px = f_px;
  m.intrinsics.fy_px = f_px * nominal.intrinsics.fy_px / nominal.intrinsics.fx_px;
  m.intrinsics.k = {0.0, 0.0, 0.0, 0.0};
  m.pose.R_room_from_camera = R_camera_from_room.transpose();
  m.pose.position_m = -R_camera_from_room.transpose() * t;
  if (planar) m.pose.position_m.z() += plane_height_m;
  if (!m.pose.position_m.allFinite() || !m.pose.R_room_from_camera.allFinite()) return false;
  double sum2 = 0.0;
  for (const Correspondence& c : points) {
    double u, v;
    if (!m.ProjectToPixel(Eigen::Vector3d(c.x_m, c.y_m, c.height_m), &u, &v)) return false;
    sum2 += std::pow(u - c.u_px, 2) + std::pow(v - c.v_px, 2);
  }
  *out = m;
  *rms_px = std::sqrt(sum2 / static_cast<double>(points.size()));
  return std::isfinite(*rms_px);
}

// The largest group of points at one height (within kSamePlaneM of one of
// them).
std::vector<Correspondence> LargestSameHeightGroup(const std::vector<Correspondence>& points) {
  std::vector<Correspondence> plane;
  for (const Correspondence& a : points) {
    std::vector<Correspondence> group;
    for (const Correspondence& b : points) {
      if (std::abs(b.height_m - a.height_m) <= kSamePlaneM) group.push_back(b);
    }
    if (group.size() > plane.size()) plane = std::move(group);
  }
  return plane;
}

// The camera of the smallest reprojection RMS (px, returned; infinite when
// no focal length gave a pose) over kSearchSteps focal lengths spaced
// geometrically from kSearchLow to kSearchHigh times the nominal one.
double SearchFocal(const std::vector<Correspondence>& used, const CameraModel& nominal, bool planar,
                   double plane_height_m, CameraModel* best) {
  double best_rms = INFINITY;
  for (int k = 0; k < kSearchSteps; ++k) {
    const double scale =
        kSearchLow * std::pow(kSearchHigh / kSearchLow, k / static_cast<double>(kSearchSteps - 1));
    CameraModel m;
    double rms = 0.0;
    if (!SolveForFocal(used, nominal, scale * nominal.intrinsics.fx_px, planar, plane_height_m, &m,
                       &rms)) {
      continue;
    }
    if (rms < best_rms) {
      best_rms = rms;
      *best = m;
    }
  }
  return best_rms;
}

}  // namespace

CameraStart FindCameraStart(const std::vector<Correspondence>& points, const CameraModel& nominal) {
  CameraStart s;
  const FisheyeIntrinsics& in = nominal.intrinsics;
  if (!(in.fx_px > 0 && in.fy_px > 0 && in.width_px > 0 && in.height_px > 0)) {
    s.message = "invalid nominal lens: focal lengths and image size must be positive";
    return s;
  }
  const int n = static_cast<int>(points.size());
  if (n < kMinPoints) {
    s.message = "too few points: need at least " + std::to_string(kMinPoints) + ", got " +
                std::to_string(n);
    return s;
  }
  const double margin = CameraModel::kPixelMarginPx;
  std::vector<Eigen::Vector2d> room, view;
  double lowest_m = INFINITY, highest_m = -INFINITY;
  for (int i = 0; i < n; ++i) {
    const Correspondence& c = points[i];
    if (!std::isfinite(c.u_px) || !std::isfinite(c.v_px) || !std::isfinite(c.x_m) ||
        !std::isfinite(c.y_m) || !std::isfinite(c.height_m)) {
      s.message = "point " + std::to_string(i) + ": non-finite pixel or position";
      return s;
    }
    if (!(c.u_px >= -margin && c.u_px <= in.width_px + margin && c.v_px >= -margin &&
          c.v_px <= in.height_px + margin)) {
      s.message = fmt::format("point {}: pixel ({:g}, {:g}) is outside the {} x {} image", i,
                              c.u_px, c.v_px, in.width_px, in.height_px);
      return s;
    }
    room.emplace_back(c.x_m, c.y_m);
    view.emplace_back((c.u_px - in.cx_px) / in.fx_px, (c.v_px - in.cy_px) / in.fy_px);
    lowest_m = std::min(lowest_m, c.height_m);
    highest_m = std::max(highest_m, c.height_m);
  }
  const double room_spread_m = SmallerSpread(room);
  if (room_spread_m < 0.01) {
    s.message =
        fmt::format("all points lie on a line: their spread across it is {:.3g} mm (need 10 mm)",
                    room_spread_m * 1000);
    return s;
  }
  // Equidistant lens: pixels / f are angles in radians.
  const double view_spread_deg = SmallerSpread(view) * 180.0 / kPi;
  if (view_spread_deg < kMinViewSpreadDeg) {
    s.message = fmt::format(
        "all points lie in one small patch of the image: they span {:.2g} deg of view across it "
        "(need {:.2g}), too little to tell the camera's distance from its focal length; spread "
        "them over the image",
        view_spread_deg, kMinViewSpreadDeg);
    return s;
  }
  // The start's points: the largest group at one height (within
  // kSamePlaneM) when it is enough for IPPE, so that one height entered
  // wrong cannot drag the start; else all points through SQPnP.
  const std::vector<Correspondence> plane = LargestSameHeightGroup(points);
  std::vector<Eigen::Vector2d> plane_xy;
  double plane_height_m = 0.0;
  for (const Correspondence& c : plane) {
    plane_xy.emplace_back(c.x_m, c.y_m);
    plane_height_m += c.height_m / static_cast<double>(plane.size());
  }
  const bool planar =
      static_cast<int>(plane.size()) >= kMinPnpPoints && SmallerSpread(plane_xy) >= 0.01;
  const std::vector<Correspondence>& used = planar ? plane : points;

  const double best_rms = SearchFocal(used, nominal, planar, plane_height_m, &s.model);
  if (!std::isfinite(best_rms)) {
    s.message = fmt::format(
        "no camera explains the points: the planar pose solver found none for focal lengths "
        "{:.4g} to {:.4g} px (check the image size, the field of view and the points)",
        kSearchLow * in.fx_px, kSearchHigh * in.fx_px);
    return s;
  }
  const double camera_z = s.model.pose.position_m.z();
  if (camera_z > lowest_m && !(camera_z > highest_m)) {
    // Most points place the camera above them, some are higher still: a
    // wrong height, not a mirrored floor.
    for (int i = 0; i < n; ++i) {
      if (points[i].height_m >= camera_z) {
        s.message = fmt::format(
            "point {}: height {:.4g} m is inconsistent: the points place the camera at z = "
            "{:.3g} m, below it",
            i, points[i].height_m, camera_z);
        return s;
      }
    }
  }
  if (!(camera_z > highest_m)) {
    s.message = fmt::format(
        "the points put the camera below them (at z = {:.3g} m, points up to {:.3g} m): their x "
        "and y are mirrored against the image (a left-handed axis pair, e.g. a chessboard's "
        "--board-axes x where +x-y was meant); swap x and y or negate one",
        camera_z, highest_m);
    s.mirrored = true;
    return s;
  }
  s.usable = true;
  s.rms_px = best_rms;
  s.message = fmt::format(
      "start from the points alone: camera at ({:.4g}, {:.4g}, {:.4g}) m, f {:.4g} px, {:.3g} px "
      "RMS through the equidistant lens",
      s.model.pose.position_m.x(), s.model.pose.position_m.y(), camera_z, s.model.intrinsics.fx_px,
      s.rms_px);
  return s;
}

}  // namespace roomfix::calib
