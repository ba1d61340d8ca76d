// roomfix analyze: the reference paper's measurements and figures from
// recorded logs: static repeatability, timing, circle fits, motion, error
// against ground truth, camera against ultrasound. A Markdown report and PNG
// figures (gnuplot) in an output folder, and the same figures as JSON.
#include <fcntl.h>
#include <fmt/format.h>
#include <spawn.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iostream>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>
#include <string>

#include "core/analysis/circle_fit.h"
#include "core/analysis/fix_quality.h"
#include "core/analysis/track_error.h"
#include "core/analysis/track_stats.h"
#include "core/world/file_io.h"
#include "msgio/pose_tracks.h"
#include "msgio/wire_check.h"
#include "tools/commands.h"
#include "tools/fixed_text.h"
#include "tools/tool_site.h"

extern char** environ;

namespace roomfix {
namespace {

using json = nlohmann::ordered_json;

struct AnalyzeOptions {
  std::vector<std::string> logs;
  // The site to report against; default: each log's own (SITE).
  std::string config_path;
  std::string out_dir;
  bool json = false;
  bool figures = true;
  double frame_rate_hz = 30.0;
  double tolerance_m = 0.015;
  double static_extent_m = 0.05;
  // Ground truth and camera tracks are sampled at 4 Hz or more; a longer
  // gap means the reference was not running, and nothing is compared there.
  double max_gap_s = 0.3;
};

json HistogramJson(const analysis::Histogram& h) {
  return {{"lo", h.lo},
          {"bin_width", h.bin_width},
          {"counts", h.counts},
          {"below", h.below},
          {"above", h.above}};
}

json LatencyJson(const analysis::LatencySummary& l) {
  return {{"n", l.n},
          {"mean_ms", l.mean_ms},
          {"median_ms", l.median_ms},
          {"p95_ms", l.p95_ms},
          {"max_ms", l.max_ms}};
}

json ErrorJson(const analysis::ErrorSummary& e) {
  return {{"compared", e.compared}, {"unmatched", e.unmatched}, {"mean_m", e.mean_m},
          {"rmse_m", e.rmse_m},     {"p95_m", e.p95_m},         {"max_m", e.max_m}};
}

json CircleJson(const analysis::DriftingCircle& c) {
  return {{"radius_m", c.radius_m}, {"radius_sigma_m", c.radius_sigma_m},
          {"cx_m", c.cx_m},         {"cx_sigma_m", c.cx_sigma_m},
          {"cy_m", c.cy_m},         {"cy_sigma_m", c.cy_sigma_m},
          {"vx_mps", c.vx_mps},     {"vx_sigma_mps", c.vx_sigma_mps},
          {"vy_mps", c.vy_mps},     {"vy_sigma_mps", c.vy_sigma_mps}};
}

// A path as a gnuplot string literal: single-quoted, quotes doubled.
std::string Gp(const std::string& path) {
  std::string out = "'";
  for (char c : path) out += c == '\'' ? std::string("''") : std::string(1, c);
  return out + "'";
}

// Runs gnuplot on a script, with no shell in between (the output folder's
// name is the user's); false (with the reason) when gnuplot is missing or
// fails. Figures are optional: the report says when one is missing.
bool RunGnuplot(const std::string& script_path, std::string* error) {
  const std::string log_path = script_path + ".log";
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, 1, log_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC,
                                   0644);
  posix_spawn_file_actions_adddup2(&actions, 1, 2);
  std::string program = "gnuplot";
  std::string script = script_path;
  char* argv[] = {program.data(), script.data(), nullptr};
  pid_t pid = -1;
  const int rc = ::posix_spawnp(&pid, "gnuplot", &actions, nullptr, argv, environ);
  posix_spawn_file_actions_destroy(&actions);
  if (rc != 0) {
    *error = std::string("cannot start gnuplot: ") + std::strerror(rc) + " (is it installed?)";
    return false;
  }
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    std::ifstream log(log_path);
    std::string first_line;
    std::getline(log, first_line);
    *error = "gnuplot failed" + (first_line.empty() ? std::string() : ": " + first_line);
    return false;
  }
  return true;
}

// Every step checked (file_io.h): a full disk is a failed run, not a
// report cut short.
bool WriteText(const std::string& path, const std::string& text, std::string* error) {
  return WriteOutputFile(path, text, error);
}

// One row of the quality table, and its header.
constexpr char kQualityRow[] =
    "{:<12} {:>5} {:>6} {:>6} {:>6} {:>6} {:>8} {:>8} {:>8} {:>9} {:>7} {:>7}\n";
constexpr char kQualityHeader[] =
    "\n{:<12} {:>5} {:>6} {:>6} {:>6} {:>6} {:>8} {:>8} {:>8} {:>9} {:>7} {:>7}\n";

