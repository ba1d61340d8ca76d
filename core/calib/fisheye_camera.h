#ifndef ROOMFIX_CORE_CALIB_FISHEYE_CAMERA_H_
#define ROOMFIX_CORE_CALIB_FISHEYE_CAMERA_H_

#include <Eigen/Core>
#include <array>

namespace roomfix::calib {

// Fisheye intrinsics in OpenCV's Kannala-Brandt model (cv::fisheye). For a
// point (X, Y, Z) in the camera frame:
//
//   a = X / Z, b = Y / Z, r = sqrt(a^2 + b^2)
//   theta   = atan2(r_xy, Z)       (the angle off the optical axis;
//                                   r_xy = sqrt(X^2 + Y^2))
//   theta_d = theta (1 + k1 theta^2 + k2 theta^4 + k3 theta^6 + k4 theta^8)
//   x' = theta_d X / r_xy, y' = theta_d Y / r_xy   (= (theta_d / r) a, b)
//   u = fx x' + cx, v = fy y' + cy
//
// OpenCV writes theta = atan(r), which is the same for Z > 0. atan2 is used
// so that the sign of Z is explicit: points with Z <= 0 (at or behind the
// image plane, theta >= 90 degrees) are not projected at all, although the
// formula itself would continue past 90 degrees for a lens that sees more.
// Skew is zero (OpenCV's alpha).
struct FisheyeIntrinsics {
  double fx_px = 0.0;
  double fy_px = 0.0;
  double cx_px = 0.0;
  double cy_px = 0.0;
  std::array<double, 4> k = {0.0, 0.0, 0.0, 0.0};
  int width_px = 0;
  int height_px = 0;
};

// The camera in the room (metres, z up). Camera frame: x to the right in the
// image, y down in the image, z along the optical axis; a camera at
// (2, 1.5, 3.1) looking straight down has its z along room -z.
// p_room = R_room_from_camera p_camera + position_m.
struct CameraPose {
  Eigen::Matrix3d R_room_from_camera = Eigen::Matrix3d::Identity();
  Eigen::Vector3d position_m = Eigen::Vector3d::Zero();
};

struct CameraModel {
  FisheyeIntrinsics intrinsics;
  CameraPose pose;

  // Pixel of a room point. False (outputs untouched) when the point is at or
  // behind the camera (Z <= 0 in the camera frame) or not finite. The pixel
  // may lie outside the image: a caller that cares checks the bounds.
  bool ProjectToPixel(const Eigen::Vector3d& room_m, double* u_px, double* v_px) const;

  // The inverse for markers on a horizontal plane: the room point at height
  // `height_m` seen at pixel (u, v). Undistortion takes the smallest root of
  // theta_d(theta) = |(x', y')| on [0, pi/2 + 0.1] (bracketed by a scan, then
  // Newton's method safeguarded by bisection: a fitted polynomial may turn
  // back beyond the angles it was fitted on, and the first root is the one
  // on the lens's monotone part); the ray R (sin theta x'/theta_d,
  // sin theta y'/theta_d, cos theta) from the camera centre then meets the
  // plane z = height_m. False (outputs untouched) when the pixel lies more
  // than kPixelMarginPx outside the image, theta_d has no root there (the
  // lens does not reach this far off axis), the ray is parallel to the plane
  // or points away from it, or an input is not finite.
  bool PixelToFloor(double u_px, double v_px, double height_m, double* x_m, double* y_m) const;

  // Unit ray in the camera frame for a pixel; the undistortion step of
  // PixelToFloor, without its image-bounds check. False when theta_d has no
  // root on [0, pi/2 + 0.1].
  bool PixelToRay(double u_px, double v_px, Eigen::Vector3d* ray_camera) const;

  // How far outside the image PixelToFloor still accepts a pixel: corners
  // found by subpixel refinement can sit just over the border.
  static constexpr double kPixelMarginPx = 2.0;
};

// The starting guess (and the synthetic camera's default): a camera at
// `mount_position_m` looking straight down (camera x along room +x, camera y
// along room -y), principal point at the image centre, k = 0 (the
// equidistant lens theta_d = theta, which a fisheye approximates), square
// pixels, and the focal length that puts `field_of_view_deg` across the
// image WIDTH: f = (width / 2) / (fov / 2 in radians). The width, not the
// diagonal, because that is how lenses for these cameras are sold (a
// "120-degree" board lens is the horizontal angle) and it errs towards a
// longer focal length, which the fit shortens easily. A 120-degree lens at
// 1280 x 960 px gives f = 611 px.
CameraModel NominalCamera(const std::array<double, 3>& mount_position_m, double field_of_view_deg,
                          int width_px, int height_px);

}  // namespace roomfix::calib

#endif  // ROOMFIX_CORE_CALIB_FISHEYE_CAMERA_H_
