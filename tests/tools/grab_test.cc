// `roomfix grab`, run as a user would: frames from the demo site's synthetic
// webcam, from image files and from video files, and each refusal.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "tests/testing/demo_site.h"
#include "tests/testing/test_paths.h"

namespace roomfix {
namespace {

using testing::BinDir;
using testing::ChildProcess;
using testing::DemoSitePath;
using testing::ReadFile;
using testing::TempDir;

// The demo site's camera (config/sites/demo_room.yaml).
constexpr int kWidthPx = 1920;
constexpr int kHeightPx = 1080;
constexpr char kSimDevice[] = "device: \"sim:webcam\"";

using RunResult = testing::ToolRun;

RunResult Roomfix(const std::vector<std::string>& args) {
  return testing::RunTool("roomfix", args, 120.0);
}

// The demo site with its camera's device replaced.
std::string SiteWithDevice(const TempDir& dir, const std::string& device) {
  std::string error;
  const std::string path =
      testing::WriteDemoSiteVariant(dir, "grab", kSimDevice, "device: \"" + device + "\"", &error);
  EXPECT_FALSE(path.empty()) << error;
  return path;
}

struct CsvRow {
  std::string file;
  int64_t seq = 0;
  int64_t capture_utime = 0;
  int width_px = 0;
  int height_px = 0;
  std::string format;
};

std::vector<CsvRow> ReadFramesCsv(const std::string& path) {
  std::istringstream lines(ReadFile(path));
  std::string line;
  std::getline(lines, line);
  EXPECT_EQ(line, "file,frame_seq,capture_utime,width_px,height_px,format");
  std::vector<CsvRow> rows;
  while (std::getline(lines, line)) {
    std::replace(line.begin(), line.end(), ',', ' ');
    std::istringstream fields(line);
    CsvRow r;
    fields >> r.file >> r.seq >> r.capture_utime >> r.width_px >> r.height_px >> r.format;
    EXPECT_FALSE(fields.fail()) << line;
    rows.push_back(r);
  }
  return rows;
}

std::vector<std::string> FilesIn(const std::string& dir, const std::string& extension) {
  std::vector<std::string> names;
  for (const auto& entry : std::filesystem::directory_iterator(dir)) {
    if (entry.path().extension() == extension) names.push_back(entry.path().filename().string());
  }
  std::sort(names.begin(), names.end());
  return names;
}

// Checks that each row's file decodes to the size the row states.
void ExpectRowsDecode(const std::string& dir, const std::vector<CsvRow>& rows, int width_px,
                      int height_px) {
  for (const CsvRow& r : rows) {
    const cv::Mat image = cv::imread(dir + "/" + r.file, cv::IMREAD_COLOR);
    ASSERT_FALSE(image.empty()) << r.file;
    EXPECT_EQ(image.cols, width_px) << r.file;
    EXPECT_EQ(image.rows, height_px) << r.file;
    EXPECT_EQ(r.width_px, width_px);
    EXPECT_EQ(r.height_px, height_px);
  }
}

TEST(RoomfixGrab, WritesTheSyntheticWebcamsJpegFramesEverySoManySeconds) {
  TempDir dir;
  const std::string out = dir.File("frames");
  const RunResult r =
      Roomfix({"grab", "--site", DemoSitePath(), "--out", out, "--count", "3", "--every", "0.2"});
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("camera 0: synthetic camera 1920x1080"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("wrote 3 frames and frames.csv to " + out), std::string::npos) << r.out;
  const std::vector<CsvRow> rows = ReadFramesCsv(out + "/frames.csv");
  ASSERT_EQ(rows.size(), 3u);
  EXPECT_EQ(FilesIn(out, ".jpg"),
            (std::vector<std::string>{"frame_0000.jpg", "frame_0001.jpg", "frame_0002.jpg"}));
  for (size_t i = 0; i < rows.size(); ++i) {
    EXPECT_EQ(rows[i].file, FilesIn(out, ".jpg")[i]);
    EXPECT_EQ(rows[i].format, "jpeg");
    if (i > 0) {
      EXPECT_GT(rows[i].seq, rows[i - 1].seq);
      // The synthetic camera stamps seq / fps from its start: 0.2 s at
      // 30 fps is at least 6 frames on.
      EXPECT_GE(rows[i].capture_utime - rows[i - 1].capture_utime, 200000);
      EXPECT_GE(rows[i].seq - rows[i - 1].seq, 6);
    }
  }
  ExpectRowsDecode(out, rows, kWidthPx, kHeightPx);
}

// The tripod walk of docs/bringup.md: each grab names its frame after the
// surveyed point and lists it in points.csv at the robot's marker height
// (0.20 m on the demo site); a point grabbed again replaces its row. On the
// synthetic camera the simulator stands the markers there: calibrate finds
// exactly one marker in each frame (the moving robot would be elsewhere).
TEST(RoomfixGrab, TripodFramesAreNamedAfterTheirPointAndListedInPointsCsv) {
  TempDir dir;
  const std::string out = dir.File("tripod");
  for (const char* point : {"1.0,1.0", "3.0,2.0", "1.0,1.0"}) {
    const RunResult r =
        Roomfix({"grab", "--site", DemoSitePath(), "--out", out, "--tripod", point});
    ASSERT_EQ(r.exit_code, 0) << r.out;
  }
  EXPECT_EQ(FilesIn(out, ".jpg"),
            (std::vector<std::string>{"tripod_1.0_1.0.jpg", "tripod_3.0_2.0.jpg"}));
  EXPECT_EQ(ReadFile(out + "/points.csv"),
            "image,x_m,y_m,height_m\ntripod_3.0_2.0.jpg,3,2,0.2\ntripod_1.0_1.0.jpg,1,1,0.2\n");
  // The synthetic robot stands where it was put: found in both frames, and
  // its markers 2 m and 1 m apart on the floor are hundreds of pixels apart
  // in the image (about 330 px per metre below a 120-degree 1080p lens).
  auto found_at = [&](const std::string& image) {
    const RunResult r = Roomfix(
        {"detect", out + "/" + image, "--site", DemoSitePath(), "--out", dir.File("view.png")});
    EXPECT_EQ(r.exit_code, 0) << r.out;
    double u = -1, v = -1;
    const size_t at = r.out.find("robot 1: found at (");
    EXPECT_NE(at, std::string::npos) << r.out;
    if (at != std::string::npos)
      std::sscanf(r.out.c_str() + at, "robot 1: found at (%lf, %lf)", &u, &v);
    return std::make_pair(u, v);
  };
  const auto a = found_at("tripod_1.0_1.0.jpg");
  const auto b = found_at("tripod_3.0_2.0.jpg");
  EXPECT_GT(std::hypot(a.first - b.first, a.second - b.second), 400.0);
}

TEST(RoomfixGrab, RefusesATripodPointThatIsNotAPointOfTheRoom) {
  TempDir dir;
  for (const char* point : {"1.0", "1.0,", "a,b", "1.0,2.0,3.0", "9.0,1.0", "nan,1"}) {
    const RunResult r =
        Roomfix({"grab", "--site", DemoSitePath(), "--out", dir.File("t"), "--tripod", point});
    EXPECT_EQ(r.exit_code, 1) << point << ": " << r.out;
    EXPECT_NE(r.out.find("--tripod " + std::string(point)), std::string::npos) << r.out;
  }
}

TEST(RoomfixGrab, CopiesJpegFilesByteForByteAfterTheSkippedOnes) {
  TempDir dir;
  const std::string source = dir.File("rendered");
  const RunResult render = Roomfix({"render-camera", "--site", DemoSitePath(), "--out", source,
                                    "--duration", "0.2", "--fps", "30"});
  ASSERT_EQ(render.exit_code, 0) << render.out;
  const std::vector<std::string> inputs = FilesIn(source, ".jpg");
  ASSERT_EQ(inputs.size(), 6u);
  const std::string site = SiteWithDevice(dir, source + "/*.jpg");
  const std::string out = dir.File("frames");
  const RunResult r =
      Roomfix({"grab", "--site", site, "--out", out, "--count", "4", "--skip", "1"});
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("properties: not applied (a file has no controls)"), std::string::npos)
      << r.out;
  const std::vector<CsvRow> rows = ReadFramesCsv(out + "/frames.csv");
  ASSERT_EQ(rows.size(), 4u);
  for (size_t i = 0; i < rows.size(); ++i) {
    EXPECT_EQ(rows[i].seq, static_cast<int64_t>(i + 1));
    EXPECT_EQ(rows[i].format, "jpeg");
    // The camera's own bytes, not re-encoded.
    EXPECT_EQ(ReadFile(out + "/" + rows[i].file), ReadFile(source + "/" + inputs[i + 1]))
        << rows[i].file;
    // Files are stamped on a virtual clock at the camera's 30 fps.
    if (i > 0) {
      EXPECT_NEAR(rows[i].capture_utime - rows[i - 1].capture_utime, 33333, 1);
    }
  }
  ExpectRowsDecode(out, rows, kWidthPx, kHeightPx);
}

TEST(RoomfixGrab, WritesRawFramesAsLosslessPng) {
  TempDir dir;
  std::filesystem::create_directories(dir.File("png"));
  std::vector<cv::Mat> inputs;
  for (int i = 0; i < 2; ++i) {
    cv::Mat image(kHeightPx, kWidthPx, CV_8UC3, cv::Scalar(20 + i, 90, 200));
    cv::circle(image, cv::Point(400 + 300 * i, 500), 60, cv::Scalar(0, 128, 255), -1);
    ASSERT_TRUE(cv::imwrite(dir.File("png/in_" + std::to_string(i) + ".png"), image));
    inputs.push_back(image);
  }
  const std::string out = dir.File("frames");
  const RunResult r = Roomfix(
      {"grab", "--site", SiteWithDevice(dir, dir.File("png")), "--out", out, "--count", "2"});
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const std::vector<CsvRow> rows = ReadFramesCsv(out + "/frames.csv");
  ASSERT_EQ(rows.size(), 2u);
  for (size_t i = 0; i < rows.size(); ++i) {
    EXPECT_EQ(rows[i].file, "frame_000" + std::to_string(i) + ".png");
    EXPECT_EQ(rows[i].format, "raw");
    const cv::Mat back = cv::imread(out + "/" + rows[i].file, cv::IMREAD_COLOR);
    ASSERT_EQ(back.size(), inputs[i].size());
    EXPECT_EQ(cv::norm(back, inputs[i], cv::NORM_INF), 0.0) << rows[i].file;
  }
}

TEST(RoomfixGrab, SpacesAVideosFramesByItsVirtualClock) {
  TempDir dir;
  const std::string clip = dir.File("clip.avi");
  const RunResult render = Roomfix({"render-camera", "--site", DemoSitePath(), "--out", clip,
                                    "--duration", "0.4", "--fps", "30"});
  ASSERT_EQ(render.exit_code, 0) << render.out;
  const std::string out = dir.File("frames");
  const RunResult r = Roomfix({"grab", "--site", SiteWithDevice(dir, clip), "--out", out, "--count",
                               "3", "--every", "0.1"});
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const std::vector<CsvRow> rows = ReadFramesCsv(out + "/frames.csv");
  ASSERT_EQ(rows.size(), 3u);
  // 0.1 s at the site's 30 fps: every third frame.
  EXPECT_EQ(rows[0].seq, 0);
  EXPECT_EQ(rows[1].seq, 3);
  EXPECT_EQ(rows[2].seq, 6);
  EXPECT_EQ(rows[2].capture_utime - rows[0].capture_utime, 200000);
  ExpectRowsDecode(out, rows, kWidthPx, kHeightPx);
}

TEST(RoomfixGrab, ReportsFramesOfAnotherSizeThanTheSites) {
  TempDir dir;
  const std::string clip = dir.File("small.avi");
  {
    cv::VideoWriter writer(clip, cv::VideoWriter::fourcc('M', 'J', 'P', 'G'), 30.0,
                           cv::Size(320, 240));
    ASSERT_TRUE(writer.isOpened());
    for (int i = 0; i < 4; ++i) writer.write(cv::Mat(240, 320, CV_8UC3, cv::Scalar(i, 80, 160)));
  }
  const std::string out = dir.File("frames");
  const RunResult r =
      Roomfix({"grab", "--site", SiteWithDevice(dir, clip), "--out", out, "--count", "2"});
  EXPECT_EQ(r.exit_code, 1) << r.out;
  EXPECT_NE(r.out.find("2 of 2 frames are 320x240, not camera 0's 1920x1080"), std::string::npos)
      << r.out;
  // The frames are still written, to look at.
  const std::vector<CsvRow> rows = ReadFramesCsv(out + "/frames.csv");
  ASSERT_EQ(rows.size(), 2u);
  ExpectRowsDecode(out, rows, 320, 240);
}

TEST(RoomfixGrab, SaysWhenTheFilesRunOutBeforeTheCount) {
  TempDir dir;
  std::filesystem::create_directories(dir.File("png"));
  for (int i = 0; i < 2; ++i) {
    ASSERT_TRUE(cv::imwrite(dir.File("png/" + std::to_string(i) + ".png"),
                            cv::Mat(kHeightPx, kWidthPx, CV_8UC3, cv::Scalar(i, 0, 0))));
  }
  const std::string out = dir.File("frames");
  const RunResult r = Roomfix(
      {"grab", "--site", SiteWithDevice(dir, dir.File("png")), "--out", out, "--count", "5"});
  EXPECT_EQ(r.exit_code, 1) << r.out;
  EXPECT_NE(r.out.find("2 of 5 frames written"), std::string::npos) << r.out;
  EXPECT_EQ(ReadFramesCsv(out + "/frames.csv").size(), 2u);
}

TEST(RoomfixGrab, RefusesAnUnknownCameraBeforeMakingTheFolder) {
  TempDir dir;
  const RunResult r =
      Roomfix({"grab", "--site", DemoSitePath(), "--camera", "7", "--out", dir.File("frames")});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.out.find("roomfix grab: " + DemoSitePath() + ": the site has no camera with id 7"),
            std::string::npos)
      << r.out;
  EXPECT_FALSE(std::filesystem::exists(dir.File("frames")));
  const RunResult negative =
      Roomfix({"grab", "--site", DemoSitePath(), "--camera", "-1", "--out", dir.File("frames")});
  EXPECT_EQ(negative.exit_code, 1);
  EXPECT_NE(negative.out.find("roomfix grab: --camera must be a site camera's id (0 or more), "
                              "not -1"),
            std::string::npos)
      << negative.out;
}

