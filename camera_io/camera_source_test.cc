#include "camera_io/camera_source.h"

#include <gtest/gtest.h>

#include <string>

#include "tests/testing/demo_site_test_fixture.h"

namespace roomfix {
namespace {

using CameraSourceTest = testing::DemoSiteTest;

TEST_F(CameraSourceTest, ChoosesTheSiteCameraAndItsCalibration) {
  CameraSourceOptions options;
  CameraChoice choice;
  std::string error;
  ASSERT_TRUE(ChooseCamera(site_, options, &choice, &error)) << error;
  EXPECT_EQ(choice.camera.id, site_.cameras.front().id);
  EXPECT_EQ(choice.device, "sim:webcam");
  // The demo site names a calibration file, which is loaded and checked.
  ASSERT_TRUE(choice.calibration.has_value());
  EXPECT_EQ(choice.calibration->width_px(), choice.camera.width_px);

  options.calibration_path = "none";
  options.device = "/dev/video7";
  ASSERT_TRUE(ChooseCamera(site_, options, &choice, &error)) << error;
  EXPECT_FALSE(choice.calibration.has_value());
  EXPECT_EQ(choice.device, "/dev/video7");
}

TEST_F(CameraSourceTest, RefusesAnUnknownCameraOrAMissingCalibration) {
  CameraSourceOptions options;
  options.camera_id = 99;
  CameraChoice choice;
  std::string error;
  EXPECT_FALSE(ChooseCamera(site_, options, &choice, &error));
  EXPECT_EQ(error, "the site has no camera with id 99");

  options.camera_id = site_.cameras.front().id;
  options.calibration_path = "/nonexistent/calibration.yaml";
  error.clear();
  EXPECT_FALSE(ChooseCamera(site_, options, &choice, &error));
  EXPECT_NE(error.find("/nonexistent/calibration.yaml"), std::string::npos) << error;
}

TEST(CameraSourceOptions, RefusesANegativeRate) {
  CameraSourceOptions options;
  std::string error;
  EXPECT_TRUE(options.IsValid(&error)) << error;
  options.fps = -1.0;
  EXPECT_FALSE(options.IsValid(&error));
}

}  // namespace
}  // namespace roomfix
