// roomfix bench camera: per-frame cost of camera_proc's pipeline on 1080p
// MJPEG frames against the reference pipeline, measured on the same frames
// in the same run, and the centroid accuracy on the same synthetic frames.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <vector>

#include "camera_proc/camera_node.h"
#include "camera_proc/frame_source.h"
#include "core/analysis/track_error.h"
#include "core/vision/marker_detector.h"
#include "msgio/bus.h"
#include "msgio/install_paths.h"
#include "sim/synthetic_camera.h"
#include "tools/commands.h"

namespace roomfix {
namespace {

using json = nlohmann::ordered_json;

struct BenchCameraOptions {
  std::string site = DataFile("config/sites/demo_room.yaml");
  std::string scenario = "clean";
  int frames = 120;
  int quality = 90;
  bool json = false;
};

double NowMs() {
  return std::chrono::duration<double, std::milli>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

struct Rendered {
  std::vector<std::vector<uint8_t>> jpeg;
  std::vector<std::vector<sim::MarkerTruth>> truth;
  std::vector<int64_t> utime;
};

int RunCameraBench(const BenchCameraOptions& o) {
  Site site;
  std::string error;
  if (!LoadSite(o.site, &site, &error)) {
    std::cerr << "bench camera: " << error << "\n";
    return 1;
  }
  if (site.cameras.empty()) {
    std::cerr << "bench camera: " << o.site << " has no camera\n";
    return 1;
  }
  const Camera& cam = site.cameras.front();
  sim::SimScenario scenario;
  if (!sim::ParseSimScenario(o.scenario, &scenario, &error)) {
    std::cerr << "bench camera: " << error << "\n";
    return 1;
  }
  calib::CameraModel lens = calib::NominalCamera(cam.mount_position_m, cam.field_of_view_deg,
                                                 cam.width_px, cam.height_px);
  const sim::SyntheticCamera synth(site, cam, lens, scenario);
  constexpr int64_t kStart = 1'700'000'000'000'000;
  Rendered r;
  for (int i = 0; i < o.frames; ++i) {
    const double t_s = i / cam.fps;
    cv::Mat bgr;
    std::vector<sim::MarkerTruth> truth;
    synth.Render(t_s, i, synth.SimulatedRobots(t_s), &bgr, &truth);
    std::vector<uint8_t> bytes;
    cv::imencode(".jpg", bgr, bytes, {cv::IMWRITE_JPEG_QUALITY, o.quality});
    r.jpeg.push_back(std::move(bytes));
    r.truth.push_back(std::move(truth));
    r.utime.push_back(kStart + static_cast<int64_t>(std::llround(t_s * 1e6)));
  }
  if (!o.json) {
    std::printf("camera bench: %d frames %dx%d, JPEG quality %d (%.0f kB each), scenario %s\n",
                o.frames, cam.width_px, cam.height_px, o.quality, r.jpeg.front().size() / 1024.0,
                scenario.name.c_str());
  }

  // Decoding alone: the whole frame (what OpenCV's capture does for every
  // frame), half size by DCT scaling (the full-frame search), one window.
  std::vector<double> decode_full, decode_half, decode_window;
  for (int i = 0; i < o.frames; ++i) {
    double t0 = NowMs();
    cv::Mat full = cv::imdecode(r.jpeg[static_cast<size_t>(i)], cv::IMREAD_COLOR);
    decode_full.push_back(NowMs() - t0);
    t0 = NowMs();
    auto image = camera::MakeJpegImage(r.jpeg[static_cast<size_t>(i)], &error);
    cv::Mat half;
    if (image == nullptr || !image->DecodeReduced(2, &half, &error)) {
      std::cerr << "bench camera: " << error << "\n";
      return 1;
    }
    decode_half.push_back(NowMs() - t0);
    const sim::MarkerTruth& m = r.truth[static_cast<size_t>(i)].front();
    t0 = NowMs();
    auto image2 = camera::MakeJpegImage(r.jpeg[static_cast<size_t>(i)], &error);
    cv::Mat window;
    image2->DecodeRegion(
        cv::Rect(static_cast<int>(m.u_px) - 80, static_cast<int>(m.v_px) - 80, 160, 160), &window,
        &error);
    decode_window.push_back(NowMs() - t0);
  }

  // The reference: decode everything, HSV, inRange, blur, SimpleBlobDetector.
  std::vector<vision::ColourClass> classes;
  for (const MarkerClass& mc : cam.marker_classes) {
    vision::ColourClass c;
    c.name = mc.name;
    c.hsv_min = mc.hsv_min;
    c.hsv_max = mc.hsv_max;
    c.min_area_px = 30;
    c.max_area_px = 20000;
    classes.push_back(c);
  }
  std::vector<double> reference;
  for (int i = 0; i < o.frames; ++i) {
    const double t0 = NowMs();
    cv::Mat full = cv::imdecode(r.jpeg[static_cast<size_t>(i)], cv::IMREAD_COLOR);
    const std::vector<vision::Blob> blobs = vision::DetectReference(full, classes);
    reference.push_back(NowMs() - t0);
  }

  // camera_proc's node, whole frames in: decode what it needs, detect,
  // track, publish MARKER_PIXELS and POSE_CAMERA.
  calib::Calibration calibration;
  calibration.model = calib::Calibration::Model::kFull;
  calibration.camera = lens;
  auto run_node = [&](bool always_full, std::vector<double>* ms, std::vector<double>* err_px,
                      int* found) {
    LoopbackBus bus;
    CameraNodeOptions options;
    options.always_full_search = always_full;
    CameraNode node(site, cam, calibration, &bus, options, kStart);
    *found = 0;
    for (int i = 0; i < o.frames; ++i) {
      camera::Frame frame;
      frame.seq = i;
      frame.capture_utime = r.utime[static_cast<size_t>(i)];
      const double t0 = NowMs();
      frame.image = camera::MakeJpegImage(r.jpeg[static_cast<size_t>(i)], &error);
      node.OnFrame(&frame, frame.capture_utime);
      // The first frame of the tracking run is its full-frame search.
      if (always_full || i > 0) ms->push_back(NowMs() - t0);
      for (const vision::RobotObservation& obs : node.last_observations()) {
        if (!obs.found) continue;
        ++*found;
        for (const sim::MarkerTruth& t : r.truth[static_cast<size_t>(i)]) {
          if (t.robot_id == obs.robot_id && !t.is_heading_marker) {
            err_px->push_back(std::hypot(obs.position.u_px - t.centroid_u_px,
                                         obs.position.v_px - t.centroid_v_px));
          }
        }
      }
    }
  };
  std::vector<double> tracking, full_search, centroid_err, full_err;
  int found_tracking = 0, found_full = 0;
  run_node(false, &tracking, &centroid_err, &found_tracking);
  run_node(true, &full_search, &full_err, &found_full);

  auto median = [](std::vector<double> v) { return analysis::Percentile(v, 0.5); };
  auto rms = [](const std::vector<double>& v) {
    double s = 0;
    for (double x : v) s += x * x;
    return v.empty() ? NAN : std::sqrt(s / v.size());
  };
  const double tracking_ms = median(tracking);
  const double full_ms = median(full_search);
  const double reference_ms = median(reference);
  const double robots = static_cast<double>(cam.robots.size()) * o.frames;
  json out;
  out["frames"] = o.frames;
  out["width_px"] = cam.width_px;
  out["height_px"] = cam.height_px;
  out["jpeg_quality"] = o.quality;
  out["tracking_median_ms"] = tracking_ms;
  out["full_search_median_ms"] = full_ms;
  out["reference_median_ms"] = reference_ms;
  out["speedup_vs_reference"] = reference_ms / tracking_ms;
  out["full_search_speedup_vs_reference"] = reference_ms / full_ms;
  out["decode_median_ms"] = median(decode_full);
  out["decode_half_median_ms"] = median(decode_half);
  out["decode_window_median_ms"] = median(decode_window);
  out["tracking_p99_ms"] = analysis::Percentile(tracking, 0.99);
  out["centroid_rms_px"] = rms(centroid_err);
  out["full_search_centroid_rms_px"] = rms(full_err);
  out["detection_rate"] = found_tracking / robots;
  if (o.json) {
    std::cout << out.dump() << "\n";
    return 0;
  }
  std::printf(
      "  per frame (median)              ms    vs reference\n"
      "  reference (decode+HSV+blob)  %6.2f        1.0x\n"
      "  camera_proc tracking         %6.2f   %7.1fx   (p99 %.2f ms)\n"
      "  camera_proc full search      %6.2f   %7.1fx\n"
      "  decoding alone: full frame %.2f ms, half size %.2f ms (%.1fx less), a 160 px window "
      "%.2f ms (%.1fx less)\n"
      "  centroid error %.3f px RMS tracking, %.3f px full search; detection rate %.4f\n",
      reference_ms, tracking_ms, reference_ms / tracking_ms, out["tracking_p99_ms"].get<double>(),
      full_ms, reference_ms / full_ms, median(decode_full), median(decode_half),
      median(decode_full) / median(decode_half), median(decode_window),
      median(decode_full) / median(decode_window), rms(centroid_err), rms(full_err),
      found_tracking / robots);
  return 0;
}

}  // namespace

void AddBenchCameraCommand(CLI::App* bench, int* exit_code) {
  auto options = std::make_shared<BenchCameraOptions>();
  auto* cmd = bench->add_subcommand(
      "camera",
      "camera_proc's per-frame time on 1080p JPEG frames (tracking and full-frame search) "
      "against the reference pipeline on the same frames, decoding costs, centroid accuracy");
  cmd->add_option("--site", options->site, "Site file (its first camera)")->capture_default_str();
  cmd->add_option("--scenario", options->scenario, "Synthetic camera scenario")
      ->capture_default_str();
  cmd->add_option("--frames", options->frames, "Frames rendered and timed")->capture_default_str();
  cmd->add_option("--quality", options->quality, "JPEG quality of the frames")
      ->capture_default_str();
  cmd->add_flag("--json", options->json, "Print one JSON object instead of a table");
  cmd->callback([options, exit_code] { *exit_code = RunCameraBench(*options); });
}

}  // namespace roomfix
