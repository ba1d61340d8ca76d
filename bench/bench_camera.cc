// roomfix_bench camera: per-frame cost of camera_proc's pipeline on 1080p
// MJPEG frames against the reference pipeline, measured on the same frames
// in the same run, and the centroid accuracy on the same synthetic frames.
#include <fmt/format.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <iostream>
#include <limits>
#include <memory>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <random>
#include <vector>

#include "bench/commands.h"
#include "camera_io/frame_source.h"
#include "camera_proc/camera_node.h"
#include "core/analysis/fix_quality.h"
#include "core/analysis/track_error.h"
#include "core/vision/marker_detector.h"
#include "msgio/bus.h"
#include "msgio/install_paths.h"
#include "roomfix/pose2d_t.hpp"
#include "sim/synthetic_camera.h"

namespace roomfix {
namespace {

using json = nlohmann::ordered_json;

struct BenchCameraOptions {
  std::string site = DataFile("config/sites/demo_room.yaml");
  std::string scenario = "clean";
  int frames = 120;
  int quality = 90;
  bool json = false;
  // The error budget: each webcam effect alone, then all together.
  bool error_budget = false;
  // The calibration's pixel_sigma_px for the budget's coverage column: what
  // a tripod calibration through the simulated webcam states
  // (WebcamPipelineTest, docs/camera.md).
  double pixel_sigma_px = 0.1;
  // Coloured dots drawn on every frame before its JPEG (a cluttered or
  // hostile view): the node runs with its blob cap and without.
  int clutter = 0;
};

// CPU time of this thread, ms: what a frame costs a core, whatever else
// the machine runs (wall time on a shared machine counts the waits).
double ThreadCpuMs() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) * 1e3 + static_cast<double>(ts.tv_nsec) * 1e-6;
}

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

// The simulated webcam with every effect off: the `clean` camera's image
// (JPEG at 90, as clean is handed over) through the webcam renderer.
WebcamSimulation AllOff() {
  WebcamSimulation w = sim::WithoutWebcamEffects(WebcamSimulation{});
  w.srgb_gamma = false;
  w.jpeg_quality = 90;
  return w;
}

// One effect of `full` switched on in `w`.
void TurnOn(const std::string& effect, const WebcamSimulation& full, WebcamSimulation* w) {
  if (effect == "lens blur (PSF)") w->psf_sigma_px = full.psf_sigma_px;
  if (effect == "vignetting") w->vignetting_corner_gain = full.vignetting_corner_gain;
  if (effect == "exposure (motion blur)") w->exposure_s = full.exposure_s;
  if (effect == "rolling shutter") w->readout_s = full.readout_s;
  if (effect == "AE and WB drift") {
    w->auto_exposure_drift = full.auto_exposure_drift;
    w->white_balance_drift = full.white_balance_drift;
  }
  if (effect == "shot and read noise") {
    w->shot_noise = full.shot_noise;
    w->read_noise_e = full.read_noise_e;
  }
  if (effect == "sRGB gamma") w->srgb_gamma = full.srgb_gamma;
  if (effect == "Bayer mosaic") w->bayer = full.bayer;
  if (effect == "MJPEG quality") w->jpeg_quality = full.jpeg_quality;
  if (effect == "robot tilt") {
    w->tilt_static_deg = full.tilt_static_deg;
    w->tilt_per_acceleration_deg_per_mps2 = full.tilt_per_acceleration_deg_per_mps2;
    w->tilt_rocking_deg = full.tilt_rocking_deg;
  }
  if (effect == "marker wear and sheen") {
    w->marker_wear = full.marker_wear;
    w->marker_sheen = full.marker_sheen;
  }
  if (effect == "timestamp latency and jitter") {
    w->timestamp_latency_s = full.timestamp_latency_s;
    w->timestamp_jitter_s = full.timestamp_jitter_s;
  }
}

struct BudgetFigures {
  double rms_m = 0.0;
  double inside_95 = 0.0;
  int64_t dropped = 0;
};

