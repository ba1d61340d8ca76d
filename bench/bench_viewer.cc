// roomfix_bench viewer: how long the viewer takes to draw one frame of a busy
// installation (10 robots seen by 4 sources with 10 s trails, 12 receivers,
// a range set per beacon, 6 processes, a camera preview) at 1280 x 800, and
// whether that leaves 30 fps.
#include <fmt/format.h>

#include <CLI/CLI.hpp>
#include <chrono>
#include <cmath>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <random>
#include <string>
#include <vector>

#include "bench/commands.h"
#include "camera_io/image_file.h"
#include "core/analysis/track_error.h"
#include "viewer/render.h"

namespace roomfix {
namespace {

using json = nlohmann::ordered_json;
using Source = PoseSource;

struct BenchViewerOptions {
  int frames = 300;
  bool json = false;
  std::string png;
};

constexpr int kRobots = 10;
constexpr double kFrameBudgetMs = 1000.0 / 30.0;
// Message rates of the sources (Hz): camera_proc, trilat_proc, the fusion,
// the simulator's ground truth.
constexpr double kSourceRateHz[viewer::kNumSources] = {30.0, 10.0, 40.0, 30.0};
// Position noise (m) each source shows, so the trails look like real ones.
constexpr double kSourceNoiseM[viewer::kNumSources] = {0.02, 0.05, 0.01, 0.0};

// An 8 x 6 m room with 12 receivers around the walls, 2.5 m up, a beacon on
// each of 10 robots and a ceiling camera in the middle.
Site MakeSite() {
  Site site;
  site.name = "bench_hall";
  site.room.size_x_m = 8.0;
  site.room.size_y_m = 6.0;
  site.room.height_m = 3.0;
  site.room.grid_m = 0.5;
  const double wall[12][2] = {{0, 0}, {8.0 / 3, 0},  {16.0 / 3, 0}, {8, 0}, {8, 2}, {8, 4},
                              {8, 6}, {16.0 / 3, 6}, {8.0 / 3, 6},  {0, 6}, {0, 4}, {0, 2}};
  for (int i = 0; i < 12; ++i) {
    Receiver r;
    r.id = i + 1;
    r.address = 0x0013A20041000000ull + static_cast<uint64_t>(i + 1);
    r.position_m = {wall[i][0], wall[i][1], 2.5};
    site.receivers.push_back(r);
  }
  for (int i = 0; i < kRobots; ++i) {
    Beacon b;
    b.id = i + 1;
    b.address = 0x0013A20042000000ull + static_cast<uint64_t>(i + 1);
    b.height_m = 1.0 + 0.05 * i;
    site.beacons.push_back(b);
    Robot robot;
    robot.id = i + 1;
    robot.name = "robot" + std::to_string(i + 1);
    robot.beacon_id = b.id;
    site.robots.push_back(robot);
  }
  Camera camera;
  camera.id = 0;
  camera.mount_position_m = {4.0, 3.0, 3.0};
  camera.field_of_view_deg = 120.0;
  site.cameras.push_back(camera);
  return site;
}

// Robot k drives a circle of its own; t in seconds.
void RobotPose(int k, double t_s, double* x_m, double* y_m, double* heading_rad) {
  const double cx = 1.2 + (k % 5) * 1.4;
  const double cy = 1.6 + (k / 5) * 2.8;
  const double r = 0.45 + 0.05 * (k % 3);
  const double w = (k % 2 == 0 ? 1 : -1) * (0.4 + 0.05 * k);
  const double a = w * t_s + k;
  *x_m = cx + r * std::cos(a);
  *y_m = cy + r * std::sin(a);
  *heading_rad = a + (w > 0 ? M_PI / 2 : -M_PI / 2);
}

std::vector<uint8_t> MakePreview(int variant) {
  cv::Mat picture(360, 640, CV_8UC3, cv::Scalar(70, 80, 90));
  cv::rectangle(picture, {40, 30}, {600, 330}, cv::Scalar(150, 160, 165), cv::FILLED);
  for (int k = 0; k < 4; ++k) {
    cv::circle(picture, {120 + 120 * k + 6 * variant, 120 + 40 * (k % 2)}, 14,
               cv::Scalar(0, 140, 255), cv::FILLED);
  }
  std::vector<uint8_t> jpeg;
  cv::imencode(".jpg", picture, jpeg, {cv::IMWRITE_JPEG_QUALITY, 80});
  return jpeg;
}

// The state at time t_s: what the viewer node would hold then.
void MakeState(const Site& site, double t_s, const std::vector<std::vector<uint8_t>>& previews,
               viewer::ViewState* state) {
  std::mt19937 rng(static_cast<unsigned>(t_s * 1000));
  std::normal_distribution<double> noise(0.0, 1.0);
  const auto now_utime = static_cast<int64_t>(1'714'564'800e6 + t_s * 1e6);
  state->site = site;
  state->now_utime = now_utime;
  state->tracks.clear();
  state->range_sets.clear();
  for (int k = 0; k < kRobots; ++k) {
    for (int s = 0; s < viewer::kNumSources; ++s) {
      viewer::TrackView t;
      t.source = viewer::kSources[s];
      t.robot_id = k + 1;
      const double period_s = 1.0 / kSourceRateHz[s];
      const auto samples = static_cast<int>(state->trail_s * kSourceRateHz[s]);
      for (int i = samples; i >= 0; --i) {
        const double ts = std::floor(t_s / period_s) * period_s - i * period_s;
        double x = 0, y = 0, h = 0;
        RobotPose(k, ts, &x, &y, &h);
        t.trail.push_back({static_cast<int64_t>(1'714'564'800e6 + ts * 1e6),
                           x + kSourceNoiseM[s] * noise(rng), y + kSourceNoiseM[s] * noise(rng)});
      }
      t.x_m = t.trail.back().x_m;
      t.y_m = t.trail.back().y_m;
      double x = 0, y = 0, h = 0;
      RobotPose(k, t_s, &x, &y, &h);
      if (t.source != Source::kUltrasound) t.heading_rad = h;
      if (t.source == Source::kUltrasound || t.source == Source::kFused) {
        const double sigma = t.source == Source::kFused ? 0.03 : 0.06;
        t.cov_xx_m2 = sigma * sigma * 1.5;
        t.cov_yy_m2 = sigma * sigma;
        t.cov_xy_m2 = sigma * sigma * 0.4;
      }
      t.utime = t.trail.back().utime;
      t.recv_utime = t.utime + 15'000;
      t.rate_hz = kSourceRateHz[s];
      t.latency_ms = s == 0 ? 38 : s == 1 ? 22 : 9;
      // Robot 10's camera view is blocked (stale); robot 9 is lost by the
      // camera: the marks are part of the picture.
      if (k == 9 && t.source == Source::kCamera) t.recv_utime = now_utime - 4'000'000;
      if (k == 8 && t.source == Source::kCamera) t.lost = true;
      state->tracks.push_back(std::move(t));
    }
    viewer::RangeSetView set;
    set.beacon_id = k + 1;
    set.beacon_height_m = site.beacons[static_cast<size_t>(k)].height_m;
    set.utime = now_utime - 60'000;
    set.recv_utime = now_utime - 40'000;
    double x = 0, y = 0, h = 0;
    RobotPose(k, t_s, &x, &y, &h);
    for (const Receiver& r : site.receivers) {
      viewer::RangeView range;
      range.receiver_id = r.id;
      range.receiver_m = r.position_m;
      range.range_m =
          std::sqrt(std::pow(r.position_m[0] - x, 2) + std::pow(r.position_m[1] - y, 2) +
                    std::pow(r.position_m[2] - set.beacon_height_m, 2)) +
          0.01 * noise(rng);
      // One echo in 12 is a reflection: long, and rejected by the solver.
      if ((r.id + k) % 12 == 0) {
        range.range_m += 0.7;
        range.rejected = true;
      }
      set.ranges.push_back(range);
    }
    state->range_sets.push_back(std::move(set));
  }
  state->processes.clear();
  auto process = [&](const char* name, const char* host, int process_state, double rate_hz,
                     int64_t dropped) {
    viewer::ProcessView p;
    p.name = name;
    p.host = host;
    p.pid = 1000 + static_cast<int>(state->processes.size());
    p.state = process_state;
    p.output_rate_hz = rate_hz;
    p.outputs = static_cast<int64_t>(rate_hz * t_s);
    p.dropped = dropped;
    p.recv_utime = now_utime - 300'000;
    state->processes.push_back(p);
    return &state->processes.back();
  };
  process("camera_proc", "ceiling-pi", 1, 300.0, 0);
  process("zigbee_bridge", "base", 2, 100.0, 12)->last_error = "serial: 3 frames with bad checksum";
  process("trilat_proc", "base", 1, 100.0, 0)->rejected = {
      {"outlier_range", 84}, {"too_few_ranges", 11}, {"stale_set", 2}};
  process("fusion_proc", "base", 1, 400.0, 0);
  process("roomfix_logger", "base", 1, 0.0, 0);
  process("sim_world", "laptop", 4, 0.0, 0)->recv_utime = now_utime - 9'000'000;
  state->has_preview = true;
  state->preview.camera_id = 0;
  state->preview.utime = now_utime - 400'000;
  // The preview changes once a second, as camera_proc sends it.
  state->preview.encoded = previews[static_cast<size_t>(t_s) % previews.size()];
  state->preview.markers.clear();
  for (int k = 0; k < 4; ++k) {
    state->preview.markers.push_back(
        {120.0 + 120 * k + 6 * (static_cast<int>(t_s) % 2), 120.0 + 40 * (k % 2), 14, "orange"});
  }
}

int RunViewerBench(const BenchViewerOptions& options) {
  if (options.frames < 1) {
    std::cerr << "roomfix_bench viewer: --frames must be at least 1\n";
    return 1;
  }
  const Site site = MakeSite();
  const std::vector<std::vector<uint8_t>> previews = {MakePreview(0), MakePreview(1)};
  viewer::RenderOptions render_options;  // 1280 x 800, 380 px panel
  std::string error;
  if (!render_options.IsValid(&error)) {
    std::cerr << "roomfix_bench viewer: " << error << "\n";
    return 1;
  }
  viewer::ViewState state;
  cv::Mat image;
  using Clock = std::chrono::steady_clock;
  auto ms_since = [](Clock::time_point t0) {
    return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
  };
  // The first frame draws the static background (as every frame of a zoom
  // or pan drag does); it is timed on its own.
  MakeState(site, 20.0, previews, &state);
  auto t0 = Clock::now();
  viewer::Render(state, render_options, &image);
  const double first_ms = ms_since(t0);

  std::vector<double> frame_ms;
  frame_ms.reserve(static_cast<size_t>(options.frames));
  for (int f = 0; f < options.frames; ++f) {
    // The state changes every frame (the robots move); building it is the
    // viewer node's work, not timed.
    MakeState(site, 20.0 + f / 30.0, previews, &state);
    t0 = Clock::now();
    viewer::Render(state, render_options, &image);
    frame_ms.push_back(ms_since(t0));
  }
  std::string png_error;
  if (!options.png.empty() && !camera::WriteImageChecked(options.png, image, &png_error)) {
    std::cerr << "roomfix_bench viewer: " << png_error << "\n";
    return 1;
  }
  const double median = analysis::Percentile(frame_ms, 0.5);
  const double p99 = analysis::Percentile(frame_ms, 0.99);
  const double max = analysis::Percentile(frame_ms, 1.0);
  // Met when 99 frames in 100 fit the 33.3 ms budget, not just the typical one.
  const bool meets = p99 <= kFrameBudgetMs;
  if (options.json) {
    json out;
    out["frame_ms_median"] = median;
    out["frame_ms_p99"] = p99;
    out["frame_ms_max"] = max;
    out["fps_median"] = median > 0 ? 1000.0 / median : 0.0;
    out["meets_30_fps"] = meets;
    std::cout << out.dump() << "\n";
    return 0;
  }
  fmt::print(
      "Viewer frame at {} x {}: {} robots x 4 sources (10 s trails), {} receivers, {} range "
      "sets, {} processes, a preview; {} frames\n"
      "  frame time: median {:.2f} ms, p99 {:.2f} ms, max {:.2f} ms ({:.0f} fps at the median)\n"
      "  30 fps ({:.1f} ms a frame, at p99): {}\n"
      "  first frame, drawing the static background (as each frame of a zoom or pan): {:.2f} ms\n",
      render_options.width_px, render_options.height_px, kRobots, site.receivers.size(), kRobots,
      state.processes.size(), options.frames, median, p99, max, median > 0 ? 1000.0 / median : 0.0,
      kFrameBudgetMs, meets ? "met" : "NOT met", first_ms);
  if (!options.png.empty()) fmt::print("  last frame written to {}\n", options.png.c_str());
  return 0;
}

}  // namespace

void AddBenchViewerCommand(CLI::App* bench, int* exit_code) {
  auto options = std::make_shared<BenchViewerOptions>();
  auto* viewer_bench = bench->add_subcommand(
      "viewer",
      "The viewer's frame time at 1280 x 800 with 10 robots x 4 sources, 12 receivers, range "
      "sets, 6 processes and a preview, against 30 fps");
  viewer_bench->add_option("--frames", options->frames, "Frames drawn")->capture_default_str();
  viewer_bench->add_flag("--json", options->json, "Print one JSON object instead of text");
  viewer_bench->add_option("--png", options->png, "Write the last frame to this PNG file");
  viewer_bench->callback([options, exit_code] { *exit_code = RunViewerBench(*options); });
}

}  // namespace roomfix
