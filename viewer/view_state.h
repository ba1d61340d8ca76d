#ifndef ROOMFIX_VIEWER_VIEW_STATE_H_
#define ROOMFIX_VIEWER_VIEW_STATE_H_

#include <array>
#include <cstdint>
#include <deque>
#include <limits>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "core/world/pose_source.h"
#include "core/world/site.h"

namespace roomfix::viewer {

// What the viewer shows, as plain data: the renderer draws it and knows
// nothing of LCM; the viewer node fills it from messages. Times are
// microseconds since the Unix epoch; "now" is the state's own now_utime, so
// a replayed log renders the same picture whatever the wall clock says.

// The sources the viewer draws (core/world/pose_source.h), in the order of
// the legend, of the panel's columns and of the keys 1 to 4 that show or
// hide them (each key is its source's number).
inline constexpr int kNumSources = 4;
inline constexpr std::array<PoseSource, kNumSources> kSources = {
    PoseSource::kCamera, PoseSource::kUltrasound, PoseSource::kFused, PoseSource::kGroundTruth};
// True for a source of kSources.
inline bool Drawn(PoseSource source) {
  return source == PoseSource::kCamera || source == PoseSource::kUltrasound ||
         source == PoseSource::kFused || source == PoseSource::kGroundTruth;
}
// For people: "camera", "ultrasound", "fused", "ground truth"; "unknown" for
// any other.
const char* SourceName(PoseSource source);

inline constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

struct TrailPoint {
  int64_t utime = 0;
  double x_m = 0.0;
  double y_m = 0.0;
};

// One robot as one source sees it.
struct TrackView {
  PoseSource source = PoseSource::kCamera;
  int robot_id = 0;
  // Latest pose; NaN heading when unknown; covariance of (x, y) in m^2, NaN
  // when unknown.
  double x_m = kNaN;
  double y_m = kNaN;
  double heading_rad = kNaN;
  double cov_xx_m2 = kNaN;
  double cov_xy_m2 = kNaN;
  double cov_yy_m2 = kNaN;
  bool degraded = false;
  // The latest message had no position.
  bool lost = false;
  // Measurement time of the latest pose and when it arrived.
  int64_t utime = 0;
  int64_t recv_utime = 0;
  // Oldest first; the renderer fades points by age over trail_s.
  std::deque<TrailPoint> trail;
  // Messages per second over the last seconds, median latency (measurement
  // to publish), ms.
  double rate_hz = 0.0;
  double latency_ms = kNaN;
  // Camera tracks: which of the site's cameras saw the robot, by camera id,
  // with the receive time of that camera's latest pose with a position
  // (several cameras see a robot in their overlap).
  std::map<int, int64_t> camera_seen_recv_utime;
};

// The floor polygon one camera's image covers (viewer/footprint.h), and the
// lens's floor position.
struct CameraFootprint {
  int camera_id = 0;
  // From the camera's calibration; false: its nominal model.
  bool calibrated = false;
  std::array<double, 2> lens_m{};
  std::vector<std::array<double, 2>> floor_m;
};

// One range of a beacon's latest range set, drawn as the circle where the
// sphere of that radius about the receiver cuts the beacon's height plane.
struct RangeView {
  int receiver_id = 0;
  std::array<double, 3> receiver_m{};
  double range_m = 0.0;
  // Inconsistent with the ultrasonic fix of that firing (drawn dashed, in
  // the warning colour).
  bool rejected = false;
};

struct RangeSetView {
  int beacon_id = 0;
  double beacon_height_m = 0.0;
  int64_t utime = 0;
  int64_t recv_utime = 0;
  std::vector<RangeView> ranges;
};

// One process as its STATUS heartbeat describes it.
struct ProcessView {
  std::string name;
  std::string host;
  int pid = 0;
  // process_status_t::STATE_* (0 starting, 1 running, 2 degraded, 3
  // stopping, 4 failed).
  int state = 0;
  int64_t inputs = 0;
  int64_t outputs = 0;
  int64_t dropped = 0;
  // Outputs per second between the last two heartbeats.
  double output_rate_hz = 0.0;
  std::vector<std::pair<std::string, int64_t>> rejected;
  // What makes up `dropped`, by cause (the STATUS counters named
  // dropped_* and fragments_*: docs/security.md), so a full receive buffer
  // (a slow process) can be told from forged fragments (a hostile sender).
  std::vector<std::pair<std::string, int64_t>> losses;
  std::string last_error;
  int64_t recv_utime = 0;
};

// The latest low-rate camera preview (an encoded image, JPEG or PNG) with
// the markers camera_proc found, in the preview's pixels.
struct PreviewView {
  int camera_id = 0;
  int64_t utime = 0;
  std::vector<uint8_t> encoded;
  struct Marker {
    double u_px = 0.0;
    double v_px = 0.0;
    double radius_px = 0.0;
    std::string colour;
  };
  std::vector<Marker> markers;
};

// The latest detector view of a camera (CAMERA_DETECTOR_VIEW: its class
// masks and blobs over the dimmed frame), drawn over the preview of the
// same camera, with each robot's line.
struct DetectorViewView {
  int camera_id = 0;
  int64_t utime = 0;
  std::vector<uint8_t> encoded;  // PNG
  // The full-resolution rectangle it shows, and the full frame's size.
  int region_u_px = 0;
  int region_v_px = 0;
  int region_width_px = 0;
  int region_height_px = 0;
  int source_width_px = 0;
  int source_height_px = 0;
  struct Robot {
    int robot_id = 0;
    bool found = false;
    std::string text;  // "robot 1: no pixels of class green"
  };
  std::vector<Robot> robots;
};

struct ViewState {
  // Room outline, grid, receivers and camera footprints come from here.
  Site site;
  // Each camera's footprint, drawn instead of the nominal view circle when
  // there (the viewer node computes them from the site).
  std::vector<CameraFootprint> footprints;
  int64_t now_utime = 0;
  std::vector<TrackView> tracks;
  std::vector<RangeSetView> range_sets;
  std::vector<ProcessView> processes;
  // "" or the line saying which processes run with which site when they
  // disagree (msgio/site_message.h, SiteHashTracker), shown over the
  // process list.
  std::string site_warning;
  bool has_preview = false;
  PreviewView preview;
  bool has_detector_view = false;
  DetectorViewView detector_view;
  // Set (by the 'd' key) to ask the cameras for their detector view; the
  // viewer node sends the request and clears it.
  bool detector_view_wanted = false;
  // Sources shown (index: the source's number, kUnknown's entry unused);
  // hidden ones are still listed in the panel, marked hidden.
  std::array<bool, kNumPoseSources> visible{true, true, true, true, true};
  // Trails cover this many seconds.
  double trail_s = 10.0;
  // A track or process is stale (marked in the picture and the panel) when
  // nothing arrived from it for this long.
  double stale_after_s = 2.0;
};

// Which part of the floor fills the picture: zoom 1 fits the whole room
// (with a margin) into the floor area left of the side panel; pan moves the
// centre, metres.
struct RenderOptions {
  int width_px = 1280;
  int height_px = 800;
  // Side panel width (process and source table); 0 for none.
  int panel_px = 380;
  double zoom = 1.0;
  double pan_x_m = 0.0;
  double pan_y_m = 0.0;

  bool IsValid(std::string* error) const;
};

}  // namespace roomfix::viewer

#endif  // ROOMFIX_VIEWER_VIEW_STATE_H_