// `frames` frames of the site's robot (trajectory as set in `site`) through
// the webcam `w`, tracked by a node that knows the camera's timing as a lab
// would state it in the site (readout, exposure, latency: what is rendered)
// and is calibrated with the lens the frames were rendered through, stating
// `pixel_sigma_px`. Each pose is judged against the robot at the pose's own
// utime.
BudgetFigures RunBudget(const Site& site, const WebcamSimulation& w, int frames,
                        double pixel_sigma_px) {
  Camera cam = site.cameras.front();
  cam.readout_s = w.readout_s;
  cam.exposure_s = w.exposure_s;
  cam.timestamp_latency_s = w.timestamp_latency_s;
  // The tilt a lab would state, per axis: the lean in an unknown direction
  // (1/sqrt 2 of it per axis), the rocking's RMS per axis at the circle's
  // 18 cm/s (0.44 of its amplitude), the circle's 0.08 m/s^2 (half per axis).
  const double tilt_deg =
      std::sqrt(std::pow(w.tilt_static_deg, 2) / 2.0 + std::pow(0.44 * w.tilt_rocking_deg, 2) +
                std::pow(w.tilt_per_acceleration_deg_per_mps2 * 0.08, 2) / 2.0);
  for (CameraRobot& r : cam.robots) r.tilt_sigma_deg = tilt_deg;
  sim::SimScenario scenario;
  std::string error;
  sim::ParseSimScenario("webcam", site, &scenario, &error);
  scenario.webcam = w;
  const calib::CameraModel lens = calib::NominalCamera(cam.mount_position_m, cam.field_of_view_deg,
                                                       cam.width_px, cam.height_px);
  const sim::SyntheticCamera synth(site, cam, lens, scenario);
  calib::Calibration calibration;
  calibration.model = calib::Calibration::Model::kFull;
  calibration.camera = synth.model();
  calibration.pixel_sigma_px = pixel_sigma_px;
  constexpr int64_t kStart = 1'700'000'000'000'000;
  LoopbackBus bus;
  std::vector<pose2d_t> poses;
  bus.Subscribe<pose2d_t>(kCameraPoseChannel,
                          [&](const pose2d_t& p, const MessageInfo&) { poses.push_back(p); });
  CameraNode node(site, cam, calibration, &bus, CameraNodeOptions{}, kStart);
  double sum2 = 0.0;
  int n = 0, inside = 0;
  for (int i = 0; i < frames; ++i) {
    const double t_s = i / cam.fps;
    cv::Mat bgr;
    synth.Render(t_s, i, synth.SimulatedRobots(t_s), &bgr);
    std::vector<uint8_t> bytes;
    camera::Frame frame;
    frame.seq = i;
    frame.capture_utime =
        kStart + static_cast<int64_t>(std::llround((t_s + synth.TimestampDelayS(i)) * 1e6));
    if (synth.Encode(bgr, 90, &bytes) && !bytes.empty()) {
      frame.image = camera::MakeJpegImage(std::move(bytes), &error);
    } else {
      frame.image = camera::MakeDecodedImage(bgr);
    }
    poses.clear();
    node.OnFrame(&frame, frame.capture_utime);
    for (const pose2d_t& p : poses) {
      if (p.status == pose2d_t::STATUS_LOST) continue;
      const sim::RobotState truth = synth.SimulatedRobots((p.utime - kStart) * 1e-6).front();
      const double dx = p.x_m - truth.x_m, dy = p.y_m - truth.y_m;
      sum2 += dx * dx + dy * dy;
      const double d2 = analysis::SquaredMahalanobis2D(
          dx, dy, p.covariance[0][0], 0.5 * (p.covariance[0][1] + p.covariance[1][0]),
          p.covariance[1][1]);
      inside += d2 <= analysis::Chi2Quantile2Dof(0.95) ? 1 : 0;
      ++n;
    }
  }
  BudgetFigures f;
  f.rms_m = n > 0 ? std::sqrt(sum2 / n) : NAN;
  f.inside_95 = n > 0 ? static_cast<double>(inside) / n : NAN;
  f.dropped = node.status().dropped();
  return f;
}

