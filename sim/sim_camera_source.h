#ifndef ROOMFIX_SIM_SIM_CAMERA_SOURCE_H_
#define ROOMFIX_SIM_SIM_CAMERA_SOURCE_H_

// The synthetic camera as a site camera's source (--device sim:SCENARIO):
// its lens, the check that the chosen calibration is of that lens,
// roomfix_sim's clock, and the frame source. camera_proc's main and
// `roomfix grab` build their source here and hand it to the camera layer,
// so that camera_proc's node and app never link the simulator.

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "camera_io/camera_source.h"
#include "camera_io/frame_source.h"
#include "core/calib/fisheye_camera.h"
#include "core/world/site.h"
#include "msgio/bus.h"

namespace roomfix {

// What the synthetic camera's flags choose.
struct SimCameraOptions {
  // Render through this calibration file's full model instead of the
  // nominal lens of the camera's mount and field of view.
  std::string lens_path;
  // Without a start time: how long to wait for roomfix_sim's heartbeat.
  double wait_s = 5.0;
  // JPEG quality of the handed-over frames, 0..100 (0: raw pixels).
  int jpeg_quality = 90;
  // Robots standing still at these floor positions instead of the
  // simulated ones (`roomfix grab --tripod` on the synthetic camera: the
  // simulator stands the tripod where the command says it stands).
  struct ParkedRobot {
    int robot_id = 0;
    double x_m = 0.0;
    double y_m = 0.0;
    double heading_rad = 0.0;
  };
  std::vector<ParkedRobot> parked_robots;

  bool IsValid(std::string* error) const;
};

// How far `calibration` puts a marker at `height_m` from where the lens
// `truth` shows it, over pixels every kCalibrationCheckGridPx whose marker,
// through `truth`, lies on the room's floor: the RMS and the largest floor
// distance. points is 0 when no such pixel maps under both (a 9-region model
// of another height).
inline constexpr double kCalibrationCheckGridPx = 20.0;
struct CalibrationError {
  double rms_m = 0.0;
  double max_m = 0.0;
  int points = 0;
};
CalibrationError CalibrationErrorOverRoom(const calib::CameraModel& truth,
                                          const calib::Calibration& calibration, const Room& room,
                                          double height_m);

// A synthetic camera (sim:) renders through a lens camera_proc knows
// exactly (the nominal lens, --sim-lens, and the webcam scenario's lens_k
// and principal offset), so a calibration of another lens is caught before
// it misplaces every pose: "" when the chosen calibration is within
// kSimCalibrationToleranceM RMS of that lens over the floor at every
// robot's marker height, else one line saying by how much it is off. The
// RMS over the floor, not the largest: a good fit drifts in the corners it
// had no points in. Measured on the demo room: demo_room_webcam.yaml, fitted
// to the webcam's images, 1.8 mm RMS and 2.6 mm at most (the fit also
// absorbs that a disc's centroid is not its centre's projection); the
// site's calibration of the nominal lens 29.8 mm RMS, 82.6 mm at most (2.3
// cm on the reference circle, issue #32). 5 mm sits between them.
inline constexpr double kSimCalibrationToleranceM = 0.005;
std::string SimCalibrationMismatch(const Site& site, const CameraChoice& choice,
                                   const SimCameraOptions& options);

// The synthetic camera must share roomfix_sim's t = 0 to show the robot where
// the simulator says it is: its STATUS time minus its uptime, from the first
// heartbeat heard on `bus` within wait_s (so separately started processes,
// as under bot-procman, agree too). 0 when none is heard in time (a warning
// says the camera keeps its own clock), or when a shutdown is asked for.
int64_t WaitForSimClock(Bus* bus, double wait_s);

// The synthetic camera's frame source for `choice.device` (sim:SCENARIO),
// real time on the clock start_utime. *summary is the one-line description
// --check prints ("camera 1, synthetic clean, ..."). With check_only it is
// not built (*source stays empty). False with a reason (an unknown scenario,
// an unreadable --sim-lens).
bool MakeSimCameraSource(const Site& site, const CameraChoice& choice,
                         const SimCameraOptions& options, int64_t start_utime, bool check_only,
                         std::unique_ptr<camera::FrameSource>* source, std::string* summary,
                         std::string* error);

// Any site camera's source: MakeSimCameraSource for sim:, else
// MakeDeviceSource (camera_io/camera_source.h), whose making is its check.
bool MakeCameraSource(const Site& site, const CameraChoice& choice,
                      const CameraSourceOptions& options, const SimCameraOptions& sim_options,
                      int64_t start_utime, bool check_only,
                      std::unique_ptr<camera::FrameSource>* source, std::string* summary,
                      std::string* error);

}  // namespace roomfix

#endif  // ROOMFIX_SIM_SIM_CAMERA_SOURCE_H_
