#ifndef ROOMFIX_CORE_WORLD_SITE_H_
#define ROOMFIX_CORE_WORLD_SITE_H_

#include <array>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/world/trajectory.h"

namespace roomfix {

// The site: one room, its ultrasonic receivers, the beacons on the robots,
// the ceiling cameras and, for the simulator, how the robots move. Room frame:
// x and y on the floor, z up, metres, origin at the surveyed point named in
// `origin`. Loaded from one YAML file (config/sites/*.yaml); see
// docs/site_file.md for every key.

struct Room {
  // The floor spans [min_x_m, min_x_m + size_x_m] x [min_y_m, min_y_m +
  // size_y_m]: the origin is wherever the surveyed mark is, often a corner
  // (min 0, 0), sometimes the middle of the room (motion-capture origins).
  double min_x_m = 0.0;
  double min_y_m = 0.0;
  double size_x_m = 0.0;
  double size_y_m = 0.0;
  double height_m = 0.0;
  // Spacing of the floor grid the reference calibrated on.
  double grid_m = 0.5;
  // Where the origin is, in words (a surveyed floor mark).
  std::string origin;
};

struct Receiver {
  int id = 0;
  // 64-bit IEEE address of the receiver's radio.
  uint64_t address = 0;
  // 802.15.4 short address (MY) when the module uses 16-bit addressing: its
  // frames (0x81) then carry only this.
  std::optional<uint16_t> short_address;
  std::array<double, 3> position_m{};
  // Subtracted from every range this receiver measures (calibration).
  double range_offset_m = 0.0;
};

struct Beacon {
  int id = 0;
  uint64_t address = 0;
  std::optional<uint16_t> short_address;
  // Height of the ultrasonic emitter above the floor; the 2D solver holds it.
  double height_m = 0.0;
};

// A colour class in OpenCV's HSV: H in [0, 179], S and V in [0, 255]. A hue
// range with hue_min > hue_max wraps through 0 (reds).
// A class's name travels in every MARKER_PIXELS marker (marker_t.colour_class),
// whose receivers refuse names of 64 bytes or more with the NUL
// (msgio/wire_check.h): a longer name would get every frame refused.
inline constexpr size_t kMaxMarkerClassNameBytes = 63;

struct MarkerClass {
  std::string name;
  std::array<int, 3> hsv_min{};
  std::array<int, 3> hsv_max{};
  // The markers' diameter; 0 when the camera's marker_code sizes markers by
  // role instead.
  double diameter_m = 0.0;
};

// Robots told apart by an ordered pair of colours (docs/camera.md, "Many
// robots"): every marker class may serve as a position or a heading marker,
// the role of a blob is read from its size (position markers are the large
// ones), and each robot's code is (position colour, heading colour). Without
// it (diameter 0 here) the role comes from the class, as in the one-robot
// demo.
struct MarkerCode {
  double position_diameter_m = 0.0;
  double heading_diameter_m = 0.0;
  // Centre of the position marker to centre of the heading marker.
  double heading_offset_m = 0.0;
  bool enabled() const { return position_diameter_m > 0.0; }
};

// A robot as the camera sees it: a large marker for its position and a small
// one for its heading, each naming a marker class.
struct CameraRobot {
  int robot_id = 0;
  std::string position_marker;
  std::string heading_marker;
  // Height of the marker tops above the floor.
  double marker_height_m = 0.0;
};

struct Camera {
  int id = 0;
  // "/dev/video0", a video file, an image glob or "sim:<scenario>".
  std::string device;
  int width_px = 0;
  int height_px = 0;
  double fps = 0.0;
  // FOURCC such as "MJPG" or "YUYV".
  std::string pixel_format;
  // Nominal position of the lens in the room frame and its full field of
  // view: the starting guess for calibration and the simulated camera's pose.
  // The calibrated model, once there, supersedes both.
  std::array<double, 3> mount_position_m{};
  double field_of_view_deg = 120.0;
  // Properties preset at start-up (brightness, contrast, saturation, hue,
  // gamma, sharpness, exposure), by name.
  std::map<std::string, double> properties;
  // Path of a calibration YAML file, resolved against the site file's folder;
  // empty when the camera is not calibrated yet.
  std::string calibration_file;
  std::vector<MarkerClass> marker_classes;
  std::vector<CameraRobot> robots;
  // Identification by ordered colour pairs with per-role sizes; disabled
  // when the site gives no `marker_code`.
  MarkerCode marker_code;
};

// The diameters of a robot's two markers on this camera: the code's
// per-role sizes when it has one, else the classes' diameters (0 for an
// unknown class).
double PositionMarkerDiameterM(const Camera& camera, const CameraRobot& robot);
double HeadingMarkerDiameterM(const Camera& camera, const CameraRobot& robot);

// A robot in the site, tying its beacon to its camera markers.
struct Robot {
  int id = 0;
  std::string name;
  // Beacon carried by the robot; nullopt when it has none.
  std::optional<int> beacon_id;
  // Top speed over the floor, m/s. trilat_proc bounds how far the beacon can
  // have moved between two firings with it (docs/trilateration.md, "Temporal
  // prior"); 1 m/s is above what a small indoor robot drives.
  double max_speed_mps = 1.0;
};

// How a simulated robot moves.
struct SimulatedRobot {
  int robot_id = 0;
  std::shared_ptr<const Trajectory> trajectory;
};

struct Simulation {
  double temperature_c = 20.0;
  std::vector<SimulatedRobot> robots;
};

struct Site {
  std::string name;
  // The file the site was loaded from (empty when parsed from text).
  std::string path;
  Room room;
  std::vector<Receiver> receivers;
  std::vector<Beacon> beacons;
  std::vector<Robot> robots;
  std::vector<Camera> cameras;
  Simulation simulation;