// Each effect alone, then all: a static robot (centre and a far corner,
// `frames` / 4 frames each) and the reference circle (`frames` frames).
int RunErrorBudget(const BenchCameraOptions& o) {
  Site site;
  std::string error;
  if (!LoadSite(o.site, &site, &error) || site.cameras.empty() || site.simulation.robots.empty()) {
    std::cerr << "roomfix_bench camera: "
              << (error.empty() ? o.site + ": no camera or robot" : error) << "\n";
    return 1;
  }
  const WebcamSimulation full = site.simulation.webcam;
  const std::shared_ptr<const Trajectory> circle = site.simulation.robots.front().trajectory;
  const std::vector<std::string> effects = {"none (ideal)",
                                            "lens blur (PSF)",
                                            "vignetting",
                                            "exposure (motion blur)",
                                            "rolling shutter",
                                            "AE and WB drift",
                                            "shot and read noise",
                                            "sRGB gamma",
                                            "Bayer mosaic",
                                            "MJPEG quality",
                                            "robot tilt",
                                            "marker wear and sheen",
                                            "timestamp latency and jitter",
                                            "all"};
  json rows = json::array();
  if (!o.json) {
    fmt::print(
        "error budget: simulated webcam ({}), calibration = the rendered lens with pixel sigma "
        "{:.3f} px; static: centre and corner, {} frames each; circle: {} frames\n"
        "  {:<30} {:>12} {:>10} {:>12} {:>10} {:>8}\n",
        o.site.c_str(), o.pixel_sigma_px, std::max(1, o.frames / 4), o.frames, "effect",
        "static mm", "inside95", "circle mm", "inside95", "dropped");
  }
  for (const std::string& effect : effects) {
    WebcamSimulation w = AllOff();
    if (effect == "all") {
      w = full;
    } else {
      TurnOn(effect, full, &w);
    }
    // Static: centre and a far corner, half each.
    double static2 = 0.0, static_in = 0.0;
    int64_t dropped = 0;
    for (const auto& [x, y] : std::vector<std::pair<double, double>>{{2.0, 1.5}, {0.7, 0.6}}) {
      StaticTrajectoryOptions so;
      so.x_m = x;
      so.y_m = y;
      so.heading_rad = 1.0;
      site.simulation.robots.front().trajectory = MakeStaticTrajectory(so, &error);
      const BudgetFigures f = RunBudget(site, w, std::max(1, o.frames / 4), o.pixel_sigma_px);
      static2 += 0.5 * f.rms_m * f.rms_m;
      static_in += 0.5 * f.inside_95;
      dropped += f.dropped;
    }
    site.simulation.robots.front().trajectory = circle;
    const BudgetFigures c = RunBudget(site, w, o.frames, o.pixel_sigma_px);
    dropped += c.dropped;
    json row;
    row["effect"] = effect;
    row["static_rms_mm"] = std::sqrt(static2) * 1e3;
    row["static_inside_95"] = static_in;
    row["circle_rms_mm"] = c.rms_m * 1e3;
    row["circle_inside_95"] = c.inside_95;
    row["dropped"] = dropped;
    rows.push_back(row);
    if (!o.json) {
      fmt::print("  {:<30} {:12.2f} {:9.1f}% {:12.2f} {:9.1f}% {:8}\n", effect.c_str(),
                 std::sqrt(static2) * 1e3, static_in * 100.0, c.rms_m * 1e3, c.inside_95 * 100.0,
                 static_cast<long long>(dropped));
      std::fflush(stdout);
    }
  }
  if (o.json) std::cout << rows.dump() << "\n";
  return 0;
}

