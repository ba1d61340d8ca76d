// FindCameraStart: a ceiling camera's start from the floor points alone, and
// the full fit from it, for a tilted and off-centre camera as for a perfect
// one; and the point sets it refuses.
#include "core/calib/camera_start.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <iostream>
#include <random>
#include <vector>

#include "core/calib/camera_fit.h"
#include "core/calib/fisheye_camera.h"

namespace roomfix::calib {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr int kWidthPx = 1920, kHeightPx = 1080;
constexpr double kNominalFovDeg = 120.0;
// The pixel noise of a detected marker or corner (the condition).
constexpr double kPixelNoisePx = 0.3;

// A real lens behind the nominal one: focal length 4 % long, principal
// point off the centre, barrel distortion; looking down from `position`
// after turning by `tilt_deg` about the axis `tilt_axis` (room frame).
CameraModel TrueCamera(const Eigen::Vector3d& position, double tilt_deg,
                       const Eigen::Vector3d& tilt_axis) {
  CameraModel m = NominalCamera({0, 0, 0}, kNominalFovDeg, kWidthPx, kHeightPx);
  m.intrinsics.fx_px *= 1.04;
  m.intrinsics.fy_px *= 1.04;
  m.intrinsics.cx_px += 6.0;
  m.intrinsics.cy_px -= 4.0;
  m.intrinsics.k = {0.02, -0.01, 0.0, 0.0};
  m.pose.R_room_from_camera =
      Eigen::AngleAxisd(tilt_deg * kPi / 180, tilt_axis.normalized()).toRotationMatrix() *
      m.pose.R_room_from_camera;
  m.pose.position_m = position;
  return m;
}

// The demo room's ceiling camera: centred 3.1 m over the 4 x 3 m floor,
// straight down.
CameraModel PerfectCamera() { return TrueCamera({2.0, 1.5, 3.1}, 0.0, {1, 0, 0}); }

// The same lens 1 m off centre (over x = 3 m) and tilted 15 degrees back
// towards the room's middle, plus 5 degrees about the other axis.
CameraModel TiltedOffCentreCamera() {
  CameraModel m = TrueCamera({3.0, 1.5, 3.1}, 15.0, {0, 1, 0});
  m.pose.R_room_from_camera =
      Eigen::AngleAxisd(5.0 * kPi / 180, Eigen::Vector3d::UnitX()).toRotationMatrix() *
      m.pose.R_room_from_camera;
  return m;
}

// Floor points every `step_m` over the 4 x 3 m room that the camera sees,
// at `height_m` (or alternating 0.0 and 0.5 m when height_m < 0), with
// Gaussian pixel noise.
std::vector<Correspondence> SeenPoints(const CameraModel& camera, double step_m, double height_m,
                                       unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, kPixelNoisePx);
  std::vector<Correspondence> out;
  int k = 0;
  for (double x = 0.2; x < 4.0; x += step_m) {
    for (double y = 0.2; y < 3.0; y += step_m, ++k) {
      const double h = height_m >= 0 ? height_m : (k % 2 == 0 ? 0.0 : 0.5);
      double u, v;
      if (!camera.ProjectToPixel(Eigen::Vector3d(x, y, h), &u, &v)) continue;
      if (u < 5 || v < 5 || u > kWidthPx - 5 || v > kHeightPx - 5) continue;
      out.push_back({u + noise(rng), v + noise(rng), x, y, h});
    }
  }
  return out;
}

// RMS floor error of the fitted model over the floor points (every 10 cm)
// that the true camera sees at height h.
double MappingRmsM(const CameraModel& truth, const CameraModel& fitted, double h) {
  double sum2 = 0;
  int n = 0;
  for (double x = 0.2; x < 4.0; x += 0.1) {
    for (double y = 0.2; y < 3.0; y += 0.1) {
      double u, v, mx, my;
      if (!truth.ProjectToPixel(Eigen::Vector3d(x, y, h), &u, &v)) continue;
      if (u < 5 || v < 5 || u > kWidthPx - 5 || v > kHeightPx - 5) continue;
      if (!fitted.PixelToFloor(u, v, h, &mx, &my)) return INFINITY;
      sum2 += std::pow(mx - x, 2) + std::pow(my - y, 2);
      ++n;
    }
  }
  return n > 0 ? std::sqrt(sum2 / n) : INFINITY;
}

// roomfix calibrate's options: one focal length, k1 and k2, no mount.
CameraFitOptions CliOptions() {
  CameraFitOptions o;
  o.equal_focal_lengths = true;
  o.distortion_terms = 2;
  return o;
}

