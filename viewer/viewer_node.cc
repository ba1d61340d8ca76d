#include "viewer/viewer_node.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>

#include "core/analysis/track_error.h"
#include "msgio/message_conversions.h"
#include "msgio/received.h"
#include "msgio/time_limits.h"
#include "roomfix/detector_view_request_t.hpp"
#include "roomfix/detector_view_t.hpp"
#include "roomfix/image_t.hpp"
#include "roomfix/marker_pixels_t.hpp"
#include "roomfix/pose2d_t.hpp"
#include "roomfix/process_status_t.hpp"
#include "roomfix/range_set_t.hpp"
#include "viewer/footprint.h"

namespace roomfix {
namespace {

// Rates and latencies are taken over the last few seconds, so a source that
// stops shows it within that time.
constexpr int64_t kRateWindowUs = 5'000'000;
constexpr size_t kLatencySamples = 30;
// Per track: receive times in the rate window and trail points. A steady
// source is 30 Hz at most (5 s: 150 samples, a 10 s trail: 300 points); the
// caps only bite on a flood, and keep the rate right (it is taken over the
// newest samples) and a frame's drawing bounded.
constexpr size_t kMaxRateSamples = 1000;
constexpr size_t kMaxTrailPoints = 2000;

}  // namespace

bool ViewerNodeOptions::IsValid(std::string* error) const {
  if (!(trail_s >= 0.0 && trail_s <= 3600.0)) {
    *error = "trail must be 0 to 3600 s";
    return false;
  }
  if (!(stale_after_s > 0.0 && stale_after_s <= 3600.0)) {
    *error = "stale time must be in (0, 3600] s";
    return false;
  }
  if (!(detector_view_rate_hz > 0.0 && detector_view_rate_hz <= 5.0) ||
      !(detector_view_duration_s > 0.0 && detector_view_duration_s <= 600.0)) {
    *error = "detector view rate must be in (0, 5] Hz and its duration in (0, 600] s";
    return false;
  }
  if (!(rejected_range_tolerance_m > 0.0)) {
    *error = "rejected-range tolerance must be positive";
    return false;
  }
  if (!(forget_after_s >= stale_after_s && forget_after_s <= 3600.0)) {
    *error = "forget time must be at least the stale time and at most 3600 s";
    return false;
  }
  if (!(forget_process_after_s >= stale_after_s && forget_process_after_s <= 86400.0)) {
    *error = "process forget time must be at least the stale time and at most 86400 s";
    return false;
  }
  if (max_processes < 1) {
    *error = "max_processes must be at least 1";
    return false;
  }
  return true;
}

std::map<int, std::string> CalibrationTextsById(const LoadedSite& loaded) {
  std::map<int, std::string> texts;
  for (size_t i = 0; i < loaded.site.cameras.size(); ++i) {
    const std::string* text = SiteCalibrationText(loaded, i);
    if (text != nullptr) texts.emplace(loaded.site.cameras[i].id, *text);
  }
  return texts;
}

ViewerNode::ViewerNode(const Site& site, Bus* bus, const ViewerNodeOptions& options,
                       int64_t start_utime)
    : bus_(bus), options_(options), status_("roomfix_viewer", start_utime) {
  state_.site = site;
  state_.footprints =
      viewer::CameraFootprints(site, options.calibration_texts, viewer::FootprintHeight(site));
  state_.trail_s = options.trail_s;
  state_.stale_after_s = options.stale_after_s;
  state_.now_utime = start_utime;
  state_.detector_view_wanted = options.detector_view_at_start;  // sent by the first Tick
  status_.SetState(process_status_t::STATE_RUNNING);

  subscriptions_.Add(bus_->Subscribe<pose2d_t>(
      kPoseChannelPattern,
      [this](const pose2d_t& p, const MessageInfo& info) { OnPose(p, info); }));
  subscriptions_.Add(bus_->Subscribe<range_set_t>(
      kRangesChannel,
      [this](const range_set_t& s, const MessageInfo& info) { OnRangeSet(s, info); }));
  subscriptions_.Add(bus_->Subscribe<process_status_t>(
      kStatusChannel,
      [this](const process_status_t& s, const MessageInfo& info) { OnStatus(s, info); }));
  subscriptions_.Add(
      bus_->Subscribe<site_t>(kSiteChannel, [this](const site_t& m, const MessageInfo& info) {
        ++messages_;
        NoteSites(m.utime, [&] { site_hashes_.ObserveSite(m, info.recv_utime); });
      }));
  SubscribeCamera();
}

void ViewerNode::OnPose(const pose2d_t& msg, const MessageInfo& info) {
  status_.AddInputs();
  ++messages_;
  // Drawn by the source the pose states, whatever its channel.
  const auto source = static_cast<PoseSource>(msg.source);
  if (!viewer::Drawn(source)) {
    status_.Reject("unknown_source");
    return;
  }
  Pose2d p;
  std::string why;
  InputProblem problem = InputProblem::kNone;
  if (!ReceivePose(msg, state_.site, info.recv_utime, &p, &why, &problem)) {
    status_.Reject(InputProblemCounter(problem));
    return;
  }
  viewer::TrackView* t = FindTrack(source, p.robot_id);
  t->recv_utime = info.recv_utime;
  // ReceivePose let NaN through only in a LOST pose.
  t->lost = p.status == PoseStatus::kLost;
  TrackHistory& h = history_[{static_cast<int>(source), p.robot_id}];
  if (h.recv_utimes.empty() && h.first_recv_utime == 0) h.first_recv_utime = info.recv_utime;
  h.recv_utimes.push_back(info.recv_utime);
  if (h.recv_utimes.size() > kMaxRateSamples) h.recv_utimes.pop_front();
  if (p.latency_us > 0 || source != PoseSource::kGroundTruth) {
    h.latencies_ms.push_back(p.latency_us * 1e-3);
    if (h.latencies_ms.size() > kLatencySamples) h.latencies_ms.pop_front();
  }
  if (t->lost) return;
  t->utime = p.utime;
  t->x_m = p.x_m;
  t->y_m = p.y_m;
  t->heading_rad = p.heading_rad;
  t->cov_xx_m2 = p.covariance[0][0];
  t->cov_xy_m2 = p.covariance[0][1];
  t->cov_yy_m2 = p.covariance[1][1];
  t->degraded = p.status == PoseStatus::kDegraded;
  // Which camera: only the site's ids (a sender can invent them).
  if (source == PoseSource::kCamera && state_.site.FindCamera(p.camera_id) != nullptr) {
    t->camera_seen_recv_utime[p.camera_id] = info.recv_utime;
  }
  t->trail.push_back({p.utime, p.x_m, p.y_m});
  if (t->trail.size() > kMaxTrailPoints) t->trail.pop_front();
}

void ViewerNode::OnRangeSet(const range_set_t& s, const MessageInfo& info) {
  status_.AddInputs();
  ++messages_;
  std::string why;
  InputProblem problem = InputProblem::kNone;
  if (!CheckRangeSet(s, state_.site, info.recv_utime, &why, &problem)) {
    status_.Reject(InputProblemCounter(problem));
    return;
  }
  const Beacon* beacon = state_.site.FindBeacon(s.beacon_id);
  if (beacon == nullptr) {
    status_.Reject("unknown_beacon");
    return;
  }
  // A range that is not a finite number refuses the whole set (the beacon's
  // last picture stays); a range from a receiver the site does not list is
  // left out of it.
  std::vector<const Receiver*> receivers(s.ranges.size());
  std::vector<InputProblem> problems(s.ranges.size());
  for (size_t i = 0; i < s.ranges.size(); ++i) {
    receivers[i] = CheckRange(s.ranges[i], state_.site, &why, &problems[i]);
    if (problems[i] == InputProblem::kNonFinite) {
      status_.Reject(InputProblemCounter(problems[i]));
      return;
    }
  }
  viewer::RangeSetView view;
  view.beacon_id = s.beacon_id;
  view.beacon_height_m = beacon->height_m;
  view.utime = s.utime;
  view.recv_utime = info.recv_utime;
  for (size_t i = 0; i < s.ranges.size(); ++i) {
    if (receivers[i] == nullptr) {
      status_.Reject(InputProblemCounter(problems[i]));
      continue;
    }
    const range_t& r = s.ranges[i];
    viewer::RangeView rv;
    rv.receiver_id = r.receiver_id;
    rv.receiver_m = {r.receiver_position_m[0], r.receiver_position_m[1], r.receiver_position_m[2]};
    rv.range_m = r.range_m;
    view.ranges.push_back(rv);
  }
  auto it = std::find_if(state_.range_sets.begin(), state_.range_sets.end(),
                         [&](const viewer::RangeSetView& v) { return v.beacon_id == s.beacon_id; });
  if (it == state_.range_sets.end()) {
    state_.range_sets.push_back(std::move(view));
  } else {
    *it = std::move(view);
  }
}

void ViewerNode::OnStatus(const process_status_t& s, const MessageInfo& info) {
  ++messages_;
  // The output rate divides by the difference of two heartbeats' utimes,
  // which must be sane to be subtracted at all.
  if (!UtimeNear(s.utime, info.recv_utime)) {
    status_.Reject("utime_out_of_range");
    return;
  }
  // One row per process name and host: a restarted process (new pid) takes
  // over its row instead of leaving a stale one behind.
  const std::string key = s.process + "@" + s.host;
  auto it =
      std::find_if(state_.processes.begin(), state_.processes.end(),
                   [&](const viewer::ProcessView& p) { return p.name + "@" + p.host == key; });
  if (it == state_.processes.end()) {
    Expire(info.recv_utime);
    if (static_cast<int>(state_.processes.size()) >= options_.max_processes) {
      status_.Reject("too_many_processes");
      return;
    }
    state_.processes.emplace_back();
    it = state_.processes.end() - 1;
  }
  StatusHistory& h = status_history_[key];
  it->output_rate_hz = h.prev_utime > 0 && s.utime > h.prev_utime
                           ? (s.outputs - h.prev_outputs) / ((s.utime - h.prev_utime) * 1e-6)
                           : 0.0;
  h.prev_utime = s.utime;
  h.prev_outputs = s.outputs;
  it->name = s.process;
  it->host = s.host;
  it->pid = s.pid;
  it->state = s.state;
  it->inputs = s.inputs;
  it->outputs = s.outputs;
  it->dropped = s.dropped;
  it->rejected.clear();
  for (const counter_t& c : s.rejected) it->rejected.push_back({c.name, c.count});
  it->losses.clear();
  for (const counter_t& c : s.counters) {
    if (c.name.rfind("dropped_", 0) == 0 || c.name.rfind("fragments_", 0) == 0) {
      it->losses.push_back({c.name, c.count});
    }
  }
  std::sort(it->rejected.begin(), it->rejected.end(),
            [](const auto& a, const auto& b) { return a.second > b.second; });
  it->last_error = s.last_error;
  it->recv_utime = info.recv_utime;
  NoteSites(s.utime, [&] { site_hashes_.ObserveStatus(s, info.recv_utime); });
}

void ViewerNode::SubscribeCamera() {
  subscriptions_.Add(
      bus_->Subscribe<image_t>(kCameraPreviewChannel, [this](const image_t& m, const MessageInfo&) {
        ++messages_;
        state_.has_preview = true;
        viewer::PreviewView& p = state_.preview;
        if (p.camera_id != m.camera_id || p.utime != m.utime) p.markers.clear();
        p.camera_id = m.camera_id;
        p.utime = m.utime;
        p.encoded = m.data;
        preview_scale_ =
            m.source_width_px > 0 ? static_cast<double>(m.width_px) / m.source_width_px : 1.0;
      }));
  SubscribeDetectorView();
  subscriptions_.Add(bus_->Subscribe<marker_pixels_t>(
      kMarkerPixelsChannel, [this](const marker_pixels_t& m, const MessageInfo&) {
        ++messages_;
        // The markers of the newest frame, in the preview's pixels.
        if (!state_.has_preview || m.camera_id != state_.preview.camera_id) return;
        state_.preview.markers.clear();
        for (const marker_t& k : m.markers) {
          state_.preview.markers.push_back({k.u_px * preview_scale_, k.v_px * preview_scale_,
                                            k.radius_px * preview_scale_, k.colour_class});
        }
      }));
}

void ViewerNode::SubscribeDetectorView() {
  subscriptions_.Add(bus_->Subscribe<detector_view_t>(
      kDetectorViewChannel, [this](const detector_view_t& m, const MessageInfo&) {
        ++messages_;
        // Only an image the renderer can place: a PNG of a region inside its
        // frame (the decoder checks the PNG itself).
        if (m.format != "png" || m.source_width_px <= 0 || m.source_height_px <= 0 ||
            m.region_u_px < 0 || m.region_v_px < 0 || m.region_width_px <= 0 ||
            m.region_height_px <= 0 || m.region_width_px > m.source_width_px - m.region_u_px ||
            m.region_height_px > m.source_height_px - m.region_v_px) {
          status_.Reject("bad_detector_view");
          return;
        }
        const DetectorViewImage in = FromMessage(m);
        viewer::DetectorViewView& v = state_.detector_view;
        state_.has_detector_view = true;
        v.camera_id = in.camera_id;
        v.utime = in.utime;
        v.encoded = in.data;
        v.region_u_px = in.region_u_px;
        v.region_v_px = in.region_v_px;
        v.region_width_px = in.region_width_px;
        v.region_height_px = in.region_height_px;
        v.source_width_px = in.source_width_px;
        v.source_height_px = in.source_height_px;
        v.robots.clear();
        for (const DetectorViewRobot& r : in.robots) {
          v.robots.push_back({r.robot_id, r.reason == detector_view_robot_t::REASON_FOUND, r.text});
        }
      }));
}

void ViewerNode::RequestDetectorView(int64_t now_utime) {
  DetectorViewRequest r;
  r.utime = now_utime;
  r.camera_id = -1;
  r.rate_hz = options_.detector_view_rate_hz;
  r.duration_s = options_.detector_view_duration_s;
  if (bus_->Publish(kDetectorViewRequestChannel, ToMessage(r))) {
    status_.Count("detector_view_requests");
  }
}

viewer::TrackView* ViewerNode::FindTrack(PoseSource source, int robot_id) {
  for (viewer::TrackView& t : state_.tracks) {
    if (t.source == source && t.robot_id == robot_id) return &t;
  }
  state_.tracks.emplace_back();
  state_.tracks.back().source = source;
  state_.tracks.back().robot_id = robot_id;
  std::sort(state_.tracks.begin(), state_.tracks.end(),
            [](const viewer::TrackView& a, const viewer::TrackView& b) {
              return std::make_pair(a.robot_id, static_cast<int>(a.source)) <
                     std::make_pair(b.robot_id, static_cast<int>(b.source));
            });
  for (viewer::TrackView& t : state_.tracks) {
    if (t.source == source && t.robot_id == robot_id) return &t;
  }
  return nullptr;
}

void ViewerNode::MarkRejectedRanges() {
  // A range is rejected when it disagrees with the ultrasonic fix of its
  // own firing (same utime); without that fix nothing is marked.
  for (viewer::RangeSetView& set : state_.range_sets) {
    int robot_id = -1;
    for (const Robot& r : state_.site.robots) {
      if (r.beacon_id && *r.beacon_id == set.beacon_id) robot_id = r.id;
    }
    const viewer::TrackView* fix = nullptr;
    for (const viewer::TrackView& t : state_.tracks) {
      if (t.source == PoseSource::kUltrasound && t.robot_id == robot_id && t.utime == set.utime &&
          !t.lost) {
        fix = &t;
      }
    }
    for (viewer::RangeView& r : set.ranges) {
      if (fix == nullptr) {
        r.rejected = false;
        continue;
      }
      const double dx = r.receiver_m[0] - fix->x_m;
      const double dy = r.receiver_m[1] - fix->y_m;
      const double dz = r.receiver_m[2] - set.beacon_height_m;
      r.rejected = std::abs(std::sqrt(dx * dx + dy * dy + dz * dz) - r.range_m) >
                   options_.rejected_range_tolerance_m;
    }
  }
}

void ViewerNode::Expire(int64_t now_utime) {
  const auto forget_us = static_cast<int64_t>(options_.forget_after_s * 1e6);
  const auto forget_process_us = static_cast<int64_t>(options_.forget_process_after_s * 1e6);
  auto silent = [&](int64_t recv_utime, int64_t after_us) {
    return SaturatingDifferenceUs(now_utime, recv_utime) > after_us;
  };
  auto& tracks = state_.tracks;
  tracks.erase(std::remove_if(tracks.begin(), tracks.end(),
                              [&](const viewer::TrackView& t) {
                                if (!silent(t.recv_utime, forget_us)) return false;
                                history_.erase({static_cast<int>(t.source), t.robot_id});
                                return true;
                              }),
               tracks.end());
  auto& sets = state_.range_sets;
  sets.erase(std::remove_if(
                 sets.begin(), sets.end(),
                 [&](const viewer::RangeSetView& v) { return silent(v.recv_utime, forget_us); }),
             sets.end());
  auto& processes = state_.processes;
  processes.erase(std::remove_if(processes.begin(), processes.end(),
                                 [&](const viewer::ProcessView& p) {
                                   if (!silent(p.recv_utime, forget_process_us)) return false;
                                   status_history_.erase(p.name + "@" + p.host);
                                   return true;
                                 }),
                  processes.end());
}

const viewer::ViewState& ViewerNode::StateAt(int64_t now_utime) {
  Expire(now_utime);
  state_.now_utime = now_utime;
  state_.trail_s = options_.trail_s;
  state_.stale_after_s = options_.stale_after_s;
  const auto trail_us = static_cast<int64_t>(options_.trail_s * 1e6);
  for (viewer::TrackView& t : state_.tracks) {
    // Trails are kept by measurement time relative to the track's newest
    // pose, so a replayed log keeps its trails whatever the wall clock.
    while (!t.trail.empty() && t.trail.front().utime < t.utime - trail_us) t.trail.pop_front();
    TrackHistory& h = history_[{static_cast<int>(t.source), t.robot_id}];
    while (!h.recv_utimes.empty() && h.recv_utimes.front() < now_utime - kRateWindowUs) {
      h.recv_utimes.pop_front();
    }
    // Over a second or more of messages, intervals per second (exact for a
    // steady stream); a burst with one receive time counts its messages
    // over at least a second rather than as an infinite rate.
    const double span_s =
        h.recv_utimes.empty() ? 0.0 : (h.recv_utimes.back() - h.recv_utimes.front()) * 1e-6;
    const double heard_s = (now_utime - h.first_recv_utime) * 1e-6;
    t.rate_hz = span_s >= 1.0
                    ? (h.recv_utimes.size() - 1) / span_s
                    : h.recv_utimes.size() / std::max(1.0, std::min(kRateWindowUs * 1e-6, heard_s));
    t.latency_ms = h.latencies_ms.empty()
                       ? viewer::kNaN
                       : analysis::Percentile({h.latencies_ms.begin(), h.latencies_ms.end()}, 0.5);
  }
  MarkRejectedRanges();
  return state_;
}

void ViewerNode::NoteSites(int64_t utime, const std::function<void()>& observe) {
  observe();
  // The line changes when a process states another hash or one expires
  // (SiteHashTracker): a disagreement that ended clears the warning.
  const std::string line = site_hashes_.Disagreement();
  if (line == state_.site_warning) return;
  state_.site_warning = line;
  if (state_.site_warning.empty()) return;
  status_.Count("site_disagreements");
  status_.SetError(state_.site_warning, utime);
  spdlog::warn("{}", state_.site_warning);
}

void ViewerNode::Tick(int64_t now_utime) {
  if (state_.detector_view_wanted) {
    state_.detector_view_wanted = false;
    RequestDetectorView(now_utime);
  }
  Expire(now_utime);
  status_.SetCounter("tracks", static_cast<int64_t>(state_.tracks.size()));
  status_.SetCounter("processes", static_cast<int64_t>(state_.processes.size()));
  status_.MaybePublish(bus_, now_utime);
}

void ViewerNode::Stop(int64_t now_utime) {
  status_.SetState(process_status_t::STATE_STOPPING);
  status_.Publish(bus_, now_utime);
}

}  // namespace roomfix
