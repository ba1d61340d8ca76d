#include "core/calib/fisheye_camera.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <opencv2/core/eigen.hpp>
#include <random>
#include <vector>

namespace roomfix::calib {
namespace {

// Tolerances, each for its reason.
// cv::fisheye::undistortPoints and PixelToRay both invert the distortion
// polynomial iteratively (OpenCV's default: at most 10 iterations or a step
// under 1e-8), so they agree to their convergence, not to rounding. 1e-6 in
// normalised coordinates (unit focal length) is ~6e-4 px at f ~ 611 px.
constexpr double kUndistortAgreement = 1e-6;
// The principal point's ray is the optical axis exactly: only rounding of
// the mount's translation (metres ~1) is left.
constexpr double kExactM = 1e-12;
// f = half width / half field of view in radians: a division of doubles.
constexpr double kClosedFormPx = 1e-9;
// A rotation built from a straight-down orientation: det R = 1 to rounding.
constexpr double kRotationDeterminant = 1e-12;

// A ceiling camera at the centre of the 4 x 3 m floor, 3.1 m up, with a
// 120-degree lens on a 1280 x 960 sensor, tilted a little and with the
// distortion of a real fisheye: every term of the model is exercised.
CameraModel TestCamera() {
  CameraModel m = NominalCamera({2.0, 1.5, 3.1}, 120.0, 1280, 960);
  m.intrinsics.fx_px *= 1.03;
  m.intrinsics.fy_px *= 1.01;
  m.intrinsics.cx_px += 7.5;
  m.intrinsics.cy_px -= 4.0;
  m.intrinsics.k = {0.02, -0.01, 0.003, -0.0005};
  m.pose.R_room_from_camera =
      m.pose.R_room_from_camera *
      Eigen::AngleAxisd(0.02, Eigen::Vector3d(1, 2, 0.5).normalized()).toRotationMatrix();
  m.pose.position_m += Eigen::Vector3d(0.03, -0.02, 0.01);
  return m;
}

TEST(FisheyeCamera, ProjectsLikeOpenCvsFisheyeModel) {
  // Same formula, evaluated by cv::fisheye::projectPoints; agreement to
  // round-off (1e-6 px is 1e-9 of the image width).
  constexpr double kTolerancePx = 1e-6;
  const CameraModel m = TestCamera();
  const Eigen::Matrix3d R_camera_from_room = m.pose.R_room_from_camera.transpose();
  const Eigen::Vector3d t = -R_camera_from_room * m.pose.position_m;
  cv::Mat R_cv;
  cv::eigen2cv(R_camera_from_room, R_cv);
  cv::Mat rvec;
  cv::Rodrigues(R_cv, rvec);
  const cv::Vec3d tvec(t.x(), t.y(), t.z());
  const cv::Matx33d K(m.intrinsics.fx_px, 0, m.intrinsics.cx_px, 0, m.intrinsics.fy_px,
                      m.intrinsics.cy_px, 0, 0, 1);
  const cv::Vec4d D(m.intrinsics.k[0], m.intrinsics.k[1], m.intrinsics.k[2], m.intrinsics.k[3]);

  std::mt19937 rng(7);
  std::uniform_real_distribution<double> x(-1.0, 5.0), y(-1.0, 4.0), z(0.0, 2.5);
  std::vector<cv::Point3d> room;
  for (int i = 0; i < 500; ++i) room.emplace_back(x(rng), y(rng), z(rng));
  std::vector<cv::Point2d> expected;
  cv::fisheye::projectPoints(room, expected, rvec, tvec, K, D);
  for (size_t i = 0; i < room.size(); ++i) {
    double u = 0, v = 0;
    ASSERT_TRUE(m.ProjectToPixel(Eigen::Vector3d(room[i].x, room[i].y, room[i].z), &u, &v));
    EXPECT_NEAR(u, expected[i].x, kTolerancePx) << i;
    EXPECT_NEAR(v, expected[i].y, kTolerancePx) << i;
  }

  // And the undistortion agrees with cv::fisheye::undistortPoints.
  std::vector<cv::Point2d> normalised;
  cv::fisheye::undistortPoints(expected, normalised, K, D);
  for (size_t i = 0; i < room.size(); ++i) {
    Eigen::Vector3d ray;
    ASSERT_TRUE(m.PixelToRay(expected[i].x, expected[i].y, &ray));
    EXPECT_NEAR(ray.x() / ray.z(), normalised[i].x, kUndistortAgreement) << i;
    EXPECT_NEAR(ray.y() / ray.z(), normalised[i].y, kUndistortAgreement) << i;
  }
}

TEST(FisheyeCamera, PixelToFloorInvertsProjectToPixelAtAnyHeight) {
  // Pure geometry, no fitting: the round trip is exact up to the Newton
  // tolerance (1e-14 rad in theta, nanometres on the floor).
  constexpr double kRoundTripM = 1e-6;
  const CameraModel m = TestCamera();
  double worst_m = 0;
  for (double h : {0.0, 0.2, 1.0}) {
    for (double x = 0; x <= 4.0 + 1e-9; x += 0.05) {
      for (double y = 0; y <= 3.0 + 1e-9; y += 0.05) {
        double u, v, bx, by;
        ASSERT_TRUE(m.ProjectToPixel(Eigen::Vector3d(x, y, h), &u, &v));
        ASSERT_TRUE(m.PixelToFloor(u, v, h, &bx, &by)) << x << " " << y << " " << h;
        worst_m = std::max(worst_m, std::hypot(bx - x, by - y));
      }
    }
  }
  EXPECT_LT(worst_m, kRoundTripM);
  std::cout << "round trip worst error " << worst_m << " m\n";
}

TEST(FisheyeCamera, RejectsPointsBehindTheCamera) {
  const CameraModel m = NominalCamera({2.0, 1.5, 3.1}, 120.0, 1280, 960);
  double u = -1, v = -1;
  EXPECT_FALSE(m.ProjectToPixel(Eigen::Vector3d(2.0, 1.5, 3.5), &u, &v));  // above
  EXPECT_FALSE(m.ProjectToPixel(Eigen::Vector3d(5.0, 1.5, 3.1), &u, &v));  // in its plane
  EXPECT_FALSE(m.ProjectToPixel(m.pose.position_m, &u, &v));               // at the centre
  EXPECT_EQ(u, -1);
  EXPECT_EQ(v, -1);
  // The inverse: a plane above the camera, a pixel off the image.
  double x, y;
  EXPECT_FALSE(m.PixelToFloor(640, 480, 3.5, &x, &y));
  EXPECT_FALSE(m.PixelToFloor(640, 480, 3.1, &x, &y));
  EXPECT_FALSE(m.PixelToFloor(-10, 480, 0.0, &x, &y));
  EXPECT_FALSE(m.PixelToFloor(640, 960 + 10, 0.0, &x, &y));
  EXPECT_FALSE(m.PixelToFloor(std::nan(""), 480, 0.0, &x, &y));
  EXPECT_TRUE(m.PixelToFloor(m.intrinsics.cx_px, m.intrinsics.cy_px, 0.0, &x, &y));
  EXPECT_NEAR(x, 2.0, kExactM);  // the principal point looks straight down
  EXPECT_NEAR(y, 1.5, kExactM);
}

TEST(FisheyeCamera, NominalCameraCoversTheFloorFromTheCeilingWithA120DegreeLens) {
  const CameraModel m = NominalCamera({2.0, 1.5, 3.1}, 120.0, 1280, 960);
  // f = 640 px / (60 degrees in radians).
  EXPECT_NEAR(m.intrinsics.fx_px, 640.0 / (M_PI / 3), kClosedFormPx);
  EXPECT_NEAR(m.pose.R_room_from_camera.determinant(), 1.0, kRotationDeterminant);
  // Looking down; image x along room x, image y along room -y.
  EXPECT_TRUE((m.pose.R_room_from_camera.col(2) - Eigen::Vector3d(0, 0, -1)).norm() < 1e-12);
  for (double x : {0.0, 4.0}) {
    for (double y : {0.0, 3.0}) {
      double u, v;
      ASSERT_TRUE(m.ProjectToPixel(Eigen::Vector3d(x, y, 0.0), &u, &v));
      EXPECT_GT(u, 0);
      EXPECT_LT(u, 1280);
      EXPECT_GT(v, 0);
      EXPECT_LT(v, 960);
      std::cout << "floor corner (" << x << ", " << y << ") at pixel (" << u << ", " << v << ")\n";
    }
  }
  double u, v;
  ASSERT_TRUE(m.ProjectToPixel(Eigen::Vector3d(4.0, 3.0, 0.0), &u, &v));
  EXPECT_GT(u, m.intrinsics.cx_px);  // +x to the right
  EXPECT_LT(v, m.intrinsics.cy_px);  // +y up in the image
}

}  // namespace
}  // namespace roomfix::calib
