// roomfix compare: each pose source in a log against the simulator's ground
// truth: error, rate and latency. `make demo` prints it and writes its JSON.
#include <fmt/format.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <string>

#include "core/analysis/circle_fit.h"
#include "core/analysis/track_error.h"
#include "core/world/file_io.h"
#include "msgio/pose_tracks.h"
#include "msgio/wire_check.h"
#include "tools/commands.h"
#include "tools/tool_site.h"

namespace roomfix {
namespace {

// Ground truth is sampled at 30 Hz or more; a longer gap means it was not
// running, and nothing is compared there.
constexpr int64_t kMaxReferenceGap_us = 200000;

// `roomfix compare OLD NEW` (a log and its `roomfix replay`): per source and
// robot, the poses in each, the error of each against the ground truth, and
// NEW's poses against OLD's at NEW's measurement times. A replay keeps the
// measurement times, so matched poses are compared exactly; between OLD's
// poses (a pose only one log has) OLD's track is interpolated, within the
// same gap as the ground truth.
nlohmann::json PrintDifference(const PoseLogs& old_logs, const PoseLogs& new_logs) {
  auto positions = [](const PoseLogs& logs, const std::pair<std::string, int>& key) {
    std::vector<analysis::TimedPosition> out;
    auto it = logs.tracks.find(key);
    if (it != logs.tracks.end()) out = it->second.Positions();
    return out;
  };
  std::set<std::pair<std::string, int>> keys;
  for (const auto& [key, track] : old_logs.tracks) keys.insert(key);
  for (const auto& [key, track] : new_logs.tracks) keys.insert(key);
  nlohmann::json out;
  fmt::print("\nNEW {} against OLD {}:\n", new_logs.logs.front().path, old_logs.logs.front().path);
  fmt::print("{:<12} {:>5} {:>7} {:>7} {:>10} {:>10} {:>9} {:>12} {:>10}\n", "source", "robot",
             "old", "new", "rmse_old_m", "rmse_new_m", "compared", "new-old_rms", "new-old_max");
  for (const auto& key : keys) {
    if (key.first == "ground_truth") continue;
    const auto old_track = positions(old_logs, key);
    const auto new_track = positions(new_logs, key);
    auto truth = positions(old_logs, {"ground_truth", key.second});
    if (truth.empty()) truth = positions(new_logs, {"ground_truth", key.second});
    const analysis::ErrorSummary old_error =
        analysis::CompareToReference(old_track, truth, kMaxReferenceGap_us);
    const analysis::ErrorSummary new_error =
        analysis::CompareToReference(new_track, truth, kMaxReferenceGap_us);
    const analysis::ErrorSummary change =
        analysis::CompareToReference(new_track, old_track, kMaxReferenceGap_us);
    fmt::print("{:<12} {:5d} {:7d} {:7d} {:10.4f} {:10.4f} {:9d} {:12.4f} {:10.4f}\n",
               key.first.c_str(), key.second, old_track.size(), new_track.size(), old_error.rmse_m,
               new_error.rmse_m, change.compared, change.rmse_m, change.max_m);
    out[key.first][std::to_string(key.second)] = {
        {"old_fixes", old_track.size()},      {"new_fixes", new_track.size()},
        {"old_rmse_m", old_error.rmse_m},     {"new_rmse_m", new_error.rmse_m},
        {"compared", change.compared},        {"new_minus_old_rms_m", change.rmse_m},
        {"new_minus_old_max_m", change.max_m}};
  }
  return out;
}

struct CompareOptions {
  std::string log_path;
  std::string new_log_path;
  std::string json_path;
  std::string config_path;
  std::string report_path;
  bool fit_circle = false;
};

// A source's track as compare uses it: positions by time and latencies.
struct SourceTrack {
  std::vector<analysis::TimedPosition> positions;
  std::vector<double> latencies_ms;
  int lost = 0;
};
using SourceTracks = std::map<std::pair<std::string, int>, SourceTrack>;

// (source, robot) -> positions and latencies
SourceTracks TracksOf(const PoseLogs& logs) {
  SourceTracks tracks;
  for (const auto& [key, track] : logs.tracks) {
    SourceTrack& t = tracks[key];
    t.positions = track.Positions();
    for (const PoseSample& s : track.samples) t.latencies_ms.push_back(s.latency_us * 1e-3);
    t.lost = track.lost;
  }
  return tracks;
}

// The table of sources against ground truth; each source's figures into
// out["sources"] (the first robot) and out["robots"].
void PrintSources(SourceTracks* tracks, nlohmann::json* out) {
  fmt::print("{:<12} {:>5} {:>7} {:>8} {:>8} {:>8} {:>8} {:>12} {:>5}\n", "source", "robot",
             "fixes", "rate_hz", "rmse_m", "p95_m", "max_m", "latency_ms", "lost");
  for (auto& [key, t] : *tracks) {
    if (key.first == "ground_truth") continue;
    std::sort(t.positions.begin(), t.positions.end(),
              [](const auto& a, const auto& b) { return a.utime < b.utime; });
    const double span_s =
        t.positions.size() > 1 ? (t.positions.back().utime - t.positions.front().utime) * 1e-6 : 0;
    const double rate = span_s > 0 ? (t.positions.size() - 1) / span_s : 0.0;
    const double latency = analysis::Percentile(t.latencies_ms, 0.5);
    nlohmann::json j = {{"fixes", t.positions.size()},
                        {"lost", t.lost},
                        {"rate_hz", rate},
                        {"latency_ms_median", latency}};
    auto truth = tracks->find({"ground_truth", key.second});
    analysis::ErrorSummary s;
    if (truth != tracks->end()) {
      auto& ref = truth->second.positions;
      std::sort(ref.begin(), ref.end(),
                [](const auto& a, const auto& b) { return a.utime < b.utime; });
      s = analysis::CompareToReference(t.positions, ref, kMaxReferenceGap_us);
      j["rmse_m"] = s.rmse_m;
      j["p95_m"] = s.p95_m;
      j["max_m"] = s.max_m;
      j["compared"] = s.compared;
    }
    fmt::print("{:<12} {:5d} {:7d} {:8.2f} {:8.4f} {:8.4f} {:8.4f} {:12.1f} {:5d}\n",
               key.first.c_str(), key.second, t.positions.size(), rate, s.rmse_m, s.p95_m, s.max_m,
               latency, t.lost);
    // One robot per source in the summary (the first); all in "robots".
    if (!(*out)["sources"].contains(key.first)) (*out)["sources"][key.first] = j;
    (*out)["robots"][std::to_string(key.second)][key.first] = j;
  }
}

// --fit-circle: the reference paper's circular motion fitted to each track.
void PrintCircleFits(const SourceTracks& tracks, nlohmann::json* out) {
  fmt::print("\n{:<12} {:>5} {:>8} {:>9} {:>9} {:>10} {:>10} {:>9} {:>8} {:>8}\n", "source",
             "robot", "r_m", "cx_m", "cy_m", "vx_mm/s", "vy_mm/s", "w_rad/s", "phase", "err_m");
  for (const auto& [key, t] : tracks) {
    std::vector<analysis::TimedPoint> points;
    for (const auto& p : t.positions) {
      points.push_back({(p.utime - t.positions.front().utime) * 1e-6, p.x_m, p.y_m});
    }
    const analysis::CircularMotionFit f = analysis::FitCircularMotion(points);
    if (!f.usable) {
      fmt::print("{:<12} {:5d} no fit: {}\n", key.first.c_str(), key.second, f.message);
      continue;
    }
    fmt::print("{:<12} {:5d} {:8.4f} {:9.4f} {:9.4f} {:10.3f} {:10.3f} {:9.4f} {:8.3f} {:8.4f}\n",
               key.first.c_str(), key.second, f.radius_m, f.cx_m, f.cy_m, f.vx_mps * 1e3,
               f.vy_mps * 1e3, f.angular_speed_radps, f.phase_rad, f.mean_error_m);
    (*out)["robots"][std::to_string(key.second)][key.first]["circle_fit"] = {
        {"radius_m", f.radius_m},
        {"radius_sigma_m", f.radius_sigma_m},
        {"cx_m", f.cx_m},
        {"cy_m", f.cy_m},
        {"vx_mps", f.vx_mps},
        {"vy_mps", f.vy_mps},
        {"angular_speed_radps", f.angular_speed_radps},
        {"phase_rad", f.phase_rad},
        {"mean_error_m", f.mean_error_m},
        {"std_error_m", f.std_error_m}};
  }
}

// parse (CLI11) -> load (the log, its site) -> compute and print (the
// tables; NEW against LOG) -> report (--json).
int RunCompare(const CompareOptions& o) {
  PoseLogs logs = ReadPoseLogs({o.log_path});
  const LogReadReport& report = logs.logs.front();
  if (!report.error.empty()) {
    std::cerr << "roomfix compare: " << report.error << "\n";
    return 1;
  }
  SourceTracks tracks = TracksOf(logs);
  // The errors need no site; which one the log was recorded in is said
  // (stderr and the JSON), a log without one is a note.
  const ToolSite site = ResolveToolSite(o.config_path, o.log_path);
  if (!ReportToolSite("roomfix compare", site, /*required=*/false)) return 1;
  nlohmann::json out;
  out["log"] = o.log_path;
  if (site.known) {
    out["site"] = {{"name", site.site.site.name},
                   {"content_hash", site.site.content_hash},
                   {"source", site.source}};
  }
  if (!o.report_path.empty()) out["report"] = o.report_path;
  PrintSources(&tracks, &out);
  if (o.fit_circle) PrintCircleFits(tracks, &out);
  if (report.undecodable > 0) {
    fmt::print(stderr, "roomfix compare: warning: {}: {} POSE_* events refused ({})\n", report.path,
               report.undecodable, RefusalCounts(report.refused));
  }
  if (report.damaged) {
    std::fflush(stdout);
    std::cerr << "roomfix compare: warning: " << report.path << ": " << report.damage << "\n";
  }
  if (!o.new_log_path.empty()) {
    const PoseLogs new_logs = ReadPoseLogs({o.new_log_path});
    const LogReadReport& new_report = new_logs.logs.front();
    if (!new_report.error.empty()) {
      std::cerr << "roomfix compare: " << new_report.error << "\n";
      return 1;
    }
    out["new_log"] = o.new_log_path;
    out["difference"] = PrintDifference(logs, new_logs);
    if (new_report.damaged) {
      std::fflush(stdout);
      std::cerr << "roomfix compare: warning: " << new_report.path << ": " << new_report.damage
                << "\n";
    }
  }
  std::string error;
  if (!o.json_path.empty() && !WriteOutputFile(o.json_path, out.dump(2) + "\n", &error)) {
    std::cerr << "roomfix compare: " << error << "\n";
    return 1;
  }
  return 0;
}

}  // namespace

void AddCompareCommand(CLI::App* app, int* exit_code) {
  auto* cmd = app->add_subcommand(
      "compare", "Error, rate and latency of every pose source in a log against ground truth");
  auto o = std::make_shared<CompareOptions>();
  cmd->add_option("LOG", o->log_path, "LCM log with POSE_* channels")->required();
  cmd->add_option("NEW", o->new_log_path,
                  "A second log (e.g. from `roomfix replay LOG`): also print each source's "
                  "difference from LOG");
  cmd->add_option("--json", o->json_path, "Also write the summary as JSON to this file");
  cmd->add_flag("--fit-circle", o->fit_circle,
                "Also fit the reference paper's circle models to each source's track");
  cmd->add_option("--config", o->config_path,
                  "Site file (default: the site the log carries on SITE); where the log's "
                  "differs, a warning names the keys");
  cmd->add_option("--report", o->report_path,
                  "Name this analysis report in the JSON (the demo's summary points to it)");
  cmd->callback([o, exit_code] { *exit_code = RunCompare(*o); });
}

}  // namespace roomfix
