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
  // One sigma of the robot's pitch and of its roll while it drives (a bumpy
  // floor, a caster), degrees: the markers move marker_height_m x tilt over
  // the floor, which the camera cannot see and the pose covariance includes.
  double tilt_sigma_deg = 0.0;
};

// pose2d_t.camera_id of a pose no camera measured (ultrasound, fused,
// ground truth); a site's camera ids are 0 or more.
inline constexpr int kNoCameraId = -1;

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
  // How the camera exposes and stamps a frame (docs/camera.md, "Time of a
  // marker"): row r of H is read at t_frame_start + r * readout_s / H after
  // integrating light for exposure_s, and the frame's capture time is the
  // last row's read time plus timestamp_latency_s. readout_s 0 is a global
  // shutter; all three 0 stamp every marker with the capture time.
  double readout_s = 0.0;
  double exposure_s = 0.0;
  double timestamp_latency_s = 0.0;
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

// What a 1080p USB webcam behind a 120-degree lens adds to the ideal image:
// the synthetic camera's `webcam` scenario (sim/synthetic_camera.h) renders
// with these. Each member is a key of the same name under the site's
// `simulation.webcam`; the defaults are published webcam and sensor figures
// (docs/synthetic_camera.md names each source and gives each model's
// equation). Zero, false or 1 for a gain switches an effect off.
struct WebcamSimulation {
  // Optics. Gaussian point spread (defocus and lens blur), sigma in pixels.
  double psf_sigma_px = 1.2;
  // Relative illumination at the image corner (cos^4-like falloff of an
  // equivalent rectilinear lens; 1 = no vignetting).
  double vignetting_corner_gain = 0.7;
  // The truth lens's distortion k1..k4 (theta_d = theta (1 + k1 theta^2 +
  // ...)) and principal point offset, added to the model the camera renders
  // through: the real lens is not the nominal equidistant one.
  std::array<double, 4> lens_k = {0.03, -0.01, 0.0, 0.0};
  std::array<double, 2> lens_principal_offset_px = {6.0, -4.0};
  // Exposure: each row integrates light over exposure_s (motion blur) and
  // rows are read one after another over readout_s (rolling shutter; the
  // shared camera-timing contract, docs/synthetic_camera.md).
  double exposure_s = 0.0156;
  double readout_s = 0.030;
  // Slow auto-exposure and white-balance drift: relative gain amplitudes and
  // periods.
  double auto_exposure_drift = 0.04;
  double auto_exposure_period_s = 17.0;
  double white_balance_drift = 0.03;
  double white_balance_period_s = 23.0;
  // Sensor: electrons at which the 8-bit output saturates (at the analogue
  // gain in use) and read noise in electrons; photon shot noise on/off.
  double full_well_e = 6000.0;
  double read_noise_e = 3.0;
  bool shot_noise = true;
  // The sRGB transfer curve (IEC 61966-2-1) between linear light and the
  // 8-bit output; false: noise is added in 8-bit units directly.
  bool srgb_gamma = true;
  // An RGGB colour filter mosaic, demosaiced by OpenCV.
  bool bayer = true;
  // MJPEG quality 1..100 (libjpeg's defaults, which OpenCV's encoder keeps,
  // subsample chroma 4:2:0); 0: frames handed over raw.
  int jpeg_quality = 80;
  // The world: the robot tilting (a static lean, a tilt against its
  // acceleration, rocking while it drives) and marker paint fading (wear)
  // and whitening at oblique views (sheen).
  double tilt_static_deg = 0.5;
  double tilt_per_acceleration_deg_per_mps2 = 2.0;
  double tilt_rocking_deg = 1.0;
  double marker_wear = 0.15;
  double marker_sheen = 0.15;
  // Timing: the buffer's timestamp is the last row's read time plus a fixed
  // latency plus a uniform jitter in [-timestamp_jitter_s, +timestamp_jitter_s].
  double timestamp_latency_s = 0.005;
  double timestamp_jitter_s = 0.0005;
};

// How ultrasound decays in the room: what sizes the beacons' firing slots
// (core/world/air_model.h; docs/trilateration.md, "Sharing the air").
struct Acoustics {
  // The transducers' frequency, Hz.
  double frequency_hz = 40000.0;
  // Relative humidity of the room's air, %: with the temperature it sets the
  // air's absorption (ISO 9613-1), about 1.1 to 1.3 dB/m at 40 kHz indoors.
  double humidity_percent = 50.0;
  // Mean absorption coefficient of the room's surfaces at frequency_hz
  // (0: a perfect mirror, 1: open air). Painted walls, glass and concrete
  // floors reflect ultrasound almost completely; 0.1 counts furniture.
  double wall_absorption = 0.1;
  // Length of the ultrasonic burst, s (40 cycles at 40 kHz).
  double pulse_s = 0.001;
  // The detection threshold lies this far below the weakest direct arrival
  // the room can produce (the farthest receiver): dB.
  double detection_margin_db = 10.0;
  // How long a pulse keeps a receiver above its threshold after the pulse
  // has arrived, s; nullopt: computed from the room (ComputeRoomDecay).
  std::optional<double> decay_s;
  // How far a beacon's slot may be off from where the TDMA table puts it:
  // synchronisation jitter and crystal drift between announcements, s.
  double clock_uncertainty_s = 0.001;
};

