// roomfix_viewer in a real window: under Xvfb (a real X server without a
// screen), the window shows a replayed log; a screenshot of the whole
// display, taken by xwd, must show a picture, not a blank screen.
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <unistd.h>

#include <chrono>
#include <cstdint>
#include <cstdlib>
#include <map>
#include <string>
#include <thread>

#include "tests/testing/demo_site.h"
#include "tests/testing/test_paths.h"

namespace roomfix {
namespace {

using testing::BinDir;
using testing::ChildProcess;
using testing::DemoSitePath;
using testing::SourceDir;

bool OnPath(const std::string& program) {
  return std::system(("command -v " + program + " > /dev/null 2>&1").c_str()) == 0;
}

uint32_t Be32(const std::string& b, size_t offset) {
  return (static_cast<uint32_t>(static_cast<uint8_t>(b[offset])) << 24) |
         (static_cast<uint32_t>(static_cast<uint8_t>(b[offset + 1])) << 16) |
         (static_cast<uint32_t>(static_cast<uint8_t>(b[offset + 2])) << 8) |
         static_cast<uint8_t>(b[offset + 3]);
}

// The pixels of an XWD file (X Window Dump, version 7, ZPixmap, 24 or 32
// bits per pixel as Xvfb's 24-bit screen gives): distinct colours and the
// share of pixels that are not the most common colour.
struct ScreenStats {
  bool parsed = false;
  std::string error;
  int width = 0;
  int height = 0;
  size_t distinct_colours = 0;
  double share_not_background = 0.0;
};

ScreenStats ReadXwd(const std::string& bytes) {
  ScreenStats s;
  if (bytes.size() < 100) {
    s.error = "file too short";
    return s;
  }
  const uint32_t header_size = Be32(bytes, 0);
  const uint32_t version = Be32(bytes, 4);
  const uint32_t width = Be32(bytes, 16);
  const uint32_t height = Be32(bytes, 20);
  const uint32_t bits_per_pixel = Be32(bytes, 44);
  const uint32_t bytes_per_line = Be32(bytes, 48);
  const uint32_t ncolors = Be32(bytes, 76);
  if (version != 7 || (bits_per_pixel != 24 && bits_per_pixel != 32)) {
    s.error = "unexpected XWD version " + std::to_string(version) + " or depth " +
              std::to_string(bits_per_pixel);
    return s;
  }
  const size_t pixels = header_size + static_cast<size_t>(ncolors) * 12;
  if (bytes.size() < pixels + static_cast<size_t>(bytes_per_line) * height) {
    s.error = "pixel data truncated";
    return s;
  }
  std::map<uint32_t, size_t> counts;
  for (uint32_t y = 0; y < height; y += 2) {
    for (uint32_t x = 0; x < width; x += 2) {
      // The colour's byte order does not matter for counting colours.
      const size_t at = pixels + static_cast<size_t>(y) * bytes_per_line + x * (bits_per_pixel / 8);
      uint32_t colour = 0;
      for (uint32_t k = 0; k < 3; ++k) colour = colour << 8 | static_cast<uint8_t>(bytes[at + k]);
      counts[colour]++;
    }
  }
  size_t total = 0, most = 0;
  for (const auto& [colour, n] : counts) {
    total += n;
    most = std::max(most, n);
  }
  s.parsed = true;
  s.width = static_cast<int>(width);
  s.height = static_cast<int>(height);
  s.distinct_colours = counts.size();
  s.share_not_background = total > 0 ? 1.0 - static_cast<double>(most) / total : 0.0;
  return s;
}

TEST(RoomfixViewerWindow, ShowsAReplayedLogInARealWindowUnderXvfb) {
  if (!OnPath("Xvfb") || !OnPath("xwd")) {
    GTEST_SKIP() << "Xvfb or xwd missing (Debian packages xvfb and x11-apps)";
  }
  testing::TempDir dir;
  const std::string display = ":" + std::to_string(90 + ::getpid() % 100);
  ChildProcess xvfb({"Xvfb", display, "-screen", "0", "1400x900x24", "-nolisten", "tcp"});
  ASSERT_TRUE(xvfb.started());
  ::setenv("DISPLAY", display.c_str(), 1);
  // In the sanitizer build, the window's system libraries (Qt, D-Bus,
  // fontconfig) keep allocations until exit; only roomfix's leaks count.
  ::setenv("LSAN_OPTIONS", ("suppressions=" + SourceDir() + "/tests/lsan_suppressions.txt").c_str(),
           0);
  // The server is ready when a client can talk to it.
  bool up = false;
  for (int i = 0; i < 100 && !up; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    up =
        std::system(
            ("xwd -root -silent -display " + display + " -out /dev/null 2>/dev/null").c_str()) == 0;
  }
  ASSERT_TRUE(up) << "Xvfb did not come up on " << display;

  ChildProcess viewer({BinDir() + "/roomfix_viewer", "--config", DemoSitePath(), "--log",
                       SourceDir() + "/tests/data/trilat_replay.lcm", "--fps", "30", "--log-level",
                       "warn"});
  ASSERT_TRUE(viewer.started());
  // The replay takes about the log's 3 s at 30 fps; the last picture stays up.
  std::this_thread::sleep_for(std::chrono::seconds(4));
  ChildProcess shot(
      {"xwd", "-root", "-silent", "-display", display, "-out", dir.File("screen.xwd")});
  ASSERT_EQ(shot.Wait(20), 0);
  const ScreenStats s = ReadXwd(testing::ReadFile(dir.File("screen.xwd")));
  ASSERT_TRUE(s.parsed) << s.error;
  EXPECT_EQ(s.width, 1400);
  // A blank screen is one colour; the viewer draws a floor, a grid, a
  // panel, text, a trail and range circles.
  EXPECT_GT(s.distinct_colours, 20u);
  EXPECT_GT(s.share_not_background, 0.3);
  viewer.Signal(SIGTERM);
  EXPECT_EQ(viewer.Wait(10), 0);
  xvfb.Signal(SIGTERM);
  xvfb.Wait(10);
  ::unsetenv("DISPLAY");
}

TEST(RoomfixViewerHeadless, WritesAFramePerTickOfLogTimeAndTheLastPicture) {
  // trilat_replay.lcm spans 3.0 s: at 10 frames per second of log time that
  // is 31 frames (both ends included).
  testing::TempDir dir;
  ChildProcess viewer({BinDir() + "/roomfix_viewer", "--config", DemoSitePath(), "--headless",
                       "--log", SourceDir() + "/tests/data/trilat_replay.lcm", "--fps", "10",
                       "--video", dir.File("frames"), "--png", dir.File("last.png"), "--log-level",
                       "warn"});
  ASSERT_EQ(viewer.Wait(60), 0);
  int frames = 0;
  for (int k = 1; k <= 40; ++k) {
    const std::string name = fmt::format("{}/frame_{:06d}.png", dir.File("frames"), k);
    frames += ::access(name.c_str(), R_OK) == 0 ? 1 : 0;
  }
  EXPECT_EQ(frames, 31);
  EXPECT_EQ(::access(dir.File("last.png").c_str(), R_OK), 0);
}

}  // namespace
}  // namespace roomfix