TEST(RoomfixGrab, KeepsWhatItWroteWhenInterrupted) {
  TempDir dir;
  const std::string out = dir.File("frames");
  // One frame every 30 s: the first is written at once, then SIGINT.
  testing::ChildProcess p({BinDir() + "/roomfix", "grab", "--site", DemoSitePath(), "--out", out,
                           "--count", "3", "--every", "30"},
                          dir.File("out.txt"));
  ASSERT_TRUE(testing::WaitForPath(out + "/frame_0000.jpg", 60));
  p.Signal(SIGINT);
  EXPECT_EQ(p.Wait(30), 1);
  const std::vector<CsvRow> rows = ReadFramesCsv(out + "/frames.csv");
  ASSERT_EQ(rows.size(), 1u);
  EXPECT_EQ(rows[0].file, "frame_0000.jpg");
  ExpectRowsDecode(out, rows, kWidthPx, kHeightPx);
}

TEST(RoomfixGrab, RefusesADeviceThatCannotBeOpened) {
  TempDir dir;
  RunResult r =
      Roomfix({"grab", "--site", SiteWithDevice(dir, "/dev/video99"), "--out", dir.File("frames")});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.out.find("roomfix grab: camera 0: cannot open /dev/video99: no such device"),
            std::string::npos)
      << r.out;
  r = Roomfix({"grab", "--site", SiteWithDevice(dir, dir.File("missing.avi")), "--out",
               dir.File("frames")});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.out.find("cannot open video " + dir.File("missing.avi") + ": no such file"),
            std::string::npos)
      << r.out;
  r = Roomfix(
      {"grab", "--site", SiteWithDevice(dir, dir.File("none/*.jpg")), "--out", dir.File("frames")});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.out.find("no image files match"), std::string::npos) << r.out;
}

