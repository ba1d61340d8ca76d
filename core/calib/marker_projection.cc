#include "core/calib/marker_projection.h"

#include <algorithm>
#include <cmath>
#include <vector>

namespace roomfix::calib {

bool DiscCentroidOffset(const CameraModel& camera, const Eigen::Vector3d& centre_m, double radius_m,
                        Eigen::Vector2d* offset_px, int segments) {
  if (segments < 8 || !(radius_m > 0.0)) return false;
  Eigen::Vector2d centre_px;
  if (!camera.ProjectToPixel(centre_m, &centre_px.x(), &centre_px.y())) return false;
  std::vector<Eigen::Vector2d> polygon(static_cast<size_t>(segments));
  for (int i = 0; i < segments; ++i) {
    const double a = 2.0 * M_PI * i / segments;
    const Eigen::Vector3d p =
        centre_m + Eigen::Vector3d(radius_m * std::cos(a), radius_m * std::sin(a), 0.0);
    double u = 0.0, v = 0.0;
    if (!camera.ProjectToPixel(p, &u, &v)) return false;
    // Relative to the centre's image, so the shoelace sums stay small and
    // lose no precision to the ~1000 px coordinates.
    polygon[static_cast<size_t>(i)] = Eigen::Vector2d(u, v) - centre_px;
  }
  // Shoelace: A = 1/2 sum (x_i y_{i+1} - x_{i+1} y_i),
  // C = 1/(6A) sum (p_i + p_{i+1}) (x_i y_{i+1} - x_{i+1} y_i).
  double twice_area = 0.0;
  Eigen::Vector2d moment = Eigen::Vector2d::Zero();
  for (int i = 0; i < segments; ++i) {
    const Eigen::Vector2d& p = polygon[static_cast<size_t>(i)];
    const Eigen::Vector2d& q = polygon[static_cast<size_t>((i + 1) % segments)];
    const double cross = p.x() * q.y() - q.x() * p.y();
    twice_area += cross;
    moment += (p + q) * cross;
  }
  if (std::abs(twice_area) < 1e-12) return false;
  *offset_px = moment / (3.0 * twice_area);
  return true;
}

bool DiscCentroidToFloor(const CameraModel& camera, double u_px, double v_px, double radius_m,
                         double height_m, double* x_m, double* y_m) {
  double x = 0.0, y = 0.0;
  if (!camera.PixelToFloor(u_px, v_px, height_m, &x, &y)) return false;
  // Fixed point: centre = PixelToFloor(centroid - offset(centre)).
  for (int iteration = 0; iteration < 3; ++iteration) {
    Eigen::Vector2d offset;
    if (!DiscCentroidOffset(camera, Eigen::Vector3d(x, y, height_m), radius_m, &offset)) break;
    double nx = 0.0, ny = 0.0;
    if (!camera.PixelToFloor(u_px - offset.x(), v_px - offset.y(), height_m, &nx, &ny)) break;
    const double step_m = std::hypot(nx - x, ny - y);
    x = nx;
    y = ny;
    if (step_m < 1e-7) break;
  }
  *x_m = x;
  *y_m = y;
  return true;
}

std::vector<Correspondence> DiscCentreCorrespondences(const CameraModel& camera,
                                                      const std::vector<Correspondence>& points) {
  std::vector<Correspondence> centres = points;
  for (Correspondence& p : centres) {
    Eigen::Vector2d offset;
    if (p.disc_radius_m > 0.0 &&
        DiscCentroidOffset(camera, Eigen::Vector3d(p.x_m, p.y_m, p.height_m), p.disc_radius_m,
                           &offset)) {
      p.u_px -= offset.x();
      p.v_px -= offset.y();
    }
    p.disc_radius_m = 0.0;
  }
  return centres;
}

CameraFitSummary FitCameraToMarkers(const std::vector<Correspondence>& points,
                                    const CameraModel& initial, const CameraFitOptions& options,
                                    int rounds) {
  CameraFitSummary fit = FitCamera(points, initial, options);
  const bool any_disc = std::any_of(points.begin(), points.end(),
                                    [](const Correspondence& p) { return p.disc_radius_m > 0.0; });
  for (int round = 0; any_disc && fit.usable && round < rounds; ++round) {
    CameraFitSummary next =
        FitCamera(DiscCentreCorrespondences(fit.model, points), fit.model, options);
    if (!next.usable) break;
    fit = std::move(next);
  }
  return fit;
}

}  // namespace roomfix::calib