// Whether a pose stream can be trusted (analysis::AssessFixes): accuracy
// with the worst fix flagged ok, the shares of ok / degraded / lost fixes,
// and the share of errors inside each fix's own 95 % covariance ellipse.
// Adds the rows to the report, returns the JSON and appends one line to
// `table` (the summary `make demo` prints). Without ground truth only the
// status shares are known; the rest is NaN ("-").
json FixQualityFigures(const PoseTrack& track, const PoseTrack* truth, int64_t max_gap_us,
                       std::ostream& md, std::string* table) {
  std::vector<analysis::RatedFix> fixes;
  fixes.reserve(track.samples.size());
  for (const PoseSample& s : track.samples) {
    fixes.push_back({s.utime, s.x_m, s.y_m, s.degraded, s.cov_xx_m2, s.cov_xy_m2, s.cov_yy_m2});
  }
  const std::vector<analysis::TimedPosition> reference =
      truth != nullptr ? truth->Positions() : std::vector<analysis::TimedPosition>{};
  const analysis::FixQuality q = analysis::AssessFixes(fixes, track.lost, reference, max_gap_us);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const bool truth_known = q.compared > 0;
  auto cm = [&](double m) { return Fixed(truth_known ? m * 100.0 : nan, 2); };
  auto pct = [](double share) { return Fixed(share * 100.0, 1); };
  md << "| fixes ok / degraded / lost | " << pct(q.share_ok) << " / " << pct(q.share_degraded)
     << " / " << pct(q.share_lost) << " % |\n";
  if (truth_known) {
    md << "| error vs ground truth: p99, worst fix flagged ok | " << cm(q.p99_m) << ", "
       << cm(q.worst_ok_m) << " cm |\n| errors inside the fix's own 95 % ellipse (median "
       << "squared Mahalanobis; calibrated: 95 %, 1.39) | " << pct(q.share_inside_95) << " % ("
       << Fixed(q.median_d2, 2) << ") over " << q.with_covariance << " fixes |\n";
  }
  *table +=
      fmt::format(kQualityRow, track.source.c_str(), track.robot_id, q.fixes, pct(q.share_ok),
                  pct(q.share_degraded), pct(q.share_lost), cm(q.rmse_m), cm(q.p99_m), cm(q.max_m),
                  cm(q.worst_ok_m), pct(q.share_inside_95), Fixed(q.median_d2, 2));
  json j = {{"fixes", q.fixes},          {"ok", q.ok},
            {"degraded", q.degraded},    {"lost", q.lost},
            {"share_ok", q.share_ok},    {"share_degraded", q.share_degraded},
            {"share_lost", q.share_lost}};
  if (truth_known) {
    j["compared"] = q.compared;
    j["rmse_m"] = q.rmse_m;
    j["p99_m"] = q.p99_m;
    j["max_m"] = q.max_m;
    j["worst_ok_m"] = std::isfinite(q.worst_ok_m) ? json(q.worst_ok_m) : json(nullptr);
    j["with_covariance"] = q.with_covariance;
    j["share_inside_95"] =
        std::isfinite(q.share_inside_95) ? json(q.share_inside_95) : json(nullptr);
    j["median_squared_mahalanobis"] =
        std::isfinite(q.median_d2) ? json(q.median_d2) : json(nullptr);
  }
  return j;
}

// Draws the figures of one analysis; each returns the PNG's file name, or ""
// when it could not be drawn (with a note for the report).
class Figures {
 public:
  Figures(std::string dir, bool enabled) : dir_(std::move(dir)), enabled_(enabled) {}

  // `site` (nullptr when no log's site is known) adds its fixed obstacles
  // as grey footprints behind the tracks: where a receiver could not hear.
  std::string Trajectory(int robot_id, const std::vector<const PoseTrack*>& tracks,
                         const Site* site) {
    const std::string name = "trajectory_robot" + std::to_string(robot_id);
    std::string plot;
    for (const PoseTrack* t : tracks) {
      const std::string data = WriteData(name + "_" + t->source, [&](std::ostream& o) {
        for (const PoseSample& s : t->samples) o << s.x_m << " " << s.y_m << "\n";
      });
      plot += (plot.empty() ? "" : ", ") +
              (Gp(data) + " using 1:2 with " +
               (t->source == "ground_truth" ? "lines lw 2" : "points pt 7 ps 0.4") + " title '" +
               t->source + "'");
    }
    // A square window around the reference track (ground truth, else the
    // camera, else everything), so a few wild fixes do not shrink the
    // track to a speck; fixes outside it are counted in the title.
    const PoseTrack* ref = nullptr;
    for (const char* source : {"ground_truth", "camera"}) {
      for (const PoseTrack* t : tracks) {
        if (ref == nullptr && t->source == source && !t->samples.empty()) ref = t;
      }
    }
    std::string range;
    std::string outside_note;
    if (ref != nullptr) {
      double x0 = 1e300, x1 = -1e300, y0 = 1e300, y1 = -1e300;
      for (const PoseSample& p : ref->samples) {
        x0 = std::min(x0, p.x_m);
        x1 = std::max(x1, p.x_m);
        y0 = std::min(y0, p.y_m);
        y1 = std::max(y1, p.y_m);
      }
      const double half = std::max(x1 - x0, y1 - y0) / 2.0 + 0.25;
      const double cx = (x0 + x1) / 2.0, cy = (y0 + y1) / 2.0;
      range = "set xrange [" + Fixed(cx - half, 3) + ":" + Fixed(cx + half, 3) + "]\nset yrange [" +
              Fixed(cy - half, 3) + ":" + Fixed(cy + half, 3) + "]\n";
      int outside = 0;
      for (const PoseTrack* t : tracks) {
        for (const PoseSample& p : t->samples) {
          outside += std::abs(p.x_m - cx) > half || std::abs(p.y_m - cy) > half;
        }
      }
      if (outside > 0) outside_note = " (" + std::to_string(outside) + " fixes outside the view)";
    }
    return Draw(name, "set title 'Robot " + std::to_string(robot_id) +
                          ": trajectory of every source" + outside_note +
                          "'\nset xlabel 'x (m)'\nset ylabel 'y (m)'\n"
                          "set size ratio -1\nset key outside right\n" +
                          ObstacleObjects(site) + range + "plot " + plot + "\n");
  }

