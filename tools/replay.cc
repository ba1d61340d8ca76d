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

namespace {

// One replay of a log through the re-run nodes: the state ReplayPipeline's
// steps share. Members are destroyed in reverse order: the nodes before the
// bus they subscribe to.
class PipelineReplay {
 public:
  PipelineReplay(const Site& site, const PipelineReplayOptions& options, LogWriter* out)
      : site_(site), options_(options), out_(out) {
    summary_.ok = true;
    bus_ = std::make_unique<ReplayBus>([this](const std::string& channel, const void* data,
                                              int size) { OnPublish(channel, data, size); });
    // The recorded outputs the new ones replace.
    if (options.trilat) replaced_.push_back(kUltrasoundPoseChannel);
    if (options.fusion) replaced_.push_back(options.fusion_options.fused_channel);
    if (options.camera) replaced_.push_back(kCameraPoseChannel);
    if (options.site_message) replaced_.push_back(kSiteChannel);
    camera_options_ = options.camera_options;
    // OnMarkerPixels never measures time, and nothing else may read a clock.
    camera_options_.steady_clock = [] { return int64_t{0}; };
  }

  PipelineReplaySummary Run(LogReader* in) {
    LogEvent event;
    EventTimeScreen screen(in);
    while (write_error_.empty() && screen.Next(&event)) {
      input_bytes_read_ += LoggedSize(event.channel, event.data.size());
      if (summary_.events_read == 0 && !StartNodes(event.utime)) return summary_;
      ++summary_.events_read;
      summary_.last_utime = event.utime;
      CatchUp(event.utime);
      MaybeWriteSite(event.utime);
      PassOn(&event);
    }
    if (summary_.events_read > 0 && write_error_.empty()) StopNodes();
    if (write_error_.empty()) out_->Flush(&write_error_);
    summary_.events_time_refused = screen.refused();
    summary_.events_read += screen.refused();
    summary_.refused = bus_->stats().refused;
    summary_.damaged = in->damaged();
    summary_.bytes_skipped = in->bytes_skipped();
    summary_.damage_regions = in->damage_regions();
    summary_.damage = in->DamageSummary();
    if (!write_error_.empty()) {
      summary_.ok = false;
      summary_.error = write_error_;
    }
    return summary_;
  }

 private:
  void Write(int64_t utime, const std::string& channel, const void* data, int size) {
    if (!write_error_.empty()) return;
    out_->Write(utime, channel, data, size, &write_error_);
  }

  // What a node publishes: into the new log, its heartbeats on
  // REPLAY_STATUS, thinned (kStatusRepeatInputRatio).
  void OnPublish(const std::string& channel, const void* data, int size) {
    if (channel != kStatusChannel) {
      ++summary_.new_outputs[channel];
      Write(bus_->now_utime(), channel, data, size);
      return;
    }
    process_status_t status{};
    std::string reason;
    if (!DecodeChecked(data, size, &status, &reason)) return;  // Our own encoding: cannot happen.
    status.host = "replay";
    status.pid = 0;
    std::vector<uint8_t> buffer(static_cast<size_t>(status.getEncodedSize()));
    status.encode(buffer.data(), 0, static_cast<int>(buffer.size()));
    const auto last = input_at_last_status_.find(publishing_node_);
    if (last != input_at_last_status_.end() &&
        input_bytes_read_ - last->second <
            kStatusRepeatInputRatio * LoggedSize(kReplayStatusChannel, buffer.size())) {
      ++summary_.heartbeats_thinned;
      return;
    }
    input_at_last_status_[publishing_node_] = input_bytes_read_;
    ++summary_.new_outputs[kReplayStatusChannel];
    Write(bus_->now_utime(), kReplayStatusChannel, buffer.data(), static_cast<int>(buffer.size()));
  }

  // The nodes start at the log's first event, as the live ones started
  // before it; their uptime in REPLAY_STATUS is log time. False (the
  // summary saying why) when a camera node cannot run.
  bool StartNodes(int64_t utime) {
    summary_.first_utime = utime;
    bus_->set_now_utime(utime);
    if (options_.trilat) trilat_.emplace(site_, bus_.get(), options_.trilat_options, utime);
    if (options_.fusion) fusion_.emplace(site_, bus_.get(), options_.fusion_options, utime);
    // The node keeps a reference to its camera: the site's own entry.
    for (const Camera& camera : site_.cameras) {
      if (!options_.camera) break;
      auto it = options_.camera_calibrations.find(camera.id);
      if (it == options_.camera_calibrations.end()) continue;
      auto node = std::make_unique<CameraNode>(site_, camera, it->second, bus_.get(),
                                               camera_options_, utime);
      std::string why;
      if (!node->ok(&why)) {
        summary_.ok = false;
        summary_.error = "camera " + std::to_string(camera.id) + ": " + why;
        return false;
      }
      CameraNode* raw = node.get();
      bus_->Subscribe<marker_pixels_t>(kMarkerPixelsChannel,
                                       [raw](const marker_pixels_t& m, const MessageInfo& info) {
                                         raw->OnMarkerPixels(m, info.recv_utime);
                                       });
      cameras_.push_back(std::move(node));
    }
    next_tick_ = utime;
    return true;
  }

