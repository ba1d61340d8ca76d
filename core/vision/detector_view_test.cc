#include "core/vision/detector_view.h"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <memory>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <string>
#include <vector>

#include "camera_proc/camera_node.h"
#include "core/calib/fisheye_camera.h"
#include "core/world/site.h"
#include "sim/synthetic_camera.h"
#include "tests/testing/demo_site.h"
#include "tests/testing/test_paths.h"

namespace roomfix::vision {
namespace {

// The view is decoded at half size, as camera_proc's full-frame search is.
constexpr int kScale = 2;

class DetectorViewTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string error;
    ASSERT_TRUE(LoadSite(testing::DemoSitePath(), &site_, &error)) << error;
    camera_ = site_.cameras.front();
    lens_ = calib::NominalCamera(camera_.mount_position_m, camera_.field_of_view_deg,
                                 camera_.width_px, camera_.height_px);
  }

  // The robot rendered at (x, y) by the clean synthetic camera with the
  // site's own classes; the truth of its markers in *truth.
  cv::Mat Render(double x_m, double y_m, std::vector<sim::MarkerTruth>* truth) {
    sim::SimScenario scenario;
    std::string error;
    EXPECT_TRUE(sim::ParseSimScenario("clean", &scenario, &error)) << error;
    const sim::SyntheticCamera camera(site_, camera_, lens_, scenario);
    sim::RobotState robot;
    robot.robot_id = camera_.robots.front().robot_id;
    robot.x_m = x_m;
    robot.y_m = y_m;
    robot.heading_rad = 0.3;
    cv::Mat full, reduced;
    camera.Render(0.0, 0, {robot}, &full, truth);
    cv::resize(full, reduced, cv::Size(), 1.0 / kScale, 1.0 / kScale, cv::INTER_AREA);
    return reduced;
  }

  // The view of `reduced` with the detector and robots camera_proc would
  // set up for `camera` (its classes and their expected blob areas).
  DetectorView View(const Camera& camera, const cv::Mat& reduced,
                    std::map<int, cv::Point2d> expected = {}) {
    CameraSetup setup;
    std::string error;
    EXPECT_TRUE(MakeCameraSetup(site_.room, camera, lens_, CameraNodeOptions{}, &setup, &error))
        << error;
    detector_ = std::make_unique<MarkerDetector>(setup.classes, DetectorOptions{});
    DetectorViewInput in;
    in.bgr = reduced;
    in.scale = kScale;
    in.region_px = cv::Rect(0, 0, camera.width_px, camera.height_px);
    in.source_size = cv::Size(camera.width_px, camera.height_px);
    in.robots = setup.robots;
    in.tracker = setup.tracker;
    in.expected_px = std::move(expected);
    return RenderDetectorView(*detector_, in);
  }

  Site site_;
  Camera camera_;
  calib::CameraModel lens_;
  std::unique_ptr<MarkerDetector> detector_;
};

TEST_F(DetectorViewTest, ARobotInViewIsFoundAndItsMarkersArePaintedInTheirClassColour) {
  std::vector<sim::MarkerTruth> truth;
  const cv::Mat reduced = Render(1.9, 1.5, &truth);
  const DetectorView view = View(camera_, reduced);
  ASSERT_EQ(view.robots.size(), 1u);
  EXPECT_EQ(view.robots[0].reason, RobotViewReason::kFound) << view.robots[0].text;
  EXPECT_EQ(view.blobs.size(), 2u);

  // The overlay survives PNG and shows each marker in its class's paint.
  std::vector<uint8_t> png;
  ASSERT_TRUE(cv::imencode(".png", view.bgr, png));
  const cv::Mat decoded = cv::imdecode(png, cv::IMREAD_COLOR);
  ASSERT_EQ(decoded.size(), reduced.size());
  for (const sim::MarkerTruth& m : truth) {
    if (m.robot_id < 0) continue;
    int k = -1;
    for (size_t i = 0; i < detector_->classes().size(); ++i) {
      if (detector_->classes()[i].name == m.colour_class) k = static_cast<int>(i);
    }
    ASSERT_GE(k, 0) << m.colour_class;
    const cv::Vec3b paint = ClassPaintBgr(detector_->classes()[k]);
    const cv::Point centre(static_cast<int>(std::lround((m.centroid_u_px + 0.5) / kScale - 0.5)),
                           static_cast<int>(std::lround((m.centroid_v_px + 0.5) / kScale - 0.5)));
    // The 5 cm heading marker is 4 view pixels across: its centre pixel is
    // the one every blur and threshold leaves in the class.
    EXPECT_EQ(decoded.at<cv::Vec3b>(centre), paint) << m.colour_class << " marker at " << centre;
  }
}

