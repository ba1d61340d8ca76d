// camera_proc: ceiling camera frames to marker pixels (MARKER_PIXELS) and,
// with a calibration, camera poses (POSE_CAMERA).
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <iostream>
#include <thread>

#include "camera_proc/camera_node.h"
#include "camera_proc/frame_source.h"
#include "camera_proc/image_file.h"
#include "camera_proc/sim_frame_source.h"
#include "msgio/process.h"
#include "roomfix/process_status_t.hpp"
#include "sim/synthetic_camera.h"

namespace {

constexpr int64_t kHintDrainBudgetUs = 10000;

// --camera ID picks the site's camera with that id (one camera_proc per
// camera, docs/operations.md); without it, the first camera.
const roomfix::Camera* FindCamera(const roomfix::Site& site, int id) {
  if (id < 0) return site.cameras.empty() ? nullptr : &site.cameras.front();
  return site.FindCamera(id);
}

// The STATUS counter for a frame the source could not hand over.
std::string BadFrameReason(const std::string& error) {
  // Over the camera's size, refused from its header before decoding.
  if (error.find(roomfix::camera::kTooLargeText) != std::string::npos) return "wrong_frame_size";
  if (error.find("empty") != std::string::npos) return "empty_frame";
  if (error.find("truncated") != std::string::npos ||
      error.find("remature end") != std::string::npos) {
    return "truncated_frame";
  }
  return "unreadable_frame";
}

}  // namespace