  // gnuplot objects for the site's fixed obstacles: a circle per cylinder,
  // a polygon per (turned) box; a moving one has no single place.
  static std::string ObstacleObjects(const Site* site) {
    if (site == nullptr) return "";
    std::string out;
    int n = 0;
    for (const Obstacle& o : site->obstacles) {
      if (o.trajectory != nullptr) continue;
      const std::string style = " behind fc rgb '#96a0aa' fs solid 0.6 border rgb '#5a646e'\n";
      ++n;
      if (o.shape == Obstacle::Shape::kCylinder) {
        out += "set object " + std::to_string(n) + " circle at " + Fixed(o.centre_m[0], 4) + "," +
               Fixed(o.centre_m[1], 4) + " size " + Fixed(o.radius_m, 4) + style;
        continue;
      }
      const double cs = std::cos(o.yaw_rad), sn = std::sin(o.yaw_rad);
      std::string corners;
      for (const auto& [u, v] : {std::pair{1, 1}, {-1, 1}, {-1, -1}, {1, -1}, {1, 1}}) {
        const double du = 0.5 * u * o.size_m[0], dv = 0.5 * v * o.size_m[1];
        corners += (corners.empty() ? " from " : " to ") +
                   Fixed(o.centre_m[0] + cs * du - sn * dv, 4) + "," +
                   Fixed(o.centre_m[1] + sn * du + cs * dv, 4);
      }
      out += "set object " + std::to_string(n) + " polygon" + corners + style;
    }
    return out;
  }

  std::string Intervals(const std::string& stem, const analysis::Timing& t) {
    const std::string ms = WriteData(stem + "_ms", [&](std::ostream& o) {
      for (size_t k = 0; k < t.interval_ms.counts.size(); ++k) {
        o << t.interval_ms.lo + (k + 0.5) * t.interval_ms.bin_width << " "
          << t.interval_ms.counts[k] << "\n";
      }
    });
    const std::string frames = WriteData(stem + "_frames", [&](std::ostream& o) {
      for (size_t k = 0; k < t.interval_frames.counts.size(); ++k) {
        o << k << " " << t.interval_frames.counts[k] << "\n";
      }
    });
    return Draw(stem, "set multiplot layout 1,2 title 'Time between successive fixes: mean " +
                          Fixed(t.mean_ms, 1) + " ms, std " + Fixed(t.std_ms, 1) +
                          " ms'\nset style fill solid 0.6\nset xlabel 'interval (ms)'\n"
                          "set ylabel 'fixes'\nplot " +
                          Gp(ms) +
                          " using 1:2 with boxes notitle\nset xlabel 'interval (frames at " +
                          Fixed(1000.0 / t.frame_period_ms, 0) + " fps)'\nset xtics 1\nplot " +
                          Gp(frames) + " using 1:2 with boxes notitle\nunset multiplot\n");
  }

  std::string ErrorOverTime(const std::string& stem, const std::vector<analysis::ErrorSample>& e) {
    if (e.empty()) return "";
    const int64_t t0 = e.front().utime;
    const std::string data = WriteData(stem, [&](std::ostream& o) {
      for (const auto& s : e) {
        o << (static_cast<double>(s.utime) - static_cast<double>(t0)) * 1e-6 << " "
          << s.error_m * 100.0 << "\n";
      }
    });
    return Draw(stem,
                "set title 'Error against ground truth'\nset xlabel 'time (s)'\n"
                "set ylabel 'error (cm)'\nplot " +
                    Gp(data) + " using 1:2 with lines notitle\n");
  }

  std::string Static(const std::string& stem, const analysis::Repeatability& r) {
    const analysis::Histogram2D& h = r.histogram;
    if (h.nx == 0 || h.ny == 0) return "";
    const std::string data = WriteData(stem, [&](std::ostream& o) {
      for (int iy = 0; iy < h.ny; ++iy) {
        for (int ix = 0; ix < h.nx; ++ix) {
          o << (h.x_lo + (ix + 0.5) * h.bin_m - r.mean_x_m) * 100.0 << " "
            << (h.y_lo + (iy + 0.5) * h.bin_m - r.mean_y_m) * 100.0 << " "
            << h.counts[static_cast<size_t>(iy * h.nx + ix)] << "\n";
        }
        o << "\n";
      }
    });
    return Draw(stem, "set title 'Static repeatability: " + std::to_string(r.n) + " fixes, std " +
                          Fixed(r.std_x_m * 100, 2) + " cm x, " + Fixed(r.std_y_m * 100, 2) +
                          " cm y'\nset xlabel 'x - mean (cm)'\nset ylabel 'y - mean (cm)'\n"
                          "set size ratio -1\nset view map\nplot " +
                          Gp(data) + " using 1:2:3 with image notitle\n");
  }