TEST_F(DetectorViewTest, AHeadingClassNarrowedToAnUnusedHueHasNoPixels) {
  std::vector<sim::MarkerTruth> truth;
  const cv::Mat reduced = Render(1.9, 1.5, &truth);
  // The frame shows a green heading marker; the site's class now asks for blue.
  Camera narrowed = camera_;
  const std::string heading = narrowed.robots.front().heading_marker;
  for (MarkerClass& c : narrowed.marker_classes) {
    if (c.name == heading) {
      c.hsv_min = {100, 200, 200};
      c.hsv_max = {105, 255, 255};
    }
  }
  const DetectorView view = View(narrowed, reduced);
  ASSERT_EQ(view.robots.size(), 1u);
  EXPECT_EQ(view.robots[0].reason, RobotViewReason::kNoPixels) << view.robots[0].text;
  EXPECT_NE(view.robots[0].text.find("no pixels of class " + heading), std::string::npos)
      << view.robots[0].text;
}

TEST_F(DetectorViewTest, APositionMarkerOverItsClassMaximumIsTooLargeWithItsAreaAndLimit) {
  std::vector<sim::MarkerTruth> truth;
  const cv::Mat reduced = Render(1.9, 1.5, &truth);
  const DetectorView found = View(camera_, reduced);
  ASSERT_EQ(found.robots[0].reason, RobotViewReason::kFound) << found.robots[0].text;
  const Blob& position = found.blobs.front();  // orange: class 0, the largest
  // A class whose maximum the marker's area exceeds by a margin the
  // measurement cannot cross; the pre-filter's loose bound still passes it.
  Camera camera = camera_;
  CameraSetup setup;
  std::string error;
  ASSERT_TRUE(MakeCameraSetup(site_.room, camera, lens_, CameraNodeOptions{}, &setup, &error));
  const double max_area_px = 0.8 * position.area_px;
  setup.classes[position.class_index].max_area_px = max_area_px;
  const MarkerDetector detector(setup.classes, DetectorOptions{});
  DetectorViewInput in;
  in.bgr = reduced;
  in.scale = kScale;
  in.region_px = cv::Rect(0, 0, camera.width_px, camera.height_px);
  in.source_size = in.region_px.size();
  in.robots = setup.robots;
  in.tracker = setup.tracker;
  const DetectorView view = RenderDetectorView(detector, in);
  ASSERT_EQ(view.robots.size(), 1u);
  EXPECT_EQ(view.robots[0].reason, RobotViewReason::kTooLarge) << view.robots[0].text;
  EXPECT_NEAR(view.robots[0].value, position.area_px, 0.05 * position.area_px);
  EXPECT_DOUBLE_EQ(view.robots[0].limit, max_area_px);
}

TEST_F(DetectorViewTest, ARobotExpectedOutsideTheImageIsOutOfView) {
  // West of the room, beyond the lens's field of view.
  const double x_m = -6.0, y_m = 1.5;
  double u = 0, v = 0;
  const double height_m = camera_.robots.front().marker_height_m;
  ASSERT_TRUE(lens_.ProjectToPixel(Eigen::Vector3d(x_m, y_m, height_m), &u, &v));
  ASSERT_FALSE(cv::Rect2d(0, 0, camera_.width_px, camera_.height_px).contains({u, v}))
      << "the test's position must lie outside the image: " << u << ", " << v;
  std::vector<sim::MarkerTruth> truth;
  const cv::Mat reduced = Render(x_m, y_m, &truth);
  const int id = camera_.robots.front().robot_id;
  const DetectorView view = View(camera_, reduced, {{id, cv::Point2d(u, v)}});
  ASSERT_EQ(view.robots.size(), 1u);
  EXPECT_EQ(view.robots[0].reason, RobotViewReason::kOutOfView) << view.robots[0].text;
  // Without a sensor saying where it is, the view can only say what is missing.
  const DetectorView blind = View(camera_, reduced);
  EXPECT_EQ(blind.robots[0].reason, RobotViewReason::kNoPixels) << blind.robots[0].text;
}

