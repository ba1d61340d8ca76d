#include "camera_proc/camera_process.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <sstream>
#include <thread>
#include <utility>

#include "camera_proc/sim_frame_source.h"
#include "msgio/process.h"
#include "roomfix/process_status_t.hpp"
#include "sim/synthetic_camera.h"

namespace roomfix {
namespace {

std::string RobotsAndCalibration(const Camera& camera, const CameraChoice& choice) {
  return std::to_string(camera.robots.size()) + " robots, " +
         (choice.calibration ? "calibrated (" + choice.calibration_path + ")" : "pixels only");
}

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

bool CameraProcOptions::IsValid(std::string* error) const {
  if (sim_jpeg_quality < 0 || sim_jpeg_quality > 100) {
    *error = "sim JPEG quality must be 0..100, not " + std::to_string(sim_jpeg_quality);
    return false;
  }
  if (!(sim_wait_s >= 0.0) || !(duration_s >= 0.0)) {
    *error = "the sim wait and the duration must be >= 0 s";
    return false;
  }
  if (!(fps >= 0.0) || !std::isfinite(fps)) {
    *error = "the frame rate must be > 0 fps (0: the site's)";
    return false;
  }
  if (!(reopen_max_s > 0.0)) {
    *error = "the longest reopen wait must be > 0 s, not " + std::to_string(reopen_max_s);
    return false;
  }
  return true;
}

bool IsSimDevice(const std::string& device) { return device.rfind("sim:", 0) == 0; }

bool ChooseCamera(const Site& site, const CameraProcOptions& options, CameraChoice* choice,
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
                                   const CameraProcOptions& options) {
  if (!IsSimDevice(choice.device) || !choice.calibration) return "";
  sim::SimScenario scenario;
  calib::CameraModel lens;
  std::string error;
  if (!sim::ParseSimScenario(choice.device, site, &scenario, &error) ||
      !SimLens(choice.camera, options.sim_lens_path, &lens, &error)) {
    return "";  // MakeCameraSource refuses these with the reason
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

bool MakeCameraSource(const Site& site, const CameraChoice& choice,
                      const CameraProcOptions& options, int64_t start_utime, bool check_only,
                      std::unique_ptr<camera::FrameSource>* source, std::string* summary,
                      std::string* error) {
  const Camera& camera = choice.camera;
  if (IsSimDevice(choice.device)) {
    sim::SimScenario scenario;
    if (!sim::ParseSimScenario(choice.device, site, &scenario, error)) return false;
    calib::CameraModel lens;
    if (!SimLens(camera, options.sim_lens_path, &lens, error)) return false;
    *summary = "camera " + std::to_string(camera.id) + ", synthetic " + scenario.name + ", " +
               RobotsAndCalibration(camera, choice);
    if (check_only) return true;
    camera::SimSourceOptions sim_options;
    sim_options.fps = camera.fps;
    sim_options.start_utime = start_utime;
    sim_options.realtime = true;
    sim_options.jpeg_quality = options.sim_jpeg_quality;
    for (const CameraProcOptions::ParkedRobot& p : options.sim_parked_robots) {
      sim_options.parked_robots.push_back(sim::RobotState{p.robot_id, p.x_m, p.y_m, p.heading_rad});
    }
    *source = std::make_unique<camera::SimFrameSource>(
        std::make_shared<sim::SyntheticCamera>(site, camera, lens, scenario), sim_options);
    return true;
  }
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
             camera.pixel_format + " at " + fps.str() + " fps, " +
             RobotsAndCalibration(camera, choice);
  return true;
}

int RunCameraSource(camera::FrameSource* source, CameraNode* node, Bus* bus,
                    const CameraLoopOptions& options, std::string* error) {
  using Seconds = std::chrono::duration<double>;
  const auto stop_at = std::chrono::steady_clock::now() + Seconds(options.duration_s);
  auto timed_out = [&] {
    return options.duration_s > 0.0 && std::chrono::steady_clock::now() >= stop_at;
  };
  double backoff_s = options.first_reopen_s;
  bool open = false;
  int rc = 0;
  bool ended = false;
  while (!ended && !ShutdownRequested() && !timed_out()) {
    const int64_t now = NowUtime();
    if (!open) {
      if (source->Open(error)) {
        open = true;
        backoff_s = options.first_reopen_s;
        node->OnSourceUp(source->Describe(), source->refused_properties(), now);
        continue;
      }
      if (!source->live()) {
        rc = 1;
        break;
      }
      node->OnSourceDown(*error, now);
      spdlog::warn("{}; retrying in {:.1f} s", *error, backoff_s);
      node->Tick(now);
      Seconds wait(backoff_s);
      if (options.duration_s > 0.0) {
        wait = std::min<Seconds>(wait, stop_at - std::chrono::steady_clock::now());
      }
      if (wait.count() > 0.0) std::this_thread::sleep_for(wait);
      backoff_s = std::min(options.reopen_max_s, backoff_s * 2.0);
      continue;
    }
    // Never blocks (see hint_drain_budget_us).
    if (DrainBus(bus, options.hint_drain_budget_us) < 0) {
      spdlog::error("LCM failed: {}", bus->stats().last_error);
      error->clear();  // logged: not a source's reason
      rc = 1;
      break;
    }
    camera::Frame frame;
    const camera::ReadStatus status = source->Read(&frame, error);
    const int64_t read_utime = NowUtime();
    switch (status) {
      case camera::ReadStatus::kFrame:
        node->OnFrame(&frame, read_utime);
        break;
      case camera::ReadStatus::kBadFrame:
        node->OnBadFrame(camera::FrameProblemCounter(frame.problem), *error, read_utime);
        break;
      case camera::ReadStatus::kEndOfStream:
        node->OnEndOfStream(read_utime);
        ended = true;
        break;
      case camera::ReadStatus::kDeviceLost:
        spdlog::warn("{}; reopening", *error);
        source->Close();
        open = false;
        node->OnSourceDown(*error, read_utime);
        break;
    }
    node->Tick(read_utime);
  }
  node->Stop(NowUtime());
  // Joins a synthetic camera's renderer before the summary.
  source->Close();
  spdlog::info("stopped: {} frames processed, {} dropped, {} skipped by the source",
               node->frames_processed(), node->status().dropped(),
               node->status().counter("source_skipped_frames"));
  return rc;
}

}  // namespace roomfix
