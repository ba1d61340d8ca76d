#include "viewer/viewer_app.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <vector>

#include "msgio/log.h"
#include "tests/testing/demo_site.h"
#include "tests/testing/test_paths.h"

namespace roomfix::viewer {
namespace {

constexpr int64_t kFrameUs = 100'000;  // 10 fps
constexpr int64_t kT0 = 1'700'000'000'000'000;

std::vector<int64_t> Drawn(ReplayPacer* pacer, int64_t utime, int limit = 1000) {
  std::vector<int64_t> drawn;
  pacer->AdvanceTo(utime, [&](int64_t t) {
    if (static_cast<int>(drawn.size()) >= limit) return false;
    drawn.push_back(t);
    return true;
  });
  return drawn;
}

TEST(ReplayPacer, DrawsEveryFrameInstantUpToEachEvent) {
  ReplayPacer pacer(kFrameUs, kMaxReplayGapUs);
  // The first event starts the frames at its own time.
  EXPECT_EQ(Drawn(&pacer, kT0), (std::vector<int64_t>{kT0}));
  // Nothing new before the next instant.
  EXPECT_TRUE(Drawn(&pacer, kT0 + 50'000).empty());
  EXPECT_EQ(Drawn(&pacer, kT0 + 350'000),
            (std::vector<int64_t>{kT0 + 100'000, kT0 + 200'000, kT0 + 300'000}));
}

TEST(ReplayPacer, SkipsAGapLongerThanTheLimit) {
  ReplayPacer pacer(kFrameUs, kMaxReplayGapUs);
  Drawn(&pacer, kT0);
  // 1.9 s: under the 2 s limit, drawn frame by frame (19 frames).
  EXPECT_EQ(Drawn(&pacer, kT0 + 1'900'000).size(), 19u);
  // 3.1 s on: a gap (a paused recording), restarted at the event.
  EXPECT_EQ(Drawn(&pacer, kT0 + 5'000'000), (std::vector<int64_t>{kT0 + 5'000'000}));
}

TEST(ReplayPacer, StopsWhenDrawingIsRefusedAndResumesThere) {
  ReplayPacer pacer(kFrameUs, kMaxReplayGapUs);
  Drawn(&pacer, kT0);
  EXPECT_EQ(Drawn(&pacer, kT0 + 500'000, /*limit=*/2),
            (std::vector<int64_t>{kT0 + 100'000, kT0 + 200'000}));
  EXPECT_EQ(Drawn(&pacer, kT0 + 400'000), (std::vector<int64_t>{kT0 + 300'000, kT0 + 400'000}));
}

TEST(ApplyKey, ZoomsPansTogglesAndAsksToQuitOrSave) {
  RenderOptions render;
  ViewState view;
  EXPECT_EQ(ApplyKey('+', &render, &view), KeyAction::kNone);
  EXPECT_DOUBLE_EQ(render.zoom, 1.25);
  // A quarter metre at zoom 1, divided by the zoom.
  EXPECT_EQ(ApplyKey('h', &render, &view), KeyAction::kNone);
  EXPECT_DOUBLE_EQ(render.pan_x_m, -0.2);
  EXPECT_EQ(ApplyKey('r', &render, &view), KeyAction::kNone);
  EXPECT_DOUBLE_EQ(render.zoom, 1.0);
  EXPECT_DOUBLE_EQ(render.pan_x_m, 0.0);
  const auto ultrasound = static_cast<size_t>(PoseSource::kUltrasound);
  ASSERT_TRUE(view.visible[ultrasound]);
  ApplyKey('2', &render, &view);
  EXPECT_FALSE(view.visible[ultrasound]);
  EXPECT_EQ(ApplyKey('q', &render, &view), KeyAction::kQuit);
  EXPECT_EQ(ApplyKey(27, &render, &view), KeyAction::kQuit);
  EXPECT_EQ(ApplyKey('s', &render, &view), KeyAction::kScreenshot);
}

TEST(ViewerAppOptions, RefusesAnFpsOutOfRangeOrHeadlessWithNothingToWrite) {
  ViewerAppOptions options;
  std::string error;
  EXPECT_TRUE(options.IsValid(&error)) << error;
  options.fps = 0.0;
  EXPECT_FALSE(options.IsValid(&error));
  options = ViewerAppOptions{};
  options.headless = true;
  EXPECT_FALSE(options.IsValid(&error));
  EXPECT_EQ(error, "--headless needs --png or --video");
}

// A headless replay writes one frame per ReplayPacer instant of the log's
// events, and the last picture, at the asked size.
TEST(ReplayIntoView, WritesAFrameAtEveryPacedInstantAndTheLastPicture) {
  const std::string log = roomfix::testing::SourceDir() + "/tests/data/pipeline_replay.lcm";
  Site site;
  std::string error;
  ASSERT_TRUE(LoadSite(roomfix::testing::DemoSitePath(), &site, &error)) << error;
  roomfix::testing::TempDir dir;
  ViewerAppOptions options;
  options.headless = true;
  options.fps = 5.0;
  options.log = log;
  options.video = dir.File("frames");
  options.png = dir.File("last.png");
  RenderOptions render;
  render.width_px = 320;
  render.height_px = 240;
  ASSERT_EQ(ReplayIntoView(site, ViewerNodeOptions{}, &render, options, nullptr, &error), 0)
      << error;

  // The instants, counted independently over the same log's event times.
  ReplayPacer pacer(options.frame_us(), kMaxReplayGapUs);
  int64_t expected = 0;
  LoopbackBus bus;
  ReplayOptions replay;
  replay.on_time = [&](int64_t utime) {
    pacer.AdvanceTo(utime, [&](int64_t) { return ++expected > 0; });
  };
  ASSERT_TRUE(ReplayLog(log, &bus, replay).ok);
  ASSERT_GT(expected, 20);  // 5.6 s at 5 fps
  int64_t written = 0;
  for (const auto& entry : std::filesystem::directory_iterator(options.video)) {
    written += entry.path().extension() == ".png";
  }
  EXPECT_EQ(written, expected);
  const cv::Mat last = cv::imread(options.png);
  EXPECT_EQ(last.cols, 320);
  EXPECT_EQ(last.rows, 240);
}

TEST(ReplayIntoView, SaysWhyALogCannotBeRead) {
  Site site;
  ViewerAppOptions options;
  options.headless = true;
  options.png = "/nonexistent/x.png";
  options.log = "/nonexistent/run.lcm";
  RenderOptions render;
  std::string error;
  EXPECT_EQ(ReplayIntoView(site, ViewerNodeOptions{}, &render, options, nullptr, &error), 1);
  EXPECT_NE(error.find("/nonexistent/run.lcm"), std::string::npos) << error;
}

}  // namespace
}  // namespace roomfix::viewer
