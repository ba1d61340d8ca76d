#ifndef ROOMFIX_CORE_CALIB_MARKER_PROJECTION_H_
#define ROOMFIX_CORE_CALIB_MARKER_PROJECTION_H_

#include <Eigen/Core>
#include <vector>

#include "core/calib/camera_fit.h"
#include "core/calib/fisheye_camera.h"

namespace roomfix::calib {

// A detector measures the area centroid of a marker's image, but the image
// of a disc's centre is not the centroid of the disc's image: perspective
// makes the near half of a tilted disc larger than the far half, and a
// fisheye lens compresses the outer half more than the inner one. For a
// 10 cm disc 2.9 m below a 120-degree lens the difference is about 0.4 mm on
// the floor in the corners of a 4 x 3 m room (marker_projection_test prints
// it): small against the 3 mm target, but a bias, not noise, and it grows
// with the marker's size and the lens's angle. These functions remove it.

// Area centroid of the image of the horizontal disc with centre `centre_m`
// (its z is the disc's height) and radius `radius_m`, minus the projection of
// the centre, pixels. The boundary is projected as a polygon of `segments`
// vertices and the centroid taken by the shoelace formula; with 64 segments
// the polygon's centroid differs from the curve's by well under 1e-3 px.
// False when a boundary point does not project (behind the camera).
bool DiscCentroidOffset(const CameraModel& camera, const Eigen::Vector3d& centre_m, double radius_m,
                        Eigen::Vector2d* offset_px, int segments = 64);

// The floor point (x, y) at `height_m` whose disc of radius `radius_m` images
// with its area centroid at (u, v): PixelToFloor of the centroid corrected by
// the offset above, iterated to a fixed point (the offset changes slowly
// across the image, so two iterations reach 1e-4 px). False when the pixel
// does not map to the plane.
bool DiscCentroidToFloor(const CameraModel& camera, double u_px, double v_px, double radius_m,
                         double height_m, double* x_m, double* y_m);

// The points with each disc marker's centroid (disc_radius_m > 0) moved to
// the image of its centre under `camera`: (u, v) - DiscCentroidOffset at the
// point's floor position. Points that are not discs, and discs whose rim does
// not project, are kept as they are; the result's disc_radius_m is 0.
std::vector<Correspondence> DiscCentreCorrespondences(const CameraModel& camera,
                                                      const std::vector<Correspondence>& points);

// FitCamera for points that are marker centroids. camera_proc maps a
// marker's centroid with the disc correction (DiscCentroidToFloor), so the
// lens must be the one that images the disc centres, not one fitted to the
// raw centroids: that fit absorbs the centroid offset into the lens (a
// radially growing stretch), and camera_proc's correction then counts it a
// second time. Measured on the hall's cameras (3.6 m above 12 cm markers,
// equidistant lens, markers up to 55 degrees off axis): every camera pose
// was stretched away from the nadir by 1.9e-4 of its distance, about 1 mm
// at 5 m, five times the pose's stated sigma there.
//
// The offset depends on the lens being fitted, so this is a fixed point:
// fit the raw centroids, move them to the centres under that fit, refit from
// it, repeat. The offset varies slowly with the lens (0.1 px at the edge of
// the hall's view for a lens that is off by 1e-4 in scale gives 1e-5 px of
// change), so `rounds` = 3 settles it far below the centroid noise. Without
// any disc point it is FitCamera. The summary's residuals are against the
// corrected points.
CameraFitSummary FitCameraToMarkers(const std::vector<Correspondence>& points,
                                    const CameraModel& initial, const CameraFitOptions& options,
                                    int rounds = 3);

}  // namespace roomfix::calib

#endif  // ROOMFIX_CORE_CALIB_MARKER_PROJECTION_H_
