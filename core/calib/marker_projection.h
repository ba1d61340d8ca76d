#ifndef ROOMFIX_CORE_CALIB_MARKER_PROJECTION_H_
#define ROOMFIX_CORE_CALIB_MARKER_PROJECTION_H_

#include <Eigen/Core>

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

}  // namespace roomfix::calib

#endif  // ROOMFIX_CORE_CALIB_MARKER_PROJECTION_H_