  const std::vector<std::string>& notes() const { return notes_; }
  // The first figure data or script that could not be written, or "".
  const std::string& write_error() const { return write_error_; }

 private:
  template <class Fill>
  std::string WriteData(const std::string& stem, Fill fill) {
    if (!enabled_) return "";
    ::mkdir((dir_ + "/data").c_str(), 0755);
    const std::string path = dir_ + "/data/" + stem + ".dat";
    std::ostringstream o;
    fill(o);
    Write(path, o.str());
    return path;
  }

  std::string Draw(const std::string& stem, const std::string& body) {
    if (!enabled_) return "";
    const std::string png = stem + ".png";
    const std::string script = dir_ + "/data/" + stem + ".gp";
    if (!Write(script, "set terminal pngcairo size 900,600 noenhanced\nset output " +
                           Gp(dir_ + "/" + png) + "\nset grid\n" + body)) {
      return "";
    }
    std::string error;
    if (!RunGnuplot(script, &error)) {
      notes_.push_back(png + ": " + error);
      return "";
    }
    return png;
  }

  // Keeps the first failed write for write_error(); false on failure.
  bool Write(const std::string& path, const std::string& text) {
    std::string error;
    if (WriteText(path, text, &error)) return true;
    if (write_error_.empty()) write_error_ = error;
    return false;
  }

  std::string dir_;
  bool enabled_;
  std::vector<std::string> notes_;
  std::string write_error_;
};

std::string DefaultOutDir(const std::string& log) {
  std::string base = log;
  if (base.size() > 4 && base.compare(base.size() - 4, 4, ".lcm") == 0) {
    base.resize(base.size() - 4);
  }
  return base + "_analysis";
}

// The flags that depend on nothing else, checked by hand (their ranges are
// part of the messages users see); false after saying why.
bool CheckOptions(const AnalyzeOptions& options) {
  const std::pair<const char*, bool> checks[] = {
      {"--frame-rate must be in (0, 10000] fps",
       options.frame_rate_hz > 0.0 && options.frame_rate_hz <= 10000.0},
      {"--tolerance must be in (0, 10] m",
       options.tolerance_m > 0.0 && options.tolerance_m <= 10.0},
      {"--static-extent must be in (0, 100] m",
       options.static_extent_m > 0.0 && options.static_extent_m <= 100.0},
      {"--max-gap must be in (0, 86400] s",
       options.max_gap_s > 0.0 && options.max_gap_s <= 86400.0}};
  for (const auto& [message, ok] : checks) {
    if (!ok) {
      std::cerr << "roomfix analyze: " << message << "\n";
      return false;
    }
  }
  return true;
}

// Reads the logs, with a progress bar on a terminal only: logs of hours
// take seconds to read.
PoseLogs ReadLogsWithProgress(const std::vector<std::string>& paths) {
  const bool show_progress = ::isatty(2) != 0;
  int last_percent = -1;
  return ReadPoseLogs(paths, [&](double fraction) {
    const int percent = static_cast<int>(fraction * 100);
    if (!show_progress || percent == last_percent) return;
    last_percent = percent;
    fmt::print(stderr, "\rreading {} log(s) [{:<40}] {:>3}%", paths.size(),
               std::string(static_cast<size_t>(percent * 40 / 100), '#'), percent);
    if (percent == 100) fmt::print(stderr, "\n");
  });
}

// Which site each log was recorded in (or --config): said on stderr, in
// the summary and the report; two logs of different sites are a warning.
// The poses themselves need no site, so a log without SITE is a note.
// False when the tool must stop (a bad --config).
bool ResolveLogSites(const AnalyzeOptions& options, const PoseLogs& logs,
                     std::vector<ToolSite>* sites) {
  for (const LogReadReport& r : logs.logs) {
    sites->push_back(r.error.empty() ? ResolveToolSite(options.config_path, r.path) : ToolSite{});
    if (!r.error.empty()) continue;
    if (!ReportToolSite("roomfix analyze", sites->back(), /*required=*/false)) return false;
  }
  if (!options.config_path.empty()) return true;
  size_t first = sites->size();
  for (size_t i = 0; i < sites->size(); ++i) {
    if (!(*sites)[i].known) continue;
    if (first == sites->size()) {
      first = i;
      continue;
    }
    const std::string mismatch =
        SiteMismatchWarning((*sites)[first].site, "the site of " + logs.logs[first].path,
                            (*sites)[i].site, "the site of " + logs.logs[i].path);
    if (mismatch.empty()) continue;
    std::cerr << "roomfix analyze: warning: logs of different sites: " << mismatch << "\n";
    (*sites)[i].warnings.push_back("logs of different sites: " + mismatch);
  }
  return true;
}

