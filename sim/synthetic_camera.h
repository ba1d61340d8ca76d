#ifndef ROOMFIX_SIM_SYNTHETIC_CAMERA_H_
#define ROOMFIX_SIM_SYNTHETIC_CAMERA_H_

#include <cstdint>
#include <memory>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "core/calib/fisheye_camera.h"
#include "core/world/site.h"

namespace roomfix::sim {

// What the synthetic camera adds to a clean view of the floor. Everything is
// a deterministic function of time and the seed, so a sequence re-renders
// identically.
struct SimScenario {
  std::string name = "clean";
  // Brightness: gain steps cycling through `gain_steps` every
  // `gain_step_period_s`, with a linear ramp of `gain_ramp_s` between steps
  // (the +-40 % of the lighting issue is {1.0, 1.4, 0.6}). Step n covers
  // [n period, (n + 1) period) and ramps from step n - 1's gain over its
  // first `gain_ramp_s`; step 0 (and any t < 0) is gain_steps[0] flat.
  std::vector<double> gain_steps = {1.0};
  double gain_step_period_s = 3.0;
  double gain_ramp_s = 0.5;
  // Gain across the floor: 1 - gradient at the room's min x, 1 + gradient at
  // its max x (a window on one side).
  double gradient = 0.0;
  // Mains flicker seen through a rolling shutter: gain 1 + a sin(2 pi f
  // (t + row * row_time_s)), so bands move through the image.
  double flicker_amplitude = 0.0;
  double flicker_hz = 100.0;
  double row_time_s = 1.0 / 30.0 / 1125.0;
  // Zero-mean Gaussian sensor noise, digital numbers (8-bit), per channel.
  double noise_sigma_dn = 0.0;
  // Objects of marker-like colour lying on the floor (height 0): each is
  // a disc of `diameter_m` at (x_m, y_m) whose colour is the named class's.
  struct Distractor {
    std::string colour_class;
    double x_m = 0.0;
    double y_m = 0.0;
    double diameter_m = 0.1;
  };
  std::vector<Distractor> distractors;
  // Seeds the sensor noise (with the frame sequence number).
  uint32_t seed = 1;
  // The `webcam` scenario: a 1080p USB webcam's optics, exposure, sensor,
  // world and timing (core/world/site.h, WebcamSimulation; each effect
  // switched off by its own member). Off in every other scenario, whose
  // frames stay as they were. With it on, Render's t_s is the instant row 0
  // is read (the frame's start in the camera-timing contract) and the
  // robots' motion over each row's exposure comes from RobotState's
  // velocity and acceleration.
  bool webcam_effects = false;
  WebcamSimulation webcam;
};

// "clean" (alias "reference_circle"), "lighting" (gain steps 1, 1.4, 0.6,
// gradient 0.3, flicker 0.1 at 100 Hz, noise 2 DN), "distractors" (an orange
// and a green disc on the floor away from the robots' paths, plus noise 2 DN),
// "harsh" (both), "webcam" (webcam_effects with WebcamSimulation's
// defaults). Accepts the "sim:" prefix. False with a message naming the
// known scenarios otherwise.
bool ParseSimScenario(const std::string& text, SimScenario* scenario, std::string* error);

// As above; "webcam" takes the site's `simulation.webcam` parameters.
bool ParseSimScenario(const std::string& text, const Site& site, SimScenario* scenario,
                      std::string* error);

// `w` with every optical, timing, motion, noise and wear effect switched
// off (no blur, vignetting, lens distortion, exposure, rolling shutter,
// drift, shot or read noise, Bayer mosaic, tilt, wear, sheen, timestamp
// delay); its tone curve (srgb_gamma) and MJPEG quality are kept. Tests and
// `roomfix_bench camera --error-budget` start from it and switch effects on
// one at a time.
WebcamSimulation WithoutWebcamEffects(WebcamSimulation w);

// Where a robot is at the instant rendered.
struct RobotState {
  int robot_id = 0;
  double x_m = 0.0;
  double y_m = 0.0;
  double heading_rad = 0.0;
  // Motion at that instant (room frame), for the webcam scenario's motion
  // blur, rolling shutter and tilt: over a frame the pose is extrapolated as
  // p + v tau + a tau^2 / 2 and heading + yaw_rate tau. Zero: still.
  double vx_mps = 0.0;
  double vy_mps = 0.0;
  double ax_mps2 = 0.0;
  double ay_mps2 = 0.0;
  double yaw_rate_radps = 0.0;
};

// What the image shows of one marker, for ground truth.
struct MarkerTruth {
  int robot_id = -1;  // -1 for a distractor
  std::string colour_class;
  bool is_heading_marker = false;
  // Centre of the marker disc in the room frame.
  double x_m = 0.0;
  double y_m = 0.0;
  double z_m = 0.0;
  // Projection of the disc's centre.
  double u_px = 0.0;
  double v_px = 0.0;
  // Coverage-weighted centroid of the disc as rendered (what an ideal
  // detector measures; differs from the centre's projection by the
  // perspective and lens distortion of a disc of finite size, < 1 px).
  double centroid_u_px = 0.0;
  double centroid_v_px = 0.0;
  double area_px = 0.0;
  // Whole disc inside the image.
  bool visible = false;
  // The instant (Render's clock, seconds) at which the centroid's row was
  // mid-exposure: t_s + centroid_v_px readout_s / H - exposure_s / 2 (the
  // camera-timing contract, with the row continuous); t_s when the scenario
  // has no rolling shutter or exposure. Under motion blur and the rolling
  // shutter the centroid above is that of the time-averaged image, which
  // for motion linear over the exposure is where the marker was then.
  double exposure_mid_t_s = 0.0;
  // The disc centre (room frame) at exposure_mid_t_s, tilt included.
  double exposure_mid_x_m = 0.0;
  double exposure_mid_y_m = 0.0;
  double exposure_mid_z_m = 0.0;
  // The robot at exposure_mid_t_s: floor position, heading and tilt (the
  // marker mast's lean forward and to the left, radians; NaN for a
  // distractor).
  double robot_x_m = 0.0;
  double robot_y_m = 0.0;
  double robot_heading_rad = 0.0;
  double robot_tilt_forward_rad = 0.0;
  double robot_tilt_left_rad = 0.0;
};

struct SyntheticCameraOptions {
  // Distance from the position marker's centre to the heading marker's,
  // along the heading, metres.
  double heading_marker_offset_m = 0.10;
  // Subsamples per pixel side when computing how much of a pixel a marker
  // covers (anti-aliasing; 8 gives centroids exact to ~0.01 px).
  int supersample = 8;
  // Floor colour (BGR) and the grid lines' colour and width.
  cv::Scalar floor_bgr = cv::Scalar(150, 160, 165);
  cv::Scalar grid_bgr = cv::Scalar(60, 60, 60);
  double grid_line_width_m = 0.01;
  // Robot body: a dark disc under the markers, `body_diameter_m` across, at
  // `body_height_m` below the markers.
  double body_diameter_m = 0.30;
  cv::Scalar body_bgr = cv::Scalar(45, 45, 45);
  // How far below the markers the body disc is (0 diameter: no body).
  double body_height_m = 0.05;
};

// The lens a scenario renders through, given the model it was asked for:
// `model` itself, or with the webcam scenario's lens_k added to its k and
// lens_principal_offset_px to its principal point (the real lens is not
// the nominal one). SyntheticCamera::model() is this.
calib::CameraModel TruthLens(const calib::CameraModel& model, const SimScenario& scenario);

// Renders the site's floor, its 0.5 m grid, robots with their markers at
// their true height, distractors, lighting and noise through a fisheye camera
// model (core/calib, the model calibration fits), at the camera's resolution
// (1920 x 1080 for the demo room). Marker colours are the middle of each
// class's HSV range. The floor is rendered once at construction; a frame
// costs the markers' pixels plus one pass for lighting and noise.
class SyntheticCamera {
 public:
  // `camera` names the site camera (classes, robots, resolution); `model`
  // is the truth the image is rendered through.
  SyntheticCamera(const Site& site, const Camera& camera, const calib::CameraModel& model,
                  SimScenario scenario, SyntheticCameraOptions options = {});

