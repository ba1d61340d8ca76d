#ifndef ROOMFIX_CAMERA_IO_CAMERA_SOURCE_H_
#define ROOMFIX_CAMERA_IO_CAMERA_SOURCE_H_

// A site camera chosen and its device opened as camera_proc opens it (the
// site's size, format, rate and properties), for camera_proc and for
// `roomfix grab`. The synthetic camera (sim:) is the simulator's:
// sim/sim_camera_source.h.

#include <cstdint>
#include <memory>
#include <optional>
#include <string>

#include "camera_io/frame_source.h"
#include "core/calib/calibration_file.h"
#include "core/world/site.h"

namespace roomfix {

// Which camera, device and calibration, and how a file source plays.
struct CameraSourceOptions {
  // The site camera with this id; -1: the site's first camera.
  int camera_id = -1;
  // "": the site camera's device. Otherwise /dev/videoN, a video file, an
  // image folder or glob, or sim:SCENARIO.
  std::string device;
  // "": the site camera's calibration file; "none": pixels only.
  std::string calibration_path;
  // Files: paced at the camera's frame rate; started again at the end.
  bool realtime = false;
  bool loop_files = false;
  // > 0: the frame rate to request (a device) or render (sim:), at most the
  // site camera's; a machine too small for several cameras at full rate
  // (scripts/demo.sh on 2 cores, docs/operations.md "A hall") runs them
  // slower while the site keeps the installation's rate. 0: the site's.
  double fps = 0.0;

  bool IsValid(std::string* error) const;
};

// Whether a device string names the synthetic camera ("sim:SCENARIO").
bool IsSimDevice(const std::string& device);

// The camera, device and calibration a camera runs with.
struct CameraChoice {
  // A copy of the site's camera with CameraSourceOptions::fps applied; the
  // node keeps a reference to it, so the choice outlives the node.
  Camera camera;
  std::string device;
  std::string calibration_path;  // "" or "none" for pixels only
  std::optional<calib::Calibration> calibration;
};

// Picks the site camera, fills device and calibration path from it where the
// options leave them empty, and loads the calibration. False with a reason:
// no such camera, a rate over the camera's, an unreadable calibration, one for another frame size
// or one whose fit residual is too large (calib::CheckFitResidual).
bool ChooseCamera(const Site& site, const CameraSourceOptions& options, CameraChoice* choice,
                  std::string* error);

// "N robots, calibrated (PATH)" or "N robots, pixels only": the end of the
// line --check prints for a source.
std::string RobotsAndCalibration(const CameraChoice& choice);

// The frame source for a device (not sim:): a webcam, video file or image
// folder (camera::MakeFrameSource) with the site camera's settings, on the
// clock start_utime. *summary is the one-line description --check prints
// ("camera 1, /dev/video0 1920x1080 MJPG at 30 fps, ..."). False with a
// reason.
bool MakeDeviceSource(const CameraChoice& choice, const CameraSourceOptions& options,
                      int64_t start_utime, std::unique_ptr<camera::FrameSource>* source,
                      std::string* summary, std::string* error);

}  // namespace roomfix

#endif  // ROOMFIX_CAMERA_IO_CAMERA_SOURCE_H_
