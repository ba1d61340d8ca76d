// roomfix_bench capacity: what one core, one process and one host carry
// (issue 19, "Capacity, measured"), for the sizing table in
// docs/operations.md, "Sizing a lab". Every figure is measured in this run:
//
// - camera_proc: `roomfix_bench camera --json` (the real node on rendered
//   JPEG frames, rendering not timed) at 1080p on the demo room's webcam and
//   on the hall's 1280 x 960 camera with its eight robots; cameras per core
//   at 30 fps = 1000 ms / (30 x the median frame time), tracking and full
//   search.
// - trilat_proc: its node on the hall site, every firing arriving as two
//   partial range sets (one per radio) that it merges and solves.
// - fusion_proc: its node with the hall's eight robots, camera poses at
//   30 Hz and ultrasonic fixes at the TDMA rate, driven on a simulated
//   receive clock.
// - roomfix_logger: `roomfix_bench logger --json` (multicast: run under
//   scripts/netns_run), the highest rate it recorded without loss.
// - latency: with --log, the p50 and p99 of POSE_FUSED latency_us (receive
//   time at fusion_proc minus the measurement's time: capture to fused pose
//   for a camera measurement) in a recorded run such as the hall test's.
#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <random>
#include <string>
#include <vector>

#include "bench/commands.h"
#include "core/analysis/track_error.h"
#include "core/world/site.h"
#include "core/world/ultrasound_model.h"
#include "fusion_proc/fusion_node.h"
#include "msgio/bus.h"
#include "msgio/install_paths.h"
#include "msgio/log.h"
#include "msgio/process.h"
#include "msgio/wire_check.h"
#include "roomfix/pose2d_t.hpp"
#include "roomfix/range_set_t.hpp"
#include "trilat_proc/trilat_node.h"