  // Renders the instant t_s (seconds since the simulation started; it drives
  // the lighting) with the robots at `robots`. `frame_seq` seeds the noise.
  void Render(double t_s, int64_t frame_seq, const std::vector<RobotState>& robots, cv::Mat* bgr,
              std::vector<MarkerTruth>* truth = nullptr) const;

  // The robots at t_s from the site's simulation section, with their
  // velocity and acceleration (central differences over 5 ms; the
  // acceleration's magnitude capped at 3 m/s^2, so a waypoint corner does
  // not throw the tilt model).
  std::vector<RobotState> SimulatedRobots(double t_s) const;

  // Seconds from Render's t_s to the frame's timestamp: t_read(H - 1) -
  // t_read(0) + latency + jitter = (H - 1) readout_s / H +
  // timestamp_latency_s + a uniform draw in +-timestamp_jitter_s seeded by
  // (seed, frame_seq). 0 without the webcam scenario.
  double TimestampDelayS(int64_t frame_seq) const;

  // The frame as the camera hands it over: JPEG at the webcam scenario's
  // jpeg_quality (4:2:0, libjpeg's default), else at `quality`; quality 0
  // leaves `bytes` empty (raw). False when the encoder fails.
  bool Encode(const cv::Mat& bgr, int quality, std::vector<uint8_t>* bytes) const;
  // The JPEG quality Encode uses given the caller's.
  int JpegQuality(int quality) const;

