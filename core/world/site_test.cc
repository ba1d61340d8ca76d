#include "core/world/site.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

#include "core/world/site_limits.h"
#include "tests/testing/demo_site.h"
#include "tests/testing/test_paths.h"

namespace roomfix {
namespace {

namespace fs = std::filesystem;
using testing::DemoSitePath;
using testing::SourceDir;

std::vector<std::string> YamlFilesIn(const std::string& dir) {
  std::vector<std::string> files;
  for (const auto& entry : fs::directory_iterator(dir)) {
    if (entry.path().extension() == ".yaml") files.push_back(entry.path().string());
  }
  std::sort(files.begin(), files.end());
  return files;
}

TEST(Site, LoadsEveryShippedSiteFile) {
  const auto files = YamlFilesIn(SourceDir() + "/config/sites");
  ASSERT_FALSE(files.empty());
  for (const auto& path : files) {
    Site site;
    std::string error;
    EXPECT_TRUE(LoadSite(path, &site, &error)) << error;
    EXPECT_EQ(site.path, path);
  }
}

TEST(Site, DemoRoomMatchesTheReferenceSetup) {
  Site site;
  std::string error;
  ASSERT_TRUE(LoadSite(DemoSitePath(), &site, &error)) << error;
  EXPECT_DOUBLE_EQ(site.room.size_x_m, 4.0);
  EXPECT_DOUBLE_EQ(site.room.size_y_m, 3.0);
  EXPECT_DOUBLE_EQ(site.room.grid_m, 0.5);

  ASSERT_EQ(site.receivers.size(), 4u);
  // One receiver in each corner of the floor rectangle, all at one height.
  std::set<std::pair<double, double>> corners;
  for (const auto& r : site.receivers) {
    corners.insert({r.position_m[0], r.position_m[1]});
    EXPECT_DOUBLE_EQ(r.position_m[2], site.receivers[0].position_m[2]);
  }
  EXPECT_EQ(corners, (std::set<std::pair<double, double>>{{0, 0}, {4, 0}, {4, 3}, {0, 3}}));

  ASSERT_EQ(site.beacons.size(), 1u);
  EXPECT_DOUBLE_EQ(site.beacons[0].height_m, 1.3);

  ASSERT_EQ(site.cameras.size(), 1u);
  const Camera& cam = site.cameras[0];
  EXPECT_DOUBLE_EQ(cam.mount_position_m[2], 3.1);
  EXPECT_DOUBLE_EQ(cam.mount_position_m[0], 2.0);
  EXPECT_DOUBLE_EQ(cam.mount_position_m[1], 1.5);
  EXPECT_EQ(cam.width_px, 1920);
  EXPECT_EQ(cam.height_px, 1080);
  ASSERT_EQ(cam.robots.size(), 1u);
  EXPECT_EQ(cam.robots[0].position_marker, "orange");
  EXPECT_EQ(cam.robots[0].heading_marker, "green");

  ASSERT_EQ(site.simulation.robots.size(), 1u);
  ASSERT_NE(site.FindRobot(1), nullptr);
  EXPECT_EQ(*site.FindRobot(1)->beacon_id, 1);
}

TEST(Site, FindsReceiversAndBeaconsByIdAndAddress) {
  Site site;
  std::string error;
  ASSERT_TRUE(LoadSite(DemoSitePath(), &site, &error)) << error;
  const Receiver* r3 = site.FindReceiver(3);
  ASSERT_NE(r3, nullptr);
  EXPECT_EQ(site.FindReceiverByAddress(r3->address), r3);
  EXPECT_EQ(site.FindReceiver(99), nullptr);
  EXPECT_EQ(site.FindBeaconByAddress(0x0013A20042000001ull), site.FindBeacon(1));
  EXPECT_EQ(site.FindReceiverByAddress(0x0013A20042000001ull), nullptr);
}

// The eight-robot site tells its robots apart by ordered colour pairs: the
// marker code sizes the markers by role, every class may serve either role,
// and no two robots share a pair.
TEST(Site, EightRobotSiteSizesMarkersByRoleAndGivesEveryRobotItsOwnPair) {
  Site site;
  std::string error;
  ASSERT_TRUE(LoadSite(SourceDir() + "/config/sites/eight_robots.yaml", &site, &error)) << error;
  ASSERT_EQ(site.cameras.size(), 1u);
  const Camera& cam = site.cameras.front();
  ASSERT_TRUE(cam.marker_code.enabled());
  EXPECT_EQ(cam.marker_code.position_diameter_m, 0.12);
  EXPECT_EQ(cam.marker_code.heading_diameter_m, 0.06);
  EXPECT_EQ(cam.marker_code.heading_offset_m, 0.12);
  EXPECT_EQ(cam.marker_classes.size(), 4u);
  for (const MarkerClass& c : cam.marker_classes) EXPECT_EQ(c.diameter_m, 0.0) << c.name;
  ASSERT_EQ(cam.robots.size(), 8u);
  std::set<std::pair<std::string, std::string>> codes;
  for (const CameraRobot& r : cam.robots) {
    EXPECT_EQ(PositionMarkerDiameterM(cam, r), 0.12);
    EXPECT_EQ(HeadingMarkerDiameterM(cam, r), 0.06);
    EXPECT_TRUE(codes.insert({r.position_marker, r.heading_marker}).second) << r.robot_id;
  }
  // Robot 1 is red/green and robot 2 green/red: only the sizes tell them apart.
  EXPECT_EQ(cam.robots[0].position_marker, cam.robots[1].heading_marker);
  EXPECT_EQ(cam.robots[1].position_marker, cam.robots[0].heading_marker);
}

// Without a marker code the role comes from the class: its diameter is the
// markers' size.
TEST(Site, WithoutAMarkerCodeEachClassGivesItsOwnDiameter) {
  Site site;
  std::string error;
  ASSERT_TRUE(LoadSite(DemoSitePath(), &site, &error)) << error;
  const Camera& cam = site.cameras.front();
  EXPECT_FALSE(cam.marker_code.enabled());
  EXPECT_EQ(PositionMarkerDiameterM(cam, cam.robots[0]), 0.10);
  EXPECT_EQ(HeadingMarkerDiameterM(cam, cam.robots[0]), 0.05);
}

// Each file in tests/data/broken_sites starts with "# expect: <text>", the
// error the loader must give. The error is one line that names the file, the
// key and the problem.
TEST(Site, RejectsEveryBrokenSiteWithOneLineNamingFileAndKey) {
  const auto files = YamlFilesIn(SourceDir() + "/tests/data/broken_sites");
  ASSERT_GE(files.size(), 20u);
  for (const auto& path : files) {
    std::ifstream in(path);
    std::string first_line;
    std::getline(in, first_line);
    const std::string prefix = "# expect: ";
    ASSERT_EQ(first_line.rfind(prefix, 0), 0u) << path << " lacks an '# expect:' line";
    const std::string expected = first_line.substr(prefix.size());

    Site site;
    std::string error;
    EXPECT_FALSE(LoadSite(path, &site, &error)) << path << " loaded";
    EXPECT_EQ(error.rfind(path + ":", 0), 0u) << "error does not start with the file: " << error;
    EXPECT_NE(error.find(expected), std::string::npos)
        << path << "\n  expected: " << expected << "\n  got:      " << error;
    EXPECT_EQ(error.find('\n'), std::string::npos) << "more than one line: " << error;
  }
}

// The head of a small inline site: its sixth line is the third receiver.
constexpr char kTwoReceivers[] =
    "name: x\n"
    "room: {size_m: [4, 3], height_m: 3}\n"
    "receivers:\n"
    "  - {id: 1, address: '0x0000000000000001', position_m: [0, 0, 2]}\n"
    "  - {id: 2, address: '0x0000000000000002', position_m: [4, 0, 2]}\n";

TEST(Site, ErrorNamesTheLineOfTheOffendingKey) {
  const std::string text = std::string(kTwoReceivers) +
                           "  - {id: 3, address: '0x0000000000000003', position_m: [4, 3, nope]}\n";
  Site site;
  std::string error;
  ASSERT_FALSE(ParseSite(text, "inline.yaml", "", &site, &error));
  EXPECT_EQ(error, "inline.yaml:6: receivers[2].position_m[2]: expected a number, got 'nope'");
}

TEST(Site, MissingFileGivesOneLine) {
  Site site;
  std::string error;
  EXPECT_FALSE(LoadSite("/nonexistent/site.yaml", &site, &error));
  EXPECT_EQ(error, "/nonexistent/site.yaml: cannot open: No such file or directory");
}

TEST(Site, ResolvesCalibrationRelativeToTheSiteFile) {
  const std::string text = std::string(kTwoReceivers) +
                           "  - {id: 3, address: '0x0000000000000003', position_m: [4, 3, 2]}\n"
                           "cameras:\n"
                           "  - {id: 0, device: /dev/video0, resolution: [640, 480], fps: 30,\n"
                           "     mount_position_m: [2, 1.5, 2.9], calibration: cal/cam0.yaml,\n"
                           "     marker_classes: [], robots: []}\n";
  Site site;
  std::string error;
  ASSERT_TRUE(ParseSite(text, "inline.yaml", "/etc/roomfix", &site, &error)) << error;
  EXPECT_EQ(site.cameras[0].calibration_file, "/etc/roomfix/cal/cam0.yaml");
}

// The camera's timing (docs/camera.md, "Time of a marker") is optional and
// 0 by default, which stamps every marker with the frame's capture time.
TEST(Site, ReadsCameraTimingAndRobotTiltWithZeroDefaults) {
  const std::string head = std::string(kTwoReceivers) +
                           "  - {id: 3, address: '0x0000000000000003', position_m: [4, 3, 2]}\n"
                           "robots: [{id: 1}]\n"
                           "cameras:\n"
                           "  - {id: 0, device: /dev/video0, resolution: [640, 480], fps: 30,\n"
                           "     mount_position_m: [2, 1.5, 2.9],\n";
  const std::string tail =
      "     marker_classes: [{name: o, hsv_min: [5, 120, 120], hsv_max: [22, 255, 255],\n"
      "                       diameter_m: 0.1},\n"
      "                      {name: g, hsv_min: [40, 80, 60], hsv_max: [85, 255, 255],\n"
      "                       diameter_m: 0.05}],\n"
      "     robots: [{robot_id: 1, position_marker: o, heading_marker: g, marker_height_m: 0.2";
  Site site;
  std::string error;
  ASSERT_TRUE(ParseSite(head + tail + "}]}\n", "inline.yaml", "", &site, &error)) << error;
  EXPECT_EQ(site.cameras[0].readout_s, 0.0);
  EXPECT_EQ(site.cameras[0].exposure_s, 0.0);
  EXPECT_EQ(site.cameras[0].timestamp_latency_s, 0.0);
  EXPECT_EQ(site.cameras[0].robots[0].tilt_sigma_deg, 0.0);
  ASSERT_TRUE(
      ParseSite(head + "     readout_s: 0.03, exposure_s: 0.016, timestamp_latency_s: 0.08,\n" +
                    tail + ", tilt_sigma_deg: 1.5}]}\n",
                "inline.yaml", "", &site, &error))
      << error;
  EXPECT_DOUBLE_EQ(site.cameras[0].readout_s, 0.03);
  EXPECT_DOUBLE_EQ(site.cameras[0].exposure_s, 0.016);
  EXPECT_DOUBLE_EQ(site.cameras[0].timestamp_latency_s, 0.08);
  EXPECT_DOUBLE_EQ(site.cameras[0].robots[0].tilt_sigma_deg, 1.5);
  // A readout longer than the 33.3 ms frame period cannot be a rolling shutter.
  EXPECT_FALSE(ParseSite(head + "     readout_s: 0.04,\n" + tail + "}]}\n", "inline.yaml", "",
                         &site, &error));
  EXPECT_NE(error.find("inline.yaml:11: cameras[0].readout_s: must be at most the frame period"),
            std::string::npos)
      << error;
  EXPECT_FALSE(
      ParseSite(head + tail + ", tilt_sigma_deg: -1}]}\n", "inline.yaml", "", &site, &error));
  EXPECT_NE(error.find("cameras[0].robots[0].tilt_sigma_deg: must be between 0 and 30"),
            std::string::npos)
      << error;
}

// The shipped LIAS-CUHKSZ site files must carry the dataset's surveyed anchor
// positions exactly, so solving its real ranges against them is meaningful.
TEST(Site, LiasPlanarSitesMatchTheDatasetAnchors) {
  const std::string data = testing::SharedDataDir();
  if (data.empty()) GTEST_SKIP() << "../shared/data is absent: real-data check skipped";
  std::ifstream csv(data + "/uwb_lias_planar/anchors.csv");
  ASSERT_TRUE(csv.good()) << "uwb_lias_planar/anchors.csv missing from " << data;
  std::string line;
  std::getline(csv, line);  // header: session,anchor,x_m,y_m,z_m
  int checked = 0;
  std::map<std::string, Site> sites;
  while (std::getline(csv, line)) {
    std::istringstream row(line);
    std::string session, anchor, x, y, z;
    std::getline(row, session, ',');
    std::getline(row, anchor, ',');
    std::getline(row, x, ',');
    std::getline(row, y, ',');
    std::getline(row, z, ',');
    const std::string name = session == "8.14" ? "lias_planar_814" : "lias_planar_820";
    if (sites.count(name) == 0) {
      std::string error;
      ASSERT_TRUE(LoadSite(SourceDir() + "/config/sites/" + name + ".yaml", &sites[name], &error))
          << error;
    }
    const Receiver* r = sites[name].FindReceiver(std::stoi(anchor));
    ASSERT_NE(r, nullptr) << name << " anchor " << anchor;
    EXPECT_EQ(r->position_m[0], std::stod(x));
    EXPECT_EQ(r->position_m[1], std::stod(y));
    EXPECT_EQ(r->position_m[2], std::stod(z));
    ++checked;
  }
  EXPECT_EQ(checked, 16);
}

MarkerClass Hsv(const std::string& name, std::array<int, 3> lo, std::array<int, 3> hi) {
  MarkerClass c;
  c.name = name;
  c.hsv_min = lo;
  c.hsv_max = hi;
  c.diameter_m = 0.05;
  return c;
}

// The demo site's orange and green, which share no pixel.
const MarkerClass kOrange = Hsv("orange", {5, 120, 120}, {22, 255, 255});
const MarkerClass kGreen = Hsv("green", {40, 80, 60}, {85, 255, 255});

TEST(HsvRangesOverlap, DisjointHuesDoNotOverlap) {
  EXPECT_FALSE(HsvRangesOverlap(kOrange, kGreen));
  EXPECT_FALSE(HsvRangesOverlap(kGreen, kOrange));
}

TEST(HsvRangesOverlap, SharedBoundsCountAsOverlap) {
  // cv::inRange is inclusive: hue 22 falls in both.
  const MarkerClass yellow = Hsv("yellow", {22, 120, 120}, {35, 255, 255});
  EXPECT_TRUE(HsvRangesOverlap(kOrange, yellow));
  EXPECT_TRUE(HsvRangesOverlap(yellow, kOrange));
  const MarkerClass next = Hsv("yellow", {23, 120, 120}, {35, 255, 255});
  EXPECT_FALSE(HsvRangesOverlap(kOrange, next));
}

TEST(HsvRangesOverlap, SameHueSeparatedBySaturationOrValueDoesNotOverlap) {
  const MarkerClass pale = Hsv("pale", {5, 0, 120}, {22, 119, 255});
  const MarkerClass dark = Hsv("dark", {5, 120, 0}, {22, 255, 119});
  EXPECT_FALSE(HsvRangesOverlap(kOrange, pale));
  EXPECT_FALSE(HsvRangesOverlap(kOrange, dark));
  EXPECT_FALSE(HsvRangesOverlap(pale, dark));
}

TEST(HsvRangesOverlap, WrappingHueRange) {
  // Red wraps through 0: 170..179 and 0..8.
  const MarkerClass red = Hsv("red", {170, 120, 120}, {8, 255, 255});
  EXPECT_TRUE(HsvRangesOverlap(red, kOrange));  // 5..8 shared
  EXPECT_TRUE(HsvRangesOverlap(kOrange, red));
  EXPECT_TRUE(HsvRangesOverlap(red, Hsv("magenta", {150, 120, 120}, {172, 255, 255})));
  EXPECT_FALSE(HsvRangesOverlap(red, Hsv("pink", {150, 120, 120}, {169, 255, 255})));
  EXPECT_FALSE(HsvRangesOverlap(red, Hsv("amber", {9, 120, 120}, {20, 255, 255})));
  EXPECT_FALSE(HsvRangesOverlap(red, kGreen));
  // Two wrapping ranges always share hue 179 and 0.
  EXPECT_TRUE(HsvRangesOverlap(red, Hsv("crimson", {178, 120, 120}, {1, 255, 255})));
  EXPECT_FALSE(HsvRangesOverlap(red, Hsv("crimson", {178, 0, 120}, {1, 100, 255})));
}

// A third receiver after kTwoReceivers and a camera with two classes; the
// second class is on line 15.
std::string SiteWithClasses(const std::string& class_a, const std::string& class_b) {
  return std::string(kTwoReceivers) +
         "  - {id: 3, address: '0x0000000000000003', position_m: [4, 3, 2]}\n"
         "cameras:\n"
         "  - id: 0\n"
         "    device: /dev/video0\n"
         "    resolution: [640, 480]\n"
         "    fps: 30\n"
         "    mount_position_m: [2, 1.5, 2.9]\n"
         "    marker_classes:\n"
         "      - " +
         class_a +
         "\n"
         "      - " +
         class_b +
         "\n"
         "    robots: []\n";
}

TEST(Site, RejectsOverlappingColourClassesNamingBothAndTheSharedBox) {
  const std::string text = SiteWithClasses(
      "{name: orange, hsv_min: [5, 120, 120], hsv_max: [22, 255, 255], diameter_m: 0.1}",
      "{name: yellow, hsv_min: [15, 150, 100], hsv_max: [35, 200, 255], diameter_m: 0.05}");
  Site site;
  std::string error;
  ASSERT_FALSE(ParseSite(text, "inline.yaml", "", &site, &error));
  EXPECT_EQ(error,
            "inline.yaml:15: cameras[0].marker_classes[1]: colour class 'yellow' overlaps 'orange' "
            "(hue 15..22, saturation 150..200, value 120..255): a pixel could not be classified");
}

// The name is sent with every marker; receivers refuse one of 64 bytes or
// more, so the site must not allow it.
TEST(Site, RejectsAMarkerClassNameTooLongToSend) {
  const std::string long_name(kMaxMarkerClassNameBytes + 1, 'o');
  const std::string text = SiteWithClasses(
      "{name: " + long_name + ", hsv_min: [5, 120, 120], hsv_max: [22, 255, 255], diameter_m: 0.1}",
      "{name: green, hsv_min: [40, 80, 60], hsv_max: [85, 255, 255], diameter_m: 0.05}");
  Site site;
  std::string error;
  ASSERT_FALSE(ParseSite(text, "inline.yaml", "", &site, &error));
  EXPECT_NE(error.find("cameras[0].marker_classes[0].name: a marker class name must have 1 to 63 "
                       "characters"),
            std::string::npos)
      << error;
  const std::string fits = SiteWithClasses(
      "{name: " + long_name.substr(1) +
          ", hsv_min: [5, 120, 120], hsv_max: [22, 255, 255], diameter_m: 0.1}",
      "{name: green, hsv_min: [40, 80, 60], hsv_max: [85, 255, 255], diameter_m: 0.05}");
  EXPECT_TRUE(ParseSite(fits, "inline.yaml", "", &site, &error)) << error;
}

// Issue #28, item 2: a site names as many receivers as it likes, and
// every process and tool builds per-receiver structures from it (the
// survey took 76 s and 614 MB for 1 000, 24 GB for 10 000). A list over its
// cap is refused before any entry is read, from a file as from a message.
TEST(Site, RefusesAListOverItsCapBeforeReadingIt) {
  Site site;
  std::string error;
  const std::string at_cap = testing::DemoSiteTextWithReceivers(kMaxSiteReceivers - 4);
  ASSERT_FALSE(at_cap.empty());
  EXPECT_TRUE(ParseSite(at_cap, "inline.yaml", "", &site, &error)) << error;
  EXPECT_EQ(site.receivers.size(), kMaxSiteReceivers);
  const std::string over = testing::DemoSiteTextWithReceivers(10000);
  ASSERT_FALSE(ParseSite(over, "inline.yaml", "", &site, &error));
  EXPECT_EQ(error.rfind("inline.yaml:", 0), 0u) << error;
  EXPECT_NE(error.find(": receivers: lists 10004 entries, over the cap of 256"), std::string::npos)
      << error;
}

TEST(Site, RejectsOverlapThroughHueZero) {
  const std::string text = SiteWithClasses(
      "{name: red, hsv_min: [170, 120, 120], hsv_max: [8, 255, 255], diameter_m: 0.1}",
      "{name: rose, hsv_min: [175, 100, 100], hsv_max: [3, 255, 255], diameter_m: 0.05}");
  Site site;
  std::string error;
  ASSERT_FALSE(ParseSite(text, "inline.yaml", "", &site, &error));
  EXPECT_NE(error.find("colour class 'rose' overlaps 'red' (hue 0..3 and 175..179, saturation "
                       "120..255, value 120..255)"),
            std::string::npos)
      << error;
}

TEST(Site, AcceptsAWrappingRedBesideOrange) {
  const std::string text = SiteWithClasses(
      "{name: red, hsv_min: [170, 120, 120], hsv_max: [4, 255, 255], diameter_m: 0.1}",
      "{name: orange, hsv_min: [5, 120, 120], hsv_max: [22, 255, 255], diameter_m: 0.05}");
  Site site;
  std::string error;
  EXPECT_TRUE(ParseSite(text, "inline.yaml", "", &site, &error)) << error;
}

TEST(Site, DemoRoomColourClassesDoNotOverlap) {
  Site site;
  std::string error;
  ASSERT_TRUE(LoadSite(DemoSitePath(), &site, &error)) << error;
  const auto& classes = site.cameras.at(0).marker_classes;
  ASSERT_EQ(classes.size(), 2u);
  EXPECT_FALSE(HsvRangesOverlap(classes[0], classes[1]));
}

TEST(RadioAddress, ParsesTheCommonSpellings) {
  uint64_t a = 0;
  ASSERT_TRUE(ParseRadioAddress("0x0013A20040A1B2C3", &a));
  EXPECT_EQ(a, 0x0013A20040A1B2C3ull);
  ASSERT_TRUE(ParseRadioAddress("0013A200 40A1B2C3", &a));
  EXPECT_EQ(a, 0x0013A20040A1B2C3ull);
  ASSERT_TRUE(ParseRadioAddress("00:13:a2:00:40:a1:b2:c3", &a));
  EXPECT_EQ(a, 0x0013A20040A1B2C3ull);
  EXPECT_EQ(FormatRadioAddress(a), "0x0013A20040A1B2C3");
}

TEST(RadioAddress, RejectsWrongLengthAndNonHex) {
  uint64_t a = 0;
  EXPECT_FALSE(ParseRadioAddress("0x13A2", &a));
  EXPECT_FALSE(ParseRadioAddress("0x0013A20040A1B2C3FF", &a));
  EXPECT_FALSE(ParseRadioAddress("0x0013A20040A1B2CG", &a));
  EXPECT_FALSE(ParseRadioAddress("", &a));
}

// A process or tool whose --camera is left out takes the site's first
// camera; a given id must exist.
TEST(SiteFinders, FindCameraOrFirstTakesTheFirstCameraWhenNoIdIsGiven) {
  Site site;
  std::string error;
  ASSERT_TRUE(LoadSite(SourceDir() + "/config/sites/two_cameras.yaml", &site, &error)) << error;
  ASSERT_EQ(site.cameras.size(), 2u);
  EXPECT_EQ(site.FindCameraOrFirst(-1), &site.cameras.front());
  EXPECT_EQ(site.FindCameraOrFirst(site.cameras.back().id), &site.cameras.back());
  EXPECT_EQ(site.FindCamera(site.cameras.back().id), &site.cameras.back());
  EXPECT_EQ(site.FindCameraOrFirst(99), nullptr);
  EXPECT_EQ(Site{}.FindCameraOrFirst(-1), nullptr);
}

}  // namespace
}  // namespace roomfix