  const Receiver* FindReceiver(int id) const;
  const Receiver* FindReceiverByAddress(uint64_t address) const;
  const Beacon* FindBeacon(int id) const;
  const Beacon* FindBeaconByAddress(uint64_t address) const;
  const Receiver* FindReceiverByShortAddress(uint16_t address) const;
  const Beacon* FindBeaconByShortAddress(uint16_t address) const;
  const Robot* FindRobot(int id) const;
};

// Reads and validates a site file. On failure returns false and sets *error
// to one line "<file>:<line>: <key>: <what is wrong>", where key is the path
// into the document (e.g. "receivers[2].address"). Checks: YAML syntax, every
// required key present with the right type, finite numbers, positive sizes,
// unique ids and radio addresses (receivers and beacons share one address
// space), at least 3 receivers, receivers not all on one line in the floor
// plane, receivers and beacon heights inside the room, robot and marker
// references that resolve, HSV ranges in OpenCV's bounds, no two colour
// classes of one camera overlapping (HsvRangesOverlap), and no unknown keys
// (a typo must not silently fall back to a default).
bool LoadSite(const std::string& path, Site* site, std::string* error);

// As LoadSite, from text; `name` stands for the file in messages and
// relative paths resolve against `base_dir`.
bool ParseSite(const std::string& yaml_text, const std::string& name, const std::string& base_dir,
               Site* site, std::string* error);

// True when some HSV pixel falls in both classes' boxes: the hue ranges
// (each wrapping through 0 when hsv_min H > hsv_max H) intersect and so do
// the saturation and value intervals (all bounds inclusive, as cv::inRange).
// LoadSite rejects two such classes on one camera: a pixel in both could not
// be classified.
bool HsvRangesOverlap(const MarkerClass& a, const MarkerClass& b);

// Parses "0x0013A20040A1B2C3", "0013A200 40A1B2C3" or "00:13:a2:...":
// 16 hex digits with optional 0x prefix and space, colon or dash separators.
bool ParseRadioAddress(const std::string& text, uint64_t* address);
std::string FormatRadioAddress(uint64_t address);

}  // namespace roomfix

#endif  // ROOMFIX_CORE_WORLD_SITE_H_