// A coordinator (XBee on a host's serial port) and the receivers whose
// reports reach the PC through it; each has its own zigbee_bridge (--radio).
struct RadioNetwork {
  int id = 0;
  // The coordinator's serial device on its host (informative: the bridge's
  // --port says where it is).
  std::string device;
  std::vector<int> receiver_ids;
};

// Something solid in the room that ultrasound does not pass through: a
// cupboard (a box), a pillar or a table leg (a vertical cylinder), a person
// walking (a cylinder following a trajectory). The simulator blocks a range's
// direct path where the segment from beacon to receiver meets one and takes
// the shortest reflected path instead (core/world/acoustic_paths.h); the
// viewer and `roomfix analyze` draw them. A site holds at most kMaxObstacles:
// each simulated range tests every mirror's path against every obstacle, so
// the work per firing grows with their square.
inline constexpr size_t kMaxObstacles = 32;

struct Obstacle {
  enum class Shape { kBox, kCylinder };
  Shape shape = Shape::kBox;
  // For figures and messages; "" when the site gives none.
  std::string name;
  // Centre of the footprint on the floor (room frame). A moving cylinder's
  // centre at time t is its trajectory's position instead (CentreAt).
  std::array<double, 2> centre_m{};
  // Box: full extent along its own x and y axes, which are the room's turned
  // by yaw_rad about z.
  std::array<double, 2> size_m{};
  double yaw_rad = 0.0;
  // Cylinder: radius of the vertical cylinder.
  double radius_m = 0.0;
  // Vertical extent: bottom_m <= z <= top_m (a table top has bottom_m > 0).
  double bottom_m = 0.0;
  double top_m = 0.0;
  // A cylinder that moves (a person); null for a fixed obstacle. Time is the
  // simulation's, s since its start, as for simulation.robots.
  std::shared_ptr<const Trajectory> trajectory;

  std::array<double, 2> CentreAt(double t_s) const;
};

struct Simulation {
  double temperature_c = 20.0;
  std::vector<SimulatedRobot> robots;
  // The `webcam` scenario's parameters (defaults when the site gives none).
  WebcamSimulation webcam;
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
  Acoustics acoustics;
  // Empty: one coordinator carries every receiver.
  std::vector<RadioNetwork> radios;
  // Solid things in the room (site key `obstacles`); empty: an open floor.
  std::vector<Obstacle> obstacles;
  Simulation simulation;

  const Receiver* FindReceiver(int id) const;
  const Receiver* FindReceiverByAddress(uint64_t address) const;
  const Beacon* FindBeacon(int id) const;
  const Beacon* FindBeaconByAddress(uint64_t address) const;
  const Receiver* FindReceiverByShortAddress(uint16_t address) const;
  const Beacon* FindBeaconByShortAddress(uint16_t address) const;
  const Robot* FindRobot(int id) const;
  // The coordinator whose network carries this receiver; nullptr when the
  // site names no radios (or, after validation, never otherwise).
  const RadioNetwork* RadioOfReceiver(int receiver_id) const;
  // The camera with this id (cameras[].id), nullptr when there is none.
  const Camera* FindCamera(int id) const;
  // As FindCamera, but id < 0 (a tool's or process's --camera left out)
  // means the site's first camera; nullptr when there is none.
  const Camera* FindCameraOrFirst(int id) const;
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

// The site as one coordinator's bridge sees it: only the receivers of radio
// `radio_id` (site `radios:`), so that its range sets expect those and its
// allowlist holds those; beacons (whose announcements every coordinator
// hears) stay. False with *error when the site names no such radio.
bool SiteForRadio(const Site& site, int radio_id, Site* out, std::string* error);

// Parses "0x0013A20040A1B2C3", "0013A200 40A1B2C3" or "00:13:a2:...":
// 16 hex digits with optional 0x prefix and space, colon or dash separators.
bool ParseRadioAddress(const std::string& text, uint64_t* address);
std::string FormatRadioAddress(uint64_t address);

}  // namespace roomfix

#endif  // ROOMFIX_CORE_WORLD_SITE_H_