TEST_F(DetectorViewTest, ARegionViewPlacesBlobsInFullFrameCoordinates) {
  std::vector<sim::MarkerTruth> truth;
  sim::SimScenario scenario;
  std::string error;
  ASSERT_TRUE(sim::ParseSimScenario("clean", &scenario, &error)) << error;
  const sim::SyntheticCamera camera(site_, camera_, lens_, scenario);
  sim::RobotState robot;
  robot.robot_id = camera_.robots.front().robot_id;
  robot.x_m = 1.9;
  robot.y_m = 1.5;
  cv::Mat full;
  camera.Render(0.0, 0, {robot}, &full, &truth);
  const sim::MarkerTruth& marker = truth.front();
  const cv::Rect region(static_cast<int>(marker.centroid_u_px) - 100,
                        static_cast<int>(marker.centroid_v_px) - 100, 200, 200);
  CameraSetup setup;
  ASSERT_TRUE(MakeCameraSetup(site_.room, camera_, lens_, CameraNodeOptions{}, &setup, &error));
  const MarkerDetector detector(setup.classes, DetectorOptions{});
  DetectorViewInput in;
  in.bgr = full(region).clone();
  in.region_px = region;
  in.source_size = full.size();
  in.robots = setup.robots;
  in.tracker = setup.tracker;
  const DetectorView view = RenderDetectorView(detector, in);
  ASSERT_FALSE(view.blobs.empty());
  double nearest_px = 1e9;
  for (const Blob& b : view.blobs) {
    nearest_px = std::min(nearest_px,
                          std::hypot(b.u_px - marker.centroid_u_px, b.v_px - marker.centroid_v_px));
  }
  constexpr double kCentroidTolerancePx = 0.5;
  EXPECT_LT(nearest_px, kCentroidTolerancePx);
  EXPECT_EQ(view.bgr.size(), region.size());
}

TEST(DetectorView, ARobotNamingNoClassOfTheDetectorIsNotPairedNotACrash) {
  const MarkerDetector detector({ColourClass{}}, DetectorOptions{});
  DetectorViewInput in;
  in.bgr = cv::Mat(64, 64, CV_8UC3, cv::Scalar(90, 90, 90));
  TrackedRobotSpec spec;
  spec.position_class = 7;
  spec.heading_class = -1;
  in.robots = {spec};
  const DetectorView view = RenderDetectorView(detector, in);
  ASSERT_EQ(view.robots.size(), 1u);
  EXPECT_EQ(view.robots[0].reason, RobotViewReason::kNotPaired);
  EXPECT_EQ(view.bgr.size(), in.bgr.size());
}

TEST(DetectorView, AnEmptyImageGivesAnEmptyViewAndNoDiagnosis) {
  const MarkerDetector detector({ColourClass{}}, DetectorOptions{});
  DetectorViewInput in;
  in.robots = {TrackedRobotSpec{}};
  const DetectorView view = RenderDetectorView(detector, in);
  EXPECT_TRUE(view.bgr.empty());
  EXPECT_TRUE(view.robots.empty());
}

// smarties.png (core/vision/marker_detector_test.cc): the view paints and
// circles the orange candies the detector finds.
TEST(DetectorView, MarksTheOrangeCandiesOfTheSmartiesPhoto) {
  const std::string data = roomfix::testing::SharedDataDir();
  if (data.empty()) GTEST_SKIP() << "../shared/data is absent: real-photo test not run";
  const cv::Mat img = cv::imread(data + "/opencv_samples/smarties.png", cv::IMREAD_COLOR);
  ASSERT_FALSE(img.empty()) << data << "/opencv_samples/smarties.png is missing or unreadable";
  ColourClass orange;
  orange.name = "orange";
  orange.hsv_min = {3, 150, 60};
  orange.hsv_max = {22, 255, 255};
  orange.min_area_px = 600;
  orange.min_circularity = 0.85;
  DetectorOptions options;
  options.lighting = LightingMode::kFixed;
  const MarkerDetector detector({orange}, options);
  DetectorViewInput in;
  in.bgr = img;
  const DetectorView view = RenderDetectorView(detector, in);
  const std::vector<Blob> plain = detector.Detect(img, ImageWindow{});
  ASSERT_FALSE(plain.empty());
  // One code path: the view's blobs are Detect's.
  ASSERT_EQ(view.blobs.size(), plain.size());
  const cv::Vec3b paint = ClassPaintBgr(orange);
  for (size_t i = 0; i < plain.size(); ++i) {
    EXPECT_NEAR(view.blobs[i].u_px, plain[i].u_px, 1e-9);
    EXPECT_NEAR(view.blobs[i].v_px, plain[i].v_px, 1e-9);
    const cv::Point c(static_cast<int>(std::lround(plain[i].u_px)),
                      static_cast<int>(std::lround(plain[i].v_px)));
    EXPECT_EQ(view.bgr.at<cv::Vec3b>(c), paint) << "candy at " << c;
  }
  // Where no class is, the photo is dimmed grey (white background: B = G = R).
  const cv::Vec3b corner = view.bgr.at<cv::Vec3b>(2, 2);
  EXPECT_EQ(corner[0], corner[1]);
  EXPECT_EQ(corner[1], corner[2]);
}

}  // namespace
}  // namespace roomfix::vision