// The summary's "logs": each log's state and site.
json LogsJson(const PoseLogs& logs, const std::vector<ToolSite>& sites) {
  json out = json::array();
  for (size_t i = 0; i < logs.logs.size(); ++i) {
    const LogReadReport& r = logs.logs[i];
    json j = {{"path", r.path}};
    const ToolSite& site = sites[i];
    if (site.known) {
      j["site"] = {
          {"name", site.site.site.name},
          {"content_hash", site.site.content_hash},
          {"source", site.source},
          {"roomfix_version", site.site.roomfix_version},
          {"publisher",
           site.site.process.empty() ? std::string() : site.site.process + "@" + site.site.host}};
    } else if (r.error.empty()) {
      j["site"] = {{"error", site.error}};
    }
    if (!site.warnings.empty()) j["site_warnings"] = site.warnings;
    if (!r.error.empty()) {
      j["error"] = r.error;
    } else {
      j["events"] = r.events;
      j["pose_events"] = r.pose_events;
      j["undecodable"] = r.undecodable;
      j["refused"] = r.refused;
      j["damaged"] = r.damaged;
      j["bytes_skipped"] = r.bytes_skipped;
      if (r.damaged) j["damage"] = r.damage;
      j["bytes_read"] = r.bytes_read;
      j["file_size"] = r.file_size;
    }
    out.push_back(j);
  }
  return out;
}

// The report's head: a table of the logs, then the site of each.
void WriteReportHead(const PoseLogs& logs, const std::vector<ToolSite>& sites, std::ostream& md) {
  md << "# roomfix analysis\n\n| log | events | poses | state |\n|---|---|---|---|\n";
  for (const LogReadReport& r : logs.logs) {
    md << "| `" << r.path << "` | " << r.events << " | " << r.pose_events << " | ";
    if (!r.error.empty()) {
      md << "unreadable: " << r.error;
    } else if (r.damaged) {
      md << "damaged: " << r.damage;
    } else {
      md << "complete";
    }
    md << " |\n";
  }
  md << "\n";
  for (size_t i = 0; i < logs.logs.size(); ++i) {
    if (!logs.logs[i].error.empty()) continue;
    md << "- `" << logs.logs[i].path
       << "`: " << (sites[i].known ? sites[i].line : "site unknown: " + sites[i].error) << "\n";
    for (const auto& w : sites[i].warnings) md << "  - warning: " << w << "\n";
  }
  if (logs.tracks.empty()) md << "\nNo pose2d_t on any POSE_* channel.\n";
}

// What the figures of one source are computed against: the options, the
// robot's reference tracks, and where the report and the figures go.
struct SourceContext {
  const AnalyzeOptions& options;
  int64_t max_gap_us;
  int robot_id;
  const PoseTrack* truth;
  const PoseTrack* camera;
  Figures* figures;
  std::ostream& md;
  std::string* quality_table;
};

// Fix rate and intervals, and the latencies of a source that is not the
// ground truth.
analysis::Timing TimingFigures(const PoseTrack& t, const SourceContext& c, json* j) {
  std::vector<int64_t> utimes;
  std::vector<double> publish_ms;
  std::vector<double> arrival_ms;
  for (const PoseSample& s : t.samples) {
    utimes.push_back(s.utime);
    publish_ms.push_back(s.latency_us * 1e-3);
    // In double: a garbage utime must not overflow the subtraction.
    arrival_ms.push_back((static_cast<double>(s.recv_utime) - static_cast<double>(s.utime)) * 1e-3);
  }
  const analysis::Timing timing = analysis::ComputeTiming(utimes, c.options.frame_rate_hz);
  (*j)["timing"] = {{"intervals", timing.intervals},
                    {"rate_hz", timing.rate_hz},
                    {"mean_ms", timing.mean_ms},
                    {"std_ms", timing.std_ms},
                    {"median_ms", timing.median_ms},
                    {"min_ms", timing.min_ms},
                    {"max_ms", timing.max_ms},
                    {"frame_period_ms", timing.frame_period_ms},
                    {"interval_ms", HistogramJson(timing.interval_ms)},
                    {"interval_frames", HistogramJson(timing.interval_frames)}};
  c.md << "| rate | " << Fixed(timing.rate_hz, 2) << " Hz |\n| interval mean, std | "
       << Fixed(timing.mean_ms, 1) << " ms, " << Fixed(timing.std_ms, 1)
       << " ms (reference camera: 236 ms, 22.9 ms) |\n";
  if (t.source != "ground_truth") {
    const analysis::LatencySummary publish = analysis::SummariseLatency(publish_ms);
    const analysis::LatencySummary arrival = analysis::SummariseLatency(arrival_ms);
    (*j)["latency_publish_ms"] = LatencyJson(publish);
    (*j)["latency_arrival_ms"] = LatencyJson(arrival);
    c.md << "| latency to publish, median (p95) | " << Fixed(publish.median_ms, 1) << " ("
         << Fixed(publish.p95_ms, 1) << ") ms |\n| latency to the logger, median (p95) | "
         << Fixed(arrival.median_ms, 1) << " (" << Fixed(arrival.p95_ms, 1) << ") ms |\n";
  }
  return timing;
}