  // The truth lens the image is rendered through: the model given, with the
  // webcam scenario's lens_k and lens_principal_offset_px added.
  const calib::CameraModel& model() const { return model_; }
  const SimScenario& scenario() const;
  int width_px() const;
  int height_px() const;

 private:
  struct Impl;
  std::shared_ptr<const Impl> impl_;
  calib::CameraModel model_;
};

// Writes a rendered sequence: JPEG frames into a folder (frame_000000.jpg
// ..., created if missing; a path without an extension is a folder) or a
// video file (.avi MJPEG, .mp4 mp4v), and the truth beside it (DIR/truth.csv,
// or FILE_truth.csv for FILE.avi) with one row per marker per frame:
// frame,t_s,utime,robot_id,colour_class,role,x_m,y_m,z_m,u_px,v_px,
// centroid_u_px,centroid_v_px,visible and the robot's heading_rad (role is
// position, heading or distractor; a distractor has robot_id -1 and heading
// nan), then capture_utime (the frame's timestamp, utime +
// TimestampDelayS), exposure_mid_t_s, exposure_mid_x_m, exposure_mid_y_m,
// exposure_mid_z_m, robot_x_m, robot_y_m, robot_heading_rad,
// robot_tilt_forward_rad, robot_tilt_left_rad (MarkerTruth). Frame f is
// t_s = f / fps, utime = start_utime + t_s 1e6, robots from
// SimulatedRobots(t_s), noise seeded by f; JPEG frames through Encode. False
// with a message when the output cannot be written or the extension is not
// .avi or .mp4.
struct SequenceOptions {
  double duration_s = 10.0;
  double fps = 30.0;
  int64_t start_utime = 0;
  int jpeg_quality = 90;
};
bool WriteSequence(const SyntheticCamera& camera, const SequenceOptions& options,
                   const std::string& out_path, std::string* error);

}  // namespace roomfix::sim

#endif  // ROOMFIX_SIM_SYNTHETIC_CAMERA_H_
