// roomfix_bench replay: how many times faster than real time `roomfix
// replay` re-runs trilat and fusion over a recorded log, on one core.
#include <fmt/format.h>
#include <time.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cstdlib>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "bench/commands.h"
#include "core/world/site.h"
#include "tools/replay.h"

namespace roomfix {
namespace {

double Seconds(clockid_t clock) {
  timespec ts{};
  ::clock_gettime(clock, &ts);
  return static_cast<double>(ts.tv_sec) + ts.tv_nsec * 1e-9;
}

struct BenchReplayOptions {
  std::string log_path;
  std::string site_path;
  int repeat = 20;
  bool json = false;
};

struct Case {
  const char* name;
  bool trilat;
  bool fusion;
  bool camera = false;
};

int RunBenchReplay(const BenchReplayOptions& args) {
  ReplaySite replay_site;
  std::string error;
  if (!ResolveReplaySite(args.log_path, args.site_path, "", &replay_site, &error)) {
    std::cerr << "roomfix_bench replay: " << error << "\n";
    return 1;
  }
  const Site& site = replay_site.loaded.site;
  if (args.repeat < 1) {
    std::cerr << "roomfix_bench replay: --repeat must be at least 1\n";
    return 1;
  }
  // The new log goes to a scratch file, so writing it is part of the cost.
  char scratch[] = "/tmp/roomfix_bench_replay_XXXXXX";
  const int fd = ::mkstemp(scratch);
  if (fd < 0) {
    std::cerr << "roomfix_bench replay: cannot make a scratch file in /tmp\n";
    return 1;
  }
  ::close(fd);
  std::vector<Case> cases = {
      {"trilat", true, false}, {"fusion", false, true}, {"trilat,fusion", true, true}};
  // camera_proc's node too, when the log holds its detections and the site
  // a calibration (roomfix replay --nodes camera).
  std::map<int, calib::Calibration> calibrations;
  bool holds_pixels = false;
  if (LogHoldsChannel(args.log_path, kMarkerPixelsChannel, &holds_pixels, &error) && holds_pixels &&
      ReplayCameraCalibrations(replay_site.loaded, &calibrations, &error) &&
      !calibrations.empty()) {
    cases.push_back({"trilat,fusion,camera", true, true, true});
  }
  nlohmann::json out = {{"log", args.log_path}, {"repeat", args.repeat}};
  if (!args.json) {
    fmt::print("replay of {}, {} runs each, single-threaded (one core); median per run\n",
               args.log_path.c_str(), args.repeat);
    fmt::print("{:<20} {:>8} {:>10} {:>10} {:>10} {:>12} {:>12}\n", "nodes", "events", "log_s",
               "wall_ms", "cpu_ms", "x_real_time", "x_rt_by_cpu");
  }
  int rc = 0;
  for (const Case& c : cases) {
    PipelineReplayOptions options;
    options.trilat = c.trilat;
    options.fusion = c.fusion;
    options.camera = c.camera;
    if (c.camera) options.camera_calibrations = calibrations;
    options.trilat_options.solver.method = trilat::Method::kRobust;
    std::vector<double> wall_s;
    std::vector<double> cpu_s;
    PipelineReplaySummary s;
    for (int i = 0; i < args.repeat; ++i) {
      const double wall0 = Seconds(CLOCK_MONOTONIC);
      const double cpu0 = Seconds(CLOCK_THREAD_CPUTIME_ID);
      s = ReplayPipelineFile(args.log_path, site, options, scratch, /*overwrite=*/true);
      cpu_s.push_back(Seconds(CLOCK_THREAD_CPUTIME_ID) - cpu0);
      wall_s.push_back(Seconds(CLOCK_MONOTONIC) - wall0);
      if (!s.ok) break;
    }
    if (!s.ok) {
      std::cerr << "roomfix_bench replay: " << s.error << "\n";
      rc = 1;
      break;
    }
    std::sort(wall_s.begin(), wall_s.end());
    std::sort(cpu_s.begin(), cpu_s.end());
    const double wall = wall_s[wall_s.size() / 2];
    const double cpu = cpu_s[cpu_s.size() / 2];
    const double span_s = (s.last_utime - s.first_utime) * 1e-6;
    // Real time is the baseline: lcm-logplayer into live processes takes
    // span_s, whatever the machine.
    const double speedup = wall > 0 ? span_s / wall : 0.0;
    // The same against the thread's CPU time: what one core does when no
    // other program shares it (wall time also counts waiting for the core).
    const double cpu_speedup = cpu > 0 ? span_s / cpu : 0.0;
    if (args.json) {
      out["cases"][c.name] = {
          {"events", s.events_read},    {"log_s", span_s},
          {"wall_ms", wall * 1e3},      {"cpu_ms", cpu * 1e3},
          {"times_real_time", speedup}, {"times_real_time_by_cpu", cpu_speedup}};
    } else {
      fmt::print("{:<20} {:8} {:10.2f} {:10.3f} {:10.3f} {:11.0f}x {:11.0f}x\n", c.name,
                 static_cast<long long>(s.events_read), span_s, wall * 1e3, cpu * 1e3, speedup,
                 cpu_speedup);
    }
  }
  ::unlink(scratch);
  if (args.json && rc == 0) fmt::print("{}\n", out.dump(2).c_str());
  return rc;
}

}  // namespace

void AddBenchReplayCommand(CLI::App* bench, int* exit_code) {
  auto* cmd = bench->add_subcommand(
      "replay", "How many times faster than real time `roomfix replay` runs trilat and fusion");
  auto args = std::make_shared<BenchReplayOptions>();
  cmd->add_option("LOG", args->log_path, "Recorded log with RANGES, POSE_CAMERA, POSE_ULTRASOUND")
      ->required();
  cmd->add_option("--config", args->site_path,
                  "The site file the log was recorded in (default: the log's SITE)");
  cmd->add_option("--repeat", args->repeat, "Runs per case (the median is printed)")
      ->capture_default_str();
  cmd->add_flag("--json", args->json, "Print one JSON object instead of a table");
  cmd->callback([args, exit_code] { *exit_code = RunBenchReplay(*args); });
}

}  // namespace roomfix