// Dots of the site's classes' colours (the middle of each HSV range), 3 to
// 5 px in radius, drawn on frame `index`: each passes the area filter as a
// blob.
void DrawClutter(const Camera& cam, int index, int dots, cv::Mat* bgr) {
  std::mt19937 rng(static_cast<uint32_t>(index));
  std::vector<cv::Scalar> colours;
  for (const MarkerClass& mc : cam.marker_classes) {
    const int h = mc.hsv_min[0] <= mc.hsv_max[0]
                      ? (mc.hsv_min[0] + mc.hsv_max[0]) / 2
                      : ((mc.hsv_min[0] + mc.hsv_max[0] + 180) / 2) % 180;
    cv::Mat3b hsv(1, 1, cv::Vec3b(static_cast<uchar>(h), 200, 200)), bgr_px;
    cv::cvtColor(hsv, bgr_px, cv::COLOR_HSV2BGR);
    const cv::Vec3b c = bgr_px(0, 0);
    colours.emplace_back(c[0], c[1], c[2]);
  }
  for (int k = 0; k < dots && !colours.empty(); ++k) {
    const cv::Point centre(static_cast<int>(rng() % static_cast<uint32_t>(cam.width_px)),
                           static_cast<int>(rng() % static_cast<uint32_t>(cam.height_px)));
    cv::circle(*bgr, centre, 3 + static_cast<int>(rng() % 3), colours[k % colours.size()],
               cv::FILLED, cv::LINE_AA);
  }
}

constexpr int64_t kBenchStartUtime = 1'700'000'000'000'000;

// Renders o.frames frames of `synth` as the camera encodes them, with
// o.clutter dots on each; false (said on stderr) when one cannot be encoded.
bool RenderFrames(const Camera& cam, const sim::SyntheticCamera& synth, const BenchCameraOptions& o,
                  Rendered* r) {
  for (int i = 0; i < o.frames; ++i) {
    const double t_s = i / cam.fps;
    cv::Mat bgr;
    std::vector<sim::MarkerTruth> truth;
    synth.Render(t_s, i, synth.SimulatedRobots(t_s), &bgr, &truth);
    if (o.clutter > 0) DrawClutter(cam, i, o.clutter, &bgr);
    // The camera's own encoding (the webcam's MJPEG quality overrides
    // --quality) and its timestamp (readout, latency, jitter: 0 otherwise).
    std::vector<uint8_t> bytes;
    if (!synth.Encode(bgr, o.quality, &bytes) || bytes.empty()) {
      std::cerr << "roomfix_bench camera: cannot encode a frame as JPEG\n";
      return false;
    }
    r->jpeg.push_back(std::move(bytes));
    r->truth.push_back(std::move(truth));
    r->utime.push_back(kBenchStartUtime +
                       static_cast<int64_t>(std::llround((t_s + synth.TimestampDelayS(i)) * 1e6)));
  }
  return true;
}

// Wall time per frame, ms, of each way of decoding.
struct DecodeTimes {
  std::vector<double> full, half, window;
};

// Decoding alone: the whole frame (what OpenCV's capture does for every
// frame), half size by DCT scaling (the full-frame search), one window.
bool TimeDecoding(const Rendered& r, DecodeTimes* d, std::string* error) {
  for (size_t i = 0; i < r.jpeg.size(); ++i) {
    double t0 = NowMs();
    cv::Mat full = cv::imdecode(r.jpeg[i], cv::IMREAD_COLOR);
    d->full.push_back(NowMs() - t0);
    t0 = NowMs();
    auto image = camera::MakeJpegImage(r.jpeg[i], error);
    cv::Mat half;
    if (image == nullptr || !image->DecodeReduced(2, &half, error)) return false;
    d->half.push_back(NowMs() - t0);
    const sim::MarkerTruth& m = r.truth[i].front();
    t0 = NowMs();
    auto image2 = camera::MakeJpegImage(r.jpeg[i], error);
    cv::Mat window;
    image2->DecodeRegion(
        cv::Rect(static_cast<int>(m.u_px) - 80, static_cast<int>(m.v_px) - 80, 160, 160), &window,
        error);
    d->window.push_back(NowMs() - t0);
  }
  return true;
}

// The reference, ms per frame: decode everything, HSV, inRange, blur,
// SimpleBlobDetector.
std::vector<double> TimeReference(const Camera& cam, const Rendered& r) {
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
  for (const std::vector<uint8_t>& jpeg : r.jpeg) {
    const double t0 = NowMs();
    cv::Mat full = cv::imdecode(jpeg, cv::IMREAD_COLOR);
    const std::vector<vision::Blob> blobs = vision::DetectReference(full, classes);
    reference.push_back(NowMs() - t0);
  }
  return reference;
}

