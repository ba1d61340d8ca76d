#include "tools/replay.h"

#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <memory>
#include <optional>
#include <vector>

#include "core/radio/range_assembler.h"
#include "core/world/file_io.h"
#include "msgio/process.h"
#include "msgio/time_limits.h"
#include "msgio/wire_check.h"
#include "roomfix/marker_pixels_t.hpp"
#include "roomfix/range_set_t.hpp"

namespace roomfix {
namespace {

// The bus the re-run nodes talk to. Recorded events come in through
// Inject(); what a node publishes goes to `on_publish` (the new log) and, as
// on a live bus, to every subscriber, so fusion hears the new trilat poses.
// Single-threaded and synchronous: the order of the output is the order of
// the calls, which is what makes it deterministic.
class ReplayBus final : public Bus {
 public:
  using PublishHook = std::function<void(const std::string& channel, const void* data, int size)>;
  explicit ReplayBus(PublishHook on_publish) : on_publish_(std::move(on_publish)) {}

  bool PublishRaw(const std::string& channel, const void* data, int size) override {
    CountPublished(true, channel);
    on_publish_(channel, data, size);
    DeliverToSubscribers(MessageInfo{channel, now_utime_}, data, size);
    return true;
  }
  SubscriptionId SubscribeRaw(const std::string& channel_regex, RawHandler handler) override {
    return AddSubscription(channel_regex, std::move(handler));
  }
  void Unsubscribe(SubscriptionId id) override { RemoveSubscription(id); }

  void Inject(const std::string& channel, const void* data, int size) {
    DeliverToSubscribers(MessageInfo{channel, now_utime_}, data, size);
  }
  void set_now_utime(int64_t utime) { now_utime_ = utime; }
  int64_t now_utime() const { return now_utime_; }