// A static track's repeatability; returns its figure's file name.
std::string StaticFigures(const std::vector<analysis::TimedPosition>& positions,
                          const std::string& stem, const SourceContext& c, json* j) {
  const analysis::Repeatability r =
      analysis::ComputeRepeatability(positions, c.options.tolerance_m);
  (*j)["repeatability"] = {{"n", r.n},
                           {"mean_x_m", r.mean_x_m},
                           {"mean_y_m", r.mean_y_m},
                           {"std_x_m", r.std_x_m},
                           {"std_y_m", r.std_y_m},
                           {"tolerance_m", r.tolerance_m},
                           {"share_outside", r.share_outside},
                           {"max_deviation_m", r.max_deviation_m},
                           {"histogram",
                            {{"x_lo", r.histogram.x_lo},
                             {"y_lo", r.histogram.y_lo},
                             {"bin_m", r.histogram.bin_m},
                             {"nx", r.histogram.nx},
                             {"ny", r.histogram.ny},
                             {"counts", r.histogram.counts},
                             {"outside", r.histogram.outside}}}};
  c.md << "| static: mean | (" << Fixed(r.mean_x_m, 4) << ", " << Fixed(r.mean_y_m, 4)
       << ") m |\n| static: std x, y | " << Fixed(r.std_x_m * 100, 3) << " cm, "
       << Fixed(r.std_y_m * 100, 3) << " cm (reference: 0.38 cm, 0.49 cm) |\n"
       << "| static: outside +-" << Fixed(r.tolerance_m * 100, 1) << " cm | "
       << Fixed(r.share_outside * 100, 2) << "% |\n";
  return c.figures->Static("static_" + stem, r);
}

// A moving track's two circle fits (a: drifting centre, b: circular motion).
json CircleFigures(const std::vector<analysis::TimedPosition>& positions, std::ostream& md) {
  std::vector<analysis::TimedPoint> points;
  for (const auto& p : positions) {
    points.push_back(
        {(static_cast<double>(p.utime) - static_cast<double>(positions.front().utime)) * 1e-6,
         p.x_m, p.y_m});
  }
  const analysis::DriftingCircleFit a = analysis::FitDriftingCircle(points);
  const analysis::CircularMotionFit b = analysis::FitCircularMotion(points);
  json circle = json::object();
  if (a.usable) {
    circle["drifting_centre"] = CircleJson(a);
    circle["drifting_centre"]["residual_std_m"] = a.residual_std_m;
    md << "| circle (a): r, centre, drift | " << Fixed(a.radius_m * 100, 2) << " cm, ("
       << Fixed(a.cx_m * 100, 1) << ", " << Fixed(a.cy_m * 100, 1) << ") cm, ("
       << Fixed(a.vx_mps * 1e3, 3) << ", " << Fixed(a.vy_mps * 1e3, 3) << ") mm/s, residual std "
       << Fixed(a.residual_std_m * 100, 3)
       << " cm (reference: 41.9 cm, (191.1, 149.6) cm, (0.264, -0.096) mm/s, 0.633 cm) |\n";
  } else {
    circle["drifting_centre"] = {{"error", a.message}};
  }
  if (b.usable) {
    circle["circular_motion"] = CircleJson(b);
    circle["circular_motion"]["angular_speed_radps"] = b.angular_speed_radps;
    circle["circular_motion"]["angular_speed_sigma_radps"] = b.angular_speed_sigma_radps;
    circle["circular_motion"]["phase_rad"] = b.phase_rad;
    circle["circular_motion"]["phase_sigma_rad"] = b.phase_sigma_rad;
    circle["circular_motion"]["mean_error_m"] = b.mean_error_m;
    circle["circular_motion"]["std_error_m"] = b.std_error_m;
    md << "| circle (b): w, phase, error mean (std) | " << Fixed(b.angular_speed_radps, 4)
       << " rad/s, " << Fixed(b.phase_rad, 3) << " rad, " << Fixed(b.mean_error_m * 100, 2) << " ("
       << Fixed(b.std_error_m * 100, 2)
       << ") cm (reference: -0.439 rad/s, 3.163 rad, 2.8 (1.8) cm) |\n";
  } else {
    circle["circular_motion"] = {{"error", b.message}};
  }
  return circle;
}

// A source against the references: the error against ground truth, the
// fix quality, and ultrasound against the camera. Adds figures' names to
// `pictures`.
void ReferenceFigures(const PoseTrack& t, const std::vector<analysis::TimedPosition>& positions,
                      const std::string& stem, const SourceContext& c, json* j,
                      std::vector<std::string>* pictures) {
  if (c.truth != nullptr && &t != c.truth) {
    const std::vector<analysis::TimedPosition> reference = c.truth->Positions();
    const analysis::ErrorSummary e =
        analysis::CompareToReference(positions, reference, c.max_gap_us);
    (*j)["ground_truth_error"] = ErrorJson(e);
    c.md << "| error vs ground truth: RMSE, p95, max | " << Fixed(e.rmse_m * 100, 2) << ", "
         << Fixed(e.p95_m * 100, 2) << ", " << Fixed(e.max_m * 100, 2) << " cm |\n";
    pictures->push_back(c.figures->ErrorOverTime(
        "error_" + stem, analysis::ErrorsOverTime(positions, reference, c.max_gap_us)));
  }
  if (&t != c.truth) {
    (*j)["quality"] = FixQualityFigures(t, c.truth, c.max_gap_us, c.md, c.quality_table);
  }
  if (c.camera != nullptr && t.source == "ultrasound") {
    const analysis::TrackOffset o =
        analysis::CompareTracks(positions, c.camera->Positions(), c.max_gap_us);
    (*j)["vs_camera"] = {
        {"matched", o.matched},     {"mean_dx_m", o.mean_dx_m},
        {"mean_dy_m", o.mean_dy_m}, {"std_dx_m", o.std_dx_m},
        {"std_dy_m", o.std_dy_m},   {"error_after_offset", ErrorJson(o.error_after_offset)}};
    c.md << "| vs camera: offset (dx, dy) | (" << Fixed(o.mean_dx_m * 100, 2) << ", "
         << Fixed(o.mean_dy_m * 100, 2) << ") cm over " << o.matched
         << " fixes |\n| vs camera: RMSE once the offset is removed | "
         << Fixed(o.error_after_offset.rmse_m * 100, 2) << " cm |\n";
  }
}