int main(int argc, char** argv) {
  roomfix::ProcessOptions process;
  roomfix::CameraNodeOptions options;
  int camera_id = -1;
  std::string device;
  std::string calibration_path;
  std::string lighting = "adaptive";
  std::string sim_lens_path;
  int64_t start_utime = 0;
  bool realtime = false;
  bool loop_files = false;
  int sim_jpeg_quality = 90;
  double duration_s = 0.0;
  double reopen_max_s = 2.0;
  double fps = 0.0;
  CLI::App app{
      "camera_proc: finds the robots' coloured markers in the ceiling camera's frames and "
      "publishes MARKER_PIXELS and, with a calibration, POSE_CAMERA"};
  roomfix::AddProcessFlags(&app, &process, /*config_required=*/true);
  app.add_option("--camera", camera_id, "Camera id in the site file (default: the first)");
  app.add_option("--device", device,
                 "Override the site's device: /dev/videoN, a video file, an image folder or glob, "
                 "or sim:SCENARIO (clean, lighting, distractors, harsh, webcam)");
  app.add_option("--calibration", calibration_path,
                 "Calibration YAML (default: the site camera's calibration; none: pixels only)");
  app.add_option("--lighting", lighting,
                 "Colour classification: fixed (the site's ranges, as the reference), normalised "
                 "(against the local background brightness) or adaptive (normalised, following "
                 "each tracked marker's colour)")
      ->capture_default_str()
      ->check(CLI::IsMember({"fixed", "normalised", "adaptive"}));
  app.add_option("--full-search-scale", options.full_search_scale,
                 "Reduction of the full-frame search (1, 2, 4, 8)")
      ->capture_default_str();
  app.add_option("--absent-search-period", options.absent_search_period_frames,
                 "Robots out of view: a full-frame search once in this many frames")
      ->check(CLI::Range(1, 300));
  app.add_option("--max-speed", options.max_speed_mps, "Robots' top speed, m/s (sizes windows)")
      ->capture_default_str();
  app.add_option("--start-utime", start_utime,
                 "Simulation and file clock: t = 0 of the simulated robots (give roomfix_sim the "
                 "same), or the first file frame's time; default now");
  double sim_wait_s = 5.0;
  app.add_option("--sim-wait", sim_wait_s,
                 "sim: without --start-utime, wait this long for roomfix_sim's heartbeat to "
                 "share its clock")
      ->capture_default_str();
  app.add_flag("--realtime", realtime,
               "Files: play at the camera's frame rate instead of as fast as they are read");
  app.add_flag("--loop", loop_files, "Files: start again at the end");
  app.add_option("--sim-jpeg-quality", sim_jpeg_quality,
                 "sim: hand frames over as JPEG of this quality, as a webcam's MJPEG (0: raw)")
      ->capture_default_str()
      ->check(CLI::Range(0, 100));
  app.add_option("--sim-lens", sim_lens_path,
                 "sim: render through this calibration file's full model (default: the nominal "
                 "lens of the site's mount position and field of view)");
  app.add_option("--reopen-max", reopen_max_s,
                 "Longest wait between attempts to reopen a lost "
                 "camera, s")
      ->capture_default_str();
  // A machine too small for several cameras at full rate (scripts/demo.sh on
  // 2 cores, docs/operations.md "A hall") runs them slower; the site keeps
  // the installation's rate.
  app.add_option("--fps", fps,
                 "Frame rate to request (a device) or render (sim:), at most the site camera's "
                 "(default: the site's)")
      ->check(CLI::PositiveNumber);
  app.add_option("--duration", duration_s, "Stop after this many seconds (0: until a signal)")
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);

  options.lighting = lighting == "fixed"        ? roomfix::vision::LightingMode::kFixed
                     : lighting == "normalised" ? roomfix::vision::LightingMode::kNormalised
                                                : roomfix::vision::LightingMode::kAdaptive;
  std::string error;
  if (!options.IsValid(&error)) {
    std::cerr << "camera_proc: " << error << "\n";
    return 1;
  }
  auto ctx = roomfix::StartProcess("camera_proc", process, &error);
  if (ctx == nullptr) {
    std::cerr << "camera_proc: " << error << "\n";
    return 1;
  }
  const roomfix::Camera* camera = FindCamera(ctx->site, camera_id);
  if (camera == nullptr) {
    std::cerr << "camera_proc: " << process.config_path << " has no camera"
              << (camera_id >= 0 ? " with id " + std::to_string(camera_id) : "") << "\n";
    return 1;
  }
  // The node keeps a reference to its camera: this copy lives to the end.
  roomfix::Camera camera_at_rate = *camera;
  if (fps > 0.0) {
    if (fps > camera->fps) {
      std::cerr << "camera_proc: --fps " << fps << " is over camera " << camera->id << "'s "
                << camera->fps << " fps\n";
      return 1;
    }
    camera_at_rate.fps = fps;
    camera = &camera_at_rate;
  }
  if (device.empty()) device = camera->device;
  if (calibration_path.empty()) calibration_path = camera->calibration_file;
  std::optional<roomfix::calib::Calibration> calibration;
  if (!calibration_path.empty() && calibration_path != "none") {
    roomfix::calib::Calibration c;
    if (!roomfix::calib::LoadCalibration(calibration_path, &c, &error)) {
      std::cerr << "camera_proc: " << error << "\n";
      return 1;
    }
    if (c.width_px() != camera->width_px || c.height_px() != camera->height_px) {
      std::cerr << "camera_proc: " << calibration_path << " is for " << c.width_px() << "x"
                << c.height_px() << " px, the camera delivers " << camera->width_px << "x"
                << camera->height_px << "\n";
      return 1;
    }
    if (const std::string fit = roomfix::calib::CheckFitResidual(c); !fit.empty()) {
      std::cerr << "camera_proc: " << calibration_path << ": " << fit << "\n";
      return 1;
    }
    calibration = c;
  }
  // The synthetic camera must share roomfix_sim's t = 0 to show the robot
  // where the simulator says it is. Without --start-utime, take it from
  // roomfix_sim's heartbeat (its STATUS time minus its uptime), so that
  // separately started processes (bot-procman) agree too.
  if (start_utime == 0 && device.rfind("sim:", 0) == 0 && !process.check) {
    const auto sub = ctx->bus->Subscribe<roomfix::process_status_t>(
        roomfix::kStatusChannel,
        [&](const roomfix::process_status_t& s, const roomfix::MessageInfo&) {
          if (s.process == "roomfix_sim" && start_utime == 0) {
            start_utime = s.utime - s.uptime_us;
            spdlog::info("synthetic camera on roomfix_sim's clock (pid {} on {})", s.pid, s.host);
          }
        });
    const auto give_up =
        std::chrono::steady_clock::now() + std::chrono::duration<double>(sim_wait_s);
    while (start_utime == 0 && !roomfix::ShutdownRequested() &&
           std::chrono::steady_clock::now() < give_up) {
      if (ctx->bus->Handle(100) < 0) break;
    }
    ctx->bus->Unsubscribe(sub);
    if (start_utime == 0) {
      spdlog::warn(
          "no roomfix_sim heard in {} s: the synthetic camera keeps its own clock, so "
          "its robot will not match roomfix_sim's ground truth",
          sim_wait_s);
    }
  }
  if (start_utime == 0) start_utime = roomfix::NowUtime();

  // The frame source: the synthetic camera, or a device, file or folder.
  std::unique_ptr<roomfix::camera::FrameSource> source;
  if (device.rfind("sim:", 0) == 0) {
    roomfix::sim::SimScenario scenario;
    if (!roomfix::sim::ParseSimScenario(device, ctx->site, &scenario, &error)) {
      std::cerr << "camera_proc: " << error << "\n";
      return 1;
    }
    roomfix::calib::CameraModel lens = roomfix::calib::NominalCamera(
        camera->mount_position_m, camera->field_of_view_deg, camera->width_px, camera->height_px);
    if (!sim_lens_path.empty()) {
      roomfix::calib::Calibration truth;
      if (!roomfix::calib::LoadCalibration(sim_lens_path, &truth, &error) ||
          truth.model != roomfix::calib::Calibration::Model::kFull) {
        std::cerr << "camera_proc: --sim-lens: "
                  << (error.empty() ? sim_lens_path + " is not a full model" : error) << "\n";
        return 1;
      }
      lens = truth.camera;
    }
    roomfix::camera::SimSourceOptions sim_options;
    sim_options.fps = camera->fps;
    sim_options.start_utime = start_utime;
    sim_options.realtime = true;
    sim_options.jpeg_quality = sim_jpeg_quality;
    if (process.check) {
      std::cout << "camera_proc: ok: camera " << camera->id << ", synthetic " << scenario.name
                << ", " << camera->robots.size() << " robots, "
                << (calibration ? "calibrated (" + calibration_path + ")" : "pixels only")
                << ", on " << process.lcm_url << "\n";
      return 0;
    }
    source = std::make_unique<roomfix::camera::SimFrameSource>(
        std::make_shared<roomfix::sim::SyntheticCamera>(ctx->site, *camera, lens, scenario),
        sim_options);
  } else {
    roomfix::camera::CaptureSettings settings;
    settings.width_px = camera->width_px;
    settings.height_px = camera->height_px;
    settings.fps = camera->fps;
    settings.pixel_format = camera->pixel_format;
    settings.properties = camera->properties;
    settings.realtime = realtime;
    settings.start_utime = start_utime;
    settings.loop = loop_files;
    source = roomfix::camera::MakeFrameSource(device, settings, &error);
    if (source == nullptr) {
      std::cerr << "camera_proc: " << error << "\n";
      return 1;
    }
    if (process.check) {
      std::cout << "camera_proc: ok: camera " << camera->id << ", " << device << " "
                << camera->width_px << "x" << camera->height_px << " " << camera->pixel_format
                << " at " << camera->fps << " fps, " << camera->robots.size() << " robots, "
                << (calibration ? "calibrated (" + calibration_path + ")" : "pixels only")
                << ", on " << process.lcm_url << "\n";
      return 0;
    }
  }

  // A device that defines its own timing (a synthetic scenario) overrides
  // the site camera's readout, exposure and latency (CameraNodeOptions).
  options.device_timing = source->device_timing();
  if (!options.IsValid(&error)) {
    std::cerr << "camera_proc: " << error << "\n";
    return 1;
  }
  roomfix::CameraNode node(ctx->site, *camera, calibration, ctx->bus.get(), options,
                           roomfix::NowUtime());
  if (!node.ok(&error)) {
    std::cerr << "camera_proc: " << error << "\n";
    return 1;
  }
  if (!calibration) {
    spdlog::warn("no calibration for camera {}: publishing MARKER_PIXELS only", camera->id);
  }

  // Open, and for a live device keep trying with a doubling wait: a webcam
  // unplugged and plugged back in comes back on its own.
  const auto stop_at = std::chrono::steady_clock::now() + std::chrono::duration<double>(duration_s);
  auto timed_out = [&] { return duration_s > 0.0 && std::chrono::steady_clock::now() >= stop_at; };
  double backoff_s = 0.1;
  bool open = false;
  int rc = 0;
  while (!roomfix::ShutdownRequested() && !timed_out()) {
    const int64_t now = roomfix::NowUtime();
    if (!open) {
      if (source->Open(&error)) {
        open = true;
        backoff_s = 0.1;
        node.OnSourceUp(source->Describe(), source->refused_properties(), now);
        continue;
      }
      if (!source->live()) {
        std::cerr << "camera_proc: " << error << "\n";
        rc = 1;
        break;
      }
      node.OnSourceDown(error, now);
      spdlog::warn("{}; retrying in {:.1f} s", error, backoff_s);
      node.Tick(now);
      auto wait = std::chrono::duration<double>(backoff_s);
      if (duration_s > 0.0) {
        wait = std::min<std::chrono::duration<double>>(wait,
                                                       stop_at - std::chrono::steady_clock::now());
      }
      if (wait.count() > 0.0) std::this_thread::sleep_for(wait);
      backoff_s = std::min(reopen_max_s, backoff_s * 2.0);
      continue;
    }
    // Hints (other sensors' poses) waiting on the bus; never blocks, and
    // gives a flood at most a third of a 30 fps frame period.
    if (roomfix::DrainBus(ctx->bus.get(), kHintDrainBudgetUs) < 0) {
      spdlog::error("LCM failed: {}", ctx->bus->stats().last_error);
      rc = 1;
      break;
    }
    roomfix::camera::Frame frame;
    const roomfix::camera::ReadStatus status = source->Read(&frame, &error);
    const int64_t read_utime = roomfix::NowUtime();
    switch (status) {
      case roomfix::camera::ReadStatus::kFrame:
        node.OnFrame(&frame, read_utime);
        break;
      case roomfix::camera::ReadStatus::kBadFrame:
        node.OnBadFrame(BadFrameReason(error), error, read_utime);
        break;
      case roomfix::camera::ReadStatus::kEndOfStream:
        node.OnEndOfStream(read_utime);
        roomfix::RequestShutdown();
        break;
      case roomfix::camera::ReadStatus::kDeviceLost:
        spdlog::warn("{}; reopening", error);
        source->Close();
        open = false;
        node.OnSourceDown(error, read_utime);
        break;
    }
    node.Tick(read_utime);
  }
  node.Stop(roomfix::NowUtime());
  // Joins a synthetic camera's renderer before the summary.
  source->Close();
  spdlog::info("stopped: {} frames processed, {} dropped, {} skipped by the source",
               node.frames_processed(), node.status().dropped(),
               node.status().counter("source_skipped_frames"));
  return rc;
}