// One run of camera_proc's node over the frames.
struct NodeRun {
  // Per frame: wall time (`ms`) and this thread's CPU time (`cpu_ms`, what
  // sizes a core).
  std::vector<double> ms, cpu_ms;
  // Each found robot's centroid error against the rendered truth, px.
  std::vector<double> err_px;
  int found = 0;
  int64_t too_many_blobs = 0;
};

// camera_proc's node, whole frames in: decode what it needs, detect, track,
// publish MARKER_PIXELS and POSE_CAMERA.
NodeRun RunNode(const Site& site, const Camera& cam, const calib::Calibration& calibration,
                const Rendered& r, bool always_full, int absent_period, int max_blobs) {
  NodeRun run;
  LoopbackBus bus;
  CameraNodeOptions options;
  options.always_full_search = always_full;
  options.absent_search_period_frames = absent_period;
  options.max_blobs_per_frame = max_blobs;
  CameraNode node(site, cam, calibration, &bus, options, kBenchStartUtime);
  std::string error;
  for (size_t i = 0; i < r.jpeg.size(); ++i) {
    camera::Frame frame;
    frame.seq = static_cast<int64_t>(i);
    frame.capture_utime = r.utime[i];
    const double t0 = NowMs(), c0 = ThreadCpuMs();
    frame.image = camera::MakeJpegImage(r.jpeg[i], &error);
    node.OnFrame(&frame, frame.capture_utime);
    // The first frame of the tracking run is its full-frame search.
    if (always_full || i > 0) {
      run.ms.push_back(NowMs() - t0);
      run.cpu_ms.push_back(ThreadCpuMs() - c0);
    }
    for (const vision::RobotObservation& obs : node.last_observations()) {
      if (!obs.found) continue;
      ++run.found;
      for (const sim::MarkerTruth& t : r.truth[i]) {
        if (t.robot_id == obs.robot_id && !t.is_heading_marker) {
          run.err_px.push_back(
              std::hypot(obs.position.u_px - t.centroid_u_px, obs.position.v_px - t.centroid_v_px));
        }
      }
    }
  }
  run.too_many_blobs = node.status().counter("too_many_blobs");
  return run;
}

// What the camera bench measured on its frames.
struct CameraTimings {
  DecodeTimes decode;
  std::vector<double> reference;
  // Tracking as camera_proc runs (robots out of view searched for every
  // absent_search_period_frames), as it ran before that option (a full-frame
  // search in every frame while any robot is out of view), and a full-frame
  // search in every frame; with clutter, also without the blob cap.
  NodeRun tracking, every_frame, full_search, uncapped;
  int period = 0;
  int cap = 0;
  // Frames of the first second, left out of the means: the adaptive
  // lighting's look-up tables are rebuilt while each class's colour
  // statistics settle (a few ms each, docs/camera.md), a start-up cost, not
  // the rate a core must carry.
  size_t settle = 0;
};

// Mean of `v` after its first `settle` values (all of them when `v` holds
// no more than twice that).
double MeanAfter(size_t settle, const std::vector<double>& v) {
  double s = 0;
  size_t n = 0;
  for (size_t k = v.size() > 2 * settle ? settle : 0; k < v.size(); ++k, ++n) s += v[k];
  return n == 0 ? NAN : s / n;
}

double Median(std::vector<double> v) { return analysis::Percentile(v, 0.5); }

double Rms(const std::vector<double>& v) {
  double s = 0;
  for (double x : v) s += x * x;
  return v.empty() ? NAN : std::sqrt(s / v.size());
}

