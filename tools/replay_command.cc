// roomfix replay: re-runs trilat_proc's, fusion_proc's (and camera_proc's,
// from recorded MARKER_PIXELS) nodes over a
// recorded log, on the log's time and as fast as the machine allows, and
// writes a new log (docs/replay.md).
#include <fmt/format.h>

#include <CLI/CLI.hpp>
#include <chrono>
#include <cstdio>
#include <iostream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "core/world/site.h"
#include "fusion_proc/fusion_flags.h"
#include "tools/commands.h"
#include "tools/replay.h"
#include "trilat_proc/trilat_options.h"

namespace roomfix {
namespace {

struct ReplayCommandOptions {
  std::string log_path;
  std::string out_path;
  std::string nodes = "trilat,fusion";
  // --site: a new site, whose receivers re-derive the recorded ranges.
  // --config: the site the log was recorded in, used as it is.
  std::string site_path;
  std::string config_path;
  // trilat_proc's flags under their own names (--method, --no-prior ...),
  // fusion_proc's prefixed with "fusion-" (both have --forget-after).
  // --method defaults to robust, which every shipped configuration runs.
  TrilatNodeOptions trilat_options;
  TrilatOptions trilat_flags{"robust"};
  FusionNodeOptions fusion_options;
  bool force = false;
  bool json = false;
};

// "trilat,fusion" into the options; false with the reason for anything else.
bool ParseNodes(const std::string& list, PipelineReplayOptions* options, std::string* error) {
  options->trilat = options->fusion = false;
  std::stringstream stream(list);
  std::string node;
  while (std::getline(stream, node, ',')) {
    if (node == "trilat") {
      options->trilat = true;
    } else if (node == "fusion") {
      options->fusion = true;
    } else if (node == "camera") {
      options->camera = true;
    } else {
      *error = "--nodes: unknown node '" + node + "' (trilat, fusion, camera)";
      return false;
    }
  }
  if (!options->trilat && !options->fusion && !options->camera) {
    *error = "--nodes: name at least one of trilat, fusion, camera";
    return false;
  }
  return true;
}

std::string Counts(const std::map<std::string, int64_t>& counts) {
  std::string out;
  for (const auto& [name, n] : counts) {
    out += (out.empty() ? "" : ", ") + name + " " + std::to_string(n);
  }
  return out.empty() ? "none" : out;
}

std::string StatusLine(const process_status_t& s) {
  std::string out = "inputs " + std::to_string(s.inputs) + ", outputs " + std::to_string(s.outputs);
  for (const counter_t& c : s.rejected)
    out += ", rejected " + c.name + " " + std::to_string(c.count);
  return out;
}

nlohmann::json StatusJson(const process_status_t& s) {
  nlohmann::json j = {{"inputs", s.inputs}, {"outputs", s.outputs}};
  for (const counter_t& c : s.rejected) j["rejected"][c.name] = c.count;
  for (const counter_t& c : s.counters) j["counters"][c.name] = c.count;
  return j;
}

// The nodes, their options and the site of the replay, from the flags and
// the log; says on stderr which site is used. False with the reason.
bool PrepareReplay(const ReplayCommandOptions& args, PipelineReplayOptions* options,
                   ReplaySite* replay_site, std::string* error) {
  if (!ParseNodes(args.nodes, options, error)) return false;
  options->trilat_options = args.trilat_options;
  options->fusion_options = args.fusion_options;
  if (!ApplyTrilatFlags(args.trilat_flags, &options->trilat_options, error)) return false;
  if (!ResolveReplaySite(args.log_path, args.config_path, args.site_path, replay_site, error)) {
    return false;
  }
  std::cerr << "roomfix replay: " << replay_site->used_line << "\n";
  for (const std::string& line : replay_site->warnings) {
    std::cerr << "roomfix replay: warning: " << line << "\n";
  }
  for (const std::string& line : replay_site->notes) {
    std::cerr << "roomfix replay: " << line << "\n";
  }
  if (options->camera) {
    // camera_proc's node starts from the detector's output: without it there
    // is nothing to track (logs never hold the full frames).
    bool holds = false;
    if (!LogHoldsChannel(args.log_path, kMarkerPixelsChannel, &holds, error)) return false;
    if (!holds) {
      *error = "--nodes camera: " + args.log_path +
               " holds no MARKER_PIXELS (the camera's detections), so camera_proc's node has "
               "no input; record MARKER_PIXELS too, or replay trilat,fusion and keep the "
               "recorded POSE_CAMERA";
      return false;
    }
    if (!ReplayCameraCalibrations(replay_site->loaded, &options->camera_calibrations, error)) {
      *error = "--nodes camera: " + *error;
      return false;
    }
  }
  // The point of a new site is new receiver positions and offsets: the
  // recorded ranges are re-derived from it. The recorded site is used as
  // is, so the ranges are exactly the recorded ones.
  options->restamp_ranges = replay_site->is_new;
  // A site from a file travels in the new log in place of the recorded one.
  if (replay_site->from_file) {
    site_t msg{};
    std::string site_error;
    if (!MakeReplaySiteMessage(replay_site->loaded, &msg, &site_error)) {
      std::cerr << "roomfix replay: warning: the new log carries no SITE: " << site_error << "\n";
    } else {
      options->site_message = msg;
    }
  }
  return true;
}

// How long the replay took against the log's span.
struct ReplayTiming {
  double span_s = 0.0;
  double wall_s = 0.0;
  double speedup = 0.0;
};

void PrintSummaryJson(const ReplayCommandOptions& args, const std::string& site_line,
                      const PipelineReplayOptions& options, const PipelineReplaySummary& s,
                      const ReplayTiming& t) {
  nlohmann::json j = {{"log", args.log_path},
                      {"out", args.out_path},
                      {"site", site_line},
                      {"ranges_rederived", options.restamp_ranges},
                      {"nodes", args.nodes},
                      {"events_read", s.events_read},
                      {"inputs_written", s.inputs_written},
                      {"inputs_not_loggable", s.inputs_not_loggable},
                      {"old_outputs_dropped", s.old_outputs_dropped},
                      {"new_outputs", s.new_outputs},
                      {"ranges_restamped", s.ranges_restamped},
                      {"ranges_kept", s.ranges_kept},
                      {"ranges_unknown_receiver", s.ranges_unknown_receiver},
                      {"ticks", s.ticks},
                      {"ticks_skipped", s.ticks_skipped},
                      {"events_time_refused", s.events_time_refused},
                      {"heartbeats_thinned", s.heartbeats_thinned},
                      {"refused", s.refused},
                      {"log_span_s", t.span_s},
                      {"wall_s", t.wall_s},
                      {"times_real_time", t.speedup},
                      {"damaged", s.damaged},
                      {"bytes_skipped", s.bytes_skipped},
                      {"damage_regions", s.damage_regions},
                      {"damage", s.damage}};
  if (options.trilat) j["trilat_proc"] = StatusJson(s.trilat_status);
  if (options.fusion) j["fusion_proc"] = StatusJson(s.fusion_status);
  for (const process_status_t& c : s.camera_status) j["camera_proc"].push_back(StatusJson(c));
  fmt::print("{}\n", j.dump(2));
}

void PrintSummaryText(const ReplayCommandOptions& args, const std::string& site_line,
                      const PipelineReplayOptions& options, const PipelineReplaySummary& s,
                      const ReplayTiming& t) {
  fmt::print("{} -> {}: {} events, {:.2f} s of log, {}\n", args.log_path, args.out_path,
             s.events_read, t.span_s, site_line);
  fmt::print("  copied:   {} recorded events ({} ranges re-derived from the site)\n",
             s.inputs_written, s.ranges_restamped);
  fmt::print("  replaced: {}\n", Counts(s.old_outputs_dropped));
  fmt::print("  new:      {}\n", Counts(s.new_outputs));
  if (options.trilat) fmt::print("  trilat:   {}\n", StatusLine(s.trilat_status));
  if (options.fusion) fmt::print("  fusion:   {}\n", StatusLine(s.fusion_status));
  for (const process_status_t& c : s.camera_status) {
    fmt::print("  camera:   {}\n", StatusLine(c));
  }
  fmt::print("  ticks:    {} run, {} skipped in gaps over {:.0f} s\n", s.ticks, s.ticks_skipped,
             kMaxCatchUpUs * 1e-6);
  if (s.heartbeats_thinned > 0) {
    fmt::print("  heartbeats: {} not written (a sparse log)\n", s.heartbeats_thinned);
  }
  fmt::print("  ran in {:.3f} s: {:.0f}x real time\n", t.wall_s, t.speedup);
}

// What of the recorded log was refused or left out.
void WarnAboutInput(const std::string& log_path, const PipelineReplaySummary& s) {
  if (!s.refused.empty()) {
    std::cerr << "roomfix replay: warning: " << log_path
              << ": recorded messages refused before decoding: " << Counts(s.refused) << "\n";
  }
  if (s.events_time_refused > 0) {
    std::cerr << "roomfix replay: warning: " << log_path << ": " << s.events_time_refused
              << " events whose time is more than " << kMaxEventTimeOffsetUs * 1e-6
              << " s from their neighbours' refused (events_time_refused)\n";
  }
  if (s.inputs_not_loggable > 0) {
    std::cerr << "roomfix replay: warning: " << log_path << ": " << s.inputs_not_loggable
              << " events on channels LCM cannot replay left out\n";
  }
  if (s.damaged) {
    std::cerr << "roomfix replay: warning: " << log_path << ": " << s.damage
              << "; every readable event was replayed\n";
  }
}

// parse (CLI11, PrepareReplay) -> load and compute (ReplayPipelineFile) ->
// report.
int RunReplayCommand(const ReplayCommandOptions& args) {
  PipelineReplayOptions options;
  ReplaySite replay_site;
  std::string error;
  if (!PrepareReplay(args, &options, &replay_site, &error)) {
    std::cerr << "roomfix replay: " << error << "\n";
    return 1;
  }
  const auto start = std::chrono::steady_clock::now();
  const PipelineReplaySummary s = ReplayPipelineFile(args.log_path, replay_site.loaded.site,
                                                     options, args.out_path, args.force);
  ReplayTiming t;
  t.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (!s.ok) {
    std::cerr << "roomfix replay: " << s.error << "\n";
    return 1;
  }
  t.span_s = (s.last_utime - s.first_utime) * 1e-6;
  t.speedup = t.wall_s > 0 ? t.span_s / t.wall_s : 0.0;
  if (args.json) {
    PrintSummaryJson(args, replay_site.used_line, options, s, t);
  } else {
    PrintSummaryText(args, replay_site.used_line, options, s, t);
  }
  std::fflush(stdout);
  WarnAboutInput(args.log_path, s);
  return 0;
}

}  // namespace

void AddReplayCommand(CLI::App* app, int* exit_code) {
  auto* cmd = app->add_subcommand("replay",
                                  "Re-run trilat_proc's, fusion_proc's and camera_proc's nodes "
                                  "over a log, on its time, as fast as possible, "
                                  "into a new log (docs/replay.md)");
  auto args = std::make_shared<ReplayCommandOptions>();
  cmd->add_option("LOG", args->log_path, "Recorded LCM log (roomfix_logger or lcm-logger)")
      ->required();
  cmd->add_option("--out", args->out_path,
                  "New log: the recorded events with the re-run nodes' outputs replaced")
      ->required();
  cmd->add_option("--nodes", args->nodes,
                  "Nodes to re-run: trilat, fusion, camera (from the log's "
                  "MARKER_PIXELS), comma-separated")
      ->capture_default_str();
  auto* config = cmd->add_option(
      "--config", args->config_path,
      "The site file (YAML) the log was recorded in, used as it is (default: the log's SITE)");
  cmd->add_option("--site", args->site_path,
                  "A new site file (YAML), e.g. with receiver offsets from `roomfix survey`: "
                  "the recorded ranges are re-derived from its receivers")
      ->excludes(config);
  // The live processes' own flags, so a log recorded with non-default
  // settings is re-run with the same ones.
  AddTrilatFlags(cmd, "", &args->trilat_options, &args->trilat_flags);
  AddFusionFlags(cmd, "fusion-", &args->fusion_options);
  cmd->add_flag("--force", args->force, "Replace --out if it exists");
  cmd->add_flag("--json", args->json, "Print the summary as JSON");
  cmd->callback([args, exit_code] { *exit_code = RunReplayCommand(*args); });
}

}  // namespace roomfix
