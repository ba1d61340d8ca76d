// roomfix_bench micro: Google Benchmark timings of the camera path's kernels
// (marker detection, JPEG decoding, the synthetic camera), each group against
// its baseline measured in the same run. These were timing loops in the unit
// tests that asserted nothing; a timing belongs here, where it is printed and
// compared, and a test asserts values.
#include <benchmark/benchmark.h>
#include <fmt/format.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <cstdio>
#include <iostream>
#include <map>
#include <memory>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <string>
#include <vector>

#include "bench/commands.h"
#include "camera_io/frame_source.h"
#include "camera_io/jpeg_image.h"
#include "core/vision/marker_detector.h"
#include "msgio/install_paths.h"
#include "sim/synthetic_camera.h"

namespace roomfix {
namespace {

struct BenchMicroOptions {
  std::string site = DataFile("config/sites/demo_room.yaml");
  std::string filter = ".";
  double min_time_s = 0.2;
};

// One rendered frame of the site's first camera (the `clean` scenario, the
// robot where its trajectory puts it at t = 0) and what the benchmarks need
// around it.
struct Scene {
  Site site;
  Camera camera;
  calib::CameraModel lens;
  cv::Mat bgr;
  std::vector<uint8_t> jpeg;  // quality 90, SimFrameSource's default
  std::vector<vision::ColourClass> classes;
  cv::Rect window;  // 120 x 120 around the first marker
};

bool MakeScene(const std::string& site_path, Scene* s, std::string* error) {
  if (!LoadSite(site_path, &s->site, error)) return false;
  if (s->site.cameras.empty()) {
    *error = site_path + " has no camera";
    return false;
  }
  s->camera = s->site.cameras.front();
  s->lens = calib::NominalCamera(s->camera.mount_position_m, s->camera.field_of_view_deg,
                                 s->camera.width_px, s->camera.height_px);
  const sim::SyntheticCamera synth(s->site, s->camera, s->lens, sim::SimScenario{});
  std::vector<sim::MarkerTruth> truth;
  synth.Render(0.0, 0, synth.SimulatedRobots(0.0), &s->bgr, &truth);
  if (truth.empty()) {
    *error = site_path + ": no marker in the first camera's view at t = 0";
    return false;
  }
  if (!synth.Encode(s->bgr, 90, &s->jpeg) || s->jpeg.empty()) {
    *error = "cannot encode the frame as JPEG";
    return false;
  }
  // The reference pipeline's classes, as `roomfix_bench camera` builds them.
  for (const MarkerClass& mc : s->camera.marker_classes) {
    vision::ColourClass c;
    c.name = mc.name;
    c.hsv_min = mc.hsv_min;
    c.hsv_max = mc.hsv_max;
    c.min_area_px = 30;
    c.max_area_px = 20000;
    s->classes.push_back(c);
  }
  s->window = cv::Rect(static_cast<int>(truth.front().u_px) - 60,
                       static_cast<int>(truth.front().v_px) - 60, 120, 120) &
              cv::Rect(0, 0, s->bgr.cols, s->bgr.rows);
  return true;
}

vision::DetectorOptions Lighting(vision::LightingMode mode) {
  vision::DetectorOptions o;
  o.lighting = mode;
  return o;
}

// Registers every benchmark; the first of each group ("group/...") is its
// baseline. `s` outlives the run.
void Register(const Scene& s) {
  auto reg = [](const std::string& name, auto fn) {
    benchmark::RegisterBenchmark(name.c_str(), fn)->Unit(benchmark::kMillisecond);
  };
  // Marker detection on the whole frame: OpenCV's HSV + inRange + blob
  // detector, then MarkerDetector at full and half size, in a window, and
  // Refine on a full-resolution window after a half-size search.
  reg("detect/reference", [&s](benchmark::State& st) {
    for (auto _ : st) benchmark::DoNotOptimize(vision::DetectReference(s.bgr, s.classes));
  });
  for (const auto mode : {vision::LightingMode::kFixed, vision::LightingMode::kNormalised}) {
    const bool fixed = mode == vision::LightingMode::kFixed;
    reg(std::string("detect/full_frame_") + (fixed ? "fixed" : "normalised"),
        [&s, mode](benchmark::State& st) {
          const vision::MarkerDetector detector(s.classes, Lighting(mode));
          for (auto _ : st) benchmark::DoNotOptimize(detector.Detect(s.bgr, vision::ImageWindow{}));
        });
  }
  reg("detect/half_size_normalised", [&s](benchmark::State& st) {
    const vision::MarkerDetector detector(s.classes, Lighting(vision::LightingMode::kNormalised));
    cv::Mat half;
    cv::resize(s.bgr, half, cv::Size(s.bgr.cols / 2, s.bgr.rows / 2), 0, 0, cv::INTER_AREA);
    vision::ImageWindow w;
    w.scale = 2;
    for (auto _ : st) benchmark::DoNotOptimize(detector.Detect(half, w));
  });
  reg("detect/window_120px_one_class", [&s](benchmark::State& st) {
    const vision::MarkerDetector detector(s.classes, Lighting(vision::LightingMode::kNormalised));
    const cv::Mat window = s.bgr(s.window).clone();
    vision::ImageWindow w;
    w.offset_u_px = s.window.x;
    w.offset_v_px = s.window.y;
    for (auto _ : st) benchmark::DoNotOptimize(detector.Detect(window, w, {0}));
  });
  reg("detect/refine_120px_window", [&s](benchmark::State& st) {
    const vision::MarkerDetector detector(s.classes, Lighting(vision::LightingMode::kNormalised));
    const cv::Mat window = s.bgr(s.window).clone();
    vision::ImageWindow w;
    w.offset_u_px = s.window.x;
    w.offset_v_px = s.window.y;
    const std::vector<vision::Blob> found = detector.Detect(window, w, {0});
    if (found.empty()) {
      st.SkipWithError("no marker in the window");
      return;
    }
    for (auto _ : st) {
      vision::Blob b = found.front();
      benchmark::DoNotOptimize(detector.Refine(window, w, 0, &b));
    }
  });

  // JPEG decoding of the frame: OpenCV's whole-frame imdecode, then
  // camera_proc's libjpeg-turbo decoder per DCT and chroma upsampling, whole
  // frame reduced by DCT scaling (1, 2, 4, 8) and a 200 px region.
  reg("decode/imdecode_full", [&s](benchmark::State& st) {
    for (auto _ : st) benchmark::DoNotOptimize(cv::imdecode(s.jpeg, cv::IMREAD_COLOR));
  });
  for (const bool fast : {true, false}) {
    for (const bool fancy : {false, true}) {
      const std::string variant =
          std::string(fast ? "ifast" : "islow") + (fancy ? "_triangular" : "_replicate");
      auto make = [&s, fast, fancy](benchmark::State& st) {
        std::string error;
        auto image = camera::MakeJpegImageWithOptions(s.jpeg, {fast, fancy}, &error);
        if (image == nullptr) st.SkipWithError(error.c_str());
        return image;
      };
      for (const int scale : {1, 2, 4, 8}) {
        reg("decode/" + variant + "_scale" + std::to_string(scale),
            [make, scale](benchmark::State& st) {
              const auto image = make(st);
              if (image == nullptr) return;
              cv::Mat out;
              std::string error;
              for (auto _ : st) benchmark::DoNotOptimize(image->DecodeReduced(scale, &out, &error));
            });
      }
      reg("decode/" + variant + "_region_200px", [make, &s](benchmark::State& st) {
        const auto image = make(st);
        if (image == nullptr) return;
        const cv::Rect roi(s.bgr.cols / 2 - 100, s.bgr.rows / 2 - 100, 200, 200);
        cv::Mat out;
        std::string error;
        for (auto _ : st) benchmark::DoNotOptimize(image->DecodeRegion(roi, &out, &error));
      });
    }
  }

  // The synthetic camera: one frame rendered per scenario (the clean one is
  // the baseline), then its JPEG encoding.
  for (const char* name : {"clean", "harsh", "webcam"}) {
    reg(std::string("render/") + name, [&s, name](benchmark::State& st) {
      sim::SimScenario scenario;
      std::string error;
      if (!sim::ParseSimScenario(name, s.site, &scenario, &error)) {
        st.SkipWithError(error.c_str());
        return;
      }
      const sim::SyntheticCamera camera(s.site, s.camera, s.lens, scenario);
      cv::Mat image;
      int64_t frame = 0;
      for (auto _ : st) {
        const double t_s = static_cast<double>(frame) / 30.0;
        camera.Render(t_s, frame++, camera.SimulatedRobots(t_s), &image);
      }
    });
  }
  reg("render/encode_jpeg_q90", [&s](benchmark::State& st) {
    const sim::SyntheticCamera camera(s.site, s.camera, s.lens, sim::SimScenario{});
    std::vector<uint8_t> bytes;
    for (auto _ : st) benchmark::DoNotOptimize(camera.Encode(s.bgr, 90, &bytes));
  });
}

// Google Benchmark's console table, then each benchmark's CPU time as a
// ratio to its group's baseline (the group's first benchmark) from the same
// run. CPU time, not wall time: every kernel is single-threaded, and on a
// shared machine wall time also counts the other processes' turns.
class RatioReporter : public benchmark::ConsoleReporter {
 public:
  // Colour codes only on a terminal.
  RatioReporter() : ConsoleReporter(isatty(STDOUT_FILENO) ? OO_Defaults : OO_Tabular) {}