// The figures as one JSON object (--json), in the order the bench prints.
json CameraFigures(const BenchCameraOptions& o, const Camera& cam,
                   const sim::SyntheticCamera& synth, const std::string& scenario,
                   const CameraTimings& t) {
  auto mean = [&t](const std::vector<double>& v) { return MeanAfter(t.settle, v); };
  const double tracking_ms = Median(t.tracking.ms);
  const double full_ms = Median(t.full_search.ms);
  const double reference_ms = Median(t.reference);
  const double robots = static_cast<double>(cam.robots.size()) * o.frames;
  json out;
  out["frames"] = o.frames;
  out["width_px"] = cam.width_px;
  out["height_px"] = cam.height_px;
  out["jpeg_quality"] = synth.JpegQuality(o.quality);
  out["scenario"] = scenario;
  out["tracking_median_ms"] = tracking_ms;
  // The mean is what sizes a core: with robots out of view one frame in
  // absent_search_period_frames carries a full-frame search.
  out["tracking_mean_ms"] = mean(t.tracking.ms);
  out["absent_search_period_frames"] = t.period;
  out["tracking_every_frame_median_ms"] = Median(t.every_frame.ms);
  out["tracking_every_frame_mean_ms"] = mean(t.every_frame.ms);
  // CPU time per frame (this thread): the figures that size a core.
  out["tracking_cpu_mean_ms"] = mean(t.tracking.cpu_ms);
  out["tracking_every_frame_cpu_mean_ms"] = mean(t.every_frame.cpu_ms);
  out["full_search_cpu_median_ms"] = Median(t.full_search.cpu_ms);
  out["clutter_dots"] = o.clutter;
  out["too_many_blobs"] = t.tracking.too_many_blobs;
  if (!t.uncapped.ms.empty()) out["uncapped_cpu_mean_ms"] = mean(t.uncapped.cpu_ms);
  out["full_search_median_ms"] = full_ms;
  out["reference_median_ms"] = reference_ms;
  out["speedup_vs_reference"] = reference_ms / tracking_ms;
  out["full_search_speedup_vs_reference"] = reference_ms / full_ms;
  out["decode_median_ms"] = Median(t.decode.full);
  out["decode_half_median_ms"] = Median(t.decode.half);
  out["decode_window_median_ms"] = Median(t.decode.window);
  out["tracking_p99_ms"] = analysis::Percentile(t.tracking.ms, 0.99);
  out["centroid_rms_px"] = Rms(t.tracking.err_px);
  out["full_search_centroid_rms_px"] = Rms(t.full_search.err_px);
  out["detection_rate"] = t.tracking.found / robots;
  return out;
}

// The figures as the bench's table.
void PrintCameraTable(const BenchCameraOptions& o, const Camera& cam, const CameraTimings& t,
                      double tracking_p99_ms) {
  auto mean = [&t](const std::vector<double>& v) { return MeanAfter(t.settle, v); };
  const double tracking_ms = Median(t.tracking.ms);
  const double full_ms = Median(t.full_search.ms);
  const double reference_ms = Median(t.reference);
  const double robots = static_cast<double>(cam.robots.size()) * o.frames;
  const DecodeTimes& d = t.decode;
  fmt::print(
      "  per frame (median)              ms    vs reference\n"
      "  reference (decode+HSV+blob)  {:6.2f}        1.0x\n"
      "  camera_proc tracking         {:6.2f}   {:7.1f}x   (p99 {:.2f} ms)\n"
      "  camera_proc full search      {:6.2f}   {:7.1f}x\n"
      "  decoding alone: full frame {:.2f} ms, half size {:.2f} ms ({:.1f}x less), a 160 px window "
      "{:.2f} ms ({:.1f}x less)\n"
      "  centroid error {:.3f} px RMS tracking, {:.3f} px full search; detection rate {:.4f}\n",
      reference_ms, tracking_ms, reference_ms / tracking_ms, tracking_p99_ms, full_ms,
      reference_ms / full_ms, Median(d.full), Median(d.half), Median(d.full) / Median(d.half),
      Median(d.window), Median(d.full) / Median(d.window), Rms(t.tracking.err_px),
      Rms(t.full_search.err_px), t.tracking.found / robots);
  const std::vector<double>& tracking_cpu = t.tracking.cpu_ms;
  const std::vector<double>& every_frame_cpu = t.every_frame.cpu_ms;
  fmt::print(
      "  CPU per frame (mean after the first second): robots out of view searched in full every "
      "{} frames {:.2f} ms; every frame (before) {:.2f} ms ({:.1f}x); full search every frame "
      "(median) {:.2f} ms\n",
      t.period, mean(tracking_cpu), mean(every_frame_cpu),
      mean(every_frame_cpu) / mean(tracking_cpu), Median(t.full_search.cpu_ms));
  if (o.clutter > 0) {
    fmt::print(
        "  {} coloured dots per frame, CPU per frame (mean): {:.2f} ms with the blob cap ({}; "
        "{} robot-frames too_many_blobs), {:.2f} ms without ({:.1f}x)\n",
        o.clutter, mean(tracking_cpu), t.cap, static_cast<long long>(t.tracking.too_many_blobs),
        mean(t.uncapped.cpu_ms), mean(t.uncapped.cpu_ms) / mean(tracking_cpu));
  }
}