// Every figure of one source of one robot: its section of the report and
// its JSON.
json SourceFigures(const PoseTrack& t, const SourceContext& c) {
  const std::vector<analysis::TimedPosition> positions = t.Positions();
  int degraded = 0;
  for (const PoseSample& s : t.samples) degraded += s.degraded ? 1 : 0;
  const std::string stem = t.source + "_robot" + std::to_string(c.robot_id);
  json j = {{"fixes", t.samples.size()}, {"lost", t.lost}, {"degraded", degraded}};
  c.md << "### " << t.source << "\n\n| figure | value |\n|---|---|\n";
  c.md << "| fixes (lost, degraded) | " << t.samples.size() << " (" << t.lost << ", " << degraded
       << ") |\n";
  const analysis::Timing timing = TimingFigures(t, c, &j);
  const analysis::Motion motion = analysis::ComputeMotion(positions);
  j["motion"] = {{"distance_m", motion.distance_m},
                 {"duration_s", motion.duration_s},
                 {"mean_speed_mps", motion.mean_speed_mps},
                 {"std_speed_mps", motion.std_speed_mps},
                 {"max_speed_mps", motion.max_speed_mps}};
  c.md << "| distance, speed mean (std) | " << Fixed(motion.distance_m, 3) << " m, "
       << Fixed(motion.mean_speed_mps * 100, 2) << " (" << Fixed(motion.std_speed_mps * 100, 2)
       << ") cm/s |\n";

  const bool is_static = analysis::LooksStatic(positions, c.options.static_extent_m);
  j["static"] = is_static;
  std::vector<std::string> pictures;
  if (is_static) {
    pictures.push_back(StaticFigures(positions, stem, c, &j));
  } else if (positions.size() >= 10) {
    j["circle"] = CircleFigures(positions, c.md);
  }
  ReferenceFigures(t, positions, stem, c, &j, &pictures);
  if (timing.intervals > 0) {
    pictures.push_back(c.figures->Intervals("intervals_" + stem, timing));
  }
  c.md << "\n";
  for (const std::string& p : pictures) {
    if (!p.empty()) c.md << "![" << p << "](" << p << ")\n";
  }
  c.md << "\n";
  return j;
}

// Every robot's section of the report (its trajectory, then each source),
// the summary's "robots" in return; each source's quality row is added to
// `quality_table`.
json RobotFigures(const AnalyzeOptions& options, const PoseLogs& logs,
                  const std::vector<ToolSite>& sites, Figures* figures, std::ostream& md,
                  std::string* quality_table) {
  std::map<int, std::vector<const PoseTrack*>> by_robot;
  for (const auto& [key, track] : logs.tracks) by_robot[key.second].push_back(&track);
  const Site* known_site = nullptr;
  for (const ToolSite& site : sites) {
    if (site.known && known_site == nullptr) known_site = &site.site.site;
  }
  json robots = json::object();
  for (const auto& [robot_id, tracks] : by_robot) {
    md << "\n## Robot " << robot_id << "\n\n";
    const std::string trajectory = figures->Trajectory(robot_id, tracks, known_site);
    if (!trajectory.empty()) md << "![trajectory](" << trajectory << ")\n\n";
    SourceContext context{options,  static_cast<int64_t>(options.max_gap_s * 1e6),
                          robot_id, nullptr,
                          nullptr,  figures,
                          md,       quality_table};
    for (const PoseTrack* t : tracks) {
      if (t->source == "ground_truth") context.truth = t;
      if (t->source == "camera") context.camera = t;
    }
    json robot = json::object();
    for (const PoseTrack* t : tracks) robot[t->source] = SourceFigures(*t, context);
    robots[std::to_string(robot_id)] = robot;
  }
  return robots;
}

// The per-source summary of the first robot, the shape `make demo` prints.
json SourcesSummary(const json& robots) {
  json sources = json::object();
  if (robots.empty()) return sources;
  for (const auto& [source, j] : robots.begin()->items()) {
    if (source == "ground_truth") continue;
    json s = {{"rate_hz", j["timing"]["rate_hz"]}};
    if (j.contains("ground_truth_error")) {
      s["rmse_m"] = j["ground_truth_error"]["rmse_m"];
      s["p95_m"] = j["ground_truth_error"]["p95_m"];
    }
    if (j.contains("latency_publish_ms")) {
      s["latency_ms_median"] = j["latency_publish_ms"]["median_ms"];
    }
    if (j.contains("quality")) s["quality"] = j["quality"];
    sources[source] = s;
  }
  return sources;
}

