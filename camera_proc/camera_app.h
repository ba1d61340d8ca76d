#ifndef ROOMFIX_CAMERA_PROC_CAMERA_PROCESS_H_
#define ROOMFIX_CAMERA_PROC_CAMERA_PROCESS_H_

// camera_proc around its node: which camera and calibration, the synthetic
// camera's clock, the frame source, and the read loop that keeps a live
// camera open. camera_proc_main.cc is its flags and calls to these.

#include <cstdint>
#include <memory>
#include <optional>
#include <string>

#include "camera_proc/camera_node.h"
#include "camera_proc/frame_source.h"
#include "core/calib/calibration_file.h"
#include "core/world/site.h"
#include "msgio/bus.h"

namespace roomfix {

// What camera_proc's flags choose besides CameraNodeOptions.
struct CameraProcOptions {
  // The site camera with this id; -1: the site's first camera.
  int camera_id = -1;
  // "": the site camera's device. Otherwise /dev/videoN, a video file, an
  // image folder or glob, or sim:SCENARIO.
  std::string device;
  // "": the site camera's calibration file; "none": pixels only.
  std::string calibration_path;
  // sim: render through this calibration file's full model instead of the
  // nominal lens of the camera's mount and field of view.
  std::string sim_lens_path;
  // t = 0 of the simulation, or the first file frame's time; 0: roomfix_sim's
  // clock (sim, see WaitForSimClock) or now.
  int64_t start_utime = 0;
  // sim without start_utime: how long to wait for roomfix_sim's heartbeat.
  double sim_wait_s = 5.0;
  // Files: paced at the camera's frame rate; started again at the end.
  bool realtime = false;
  bool loop_files = false;
  // sim: JPEG quality of the handed-over frames, 0..100 (0: raw pixels).
  int sim_jpeg_quality = 90;
  // sim: robots standing still at these floor positions instead of the
  // simulated ones (`roomfix grab --tripod` on the synthetic camera: the
  // simulator stands the tripod where the command says it stands).
  struct ParkedRobot {
    int robot_id = 0;
    double x_m = 0.0;
    double y_m = 0.0;
    double heading_rad = 0.0;
  };
  std::vector<ParkedRobot> sim_parked_robots;
  // Stop after this long (0: until a signal or the end of a file source).
  double duration_s = 0.0;
  // Longest wait between attempts to reopen a lost live camera, s.
  double reopen_max_s = 2.0;
  // > 0: the frame rate to request (a device) or render (sim:), at most the
  // site camera's; a machine too small for several cameras at full rate
  // (scripts/demo.sh on 2 cores, docs/operations.md "A hall") runs them
  // slower while the site keeps the installation's rate. 0: the site's.
  double fps = 0.0;

  bool IsValid(std::string* error) const;
};

// Whether a device string names the synthetic camera ("sim:SCENARIO").
bool IsSimDevice(const std::string& device);

// The camera, device and calibration camera_proc runs with.
struct CameraChoice {
  // A copy of the site's camera with CameraProcOptions::fps applied; the node
  // keeps a reference to it, so the choice outlives the node.
  Camera camera;
  std::string device;
  std::string calibration_path;  // "" or "none" for pixels only
  std::optional<calib::Calibration> calibration;
};

// Picks the site camera, fills device and calibration path from it where the
// options leave them empty, and loads the calibration. False with a reason:
// no such camera, a rate over the camera's, an unreadable calibration, one for another frame size
// or one whose fit residual is too large (calib::CheckFitResidual).
bool ChooseCamera(const Site& site, const CameraProcOptions& options, CameraChoice* choice,
                  std::string* error);

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
                                   const CameraProcOptions& options);

// The synthetic camera must share roomfix_sim's t = 0 to show the robot where
// the simulator says it is: its STATUS time minus its uptime, from the first
// heartbeat heard on `bus` within wait_s (so separately started processes,
// as under bot-procman, agree too). 0 when none is heard in time (a warning
// says the camera keeps its own clock), or when a shutdown is asked for.
int64_t WaitForSimClock(Bus* bus, double wait_s);

// The frame source for `choice.device`: the synthetic camera (sim:) or a
// webcam, video file or image folder (camera::MakeFrameSource), on the clock
// start_utime. *summary is the one-line description --check prints
// ("camera 1, synthetic clean"). With check_only the synthetic camera is not
// built (*source stays empty); a device source is, since making it is the
// check. False with a reason (an unknown scenario, an unreadable --sim-lens).
bool MakeCameraSource(const Site& site, const CameraChoice& choice,
                      const CameraProcOptions& options, int64_t start_utime, bool check_only,
                      std::unique_ptr<camera::FrameSource>* source, std::string* summary,
                      std::string* error);

// How RunCameraSource paces itself.
struct CameraLoopOptions {
  // Stop after this long (<= 0: until a shutdown is asked for or a file
  // source ends).
  double duration_s = 0.0;
  // The wait before reopening a lost live camera starts at first_reopen_s and
  // doubles up to reopen_max_s.
  double first_reopen_s = 0.1;
  double reopen_max_s = 2.0;
  // Hints (other sensors' poses) are dispatched for at most this long before
  // each frame: a third of a 30 fps frame period, so a flood cannot starve
  // the camera.
  int64_t hint_drain_budget_us = 10000;
};

// The read loop: opens the source (a live one is retried with a doubling
// wait, a webcam unplugged and plugged back in comes back on its own),
// dispatches the bus, reads frames into the node (an unreadable one counted
// under its camera::FrameProblem), reopens a lost device, and ends at the end
// of a file source, at the duration or when a shutdown is asked for.
// Stops the node and closes the source (joining a synthetic camera's
// renderer). Returns 0, or 1 when a file source cannot be opened (the reason
// in *error) or LCM fails (the reason logged).
int RunCameraSource(camera::FrameSource* source, CameraNode* node, Bus* bus,
                    const CameraLoopOptions& options, std::string* error);

}  // namespace roomfix

#endif  // ROOMFIX_CAMERA_PROC_CAMERA_PROCESS_H_
