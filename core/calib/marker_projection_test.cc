#include "core/calib/marker_projection.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

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

// The tripod procedure on an exact camera: each marker's image centroid
// (the disc's, not its centre's) at a 0.25 m grid of the demo floor.
std::vector<Correspondence> TripodCentroids(const CameraModel& camera) {
  std::vector<Correspondence> points;
  for (double x = 0.25; x < 3.9; x += 0.25) {
    for (double y = 0.25; y < 2.9; y += 0.25) {
      const Eigen::Vector3d centre(x, y, kMarkerHeightM);
      Eigen::Vector2d offset;
      double u = 0, v = 0;
      if (!camera.ProjectToPixel(centre, &u, &v) ||
          !DiscCentroidOffset(camera, centre, kMarkerRadiusM, &offset)) {
        continue;
      }
      points.push_back({u + offset.x(), v + offset.y(), x, y, kMarkerHeightM, kMarkerRadiusM});
    }
  }
  return points;
}

// The largest floor error over the points when camera_proc maps each
// centroid with the disc correction through `fitted`.
double WorstDiscMappingErrorM(const CameraModel& fitted,
                              const std::vector<Correspondence>& points) {
  double worst = 0.0;
  for (const Correspondence& p : points) {
    double x = 0, y = 0;
    EXPECT_TRUE(DiscCentroidToFloor(fitted, p.u_px, p.v_px, p.disc_radius_m, p.height_m, &x, &y));
    worst = std::max(worst, std::hypot(x - p.x_m, y - p.y_m));
  }
  return worst;
}

TEST(FitCameraToMarkers, FitsTheLensThatImagesTheDiscCentres) {
  // Fitted to the raw centroids, the lens absorbs the disc offsets, and
  // camera_proc's correction then counts them twice: in the demo room's
  // corners that is tenths of a millimetre, well above the exact data's
  // nothing. Fitted to the centres, the mapping is exact to the fit's
  // convergence (1e-5 m, far below any centroid noise).
  constexpr double kExactToleranceM = 1e-5;
  constexpr double kDoubleCountedAtLeastM = 1e-4;
  const CameraModel truth = DemoCamera();
  const std::vector<Correspondence> points = TripodCentroids(truth);
  ASSERT_GT(points.size(), 100u);
  CameraFitOptions options;
  options.equal_focal_lengths = true;
  options.distortion_terms = 2;
  const CameraModel start = NominalCamera({2.01, 1.49, 3.12}, 118.0, 1920, 1080);
  const CameraFitSummary raw = FitCamera(points, start, options);
  const CameraFitSummary centres = FitCameraToMarkers(points, start, options);
  ASSERT_TRUE(raw.usable) << raw.message;
  ASSERT_TRUE(centres.usable) << centres.message;
  const double raw_worst_m = WorstDiscMappingErrorM(raw.model, points);
  const double centres_worst_m = WorstDiscMappingErrorM(centres.model, points);
  std::printf("worst mapped marker: raw-centroid fit %.3f mm, disc-centre fit %.5f mm\n",
              1e3 * raw_worst_m, 1e3 * centres_worst_m);
  EXPECT_GT(raw_worst_m, kDoubleCountedAtLeastM);
  EXPECT_LT(centres_worst_m, kExactToleranceM);
}

TEST(FitCameraToMarkers, IsFitCameraWhenNoPointIsADisc) {
  std::vector<Correspondence> points = TripodCentroids(DemoCamera());
  for (Correspondence& p : points) p.disc_radius_m = 0.0;
  CameraFitOptions options;
  options.equal_focal_lengths = true;
  const CameraModel start = NominalCamera({2.0, 1.5, 3.1}, 120.0, 1920, 1080);
  const CameraFitSummary a = FitCamera(points, start, options);
  const CameraFitSummary b = FitCameraToMarkers(points, start, options);
  EXPECT_EQ(a.rms_px, b.rms_px);
  EXPECT_EQ(a.iterations, b.iterations);
}

}  // namespace
}  // namespace roomfix::calib