  void ReportRuns(const std::vector<Run>& runs) override {
    ConsoleReporter::ReportRuns(runs);
    for (const Run& r : runs) {
      if (r.error_occurred || r.run_type != Run::RT_Iteration) continue;
      const std::string name = r.benchmark_name();
      const std::string group = name.substr(0, name.find('/'));
      if (baseline_ms_.count(group) == 0) baseline_ms_[group] = {name, r.GetAdjustedCPUTime()};
      rows_.push_back({name, r.GetAdjustedCPUTime() / baseline_ms_[group].second});
    }
  }
  void PrintRatios() const {
    fmt::print("\n{:<40} {}\n", "benchmark", "CPU time / its group's baseline");
    for (const auto& [name, ratio] : rows_) fmt::print("{:<40} {:8.3f}\n", name.c_str(), ratio);
    for (const auto& [group, baseline] : baseline_ms_) {
      fmt::print("baseline of {}: {}\n", group.c_str(), baseline.first.c_str());
    }
  }

 private:
  std::map<std::string, std::pair<std::string, double>> baseline_ms_;
  std::vector<std::pair<std::string, double>> rows_;
};

int RunMicroBench(const BenchMicroOptions& o) {
  static Scene scene;  // the registered benchmarks refer to it
  std::string error;
  if (!MakeScene(o.site, &scene, &error)) {
    std::cerr << "roomfix_bench micro: " << error << "\n";
    return 1;
  }
  Register(scene);
  std::string filter = "--benchmark_filter=" + o.filter;
  std::string min_time = "--benchmark_min_time=" + std::to_string(o.min_time_s);
  std::string program = "roomfix_bench micro";
  char* argv[] = {program.data(), filter.data(), min_time.data(), nullptr};
  int argc = 3;
  benchmark::Initialize(&argc, argv);
  RatioReporter reporter;
  const size_t ran = benchmark::RunSpecifiedBenchmarks(&reporter);
  benchmark::Shutdown();
  if (ran == 0) {
    std::cerr << "roomfix_bench micro: no benchmark matches '" << o.filter << "'\n";
    return 1;
  }
  reporter.PrintRatios();
  return 0;
}

}  // namespace

void AddBenchMicroCommand(CLI::App* bench, int* exit_code) {
  auto options = std::make_shared<BenchMicroOptions>();
  auto* cmd = bench->add_subcommand(
      "micro",
      "Google Benchmark timings of marker detection, JPEG decoding and the synthetic camera on "
      "one 1080p frame, each against its group's baseline (reference detector, cv::imdecode, "
      "the clean render)");
  cmd->add_option("--site", options->site, "Site file (its first camera)")->capture_default_str();
  cmd->add_option("--filter", options->filter, "Regular expression of the benchmarks to run")
      ->capture_default_str();
  cmd->add_option("--min-time", options->min_time_s, "Seconds each benchmark runs at least")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  cmd->callback([options, exit_code] { *exit_code = RunMicroBench(*options); });
}

}  // namespace roomfix