int RunCameraBench(const BenchCameraOptions& o) {
  Site site;
  std::string error;
  if (!LoadSite(o.site, &site, &error)) {
    std::cerr << "roomfix_bench camera: " << error << "\n";
    return 1;
  }
  if (site.cameras.empty()) {
    std::cerr << "roomfix_bench camera: " << o.site << " has no camera\n";
    return 1;
  }
  const Camera& cam = site.cameras.front();
  sim::SimScenario scenario;
  // "webcam" renders with the site's simulation.webcam parameters.
  if (!sim::ParseSimScenario(o.scenario, site, &scenario, &error)) {
    std::cerr << "roomfix_bench camera: " << error << "\n";
    return 1;
  }
  calib::CameraModel lens = calib::NominalCamera(cam.mount_position_m, cam.field_of_view_deg,
                                                 cam.width_px, cam.height_px);
  const sim::SyntheticCamera synth(site, cam, lens, scenario);
  Rendered r;
  if (!RenderFrames(cam, synth, o, &r)) return 1;
  if (!o.json) {
    fmt::print("camera bench: {} frames {}x{}, JPEG quality {} ({:.0f} kB each), scenario {}\n",
               o.frames, cam.width_px, cam.height_px, synth.JpegQuality(o.quality),
               r.jpeg.front().size() / 1024.0, scenario.name.c_str());
  }
  CameraTimings t;
  if (!TimeDecoding(r, &t.decode, &error)) {
    std::cerr << "roomfix_bench camera: " << error << "\n";
    return 1;
  }
  t.reference = TimeReference(cam, r);
  calib::Calibration calibration;
  calibration.model = calib::Calibration::Model::kFull;
  // The lens the frames were rendered through (the webcam's includes its
  // own distortion): the centroid error is the detector's alone.
  calibration.camera = synth.model();
  t.period = CameraNodeOptions{}.absent_search_period_frames;
  t.cap = CameraNodeOptions{}.max_blobs_per_frame;
  t.tracking = RunNode(site, cam, calibration, r, false, t.period, t.cap);
  t.every_frame = RunNode(site, cam, calibration, r, false, 1, t.cap);
  t.full_search = RunNode(site, cam, calibration, r, true, t.period, t.cap);
  if (o.clutter > 0) {
    t.uncapped =
        RunNode(site, cam, calibration, r, false, t.period, std::numeric_limits<int>::max());
  }
  t.settle = static_cast<size_t>(std::lround(cam.fps));
  const json out = CameraFigures(o, cam, synth, scenario.name, t);
  if (o.json) {
    std::cout << out.dump() << "\n";
    return 0;
  }
  PrintCameraTable(o, cam, t, out["tracking_p99_ms"].get<double>());
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
  cmd->add_option("--clutter", options->clutter,
                  "Coloured dots drawn on every frame (a cluttered or hostile view)")
      ->check(CLI::Range(0, 100000));
  cmd->add_flag("--error-budget", options->error_budget,
                "Accuracy instead of time: the simulated webcam with each effect alone, then all "
                "(static robot and reference circle: RMS error and coverage of the 95 % ellipse)");
  cmd->add_option("--pixel-sigma-px", options->pixel_sigma_px,
                  "--error-budget: the calibration's pixel_sigma_px for the covariance")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  cmd->callback([options, exit_code] {
    *exit_code = options->error_budget ? RunErrorBudget(*options) : RunCameraBench(*options);
  });
}

}  // namespace roomfix