TEST(RoomfixGrab, RefusesAnOutFolderItCannotWrite) {
  TempDir dir;
  ASSERT_TRUE(testing::WriteFile(dir.File("plain"), "a file, not a folder\n"));
  const RunResult r =
      Roomfix({"grab", "--site", DemoSitePath(), "--out", dir.File("plain/frames")});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.out.find("roomfix grab: " + dir.File("plain/frames") + ": cannot make the folder"),
            std::string::npos)
      << r.out;
}

TEST(RoomfixGrab, RefusesACountBelowOne) {
  TempDir dir;
  for (const char* count : {"0", "-3"}) {
    const RunResult r =
        Roomfix({"grab", "--site", DemoSitePath(), "--out", dir.File("frames"), "--count", count});
    EXPECT_EQ(r.exit_code, 1);
    EXPECT_NE(r.out.find(std::string("roomfix grab: --count must be at least 1, not ") + count),
              std::string::npos)
        << r.out;
  }
  EXPECT_FALSE(std::filesystem::exists(dir.File("frames")));
}

TEST(RoomfixGrab, GivesUpWhenNoFrameComesInTime) {
  TempDir dir;
  // No frame of the synthetic camera is rendered within a microsecond.
  const RunResult r = Roomfix(
      {"grab", "--site", DemoSitePath(), "--out", dir.File("frames"), "--timeout", "0.000001"});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.out.find("roomfix grab: no frame from sim:webcam in 1e-06 s (--timeout)"),
            std::string::npos)
      << r.out;
  EXPECT_FALSE(std::filesystem::exists(dir.File("frames/frames.csv")));
}

}  // namespace
}  // namespace roomfix
