#include "core/calib/fisheye_camera.h"

#include <algorithm>
#include <cmath>

namespace roomfix::calib {
namespace {

constexpr double kPi = 3.14159265358979323846;
// Undistortion searches theta on [0, pi/2 + kThetaMarginRad]: a little past
// 90 degrees, so that a pixel on the horizon of a wide lens still inverts.
constexpr double kThetaMarginRad = 0.1;

// theta_d(theta) and its derivative.
void Distort(const std::array<double, 4>& k, double theta, double* theta_d, double* dtheta_d) {
  const double t2 = theta * theta;
  const double poly = 1 + t2 * (k[0] + t2 * (k[1] + t2 * (k[2] + t2 * k[3])));
  const double dpoly_t = 2 * k[0] + t2 * (4 * k[1] + t2 * (6 * k[2] + t2 * 8 * k[3]));
  *theta_d = theta * poly;
  *dtheta_d = poly + t2 * dpoly_t;
}

// Solves theta_d(theta) = target for the smallest root on
// [0, pi/2 + kThetaMarginRad]: the first sign change on a 128-step scan
// brackets it (a fitted polynomial may turn back down beyond the angles it
// was fitted on, so theta_d at the end of the interval says nothing), then
// Newton steps, falling back on bisection whenever a step would leave the
// bracket.
bool Undistort(const std::array<double, 4>& k, double target, double* theta) {
  constexpr int kScanSteps = 128;
  const double end = kPi / 2 + kThetaMarginRad;
  double lo = 0.0, hi = -1.0;
  for (int i = 1; i <= kScanSteps; ++i) {
    const double t = end * i / kScanSteps;
    double f, d;
    Distort(k, t, &f, &d);
    if (f >= target) {
      hi = t;
      break;
    }
    lo = t;
  }
  if (hi < 0) return false;
  double t = 0.5 * (lo + hi);
  for (int i = 0; i < 100; ++i) {
    double f, df;
    Distort(k, t, &f, &df);
    const double residual = f - target;
    if (std::abs(residual) < 1e-14) break;
    if (residual < 0) {
      lo = t;
    } else {
      hi = t;
    }
    double next = df > 0 ? t - residual / df : lo - 1.0;
    if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
    if (std::abs(next - t) < 1e-15) {
      t = next;
      break;
    }
    t = next;
  }
  double f, df;
  Distort(k, t, &f, &df);
  if (!(std::abs(f - target) < 1e-9)) return false;
  *theta = t;
  return true;
}

}  // namespace

bool CameraModel::ProjectToPixel(const Eigen::Vector3d& room_m, double* u_px, double* v_px) const {
  const Eigen::Vector3d p = pose.R_room_from_camera.transpose() * (room_m - pose.position_m);
  if (!p.allFinite() || !(p.z() > 0)) return false;
  const double r_xy = std::hypot(p.x(), p.y());
  const double theta = std::atan2(r_xy, p.z());
  double theta_d, unused;
  Distort(intrinsics.k, theta, &theta_d, &unused);
  // theta_d / r_xy -> 1 / Z on the axis.
  const double scale = r_xy > 1e-12 * p.z() ? theta_d / r_xy : 1.0 / p.z();
  *u_px = intrinsics.fx_px * scale * p.x() + intrinsics.cx_px;
  *v_px = intrinsics.fy_px * scale * p.y() + intrinsics.cy_px;
  return true;
}

bool CameraModel::PixelToRay(double u_px, double v_px, Eigen::Vector3d* ray_camera) const {
  if (!std::isfinite(u_px) || !std::isfinite(v_px)) return false;
  const double xd = (u_px - intrinsics.cx_px) / intrinsics.fx_px;
  const double yd = (v_px - intrinsics.cy_px) / intrinsics.fy_px;
  const double theta_d = std::hypot(xd, yd);
  if (!std::isfinite(theta_d)) return false;
  double theta = 0.0;
  if (!Undistort(intrinsics.k, theta_d, &theta)) return false;
  if (theta_d < 1e-15) {
    *ray_camera = Eigen::Vector3d(0, 0, 1);
  } else {
    const double s = std::sin(theta) / theta_d;
    *ray_camera = Eigen::Vector3d(s * xd, s * yd, std::cos(theta));
  }
  return true;
}

bool CameraModel::PixelToFloor(double u_px, double v_px, double height_m, double* x_m,
                               double* y_m) const {
  if (!std::isfinite(height_m)) return false;
  if (!(u_px >= -kPixelMarginPx && u_px <= intrinsics.width_px + kPixelMarginPx &&
        v_px >= -kPixelMarginPx && v_px <= intrinsics.height_px + kPixelMarginPx)) {
    return false;
  }
  Eigen::Vector3d ray;
  if (!PixelToRay(u_px, v_px, &ray)) return false;
  const Eigen::Vector3d d = pose.R_room_from_camera * ray;
  const double dz = height_m - pose.position_m.z();
  // Parallel (grazing) or pointing away from the plane.
  if (std::abs(d.z()) < 1e-12 || dz / d.z() <= 0) return false;
  const double t = dz / d.z();
  *x_m = pose.position_m.x() + t * d.x();
  *y_m = pose.position_m.y() + t * d.y();
  return true;
}

CameraModel NominalCamera(const std::array<double, 3>& mount_position_m, double field_of_view_deg,
                          int width_px, int height_px) {
  CameraModel m;
  const double half_fov_rad = 0.5 * field_of_view_deg * kPi / 180.0;
  m.intrinsics.fx_px = 0.5 * width_px / half_fov_rad;
  m.intrinsics.fy_px = m.intrinsics.fx_px;
  // Pixel centres run from 0 to width - 1 in OpenCV's convention.
  m.intrinsics.cx_px = 0.5 * (width_px - 1);
  m.intrinsics.cy_px = 0.5 * (height_px - 1);
  m.intrinsics.width_px = width_px;
  m.intrinsics.height_px = height_px;
  // Columns: camera x, y, z in room coordinates.
  m.pose.R_room_from_camera << 1, 0, 0, 0, -1, 0, 0, 0, -1;
  m.pose.position_m =
      Eigen::Vector3d(mount_position_m[0], mount_position_m[1], mount_position_m[2]);
  return m;
}

}  // namespace roomfix::calib