namespace roomfix {
namespace {

// Degrees to radians is one product: a few ulps.
constexpr double kYawTolerance_rad = 1e-12;

TEST(Site, ReadsObstaclesWithTheirShapesExtentsAndMotion) {
  const std::string text = std::string(kTwoReceivers) +
                           "  - {id: 3, address: '0x0000000000000003', position_m: [4, 3, 2]}\n"
                           "obstacles:\n"
                           "  - {type: box, name: cupboard, centre_m: [1, 2.7], size_m: [1.2, 0.5],"
                           " yaw_deg: 90, top_m: 2.0}\n"
                           "  - {type: cylinder, centre_m: [2, 1.5], radius_m: 0.25, bottom_m: 0.1,"
                           " top_m: 3}\n"
                           "  - type: cylinder\n    radius_m: 0.2\n    top_m: 1.8\n"
                           "    trajectory: {type: static, position_m: [3, 1]}\n";
  Site site;
  std::string error;
  ASSERT_TRUE(ParseSite(text, "o.yaml", ".", &site, &error)) << error;
  ASSERT_EQ(site.obstacles.size(), 3u);
  const Obstacle& box = site.obstacles[0];
  EXPECT_EQ(box.shape, Obstacle::Shape::kBox);
  EXPECT_EQ(box.name, "cupboard");
  EXPECT_EQ(box.size_m, (std::array<double, 2>{1.2, 0.5}));
  EXPECT_NEAR(box.yaw_rad, M_PI / 2, kYawTolerance_rad);
  EXPECT_EQ(box.bottom_m, 0.0);
  EXPECT_EQ(box.top_m, 2.0);
  const Obstacle& pillar = site.obstacles[1];
  EXPECT_EQ(pillar.shape, Obstacle::Shape::kCylinder);
  EXPECT_EQ(pillar.radius_m, 0.25);
  EXPECT_EQ(pillar.bottom_m, 0.1);
  EXPECT_EQ(pillar.CentreAt(100.0), (std::array<double, 2>{2, 1.5}));
  const Obstacle& person = site.obstacles[2];
  ASSERT_NE(person.trajectory, nullptr);
  EXPECT_EQ(person.CentreAt(5.0), (std::array<double, 2>{3, 1}));
}

}  // namespace
}  // namespace roomfix
