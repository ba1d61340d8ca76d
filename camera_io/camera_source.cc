#include "camera_io/camera_source.h"

#include <cmath>
#include <sstream>

namespace roomfix {

bool CameraSourceOptions::IsValid(std::string* error) const {
  if (!(fps >= 0.0) || !std::isfinite(fps)) {
    *error = "the frame rate must be > 0 fps (0: the site's)";
    return false;
  }
  return true;
}

bool IsSimDevice(const std::string& device) { return device.rfind("sim:", 0) == 0; }

bool ChooseCamera(const Site& site, const CameraSourceOptions& options, CameraChoice* choice,
                  std::string* error) {
  const Camera* camera = site.FindCameraOrFirst(options.camera_id);
  if (camera == nullptr) {
    *error = "the site has no camera" +
             (options.camera_id >= 0 ? " with id " + std::to_string(options.camera_id) : "");
    return false;
  }
  if (options.fps > camera->fps) {
    std::ostringstream text;
    text << "--fps " << options.fps << " is over camera " << camera->id << "'s " << camera->fps
         << " fps";
    *error = text.str();
    return false;
  }
  choice->camera = *camera;
  if (options.fps > 0.0) choice->camera.fps = options.fps;
  choice->device = options.device.empty() ? camera->device : options.device;
  choice->calibration_path =
      options.calibration_path.empty() ? camera->calibration_file : options.calibration_path;
  choice->calibration.reset();
  const std::string& path = choice->calibration_path;
  if (path.empty() || path == "none") return true;
  calib::Calibration c;
  if (!calib::LoadCalibration(path, &c, error)) return false;
  if (c.width_px() != camera->width_px || c.height_px() != camera->height_px) {
    *error = path + " is for " + std::to_string(c.width_px()) + "x" +
             std::to_string(c.height_px()) + " px, the camera delivers " +
             std::to_string(camera->width_px) + "x" + std::to_string(camera->height_px);
    return false;
  }
  if (const std::string fit = calib::CheckFitResidual(c); !fit.empty()) {
    *error = path + ": " + fit;
    return false;
  }
  choice->calibration = c;
  return true;
}

std::string RobotsAndCalibration(const CameraChoice& choice) {
  return std::to_string(choice.camera.robots.size()) + " robots, " +
         (choice.calibration ? "calibrated (" + choice.calibration_path + ")" : "pixels only");
}

bool MakeDeviceSource(const CameraChoice& choice, const CameraSourceOptions& options,
                      int64_t start_utime, std::unique_ptr<camera::FrameSource>* source,
                      std::string* summary, std::string* error) {
  const Camera& camera = choice.camera;
  camera::CaptureSettings settings;
  settings.width_px = camera.width_px;
  settings.height_px = camera.height_px;
  settings.fps = camera.fps;
  settings.pixel_format = camera.pixel_format;
  settings.properties = camera.properties;
  settings.realtime = options.realtime;
  settings.start_utime = start_utime;
  settings.loop = options.loop_files;
  *source = camera::MakeFrameSource(choice.device, settings, error);
  if (*source == nullptr) return false;
  std::ostringstream fps;
  fps << camera.fps;
  *summary = "camera " + std::to_string(camera.id) + ", " + choice.device + " " +
             std::to_string(camera.width_px) + "x" + std::to_string(camera.height_px) + " " +
             camera.pixel_format + " at " + fps.str() + " fps, " + RobotsAndCalibration(choice);
  return true;
}

}  // namespace roomfix
