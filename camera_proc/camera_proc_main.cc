// camera_proc: ceiling camera frames to marker pixels (MARKER_PIXELS) and,
// with a calibration, camera poses (POSE_CAMERA). Flags here; the camera and
// its source in camera_io/camera_source.h (the synthetic camera's in
// sim/sim_camera_source.h, linked here only), the read loop in camera_app.h
// and the node in camera_node.h.
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <iostream>

#include "camera_io/camera_source.h"
#include "camera_proc/camera_app.h"
#include "camera_proc/camera_node.h"
#include "msgio/process.h"
#include "sim/sim_camera_source.h"

namespace {

// What camera_proc's flags choose besides CameraNodeOptions.
struct RunOptions {
  roomfix::CameraSourceOptions source;
  roomfix::SimCameraOptions sim;
  roomfix::CameraLoopOptions loop;
  // t = 0 of the simulation, or the first file frame's time; 0: roomfix_sim's
  // clock (sim, see WaitForSimClock) or now.
  int64_t start_utime = 0;
};

void AddFlags(CLI::App* app, RunOptions* run, roomfix::CameraNodeOptions* node,
              std::string* lighting) {
  app->add_option("--camera", run->source.camera_id,
                  "Camera id in the site file (default: the first)");
  app->add_option("--device", run->source.device,
                  "Override the site's device: /dev/videoN, a video file, an image folder or "
                  "glob, or sim:SCENARIO (clean, lighting, distractors, harsh, webcam)");
  app->add_option("--calibration", run->source.calibration_path,
                  "Calibration YAML (default: the site camera's calibration; none: pixels only)");
  app->add_option("--lighting", *lighting,
                  "Colour classification: fixed (the site's ranges, as the reference), normalised "
                  "(against the local background brightness) or adaptive (normalised, following "
                  "each tracked marker's colour)")
      ->capture_default_str()
      ->check(CLI::IsMember({"fixed", "normalised", "adaptive"}));
  app->add_option("--full-search-scale", node->full_search_scale,
                  "Reduction of the full-frame search (1, 2, 4, 8)")
      ->capture_default_str();
  app->add_option("--absent-search-period", node->absent_search_period_frames,
                  "Robots out of view: a full-frame search once in this many frames")
      ->capture_default_str()
      ->check(CLI::Range(1, 300));
  app->add_option("--max-speed", node->max_speed_mps, "Robots' top speed, m/s (sizes windows)")
      ->capture_default_str();
  app->add_option("--detector-view-hz", node->detector_view_hz,
                  "What the detector sees (class masks, blobs, why each robot is not found) on "
                  "CAMERA_DETECTOR_VIEW this often, whole frame (0: only when a viewer asks on "
                  "CAMERA_DETECTOR_VIEW_REQUEST)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 5.0));
  app->add_option("--start-utime", run->start_utime,
                  "Simulation and file clock: t = 0 of the simulated robots (give roomfix_sim "
                  "the same), or the first file frame's time; default now");
  app->add_option("--sim-wait", run->sim.wait_s,
                  "sim: without --start-utime, wait this long for roomfix_sim's heartbeat to "
                  "share its clock")
      ->capture_default_str();
  app->add_flag("--realtime", run->source.realtime,
                "Files: play at the camera's frame rate instead of as fast as they are read");
  app->add_flag("--loop", run->source.loop_files, "Files: start again at the end");
  app->add_option("--sim-jpeg-quality", run->sim.jpeg_quality,
                  "sim: hand frames over as JPEG of this quality, as a webcam's MJPEG (0: raw)")
      ->capture_default_str()
      ->check(CLI::Range(0, 100));
  app->add_option("--sim-lens", run->sim.lens_path,
                  "sim: render through this calibration file's full model (default: the "
                  "nominal lens of the site's mount position and field of view)");
  app->add_option("--reopen-max", run->loop.reopen_max_s,
                  "Longest wait between attempts to reopen a lost camera, s")
      ->capture_default_str();
  app->add_option("--fps", run->source.fps,
                  "Frame rate to request (a device) or render (sim:), at most the site camera's "
                  "(default: the site's)")
      ->check(CLI::PositiveNumber);
  app->add_option("--duration", run->loop.duration_s,
                  "Stop after this many seconds (0: until a signal)")
      ->capture_default_str();
}

constexpr char kProcessName[] = "camera_proc";

}  // namespace

int main(int argc, char** argv) {
  roomfix::ProcessOptions process;
  RunOptions run;
  roomfix::CameraNodeOptions options;
  std::string lighting = "adaptive";
  CLI::App app{
      "camera_proc: finds the robots' coloured markers in the ceiling camera's frames and "
      "publishes MARKER_PIXELS and, with a calibration, POSE_CAMERA"};
  roomfix::AddProcessFlags(&app, &process, /*config_required=*/true);
  AddFlags(&app, &run, &options, &lighting);
  CLI11_PARSE(app, argc, argv);
  options.lighting = lighting == "fixed"        ? roomfix::vision::LightingMode::kFixed
                     : lighting == "normalised" ? roomfix::vision::LightingMode::kNormalised
                                                : roomfix::vision::LightingMode::kAdaptive;
  std::string error;
  if (!options.IsValid(&error) || !run.source.IsValid(&error) || !run.sim.IsValid(&error) ||
      !run.loop.IsValid(&error)) {
    return roomfix::PrintFailure(kProcessName, error);
  }
  auto ctx = roomfix::StartProcess("camera_proc", process, &error);
  if (ctx == nullptr) return roomfix::PrintFailure(kProcessName, error);
  roomfix::CameraChoice choice;
  if (!roomfix::ChooseCamera(ctx->site, run.source, &choice, &error))
    return roomfix::PrintFailure(kProcessName, error);
  const std::string mismatch = roomfix::SimCalibrationMismatch(ctx->site, choice, run.sim);
  if (!mismatch.empty()) spdlog::warn("{}", mismatch);
  int64_t start_utime = run.start_utime;
  if (start_utime == 0 && roomfix::IsSimDevice(choice.device) && !process.check) {
    start_utime = roomfix::WaitForSimClock(ctx->bus.get(), run.sim.wait_s);
  }
  if (start_utime == 0) start_utime = roomfix::NowUtime();
  std::unique_ptr<roomfix::camera::FrameSource> source;
  std::string summary;
  if (!roomfix::MakeCameraSource(ctx->site, choice, run.source, run.sim, start_utime, process.check,
                                 &source, &summary, &error)) {
    return roomfix::PrintFailure(kProcessName, error);
  }
  if (process.check) {
    std::cout << "camera_proc: ok: " << summary << ", on " << process.lcm_url << "\n";
    return 0;
  }
  // A device that defines its own timing (a synthetic scenario) overrides
  // the site camera's readout, exposure and latency (CameraNodeOptions).
  options.device_timing = source->device_timing();
  if (!options.IsValid(&error)) return roomfix::PrintFailure(kProcessName, error);
  roomfix::CameraNode node(ctx->site, choice.camera, choice.calibration, ctx->bus.get(), options,
                           roomfix::NowUtime());
  if (!node.ok(&error)) return roomfix::PrintFailure(kProcessName, error);
  if (!mismatch.empty()) {
    node.OnSetupProblem("calibration_not_of_sim_lens", mismatch, roomfix::NowUtime());
  }
  if (!choice.calibration) {
    spdlog::warn("no calibration for camera {}: publishing MARKER_PIXELS only", choice.camera.id);
  }
  const int rc = roomfix::RunCameraSource(source.get(), &node, ctx->bus.get(), run.loop, &error);
  if (rc != 0 && !error.empty()) roomfix::PrintFailure(kProcessName, error);
  return rc;
}
