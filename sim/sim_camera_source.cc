#include "sim/sim_camera_source.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <sstream>
#include <utility>

#include "msgio/process.h"
#include "roomfix/process_status_t.hpp"
#include "sim/sim_frame_source.h"
#include "sim/synthetic_camera.h"

namespace roomfix {
namespace {

// The lens the synthetic camera renders through: the nominal one of the
// camera's mount and field of view, or a calibration file's full model.
bool SimLens(const Camera& camera, const std::string& sim_lens_path, calib::CameraModel* lens,
             std::string* error) {
  *lens = calib::NominalCamera(camera.mount_position_m, camera.field_of_view_deg, camera.width_px,
                               camera.height_px);
  if (sim_lens_path.empty()) return true;
  calib::Calibration truth;
  std::string why;
  if (!calib::LoadCalibration(sim_lens_path, &truth, &why) ||
      truth.model != calib::Calibration::Model::kFull) {
    *error = "--sim-lens: " + (why.empty() ? sim_lens_path + " is not a full model" : why);
    return false;
  }
  *lens = truth.camera;
  return true;
}

}  // namespace

bool SimCameraOptions::IsValid(std::string* error) const {
  if (jpeg_quality < 0 || jpeg_quality > 100) {
    *error = "sim JPEG quality must be 0..100, not " + std::to_string(jpeg_quality);
    return false;
  }
  if (!(wait_s >= 0.0)) {
    *error = "the sim wait must be >= 0 s";
    return false;
  }
  return true;
}

CalibrationError CalibrationErrorOverRoom(const calib::CameraModel& truth,
                                          const calib::Calibration& calibration, const Room& room,
                                          double height_m) {
  CalibrationError result;
  double sum2 = 0.0;
  std::string why;
  for (double v = 0.0; v < truth.intrinsics.height_px; v += kCalibrationCheckGridPx) {
    for (double u = 0.0; u < truth.intrinsics.width_px; u += kCalibrationCheckGridPx) {
      double x_m = 0.0, y_m = 0.0, cx_m = 0.0, cy_m = 0.0;
      if (!truth.PixelToFloor(u, v, height_m, &x_m, &y_m)) continue;
      if (x_m < room.min_x_m || x_m > room.min_x_m + room.size_x_m || y_m < room.min_y_m ||
          y_m > room.min_y_m + room.size_y_m) {
        continue;
      }
      if (!calibration.PixelToFloor(u, v, height_m, &cx_m, &cy_m, &why)) continue;
      const double d_m = std::hypot(cx_m - x_m, cy_m - y_m);
      sum2 += d_m * d_m;
      result.max_m = std::max(result.max_m, d_m);
      ++result.points;
    }
  }
  if (result.points > 0) result.rms_m = std::sqrt(sum2 / result.points);
  return result;
}

std::string SimCalibrationMismatch(const Site& site, const CameraChoice& choice,
                                   const SimCameraOptions& options) {
  if (!IsSimDevice(choice.device) || !choice.calibration) return "";
  sim::SimScenario scenario;
  calib::CameraModel lens;
  std::string error;
  if (!sim::ParseSimScenario(choice.device, site, &scenario, &error) ||
      !SimLens(choice.camera, options.lens_path, &lens, &error)) {
    return "";  // MakeSimCameraSource refuses these with the reason
  }
  const calib::CameraModel truth = sim::TruthLens(lens, scenario);
  CalibrationError worst;
  for (const CameraRobot& robot : choice.camera.robots) {
    const CalibrationError e =
        CalibrationErrorOverRoom(truth, *choice.calibration, site.room, robot.marker_height_m);
    if (e.rms_m > worst.rms_m) worst = e;
  }
  if (worst.rms_m <= kSimCalibrationToleranceM) return "";
  std::ostringstream text;
  text.precision(1);
  text << std::fixed << "calibration " << choice.calibration_path << " is not the lens "
       << choice.device << " renders through: it puts markers " << worst.rms_m * 1e3
       << " mm RMS (up to " << worst.max_m * 1e3
       << " mm) from where they are on the floor (the webcam scenario's lens has its own fit, "
          "config/calibration/demo_room_webcam.yaml for the demo room; give it with "
          "--calibration)";
  return text.str();
}

int64_t WaitForSimClock(Bus* bus, double wait_s) {
  int64_t start_utime = 0;
  const auto sub = bus->Subscribe<process_status_t>(
      kStatusChannel, [&](const process_status_t& s, const MessageInfo&) {
        if (s.process == "roomfix_sim" && start_utime == 0) {
          start_utime = s.utime - s.uptime_us;
          spdlog::info("synthetic camera on roomfix_sim's clock (pid {} on {})", s.pid, s.host);
        }
      });
  const auto give_up = std::chrono::steady_clock::now() + std::chrono::duration<double>(wait_s);
  while (start_utime == 0 && !ShutdownRequested() && std::chrono::steady_clock::now() < give_up) {
    if (bus->Handle(100) < 0) break;
  }
  bus->Unsubscribe(sub);
  if (start_utime == 0) {
    spdlog::warn(
        "no roomfix_sim heard in {} s: the synthetic camera keeps its own clock, so "
        "its robot will not match roomfix_sim's ground truth",
        wait_s);
  }
  return start_utime;
}

bool MakeSimCameraSource(const Site& site, const CameraChoice& choice,
                         const SimCameraOptions& options, int64_t start_utime, bool check_only,
                         std::unique_ptr<camera::FrameSource>* source, std::string* summary,
                         std::string* error) {
  const Camera& camera = choice.camera;
  sim::SimScenario scenario;
  if (!sim::ParseSimScenario(choice.device, site, &scenario, error)) return false;
  calib::CameraModel lens;
  if (!SimLens(camera, options.lens_path, &lens, error)) return false;
  *summary = "camera " + std::to_string(camera.id) + ", synthetic " + scenario.name + ", " +
             RobotsAndCalibration(choice);
  if (check_only) return true;
  sim::SimSourceOptions sim_options;
  sim_options.fps = camera.fps;
  sim_options.start_utime = start_utime;
  sim_options.realtime = true;
  sim_options.jpeg_quality = options.jpeg_quality;
  for (const SimCameraOptions::ParkedRobot& p : options.parked_robots) {
    sim_options.parked_robots.push_back(sim::RobotState{p.robot_id, p.x_m, p.y_m, p.heading_rad});
  }
  *source = std::make_unique<sim::SimFrameSource>(
      std::make_shared<sim::SyntheticCamera>(site, camera, lens, scenario), sim_options);
  return true;
}

bool MakeCameraSource(const Site& site, const CameraChoice& choice,
                      const CameraSourceOptions& options, const SimCameraOptions& sim_options,
                      int64_t start_utime, bool check_only,
                      std::unique_ptr<camera::FrameSource>* source, std::string* summary,
                      std::string* error) {
  if (IsSimDevice(choice.device)) {
    return MakeSimCameraSource(site, choice, sim_options, start_utime, check_only, source, summary,
                               error);
  }
  return MakeDeviceSource(choice, options, start_utime, source, summary, error);
}

}  // namespace roomfix
