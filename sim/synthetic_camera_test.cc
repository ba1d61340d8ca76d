#include "sim/synthetic_camera.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>
#include <string>
#include <vector>

#include "tests/testing/demo_site.h"
#include "tests/testing/test_paths.h"

namespace roomfix::sim {
namespace {

// The truth centroid against an independent 16 x 16 brute force: the ray
// map's bilinear interpolation and 8 x 8 coverage agree with exact rays to
// this (the header promises ~0.01 px).
constexpr double kCentroidTolerancePx = 0.01;
// The marker's area against the brute force, relative.
constexpr double kAreaRelativeTolerance = 0.005;
// A perspective bias of a 10 cm disc 20 cm above the floor is a fraction of
// a pixel; at the image centre it vanishes by symmetry (to rounding).
constexpr double kMaxBiasPx = 1.0;
constexpr double kCentreBiasPx = 1e-3;
// Gains measured on a flat floor patch: the 8-bit rounding of one DN over a
// brightness of ~160.
constexpr double kGainTolerance = 0.01;
// Measured sigma of noise over a 60 x 60 patch (10800 samples per channel:
// the estimate's own spread is sigma / sqrt(2 N) ~ 0.7 %; rounding to 8 bits
// adds 1/12 DN^2 of variance).
constexpr double kSigmaTolerance = 0.1;
// Positions the renderer computes in closed form (a marker offset by
// cos/sin, a row's time times a speed): only double rounding of values ~1 m.
constexpr double kClosedFormM = 1e-12;
constexpr double kClosedFormRad = 1e-12;
constexpr double kClosedFormS = 1e-12;
// A grid line 3 px wide is anti-aliased: its centre pixel is not all line
// colour, the floor's colour bleeds in by up to 12 DN.
constexpr double kGridLineDn = 12.0;
// One 8-bit code, the rounding of a rendered pixel against a value computed
// in double (flicker, wear, sheen blends).
constexpr double kOneCodeDn = 1.0;
// Bayer mosaic demosaiced by OpenCV's bilinear code: on a flat colour the
// neighbours' interpolation adds up to two codes of rounding.
constexpr double kDemosaicFlatDn = 2.0;
// A ratio of two patch means (8-bit codes near 100..200): 1 % each, 2 %
// for the ratio.
constexpr double kPatchRatioTolerance = 0.02;
// The mean of 3600 noisy samples against the noise-free floor colour: the
// mean's own spread is sigma / 60 ~ 0.03 DN, rounding to codes averages out.
constexpr double kNoiseMeanDn = 0.1;
// A symmetric blur or an effect switched off moves a coverage centroid by
// 8-bit rounding of the rim only: a few hundredths of a pixel.
constexpr double kCentroidStaysPx = 0.05;
// Two renders of the same marker through different paths (rolling shutter
// against a still marker placed at the row's time; the streak against the
// marker's mid-exposure projection): the 8 x 8 coverage sampling's
// quantisation, ~0.01 px, with a margin.
constexpr double kSameMarkerPx = 0.02;
// A centroid from coverage moments of 8-bit colours against the truth's
// exact centroid, inside a motion streak's soft edges.
constexpr double kCoverageCentroidPx = 0.1;

struct Demo {
  Site site;
  Camera camera;
  calib::CameraModel model;
};

const Demo& DemoRoom() {
  static const Demo* demo = [] {
    auto* d = new Demo;
    std::string error;
    const std::string path = testing::DemoSitePath();
    if (!LoadSite(path, &d->site, &error)) {
      ADD_FAILURE() << error;
      return d;
    }
    d->camera = d->site.cameras.at(0);
    d->model = calib::NominalCamera(d->camera.mount_position_m, d->camera.field_of_view_deg,
                                    d->camera.width_px, d->camera.height_px);
    return d;
  }();
  return *demo;
}

const SyntheticCamera& CleanCamera() {
  static const SyntheticCamera* camera = [] {
    const Demo& d = DemoRoom();
    return new SyntheticCamera(d.site, d.camera, d.model, SimScenario{});
  }();
  return *camera;
}

cv::Point Pixel(const calib::CameraModel& model, double x, double y, double z) {
  double u = 0, v = 0;
  EXPECT_TRUE(model.ProjectToPixel(Eigen::Vector3d(x, y, z), &u, &v));
  return cv::Point(static_cast<int>(std::lround(u)), static_cast<int>(std::lround(v)));
}

// Mean of a (2 half + 1)^2 patch, all channels.
double PatchMean(const cv::Mat& image, cv::Point centre, int half) {
  const cv::Rect r(centre.x - half, centre.y - half, 2 * half + 1, 2 * half + 1);
  const cv::Scalar m = cv::mean(image(r));
  return (m[0] + m[1] + m[2]) / 3.0;
}

bool InClassRange(const cv::Vec3b& bgr, const MarkerClass& c) {
  cv::Mat px(1, 1, CV_8UC3, cv::Scalar(bgr[0], bgr[1], bgr[2]));
  cv::Mat hsv;
  cv::cvtColor(px, hsv, cv::COLOR_BGR2HSV);
  const cv::Vec3b p = hsv.at<cv::Vec3b>(0, 0);
  for (int i = 0; i < 3; ++i) {
    if (p[i] < c.hsv_min[i] || p[i] > c.hsv_max[i]) return false;
  }
  return true;
}

const MarkerClass& Class(const std::string& name) {
  for (const auto& c : DemoRoom().camera.marker_classes) {
    if (c.name == name) return c;
  }
  ADD_FAILURE() << name;
  return DemoRoom().camera.marker_classes.at(0);
}

// Coverage-weighted centroid of a disc by brute force: 16 x 16 subsamples
// per pixel, each through CameraModel::PixelToRay (no ray map).
void BruteForceCentroid(const calib::CameraModel& model, double cx, double cy, double z, double r,
                        double* cu, double* cv_px, double* area) {
  double u_min = 1e9, u_max = -1e9, v_min = 1e9, v_max = -1e9;
  for (int k = 0; k < 64; ++k) {
    const double phi = 2 * M_PI * k / 64;
    double u, v;
    ASSERT_TRUE(model.ProjectToPixel(
        Eigen::Vector3d(cx + r * std::cos(phi), cy + r * std::sin(phi), z), &u, &v));
    u_min = std::min(u_min, u), u_max = std::max(u_max, u);
    v_min = std::min(v_min, v), v_max = std::max(v_max, v);
  }
  constexpr int kSub = 16;
  double sum = 0, su = 0, sv = 0;
  for (int j = static_cast<int>(v_min) - 2; j <= static_cast<int>(v_max) + 2; ++j) {
    for (int i = static_cast<int>(u_min) - 2; i <= static_cast<int>(u_max) + 2; ++i) {
      int hits = 0;
      for (int sj = 0; sj < kSub; ++sj) {
        for (int si = 0; si < kSub; ++si) {
          Eigen::Vector3d ray;
          ASSERT_TRUE(
              model.PixelToRay(i - 0.5 + (si + 0.5) / kSub, j - 0.5 + (sj + 0.5) / kSub, &ray));
          const Eigen::Vector3d d = model.pose.R_room_from_camera * ray;
          const double t = (z - model.pose.position_m.z()) / d.z();
          const double x = model.pose.position_m.x() + t * d.x() - cx;
          const double y = model.pose.position_m.y() + t * d.y() - cy;
          if (x * x + y * y <= r * r) ++hits;
        }
      }
      const double c = static_cast<double>(hits) / (kSub * kSub);
      sum += c;
      su += c * i;
      sv += c * j;
    }
  }
  *area = sum;
  *cu = su / sum;
  *cv_px = sv / sum;
}

TEST(SyntheticCamera, RendersAtTheCameraResolutionAsBgr8) {
  cv::Mat image;
  CleanCamera().Render(0.0, 0, {}, &image);
  EXPECT_EQ(image.cols, 1920);
  EXPECT_EQ(image.rows, 1080);
  EXPECT_EQ(image.type(), CV_8UC3);
  EXPECT_EQ(CleanCamera().width_px(), 1920);
  EXPECT_EQ(CleanCamera().height_px(), 1080);
}

TEST(SyntheticCamera, GridLineAppearsWhereTheModelProjectsIt) {
  const SyntheticCameraOptions defaults;
  cv::Mat image;
  CleanCamera().Render(0.0, 0, {}, &image);
  // On the line x = 1.0 m (3 px wide under the camera): grid colour.
  const cv::Vec3b line = image.at<cv::Vec3b>(Pixel(DemoRoom().model, 1.0, 1.25, 0.0));
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(line[c], defaults.grid_bgr[c], kGridLineDn) << c;
  // Half a cell away, in the middle of a cell: the floor colour exactly.
  const cv::Vec3b floor = image.at<cv::Vec3b>(Pixel(DemoRoom().model, 1.25, 1.25, 0.0));
  for (int c = 0; c < 3; ++c) EXPECT_EQ(floor[c], defaults.floor_bgr[c]) << c;
  // Outside the room: the darker wall colour.
  const cv::Vec3b wall = image.at<cv::Vec3b>(Pixel(DemoRoom().model, -0.3, 1.25, 0.0));
  EXPECT_LT(wall[1], floor[1] * 0.7);
}

class TruthCentroid : public ::testing::TestWithParam<std::pair<double, double>> {};

TEST_P(TruthCentroid, MatchesBruteForceWithExactRays) {
  const auto [x, y] = GetParam();
  cv::Mat image;
  std::vector<MarkerTruth> truth;
  CleanCamera().Render(0.0, 0, {{1, x, y, 0.0}}, &image, &truth);
  ASSERT_EQ(truth.size(), 2u);
  for (const MarkerTruth& t : truth) {
    SCOPED_TRACE(t.colour_class);
    double cu = 0, cv_px = 0, area = 0;
    BruteForceCentroid(DemoRoom().model, t.x_m, t.y_m, t.z_m,
                       0.5 * Class(t.colour_class).diameter_m, &cu, &cv_px, &area);
    std::printf(
        "marker %s at (%.2f, %.2f): truth centroid (%.4f, %.4f) brute force (%.4f, %.4f)"
        " diff (%.5f, %.5f) px, area %.2f vs %.2f px, bias %.4f px\n",
        t.colour_class.c_str(), t.x_m, t.y_m, t.centroid_u_px, t.centroid_v_px, cu, cv_px,
        t.centroid_u_px - cu, t.centroid_v_px - cv_px, t.area_px, area,
        std::hypot(t.centroid_u_px - t.u_px, t.centroid_v_px - t.v_px));
    EXPECT_NEAR(t.centroid_u_px, cu, kCentroidTolerancePx);
    EXPECT_NEAR(t.centroid_v_px, cv_px, kCentroidTolerancePx);
    EXPECT_NEAR(t.area_px, area, kAreaRelativeTolerance * area);
    EXPECT_TRUE(t.visible);
  }
}

INSTANTIATE_TEST_SUITE_P(CentreAndCorner, TruthCentroid,
                         ::testing::Values(std::make_pair(2.0, 1.5), std::make_pair(0.3, 0.3),
                                           std::make_pair(3.7, 2.7)));

TEST(SyntheticCamera, TruthCentroidMatchesBruteForceThroughADistortedTiltedLens) {
  // A calibrated-looking model: distortion, unequal focal lengths, an
  // off-centre principal point and a 1-degree tilt.
  const Demo& d = DemoRoom();
  calib::CameraModel lens = d.model;
  lens.intrinsics.fx_px = 905.0;
  lens.intrinsics.fy_px = 900.0;
  lens.intrinsics.cx_px = 955.0;
  lens.intrinsics.cy_px = 545.0;
  lens.intrinsics.k = {0.02, -0.01, 0.003, 0.0};
  lens.pose.R_room_from_camera =
      Eigen::AngleAxisd(0.0175, Eigen::Vector3d::UnitY()).toRotationMatrix() *
      lens.pose.R_room_from_camera;
  const SyntheticCamera camera(d.site, d.camera, lens, SimScenario{});
  for (const auto& [x, y] : {std::make_pair(2.0, 1.5), std::make_pair(0.3, 2.7)}) {
    cv::Mat image;
    std::vector<MarkerTruth> truth;
    camera.Render(0.0, 0, {{1, x, y, 0.3}}, &image, &truth);
    ASSERT_EQ(truth.size(), 2u);
    for (const MarkerTruth& t : truth) {
      double cu = 0, cv_px = 0, area = 0;
      BruteForceCentroid(lens, t.x_m, t.y_m, t.z_m, 0.5 * Class(t.colour_class).diameter_m, &cu,
                         &cv_px, &area);
      std::printf("distorted lens, %s at (%.2f, %.2f): diff (%.5f, %.5f) px\n",
                  t.colour_class.c_str(), t.x_m, t.y_m, t.centroid_u_px - cu,
                  t.centroid_v_px - cv_px);
      EXPECT_NEAR(t.centroid_u_px, cu, kCentroidTolerancePx);
      EXPECT_NEAR(t.centroid_v_px, cv_px, kCentroidTolerancePx);
      EXPECT_NEAR(t.area_px, area, kAreaRelativeTolerance * area);
    }
  }
}

TEST(SyntheticCamera, PerspectiveBiasIsBelowOnePixelAndVanishesAtTheCentre) {
  cv::Mat image;
  std::vector<MarkerTruth> centre, corner;
  CleanCamera().Render(0.0, 0, {{1, 2.0, 1.5, 0.0}}, &image, &centre);
  CleanCamera().Render(0.0, 0, {{1, 0.3, 0.3, 0.0}}, &image, &corner);
  ASSERT_FALSE(centre.empty());
  ASSERT_FALSE(corner.empty());
  // Camera at (2, 1.5): the position marker below it is symmetric.
  EXPECT_LT(std::hypot(centre[0].centroid_u_px - centre[0].u_px,
                       centre[0].centroid_v_px - centre[0].v_px),
            kCentreBiasPx);
  const double bias = std::hypot(corner[0].centroid_u_px - corner[0].u_px,
                                 corner[0].centroid_v_px - corner[0].v_px);
  EXPECT_GT(bias, 0.01);
  EXPECT_LT(bias, kMaxBiasPx);
}

TEST(SyntheticCamera, MarkerMiddleHasTheClassColour) {
  cv::Mat image;
  std::vector<MarkerTruth> truth;
  CleanCamera().Render(0.0, 0, {{1, 1.2, 0.9, 0.7}}, &image, &truth);
  ASSERT_EQ(truth.size(), 2u);
  for (const MarkerTruth& t : truth) {
    const cv::Vec3b p = image.at<cv::Vec3b>(static_cast<int>(std::lround(t.v_px)),
                                            static_cast<int>(std::lround(t.u_px)));
    EXPECT_TRUE(InClassRange(p, Class(t.colour_class)))
        << t.colour_class << " " << static_cast<int>(p[0]) << "," << static_cast<int>(p[1]) << ","
        << static_cast<int>(p[2]);
  }
  EXPECT_FALSE(truth[0].is_heading_marker);
  EXPECT_TRUE(truth[1].is_heading_marker);
  EXPECT_NEAR(truth[1].x_m, 1.2 + 0.1 * std::cos(0.7), kClosedFormM);
  EXPECT_NEAR(truth[1].y_m, 0.9 + 0.1 * std::sin(0.7), kClosedFormM);
  EXPECT_DOUBLE_EQ(truth[0].z_m, 0.20);
}

TEST(SyntheticCamera, FloorBrightnessFollowsTheGainSteps) {
  const Demo& d = DemoRoom();
  SimScenario s;
  s.gain_steps = {1.0, 1.4, 0.6};
  const SyntheticCamera camera(d.site, d.camera, d.model, s);
  const cv::Point flat = Pixel(d.model, 1.25, 1.25, 0.0);
  auto brightness = [&](double t) {
    cv::Mat image;
    camera.Render(t, 0, {}, &image);
    return PatchMean(image, flat, 5);
  };
  const double b0 = brightness(1.0);
  EXPECT_NEAR(brightness(2.9) / b0, 1.0, kGainTolerance);
  EXPECT_NEAR(brightness(3.25) / b0, 1.2, kGainTolerance);  // half-way up the ramp
  EXPECT_NEAR(brightness(4.0) / b0, 1.4, kGainTolerance);
  EXPECT_NEAR(brightness(7.0) / b0, 0.6, kGainTolerance);
  EXPECT_NEAR(brightness(10.0) / b0, 1.0, kGainTolerance);  // the cycle repeats
}

TEST(SyntheticCamera, GradientBrightensThePlusXSide) {
  const Demo& d = DemoRoom();
  SimScenario s;
  s.gradient = 0.3;
  const SyntheticCamera camera(d.site, d.camera, d.model, s);
  cv::Mat image;
  camera.Render(0.0, 0, {}, &image);
  const double low = PatchMean(image, Pixel(d.model, 0.25, 1.25, 0.0), 3);
  const double high = PatchMean(image, Pixel(d.model, 3.75, 1.25, 0.0), 3);
  EXPECT_GT(high, low);
  // Gains 1 - 0.3 * 0.875 and 1 + 0.3 * 0.875.
  EXPECT_NEAR(high / low, (1 + 0.2625) / (1 - 0.2625), kPatchRatioTolerance);
}

TEST(SyntheticCamera, FlickerMakesRowBands) {
  const Demo& d = DemoRoom();
  SimScenario s;
  s.flicker_amplitude = 0.1;
  const SyntheticCamera camera(d.site, d.camera, d.model, s);
  cv::Mat image;
  camera.Render(0.0, 0, {}, &image);
  // 100 Hz over 1125 rows of 1/30 s: a period of 337.5 rows.
  const double a = PatchMean(image, Pixel(d.model, 1.25, 1.25, 0.0), 0);
  cv::Mat clean;
  CleanCamera().Render(0.0, 0, {}, &clean);
  const cv::Point p = Pixel(d.model, 1.25, 1.25, 0.0);
  const double expected =
      PatchMean(clean, p, 0) * (1 + 0.1 * std::sin(2 * M_PI * 100 * p.y * s.row_time_s));
  EXPECT_NEAR(a, expected, kOneCodeDn);
}

TEST(SyntheticCamera, NoiseHasTheRequestedSigma) {
  const Demo& d = DemoRoom();
  SimScenario s;
  s.noise_sigma_dn = 2.0;
  const SyntheticCamera camera(d.site, d.camera, d.model, s);
  cv::Mat image;
  camera.Render(0.0, 5, {}, &image);
  const cv::Point c = Pixel(d.model, 1.75, 1.25, 0.0);
  const cv::Rect r(c.x - 30, c.y - 30, 60, 60);
  cv::Scalar mean, sigma;
  cv::meanStdDev(image(r), mean, sigma);
  const SyntheticCameraOptions defaults;
  for (int ch = 0; ch < 3; ++ch) {
    std::printf("channel %d: mean %.3f sigma %.3f DN\n", ch, mean[ch], sigma[ch]);
    EXPECT_NEAR(sigma[ch], std::sqrt(4.0 + 1.0 / 12.0), kSigmaTolerance);
    EXPECT_NEAR(mean[ch], defaults.floor_bgr[ch], kNoiseMeanDn);
  }
}

TEST(SyntheticCamera, SameSeedTimeAndFrameGiveTheSameImage) {
  const Demo& d = DemoRoom();
  SimScenario s;
  ASSERT_TRUE(ParseSimScenario("harsh", &s, nullptr));
  const SyntheticCamera a(d.site, d.camera, d.model, s);
  const SyntheticCamera b(d.site, d.camera, d.model, s);
  const std::vector<RobotState> robots = a.SimulatedRobots(2.5);
  cv::Mat ia, ib, ic;
  a.Render(2.5, 75, robots, &ia);
  b.Render(2.5, 75, robots, &ib);
  a.Render(2.5, 76, robots, &ic);
  EXPECT_EQ(cv::norm(ia, ib, cv::NORM_INF), 0.0);
  EXPECT_GT(cv::norm(ia, ic, cv::NORM_INF), 0.0);  // another frame, other noise
}

TEST(SyntheticCamera, DistractorsAppearWherePlaced) {
  const Demo& d = DemoRoom();
  SimScenario s;
  ASSERT_TRUE(ParseSimScenario("sim:distractors", &s, nullptr));
  ASSERT_EQ(s.distractors.size(), 3u);
  const SyntheticCamera camera(d.site, d.camera, d.model, s);
  cv::Mat image;
  std::vector<MarkerTruth> truth;
  camera.Render(0.0, 0, camera.SimulatedRobots(0.0), &image, &truth);
  int distractors = 0;
  for (const MarkerTruth& t : truth) {
    if (t.robot_id != -1) continue;
    ++distractors;
    EXPECT_TRUE(t.visible);
    EXPECT_EQ(t.z_m, 0.0);
    const cv::Vec3b p = image.at<cv::Vec3b>(Pixel(d.model, t.x_m, t.y_m, 0.0));
    EXPECT_TRUE(InClassRange(p, Class(t.colour_class))) << t.colour_class;
  }
  EXPECT_EQ(distractors, 3);
}

TEST(SyntheticCamera, SimulatedRobotsFollowTheSiteTrajectories) {
  const Demo& d = DemoRoom();
  ASSERT_EQ(d.site.simulation.robots.size(), 1u);
  const auto robots = CleanCamera().SimulatedRobots(4.0);
  ASSERT_EQ(robots.size(), 1u);
  const GroundTruthPose pose = d.site.simulation.robots[0].trajectory->PoseAt(4.0);
  EXPECT_EQ(robots[0].robot_id, 1);
  EXPECT_DOUBLE_EQ(robots[0].x_m, pose.x_m);
  EXPECT_DOUBLE_EQ(robots[0].y_m, pose.y_m);
  EXPECT_DOUBLE_EQ(robots[0].heading_rad, pose.heading_rad);
}

TEST(ParseSimScenario, KnowsTheScenarios) {
  SimScenario s;
  std::string error;
  ASSERT_TRUE(ParseSimScenario("clean", &s, &error));
  EXPECT_TRUE(s.distractors.empty());
  EXPECT_EQ(s.noise_sigma_dn, 0.0);
  ASSERT_TRUE(ParseSimScenario("sim:reference_circle", &s, &error));
  EXPECT_EQ(s.gain_steps, std::vector<double>{1.0});
  ASSERT_TRUE(ParseSimScenario("lighting", &s, &error));
  EXPECT_EQ(s.gain_steps, (std::vector<double>{1.0, 1.4, 0.6}));
  EXPECT_EQ(s.gradient, 0.3);
  EXPECT_EQ(s.flicker_amplitude, 0.1);
  EXPECT_EQ(s.flicker_hz, 100.0);
  EXPECT_EQ(s.noise_sigma_dn, 2.0);
  EXPECT_TRUE(s.distractors.empty());
  ASSERT_TRUE(ParseSimScenario("distractors", &s, &error));
  EXPECT_EQ(s.gain_steps, std::vector<double>{1.0});
  EXPECT_EQ(s.noise_sigma_dn, 2.0);
  EXPECT_EQ(s.distractors.size(), 3u);
  ASSERT_TRUE(ParseSimScenario("sim:harsh", &s, &error));
  EXPECT_EQ(s.gradient, 0.3);
  EXPECT_EQ(s.distractors.size(), 3u);
  EXPECT_EQ(s.name, "harsh");
}

TEST(ParseSimScenario, RejectsAnUnknownNameListingTheKnownOnes) {
  SimScenario s;
  std::string error;
  EXPECT_FALSE(ParseSimScenario("sim:foggy", &s, &error));
  EXPECT_NE(error.find("foggy"), std::string::npos);
  for (const char* name : {"clean", "reference_circle", "lighting", "distractors", "harsh"}) {
    EXPECT_NE(error.find(name), std::string::npos) << name;
  }
}

// A small camera for the sequence tests (the same room and lens).
SyntheticCamera SmallCamera() {
  const Demo& d = DemoRoom();
  Camera c = d.camera;
  c.width_px = 320;
  c.height_px = 180;
  return SyntheticCamera(d.site, c, calib::NominalCamera(c.mount_position_m, 120, 320, 180),
                         SimScenario{});
}

int CountLines(const std::string& path) {
  std::ifstream in(path);
  std::string line;
  int n = 0;
  while (std::getline(in, line)) ++n;
  return n;
}

TEST(WriteSequence, WritesFramesAndTruthIntoAFolder) {
  testing::TempDir dir;
  const SyntheticCamera camera = SmallCamera();
  SequenceOptions o;
  o.duration_s = 0.5;
  o.fps = 10;
  std::string error;
  const std::string out = dir.File("seq");
  ASSERT_TRUE(WriteSequence(camera, o, out, &error)) << error;
  for (int f = 0; f < 5; ++f) {
    const std::string name = fmt::format("/frame_{:06d}.jpg", f);
    EXPECT_TRUE(std::filesystem::exists(out + name)) << name;
  }
  EXPECT_FALSE(std::filesystem::exists(out + "/frame_000005.jpg"));
  // Header and two markers (position, heading) per frame.
  EXPECT_EQ(CountLines(out + "/truth.csv"), 1 + 5 * 2);
  const std::string csv = testing::ReadFile(out + "/truth.csv");
  EXPECT_EQ(csv.rfind("frame,t_s,utime,robot_id,colour_class,role,x_m,y_m,z_m,u_px,v_px,"
                      "centroid_u_px,centroid_v_px,visible,heading_rad,capture_utime,"
                      "exposure_mid_t_s,exposure_mid_x_m,exposure_mid_y_m,exposure_mid_z_m,"
                      "robot_x_m,robot_y_m,robot_heading_rad,robot_tilt_forward_rad,"
                      "robot_tilt_left_rad\n",
                      0),
            0u);
  EXPECT_NE(csv.find(",position,"), std::string::npos);
  EXPECT_NE(csv.find(",heading,"), std::string::npos);
}

TEST(WriteSequence, WritesAnAviThatVideoCaptureReadsBack) {
  testing::TempDir dir;
  const SyntheticCamera camera = SmallCamera();
  SequenceOptions o;
  o.duration_s = 0.6;
  o.fps = 10;
  std::string error;
  ASSERT_TRUE(WriteSequence(camera, o, dir.File("seq.avi"), &error)) << error;
  cv::VideoCapture capture(dir.File("seq.avi"));
  ASSERT_TRUE(capture.isOpened());
  int frames = 0;
  cv::Mat frame;
  while (capture.read(frame)) {
    EXPECT_EQ(frame.cols, 320);
    EXPECT_EQ(frame.rows, 180);
    ++frames;
  }
  EXPECT_EQ(frames, 6);
  EXPECT_EQ(CountLines(dir.File("seq_truth.csv")), 1 + 6 * 2);
}

TEST(WriteSequence, RefusesAnUnwritablePathOrUnknownExtension) {
  const SyntheticCamera camera = SmallCamera();
  SequenceOptions o;
  o.duration_s = 0.1;
  o.fps = 10;
  std::string error;
  EXPECT_FALSE(WriteSequence(camera, o, "/proc/roomfix_no_such/seq", &error));
  EXPECT_NE(error.find("/proc/roomfix_no_such/seq"), std::string::npos) << error;
  error.clear();
  EXPECT_FALSE(WriteSequence(camera, o, "/proc/roomfix_no_such/seq.avi", &error));
  EXPECT_FALSE(error.empty());
  testing::TempDir dir;
  error.clear();
  EXPECT_FALSE(WriteSequence(camera, o, dir.File("seq.mkv"), &error));
  EXPECT_NE(error.find(".mkv"), std::string::npos) << error;
}

// ---------------------------------------------------------------------------
// The webcam scenario.

// The lean is two rotations (forward, then left) whose horizontal offset is
// h sqrt(sin^2 l + cos^2 l sin^2 f), not h sin(hypot(f, l)): they differ by
// ~h f^2 l^2, under a micrometre at 2 degrees.
constexpr double kLeanCompositionM = 1e-6;

// The webcam scenario with every effect switched off: must render the clean
// image.
SimScenario WebcamAllOff() {
  SimScenario s;
  EXPECT_TRUE(ParseSimScenario("webcam", &s, nullptr));
  s.webcam = WithoutWebcamEffects(s.webcam);
  return s;
}

// A robot still at (x, y) facing +x, or moving at (vx, vy).
RobotState Robot(double x, double y, double vx = 0.0, double vy = 0.0) {
  RobotState r;
  r.robot_id = 1;
  r.x_m = x;
  r.y_m = y;
  r.vx_mps = vx;
  r.vy_mps = vy;
  return r;
}

const MarkerTruth& Position(const std::vector<MarkerTruth>& truth) {
  for (const auto& m : truth) {
    if (m.robot_id >= 0 && !m.is_heading_marker) return m;
  }
  ADD_FAILURE() << "no position marker";
  return truth.at(0);
}

// Per-pixel coverage of the position marker estimated from the image: the
// pixel's colour between the floor's (`floor`, the same frame without the
// robot) and the marker's (its centre pixel), projected on that difference.
// Returns the coverage's centroid and its variance (sum over u and v),
// within `half` pixels of `centre`.
void CoverageMoments(const cv::Mat& image, const cv::Mat& floor, cv::Point centre, int half,
                     double* cu, double* cv_px, double* variance) {
  const cv::Vec3b m = image.at<cv::Vec3b>(centre);
  double s = 0, su = 0, sv = 0, suu = 0, svv = 0;
  for (int j = centre.y - half; j <= centre.y + half; ++j) {
    for (int i = centre.x - half; i <= centre.x + half; ++i) {
      const cv::Vec3b p = image.at<cv::Vec3b>(j, i), f = floor.at<cv::Vec3b>(j, i);
      double num = 0, den = 0;
      for (int c = 0; c < 3; ++c) {
        num += (p[c] - f[c]) * static_cast<double>(m[c] - f[c]);
        den += static_cast<double>(m[c] - f[c]) * (m[c] - f[c]);
      }
      const double w = std::clamp(num / den, 0.0, 1.0);
      s += w;
      su += w * i;
      sv += w * j;
      suu += w * i * i;
      svv += w * j * j;
    }
  }
  *cu = su / s;
  *cv_px = sv / s;
  *variance = suu / s - (su / s) * (su / s) + svv / s - (sv / s) * (sv / s);
}

TEST(Webcam, EveryEffectOffRendersTheCleanImage) {
  const Demo& d = DemoRoom();
  const SyntheticCamera webcam(d.site, d.camera, d.model, WebcamAllOff());
  const std::vector<RobotState> robots = {Robot(1.9, 1.3, 0.2, 0.1)};
  cv::Mat a, b;
  std::vector<MarkerTruth> ta, tb;
  webcam.Render(1.0, 3, robots, &a, &ta);
  CleanCamera().Render(1.0, 3, robots, &b, &tb);
  EXPECT_EQ(cv::norm(a, b, cv::NORM_INF), 0.0);
  ASSERT_EQ(ta.size(), tb.size());
  for (size_t k = 0; k < ta.size(); ++k) {
    EXPECT_EQ(ta[k].centroid_u_px, tb[k].centroid_u_px);
    EXPECT_EQ(ta[k].centroid_v_px, tb[k].centroid_v_px);
    EXPECT_EQ(ta[k].exposure_mid_t_s, 1.0);
  }
  EXPECT_EQ(webcam.TimestampDelayS(3), 0.0);
}

TEST(Webcam, PointSpreadWidensTheMarkersEdge) {
  // The coverage's variance grows by the PSF's: sigma^2 per axis, 2 sigma^2
  // summed over u and v (a Gaussian convolution adds variances). Tolerance
  // 10 %: the coverage is estimated from 8-bit colours, whose rounding in
  // the blurred rim weighs with r^2 ~ 250 px^2 (measured: 4.79 for 4.5).
  constexpr double kVarianceTolerancePx2 = 0.45;
  const Demo& d = DemoRoom();
  SimScenario blurred = WebcamAllOff();
  blurred.webcam.psf_sigma_px = 1.5;
  // No body, and the heading marker out of the measuring window.
  SyntheticCameraOptions no_body;
  no_body.body_diameter_m = 0.0;
  no_body.heading_marker_offset_m = 0.3;
  const SyntheticCamera sharp(d.site, d.camera, d.model, WebcamAllOff(), no_body);
  const SyntheticCamera blur(d.site, d.camera, d.model, blurred, no_body);
  const std::vector<RobotState> robots = {Robot(1.6, 1.2)};
  cv::Mat a, b, floor_a, floor_b;
  std::vector<MarkerTruth> truth;
  sharp.Render(0.0, 0, robots, &a, &truth);
  blur.Render(0.0, 0, robots, &b);
  sharp.Render(0.0, 0, {}, &floor_a);
  blur.Render(0.0, 0, {}, &floor_b);
  const MarkerTruth& m = Position(truth);
  const cv::Point c(static_cast<int>(std::lround(m.centroid_u_px)),
                    static_cast<int>(std::lround(m.centroid_v_px)));
  double au, av, va, bu, bv, vb;
  CoverageMoments(a, floor_a, c, 24, &au, &av, &va);
  CoverageMoments(b, floor_b, c, 24, &bu, &bv, &vb);
  std::printf("coverage variance sharp %.3f px^2, blurred %.3f px^2 (expected + %.3f)\n", va, vb,
              2 * 1.5 * 1.5);
  EXPECT_NEAR(vb - va, 2 * 1.5 * 1.5, kVarianceTolerancePx2);
  // The blur is symmetric: the centroid stays.
  EXPECT_NEAR(bu, au, kCentroidStaysPx);
  EXPECT_NEAR(bv, av, kCentroidStaysPx);
}

TEST(Webcam, VignettingDarkensTowardsTheCornersAsCos4) {
  const Demo& d = DemoRoom();
  SimScenario s = WebcamAllOff();
  s.webcam.vignetting_corner_gain = 0.6;
  const SyntheticCamera vignetted(d.site, d.camera, d.model, s);
  cv::Mat a, b;
  vignetted.Render(0.0, 0, {}, &a);
  CleanCamera().Render(0.0, 0, {}, &b);
  // Linear light ratio at floor points, against g(rho) = 1 / (1 + T rho^2)^2.
  const double cx = d.model.intrinsics.cx_px, cy = d.model.intrinsics.cy_px;
  const double r_corner = std::hypot(cx + 0.5, cy + 0.5);
  const double T = 1 / std::sqrt(0.6) - 1;
  for (const auto& [x, y] : {std::pair{1.75, 1.25}, std::pair{0.25, 0.25}, std::pair{3.8, 2.8}}) {
    const cv::Point p = Pixel(d.model, x, y, 0.0);
    const double rho2 = (std::pow(p.x - cx, 2) + std::pow(p.y - cy, 2)) / (r_corner * r_corner);
    const double g = 1 / std::pow(1 + T * rho2, 2);
    const double va = a.at<cv::Vec3b>(p)[1] / 255.0, vb = b.at<cv::Vec3b>(p)[1] / 255.0;
    auto lin = [](double c) {
      return c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4);
    };
    // One 8-bit step of the darker value, relative.
    EXPECT_NEAR(lin(va) / lin(vb), g, kPatchRatioTolerance) << x << ", " << y;
  }
}

TEST(Webcam, TheTruthLensIsTheNominalOnePlusTheScenariosDistortion) {
  const Demo& d = DemoRoom();
  SimScenario s = WebcamAllOff();
  s.webcam.lens_k = {0.03, -0.01, 0, 0};
  s.webcam.lens_principal_offset_px = {6, -4};
  const SyntheticCamera camera(d.site, d.camera, d.model, s);
  EXPECT_EQ(camera.model().intrinsics.k[0], 0.03);
  EXPECT_EQ(camera.model().intrinsics.cx_px, d.model.intrinsics.cx_px + 6);
  std::vector<MarkerTruth> truth;
  cv::Mat image;
  camera.Render(0.0, 0, {Robot(0.6, 0.5)}, &image, &truth);
  const MarkerTruth& m = Position(truth);
  double u_truth, v_truth, u_nominal, v_nominal;
  ASSERT_TRUE(camera.model().ProjectToPixel({m.x_m, m.y_m, m.z_m}, &u_truth, &v_truth));
  ASSERT_TRUE(d.model.ProjectToPixel({m.x_m, m.y_m, m.z_m}, &u_nominal, &v_nominal));
  // Rendered through the truth lens (the perspective bias of a finite disc
  // is below 1 px) ...
  EXPECT_NEAR(m.centroid_u_px, u_truth, kMaxBiasPx);
  EXPECT_NEAR(m.centroid_v_px, v_truth, kMaxBiasPx);
  // ... which near the floor's corner (30 degrees off axis) is ~3.4 px from
  // the nominal one: k1 0.03 adds ~4 px there, the principal point offset
  // takes some back.
  const double shift = std::hypot(u_truth - u_nominal, v_truth - v_nominal);
  std::printf("truth lens against the nominal one at (0.6, 0.5) m: %.2f px\n", shift);
  EXPECT_GT(shift, 3 * kMaxBiasPx);
}

TEST(Webcam, NoiseFollowsShotAndReadNoiseInLinearLight) {
  const Demo& d = DemoRoom();
  SimScenario s = WebcamAllOff();
  s.webcam.full_well_e = 1000.0;
  s.webcam.read_noise_e = 5.0;
  s.webcam.shot_noise = true;
  const SyntheticCamera camera(d.site, d.camera, d.model, s);
  cv::Mat image, clean;
  camera.Render(0.0, 5, {}, &image);
  CleanCamera().Render(0.0, 5, {}, &clean);
  const cv::Point c = Pixel(d.model, 1.75, 1.25, 0.0);
  auto lin = [](double v) {
    const double x = v / 255.0;
    return x <= 0.04045 ? x / 12.92 : std::pow((x + 0.055) / 1.055, 2.4);
  };
  for (int ch = 0; ch < 3; ++ch) {
    double s1 = 0, s2 = 0;
    int n = 0;
    for (int j = c.y - 30; j < c.y + 30; ++j) {
      for (int i = c.x - 30; i < c.x + 30; ++i) {
        const double x = lin(image.at<cv::Vec3b>(j, i)[ch]);
        s1 += x;
        s2 += x * x;
        ++n;
      }
    }
    const double mean = s1 / n, sigma = std::sqrt(s2 / n - mean * mean);
    const double signal = lin(clean.at<cv::Vec3b>(c)[ch]);
    const double e = signal * 1000.0;
    // Shot and read noise, plus the 8-bit output's rounding (1/12 of a code
    // squared, through the curve's slope at this level).
    const double slope =
        (lin(clean.at<cv::Vec3b>(c)[ch] + 0.5) - lin(clean.at<cv::Vec3b>(c)[ch] - 0.5));
    const double expected = std::sqrt((e + 25.0) / 1e6 + slope * slope / 12.0);
    std::printf("channel %d: linear mean %.4f (clean %.4f), sigma %.5f, model %.5f\n", ch, mean,
                signal, sigma, expected);
    // The estimate's own spread over 3600 samples is 1.2 %; 5 % allows for
    // the int8 noise bank's clipping and quantisation. The mean's spread is
    // sigma / 60, under 1 % of the signal.
    constexpr double kSigmaRelative = 0.05;
    constexpr double kMeanRelative = 0.01;
    EXPECT_NEAR(sigma / expected, 1.0, kSigmaRelative) << ch;
    EXPECT_NEAR(mean / signal, 1.0, kMeanRelative) << ch;
  }
}

TEST(Webcam, RollingShutterPutsAMovingMarkerWhereItsRowsTimeSays) {
  const Demo& d = DemoRoom();
  SimScenario s = WebcamAllOff();
  s.webcam.readout_s = 0.030;
  const SyntheticCamera camera(d.site, d.camera, d.model, s);
  const SyntheticCamera global(d.site, d.camera, d.model, WebcamAllOff());
  // 1 m/s along x: 30 mm over the readout, ~10 px.
  const RobotState moving = Robot(1.5, 1.2, 1.0, 0.0);
  std::vector<MarkerTruth> truth, still;
  cv::Mat image;
  camera.Render(2.0, 0, {moving}, &image, &truth);
  const MarkerTruth& m = Position(truth);
  const double row_time = m.centroid_v_px * 0.030 / d.camera.height_px;
  EXPECT_DOUBLE_EQ(m.exposure_mid_t_s, 2.0 + row_time);
  EXPECT_NEAR(m.exposure_mid_x_m, 1.5 + 1.0 * row_time, kClosedFormM);
  // The image shows the marker where it was when its centroid's row was
  // read: its projection then is the centroid (to the finite disc's
  // perspective bias, measured on the still marker at that place).
  RobotState there = moving;
  there.x_m = m.exposure_mid_x_m;
  there.vx_mps = 0.0;
  global.Render(2.0, 0, {there}, &image, &still);
  EXPECT_NEAR(m.centroid_u_px, Position(still).centroid_u_px, kSameMarkerPx);
  EXPECT_NEAR(m.centroid_v_px, Position(still).centroid_v_px, kSameMarkerPx);
  // And not where it was at the frame's start.
  std::vector<MarkerTruth> start;
  global.Render(2.0, 0, {moving}, &image, &start);
  EXPECT_GT(std::abs(m.centroid_u_px - Position(start).centroid_u_px), 3.0);
}

TEST(Webcam, MotionBlurStreakIsSpeedTimesExposure) {
  const Demo& d = DemoRoom();
  SimScenario s = WebcamAllOff();
  s.webcam.exposure_s = 0.0156;
  SyntheticCameraOptions no_body;
  no_body.body_diameter_m = 0.0;
  no_body.heading_marker_offset_m = 0.3;
  const SyntheticCamera blurred(d.site, d.camera, d.model, s, no_body);
  const SyntheticCamera still(d.site, d.camera, d.model, WebcamAllOff(), no_body);
  // 1 m/s sideways: 15.6 mm, ~5 px.
  const RobotState moving = Robot(1.7, 1.4, 0.0, 1.0);
  cv::Mat a, b, floor;
  std::vector<MarkerTruth> ta, tb;
  blurred.Render(0.0, 0, {moving}, &a, &ta);
  still.Render(0.0, 0, {moving}, &b, &tb);
  still.Render(0.0, 0, {}, &floor);
  double u0, v0, u1, v1;
  ASSERT_TRUE(d.model.ProjectToPixel({1.7, 1.4 - 0.0156, 0.2}, &u0, &v0));
  ASSERT_TRUE(d.model.ProjectToPixel({1.7, 1.4, 0.2}, &u1, &v1));
  const double streak = std::hypot(u1 - u0, v1 - v0);
  const cv::Point c(static_cast<int>(std::lround(Position(tb).centroid_u_px)),
                    static_cast<int>(std::lround(Position(tb).centroid_v_px)));
  double au, av, va, bu, bv, vb;
  CoverageMoments(a, floor, c, 22, &au, &av, &va);
  CoverageMoments(b, floor, c, 22, &bu, &bv, &vb);
  // A box of length L adds L^2 / 12 of variance along the motion.
  const double measured = std::sqrt(12 * (va - vb));
  std::printf("streak %.2f px measured, %.2f px = speed x exposure\n", measured, streak);
  // The streak's length from second moments of 8-bit coverage: 5 %.
  constexpr double kStreakRelative = 0.05;
  EXPECT_NEAR(measured, streak, kStreakRelative * streak);
  // The centroid of the streak is the marker at mid-exposure.
  const MarkerTruth& m = Position(ta);
  EXPECT_NEAR(m.exposure_mid_t_s, -0.0078, kClosedFormS);
  EXPECT_NEAR(m.exposure_mid_y_m, 1.4 - 0.0078, kClosedFormM);
  double um, vm;
  ASSERT_TRUE(d.model.ProjectToPixel({1.7, 1.4 - 0.0078, 0.2}, &um, &vm));
  EXPECT_NEAR(m.centroid_u_px - Position(tb).centroid_u_px, um - u1, kSameMarkerPx);
  EXPECT_NEAR(m.centroid_v_px - Position(tb).centroid_v_px, vm - v1, kSameMarkerPx);
  EXPECT_NEAR(au, m.centroid_u_px, kCoverageCentroidPx);
  EXPECT_NEAR(av, m.centroid_v_px, kCoverageCentroidPx);
}

TEST(Webcam, TimestampIsTheLastRowsReadPlusLatencyWithinTheJitter) {
  const Demo& d = DemoRoom();
  SimScenario s;
  ASSERT_TRUE(ParseSimScenario("webcam", &s, nullptr));
  const SyntheticCamera camera(d.site, d.camera, d.model, s);
  const double nominal = s.webcam.readout_s * 1079.0 / 1080.0 + s.webcam.timestamp_latency_s;
  double lo = 1e9, hi = -1e9, sum = 0;
  constexpr int kFrames = 2000;
  for (int f = 0; f < kFrames; ++f) {
    const double delay = camera.TimestampDelayS(f);
    lo = std::min(lo, delay);
    hi = std::max(hi, delay);
    sum += delay;
    EXPECT_EQ(delay, camera.TimestampDelayS(f));
  }
  EXPECT_GE(lo, nominal - s.webcam.timestamp_jitter_s);
  EXPECT_LE(hi, nominal + s.webcam.timestamp_jitter_s);
  // A uniform jitter fills its range and averages out (its mean's sigma
  // over 2000 frames is j / sqrt(3 x 2000) ~ 0.013 j).
  EXPECT_GT(hi - lo, 1.9 * s.webcam.timestamp_jitter_s);
  constexpr double kJitterMeanFraction = 0.05;  // ~4 sigma of the mean
  EXPECT_NEAR(sum / kFrames, nominal, kJitterMeanFraction * s.webcam.timestamp_jitter_s);
}

TEST(Webcam, RobotTiltsByItsStaticLeanAndMovesTheMarker) {
  const Demo& d = DemoRoom();
  SimScenario s = WebcamAllOff();
  s.webcam.tilt_static_deg = 1.0;
  const SyntheticCamera camera(d.site, d.camera, d.model, s);
  std::vector<MarkerTruth> truth;
  cv::Mat image;
  camera.Render(0.0, 0, {Robot(2.0, 1.5)}, &image, &truth);
  const MarkerTruth& m = Position(truth);
  const double tilt = std::hypot(m.robot_tilt_forward_rad, m.robot_tilt_left_rad);
  EXPECT_NEAR(tilt, M_PI / 180, kClosedFormRad);
  // 20 cm up, one degree: 3.49 mm sideways.
  EXPECT_NEAR(std::hypot(m.x_m - 2.0, m.y_m - 1.5), 0.2 * std::sin(M_PI / 180), kLeanCompositionM);
}

TEST(Webcam, DrivingRobotTiltsByADegreeOrTwo) {
  // The reference circle at 20 cm/s with the default tilt model: a rocking
  // lean around the static one, within the "a degree or two", and
  // the marker off the robot's centre by its mast height times the lean.
  const Demo& d = DemoRoom();
  SimScenario s;
  ASSERT_TRUE(ParseSimScenario("webcam", &s, nullptr));
  Camera small = d.camera;
  small.width_px = 320;
  small.height_px = 180;
  const SyntheticCamera camera(d.site, small,
                               calib::NominalCamera(small.mount_position_m, 120, 320, 180), s);
  double max_tilt = 0, min_tilt = 1e9;
  for (int f = 0; f < 100; ++f) {
    std::vector<MarkerTruth> truth;
    cv::Mat image;
    const double t = f / 10.0;
    camera.Render(t, f, camera.SimulatedRobots(t), &image, &truth);
    const MarkerTruth& m = Position(truth);
    const double tilt = std::hypot(m.robot_tilt_forward_rad, m.robot_tilt_left_rad);
    max_tilt = std::max(max_tilt, tilt * 180 / M_PI);
    min_tilt = std::min(min_tilt, tilt * 180 / M_PI);
    EXPECT_NEAR(std::hypot(m.exposure_mid_x_m - m.robot_x_m, m.exposure_mid_y_m - m.robot_y_m),
                0.2 * std::sin(tilt), kLeanCompositionM);
  }
  std::printf("tilt on the reference circle: %.2f .. %.2f degrees\n", min_tilt, max_tilt);
  EXPECT_GT(max_tilt, 0.8);
  EXPECT_LT(max_tilt, 2.5);
}

TEST(Webcam, WornMarkersFadeTowardsGrey) {
  const Demo& d = DemoRoom();
  SimScenario worn = WebcamAllOff();
  worn.webcam.marker_wear = 0.5;
  const SyntheticCamera camera(d.site, d.camera, d.model, worn);
  std::vector<MarkerTruth> truth;
  cv::Mat a, b;
  camera.Render(0.0, 0, {Robot(2.0, 1.5)}, &a, &truth);
  CleanCamera().Render(0.0, 0, {Robot(2.0, 1.5)}, &b);
  const cv::Point c(static_cast<int>(std::lround(Position(truth).centroid_u_px)),
                    static_cast<int>(std::lround(Position(truth).centroid_v_px)));
  const cv::Vec3b pa = a.at<cv::Vec3b>(c), pb = b.at<cv::Vec3b>(c);
  // colour = (1 - f) class + f grey, the same f for every channel, f <= wear.
  const double f = (pb[2] - pa[2]) / (pb[2] - 150.0);
  EXPECT_GT(f, 0.0);
  EXPECT_LE(f, 0.5);
  for (int ch = 0; ch < 3; ++ch) {
    EXPECT_NEAR(pa[ch], (1 - f) * pb[ch] + f * 150.0, kOneCodeDn) << ch;
  }
}

TEST(Webcam, BayerMosaicKeepsFlatColoursAndFringesEdges) {
  const Demo& d = DemoRoom();
  SimScenario s = WebcamAllOff();
  s.webcam.bayer = true;
  const SyntheticCamera camera(d.site, d.camera, d.model, s);
  std::vector<MarkerTruth> truth;
  cv::Mat a, b;
  camera.Render(0.0, 0, {Robot(2.0, 1.5)}, &a, &truth);
  CleanCamera().Render(0.0, 0, {Robot(2.0, 1.5)}, &b);
  // Inside the marker and on the open floor every channel survives the
  // mosaic (an RGGB layout demosaiced with the matching OpenCV code).
  const cv::Point c(static_cast<int>(std::lround(Position(truth).centroid_u_px)),
                    static_cast<int>(std::lround(Position(truth).centroid_v_px)));
  for (const cv::Point p : {c, Pixel(d.model, 1.75, 1.25, 0.0)}) {
    for (int ch = 0; ch < 3; ++ch) {
      EXPECT_NEAR(a.at<cv::Vec3b>(p)[ch], b.at<cv::Vec3b>(p)[ch], kDemosaicFlatDn)
          << p << " " << ch;
    }
  }
  // At edges the interpolation differs from the ideal image.
  EXPECT_GT(cv::norm(a, b, cv::NORM_INF), 20.0);
}

TEST(Webcam, AutoExposureAndWhiteBalanceDriftSlowly) {
  // Linear floor brightness over one period: max / min = (1 + a) / (1 - a)
  // (20 samples catch the extremes to cos(pi / 20), 1 %), and the red gain
  // against green likewise for the white balance. Tolerance: 8-bit codes
  // near 160 are 1 % apart in linear light.
  constexpr double kRatioTolerance = 0.04;
  const Demo& d = DemoRoom();
  SimScenario s = WebcamAllOff();
  s.webcam.auto_exposure_drift = 0.2;
  s.webcam.auto_exposure_period_s = 2.0;
  s.webcam.white_balance_drift = 0.1;
  s.webcam.white_balance_period_s = 2.0;
  const SyntheticCamera camera(d.site, d.camera, d.model, s);
  const cv::Point p = Pixel(d.model, 1.75, 1.25, 0.0);
  auto lin = [](double v) {
    const double x = v / 255.0;
    return x <= 0.04045 ? x / 12.92 : std::pow((x + 0.055) / 1.055, 2.4);
  };
  cv::Mat clean;
  CleanCamera().Render(0.0, 0, {}, &clean);
  const cv::Vec3b c = clean.at<cv::Vec3b>(p);
  double g_lo = 1e9, g_hi = 0, r_lo = 1e9, r_hi = 0;
  for (int k = 0; k < 20; ++k) {
    cv::Mat image;
    camera.Render(k * 0.1, k, {}, &image);
    const cv::Vec3b v = image.at<cv::Vec3b>(p);
    const double g = lin(v[1]) / lin(c[1]);
    const double r = (lin(v[2]) / lin(c[2])) / g;
    g_lo = std::min(g_lo, g), g_hi = std::max(g_hi, g);
    r_lo = std::min(r_lo, r), r_hi = std::max(r_hi, r);
  }
  EXPECT_NEAR(g_hi / g_lo, 1.2 / 0.8, kRatioTolerance * 1.5);
  EXPECT_NEAR(r_hi / r_lo, 1.1 / 0.9, kRatioTolerance * 1.2);
}

TEST(Webcam, SheenWhitensMarkersSeenObliquely) {
  const Demo& d = DemoRoom();
  SimScenario s = WebcamAllOff();
  s.webcam.marker_sheen = 0.5;
  const SyntheticCamera camera(d.site, d.camera, d.model, s);
  for (const auto& [x, y] : {std::pair{2.0, 1.5}, std::pair{0.5, 0.5}}) {
    std::vector<MarkerTruth> truth;
    cv::Mat a, b;
    camera.Render(0.0, 0, {Robot(x, y)}, &a, &truth);
    CleanCamera().Render(0.0, 0, {Robot(x, y)}, &b);
    const cv::Point c(static_cast<int>(std::lround(Position(truth).centroid_u_px)),
                      static_cast<int>(std::lround(Position(truth).centroid_v_px)));
    // colour = (1 - s) class + s white, s = 0.5 min(1, (1 - cos view) / 0.5).
    const Eigen::Vector3d to_camera = d.model.pose.position_m - Eigen::Vector3d(x, y, 0.2);
    const double cos_view = to_camera.z() / to_camera.norm();
    const double sheen = 0.5 * std::min(1.0, (1 - cos_view) / 0.5);
    const cv::Vec3b pa = a.at<cv::Vec3b>(c), pb = b.at<cv::Vec3b>(c);
    for (int ch = 0; ch < 3; ++ch) {
      EXPECT_NEAR(pa[ch], (1 - sheen) * pb[ch] + sheen * 255.0, kOneCodeDn) << x << " " << ch;
    }
  }
}

TEST(Webcam, SameSequenceNumberGivesTheSameBytes) {
  const Demo& d = DemoRoom();
  SimScenario s;
  ASSERT_TRUE(ParseSimScenario("webcam", &s, nullptr));
  const SyntheticCamera camera(d.site, d.camera, d.model, s);
  cv::Mat a, b, c;
  const auto robots = camera.SimulatedRobots(1.0);
  camera.Render(1.0, 30, robots, &a);
  camera.Render(1.0, 30, robots, &b);
  camera.Render(1.0, 31, robots, &c);
  EXPECT_EQ(cv::norm(a, b, cv::NORM_INF), 0.0);
  EXPECT_GT(cv::norm(a, c, cv::NORM_INF), 0.0);
  std::vector<uint8_t> ja, jb;
  ASSERT_TRUE(camera.Encode(a, 90, &ja));
  ASSERT_TRUE(camera.Encode(b, 90, &jb));
  EXPECT_EQ(ja, jb);
  EXPECT_EQ(camera.JpegQuality(90), 80);
}

TEST(Webcam, SiteParametersReachTheScenario) {
  Site site = DemoRoom().site;
  site.simulation.webcam.exposure_s = 0.01;
  SimScenario s;
  std::string error;
  ASSERT_TRUE(ParseSimScenario("sim:webcam", site, &s, &error)) << error;
  EXPECT_TRUE(s.webcam_effects);
  EXPECT_EQ(s.webcam.exposure_s, 0.01);
  ASSERT_TRUE(ParseSimScenario("clean", site, &s, &error));
  EXPECT_FALSE(s.webcam_effects);
}

}  // namespace
}  // namespace roomfix::sim
