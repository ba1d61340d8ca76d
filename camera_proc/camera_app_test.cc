#include "camera_proc/camera_app.h"

#include <gtest/gtest.h>

#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <vector>

#include "camera_io/camera_source.h"
#include "msgio/process.h"
#include "roomfix/process_status_t.hpp"
#include "tests/testing/demo_site_test_fixture.h"
#include "tests/testing/test_paths.h"

namespace roomfix {
namespace {

void WriteBytes(const std::string& path, const std::vector<uint8_t>& bytes) {
  std::ofstream out(path, std::ios::binary);
  out.write(reinterpret_cast<const char*>(bytes.data()),
            static_cast<std::streamsize>(bytes.size()));
}

using CameraAppTest = testing::DemoSiteTest;

// A folder of frames, some bad: each good one is processed, each bad one is
// counted under the kind its source reported (not guessed from its text),
// and the loop ends at the end of the folder with 0.
TEST_F(CameraAppTest, RunsAFolderCountingBadFramesByKind) {
  testing::TempDir dir;
  const Camera& camera = site_.cameras.front();
  std::vector<uint8_t> jpeg;
  ASSERT_TRUE(cv::imencode(
      ".jpg", cv::Mat(camera.height_px, camera.width_px, CV_8UC3, cv::Scalar(90, 90, 90)), jpeg));
  WriteBytes(dir.File("a.jpg"), jpeg);
  std::vector<uint8_t> cut(jpeg.begin(), jpeg.begin() + static_cast<long>(jpeg.size() / 2));
  WriteBytes(dir.File("b.jpg"), cut);
  WriteBytes(dir.File("c.jpg"), {});
  WriteBytes(dir.File("d.png"),
             {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n', 0, 0, 0, 13, 'I', 'H', 'D',
              'R',  0,   1,   0,   0,    0,    1,    0,    0, 8, 2, 0,  0,   0});
  WriteBytes(dir.File("e.png"), {'n', 'o', 't', ' ', 'a', 'n', ' ', 'i', 'm', 'a', 'g', 'e'});
  WriteBytes(dir.File("f.jpg"), jpeg);

  CameraSourceOptions options;
  options.device = dir.path();
  options.calibration_path = "none";
  CameraChoice choice;
  std::string error;
  ASSERT_TRUE(ChooseCamera(site_, options, &choice, &error)) << error;
  std::unique_ptr<camera::FrameSource> source;
  std::string summary;
  ASSERT_TRUE(MakeDeviceSource(choice, options, 1'700'000'000'000'000, &source, &summary, &error))
      << error;
  LoopbackBus bus;
  std::vector<process_status_t> statuses;
  bus.Subscribe<process_status_t>(
      kStatusChannel,
      [&](const process_status_t& s, const MessageInfo&) { statuses.push_back(s); });
  CameraNode node(site_, camera, std::nullopt, &bus, CameraNodeOptions{}, NowUtime());
  ASSERT_TRUE(node.ok(&error)) << error;
  CameraLoopOptions loop;
  loop.duration_s = 30.0;  // a bound should the end never come; it comes at once
  EXPECT_EQ(RunCameraSource(source.get(), &node, &bus, loop, &error), 0) << error;
  EXPECT_EQ(node.frames_processed(), 2);
  EXPECT_EQ(node.status().rejected("truncated_frame"), 1);
  EXPECT_EQ(node.status().rejected("empty_frame"), 1);
  EXPECT_EQ(node.status().rejected("wrong_frame_size"), 1);
  EXPECT_EQ(node.status().rejected("unreadable_frame"), 1);
  ASSERT_FALSE(statuses.empty());
  EXPECT_EQ(statuses.back().state, process_status_t::STATE_STOPPING);
}

TEST_F(CameraAppTest, AFileSourceThatCannotOpenEndsWithItsReason) {
  testing::TempDir dir;
  CameraSourceOptions options;
  options.device = dir.path() + "/*.jpg";  // matches nothing
  options.calibration_path = "none";
  CameraChoice choice;
  std::string error;
  ASSERT_TRUE(ChooseCamera(site_, options, &choice, &error)) << error;
  std::unique_ptr<camera::FrameSource> source;
  std::string summary;
  ASSERT_TRUE(MakeDeviceSource(choice, options, 1, &source, &summary, &error)) << error;
  LoopbackBus bus;
  CameraNode node(site_, site_.cameras.front(), std::nullopt, &bus, CameraNodeOptions{},
                  NowUtime());
  EXPECT_EQ(RunCameraSource(source.get(), &node, &bus, CameraLoopOptions{}, &error), 1);
  EXPECT_NE(error.find("no image files match"), std::string::npos) << error;
}

TEST(CameraLoopOptions, RefusesANegativeDurationOrNoReopenWait) {
  CameraLoopOptions options;
  std::string error;
  EXPECT_TRUE(options.IsValid(&error)) << error;
  options.duration_s = -1.0;
  EXPECT_FALSE(options.IsValid(&error));
  options = CameraLoopOptions{};
  options.reopen_max_s = 0.0;
  EXPECT_FALSE(options.IsValid(&error));
  EXPECT_NE(error.find("reopen"), std::string::npos) << error;
}

}  // namespace
}  // namespace roomfix
