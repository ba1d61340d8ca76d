#include "core/world/site.h"

#include <fmt/format.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <set>
#include <sstream>
#include <stdexcept>
#include <tuple>
#include <utility>

#include "core/world/file_io.h"
#include "core/world/site_limits.h"
#include "core/world/yaml_reader.h"

namespace roomfix {
namespace {

// The site's own value types on top of the shared strict reader.
class Reader : public YamlReader {
 public:
  explicit Reader(const YamlReader& base) : YamlReader(base) {}

  uint64_t Address(const YAML::Node& node, const std::string& key) const {
    uint64_t address = 0;
    if (!node.IsScalar() || !ParseRadioAddress(node.Scalar(), &address)) {
      Fail(node, key, "expected a 64-bit radio address of 16 hex digits, e.g. 0x0013A20040A1B2C3");
    }
    return address;
  }

  // A 16-bit 802.15.4 short address (MY): 1 to 4 hex digits, below 0xFFFE
  // (0xFFFE and 0xFFFF mean "use the 64-bit address").
  uint16_t ShortAddress(const YAML::Node& node, const std::string& key) const {
    const std::string text = node.IsScalar() ? node.Scalar() : "";
    std::string digits =
        text.rfind("0x", 0) == 0 || text.rfind("0X", 0) == 0 ? text.substr(2) : text;
    const bool hex = !digits.empty() && digits.size() <= 4 &&
                     digits.find_first_not_of("0123456789abcdefABCDEF") == std::string::npos;
    const unsigned long value = hex ? std::stoul(digits, nullptr, 16) : 0xFFFFul;
    if (value >= 0xFFFE) {
      Fail(node, key, "expected a 16-bit short address below 0xFFFE, e.g. 0x1234");
    }
    return static_cast<uint16_t>(value);
  }

  // A list (ExpectSequence) of at most `cap` entries (site.h, "The most of
  // each list"): checked before any entry is read.
  void ExpectListOfAtMost(const YAML::Node& node, const std::string& key, size_t cap) const {
    ExpectSequence(node, key);
    if (node.size() > cap) {
      Fail(node, key,
           "lists " + std::to_string(node.size()) + " entries, over the cap of " +
               std::to_string(cap) + " (docs/site_file.md, \"Limits\")");
    }
  }

