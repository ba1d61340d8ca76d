#include "core/calib/marker_projection.h"

#include <gtest/gtest.h>

#include <cmath>

namespace roomfix::calib {
namespace {

// The demo room's camera: a 120-degree lens 3.1 m above the middle of the
// 4 x 3 m floor, 1920 x 1080 px; markers 10 cm across, 0.2 m up.
constexpr double kMarkerRadiusM = 0.05;
constexpr double kMarkerHeightM = 0.2;

CameraModel DemoCamera() { return NominalCamera({2.0, 1.5, 3.1}, 120.0, 1920, 1080); }

// The disc's image centroid by brute force: every pixel of a box around the
// disc, split into n x n subsamples, each traced back to the marker plane.
Eigen::Vector2d BruteForceCentroid(const CameraModel& camera, const Eigen::Vector3d& centre,
                                   double radius_m, int n) {
  double u0 = 0, v0 = 0;
  camera.ProjectToPixel(centre, &u0, &v0);
  const int half = 40;
  double sum = 0, su = 0, sv = 0;
  for (int v = static_cast<int>(v0) - half; v <= static_cast<int>(v0) + half; ++v) {
    for (int u = static_cast<int>(u0) - half; u <= static_cast<int>(u0) + half; ++u) {
      for (int j = 0; j < n; ++j) {
        for (int i = 0; i < n; ++i) {
          const double su_px = u - 0.5 + (i + 0.5) / n;
          const double sv_px = v - 0.5 + (j + 0.5) / n;
          double x = 0, y = 0;
          if (!camera.PixelToFloor(su_px, sv_px, centre.z(), &x, &y)) continue;
          if (std::hypot(x - centre.x(), y - centre.y()) <= radius_m) {
            sum += 1;
            su += su_px;
            sv += sv_px;
          }
        }
      }
    }
  }
  return Eigen::Vector2d(su / sum, sv / sum);
}

TEST(DiscCentroidOffset, IsZeroStraightBelowTheCamera) {
  // Below the lens the disc images as a circle centred on its centre.
  constexpr double kTolerancePx = 1e-9;
  Eigen::Vector2d offset;
  ASSERT_TRUE(DiscCentroidOffset(DemoCamera(), Eigen::Vector3d(2.0, 1.5, kMarkerHeightM),
                                 kMarkerRadiusM, &offset));
  EXPECT_NEAR(offset.norm(), 0.0, kTolerancePx);
}

TEST(DiscCentroidOffset, MatchesASupersampledImageOfTheDiscInTheCorner) {
  // The polygon's shoelace centroid equals the centroid of the rendered
  // coverage, and the offset is a sizeable fraction of a pixel in a floor
  // corner.
  constexpr double kTolerancePx = 0.01;
  constexpr double kMinimumCornerOffsetPx = 0.05;
  const CameraModel camera = DemoCamera();
  for (const Eigen::Vector3d& centre :
       {Eigen::Vector3d(0.3, 0.3, kMarkerHeightM), Eigen::Vector3d(3.6, 2.7, kMarkerHeightM),
        Eigen::Vector3d(1.0, 2.0, kMarkerHeightM)}) {
    Eigen::Vector2d offset;
    ASSERT_TRUE(DiscCentroidOffset(camera, centre, kMarkerRadiusM, &offset));
    double u0 = 0, v0 = 0;
    camera.ProjectToPixel(centre, &u0, &v0);
    const Eigen::Vector2d brute =
        BruteForceCentroid(camera, centre, kMarkerRadiusM, 8) - Eigen::Vector2d(u0, v0);
    EXPECT_NEAR(offset.x(), brute.x(), kTolerancePx) << centre.transpose();
    EXPECT_NEAR(offset.y(), brute.y(), kTolerancePx) << centre.transpose();
    if (centre.x() < 0.5 || centre.x() > 3.5) {
      EXPECT_GT(offset.norm(), kMinimumCornerOffsetPx) << centre.transpose();
    }
  }
}

TEST(DiscCentroidToFloor, RecoversTheDiscCentreFromItsImageCentroid) {
  // PixelToFloor of the raw centroid is off by the offset (millimetres in
  // the corners); the corrected mapping returns the centre to 0.05 mm.
  constexpr double kToleranceM = 5e-5;
  const CameraModel camera = DemoCamera();
  const Eigen::Vector3d centre(0.3, 0.3, kMarkerHeightM);
  const Eigen::Vector2d centroid = BruteForceCentroid(camera, centre, kMarkerRadiusM, 8);
  double x = 0, y = 0;
  ASSERT_TRUE(DiscCentroidToFloor(camera, centroid.x(), centroid.y(), kMarkerRadiusM,
                                  kMarkerHeightM, &x, &y));
  EXPECT_NEAR(x, centre.x(), kToleranceM);
  EXPECT_NEAR(y, centre.y(), kToleranceM);
  double raw_x = 0, raw_y = 0;
  ASSERT_TRUE(camera.PixelToFloor(centroid.x(), centroid.y(), kMarkerHeightM, &raw_x, &raw_y));
  std::printf("corner marker: uncorrected error %.2f mm, corrected %.3f mm\n",
              1e3 * std::hypot(raw_x - centre.x(), raw_y - centre.y()),
              1e3 * std::hypot(x - centre.x(), y - centre.y()));
}

}  // namespace
}  // namespace roomfix::calib
