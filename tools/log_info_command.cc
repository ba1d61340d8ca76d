#include <fmt/format.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cstdio>
#include <iostream>
#include <map>
#include <string>
#include <vector>

#include "msgio/channels.h"
#include "msgio/log.h"
#include "msgio/message_json.h"
#include "msgio/wire_check.h"
#include "roomfix/marker_pixels_t.hpp"
#include "roomfix/process_status_t.hpp"
#include "tools/commands.h"

namespace roomfix {
namespace {

struct ChannelSummary {
  int64_t events = 0;
  int64_t bytes = 0;
  int64_t first_utime = 0;
  int64_t last_utime = 0;
  std::map<std::string, int64_t> types;
};

// A camera's frames as camera_proc published them on MARKER_PIXELS: how
// many, at what rate, and the gaps in the camera's numbering (frames the
// camera or camera_proc dropped: it publishes every frame it processes).
struct CameraFrames {
  int64_t frames = 0;
  int64_t first_seq = 0;
  int64_t last_seq = 0;
  int64_t dropped = 0;
  int64_t out_of_order = 0;
  int64_t first_utime = 0;
  int64_t last_utime = 0;
  std::vector<int32_t> processing_us;
};
// What a camera_proc's last STATUS says of the gaps: frames its synthetic
// camera's renderer skipped because it fell behind real time
// (source_skipped_frames), which are not frames camera_proc dropped.
struct CameraProcStatus {
  int64_t source_skipped = 0;
};
// Cameras beyond this many share no row: a log's camera ids are outside input.
constexpr size_t kMaxCameras = 64;

// bot-procman's own traffic (libbot2's bot2-procman): the deputy and the
// sheriff use these fixed channel names, each for one type of package
// bot_procman (read from bot2-procman's procman_deputy.c and sheriff.py;
// the unnumbered ones are the older protocol, still spoken by both). A log
// of a system run under bot-procman holds them, so they are named rather
// than reported as unknown. Named by channel: roomfix does not carry
// libbot2's type definitions to check their fingerprints.
struct ForeignChannel {
  const char* channel;
  const char* type;
};
constexpr ForeignChannel kProcmanChannels[] = {
    {"PMD_ORDERS2", "bot_procman.orders2_t (bot-procman, libbot2)"},
    {"PMD_INFO2", "bot_procman.info2_t (bot-procman, libbot2)"},
    {"PMD_PRINTF", "bot_procman.printf_t (bot-procman, libbot2)"},
    {"PMD_DISCOVER", "bot_procman.discovery_t (bot-procman, libbot2)"},
    {"PMD_ORDERS", "bot_procman.orders_t (bot-procman, libbot2)"},
    {"PMD_INFO", "bot_procman.info_t (bot-procman, libbot2)"},
};

// What a payload that is no roomfix type is called on `channel`.
const char* ForeignTypeName(const std::string& channel) {
  for (const auto& c : kProcmanChannels) {
    if (channel == c.channel) return c.type;
  }
  return "(not a roomfix type)";
}

constexpr size_t kMaxListedChannels = 1024;
constexpr char kUnlistedChannels[] = "(other channels)";

// Everything log-info counts over a log.
struct LogSummary {
  // A log holds whatever was on the bus, and anyone can invent channel
  // names: past kMaxListedChannels distinct names the rest share one row,
  // so the table (and memory) stays bounded however many there are.
  std::map<std::string, ChannelSummary> channels;
  std::map<int, CameraFrames> cameras;
  // By pid (STATUS carries no camera id); as many as there are cameras.
  std::map<int32_t, CameraProcStatus> camera_procs;
  int64_t unlisted_channel_events = 0;
  // MARKER_PIXELS and STATUS events refused before decoding, by reason.
  std::map<std::string, int64_t> refused;
};

// The event's row of the channel table.
void CountChannel(const LogEvent& event, LogSummary* s) {
  auto it = s->channels.find(event.channel);
  if (it == s->channels.end()) {
    const bool listed = s->channels.size() < kMaxListedChannels;
    if (!listed) ++s->unlisted_channel_events;
    it = s->channels.emplace(listed ? event.channel : kUnlistedChannels, ChannelSummary{}).first;
  }
  ChannelSummary& c = it->second;
  if (c.events == 0) c.first_utime = event.utime;
  c.last_utime = event.utime;
  ++c.events;
  c.bytes += static_cast<int64_t>(event.data.size());
  const char* type = RoomfixTypeName(event.data.data(), static_cast<int>(event.data.size()));
  ++c.types[type != nullptr ? type : ForeignTypeName(event.channel)];
}

// A camera's frame (MARKER_PIXELS) or a camera_proc's heartbeat (STATUS).
void CountCameraEvent(const LogEvent& event, LogSummary* s) {
  marker_pixels_t pixels;
  process_status_t status;
  std::string reason;
  const bool is_status = event.channel == kStatusChannel;
  const bool is_pixels = event.channel == kMarkerPixelsChannel;
  const int size = static_cast<int>(event.data.size());
  // A refused event is not a frame or a heartbeat: counted for the
  // warning, never read.
  const bool decoded = (is_status && DecodeChecked(event.data.data(), size, &status, &reason)) ||
                       (is_pixels && DecodeChecked(event.data.data(), size, &pixels, &reason));
  if ((is_status || is_pixels) && !decoded) ++s->refused[reason];
  if (is_status && decoded && status.process == "camera_proc" &&
      (s->camera_procs.size() < kMaxCameras || s->camera_procs.count(status.pid) > 0)) {
    // Counters are totals since start: the last heartbeat holds them all.
    CameraProcStatus& p = s->camera_procs[status.pid];
    for (const counter_t& counter : status.counters) {
      if (counter.name == "source_skipped_frames") p.source_skipped = counter.count;
    }
  }
  if (!is_pixels || !decoded) return;
  if (s->cameras.size() >= kMaxCameras && s->cameras.count(pixels.camera_id) == 0) return;
  CameraFrames& f = s->cameras[pixels.camera_id];
  if (f.frames == 0) {
    f.first_seq = pixels.frame_seq;
    f.first_utime = pixels.utime;
  } else if (pixels.frame_seq > f.last_seq) {
    f.dropped += pixels.frame_seq - f.last_seq - 1;
  } else {
    ++f.out_of_order;
  }
  f.last_seq = std::max(f.last_seq, pixels.frame_seq);
  f.last_utime = std::max(f.last_utime, pixels.utime);
  ++f.frames;
  f.processing_us.push_back(pixels.processing_time_us);
}

// Channel names come from the log: printed as C strings, up to a NUL byte.
void PrintChannels(const LogSummary& s) {
  fmt::print("{:<24} {:>8} {:>10} {:>9}  {}\n", "channel", "events", "bytes", "rate_hz", "type");
  for (const auto& [name, c] : s.channels) {
    const double span_s = (c.last_utime - c.first_utime) * 1e-6;
    const double rate = span_s > 0 ? (c.events - 1) / span_s : 0.0;
    for (const auto& [type, count] : c.types) {
      fmt::print("{:<24} {:8d} {:10d} {:9.2f}  {}\n", name.c_str(), count, c.bytes, rate,
                 type.c_str());
    }
  }
}

void PrintCameras(LogSummary* s) {
  int64_t source_skipped = 0;
  for (const auto& [pid, p] : s->camera_procs) source_skipped += p.source_skipped;
  for (auto& [id, f] : s->cameras) {
    const double span_s = (f.last_utime - f.first_utime) * 1e-6;
    // One camera, so its camera_procs' skips are its own: split the gaps.
    // With several the STATUS cannot say whose they are (listed below).
    std::string split;
    if (s->cameras.size() == 1 && !s->camera_procs.empty()) {
      split = ": " + std::to_string(f.dropped - source_skipped) + " by camera_proc, " +
              std::to_string(source_skipped) + " skipped by the synthetic camera's renderer";
    }
    auto mid = f.processing_us.begin() + static_cast<std::ptrdiff_t>(f.processing_us.size() / 2);
    std::nth_element(f.processing_us.begin(), mid, f.processing_us.end());
    fmt::print(
        "camera {}: {} frames (seq {}..{}) at {:.2f} fps, {} dropped (gaps in frame_seq{}){}, "
        "capture to detection median {:.1f} ms\n",
        id, f.frames, f.first_seq, f.last_seq, span_s > 0 ? (f.frames - 1) / span_s : 0.0,
        f.dropped, split,
        f.out_of_order > 0 ? ", " + std::to_string(f.out_of_order) + " out of order"
                           : std::string(),
        *mid * 1e-3);
  }
  if (s->cameras.size() != 1) {
    for (const auto& [pid, p] : s->camera_procs) {
      if (p.source_skipped == 0) continue;
      fmt::print("camera_proc pid {}: {} frames skipped by the synthetic camera's renderer\n", pid,
                 p.source_skipped);
    }
  }
}

// parse (CLI11) -> load and count (every event) -> report. Exit 2 for a
// damaged log: every good event around the damage is in the table.
int RunLogInfo(const std::string& path) {
  std::string error;
  auto reader = LogReader::Open(path, &error);
  if (reader == nullptr) {
    std::cerr << "roomfix log-info: " << error << "\n";
    return 1;
  }
  LogSummary s;
  LogEvent event;
  while (reader->Next(&event)) {
    CountChannel(event, &s);
    CountCameraEvent(event, &s);
  }
  fmt::print("{}: {} events, {} bytes\n", path, reader->events_read(), reader->file_size());
  PrintChannels(s);
  PrintCameras(&s);
  if (!s.refused.empty()) {
    int64_t total = 0;
    for (const auto& [reason, count] : s.refused) total += count;
    std::cerr << "roomfix log-info: warning: " << total
              << " MARKER_PIXELS and STATUS events refused (" << RefusalCounts(s.refused) << ")\n";
  }
  if (s.unlisted_channel_events > 0) {
    std::cerr << "roomfix log-info: warning: more than " << kMaxListedChannels
              << " channels; events on the rest are summed under " << kUnlistedChannels << "\n";
  }
  if (!reader->damaged()) return 0;
  fmt::print("damaged: {}\n", reader->DamageSummary());
  std::fflush(stdout);
  std::cerr << "roomfix log-info: warning: " << path << ": " << reader->DamageSummary() << "\n";
  return 2;
}

}  // namespace

void AddLogInfoCommand(CLI::App* app, int* exit_code) {
  auto* cmd = app->add_subcommand(
      "log-info", "Summarise an LCM log: events, types and rate per channel, and any damage");
  auto path = std::make_shared<std::string>();
  cmd->add_option("LOG", *path, "LCM log file (roomfix_logger or lcm-logger)")->required();
  cmd->callback([path, exit_code] { *exit_code = RunLogInfo(*path); });
}

}  // namespace roomfix