  // Every node's tick at `now`. The node publishing is the one being ticked
  // or stopped (camera nodes share a process name): trilat 0, fusion 1, the
  // cameras 2...
  void Tick(int64_t now) {
    bus_->set_now_utime(now);
    publishing_node_ = 0;
    if (trilat_) trilat_->Tick(now);
    publishing_node_ = 1;
    if (fusion_) fusion_->Tick(now);
    for (size_t i = 0; i < cameras_.size(); ++i) {
      publishing_node_ = 2 + static_cast<int>(i);
      cameras_[i]->Tick(now);
    }
    publishing_node_ = -1;
    ++summary_.ticks;
  }

  // The ticks a live node would have had before an event at `utime`
  // arrived. A gap longer than kMaxCatchUpUs (a pause, a sparse log, a
  // timestamp that jumps) is crossed with one tick at the event's time; the
  // grid ticks in it are counted, not run.
  void CatchUp(int64_t utime) {
    const int64_t tick_us = int64_t{options_.tick_period_ms} * 1000;
    const int64_t gap_us = SaturatingDifferenceUs(utime, next_tick_);
    if (gap_us > kMaxCatchUpUs) {
      summary_.ticks_skipped += gap_us / tick_us;
      next_tick_ = utime;
    }
    while (next_tick_ <= utime) {
      Tick(next_tick_);
      if (next_tick_ == INT64_MAX) break;
      next_tick_ = SaturatingAddUs(next_tick_, tick_us);
    }
  }

  // A new site's SITE, every kSitePeriodUs and no more often than
  // kSiteRepeatInputRatio of the input allows.
  void MaybeWriteSite(int64_t utime) {
    if (!options_.site_message || utime < next_site_utime_ ||
        (!site_bytes_.empty() &&
         input_bytes_since_site_ <
             kSiteRepeatInputRatio * static_cast<int64_t>(site_bytes_.size()))) {
      return;
    }
    site_t site_msg = *options_.site_message;
    site_msg.utime = utime;
    site_bytes_.assign(static_cast<size_t>(site_msg.getEncodedSize()), 0);
    site_msg.encode(site_bytes_.data(), 0, static_cast<int>(site_bytes_.size()));
    Write(utime, kSiteChannel, site_bytes_.data(), static_cast<int>(site_bytes_.size()));
    ++summary_.new_outputs[kSiteChannel];
    next_site_utime_ = SaturatingAddUs(utime, kSitePeriodUs);
    input_bytes_since_site_ = 0;
  }

  // A recorded event: dropped when a re-run node replaces its channel,
  // otherwise copied into the new log and delivered to the nodes.
  void PassOn(LogEvent* event) {
    if (std::find(replaced_.begin(), replaced_.end(), event->channel) != replaced_.end()) {
      ++summary_.old_outputs_dropped[event->channel];
      return;
    }
    if (options_.restamp_ranges && event->channel == kRangesChannel) {
      RestampRanges(site_, &event->data, &summary_);
    }
    const int size = static_cast<int>(event->data.size());
    std::string why;
    if (!LogWriter::Loggable(event->channel, size, &why)) {
      // LogReader reads channels LCM's tools cannot replay (up to 999
      // bytes); such an event is counted and left out, not a failed run.
      ++summary_.inputs_not_loggable;
      return;
    }
    Write(event->utime, event->channel, event->data.data(), size);
    ++summary_.inputs_written;
    input_bytes_since_site_ += size;
    bus_->set_now_utime(event->utime);
    bus_->Inject(event->channel, event->data.data(), size);
  }

  // A last tick at the last event, then each node's last word, always
  // written.
  void StopNodes() {
    const int64_t last = summary_.last_utime;
    Tick(last);
    input_at_last_status_.clear();
    publishing_node_ = 0;
    if (trilat_) {
      trilat_->Stop(last);
      summary_.trilat_status = trilat_->status().Make(last, nullptr);
    }
    publishing_node_ = 1;
    if (fusion_) {
      fusion_->Stop(last);
      summary_.fusion_status = fusion_->status().Make(last, nullptr);
    }
    for (size_t i = 0; i < cameras_.size(); ++i) {
      publishing_node_ = 2 + static_cast<int>(i);
      cameras_[i]->Stop(last);
      summary_.camera_status.push_back(cameras_[i]->status().Make(last, nullptr));
    }
    publishing_node_ = -1;
  }

  const Site& site_;
  const PipelineReplayOptions& options_;
  LogWriter* out_;
  PipelineReplaySummary summary_;
  std::string write_error_;
  // Input bytes read so far, and the input read when each node last had a
  // heartbeat written (kStatusRepeatInputRatio); the node publishing now.
  int64_t input_bytes_read_ = 0;
  int publishing_node_ = -1;
  std::map<int, int64_t> input_at_last_status_;
  std::vector<std::string> replaced_;
  std::vector<uint8_t> site_bytes_;
  int64_t next_site_utime_ = 0;
  int64_t input_bytes_since_site_ = 0;
  CameraNodeOptions camera_options_;
  int64_t next_tick_ = 0;
  std::unique_ptr<ReplayBus> bus_;
  std::optional<TrilatNode> trilat_;
  std::optional<FusionNode> fusion_;
  // Heap-held: a node's subscriptions capture its address.
  std::vector<std::unique_ptr<CameraNode>> cameras_;
};

}  // namespace

PipelineReplaySummary ReplayPipeline(LogReader* in, const Site& site,
                                     const PipelineReplayOptions& options, LogWriter* out) {
  PipelineReplaySummary summary;
  if (!options.IsValid(&summary.error)) return summary;
  return PipelineReplay(site, options, out).Run(in);
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