 private:
  PublishHook on_publish_;
  int64_t now_utime_ = 0;
};

// Re-derives a recorded range set's ranges from `site` (restamp_ranges).
// Returns false when the set is not a range set DecodeChecked accepts; the
// event is then passed on unchanged, for the node to refuse and count.
bool RestampRanges(const Site& site, std::vector<uint8_t>* data, PipelineReplaySummary* summary) {
  range_set_t set{};
  std::string reason;
  if (!DecodeChecked(data->data(), static_cast<int>(data->size()), &set, &reason)) return false;
  for (range_t& r : set.ranges) {
    const Receiver* receiver = site.FindReceiver(r.receiver_id);
    if (receiver == nullptr) {  // trilat refuses it: unknown_receiver.
      ++summary->ranges_unknown_receiver;
      continue;
    }
    for (int k = 0; k < 3; ++k) r.receiver_position_m[k] = receiver->position_m[k];
    if (std::isfinite(r.time_of_flight_us) && r.time_of_flight_us > 0 &&
        std::isfinite(set.speed_of_sound_mps)) {
      r.range_m = radio::RangeFromTimeOfFlight(r.time_of_flight_us, set.speed_of_sound_mps,
                                               receiver->range_offset_m);
      ++summary->ranges_restamped;
    } else {
      ++summary->ranges_kept;
    }
  }
  const int size = set.getEncodedSize();
  data->assign(static_cast<size_t>(size), 0);
  return set.encode(data->data(), 0, size) == size;
}

int64_t SaturatingAddUs(int64_t a, int64_t b) { return a > INT64_MAX - b ? INT64_MAX : a + b; }

// |a - b| without overflow, saturated at INT64_MAX.
int64_t DistanceUs(int64_t a, int64_t b) {
  const int64_t d = SaturatingDifferenceUs(a, b);
  return d == INT64_MIN ? INT64_MAX : (d < 0 ? -d : d);
}

// An event's size in an LCM log file: the 28-byte header, channel, payload.
int64_t LoggedSize(const std::string& channel, size_t payload) {
  constexpr int64_t kLcmEventHeaderBytes = 28;
  return kLcmEventHeaderBytes + static_cast<int64_t>(channel.size() + payload);
}

}  // namespace

bool EventTimeScreen::Plausible(int64_t utime) const {
  // A recorded log's times rise, so a time can be judged only against the
  // order: an event far ahead of most of the events after it, or far behind
  // the last accepted one while the events after it do not follow it there
  // (which would be a host clock stepped back), cannot be right. A sparse
  // log, however far apart its events, is never refused.
  bool have_ahead = !ahead_.empty();
  int64_t ahead_median = 0;
  if (have_ahead) {
    std::vector<int64_t> ahead;
    for (const LogEvent& e : ahead_) ahead.push_back(e.utime);
    std::sort(ahead.begin(), ahead.end());
    ahead_median = ahead[(ahead.size() - 1) / 2];
    if (SaturatingDifferenceUs(utime, ahead_median) > kMaxEventTimeOffsetUs) return false;
  }
  if (!accepted_.empty() &&
      SaturatingDifferenceUs(accepted_.back(), utime) > kMaxEventTimeOffsetUs) {
    return have_ahead && DistanceUs(ahead_median, utime) <= kMaxEventTimeOffsetUs;
  }
  return true;
}

bool EventTimeScreen::Next(LogEvent* event) {
  for (;;) {
    while (!end_ && ahead_.size() <= static_cast<size_t>(kEventTimeNeighbours)) {
      LogEvent e;
      if (!in_->Next(&e)) {
        end_ = true;
        break;
      }
      ahead_.push_back(std::move(e));
    }
    if (ahead_.empty()) return false;
    *event = std::move(ahead_.front());
    ahead_.pop_front();
    if (!Plausible(event->utime)) {
      ++refused_;
      continue;
    }
    accepted_.push_back(event->utime);
    if (accepted_.size() > static_cast<size_t>(kEventTimeNeighbours)) accepted_.pop_front();
    return true;
  }
}

bool MakeReplaySiteMessage(const LoadedSite& loaded, site_t* msg, std::string* error) {
  if (!MakeSiteMessage(loaded, "roomfix replay", 0, msg, error)) return false;
  msg->host = "replay";
  msg->pid = 0;
  return true;
}

bool ResolveReplaySite(const std::string& log_path, const std::string& config_path,
                       const std::string& new_site_path, ReplaySite* out, std::string* error) {
  if (!config_path.empty() && !new_site_path.empty()) {
    *error = "give --config (the recorded site) or --site (a new one), not both";
    return false;
  }
  out->is_new = !new_site_path.empty();
  out->from_file = !config_path.empty() || out->is_new;
  const std::string& path = out->is_new ? new_site_path : config_path;
  ToolSite resolved = ResolveToolSite(path, log_path);
  if (!resolved.known) {
    *error = resolved.error + (out->from_file ? "" : " (or --site NEW.yaml)");
    return false;
  }
  out->loaded = std::move(resolved.site);
  out->used_line = resolved.line;
  const std::vector<std::string>& lines = resolved.warnings;
  if (out->is_new) {
    out->used_line = "new site from --site " + new_site_path + ": " + DescribeSite(out->loaded);
    out->notes = lines;
  } else {
    out->warnings = lines;
  }
  return true;
}

bool ReplayCameraCalibrations(const LoadedSite& loaded, std::map<int, calib::Calibration>* out,
                              std::string* error) {
  out->clear();
  for (size_t i = 0; i < loaded.site.cameras.size(); ++i) {
    const Camera& camera = loaded.site.cameras[i];
    const std::string* text = SiteCalibrationText(loaded, i);
    if (text == nullptr) continue;
    calib::Calibration c;
    const std::string name =
        "camera " + std::to_string(camera.id) + "'s calibration " + camera.calibration_file;
    if (!calib::ParseCalibration(*text, name, &c, error)) return false;
    if (c.width_px() != camera.width_px || c.height_px() != camera.height_px) {
      *error = name + " is for " + std::to_string(c.width_px()) + "x" +
               std::to_string(c.height_px()) + " px, the camera delivers " +
               std::to_string(camera.width_px) + "x" + std::to_string(camera.height_px);
      return false;
    }
    // camera_proc refuses a fit this poor; so does its replay.
    if (const std::string fit = calib::CheckFitResidual(c); !fit.empty()) {
      *error = name + ": " + fit;
      return false;
    }
    (*out)[camera.id] = std::move(c);
  }
  return true;
}

bool LogHoldsChannel(const std::string& path, const std::string& channel, bool* holds,
                     std::string* error) {
  *holds = false;
  auto reader = LogReader::Open(path, error);
  if (reader == nullptr) return false;
  LogEvent event;
  while (reader->Next(&event)) {
    if (event.channel == channel) {
      *holds = true;
      break;
    }
  }
  return true;
}

bool PipelineReplayOptions::IsValid(std::string* error) const {
  if (!trilat && !fusion && !camera) {
    *error = "no node to re-run (choose trilat, fusion, camera)";
    return false;
  }
  if (camera && camera_calibrations.empty()) {
    *error = "camera: no camera of the site has a calibration, so there is no POSE_CAMERA to make";
    return false;
  }
  if (camera && !camera_options.IsValid(error)) return false;
  if (tick_period_ms <= 0 || tick_period_ms > 1000) {
    *error = "tick_period_ms must be in 1..1000";
    return false;
  }
  if (trilat && !trilat_options.IsValid(error)) return false;
  if (fusion && !fusion_options.IsValid(error)) return false;
  return true;
}

PipelineReplaySummary ReplayPipeline(LogReader* in, const Site& site,
                                     const PipelineReplayOptions& options, LogWriter* out) {
  PipelineReplaySummary summary;
  if (!options.IsValid(&summary.error)) return summary;
  summary.ok = true;
  std::string write_error;
  auto write = [&](int64_t utime, const std::string& channel, const void* data, int size) {
    if (!write_error.empty()) return;
    out->Write(utime, channel, data, size, &write_error);
  };

  // Input bytes read so far, and when each node last had a heartbeat
  // written (kStatusRepeatInputRatio). The node is the one being ticked or
  // stopped (camera nodes share a process name): trilat 0, fusion 1, the
  // cameras 2...
  int64_t input_bytes_read = 0;
  int publishing_node = -1;
  std::map<int, int64_t> input_at_last_status;
  std::unique_ptr<ReplayBus> bus;
  bus = std::make_unique<ReplayBus>([&](const std::string& channel, const void* data, int size) {
    if (channel != kStatusChannel) {
      ++summary.new_outputs[channel];
      write(bus->now_utime(), channel, data, size);
      return;
    }
    process_status_t status{};
    std::string reason;
    if (!DecodeChecked(data, size, &status, &reason)) return;  // Our own encoding: cannot happen.
    status.host = "replay";
    status.pid = 0;
    std::vector<uint8_t> buffer(static_cast<size_t>(status.getEncodedSize()));
    status.encode(buffer.data(), 0, static_cast<int>(buffer.size()));
    const auto last = input_at_last_status.find(publishing_node);
    if (last != input_at_last_status.end() &&
        input_bytes_read - last->second <
            kStatusRepeatInputRatio * LoggedSize(kReplayStatusChannel, buffer.size())) {
      ++summary.heartbeats_thinned;
      return;
    }
    input_at_last_status[publishing_node] = input_bytes_read;
    ++summary.new_outputs[kReplayStatusChannel];
    write(bus->now_utime(), kReplayStatusChannel, buffer.data(), static_cast<int>(buffer.size()));
  });

  // The recorded outputs the new ones replace.
  std::vector<std::string> replaced;
  if (options.trilat) replaced.push_back(kUltrasoundPoseChannel);
  if (options.fusion) replaced.push_back(options.fusion_options.fused_channel);
  if (options.camera) replaced.push_back(kCameraPoseChannel);
  if (options.site_message) replaced.push_back(kSiteChannel);
  std::vector<uint8_t> site_bytes;
  int64_t next_site_utime = 0;
  int64_t input_bytes_since_site = 0;

  // The nodes start at the log's first event, as the live ones started
  // before it; their uptime in REPLAY_STATUS is log time.
  std::optional<TrilatNode> trilat;
  std::optional<FusionNode> fusion;
  // Heap-held: a node's subscriptions capture its address.
  std::vector<std::unique_ptr<CameraNode>> cameras;
  CameraNodeOptions camera_options = options.camera_options;
  // OnMarkerPixels never measures time, and nothing else may read a clock.
  camera_options.steady_clock = [] { return int64_t{0}; };
  const int64_t tick_us = int64_t{options.tick_period_ms} * 1000;
  int64_t next_tick = 0;
  auto tick = [&](int64_t now) {
    bus->set_now_utime(now);
    publishing_node = 0;
    if (trilat) trilat->Tick(now);
    publishing_node = 1;
    if (fusion) fusion->Tick(now);
    for (size_t i = 0; i < cameras.size(); ++i) {
      publishing_node = 2 + static_cast<int>(i);
      cameras[i]->Tick(now);
    }
    publishing_node = -1;
    ++summary.ticks;
  };

  LogEvent event;
  EventTimeScreen screen(in);
  while (write_error.empty() && screen.Next(&event)) {
    input_bytes_read += LoggedSize(event.channel, event.data.size());
    if (summary.events_read == 0) {
      summary.first_utime = event.utime;
      bus->set_now_utime(event.utime);
      if (options.trilat) trilat.emplace(site, bus.get(), options.trilat_options, event.utime);
      if (options.fusion) fusion.emplace(site, bus.get(), options.fusion_options, event.utime);
      // The node keeps a reference to its camera: the site's own entry.
      for (const Camera& camera : site.cameras) {
        if (!options.camera) break;
        auto it = options.camera_calibrations.find(camera.id);
        if (it == options.camera_calibrations.end()) continue;
        auto node = std::make_unique<CameraNode>(site, camera, it->second, bus.get(),
                                                 camera_options, event.utime);
        std::string why;
        if (!node->ok(&why)) {
          summary.ok = false;
          summary.error = "camera " + std::to_string(camera.id) + ": " + why;
          return summary;
        }
        CameraNode* raw = node.get();
        bus->Subscribe<marker_pixels_t>(kMarkerPixelsChannel,
                                        [raw](const marker_pixels_t& m, const MessageInfo& info) {
                                          raw->OnMarkerPixels(m, info.recv_utime);
                                        });
        cameras.push_back(std::move(node));
      }
      next_tick = event.utime;
    }
    ++summary.events_read;
    summary.last_utime = event.utime;
    // The ticks a live node would have had before this event arrived. A gap
    // longer than kMaxCatchUpUs (a pause, a sparse log, a timestamp that
    // jumps) is crossed with one tick at the event's time; the grid ticks
    // in it are counted, not run.
    const int64_t gap_us = SaturatingDifferenceUs(event.utime, next_tick);
    if (gap_us > kMaxCatchUpUs) {
      summary.ticks_skipped += gap_us / tick_us;
      next_tick = event.utime;
    }
    while (next_tick <= event.utime) {
      tick(next_tick);
      if (next_tick == INT64_MAX) break;
      next_tick = SaturatingAddUs(next_tick, tick_us);
    }
    if (options.site_message && event.utime >= next_site_utime &&
        (site_bytes.empty() ||
         input_bytes_since_site >=
             kSiteRepeatInputRatio * static_cast<int64_t>(site_bytes.size()))) {
      site_t site_msg = *options.site_message;
      site_msg.utime = event.utime;
      site_bytes.assign(static_cast<size_t>(site_msg.getEncodedSize()), 0);
      site_msg.encode(site_bytes.data(), 0, static_cast<int>(site_bytes.size()));
      write(event.utime, kSiteChannel, site_bytes.data(), static_cast<int>(site_bytes.size()));
      ++summary.new_outputs[kSiteChannel];
      next_site_utime = SaturatingAddUs(event.utime, kSitePeriodUs);
      input_bytes_since_site = 0;
    }
    bool is_replaced = false;
    for (const std::string& channel : replaced)
      is_replaced = is_replaced || event.channel == channel;
    if (is_replaced) {
      ++summary.old_outputs_dropped[event.channel];
      continue;
    }
    if (options.restamp_ranges && event.channel == kRangesChannel) {
      RestampRanges(site, &event.data, &summary);
    }
    const int size = static_cast<int>(event.data.size());
    std::string why;
    if (!LogWriter::Loggable(event.channel, size, &why)) {
      // LogReader reads channels LCM's tools cannot replay (up to 999
      // bytes); such an event is counted and left out, not a failed run.
      ++summary.inputs_not_loggable;
      continue;
    }
    write(event.utime, event.channel, event.data.data(), size);
    ++summary.inputs_written;
    input_bytes_since_site += size;
    bus->set_now_utime(event.utime);
    bus->Inject(event.channel, event.data.data(), size);
  }
  if (summary.events_read > 0 && write_error.empty()) {
    tick(summary.last_utime);
    // Each node's last word is always written.
    input_at_last_status.clear();
    publishing_node = 0;
    if (trilat) {
      trilat->Stop(summary.last_utime);
      summary.trilat_status = trilat->status().Make(summary.last_utime, nullptr);
    }
    publishing_node = 1;
    if (fusion) {
      fusion->Stop(summary.last_utime);
      summary.fusion_status = fusion->status().Make(summary.last_utime, nullptr);
    }
    for (size_t i = 0; i < cameras.size(); ++i) {
      publishing_node = 2 + static_cast<int>(i);
      cameras[i]->Stop(summary.last_utime);
      summary.camera_status.push_back(cameras[i]->status().Make(summary.last_utime, nullptr));
    }
    publishing_node = -1;
  }
  if (write_error.empty()) out->Flush(&write_error);
  summary.events_time_refused = screen.refused();
  summary.events_read += screen.refused();
  summary.refused = bus->stats().refused;
  summary.damaged = in->damaged();
  summary.bytes_skipped = in->bytes_skipped();
  summary.damage_regions = in->damage_regions();
  summary.damage = in->DamageSummary();
  if (!write_error.empty()) {
    summary.ok = false;
    summary.error = write_error;
  }
  return summary;
}

PipelineReplaySummary ReplayPipelineFile(const std::string& in_path, const Site& site,
                                         const PipelineReplayOptions& options,
                                         const std::string& out_path, bool overwrite) {
  PipelineReplaySummary summary;
  if (!options.IsValid(&summary.error)) return summary;
  struct stat in_stat {};
  struct stat out_stat {};
  if (::stat(out_path.c_str(), &out_stat) == 0) {
    if (::stat(in_path.c_str(), &in_stat) == 0 && in_stat.st_dev == out_stat.st_dev &&
        in_stat.st_ino == out_stat.st_ino) {
      summary.error = out_path + ": is the input log; the replay writes a new one";
      return summary;
    }
    if (!overwrite) {
      summary.error = out_path + ": exists (give --force to replace it)";
      return summary;
    }
  }
  auto reader = LogReader::Open(in_path, &summary.error);
  if (reader == nullptr) return summary;
  // The new log is written to a hidden partial file beside out_path and
  // renamed into place only when the whole replay was written and synced:
  // a full disk leaves no new log that stops short (issue #28).
  // A device or FIFO (/dev/null) cannot be replaced: written in place.
  if (::stat(out_path.c_str(), &out_stat) == 0 && !S_ISREG(out_stat.st_mode)) {
    auto writer = LogWriter::Create(out_path, overwrite, &summary.error);
    if (writer == nullptr) return summary;
    return ReplayPipeline(reader.get(), site, options, writer.get());
  }
  std::string target = out_path;  // A link is replaced at the file it names.
  if (char* real = ::realpath(out_path.c_str(), nullptr)) {
    target = real;
    std::free(real);
  }
  const std::string partial = PartialPathFor(target) + "-" + std::to_string(::getpid());
  auto writer = LogWriter::Create(partial, /*overwrite=*/true, &summary.error);
  if (writer == nullptr) {
    summary.error =
        out_path + ": cannot create: " + summary.error.substr(summary.error.rfind(": ") + 2);
    return summary;
  }
  summary = ReplayPipeline(reader.get(), site, options, writer.get());
  std::string sync_error;
  if (summary.ok && !writer->Sync(&sync_error)) {
    summary.ok = false;
    summary.error = sync_error;
  }
  writer.reset();
  if (summary.ok && std::rename(partial.c_str(), target.c_str()) != 0) {
    summary.ok = false;
    summary.error = out_path + ": cannot write: " + std::strerror(errno);
  }
  if (!summary.ok) {
    ::unlink(partial.c_str());
    // A failed write of the new log names the file the user gave, not the
    // partial one, as every writer does: "OUT: cannot write: REASON".
    if (summary.error.rfind(partial, 0) == 0) {
      summary.error =
          out_path + ": cannot write: " + summary.error.substr(summary.error.rfind(": ") + 2);
    }
  }
  return summary;
}

}  // namespace roomfix
