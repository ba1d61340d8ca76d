// roomfix survey: each receiver's position and range offset (and scale) from
// a log in which a robot drives around with range sets and a reference track
// (camera, ground truth or fused), or from the range sets alone with two
// surveyed receivers pinned. Prints site value, estimate, 1-sigma and change
// per receiver, the held-out trilateration error before and after, and
// writes a site-file fragment. The maths is in core/survey and docs/survey.md.
#include <fmt/format.h>
#include <yaml-cpp/yaml.h>

#include <CLI/CLI.hpp>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "core/survey/receiver_survey.h"
#include "core/world/file_io.h"
#include "core/world/site.h"
#include "msgio/channels.h"
#include "msgio/log.h"
#include "msgio/pose_tracks.h"
#include "msgio/wire_check.h"
#include "roomfix/range_set_t.hpp"
#include "tools/commands.h"
#include "tools/flag_checks.h"
#include "tools/tool_site.h"

namespace roomfix {
namespace {

using nlohmann::json;

// A reference sampled at 30 Hz or more; a longer gap means it was not
// running, and no firing there is aligned.
constexpr int64_t kMaxReferenceGap_us = 200000;

struct SurveyCommandOptions {
  std::string log;
  std::string site;
  std::string reference = "camera";
  int robot = -1;
  bool scale = false;
  bool auto_scale = false;
  bool fix_heights = false;
  bool offsets_only = false;
  bool no_reference = false;
  std::string pin;
  std::string out;
  std::string json_path;
  double block_s = 10.0;
  int period = 3;
};

json Number(double v) { return std::isfinite(v) ? json(v) : json(nullptr); }

json ErrorJson(const survey::TrilaterationError& e) {
  return {{"firings", e.firings},       {"fixes", e.fixes},
          {"rmse_m", Number(e.rmse_m)}, {"median_m", Number(e.median_m)},
          {"p95_m", Number(e.p95_m)},   {"max_m", Number(e.max_m)}};
}

bool ParsePins(const std::string& text, std::vector<int>* ids) {
  std::stringstream s(text);
  std::string item;
  while (std::getline(s, item, ',')) {
    try {
      size_t used = 0;
      ids->push_back(std::stoi(item, &used));
      if (used != item.size()) return false;
    } catch (const std::exception&) {
      return false;
    }
  }
  return !ids->empty();
}

// One receiver as a flow map on one line, in the site file's keys, with its
// range scale (no site-file key) as a comment beside it.
void EmitReceiver(const Receiver& r, const survey::ReceiverEstimate& e, YAML::Emitter* out) {
  *out << YAML::Flow << YAML::BeginMap << YAML::Key << "id" << YAML::Value << r.id;
  *out << YAML::Key << "address" << YAML::Value << YAML::DoubleQuoted
       << FormatRadioAddress(r.address);
  if (r.short_address.has_value()) {
    *out << YAML::Key << "short_address" << YAML::Value
         << fmt::format("0x{:04X}", *r.short_address);
  }
  // Millimetres: the survey's 1-sigma is a few of them, so four decimals in
  // metres say all it knows (written as the scalar's text).
  *out << YAML::Key << "position_m" << YAML::Value << YAML::Flow << YAML::BeginSeq
       << fmt::format("{:.4f}", e.position_m.x()) << fmt::format("{:.4f}", e.position_m.y())
       << fmt::format("{:.4f}", e.position_m.z()) << YAML::EndSeq;
  *out << YAML::Key << "range_offset_m" << YAML::Value << fmt::format("{:.4f}", e.range_offset_m)
       << YAML::EndMap;
  if (e.scale_estimated) {
    *out << YAML::Comment(fmt::format(
        "range scale {:.5f} +- {:.5f} (not a site-file key: correct the speed of sound or "
        "the receiver's clock)",
        e.range_scale, e.range_scale_sigma));
  }
}

// The robot to survey with (--robot, else the first with a beacon) and its
// beacon; false with the reason.
bool FindSurveyBeacon(const Site& site, const SurveyCommandOptions& a, const Robot** robot,
                      const Beacon** beacon, std::string* error) {
  *robot = nullptr;
  for (const Robot& r : site.robots) {
    if ((a.robot < 0 || r.id == a.robot) && r.beacon_id.has_value()) {
      *robot = &r;
      break;
    }
  }
  if (*robot == nullptr) {
    const std::string site_name = a.site.empty() ? "the site of " + a.log : a.site;
    *error = "no robot with a beacon" +
             (a.robot >= 0 ? " and id " + std::to_string(a.robot) : std::string()) + " in " +
             site_name;
    return false;
  }
  *beacon = site.FindBeacon(*(*robot)->beacon_id);
  if (*beacon == nullptr) {
    *error = "robot " + std::to_string((*robot)->id) + "'s beacon is not in the site";
    return false;
  }
  return true;
}

// The range sets of one beacon in a log, by time.
struct BeaconFirings {
  std::vector<survey::Firing> firings;
  int undecodable = 0;
  std::map<std::string, int64_t> refused;  // by reason
  bool damaged = false;
};

// Reads the beacon's RANGES events; false with the reason when the log
// cannot be opened or holds none.
bool ReadFirings(const std::string& log, const Site& site, const Beacon& beacon, BeaconFirings* out,
                 std::string* error) {
  auto reader = LogReader::Open(log, error);
  if (!reader) return false;
  LogEvent event;
  while (reader->Next(&event)) {
    if (event.channel != kRangesChannel) continue;
    range_set_t set;
    std::string reason;
    if (!DecodeChecked(event.data.data(), static_cast<int>(event.data.size()), &set, &reason)) {
      ++out->undecodable;
      ++out->refused[reason];
      continue;
    }
    if (set.beacon_id != beacon.id) continue;
    survey::Firing f;
    f.utime = set.utime;
    f.beacon_height_m = beacon.height_m;
    for (const range_t& r : set.ranges) {
      // The raw range: time of flight times the speed of sound; from the
      // corrected range and the site's offset when the time is missing.
      double raw = r.time_of_flight_us * 1e-6 * set.speed_of_sound_mps;
      if (!(std::isfinite(raw) && raw > 0)) {
        const Receiver* rx = site.FindReceiver(r.receiver_id);
        raw = r.range_m + (rx != nullptr ? rx->range_offset_m : 0.0);
      }
      f.ranges.push_back({r.receiver_id, raw});
    }
    out->firings.push_back(f);
  }
  out->damaged = reader->damaged();
  if (out->damaged) {
    std::cerr << "roomfix survey: warning: " << log << ": " << reader->DamageSummary() << "\n";
  }
  reader.reset();
  if (out->firings.empty()) {
    *error = "no RANGES from beacon " + std::to_string(beacon.id) + " in " + log;
    return false;
  }
  std::sort(out->firings.begin(), out->firings.end(),
            [](const auto& x, const auto& y) { return x.utime < y.utime; });
  return true;
}

// The reference track (--reference) of the robot; empty without one, which
// is an error unless --no-reference.
bool ReadReference(const SurveyCommandOptions& a, int robot_id,
                   std::vector<survey::ReferenceSample>* reference, std::string* error) {
  PoseLogs poses = ReadPoseLogs({a.log});
  auto track = poses.tracks.find({a.reference, robot_id});
  if (track != poses.tracks.end()) {
    for (const PoseSample& s : track->second.samples) {
      if (std::isfinite(s.x_m) && std::isfinite(s.y_m)) {
        reference->push_back({s.utime, s.x_m, s.y_m});
      }
    }
  }
  if (!reference->empty() || a.no_reference) return true;
  std::string have;
  for (const auto& [key, t] : poses.tracks) {
    have += " " + key.first + "/" + std::to_string(key.second);
  }
  *error = "no " + a.reference + " poses of robot " + std::to_string(robot_id) + " in " + a.log +
           " (tracks:" + (have.empty() ? " none" : have) +
           "); use --reference or --no-reference --pin ID,ID";
  return false;
}

// The fit on every firing, and the held-out evaluation of a fit on most
// of them.
struct SurveyFit {
  std::vector<survey::ReceiverModel> site_models;
  std::vector<int> not_heard;
  survey::SurveyResult result;
  bool can_evaluate = false;
  survey::TrilaterationError before, after;
};

bool FitSurvey(const SurveyCommandOptions& a, const std::vector<int>& pins, const Site& site,
               const std::vector<survey::Firing>& firings, bool have_reference, SurveyFit* fit,
               std::string* error) {
  // Only the receivers the beacon was heard by are unknowns: the normal
  // matrix grows with the square of the receivers estimated and its
  // eigen-decomposition with the cube, so a site's receivers that no range
  // names (a site from a log names what its publisher wrote, up to
  // kMaxSiteReceivers of core/world/site_limits.h) cost nothing; they are
  // listed as not heard.
  std::set<int> heard;
  for (const survey::Firing& f : firings) {
    for (const survey::RangeObservation& o : f.ranges) heard.insert(o.receiver_id);
  }
  for (const Receiver& r : site.receivers) {
    if (heard.count(r.id) == 0) {
      fit->not_heard.push_back(r.id);
      continue;
    }
    fit->site_models.push_back(
        {r.id, Eigen::Map<const Eigen::Vector3d>(r.position_m.data()), r.range_offset_m, 1.0});
  }
  survey::SurveyOptions options;
  options.scale = a.scale        ? survey::ScaleMode::kOn
                  : a.auto_scale ? survey::ScaleMode::kAuto
                                 : survey::ScaleMode::kOff;
  options.estimate_heights = !a.fix_heights;
  options.estimate_positions = !a.offsets_only;
  options.pinned_ids = pins;
  auto fit_with = [&](const std::vector<survey::Firing>& data) {
    return a.no_reference ? survey::SurveyWithoutReference(fit->site_models, data, options)
                          : survey::SurveyWithReference(fit->site_models, data, options);
  };
  // Held-out evaluation: fit on most blocks, evaluate on the others.
  std::vector<survey::Firing> fit_part, held_out;
  survey::SplitByTime(firings, a.block_s, a.period, &fit_part, &held_out);
  const survey::SurveyResult split_result = fit_with(fit_part);
  // The fragment: every firing.
  fit->result = fit_with(firings);
  if (!fit->result.usable) {
    *error = fit->result.message;
    return false;
  }
  fit->can_evaluate = have_reference && split_result.usable;
  if (fit->can_evaluate) {
    fit->before = survey::EvaluateTrilateration(fit->site_models, held_out);
    fit->after = survey::EvaluateTrilateration(split_result.Models(), held_out);
  }
  return true;
}

// The table of receivers (site value, estimate, 1-sigma, change); returns
// them as JSON.
json PrintReceivers(const Site& site, const survey::SurveyResult& result) {
  fmt::print(
      "{:>4} {:<9} {:>9} {:>9} {:>9} {:>9}   {:>9} {:>9} {:>9}   {:>7} {:>7} {:>7}   "
      "{:>8} {:>7}\n",
      "id", "", "x_m", "y_m", "z_m", "offset_m", "sigma_x", "sigma_y", "sigma_z", "dx_mm", "dy_mm",
      "dz_mm", "doff_mm", "used");
  json receivers = json::array();
  for (const Receiver& r : site.receivers) {
    const survey::ReceiverEstimate* e = result.Find(r.id);
    if (e == nullptr) continue;
    const Eigen::Vector3d p0 = Eigen::Map<const Eigen::Vector3d>(r.position_m.data());
    const Eigen::Vector3d d = (e->position_m - p0) * 1e3;
    fmt::print("{:4d} {:<9} {:9.4f} {:9.4f} {:9.4f} {:9.4f}\n", r.id, "site", p0.x(), p0.y(),
               p0.z(), r.range_offset_m);
    fmt::print(
        "{:>4} {:<9} {:9.4f} {:9.4f} {:9.4f} {:9.4f}   {:9.4f} {:9.4f} {:9.4f}   {:7.1f} {:7.1f} "
        "{:7.1f}   {:8.1f} {:7d}\n",
        "", e->pinned ? "pinned" : "estimate", e->position_m.x(), e->position_m.y(),
        e->position_m.z(), e->range_offset_m, e->position_sigma_m.x(), e->position_sigma_m.y(),
        e->position_sigma_m.z(), d.x(), d.y(), d.z(), (e->range_offset_m - r.range_offset_m) * 1e3,
        e->ranges_used);
    if (e->scale_estimated) {
      fmt::print("{:>4} {:<9} scale {:.5f} +- {:.5f}\n", "", "", e->range_scale,
                 e->range_scale_sigma);
    }
    receivers.push_back(
        {{"id", r.id},
         {"site_position_m", {p0.x(), p0.y(), p0.z()}},
         {"site_range_offset_m", r.range_offset_m},
         {"position_m", {e->position_m.x(), e->position_m.y(), e->position_m.z()}},
         {"position_sigma_m",
          {e->position_sigma_m.x(), e->position_sigma_m.y(), e->position_sigma_m.z()}},
         {"range_offset_m", e->range_offset_m},
         {"range_offset_sigma_m", e->range_offset_sigma_m},
         {"range_scale", e->range_scale},
         {"range_scale_sigma", e->range_scale_sigma},
         {"scale_estimated", e->scale_estimated},
         {"pinned", e->pinned},
         {"ranges_used", e->ranges_used},
         {"ranges_rejected", e->ranges_rejected}});
  }
  fmt::print("\n");
  return receivers;
}

// The notes and the held-out trilateration error before and after.
void PrintEvaluation(const SurveyCommandOptions& a, int beacon_id, const SurveyFit& fit) {
  if (!fit.not_heard.empty()) {
    std::string ids;
    for (size_t i = 0; i < fit.not_heard.size() && i < 16; ++i) {
      ids += (i ? ", " : "") + std::to_string(fit.not_heard[i]);
    }
    if (fit.not_heard.size() > 16) ids += ", ...";
    fmt::print("note: {} receivers of the site never heard from beacon {}, not surveyed ({})\n",
               fit.not_heard.size(), beacon_id, ids);
  }
  for (const auto& n : fit.result.notes) fmt::print("note: {}\n", n);
  if (!fit.can_evaluate) {
    fmt::print("\nno reference track: the held-out error against a reference is not available\n");
    return;
  }
  fmt::print(
      "\nheld-out trilateration error (one {:.0f} s block in {}, {} firings; fitted on the "
      "others):\n",
      a.block_s, a.period, fit.before.firings);
  for (const auto& [label, e] : {std::pair{"before (site file):", &fit.before},
                                 std::pair{"after  (surveyed): ", &fit.after}}) {
    fmt::print("  {} RMSE {:.4f} m, median {:.4f}, p95 {:.4f}, max {:.4f} ({} fixes)\n", label,
               e->rmse_m, e->median_m, e->p95_m, e->max_m, e->fixes);
  }
}

// The receivers as a site-file fragment, written whole at the end with
// every step checked (file_io.h).
bool WriteFragment(const SurveyCommandOptions& a, const Site& site,
                   const survey::SurveyResult& result, std::string* error) {
  std::ostringstream header;
  header << "roomfix survey of " << a.log << " ("
         << (a.no_reference ? "no reference, pinned " + a.pin : "reference " + a.reference) << ", "
         << result.firings_used << " firings, residual rms " << result.residual_rms_m
         << " m).\nPaste over the site file's receivers.";
  YAML::Emitter fragment;
  fragment << YAML::Comment(header.str()) << YAML::BeginMap << YAML::Key << "receivers"
           << YAML::Value << YAML::BeginSeq;
  for (const Receiver& r : site.receivers) {
    const survey::ReceiverEstimate* e = result.Find(r.id);
    if (e != nullptr) EmitReceiver(r, *e, &fragment);
  }
  fragment << YAML::EndSeq << YAML::EndMap;
  return WriteOutputFile(a.out, std::string(fragment.c_str()) + "\n", error);
}

bool WriteJson(const SurveyCommandOptions& a, size_t firings, const SurveyFit& fit, json receivers,
               std::string* error) {
  const survey::SurveyResult& result = fit.result;
  json out = {{"log", a.log},
              {"reference", a.no_reference ? json(nullptr) : json(a.reference)},
              {"firings", firings},
              {"ranges_used", result.ranges_used},
              {"ranges_rejected", result.ranges_rejected},
              {"residual_rms_m", Number(result.residual_rms_m)},
              {"condition_number", Number(result.condition_number)},
              {"scale_estimated", result.scale_estimated},
              {"receivers", std::move(receivers)},
              {"receivers_not_heard", fit.not_heard},
              {"notes", result.notes}};
  if (fit.can_evaluate) {
    out["held_out"] = {{"before", ErrorJson(fit.before)}, {"after", ErrorJson(fit.after)}};
  }
  return WriteOutputFile(a.json_path, out.dump(2) + "\n", error);
}

// parse (CLI11) -> load (site, range sets, reference) -> compute (the fit)
// -> report (stdout, --out, --json).
int Run(const SurveyCommandOptions& a) {
  // The starting values: --site/--config, or the site the log carries
  // (SITE); needed either way, so a log without one is an error.
  const ToolSite resolved = ResolveToolSite(a.site, a.log);
  if (!ReportToolSite("roomfix survey", resolved, /*required=*/true)) return 1;
  const Site& site = resolved.site.site;
  auto fail = [](const std::string& error) {
    std::cerr << "roomfix survey: " << error << "\n";
    return 1;
  };
  std::string error;
  const Robot* robot = nullptr;
  const Beacon* beacon = nullptr;
  if (!FindSurveyBeacon(site, a, &robot, &beacon, &error)) return fail(error);
  std::vector<int> pins;
  if (a.no_reference && !ParsePins(a.pin, &pins)) {
    return fail("--no-reference needs --pin ID,ID (two surveyed receivers)");
  }
  BeaconFirings read;
  if (!ReadFirings(a.log, site, *beacon, &read, &error)) return fail(error);
  std::vector<survey::ReferenceSample> reference;
  if (!ReadReference(a, robot->id, &reference, &error)) return fail(error);
  survey::AlignmentSummary alignment;
  if (!reference.empty()) {
    alignment = survey::AlignToReference(reference, kMaxReferenceGap_us, &read.firings);
  }
  SurveyFit fit;
  if (!FitSurvey(a, pins, site, read.firings, !reference.empty(), &fit, &error)) {
    return fail(error);
  }

  const survey::SurveyResult& result = fit.result;
  fmt::print("roomfix survey {}: robot {}, beacon {} at {:.3f} m, {} firings", a.log, robot->id,
             beacon->id, beacon->height_m, read.firings.size());
  if (a.no_reference) {
    fmt::print(", no reference (pinned {})\n", a.pin);
  } else {
    fmt::print(", reference {}: {} aligned, {} outside its span, {} in gaps > {:.1f} s\n",
               a.reference, alignment.aligned, alignment.outside_span, alignment.in_gap,
               kMaxReferenceGap_us * 1e-6);
  }
  fmt::print("{} ranges used, {} rejected as outliers, {} invalid; residual rms {:.4f} m\n\n",
             result.ranges_used, result.ranges_rejected, result.ranges_invalid,
             result.residual_rms_m);
  json receivers = PrintReceivers(site, result);
  PrintEvaluation(a, beacon->id, fit);
  if (read.undecodable > 0) {
    fmt::print(stderr, "roomfix survey: warning: {} RANGES events refused ({})\n", read.undecodable,
               RefusalCounts(read.refused));
  }
  if (read.damaged) fmt::print("the log is damaged; every good event around the damage was used\n");
  if (!a.out.empty() && !WriteFragment(a, site, result, &error)) return fail(error);
  if (!a.json_path.empty() &&
      !WriteJson(a, read.firings.size(), fit, std::move(receivers), &error)) {
    return fail(error);
  }
  return 0;
}

}  // namespace

void AddSurveyCommand(CLI::App* app, int* exit_code) {
  auto* cmd = app->add_subcommand(
      "survey", "Receiver positions and range offsets from a drive with a reference track");
  auto a = std::make_shared<SurveyCommandOptions>();
  cmd->add_option("LOG", a->log, "LCM log with RANGES and a POSE_* reference")->required();
  cmd->add_option("--site,--config", a->site,
                  "Site file: starting values and the 'before' (default: the site the log "
                  "carries on SITE; given, a warning names the keys where the log's differs)");
  cmd->add_option("--reference", a->reference, "Reference pose source")
      ->check(CLI::IsMember({"camera", "ground_truth", "fused"}));
  cmd->add_option("--robot", a->robot, "Robot id (default: the first with a beacon)");
  cmd->add_flag("--scale", a->scale, "Also estimate a range scale per receiver");
  cmd->add_flag("--auto-scale", a->auto_scale,
                "Estimate scales only when significant and the ranges span enough");
  cmd->add_flag("--fix-heights", a->fix_heights, "Keep the receivers' heights from the site");
  cmd->add_flag("--offsets-only", a->offsets_only, "Keep positions; estimate range offsets only");
  cmd->add_flag("--no-reference", a->no_reference,
                "Self-calibration: beacon positions unknown, two receivers pinned");
  cmd->add_option("--pin", a->pin, "With --no-reference: ids of two surveyed receivers, ID,ID");
  cmd->add_option("--block", a->block_s, "Held-out split: block length, seconds")
      ->check(FiniteAbove(0.0, "seconds > 0"));
  cmd->add_option("--period", a->period, "Held-out split: every N-th block is held out")
      ->check(CLI::Range(2, 100));
  cmd->add_option("--out", a->out, "Write the receivers as a site-file fragment (YAML)");
  cmd->add_option("--json", a->json_path, "Also write the result as JSON to this file");
  cmd->callback([a, exit_code] { *exit_code = Run(*a); });
}

}  // namespace roomfix