double AngleBetweenDeg(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) {
  return Eigen::AngleAxisd(a.transpose() * b).angle() * 180 / kPi;
}

const CameraModel kNominal = NominalCamera({0, 0, 1}, kNominalFovDeg, kWidthPx, kHeightPx);

// The start alone: within a few centimetres and a degree of the truth for
// either camera (the equidistant lens without k1, k2 is a few pixels off).
TEST(CameraStart, FindsATiltedOffCentreCameraFromTheFloorPointsAlone) {
  constexpr double kStartPositionM = 0.10;
  constexpr double kStartAngleDeg = 1.5;
  for (const CameraModel& truth : {PerfectCamera(), TiltedOffCentreCamera()}) {
    const auto points = SeenPoints(truth, 0.4, 0.0, 1);
    const CameraStart start = FindCameraStart(points, kNominal);
    ASSERT_TRUE(start.usable) << start.message;
    const double dp = (start.model.pose.position_m - truth.pose.position_m).norm();
    const double da =
        AngleBetweenDeg(start.model.pose.R_room_from_camera, truth.pose.R_room_from_camera);
    std::cout << points.size() << " points: " << start.message << "; " << dp * 1e3 << " mm and "
              << da << " deg from the truth\n";
    EXPECT_LT(dp, kStartPositionM);
    EXPECT_LT(da, kStartAngleDeg);
  }
  // Every point at its own height (0 to 0.5 m): no plane, so SQPnP on all.
  const CameraModel truth = TiltedOffCentreCamera();
  auto points = SeenPoints(truth, 0.4, 0.0, 2);
  for (size_t i = 0; i < points.size(); ++i) {
    Correspondence& c = points[i];
    c.height_m = 0.5 * static_cast<double>(i) / static_cast<double>(points.size());
    ASSERT_TRUE(truth.ProjectToPixel(Eigen::Vector3d(c.x_m, c.y_m, c.height_m), &c.u_px, &c.v_px));
  }
  const CameraStart start = FindCameraStart(points, kNominal);
  ASSERT_TRUE(start.usable) << start.message;
  std::cout << "scattered heights: " << start.message << "\n";
  EXPECT_LT((start.model.pose.position_m - truth.pose.position_m).norm(), kStartPositionM);
  EXPECT_LT(AngleBetweenDeg(start.model.pose.R_room_from_camera, truth.pose.R_room_from_camera),
            kStartAngleDeg);
}

// The full fit from that start, without any mount: a tilted, off-centre
// camera maps the floor as well as a perfect one. Points at two heights
// (0.0 and 0.5 m alternating) fix the camera's height (camera_fit.h), so
// every height maps; points at one height map that height.
TEST(CameraStart, ATiltedOffCentreCameraCalibratesAsWellAsAPerfectOne) {
  // "As well": within 30 % (plus 0.2 mm for the noise draw) of the perfect
  // camera's error, and within the millimetre budget of camera_fit.h.
  constexpr double kRelative = 1.3;
  constexpr double kAbsoluteSlackM = 0.0002;
  constexpr double kBudgetM = 0.003;
  struct Case {
    const char* name;
    double height_m;  // < 0: two heights
    std::vector<double> mapped_heights;
  };
  for (const Case& c :
       {Case{"two heights", -1.0, {0.0, 0.2, 0.5}}, Case{"one height", 0.2, {0.2}}}) {
    double perfect_rms[3] = {0, 0, 0};
    for (int which = 0; which < 2; ++which) {
      const CameraModel truth = which == 0 ? PerfectCamera() : TiltedOffCentreCamera();
      const auto points = SeenPoints(truth, 0.4, c.height_m, 7);
      const CameraStart start = FindCameraStart(points, kNominal);
      ASSERT_TRUE(start.usable) << start.message;
      const CameraFitSummary fit = FitCamera(points, start.model, CliOptions());
      ASSERT_TRUE(fit.usable) << fit.message;
      EXPECT_LT(fit.rms_px, 1.5 * kPixelNoisePx) << c.name;
      for (size_t k = 0; k < c.mapped_heights.size(); ++k) {
        const double rms = MappingRmsM(truth, fit.model, c.mapped_heights[k]);
        std::cout << c.name << ", " << (which == 0 ? "perfect" : "tilted 15+5 deg, 1 m off")
                  << " camera, " << points.size() << " points: " << fit.message << "; floor at "
                  << c.mapped_heights[k] << " m: RMS " << rms * 1e3 << " mm\n";
        if (which == 0) {
          perfect_rms[k] = rms;
          EXPECT_LT(rms, kBudgetM) << c.name;
        } else {
          EXPECT_LT(rms, kRelative * perfect_rms[k] + kAbsoluteSlackM) << c.name;
          EXPECT_LT(rms, kBudgetM) << c.name;
        }
      }
    }
  }
}

