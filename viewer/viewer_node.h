#ifndef ROOMFIX_VIEWER_VIEWER_NODE_H_
#define ROOMFIX_VIEWER_VIEWER_NODE_H_

#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <string>
#include <utility>

#include "core/world/site.h"
#include "msgio/bus.h"
#include "msgio/channels.h"
#include "msgio/lcm_types_fwd.h"
#include "msgio/process.h"
#include "msgio/site_message.h"
#include "msgio/subscriptions.h"
#include "viewer/view_state.h"

namespace roomfix {

struct ViewerNodeOptions {
  // Seconds of trail behind each pose.
  double trail_s = 10.0;
  // A source or process is stale after this long without a message.
  double stale_after_s = 2.0;
  // A range is drawn as rejected when it disagrees with the ultrasonic fix
  // of its firing by more than this (the fix's own residuals are a few cm).
  double rejected_range_tolerance_m = 0.15;
  // A track or range set is dropped after this long without a message, a
  // process row after forget_process_after_s (longer, so that a process that
  // died stays on screen, stale, for a while). So the picture and the work
  // per frame hold only what is alive.
  double forget_after_s = 10.0;
  double forget_process_after_s = 300.0;
  // At most this many process rows; STATUS from further names is refused
  // (too_many_processes) until a row expires.
  int max_processes = 64;
  // Each camera's calibration text by camera id, for its footprint: the
  // texts the site carries (CalibrationTextsById), never files it names.
  std::map<int, std::string> calibration_texts;
  // What the 'd' key (and --detector-view) asks every camera for: its
  // detector view of the whole frame at this rate, for this long.
  double detector_view_rate_hz = 1.0;
  double detector_view_duration_s = 30.0;
  // Ask for it once at start (--detector-view), as the 'd' key does.
  bool detector_view_at_start = false;

  bool IsValid(std::string* error) const;
};

// The calibration texts a loaded site carries, by camera id
// (SiteCalibrationText): cameras without one are left out.
std::map<int, std::string> CalibrationTextsById(const LoadedSite& loaded);

// Keeps the viewer's picture of the system up to date from the bus: every
// pose2d_t on POSE_.*, the range sets on RANGES, the STATUS heartbeats, the
// camera previews (CAMERA_PREVIEW), the markers found (MARKER_PIXELS) and the
// sites the processes run with (SITE and STATUS: a disagreement is a warning).
// StateAt(now) gives the state to render as of `now` (trails pruned, rates,
// stale marks, rejected ranges), so live and replayed logs are drawn by the
// same code. Publishes its own STATUS heartbeat from Tick.
//
// Limits: rows are kept only for what the site names: a pose of a robot it
// does not list is refused (unknown_robot), a range set of an unknown beacon
// (unknown_beacon), ranges from unknown receivers are dropped
// (unknown_receiver) and a set with more ranges than the site has receivers
// is refused (too_many_ranges). A message whose utime is more than
// kMaxUtimeSkewUs from its receive time (utime_out_of_range) or that holds
// an infinity, or a NaN where a number is required (non_finite), is
// refused. Rows expire (forget_after_s) and each track's trail and rate
// window hold a bounded number of points, so a flood leaves nothing behind
// once it stops.
class ViewerNode {
 public:
  ViewerNode(const Site& site, Bus* bus, const ViewerNodeOptions& options, int64_t start_utime);

  const viewer::ViewState& StateAt(int64_t now_utime);
  // Visibility toggles and other view settings the window changes.
  viewer::ViewState* mutable_state() { return &state_; }
  // Also sends the detector view request the state asks for
  // (ViewState::detector_view_wanted).
  void Tick(int64_t now_utime);
  // Asks every camera for its detector view now.
  void RequestDetectorView(int64_t now_utime);
  void Stop(int64_t now_utime);
  const StatusReporter& status() const { return status_; }
  int64_t messages() const { return messages_; }

 private:
  struct TrackHistory {
    int64_t first_recv_utime = 0;
    std::deque<int64_t> recv_utimes;
    std::deque<double> latencies_ms;
  };
  struct StatusHistory {
    int64_t prev_utime = 0;
    int64_t prev_outputs = 0;
  };
  // Each input, checked (msgio/received.h) and entered into the state.
  void OnPose(const pose2d_t& msg, const MessageInfo& info);
  void OnRangeSet(const range_set_t& set, const MessageInfo& info);
  void OnStatus(const process_status_t& status, const MessageInfo& info);
  // The camera's pictures: previews, their markers, detector views.
  void SubscribeCamera();
  viewer::TrackView* FindTrack(PoseSource source, int robot_id);
  void MarkRejectedRanges();
  // Runs `observe` on the site tracker and, when it saw a new hash, updates
  // the warning (logged, counted as site_disagreements, and in STATUS).
  void NoteSites(int64_t utime, const std::function<void()>& observe);
  void SubscribeDetectorView();
  // Drops rows not heard from for their forget time as of now_utime.
  void Expire(int64_t now_utime);

  Bus* bus_;
  ViewerNodeOptions options_;
  StatusReporter status_;
  viewer::ViewState state_;
  std::map<std::pair<int, int>, TrackHistory> history_;
  std::map<std::string, StatusHistory> status_history_;
  // Which site each process states (SITE, STATUS site_hash); a
  // disagreement is warned about once per change and shown in the panel.
  SiteHashTracker site_hashes_;
  // Preview pixels per full-frame pixel of the latest preview.
  double preview_scale_ = 1.0;
  int64_t messages_ = 0;
  // Last: ended first, before anything the handlers use.
  Subscriptions subscriptions_{bus_};
};

}  // namespace roomfix

#endif  // ROOMFIX_VIEWER_VIEWER_NODE_H_