namespace roomfix {
namespace {

using json = nlohmann::ordered_json;

struct BenchCapacityOptions {
  std::string hall_site = DataFile("config/sites/hall.yaml");
  std::string room_site = DataFile("config/sites/demo_room.yaml");
  int camera_frames = 60;
  int firings = 20000;
  double fusion_seconds = 120.0;
  bool logger = true;
  std::string log;
  bool latency_only = false;
  bool json_out = false;
};

// The camera rate the table is for.
constexpr double kCameraFps = 30.0;

std::string SelfExe() {
  char buffer[4096];
  const ssize_t n = ::readlink("/proc/self/exe", buffer, sizeof(buffer) - 1);
  return n > 0 ? std::string(buffer, static_cast<size_t>(n)) : "roomfix_bench";
}

// Runs this binary with `args` and parses the last line of its standard
// output as JSON; an object with "error" when it fails.
json RunSelf(const std::string& args) {
  const std::string command = "'" + SelfExe() + "' " + args + " 2>/dev/null";
  FILE* pipe = ::popen(command.c_str(), "r");
  if (pipe == nullptr) return {{"error", "cannot run " + command}};
  std::string out;
  std::array<char, 4096> buffer;
  size_t n;
  while ((n = std::fread(buffer.data(), 1, buffer.size(), pipe)) > 0) out.append(buffer.data(), n);
  const int rc = ::pclose(pipe);
  while (!out.empty() && out.back() == '\n') out.pop_back();
  const std::string last =
      out.substr(out.find_last_of('\n') == std::string::npos ? 0 : out.find_last_of('\n') + 1);
  json j = json::parse(last, nullptr, /*allow_exceptions=*/false);
  if (rc != 0 || j.is_discarded()) {
    return {{"error", "'" + args + "' exited " + std::to_string(rc) + ": " + last}};
  }
  return j;
}

json CameraRow(const std::string& site, const std::string& scenario, int frames) {
  json r = RunSelf("camera --json --site '" + site + "' --scenario " + scenario + " --frames " +
                   std::to_string(frames));
  if (r.contains("error")) return r;
  json row;
  row["site"] = site;
  row["scenario"] = scenario;
  row["resolution"] =
      std::to_string(r["width_px"].get<int>()) + "x" + std::to_string(r["height_px"].get<int>());
  row["tracking_ms"] = r["tracking_median_ms"];
  // In operation: the mean over frames, one in absent_search_period_frames
  // carrying a full-frame search while robots are out of view (a hall).
  // CPU time, not wall time: what a frame costs a core on a shared machine.
  row["operating_ms"] = r["tracking_cpu_mean_ms"];
  row["absent_search_period_frames"] = r["absent_search_period_frames"];
  row["every_frame_ms"] = r["tracking_every_frame_cpu_mean_ms"];
  row["full_search_ms"] = r["full_search_median_ms"];
  row["cameras_per_core_tracking"] = 1000.0 / (kCameraFps * r["tracking_median_ms"].get<double>());
  row["cameras_per_core_operating"] =
      1000.0 / (kCameraFps * r["tracking_cpu_mean_ms"].get<double>());
  row["cameras_per_core_every_frame"] =
      1000.0 / (kCameraFps * r["tracking_every_frame_cpu_mean_ms"].get<double>());
  row["cameras_per_core_full_search"] =
      1000.0 / (kCameraFps * r["full_search_median_ms"].get<double>());
  row["detection_rate"] = r["detection_rate"];
  return row;
}

const Trajectory* TrajectoryOf(const Site& site, int robot_id) {
  for (const SimulatedRobot& s : site.simulation.robots) {
    if (s.robot_id == robot_id) return s.trajectory.get();
  }
  return nullptr;
}

// trilat_proc's node on the site: `firings` firings, beacons in turn on the
// TDMA table's slots, each as one partial set per radio (or one set).
json TrilatRow(const Site& site, int firings) {
  LoopbackBus bus;
  TrilatNodeOptions options;
  constexpr int64_t kStart = 1'700'000'000'000'000;
  TrilatNode node(site, &bus, options, kStart);
  int64_t poses = 0, full_poses = 0;
  bus.Subscribe<pose2d_t>(kUltrasoundPoseChannel, [&](const pose2d_t& p, const MessageInfo&) {
    ++poses;
    if (p.num_measurements == static_cast<int>(site.receivers.size())) ++full_poses;
  });
  std::vector<std::pair<int, int>> beacons;  // (beacon, robot)
  for (const Robot& r : site.robots) {
    if (r.beacon_id && TrajectoryOf(site, r.id) != nullptr) beacons.push_back({*r.beacon_id, r.id});
  }
  if (beacons.empty()) return {{"error", "the site has no simulated robot with a beacon"}};
  std::mt19937_64 rng(1);
  UltrasoundNoise noise;
  noise.sigma_m = 0.01;
  // Encoded ahead, so that the timing is the node's alone (decode, merge,
  // solve, publish).
  struct Part {
    int64_t recv_utime;
    std::vector<uint8_t> bytes;
  };
  std::vector<Part> parts;
  // A slot of the hall (trilateration.md, "Sharing the air").
  constexpr int64_t kSlotUs = 120'000;
  for (int k = 0; k < firings; ++k) {
    const auto& [beacon_id, robot_id] = beacons[static_cast<size_t>(k) % beacons.size()];
    const int64_t utime = kStart + k * kSlotUs;
    const GroundTruthPose truth = TrajectoryOf(site, robot_id)->PoseAt(k * kSlotUs * 1e-6);
    const Beacon* beacon = nullptr;
    for (const Beacon& b : site.beacons) {
      if (b.id == beacon_id) beacon = &b;
    }
    const std::array<double, 3> p = {truth.x_m, truth.y_m, beacon->height_m};
    std::map<int, range_set_t> by_radio;
    for (const SimulatedRange& s : SimulateRanges(site, p, 20.0, noise, &rng)) {
      const RadioNetwork* radio = site.RadioOfReceiver(s.receiver_id);
      range_set_t& set = by_radio[radio ? radio->id : 0];
      set.utime = utime;
      set.beacon_id = beacon_id;
      set.firing_seq = k / static_cast<int>(beacons.size());
      set.temperature_c = 20.0;
      set.speed_of_sound_mps = SpeedOfSound(20.0);
      set.num_expected = radio ? static_cast<int32_t>(radio->receiver_ids.size())
                               : static_cast<int32_t>(site.receivers.size());
      range_t r{};
      r.receiver_id = s.receiver_id;
      const Receiver* rc = site.FindReceiver(s.receiver_id);
      for (int i = 0; i < 3; ++i) r.receiver_position_m[i] = rc->position_m[i];
      r.range_m = s.measured_m;
      set.ranges.push_back(r);
    }
    int i = 0;
    for (auto& [radio_id, set] : by_radio) {
      set.num_ranges = static_cast<int32_t>(set.ranges.size());
      Part part;
      // The bridges' sets reach trilat_proc a few ms after the firing.
      part.recv_utime = utime + 5'000 + 1'000 * i++;
      part.bytes.resize(static_cast<size_t>(set.getEncodedSize()));
      set.encode(part.bytes.data(), 0, static_cast<int>(part.bytes.size()));
      parts.push_back(std::move(part));
    }
  }
  const auto start = std::chrono::steady_clock::now();
  for (const Part& part : parts) {
    bus.Inject(kRangesChannel, part.bytes.data(), static_cast<int>(part.bytes.size()),
               part.recv_utime);
    node.Tick(part.recv_utime);
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  json row;
  row["receivers"] = site.receivers.size();
  row["radios"] = site.radios.size();
  row["firings"] = firings;
  row["range_sets"] = parts.size();
  row["poses"] = poses;
  row["poses_from_every_receiver"] = full_poses;
  row["seconds"] = seconds;
  row["range_sets_per_s"] = parts.size() / seconds;
  row["firings_per_s"] = firings / seconds;
  return row;
}

// fusion_proc's node on the site's robots: camera poses at 30 Hz (one
// camera each) and ultrasonic fixes at `ultrasound_hz`, on a simulated
// receive clock (camera 30 ms late, ultrasound 60 ms).
json FusionRow(const Site& site, double seconds_simulated, double ultrasound_hz) {
  struct Item {
    int64_t recv_utime;
    bool camera;
    pose2d_t pose;
  };
  constexpr int64_t kStart = 1'700'000'000'000'000;
  std::mt19937_64 rng(2);
  std::normal_distribution<double> mm(0.0, 0.003), cm(0.0, 0.03);
  std::vector<Item> items;
  int robots = 0;
  for (const Robot& r : site.robots) {
    const Trajectory* t = TrajectoryOf(site, r.id);
    if (t == nullptr) continue;
    ++robots;
    auto add = [&](double t_s, bool camera) {
      const GroundTruthPose g = t->PoseAt(t_s);
      pose2d_t p{};
      p.utime = kStart + static_cast<int64_t>(t_s * 1e6);
      p.source = camera ? pose2d_t::SOURCE_CAMERA : pose2d_t::SOURCE_ULTRASOUND;
      p.camera_id = camera ? 0 : kNoCameraId;
      p.robot_id = r.id;
      p.measurement_seq = static_cast<int64_t>(items.size());
      const double sigma = camera ? 0.003 : 0.03;
      p.x_m = g.x_m + (camera ? mm(rng) : cm(rng));
      p.y_m = g.y_m + (camera ? mm(rng) : cm(rng));
      p.heading_rad = g.heading_rad;
      p.covariance[0][0] = p.covariance[1][1] = sigma * sigma;
      p.covariance[2][2] = camera ? 0.01 : 1e6;
      p.num_measurements = camera ? 2 : 12;
      p.status = pose2d_t::STATUS_OK;
      const int64_t delay = camera ? 30'000 : 60'000;
      p.latency_us = delay;
      items.push_back({p.utime + delay, camera, p});
    };
    for (double t_s = 0.0; t_s < seconds_simulated; t_s += 1.0 / kCameraFps) add(t_s, true);
    for (double t_s = 0.05 * r.id; t_s < seconds_simulated; t_s += 1.0 / ultrasound_hz) {
      add(t_s, false);
    }
  }
  if (robots == 0) return {{"error", "the site has no simulated robot"}};
  std::sort(items.begin(), items.end(),
            [](const Item& a, const Item& b) { return a.recv_utime < b.recv_utime; });
  std::vector<std::vector<uint8_t>> encoded;
  encoded.reserve(items.size());
  for (const Item& i : items) {
    std::vector<uint8_t> bytes(static_cast<size_t>(i.pose.getEncodedSize()));
    i.pose.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
    encoded.push_back(std::move(bytes));
  }
  LoopbackBus bus;
  FusionNodeOptions options;
  FusionNode node(site, &bus, options, kStart);
  int64_t fused = 0;
  bus.Subscribe<pose2d_t>(kFusedPoseChannel, [&](const pose2d_t&, const MessageInfo&) { ++fused; });
  const auto start = std::chrono::steady_clock::now();
  for (size_t k = 0; k < items.size(); ++k) {
    bus.Inject(items[k].camera ? options.camera_channel : options.ultrasound_channel,
               encoded[k].data(), static_cast<int>(encoded[k].size()), items[k].recv_utime);
    node.Tick(items[k].recv_utime);
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const double per_s = items.size() / seconds;
  const double per_robot_hz = kCameraFps + ultrasound_hz;
  json row;
  row["robots"] = robots;
  row["measurements"] = items.size();
  row["fused_poses"] = fused;
  row["seconds"] = seconds;
  row["measurements_per_s"] = per_s;
  row["robots_per_core_one_camera"] = per_s / per_robot_hz;
  // A robot in an overlap is seen by two cameras: twice the camera poses.
  row["robots_per_core_two_cameras"] = per_s / (2.0 * kCameraFps + ultrasound_hz);
  return row;
}

// POSE_FUSED latency in a log: p50 and p99 of latency_us over every fused
// pose that is not LOST. fusion_proc publishes one per measurement, at the
// measurement's time, so this is capture (or firing) to fused pose; at 30 fps
// per camera against 1 Hz per beacon nearly all are camera measurements.
json LatencyRow(const std::string& path) {
  std::vector<LogEvent> events;
  std::string error;
  if (!ReadLogEvents(path, &events, &error)) return {{"error", error}};
  std::vector<double> latency_ms;
  int64_t refused = 0;
  for (const LogEvent& e : events) {
    if (e.channel != kFusedPoseChannel) continue;
    pose2d_t p;
    std::string reason, detail;
    if (!DecodeChecked(e.data.data(), static_cast<int>(e.data.size()), &p, &reason, &detail)) {
      ++refused;
      continue;
    }
    if (p.status == pose2d_t::STATUS_LOST) continue;
    latency_ms.push_back(p.latency_us * 1e-3);
  }
  if (latency_ms.empty()) return {{"error", path + ": no POSE_FUSED"}};
  json row;
  row["log"] = path;
  row["fused_poses"] = latency_ms.size();
  row["refused"] = refused;
  row["p50_ms"] = analysis::Percentile(latency_ms, 0.5);
  row["p99_ms"] = analysis::Percentile(latency_ms, 0.99);
  row["max_ms"] = *std::max_element(latency_ms.begin(), latency_ms.end());
  return row;
}

void PrintError(const char* what, const json& row) {
  fmt::print("  {}: not measured: {}\n", what, row["error"].get<std::string>().c_str());
}

void PrintCapacity(const json& out);

int RunCapacityBench(const BenchCapacityOptions& o) {
  Site hall;
  std::string error;
  if (!LoadSite(o.hall_site, &hall, &error)) {
    std::cerr << "roomfix_bench capacity: " << error << "\n";
    return 1;
  }
  json out;
  if (!o.latency_only) {
    out["camera"] = json::array({CameraRow(o.room_site, "webcam", o.camera_frames),
                                 CameraRow(o.hall_site, "clean", o.camera_frames)});
    out["trilat"] = TrilatRow(hall, o.firings);
    // The TDMA rate with the hall's eight beacons: about 1 Hz each.
    out["fusion"] = FusionRow(hall, o.fusion_seconds, 1.0);
  }
  if (o.logger && !o.latency_only) {
    json r = RunSelf("logger --json --seconds 2 --rates 20000 50000 100000 150000");
    out["logger"] =
        r.contains("error")
            ? r
            : json{{"max_rate_without_loss_per_s", r["udpm_bus"]["max_rate_without_loss_per_s"]},
                   {"payload_bytes", r["payload_bytes"]}};
  }
  if (!o.log.empty()) out["latency"] = LatencyRow(o.log);
  if (o.json_out) {
    std::cout << out.dump() << "\n";
    return 0;
  }
  if (o.latency_only) {
    if (!out.contains("latency")) {
      std::cerr << "roomfix_bench capacity: --latency-only needs --log\n";
      return 1;
    }
  } else {
    PrintCapacity(out);
  }
  if (out.contains("latency")) {
    const json& l = out["latency"];
    if (l.contains("error")) {
      PrintError("latency", l);
      return o.latency_only ? 1 : 0;
    }
    fmt::print(
        "  capture to POSE_FUSED ({}, {} fused poses): p50 {:.1f} ms, p99 {:.1f} ms, max {:.1f} "
        "ms\n",
        l["log"].get<std::string>().c_str(), l["fused_poses"].get<int>(), l["p50_ms"].get<double>(),
        l["p99_ms"].get<double>(), l["max_ms"].get<double>());
  }
  return 0;
}

void PrintCapacity(const json& out) {
  fmt::print("capacity (one core each unless said; {:.0f} fps cameras)\n", kCameraFps);
  fmt::print(
      "  camera_proc, per frame (median)     tracking   full search   cameras/core at "
      "30 fps (tracking / full search)\n");
  for (const json& row : out["camera"]) {
    if (row.contains("error")) {
      PrintError("camera_proc", row);
      continue;
    }
    fmt::print("    {:<9} {:<7} {:<22} {:6.2f} ms  {:8.2f} ms     {:5.1f} / {:4.1f}\n",
               row["resolution"].get<std::string>().c_str(),
               row["scenario"].get<std::string>().c_str(),
               row["site"]
                   .get<std::string>()
                   .substr(row["site"].get<std::string>().rfind('/') + 1)
                   .c_str(),
               row["tracking_ms"].get<double>(), row["full_search_ms"].get<double>(),
               row["cameras_per_core_tracking"].get<double>(),
               row["cameras_per_core_full_search"].get<double>());
    fmt::print(
        "              in operation (CPU mean; robots out of view searched every {} frames): "
        "{:.2f} "
        "ms, {:.1f} cameras/core; searched every frame (before): {:.2f} ms, {:.1f} cameras/core\n",
        row["absent_search_period_frames"].get<int>(), row["operating_ms"].get<double>(),
        row["cameras_per_core_operating"].get<double>(), row["every_frame_ms"].get<double>(),
        row["cameras_per_core_every_frame"].get<double>());
  }
  const json& t = out["trilat"];
  if (t.contains("error")) {
    PrintError("trilat_proc", t);
  } else {
    fmt::print(
        "  trilat_proc (hall: {} receivers on {} radios, merged parts): {:.0f} range sets/s = "
        "{:.0f} "
        "firings/s ({} of {} poses from every receiver)\n",
        t["receivers"].get<int>(), t["radios"].get<int>(), t["range_sets_per_s"].get<double>(),
        t["firings_per_s"].get<double>(), t["poses_from_every_receiver"].get<int>(),
        t["poses"].get<int>());
  }
  const json& f = out["fusion"];
  if (f.contains("error")) {
    PrintError("fusion_proc", f);
  } else {
    fmt::print(
        "  fusion_proc ({} robots, 30 Hz camera + 1 Hz ultrasound each): {:.0f} measurements/s = "
        "{:.0f} robots/core with one camera each, {:.0f} in overlaps (two cameras)\n",
        f["robots"].get<int>(), f["measurements_per_s"].get<double>(),
        f["robots_per_core_one_camera"].get<double>(),
        f["robots_per_core_two_cameras"].get<double>());
  }
  if (out.contains("logger")) {
    const json& l = out["logger"];
    if (l.contains("error")) {
      PrintError("roomfix_logger (multicast: run under scripts/netns_run)", l);
    } else {
      fmt::print("  roomfix_logger: {} messages/s recorded without loss ({}-byte payloads)\n",
                 l["max_rate_without_loss_per_s"].get<int>(), l["payload_bytes"].get<int>());
    }
  }
}

}  // namespace

void AddBenchCapacityCommand(CLI::App* bench, int* exit_code) {
  auto o = std::make_shared<BenchCapacityOptions>();
  auto* cmd = bench->add_subcommand(
      "capacity",
      "What one core carries: cameras per core at 30 fps (tracking, full search), range sets per "
      "second through trilat_proc, robots per fusion_proc, messages per second through the "
      "logger, and with --log the capture-to-POSE_FUSED latency of a recorded run");
  cmd->add_option("--hall", o->hall_site, "The hall site (trilat, fusion, its camera)")
      ->capture_default_str();
  cmd->add_option("--room", o->room_site, "A site with a 1080p webcam camera")
      ->capture_default_str();
  cmd->add_option("--camera-frames", o->camera_frames, "Frames per camera case")
      ->check(CLI::Range(10, 10000))
      ->capture_default_str();
  cmd->add_option("--firings", o->firings, "Firings through trilat_proc's node")
      ->check(CLI::Range(100, 10000000))
      ->capture_default_str();
  cmd->add_option("--fusion-seconds", o->fusion_seconds, "Simulated seconds through fusion_proc")
      ->check(CLI::Range(1.0, 3600.0))
      ->capture_default_str();
  cmd->add_flag("!--no-logger", o->logger, "Skip the logger (it needs multicast)");
  cmd->add_option("--log", o->log, "A recorded run: POSE_FUSED latency p50 / p99");
  cmd->add_flag("--latency-only", o->latency_only, "Only the latency of --log");
  cmd->add_flag("--json", o->json_out, "Print one JSON object instead of the table");
  cmd->callback([o, exit_code] { *exit_code = RunCapacityBench(*o); });
}

}  // namespace roomfix
