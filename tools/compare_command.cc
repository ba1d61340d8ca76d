// roomfix compare: each pose source in a log against the simulator's ground
// truth: error, rate and latency. `make demo` prints it and writes its JSON.
#include <CLI/CLI.hpp>
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
  std::printf("\nNEW %s against OLD %s:\n", new_logs.logs.front().path.c_str(),
              old_logs.logs.front().path.c_str());
  std::printf("%-12s %5s %7s %7s %10s %10s %9s %12s %10s\n", "source", "robot", "old", "new",
              "rmse_old_m", "rmse_new_m", "compared", "new-old_rms", "new-old_max");
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
    std::printf("%-12s %5d %7zu %7zu %10.4f %10.4f %9d %12.4f %10.4f\n", key.first.c_str(),
                key.second, old_track.size(), new_track.size(), old_error.rmse_m, new_error.rmse_m,
                change.compared, change.rmse_m, change.max_m);
    out[key.first][std::to_string(key.second)] = {
        {"old_fixes", old_track.size()},      {"new_fixes", new_track.size()},
        {"old_rmse_m", old_error.rmse_m},     {"new_rmse_m", new_error.rmse_m},
        {"compared", change.compared},        {"new_minus_old_rms_m", change.rmse_m},
        {"new_minus_old_max_m", change.max_m}};
  }
  return out;
}

}  // namespace