// A field of view 30 % off either way still starts the fit: the focal-length
// search covers 0.6-1.67 times the nominal focal length.
TEST(CameraStart, CopesWithANominalFieldOfViewThirtyPercentOff) {
  const CameraModel truth = TiltedOffCentreCamera();
  const auto points = SeenPoints(truth, 0.4, -1.0, 3);
  for (const double fov : {90.0, 160.0}) {
    const CameraStart start =
        FindCameraStart(points, NominalCamera({0, 0, 1}, fov, kWidthPx, kHeightPx));
    ASSERT_TRUE(start.usable) << start.message;
    const CameraFitSummary fit = FitCamera(points, start.model, CliOptions());
    ASSERT_TRUE(fit.usable) << fov << ": " << fit.message;
    EXPECT_LT(fit.rms_px, 1.5 * kPixelNoisePx) << fov;
    EXPECT_LT(MappingRmsM(truth, fit.model, 0.2), 0.003) << fov;
  }
}

// Each refusal is one line saying what is wrong with the points.
TEST(CameraStart, RefusesPointSetsThatCannotPlaceTheCamera) {
  const CameraModel truth = TiltedOffCentreCamera();
  const auto good = SeenPoints(truth, 0.4, 0.0, 5);
  ASSERT_GE(good.size(), 30u);

  const std::vector<Correspondence> few(good.begin(), good.begin() + 9);
  EXPECT_EQ(FindCameraStart(few, kNominal).message, "too few points: need at least 10, got 9");

  std::vector<Correspondence> line;
  for (int i = 0; i < 12; ++i) {
    double u, v;
    ASSERT_TRUE(truth.ProjectToPixel(Eigen::Vector3d(0.5 + 0.25 * i, 1.2, 0.0), &u, &v));
    line.push_back({u, v, 0.5 + 0.25 * i, 1.2, 0.0});
  }
  EXPECT_EQ(FindCameraStart(line, kNominal).message.rfind("all points lie on a line", 0), 0u)
      << FindCameraStart(line, kNominal).message;

  // A 12 x 12 cm patch of 16 markers near the middle of the floor: 0.8 deg
  // of view (standard deviation across it).
  std::vector<Correspondence> patch;
  for (int i = 0; i < 4; ++i) {
    for (int j = 0; j < 4; ++j) {
      const double x = 2.3 + 0.04 * i, y = 1.4 + 0.04 * j;
      double u, v;
      ASSERT_TRUE(truth.ProjectToPixel(Eigen::Vector3d(x, y, 0.0), &u, &v));
      patch.push_back({u, v, x, y, 0.0});
    }
  }
  const CameraStart small = FindCameraStart(patch, kNominal);
  EXPECT_FALSE(small.usable);
  EXPECT_EQ(small.message.rfind("all points lie in one small patch of the image", 0), 0u)
      << small.message;

  // The same floor with y negated: a mirror image, which only a camera
  // under the floor would see.
  std::vector<Correspondence> mirrored = good;
  for (auto& c : mirrored) c.y_m = -c.y_m;
  const CameraStart below = FindCameraStart(mirrored, kNominal);
  EXPECT_FALSE(below.usable);
  EXPECT_TRUE(below.mirrored);
  EXPECT_EQ(below.message.rfind("the points put the camera below them", 0), 0u) << below.message;
  std::cout << below.message << "\n" << small.message << "\n";

  // One height entered wrong, above the camera the other points place.
  std::vector<Correspondence> high = good;
  high[7].height_m = 3.5;
  EXPECT_EQ(FindCameraStart(high, kNominal)
                .message.rfind("point 7: height 3.5 m is inconsistent: "
                               "the points place the camera at z = 3.",
                               0),
            0u)
      << FindCameraStart(high, kNominal).message;

  // The image size is checked before anything is solved.
  std::vector<Correspondence> outside = good;
  outside[3].u_px = kWidthPx + 50;
  EXPECT_EQ(FindCameraStart(outside, kNominal).message.rfind("point 3: pixel (1970, ", 0), 0u);
}

}  // namespace
}  // namespace roomfix::calib
