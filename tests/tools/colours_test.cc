// `roomfix colours`, run as a lab would: on the tripod and parked-robot
// images `roomfix render-camera` writes through the simulated webcam, on
// labelled real photos, and on hostile input.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <utility>
#include <vector>

#include "core/world/site.h"
#include "tests/testing/test_paths.h"
#include "tools/colours_site_edit.h"

namespace roomfix {
namespace {

using testing::BinDir;
using testing::ChildProcess;
using testing::ReadFile;
using testing::SourceDir;
using testing::TempDir;
using testing::WriteFile;

using RunResult = testing::ToolRun;

RunResult Roomfix(const std::vector<std::string>& args) {
  return testing::RunTool("roomfix", args, 300.0);
}

// The eight-robot site's tripod and parked robots through the webcam.
class EightRobotFrames : public ::testing::Test {
 protected:
  void SetUp() override {
    site_ = SourceDir() + "/config/sites/eight_robots.yaml";
    const RunResult r =
        Roomfix({"render-camera", "--site", site_, "--scenario", "webcam", "--tripod-grid",
                 dir_.File("frames"), "--tripod-step", "1.5", "--tripod-robots"});
    ASSERT_EQ(r.exit_code, 0) << r.out;
  }
  TempDir dir_;
  std::string site_;
};

TEST_F(EightRobotFrames, WritesASiteCopyWhoseClassesItDidNotTypeAndThatLoads) {
  // The copy beside the original, so its relative paths still resolve.
  const std::string out = SourceDir() + "/config/sites/.colours_test_copy.yaml";
  const RunResult r =
      Roomfix({"colours", "--site", site_, "--frames", dir_.File("frames"), "--out", out});
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("wrote " + out), std::string::npos) << r.out;
  for (const char* name : {"red", "yellow", "green", "blue"}) {
    EXPECT_NE(r.out.find(std::string("  ") + name), std::string::npos) << name << "\n" << r.out;
  }
  Site copy, original;
  std::string error;
  ASSERT_TRUE(LoadSite(out, &copy, &error)) << error;
  ASSERT_TRUE(LoadSite(site_, &original, &error)) << error;
  std::filesystem::remove(out);
  // Only the boxes changed: same classes, same robots, comments kept.
  ASSERT_EQ(copy.cameras.front().marker_classes.size(),
            original.cameras.front().marker_classes.size());
  EXPECT_EQ(copy.cameras.front().robots.size(), original.cameras.front().robots.size());
  bool some_box_differs = false;
  for (size_t i = 0; i < copy.cameras.front().marker_classes.size(); ++i) {
    const MarkerClass& a = copy.cameras.front().marker_classes[i];
    const MarkerClass& b = original.cameras.front().marker_classes[i];
    EXPECT_EQ(a.name, b.name);
    some_box_differs |= a.hsv_min != b.hsv_min || a.hsv_max != b.hsv_max;
    // Each learned hue range holds the hue the class's markers are painted
    // (the middle of the typed range: the simulator's rule).
    const int mid = b.hsv_min[0] <= b.hsv_max[0] ? (b.hsv_min[0] + b.hsv_max[0]) / 2
                                                 : ((b.hsv_min[0] + b.hsv_max[0] + 180) / 2) % 180;
    const bool inside = a.hsv_min[0] <= a.hsv_max[0] ? mid >= a.hsv_min[0] && mid <= a.hsv_max[0]
                                                     : mid >= a.hsv_min[0] || mid <= a.hsv_max[0];
    EXPECT_TRUE(inside) << a.name << " H " << a.hsv_min[0] << ".." << a.hsv_max[0] << " misses "
                        << mid;
  }
  EXPECT_TRUE(some_box_differs);
}

TEST_F(EightRobotFrames, WithoutPlacesTheClustersTakeTheSiteNamesTheirColoursFallIn) {
  // The frames alone, with no robots.csv or points.csv: named by the
  // site's current boxes.
  std::filesystem::remove(dir_.File("frames/robots.csv"));
  std::filesystem::remove(dir_.File("frames/points.csv"));
  const RunResult r = Roomfix({"colours", "--site", site_, "--frames", dir_.File("frames")});
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("0 marker(s) at known places"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("- {name: yellow, hsv_min: ["), std::string::npos) << r.out;
}

TEST_F(EightRobotFrames, SaysWhichClassesHoldUnderOtherLightAndProposesBoxesForEvery) {
  // The lighting scenario's frames at gains 1.4 (t = 4 s) and 0.6 (t = 7 s),
  // with a 30 % gradient, flicker and noise: the robots where they drive,
  // no known places, so each disc is judged by the nearest learned colour.
  std::filesystem::create_directories(dir_.File("other"));
  for (const char* t : {"4", "7"}) {
    const RunResult r =
        Roomfix({"render-camera", "--site", site_, "--scenario", "lighting", "--png",
                 dir_.File(std::string("other/at_") + t + ".png"), "--time", t});
    ASSERT_EQ(r.exit_code, 0) << r.out;
  }
  const RunResult r = Roomfix(
      {"colours", "--site", site_, "--frames", dir_.File("frames"), "--check", dir_.File("other")});
  ASSERT_EQ(r.exit_code, 0) << r.out;
  for (const char* name : {"red", "yellow", "green", "blue"}) {
    EXPECT_NE(r.out.find(std::string("  ") + name + ": holds ("), std::string::npos) << name << "\n"
                                                                                     << r.out;
  }
  EXPECT_NE(r.out.find("every class holds under every light given"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("boxes for every light"), std::string::npos) << r.out;
}

TEST_F(EightRobotFrames, AnotherLightWithNoMarkerInViewChecksNothingAndSaysSo) {
  std::filesystem::create_directories(dir_.File("dark"));
  std::string ppm = "P6\n1920 1080\n255\n";
  ppm.append(1920 * 1080 * 3, static_cast<char>(60));
  WriteFile(dir_.File("dark/grey.ppm"), ppm);
  const RunResult r = Roomfix(
      {"colours", "--site", site_, "--frames", dir_.File("frames"), "--check", dir_.File("dark")});
  EXPECT_NE(r.out.find("red: NOT SEEN"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("not every class holds, or was seen, under every light given"),
            std::string::npos)
      << r.out;
  EXPECT_EQ(r.out.find("every class holds under every light given"), std::string::npos) << r.out;
}

TEST_F(EightRobotFrames, RefusesFramesOfAnotherSizeThanTheCamera) {
  std::filesystem::create_directories(dir_.File("small"));
  std::string ppm = "P6\n960 540\n255\n";
  ppm.append(960 * 540 * 3, static_cast<char>(60));
  WriteFile(dir_.File("small/half.ppm"), ppm);
  const RunResult r = Roomfix({"colours", "--site", site_, "--frames", dir_.File("small")});
  EXPECT_EQ(r.exit_code, 1) << r.out;
  EXPECT_NE(r.out.find("960x540, not camera 0's 1920x1080"), std::string::npos) << r.out;
}

TEST(ColoursCommand, AsksWhichSiteClassEachUnknownColourIsAndTakesTheAnswer) {
  const std::string data = testing::SharedDataDir();
  if (data.empty()) GTEST_SKIP() << "../shared/data is absent: real-photo test not run";
  // The demo site's camera (orange and green classes) at the photo's size.
  TempDir dir;
  std::string site = ReadFile(SourceDir() + "/config/sites/demo_room.yaml");
  for (const auto& [from, to] :
       {std::pair<std::string, std::string>{"resolution: [1920, 1080]", "resolution: [413, 356]"},
        {"calibration: ../calibration/demo_room_camera.yaml", "# no calibration"}}) {
    ASSERT_NE(site.find(from), std::string::npos) << from;
    site.replace(site.find(from), from.size(), to);
  }
  WriteFile(dir.File("site.yaml"), site);
  std::filesystem::copy_file(data + "/opencv_samples/smarties.png", dir.File("smarties.png"));
  const std::vector<std::string> base = {
      "colours",    "--site", dir.File("site.yaml"), "--frames", dir.File("smarties.png"),
      "--lighting", "fixed",  "--min-radius",        "10"};
  RunResult r = Roomfix(base);
  EXPECT_EQ(r.exit_code, 3) << r.out;
  EXPECT_NE(r.out.find("which of the site's classes (orange, green) is each of colour_"),
            std::string::npos)
      << r.out;
  // The orange and green candies took the site's names by colour; the
  // others (blue, red, brown) are no marker of this site: "-" says so, and
  // the two boxes are proposed.
  std::vector<std::string> args = base;
  for (const char* n : {"colour_1=-", "colour_2=-", "colour_3=-"}) {
    args.push_back("--name");
    args.push_back(n);
  }
  r = Roomfix(args);
  EXPECT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("- {name: orange, hsv_min: ["), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("- {name: green, hsv_min: ["), std::string::npos) << r.out;
}

TEST(ColoursCommand, RefusesFramesWithoutMarkersCorruptFilesAndFramesLargerThanTheCamera) {
  TempDir dir;
  const std::string site = SourceDir() + "/config/sites/demo_room.yaml";
  // A frame with the demo robot's markers, for the flag checks below.
  const RunResult grey =
      Roomfix({"render-camera", "--site", site, "--png", dir.File("floor.png"), "--time", "0"});
  ASSERT_EQ(grey.exit_code, 0) << grey.out;
  WriteFile(dir.File("not_an_image.jpg"), "this is not a JPEG");
  RunResult r = Roomfix({"colours", "--site", site, "--frames", dir.File("not_an_image.jpg")});
  EXPECT_EQ(r.exit_code, 1) << r.out;
  EXPECT_NE(r.out.find("not_an_image.jpg"), std::string::npos) << r.out;
  r = Roomfix({"colours", "--site", site, "--frames", dir.path() + "/missing.png"});
  EXPECT_EQ(r.exit_code, 1) << r.out;
  std::filesystem::create_directory(dir.File("empty"));
  r = Roomfix({"colours", "--site", site, "--frames", dir.File("empty")});
  EXPECT_EQ(r.exit_code, 1) << r.out;
  EXPECT_NE(r.out.find("no image file"), std::string::npos) << r.out;
  r = Roomfix({"colours", "--site", site, "--frames", dir.File("floor.png"), "--name", "x"});
  EXPECT_NE(r.exit_code, 0) << r.out;
  r = Roomfix({"colours", "--site", site, "--frames", dir.File("floor.png"),
               "--white-balance-drift", "1.5"});
  EXPECT_EQ(r.exit_code, 2) << r.out;
  EXPECT_NE(r.out.find("[0, 1)"), std::string::npos) << r.out;
}

TEST(ColoursCommand, RefusesAFrameOfTheFloorAlone) {
  TempDir dir;
  const std::string site = SourceDir() + "/config/sites/demo_room.yaml";
  // A uniform grey frame of the camera's size (binary PPM).
  std::string ppm = "P6\n1920 1080\n255\n";
  ppm.append(1920 * 1080 * 3, static_cast<char>(120));
  WriteFile(dir.File("grey.ppm"), ppm);
  const RunResult r = Roomfix({"colours", "--site", site, "--frames", dir.File("grey.ppm")});
  EXPECT_EQ(r.exit_code, 1) << r.out;
  EXPECT_NE(r.out.find("no marker disc found"), std::string::npos) << r.out;
}

TEST(ReplaceClassBoxes, ChangesOnlyTheBoxesAndKeepsCommentsAndOtherCameras) {
  const std::string text =
      "# a comment\n"
      "cameras:\n"
      "  - id: 0\n"
      "    marker_classes:\n"
      "      - {name: red, hsv_min: [170, 110, 70], hsv_max: [8, 255, 255]}  # red\n"
      "  - id: 1\n"
      "    marker_classes:\n"
      "      - {name: red, hsv_min: [1, 2, 3], hsv_max: [4, 5, 6]}\n";
  vision::LearnedClass red;
  red.name = "red";
  red.hsv_min = {172, 60, 40};
  red.hsv_max = {7, 255, 255};
  std::string out, error;
  ASSERT_TRUE(ReplaceClassBoxes(text, 0, {red}, &out, &error)) << error;
  EXPECT_EQ(out,
            "# a comment\n"
            "cameras:\n"
            "  - id: 0\n"
            "    marker_classes:\n"
            "      - {name: red, hsv_min: [172, 60, 40], hsv_max: [7, 255, 255]}  # red\n"
            "  - id: 1\n"
            "    marker_classes:\n"
            "      - {name: red, hsv_min: [1, 2, 3], hsv_max: [4, 5, 6]}\n");
  red.name = "mauve";
  EXPECT_FALSE(ReplaceClassBoxes(text, 0, {red}, &out, &error));
  EXPECT_NE(error.find("no class 'mauve'"), std::string::npos) << error;
  const std::string block =
      "cameras:\n  - id: 0\n    marker_classes:\n      - name: red\n        hsv_min:\n"
      "          - 1\n          - 2\n          - 3\n        hsv_max: [4, 5, 6]\n";
  red.name = "red";
  EXPECT_FALSE(ReplaceClassBoxes(block, 0, {red}, &out, &error));
  EXPECT_NE(error.find("flow list"), std::string::npos) << error;
  EXPECT_FALSE(ReplaceClassBoxes("cameras: [", 0, {red}, &out, &error));
}

}  // namespace
}  // namespace roomfix