// Standard output: the summary as JSON, or where the report is, the
// quality table and the logs that could not be read in full.
void PrintResult(const AnalyzeOptions& options, const PoseLogs& logs, const std::string& out_dir,
                 const json& out, const std::string& quality_table) {
  if (options.json) {
    std::cout << out.dump() << "\n";
    return;
  }
  std::cout << "report: " << out_dir << "/report.md\nsummary: " << out_dir << "/summary.json\n";
  if (!quality_table.empty()) {
    // Whether each source can be trusted: status shares, accuracy with
    // the worst fix flagged ok, and the share of errors inside the fix's
    // own 95 % ellipse (calibrated: 95 %, median squared Mahalanobis 1.39).
    std::cout << fmt::format(kQualityHeader, "source", "robot", "fixes", "ok%", "degr%", "lost%",
                             "rmse_cm", "p99_cm", "max_cm", "worst_ok", "in95%", "med_d2")
              << quality_table;
  }
  for (const LogReadReport& r : logs.logs) {
    if (!r.error.empty()) std::cout << "unreadable: " << r.error << "\n";
    if (r.damaged) std::cout << r.path << ": damaged, " << r.damage << "\n";
  }
}

// parse (CLI11, CheckOptions) -> load (the logs and their sites) ->
// compute (the figures, into the report) -> report (files and stdout).
int RunAnalyze(const AnalyzeOptions& options) {
  if (!CheckOptions(options)) return 1;
  const std::string out_dir =
      options.out_dir.empty() ? DefaultOutDir(options.logs[0]) : options.out_dir;
  if (::mkdir(out_dir.c_str(), 0755) != 0 && errno != EEXIST) {
    std::cerr << "roomfix analyze: cannot make " << out_dir << ": " << std::strerror(errno) << "\n";
    return 1;
  }
  const PoseLogs logs = ReadLogsWithProgress(options.logs);
  std::vector<ToolSite> sites;
  if (!ResolveLogSites(options, logs, &sites)) return 1;
  json out;
  out["logs"] = LogsJson(logs, sites);
  for (const LogReadReport& r : logs.logs) {
    if (r.damaged) std::cerr << "roomfix analyze: warning: " << r.path << ": " << r.damage << "\n";
  }
  const bool all_unreadable = std::all_of(logs.logs.begin(), logs.logs.end(),
                                          [](const LogReadReport& r) { return !r.error.empty(); });
  if (all_unreadable) {
    for (const LogReadReport& r : logs.logs) std::cerr << "roomfix analyze: " << r.error << "\n";
    return 1;
  }

  Figures figures(out_dir, options.figures);
  std::ostringstream md;
  WriteReportHead(logs, sites, md);
  std::string quality_table;
  out["robots"] = RobotFigures(options, logs, sites, &figures, md, &quality_table);
  for (const std::string& note : figures.notes()) md << "\nFigure not drawn: " << note << "\n";
  out["sources"] = SourcesSummary(out["robots"]);
  out["report"] = out_dir + "/report.md";
  std::string write_error = figures.write_error();
  if (!write_error.empty() || !WriteText(out_dir + "/report.md", md.str(), &write_error) ||
      !WriteText(out_dir + "/summary.json", out.dump(2) + "\n", &write_error)) {
    std::cerr << "roomfix analyze: " << write_error << "\n";
    return 1;
  }
  for (const LogReadReport& r : logs.logs) {
    if (r.undecodable > 0) {
      std::cerr << "roomfix analyze: warning: " << r.path << ": " << r.undecodable
                << " POSE_* events refused (" << RefusalCounts(r.refused) << ")\n";
    }
  }
  PrintResult(options, logs, out_dir, out, quality_table);
  return 0;
}

}  // namespace

void AddAnalyzeCommand(CLI::App* app, int* exit_code) {
  auto options = std::make_shared<AnalyzeOptions>();
  auto* cmd = app->add_subcommand(
      "analyze",
      "The reference paper's measurements from logs (written by roomfix_logger or lcm-logger): "
      "static repeatability, timing, circle fits, motion, error against ground truth, camera "
      "against ultrasound; a Markdown report with PNG figures");
  cmd->add_option("LOG", options->logs, "LCM logs, analysed together")->required();
  cmd->add_option("--config", options->config_path,
                  "Site file to report against (default: the site each log carries on SITE); "
                  "where the log's differs, a warning names the keys");
  cmd->add_option("--out", options->out_dir,
                  "Output folder (default: LOG without .lcm + _analysis)");
  cmd->add_flag("--json", options->json, "Print the summary as one JSON object on stdout");
  cmd->add_flag("!--no-figures", options->figures, "Skip the PNG figures (no gnuplot needed)");
  cmd->add_option("--frame-rate", options->frame_rate_hz,
                  "Camera frame rate for the interval histogram in frames")
      ->capture_default_str();
  cmd->add_option("--tolerance", options->tolerance_m,
                  "Static repeatability: the share of fixes outside +- this, m")
      ->capture_default_str();
  cmd->add_option("--static-extent", options->static_extent_m,
                  "A track is static when 90% of its fixes lie within this of its median, m")
      ->capture_default_str();
  cmd->add_option("--max-gap", options->max_gap_s,
                  "No comparison where the reference track has a gap longer than this, s")
      ->capture_default_str();
  cmd->callback([options, exit_code] { *exit_code = RunAnalyze(*options); });
}

}  // namespace roomfix