  // Reads the required integer `field` of an entry and checks that no
  // earlier entry had it ("duplicate <what> id N").
  int UniqueId(const YAML::Node& map, const std::string& key, const char* field, const char* what,
               std::set<int>* seen) const {
    const YAML::Node node = Required(map, key, field);
    const int id = Int(node, key + "." + field);
    if (!seen->insert(id).second) {
      Fail(node, key + "." + field, std::string("duplicate ") + what + " id " + std::to_string(id));
    }
    return id;
  }
};

using K = Reader;  // K::Join / K::Index build key paths.

Room ParseRoom(const Reader& r, const YAML::Node& node) {
  const std::string key = "room";
  r.ExpectMap(node, key);
  r.OnlyKeys(node, key, {"size_m", "min_corner_m", "height_m", "grid_m", "origin"});
  Room room;
  const YAML::Node size = r.Required(node, key, "size_m");
  const auto xy = r.Doubles<2>(size, "room.size_m");
  if (xy[0] <= 0.0 || xy[1] <= 0.0) r.Fail(size, "room.size_m", "sizes must be positive");
  room.size_x_m = xy[0];
  room.size_y_m = xy[1];
  if (node["min_corner_m"]) {
    const auto corner = r.Doubles<2>(node["min_corner_m"], "room.min_corner_m");
    room.min_x_m = corner[0];
    room.min_y_m = corner[1];
  }
  room.height_m = r.Positive(r.Required(node, key, "height_m"), "room.height_m");
  if (node["grid_m"]) room.grid_m = r.Positive(node["grid_m"], "room.grid_m");
  if (node["origin"]) room.origin = r.String(node["origin"], "room.origin");
  return room;
}

// Positions may sit on the walls and ceiling, so a small tolerance allows for
// surveying error; anything further out is a typo or a wrong unit.
constexpr double kOutsideRoomTolerance_m = 0.05;

void CheckInsideRoom(const Reader& r, const YAML::Node& node, const std::string& key,
                     const Room& room, const std::array<double, 3>& p) {
  const double t = kOutsideRoomTolerance_m;
  const double x0 = room.min_x_m;
  const double y0 = room.min_y_m;
  if (p[0] < x0 - t || p[0] > x0 + room.size_x_m + t || p[1] < y0 - t ||
      p[1] > y0 + room.size_y_m + t || p[2] < -t || p[2] > room.height_m + t) {
    std::ostringstream s;
    s << "position (" << p[0] << ", " << p[1] << ", " << p[2] << ") m is outside the room ("
      << room.size_x_m << " x " << room.size_y_m << " x " << room.height_m << " m from (" << x0
      << ", " << y0 << ", 0))";
    r.Fail(node, key, s.str());
  }
}

// Receivers on one line (in the floor plane) cannot fix a position in 2D: the
// mirror image across the line fits the ranges equally well. The test is the
// smaller principal spread of the receivers' (x, y): the square root of the
// smaller eigenvalue of their 2x2 covariance, compared with a centimetre.
constexpr double kCollinearSpread_m = 0.01;

double SmallerPrincipalSpread(const std::vector<Receiver>& receivers) {
  double mx = 0, my = 0;
  for (const auto& rc : receivers) {
    mx += rc.position_m[0];
    my += rc.position_m[1];
  }
  const double n = static_cast<double>(receivers.size());
  mx /= n;
  my /= n;
  double sxx = 0, syy = 0, sxy = 0;
  for (const auto& rc : receivers) {
    const double dx = rc.position_m[0] - mx;
    const double dy = rc.position_m[1] - my;
    sxx += dx * dx;
    syy += dy * dy;
    sxy += dx * dy;
  }
  sxx /= n;
  syy /= n;
  sxy /= n;
  const double mean = 0.5 * (sxx + syy);
  const double diff = std::sqrt(0.25 * (sxx - syy) * (sxx - syy) + sxy * sxy);
  return std::sqrt(std::max(0.0, mean - diff));
}

void ParseRadios(const Reader& r, const YAML::Node& root, Site* site) {
  std::map<uint64_t, std::string> address_owner;
  auto claim_address = [&](const YAML::Node& node, const std::string& key, uint64_t address) {
    auto [it, fresh] = address_owner.emplace(address, key);
    if (!fresh) {
      r.Fail(node, key,
             "duplicate address " + FormatRadioAddress(address) + " (also " + it->second + ")");
    }
  };

  std::map<uint16_t, std::string> short_owner;
  auto claim_short = [&](const YAML::Node& node, const std::string& key, uint16_t address) {
    auto [it, fresh] = short_owner.emplace(address, key);
    if (!fresh) {
      r.Fail(node, key,
             fmt::format("duplicate short address 0x{:04X} (also {})", address, it->second));
    }
  };

  const YAML::Node receivers = r.Required(root, "", "receivers");
  r.ExpectListOfAtMost(receivers, "receivers", kMaxSiteReceivers);
  std::set<int> receiver_ids;
  for (size_t i = 0; i < receivers.size(); ++i) {
    const YAML::Node node = receivers[i];
    const std::string key = K::Index("receivers", i);
    r.ExpectMap(node, key);
    r.OnlyKeys(node, key, {"id", "address", "short_address", "position_m", "range_offset_m"});
    Receiver rc;
    rc.id = r.UniqueId(node, key, "id", "receiver", &receiver_ids);
    const YAML::Node address = r.Required(node, key, "address");
    rc.address = r.Address(address, key + ".address");
    claim_address(address, key + ".address", rc.address);
    if (node["short_address"]) {
      rc.short_address = r.ShortAddress(node["short_address"], key + ".short_address");
      claim_short(node["short_address"], key + ".short_address", *rc.short_address);
    }
    const YAML::Node position = r.Required(node, key, "position_m");
    rc.position_m = r.Doubles<3>(position, key + ".position_m");
    CheckInsideRoom(r, position, key + ".position_m", site->room, rc.position_m);
    if (node["range_offset_m"]) {
      rc.range_offset_m = r.Double(node["range_offset_m"], key + ".range_offset_m");
    }
    site->receivers.push_back(rc);
  }
  if (site->receivers.size() < 3) {
    r.Fail(receivers, "receivers",
           "at least 3 receivers are needed to fix a position, got " +
               std::to_string(site->receivers.size()));
  }
  if (SmallerPrincipalSpread(site->receivers) < kCollinearSpread_m) {
    r.Fail(receivers, "receivers",
           "all receivers lie on one line in the floor plane; the position would be ambiguous");
  }

  const YAML::Node beacons = root["beacons"];
  if (!beacons) return;
  r.ExpectListOfAtMost(beacons, "beacons", kMaxSiteBeacons);
  std::set<int> beacon_ids;
  for (size_t i = 0; i < beacons.size(); ++i) {
    const YAML::Node node = beacons[i];
    const std::string key = K::Index("beacons", i);
    r.ExpectMap(node, key);
    r.OnlyKeys(node, key, {"id", "address", "short_address", "height_m"});
    Beacon b;
    b.id = r.UniqueId(node, key, "id", "beacon", &beacon_ids);
    const YAML::Node address = r.Required(node, key, "address");
    b.address = r.Address(address, key + ".address");
    claim_address(address, key + ".address", b.address);
    if (node["short_address"]) {
      b.short_address = r.ShortAddress(node["short_address"], key + ".short_address");
      claim_short(node["short_address"], key + ".short_address", *b.short_address);
    }
    const YAML::Node height = r.Required(node, key, "height_m");
    b.height_m = r.Double(height, key + ".height_m");
    if (b.height_m < 0.0 || b.height_m > site->room.height_m) {
      r.Fail(height, key + ".height_m", "must be between the floor and the ceiling");
    }
    site->beacons.push_back(b);
  }
}

void ParseRobots(const Reader& r, const YAML::Node& root, Site* site) {
  const YAML::Node robots = root["robots"];
  if (!robots) return;
  r.ExpectListOfAtMost(robots, "robots", kMaxSiteRobots);
  std::set<int> ids;
  std::set<int> beacons_used;
  for (size_t i = 0; i < robots.size(); ++i) {
    const YAML::Node node = robots[i];
    const std::string key = K::Index("robots", i);
    r.ExpectMap(node, key);
    r.OnlyKeys(node, key, {"id", "name", "beacon_id", "max_speed_mps"});
    Robot robot;
    robot.id = r.UniqueId(node, key, "id", "robot", &ids);
    if (node["name"]) robot.name = r.String(node["name"], key + ".name");
    if (node["max_speed_mps"]) {
      robot.max_speed_mps = r.Positive(node["max_speed_mps"], key + ".max_speed_mps");
    }
    if (const YAML::Node beacon = node["beacon_id"]) {
      robot.beacon_id = r.Int(beacon, key + ".beacon_id");
      if (site->FindBeacon(*robot.beacon_id) == nullptr) {
        r.Fail(beacon, key + ".beacon_id", "no beacon with id " + std::to_string(*robot.beacon_id));
      }
      if (!beacons_used.insert(*robot.beacon_id).second) {
        r.Fail(beacon, key + ".beacon_id", "beacon already carried by another robot");
      }
    }
    site->robots.push_back(robot);
  }
}

// The code's sizes must let a blob's size say its role and keep the two
// markers apart: see docs/camera.md, "Many robots", for the figures.
constexpr double kMaxHeadingToPositionRatio = 0.6;
constexpr double kMinMarkerGapM = 0.02;

MarkerCode ParseMarkerCode(const Reader& r, const YAML::Node& node, const std::string& key) {
  r.ExpectMap(node, key);
  r.OnlyKeys(node, key, {"position_diameter_m", "heading_diameter_m", "heading_offset_m"});
  MarkerCode code;
  code.position_diameter_m =
      r.Positive(r.Required(node, key, "position_diameter_m"), key + ".position_diameter_m");
  const YAML::Node heading = r.Required(node, key, "heading_diameter_m");
  code.heading_diameter_m = r.Positive(heading, key + ".heading_diameter_m");
  const YAML::Node offset = r.Required(node, key, "heading_offset_m");
  code.heading_offset_m = r.Positive(offset, key + ".heading_offset_m");
  if (code.heading_diameter_m > kMaxHeadingToPositionRatio * code.position_diameter_m) {
    r.Fail(heading, key + ".heading_diameter_m",
           fmt::format("must be at most {:.1f} times position_diameter_m ({:.3f} m): the size "
                       "tells a heading marker from a position marker",
                       kMaxHeadingToPositionRatio,
                       kMaxHeadingToPositionRatio * code.position_diameter_m));
  }
  const double gap_m =
      code.heading_offset_m - 0.5 * (code.position_diameter_m + code.heading_diameter_m);
  if (gap_m < kMinMarkerGapM) {
    r.Fail(offset, key + ".heading_offset_m",
           fmt::format("leaves {:.3f} m between the two markers' edges, under {:.2f} m: they "
                       "would blur into one blob",
                       gap_m, kMinMarkerGapM));
  }
  return code;
}

MarkerClass ParseMarkerClass(const Reader& r, const YAML::Node& node, const std::string& key,
                             const MarkerCode& code, const std::string& code_key) {
  r.ExpectMap(node, key);
  r.OnlyKeys(node, key, {"name", "hsv_min", "hsv_max", "diameter_m"});
  MarkerClass mc;
  mc.name = r.String(r.Required(node, key, "name"), key + ".name");
  if (mc.name.empty() || mc.name.size() > kMaxMarkerClassNameBytes) {
    r.Fail(node["name"], key + ".name",
           "a marker class name must have 1 to " + std::to_string(kMaxMarkerClassNameBytes) +
               " characters");
  }
  const YAML::Node lo = r.Required(node, key, "hsv_min");
  const YAML::Node hi = r.Required(node, key, "hsv_max");
  mc.hsv_min = r.Ints<3>(lo, key + ".hsv_min");
  mc.hsv_max = r.Ints<3>(hi, key + ".hsv_max");
  const std::array<int, 3> upper = {179, 255, 255};
  for (const auto& [n, v, k] : {std::make_tuple(lo, mc.hsv_min, key + ".hsv_min"),
                                std::make_tuple(hi, mc.hsv_max, key + ".hsv_max")}) {
    for (size_t c = 0; c < 3; ++c) {
      if (v[c] < 0 || v[c] > upper[c]) {
        r.Fail(n, k, "OpenCV HSV bounds are H 0-179, S 0-255, V 0-255");
      }
    }
  }
  // Hue may wrap (min > max covers reds); saturation and value may not.
  if (mc.hsv_min[1] > mc.hsv_max[1] || mc.hsv_min[2] > mc.hsv_max[2]) {
    r.Fail(lo, key + ".hsv_min", "saturation and value minimums must not exceed the maximums");
  }
  if (code.enabled()) {
    // Two sizes for one class would leave the reader guessing which holds.
    if (node["diameter_m"]) {
      r.Fail(node["diameter_m"], key + ".diameter_m",
             "marker sizes are per role under " + code_key + ": remove this diameter");
    }
  } else {
    mc.diameter_m = r.Positive(r.Required(node, key, "diameter_m"), key + ".diameter_m");
  }
  return mc;
}

// The hue range of a class as one or two plain intervals: a wrapping range
// (hsv_min H above hsv_max H) covers min..179 and 0..max.
std::vector<std::pair<int, int>> HueIntervals(const MarkerClass& c) {
  if (c.hsv_min[0] <= c.hsv_max[0]) return {{c.hsv_min[0], c.hsv_max[0]}};
  return {{c.hsv_min[0], 179}, {0, c.hsv_max[0]}};
}

std::vector<std::pair<int, int>> HueIntersection(const MarkerClass& a, const MarkerClass& b) {
  std::vector<std::pair<int, int>> out;
  for (const auto& [a_lo, a_hi] : HueIntervals(a)) {
    for (const auto& [b_lo, b_hi] : HueIntervals(b)) {
      const int lo = std::max(a_lo, b_lo);
      const int hi = std::min(a_hi, b_hi);
      if (lo <= hi) out.emplace_back(lo, hi);
    }
  }
  std::sort(out.begin(), out.end());
  return out;
}

// "hue 10..15, saturation 120..200, value 60..255" for the shared box; a
// shared hue range through 0 reads "hue 175..179 and 0..5".
std::string DescribeOverlap(const MarkerClass& a, const MarkerClass& b) {
  std::ostringstream s;
  s << "hue ";
  const auto hue = HueIntersection(a, b);
  for (size_t i = 0; i < hue.size(); ++i) {
    if (i > 0) s << " and ";
    s << hue[i].first << ".." << hue[i].second;
  }
  const char* names[] = {"hue", "saturation", "value"};
  for (size_t c = 1; c < 3; ++c) {
    s << ", " << names[c] << " " << std::max(a.hsv_min[c], b.hsv_min[c]) << ".."
      << std::min(a.hsv_max[c], b.hsv_max[c]);
  }
  return s.str();
}

// cameras[i].robots: each robot's two marker classes (known to the camera,
// different, a code no other robot has, and without a marker code each class
// in one role only), marker height and tilt.
void ParseCameraRobots(const Reader& r, const YAML::Node& node, const std::string& key,
                       const std::string& code_key, const Site& site, Camera* cam) {
  auto has_class = [&](const std::string& name) {
    return std::any_of(cam->marker_classes.begin(), cam->marker_classes.end(),
                       [&](const MarkerClass& mc) { return mc.name == name; });
  };
  const YAML::Node robots = r.Required(node, key, "robots");
  r.ExpectListOfAtMost(robots, key + ".robots", kMaxSiteRobots);
  std::set<int> robot_ids;
  // Per class: the first robot using it as a position and as a heading
  // marker (for the role check without a code); per code: its robot.
  std::map<std::string, size_t> position_user, heading_user;
  std::map<std::pair<std::string, std::string>, size_t> code_user;
  for (size_t k = 0; k < robots.size(); ++k) {
    const YAML::Node rn = robots[k];
    const std::string rkey = K::Index(key + ".robots", k);
    r.ExpectMap(rn, rkey);
    r.OnlyKeys(
        rn, rkey,
        {"robot_id", "position_marker", "heading_marker", "marker_height_m", "tilt_sigma_deg"});
    CameraRobot cr;
    const YAML::Node rid = r.Required(rn, rkey, "robot_id");
    cr.robot_id = r.Int(rid, rkey + ".robot_id");
    if (site.FindRobot(cr.robot_id) == nullptr) {
      r.Fail(rid, rkey + ".robot_id", "no robot with id " + std::to_string(cr.robot_id));
    }
    if (!robot_ids.insert(cr.robot_id).second) {
      r.Fail(rid, rkey + ".robot_id", "robot listed twice for this camera");
    }
    for (auto [field, out] : {std::make_pair("position_marker", &cr.position_marker),
                              std::make_pair("heading_marker", &cr.heading_marker)}) {
      const YAML::Node m = r.Required(rn, rkey, field);
      *out = r.String(m, rkey + "." + field);
      if (!has_class(*out)) {
        r.Fail(m, rkey + "." + field, "no marker class named '" + *out + "'");
      }
    }
    if (cr.position_marker == cr.heading_marker) {
      // With a code the sizes would tell the roles apart, but the two
      // markers' gap (a few pixels at the far corners) blurs shut and the
      // pair reads as one blob.
      r.Fail(rn, rkey + ".heading_marker",
             "must differ from position_marker (two markers of one colour side by side merge "
             "into one blob)");
    }
    const auto code = std::make_pair(cr.position_marker, cr.heading_marker);
    if (const auto it = code_user.find(code); it != code_user.end()) {
      r.Fail(rn, rkey,
             "code " + cr.position_marker + "/" + cr.heading_marker + " is already robot " +
                 std::to_string(cam->robots[it->second].robot_id) + "'s (" +
                 K::Index(key + ".robots", it->second) +
                 "): the camera could not tell the two robots apart");
    }
    code_user[code] = k;
    if (!cam->marker_code.enabled()) {
      // Without a code a blob's role comes from its class alone.
      const auto pos = heading_user.find(cr.position_marker);
      const auto head = position_user.find(cr.heading_marker);
      if (pos != heading_user.end() || head != position_user.end()) {
        const bool as_pos = pos != heading_user.end();
        const std::string& cls = as_pos ? cr.position_marker : cr.heading_marker;
        const size_t other = as_pos ? pos->second : head->second;
        r.Fail(rn, rkey + (as_pos ? ".position_marker" : ".heading_marker"),
               "class '" + cls + "' is robot " + std::to_string(cam->robots[other].robot_id) +
                   "'s " + (as_pos ? "heading" : "position") +
                   " marker: a class serves one role unless " + code_key +
                   " sizes the roles (docs/camera.md, \"Many robots\")");
      }
      position_user.emplace(cr.position_marker, k);
      heading_user.emplace(cr.heading_marker, k);
    }
    const YAML::Node h = r.Required(rn, rkey, "marker_height_m");
    cr.marker_height_m = r.Double(h, rkey + ".marker_height_m");
    if (cr.marker_height_m < 0.0 || cr.marker_height_m >= site.room.height_m) {
      r.Fail(h, rkey + ".marker_height_m", "must be between the floor and the ceiling");
    }
    if (const YAML::Node tilt = rn["tilt_sigma_deg"]) {
      cr.tilt_sigma_deg = r.Double(tilt, rkey + ".tilt_sigma_deg");
      if (cr.tilt_sigma_deg < 0.0 || cr.tilt_sigma_deg > 30.0) {
        r.Fail(tilt, rkey + ".tilt_sigma_deg", "must be between 0 and 30 degrees");
      }
    }
    cam->robots.push_back(cr);
  }
}

void ParseCameras(const Reader& r, const YAML::Node& root, const std::string& base_dir,
                  Site* site) {
  const YAML::Node cameras = root["cameras"];
  if (!cameras) return;
  r.ExpectListOfAtMost(cameras, "cameras", kMaxSiteCameras);
  std::set<int> ids;
  static const std::set<std::string> kProperties = {
      "brightness", "contrast", "saturation", "hue",           "gamma",
      "sharpness",  "exposure", "gain",       "white_balance", "focus"};
  for (size_t i = 0; i < cameras.size(); ++i) {
    const YAML::Node node = cameras[i];
    const std::string key = K::Index("cameras", i);
    r.ExpectMap(node, key);
    r.OnlyKeys(node, key,
               {"id", "device", "resolution", "fps", "pixel_format", "mount_position_m",
                "field_of_view_deg", "properties", "calibration", "marker_code", "marker_classes",
                "robots", "readout_s", "exposure_s", "timestamp_latency_s"});
    Camera cam;
    cam.id = r.UniqueId(node, key, "id", "camera", &ids);
    // pose2d_t.camera_id is -1 (NO_CAMERA) for poses no camera measured.
    if (cam.id < 0) r.Fail(node["id"], key + ".id", "must be 0 or more");
    cam.device = r.String(r.Required(node, key, "device"), key + ".device");
    const YAML::Node resolution = r.Required(node, key, "resolution");
    const auto wh = r.Ints<2>(resolution, key + ".resolution");
    if (wh[0] <= 0 || wh[1] <= 0) r.Fail(resolution, key + ".resolution", "must be positive");
    cam.width_px = wh[0];
    cam.height_px = wh[1];
    cam.fps = r.Positive(r.Required(node, key, "fps"), key + ".fps");
    if (node["pixel_format"]) {
      cam.pixel_format = r.String(node["pixel_format"], key + ".pixel_format");
      if (cam.pixel_format.size() != 4) {
        r.Fail(node["pixel_format"], key + ".pixel_format",
               "expected a four-character code such as MJPG or YUYV");
      }
    }
    const YAML::Node mount = r.Required(node, key, "mount_position_m");
    cam.mount_position_m = r.Doubles<3>(mount, key + ".mount_position_m");
    CheckInsideRoom(r, mount, key + ".mount_position_m", site->room, cam.mount_position_m);
    if (const YAML::Node fov = node["field_of_view_deg"]) {
      cam.field_of_view_deg = r.Positive(fov, key + ".field_of_view_deg");
      if (cam.field_of_view_deg >= 200.0) {
        r.Fail(fov, key + ".field_of_view_deg", "must be below 200 degrees");
      }
    }
    // Timing: a rolling shutter reads its rows within one frame period, and
    // exposes each for at most a frame period; a latency is at most a second
    // (a longer one is a clock problem, not a camera's).
    const double period_s = 1.0 / cam.fps;
    for (auto [field, out, max_s, what] :
         {std::make_tuple("readout_s", &cam.readout_s, period_s, "the frame period"),
          std::make_tuple("exposure_s", &cam.exposure_s, period_s, "the frame period"),
          std::make_tuple("timestamp_latency_s", &cam.timestamp_latency_s, 1.0, "1 s")}) {
      if (const YAML::Node t = node[field]) {
        *out = r.Double(t, key + "." + field);
        if (*out < 0.0) r.Fail(t, key + "." + field, "must not be negative");
        if (*out > max_s + 1e-12) {
          r.Fail(t, key + "." + field,
                 std::string("must be at most ") + what + " (" + std::to_string(max_s) + " s)");
        }
      }
    }
    if (const YAML::Node props = node["properties"]) {
      r.ExpectMap(props, key + ".properties");
      for (const auto& kv : props) {
        const std::string name = kv.first.as<std::string>();
        const std::string pkey = key + ".properties." + name;
        if (kProperties.count(name) == 0) {
          r.Fail(kv.first, pkey, "unknown camera property");
        }
        cam.properties[name] = r.Double(kv.second, pkey);
      }
    }
    if (const YAML::Node cal = node["calibration"]) {
      std::string file = r.String(cal, key + ".calibration");
      if (!file.empty() && file[0] != '/' && !base_dir.empty()) file = base_dir + "/" + file;
      cam.calibration_file = file;
    }
    const std::string code_key = key + ".marker_code";
    if (const YAML::Node code = node["marker_code"])
      cam.marker_code = ParseMarkerCode(r, code, code_key);
    const YAML::Node classes = r.Required(node, key, "marker_classes");
    r.ExpectListOfAtMost(classes, key + ".marker_classes", kMaxCameraMarkerClasses);
    for (size_t c = 0; c < classes.size(); ++c) {
      const std::string ckey = K::Index(key + ".marker_classes", c);
      MarkerClass mc = ParseMarkerClass(r, classes[c], ckey, cam.marker_code, code_key);
      for (const auto& other : cam.marker_classes) {
        if (other.name == mc.name) {
          r.Fail(classes[c], ckey + ".name", "duplicate marker class '" + mc.name + "'");
        }
        if (HsvRangesOverlap(mc, other)) {
          r.Fail(classes[c], ckey,
                 "colour class '" + mc.name + "' overlaps '" + other.name + "' (" +
                     DescribeOverlap(mc, other) + "): a pixel could not be classified");
        }
      }
      cam.marker_classes.push_back(mc);
    }
    ParseCameraRobots(r, node, key, code_key, *site, &cam);
    site->cameras.push_back(cam);
  }
}

std::shared_ptr<const Trajectory> ParseTrajectory(const Reader& r, const YAML::Node& node,
                                                  const std::string& key) {
  r.ExpectMap(node, key);
  const YAML::Node type_node = r.Required(node, key, "type");
  const std::string type = r.String(type_node, key + ".type");
  auto num = [&](const char* name, double* out) {
    if (node[name]) *out = r.Double(node[name], key + "." + name);
  };
  auto xy = [&](const char* name, double* x, double* y) {
    if (node[name]) {
      const auto v = r.Doubles<2>(node[name], key + "." + name);
      *x = v[0];
      *y = v[1];
    }
  };
  std::string error;
  std::unique_ptr<Trajectory> t;
  if (type == "static") {
    r.OnlyKeys(node, key, {"type", "position_m", "heading_rad"});
    StaticTrajectoryOptions o;
    r.Required(node, key, "position_m");
    xy("position_m", &o.x_m, &o.y_m);
    num("heading_rad", &o.heading_rad);
    t = MakeStaticTrajectory(o, &error);
  } else if (type == "circle" || type == "reference_circle") {
    // reference_circle is circle with every default taken from the paper.
    r.OnlyKeys(
        node, key,
        {"type", "radius_m", "centre_m", "centre_drift_mps", "angular_speed_radps", "phase_rad"});
    CircleTrajectoryOptions o;
    num("radius_m", &o.radius_m);
    xy("centre_m", &o.cx_m, &o.cy_m);
    xy("centre_drift_mps", &o.drift_x_mps, &o.drift_y_mps);
    num("angular_speed_radps", &o.angular_speed_radps);
    num("phase_rad", &o.phase_rad);
    t = MakeCircleTrajectory(o, &error);
  } else if (type == "waypoints") {
    r.OnlyKeys(node, key, {"type", "points_m", "speed_mps", "loop"});
    WaypointTrajectoryOptions o;
    const YAML::Node points = r.Required(node, key, "points_m");
    r.ExpectListOfAtMost(points, key + ".points_m", kMaxWaypoints);
    for (size_t i = 0; i < points.size(); ++i) {
      const auto p = r.Doubles<2>(points[i], K::Index(key + ".points_m", i));
      o.points_m.emplace_back(p[0], p[1]);
    }
    num("speed_mps", &o.speed_mps);
    if (node["loop"]) o.loop = r.Bool(node["loop"], key + ".loop");
    t = MakeWaypointTrajectory(o, &error);
  } else if (type == "figure_eight") {
    r.OnlyKeys(node, key, {"type", "centre_m", "half_size_m", "period_s"});
    FigureEightTrajectoryOptions o;
    xy("centre_m", &o.cx_m, &o.cy_m);
    xy("half_size_m", &o.half_width_m, &o.half_height_m);
    num("period_s", &o.period_s);
    t = MakeFigureEightTrajectory(o, &error);
  } else {
    r.Fail(type_node, key + ".type",
           "unknown trajectory type '" + type +
               "' (static, circle, reference_circle, waypoints, figure_eight)");
  }
  if (t == nullptr) r.Fail(node, key, error);
  return t;
}

// simulation.webcam: every key optional, each checked against the range in
// which its model means something (docs/synthetic_camera.md).
WebcamSimulation ParseWebcam(const Reader& r, const YAML::Node& node) {
  const std::string key = "simulation.webcam";
  r.ExpectMap(node, key);
  r.OnlyKeys(node, key,
             {"psf_sigma_px",
              "vignetting_corner_gain",
              "lens_k",
              "lens_principal_offset_px",
              "exposure_s",
              "readout_s",
              "auto_exposure_drift",
              "auto_exposure_period_s",
              "white_balance_drift",
              "white_balance_period_s",
              "full_well_e",
              "read_noise_e",
              "shot_noise",
              "srgb_gamma",
              "bayer",
              "jpeg_quality",
              "tilt_static_deg",
              "tilt_per_acceleration_deg_per_mps2",
              "tilt_rocking_deg",
              "marker_wear",
              "marker_sheen",
              "timestamp_latency_s",
              "timestamp_jitter_s"});
  WebcamSimulation w;
  // A number in [lo, hi] (inclusive).
  auto in_range = [&](const char* name, double lo, double hi, const char* what, double* out) {
    const YAML::Node n = node[name];
    if (!n) return;
    const double v = r.Double(n, key + "." + name);
    if (v < lo || v > hi) r.Fail(n, key + "." + name, what);
    *out = v;
  };
  auto flag = [&](const char* name, bool* out) {
    if (node[name]) *out = r.Bool(node[name], key + "." + name);
  };
  in_range("psf_sigma_px", 0.0, 10.0, "must be between 0 (sharp) and 10 px", &w.psf_sigma_px);
  in_range("vignetting_corner_gain", 0.05, 1.0,
           "must be between 0.05 and 1 (the corner's illumination relative to the centre)",
           &w.vignetting_corner_gain);
  if (node["lens_k"]) {
    w.lens_k = r.Doubles<4>(node["lens_k"], key + ".lens_k");
    for (const double k : w.lens_k) {
      if (std::abs(k) > 0.5) {
        r.Fail(node["lens_k"], key + ".lens_k",
               "each coefficient must be within +-0.5 (a fisheye lens, not a different one)");
      }
    }
  }
  if (node["lens_principal_offset_px"]) {
    w.lens_principal_offset_px =
        r.Doubles<2>(node["lens_principal_offset_px"], key + ".lens_principal_offset_px");
    for (const double o : w.lens_principal_offset_px) {
      if (std::abs(o) > 100.0) {
        r.Fail(node["lens_principal_offset_px"], key + ".lens_principal_offset_px",
               "must be within +-100 px");
      }
    }
  }
  in_range("exposure_s", 0.0, 0.1, "must be between 0 (instantaneous) and 0.1 s", &w.exposure_s);
  in_range("readout_s", 0.0, 0.1, "must be between 0 (global shutter) and 0.1 s", &w.readout_s);
  in_range("auto_exposure_drift", 0.0, 0.5, "must be between 0 and 0.5 (relative gain)",
           &w.auto_exposure_drift);
  in_range("auto_exposure_period_s", 0.1, 3600.0, "must be between 0.1 and 3600 s",
           &w.auto_exposure_period_s);
  in_range("white_balance_drift", 0.0, 0.5, "must be between 0 and 0.5 (relative gain)",
           &w.white_balance_drift);
  in_range("white_balance_period_s", 0.1, 3600.0, "must be between 0.1 and 3600 s",
           &w.white_balance_period_s);
  in_range("full_well_e", 10.0, 1e6, "must be between 10 and 1e6 electrons", &w.full_well_e);
  in_range("read_noise_e", 0.0, 1000.0, "must be between 0 and 1000 electrons", &w.read_noise_e);
  flag("shot_noise", &w.shot_noise);
  flag("srgb_gamma", &w.srgb_gamma);
  flag("bayer", &w.bayer);
  if (const YAML::Node q = node["jpeg_quality"]) {
    w.jpeg_quality = r.Int(q, key + ".jpeg_quality");
    if (w.jpeg_quality < 0 || w.jpeg_quality > 100) {
      r.Fail(q, key + ".jpeg_quality", "must be 1..100, or 0 for raw frames");
    }
  }
  in_range("tilt_static_deg", 0.0, 10.0, "must be between 0 and 10 degrees", &w.tilt_static_deg);
  in_range("tilt_per_acceleration_deg_per_mps2", 0.0, 20.0,
           "must be between 0 and 20 degrees per m/s^2", &w.tilt_per_acceleration_deg_per_mps2);
  in_range("tilt_rocking_deg", 0.0, 10.0, "must be between 0 and 10 degrees", &w.tilt_rocking_deg);
  in_range("marker_wear", 0.0, 1.0, "must be between 0 and 1", &w.marker_wear);
  in_range("marker_sheen", 0.0, 1.0, "must be between 0 and 1", &w.marker_sheen);
  in_range("timestamp_latency_s", 0.0, 1.0, "must be between 0 and 1 s", &w.timestamp_latency_s);
  in_range("timestamp_jitter_s", 0.0, 0.1, "must be between 0 and 0.1 s", &w.timestamp_jitter_s);
  return w;
}

void ParseSimulation(const Reader& r, const YAML::Node& root, Site* site) {
  const YAML::Node sim = root["simulation"];
  if (!sim) return;
  r.ExpectMap(sim, "simulation");
  r.OnlyKeys(sim, "simulation", {"temperature_c", "robots", "webcam"});
  if (sim["temperature_c"]) {
    site->simulation.temperature_c = r.Double(sim["temperature_c"], "simulation.temperature_c");
  }
  if (const YAML::Node webcam = sim["webcam"]) {
    site->simulation.webcam = ParseWebcam(r, webcam);
  }
  const YAML::Node robots = sim["robots"];
  if (!robots) return;
  r.ExpectListOfAtMost(robots, "simulation.robots", kMaxSiteRobots);
  std::set<int> ids;
  for (size_t i = 0; i < robots.size(); ++i) {
    const std::string key = K::Index("simulation.robots", i);
    const YAML::Node node = robots[i];
    r.ExpectMap(node, key);
    r.OnlyKeys(node, key, {"robot_id", "trajectory"});
    SimulatedRobot sr;
    const YAML::Node id = r.Required(node, key, "robot_id");
    sr.robot_id = r.Int(id, key + ".robot_id");
    if (site->FindRobot(sr.robot_id) == nullptr) {
      r.Fail(id, key + ".robot_id", "no robot with id " + std::to_string(sr.robot_id));
    }
    if (!ids.insert(sr.robot_id).second) {
      r.Fail(id, key + ".robot_id", "robot simulated twice");
    }
    sr.trajectory = ParseTrajectory(r, r.Required(node, key, "trajectory"), key + ".trajectory");
    site->simulation.robots.push_back(sr);
  }
}

// True when the point lies inside a fixed obstacle (its footprint and its
// vertical extent, boundaries included).
bool InsideObstacle(const Obstacle& o, const std::array<double, 3>& p) {
  if (p[2] < o.bottom_m || p[2] > o.top_m) return false;
  const double dx = p[0] - o.centre_m[0];
  const double dy = p[1] - o.centre_m[1];
  if (o.shape == Obstacle::Shape::kCylinder) return dx * dx + dy * dy <= o.radius_m * o.radius_m;
  const double c = std::cos(o.yaw_rad);
  const double s = std::sin(o.yaw_rad);
  return std::abs(c * dx + s * dy) <= 0.5 * o.size_m[0] &&
         std::abs(-s * dx + c * dy) <= 0.5 * o.size_m[1];
}

// Whole-degree yaw bound: a box turned by more than half a turn is the same
// box turned the other way, so a larger figure is a unit mix-up (radians).
constexpr double kMaxObstacleYawDeg = 180.0;

Obstacle ParseObstacle(const Reader& r, const YAML::Node& node, const std::string& key,
                       const Site& site) {
  r.ExpectMap(node, key);
  const YAML::Node type_node = r.Required(node, key, "type");
  const std::string type = r.String(type_node, key + ".type");
  Obstacle o;
  if (type == "box") {
    r.OnlyKeys(node, key, {"type", "name", "centre_m", "size_m", "yaw_deg", "bottom_m", "top_m"});
    o.shape = Obstacle::Shape::kBox;
    const YAML::Node size = r.Required(node, key, "size_m");
    o.size_m = r.Doubles<2>(size, key + ".size_m");
    if (!(o.size_m[0] > 0.0 && o.size_m[1] > 0.0)) {
      r.Fail(size, key + ".size_m", "sizes must be positive");
    }
    if (const YAML::Node yaw = node["yaw_deg"]) {
      const double yaw_deg = r.Double(yaw, key + ".yaw_deg");
      if (std::abs(yaw_deg) > kMaxObstacleYawDeg) {
        r.Fail(yaw, key + ".yaw_deg", "must be within +-180 degrees");
      }
      o.yaw_rad = yaw_deg * M_PI / 180.0;
    }
  } else if (type == "cylinder") {
    r.OnlyKeys(node, key,
               {"type", "name", "centre_m", "radius_m", "bottom_m", "top_m", "trajectory"});
    o.shape = Obstacle::Shape::kCylinder;
    o.radius_m = r.Positive(r.Required(node, key, "radius_m"), key + ".radius_m");
    if (node["trajectory"] && node["centre_m"]) {
      r.Fail(node["centre_m"], key + ".centre_m",
             "give either centre_m (a fixed cylinder) or trajectory (a moving one), not both");
    }
    if (node["trajectory"]) {
      o.trajectory = ParseTrajectory(r, node["trajectory"], key + ".trajectory");
    }
  } else {
    r.Fail(type_node, key + ".type", "unknown obstacle type '" + type + "' (box, cylinder)");
  }
  if (node["name"]) o.name = r.String(node["name"], key + ".name");
  if (o.trajectory == nullptr) {
    const YAML::Node centre = r.Required(node, key, "centre_m");
    o.centre_m = r.Doubles<2>(centre, key + ".centre_m");
    CheckInsideRoom(r, centre, key + ".centre_m", site.room, {o.centre_m[0], o.centre_m[1], 0.0});
  }
  if (node["bottom_m"]) o.bottom_m = r.Double(node["bottom_m"], key + ".bottom_m");
  const YAML::Node top = r.Required(node, key, "top_m");
  o.top_m = r.Double(top, key + ".top_m");
  if (o.bottom_m < 0.0 || o.bottom_m >= site.room.height_m) {
    r.Fail(node["bottom_m"], key + ".bottom_m",
           "must be at or above the floor and below the ceiling");
  }
  if (!(o.top_m > o.bottom_m && o.top_m <= site.room.height_m + kOutsideRoomTolerance_m)) {
    r.Fail(top, key + ".top_m", "must be above bottom_m and at most the ceiling's height");
  }
  return o;
}

// `obstacles:` (optional), after the receivers: a receiver inside a fixed
// obstacle could hear nothing, which is a typo, not a room.
void ParseObstacles(const Reader& r, const YAML::Node& root, Site* site) {
  const YAML::Node obstacles = root["obstacles"];
  if (!obstacles) return;
  r.ExpectSequence(obstacles, "obstacles");
  if (obstacles.size() > kMaxObstacles) {
    r.Fail(obstacles, "obstacles",
           std::to_string(obstacles.size()) + " obstacles, over the cap of " +
               std::to_string(kMaxObstacles) + " (each simulated range is tested against all)");
  }
  for (size_t i = 0; i < obstacles.size(); ++i) {
    const std::string key = K::Index("obstacles", i);
    const Obstacle o = ParseObstacle(r, obstacles[i], key, *site);
    if (o.trajectory == nullptr) {
      for (size_t j = 0; j < site->receivers.size(); ++j) {
        if (InsideObstacle(o, site->receivers[j].position_m)) {
          r.Fail(obstacles[i], key,
                 "receivers[" + std::to_string(j) + "] (id " +
                     std::to_string(site->receivers[j].id) +
                     ") lies inside this obstacle: it could hear nothing");
        }
      }
    }
    site->obstacles.push_back(o);
  }
}

// `acoustics:` (optional): every key optional, each checked against the
// bounds in which the decay model of core/world/air_model.h means something.
void ParseAcoustics(const Reader& r, const YAML::Node& root, Site* site) {
  const YAML::Node node = root["acoustics"];
  if (!node) return;
  r.ExpectMap(node, "acoustics");
  r.OnlyKeys(node, "acoustics",
             {"frequency_hz", "humidity_percent", "wall_absorption", "pulse_s",
              "detection_margin_db", "decay_s", "clock_uncertainty_s"});
  Acoustics& a = site->acoustics;
  auto read = [&](const char* name, double lo, double hi, double* out) {
    const YAML::Node v = node[name];
    if (!v) return;
    const std::string key = std::string("acoustics.") + name;
    *out = r.Double(v, key);
    if (!(*out >= lo && *out <= hi)) {
      std::ostringstream what;
      what << "must be in [" << lo << ", " << hi << "]";
      r.Fail(v, key, what.str());
    }
  };
  read("frequency_hz", 20000.0, 200000.0, &a.frequency_hz);
  read("humidity_percent", 0.0, 100.0, &a.humidity_percent);
  read("wall_absorption", 0.01, 1.0, &a.wall_absorption);
  read("pulse_s", 1e-5, 0.01, &a.pulse_s);
  read("detection_margin_db", 0.0, 60.0, &a.detection_margin_db);
  read("clock_uncertainty_s", 0.0, 0.1, &a.clock_uncertainty_s);
  if (node["decay_s"]) {
    double decay_s = 0.0;
    read("decay_s", 0.0, 2.0, &decay_s);
    a.decay_s = decay_s;
  }
}

// `radios:` (optional): coordinators, each listing the receivers its network
// carries. Every receiver belongs to exactly one radio once any is named, so
// that each report has one way to the PC.
void ParseRadioNetworks(const Reader& r, const YAML::Node& root, Site* site) {
  const YAML::Node radios = root["radios"];
  if (!radios) return;
  r.ExpectListOfAtMost(radios, "radios", kMaxSiteRadios);
  std::set<int> ids;
  std::map<int, std::string> owner;
  for (size_t i = 0; i < radios.size(); ++i) {
    const YAML::Node node = radios[i];
    const std::string key = K::Index("radios", i);
    r.ExpectMap(node, key);
    r.OnlyKeys(node, key, {"id", "device", "receivers"});
    RadioNetwork radio;
    radio.id = r.UniqueId(node, key, "id", "radio", &ids);
    if (node["device"]) radio.device = r.String(node["device"], key + ".device");
    const YAML::Node receivers = r.Required(node, key, "receivers");
    r.ExpectListOfAtMost(receivers, key + ".receivers", kMaxSiteReceivers);
    for (size_t j = 0; j < receivers.size(); ++j) {
      const std::string rkey = K::Index(key + ".receivers", j);
      const int id = r.Int(receivers[j], rkey);
      if (site->FindReceiver(id) == nullptr) {
        r.Fail(receivers[j], rkey, "no receiver with id " + std::to_string(id));
      }
      auto [it, fresh] = owner.emplace(id, key);
      if (!fresh) {
        r.Fail(receivers[j], rkey,
               "receiver " + std::to_string(id) + " is already on " + it->second);
      }
      radio.receiver_ids.push_back(id);
    }
    site->radios.push_back(radio);
  }
  for (const Receiver& rc : site->receivers) {
    if (owner.count(rc.id) == 0) {
      r.Fail(radios, "radios",
             "receiver " + std::to_string(rc.id) + " is on no radio (list it under one)");
    }
  }
}

std::string DirName(const std::string& path) {
  const size_t slash = path.find_last_of('/');
  if (slash == std::string::npos) return ".";
  return slash == 0 ? "/" : path.substr(0, slash);
}

}  // namespace

namespace {
template <class T, class Pred>
const T* FindIf(const std::vector<T>& items, Pred pred) {
  auto it = std::find_if(items.begin(), items.end(), pred);
  return it == items.end() ? nullptr : &*it;
}
}  // namespace

const Receiver* Site::FindReceiver(int id) const {
  return FindIf(receivers, [id](const Receiver& r) { return r.id == id; });
}
const Receiver* Site::FindReceiverByShortAddress(uint16_t address) const {
  return FindIf(receivers, [address](const Receiver& r) { return r.short_address == address; });
}

const Beacon* Site::FindBeaconByShortAddress(uint16_t address) const {
  return FindIf(beacons, [address](const Beacon& b) { return b.short_address == address; });
}

const Receiver* Site::FindReceiverByAddress(uint64_t address) const {
  return FindIf(receivers, [address](const Receiver& r) { return r.address == address; });
}
const Beacon* Site::FindBeacon(int id) const {
  return FindIf(beacons, [id](const Beacon& b) { return b.id == id; });
}
const Beacon* Site::FindBeaconByAddress(uint64_t address) const {
  return FindIf(beacons, [address](const Beacon& b) { return b.address == address; });
}
const RadioNetwork* Site::RadioOfReceiver(int receiver_id) const {
  for (const RadioNetwork& radio : radios) {
    for (int id : radio.receiver_ids) {
      if (id == receiver_id) return &radio;
    }
  }
  return nullptr;
}

std::array<double, 2> Obstacle::CentreAt(double t_s) const {
  if (trajectory == nullptr) return centre_m;
  const GroundTruthPose p = trajectory->PoseAt(t_s);
  return {p.x_m, p.y_m};
}

const Robot* Site::FindRobot(int id) const {
  return FindIf(robots, [id](const Robot& r) { return r.id == id; });
}

const Camera* Site::FindCamera(int id) const {
  return FindIf(cameras, [id](const Camera& c) { return c.id == id; });
}

const Camera* Site::FindCameraOrFirst(int id) const {
  if (id >= 0) return FindCamera(id);
  return cameras.empty() ? nullptr : &cameras.front();
}

double PositionMarkerDiameterM(const Camera& camera, const CameraRobot& robot) {
  if (camera.marker_code.enabled()) return camera.marker_code.position_diameter_m;
  for (const MarkerClass& c : camera.marker_classes) {
    if (c.name == robot.position_marker) return c.diameter_m;
  }
  return 0.0;
}

double HeadingMarkerDiameterM(const Camera& camera, const CameraRobot& robot) {
  if (camera.marker_code.enabled()) return camera.marker_code.heading_diameter_m;
  for (const MarkerClass& c : camera.marker_classes) {
    if (c.name == robot.heading_marker) return c.diameter_m;
  }
  return 0.0;
}

bool HsvRangesOverlap(const MarkerClass& a, const MarkerClass& b) {
  for (size_t c = 1; c < 3; ++c) {
    if (std::max(a.hsv_min[c], b.hsv_min[c]) > std::min(a.hsv_max[c], b.hsv_max[c])) return false;
  }
  return !HueIntersection(a, b).empty();
}

bool SiteForRadio(const Site& site, int radio_id, Site* out, std::string* error) {
  const RadioNetwork* radio = nullptr;
  for (const RadioNetwork& r : site.radios) {
    if (r.id == radio_id) radio = &r;
  }
  if (radio == nullptr) {
    *error = "the site names no radio " + std::to_string(radio_id) +
             (site.radios.empty() ? " (it has no radios: section)" : "");
    return false;
  }
  Site filtered = site;
  filtered.receivers.clear();
  for (const Receiver& rc : site.receivers) {
    if (std::find(radio->receiver_ids.begin(), radio->receiver_ids.end(), rc.id) !=
        radio->receiver_ids.end()) {
      filtered.receivers.push_back(rc);
    }
  }
  *out = std::move(filtered);
  return true;
}

bool ParseRadioAddress(const std::string& text, uint64_t* address) {
  std::string digits;
  size_t start = 0;
  if (text.size() >= 2 && text[0] == '0' && (text[1] == 'x' || text[1] == 'X')) start = 2;
  for (size_t i = start; i < text.size(); ++i) {
    const char c = text[i];
    if (c == ' ' || c == ':' || c == '-') continue;
    if (!std::isxdigit(static_cast<unsigned char>(c))) return false;
    digits.push_back(c);
  }
  if (digits.size() != 16) return false;
  *address = std::stoull(digits, nullptr, 16);
  return true;
}

std::string FormatRadioAddress(uint64_t address) { return fmt::format("0x{:016X}", address); }

bool ParseSite(const std::string& yaml_text, const std::string& name, const std::string& base_dir,
               Site* site, std::string* error) {
  Site parsed;
  const bool ok = ParseYamlDocument(
      yaml_text, name,
      [&](const YamlReader& base, const YAML::Node& root) {
        const Reader r(base);
        r.OnlyKeys(root, "",
                   {"name", "room", "receivers", "beacons", "robots", "cameras", "acoustics",
                    "radios", "obstacles", "simulation"});
        parsed.name = r.String(r.Required(root, "", "name"), "name");
        parsed.room = ParseRoom(r, r.Required(root, "", "room"));
        ParseRadios(r, root, &parsed);
        ParseRobots(r, root, &parsed);
        ParseCameras(r, root, base_dir, &parsed);
        ParseAcoustics(r, root, &parsed);
        ParseRadioNetworks(r, root, &parsed);
        ParseObstacles(r, root, &parsed);
        ParseSimulation(r, root, &parsed);
      },
      error);
  if (!ok) return false;
  *site = std::move(parsed);
  return true;
}

bool LoadSite(const std::string& path, Site* site, std::string* error) {
  std::string text;
  if (!ReadConfigFile(path, &text, error)) return false;
  if (!ParseSite(text, path, DirName(path), site, error)) return false;
  site->path = path;
  return true;
}

}  // namespace roomfix