void AddCompareCommand(CLI::App* app, int* exit_code) {
  auto* cmd = app->add_subcommand(
      "compare", "Error, rate and latency of every pose source in a log against ground truth");
  auto log_path = std::make_shared<std::string>();
  auto json_path = std::make_shared<std::string>();
  auto fit_circle = std::make_shared<bool>(false);
  cmd->add_option("LOG", *log_path, "LCM log with POSE_* channels")->required();
  auto new_log_path = std::make_shared<std::string>();
  cmd->add_option("NEW", *new_log_path,
                  "A second log (e.g. from `roomfix replay LOG`): also print each source's "
                  "difference from LOG");
  cmd->add_option("--json", *json_path, "Also write the summary as JSON to this file");
  cmd->add_flag("--fit-circle", *fit_circle,
                "Also fit the reference paper's circle models to each source's track");
  auto config_path = std::make_shared<std::string>();
  cmd->add_option("--config", *config_path,
                  "Site file (default: the site the log carries on SITE); where the log's "
                  "differs, a warning names the keys");
  auto report_path = std::make_shared<std::string>();
  cmd->add_option("--report", *report_path,
                  "Name this analysis report in the JSON (the demo's summary points to it)");
  cmd->callback([log_path, new_log_path, json_path, report_path, fit_circle, config_path,
                 exit_code] {
    PoseLogs logs = ReadPoseLogs({*log_path});
    const LogReadReport& report = logs.logs.front();
    if (!report.error.empty()) {
      std::cerr << "roomfix compare: " << report.error << "\n";
      *exit_code = 1;
      return;
    }
    // (source, robot) -> positions and latencies
    struct SourceTrack {
      std::vector<analysis::TimedPosition> positions;
      std::vector<double> latencies_ms;
      int lost = 0;
    };
    std::map<std::pair<std::string, int>, SourceTrack> tracks;
    for (const auto& [key, track] : logs.tracks) {
      SourceTrack& t = tracks[key];
      t.positions = track.Positions();
      for (const PoseSample& s : track.samples) t.latencies_ms.push_back(s.latency_us * 1e-3);
      t.lost = track.lost;
    }
    // The errors need no site; which one the log was recorded in is said
    // (stderr and the JSON), a log without one is a note.
    const ToolSite site = ResolveToolSite(*config_path, *log_path);
    if (!ReportToolSite("roomfix compare", site, /*required=*/false)) {
      *exit_code = 1;
      return;
    }
    nlohmann::json out;
    out["log"] = *log_path;
    if (site.known) {
      out["site"] = {{"name", site.site.site.name},
                     {"content_hash", site.site.content_hash},
                     {"source", site.source}};
    }
    if (!report_path->empty()) out["report"] = *report_path;
    std::printf("%-12s %5s %7s %8s %8s %8s %8s %12s %5s\n", "source", "robot", "fixes", "rate_hz",
                "rmse_m", "p95_m", "max_m", "latency_ms", "lost");
    for (auto& [key, t] : tracks) {
      if (key.first == "ground_truth") continue;
      std::sort(t.positions.begin(), t.positions.end(),
                [](const auto& a, const auto& b) { return a.utime < b.utime; });
      const double span_s = t.positions.size() > 1
                                ? (t.positions.back().utime - t.positions.front().utime) * 1e-6
                                : 0;
      const double rate = span_s > 0 ? (t.positions.size() - 1) / span_s : 0.0;
      const double latency = analysis::Percentile(t.latencies_ms, 0.5);
      nlohmann::json j = {{"fixes", t.positions.size()},
                          {"lost", t.lost},
                          {"rate_hz", rate},
                          {"latency_ms_median", latency}};
      auto truth = tracks.find({"ground_truth", key.second});
      analysis::ErrorSummary s;
      if (truth != tracks.end()) {
        auto& ref = truth->second.positions;
        std::sort(ref.begin(), ref.end(),
                  [](const auto& a, const auto& b) { return a.utime < b.utime; });
        s = analysis::CompareToReference(t.positions, ref, kMaxReferenceGap_us);
        j["rmse_m"] = s.rmse_m;
        j["p95_m"] = s.p95_m;
        j["max_m"] = s.max_m;
        j["compared"] = s.compared;
      }
      std::printf("%-12s %5d %7zu %8.2f %8.4f %8.4f %8.4f %12.1f %5d\n", key.first.c_str(),
                  key.second, t.positions.size(), rate, s.rmse_m, s.p95_m, s.max_m, latency,
                  t.lost);
      // One robot per source in the summary (the first); all in "robots".
      if (!out["sources"].contains(key.first)) out["sources"][key.first] = j;
      out["robots"][std::to_string(key.second)][key.first] = j;
    }
    if (*fit_circle) {
      std::printf("\n%-12s %5s %8s %9s %9s %10s %10s %9s %8s %8s\n", "source", "robot", "r_m",
                  "cx_m", "cy_m", "vx_mm/s", "vy_mm/s", "w_rad/s", "phase", "err_m");
      for (auto& [key, t] : tracks) {
        std::vector<analysis::TimedPoint> points;
        for (const auto& p : t.positions) {
          points.push_back({(p.utime - t.positions.front().utime) * 1e-6, p.x_m, p.y_m});
        }
        const analysis::CircularMotionFit f = analysis::FitCircularMotion(points);
        if (!f.usable) {
          std::printf("%-12s %5d no fit: %s\n", key.first.c_str(), key.second, f.message.c_str());
          continue;
        }
        std::printf("%-12s %5d %8.4f %9.4f %9.4f %10.3f %10.3f %9.4f %8.3f %8.4f\n",
                    key.first.c_str(), key.second, f.radius_m, f.cx_m, f.cy_m, f.vx_mps * 1e3,
                    f.vy_mps * 1e3, f.angular_speed_radps, f.phase_rad, f.mean_error_m);
        out["robots"][std::to_string(key.second)][key.first]["circle_fit"] = {
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
    if (report.undecodable > 0) {
      std::fprintf(stderr, "roomfix compare: warning: %s: %lld POSE_* events refused (%s)\n",
                   report.path.c_str(), static_cast<long long>(report.undecodable),
                   RefusalCounts(report.refused).c_str());
    }
    if (report.damaged) {
      std::fflush(stdout);
      std::cerr << "roomfix compare: warning: " << report.path << ": " << report.damage << "\n";
    }
    if (!new_log_path->empty()) {
      const PoseLogs new_logs = ReadPoseLogs({*new_log_path});
      const LogReadReport& new_report = new_logs.logs.front();
      if (!new_report.error.empty()) {
        std::cerr << "roomfix compare: " << new_report.error << "\n";
        *exit_code = 1;
        return;
      }
      out["new_log"] = *new_log_path;
      out["difference"] = PrintDifference(logs, new_logs);
      if (new_report.damaged) {
        std::fflush(stdout);
        std::cerr << "roomfix compare: warning: " << new_report.path << ": " << new_report.damage
                  << "\n";
      }
    }
    if (!json_path->empty()) {
      std::string error;
      if (!WriteOutputFile(*json_path, out.dump(2) + "\n", &error)) {
        std::cerr << "roomfix compare: " << error << "\n";
        *exit_code = 1;
        return;
      }
    }
    *exit_code = 0;
  });
}

}  // namespace roomfix
