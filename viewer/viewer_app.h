#ifndef ROOMFIX_VIEWER_VIEWER_APP_H_
#define ROOMFIX_VIEWER_VIEWER_APP_H_

// roomfix_viewer around its node: what to draw into (a window, a video, a
// PNG), the replay's pacing on log time, the keys, and the two runs (a log
// replayed, or live on the bus). roomfix_viewer_main.cc is its flags, the
// window (OpenCV highgui, optional) and calls to these.

#include <cstdint>
#include <functional>
#include <opencv2/core.hpp>
#include <string>

#include "camera_io/video_file.h"
#include "core/world/site.h"
#include "msgio/bus.h"
#include "viewer/render.h"
#include "viewer/view_state.h"
#include "viewer/viewer_node.h"

namespace roomfix::viewer {

// What the viewer's flags choose besides the node's and the renderer's
// options.
struct ViewerAppOptions {
  bool headless = false;             // no window: --png and/or --video
  std::string png;                   // the picture at the end
  std::string video;                 // every frame: .mp4/.avi/.mkv or a folder
  std::string log;                   // replay this log ("": live)
  double duration_s = 0.0;           // live: stop after this long (0: a signal)
  double fps = 30.0;                 // of the window and the video, (0, 240]
  std::string screenshot_dir = ".";  // where the 's' key saves pictures

  // False with a reason: fps out of range, headless with nothing to write.
  bool IsValid(std::string* error) const;
  int64_t frame_us() const;
};

// Writes frames to a video file (.mp4, .avi, .mkv) or, for any other target,
// numbered PNGs (frame_000001.png ...) in that folder, made if missing.
class FrameSink {
 public:
  bool Open(const std::string& target, double fps, cv::Size size, std::string* error);
  bool Write(const cv::Mat& frame);
  // Finishes a video file: checked and renamed into place, or removed
  // (camera::CheckedVideoWriter). True for an image sequence.
  bool Close(std::string* error);
  int64_t frames() const { return frames_; }
  // Why the last image of a sequence could not be written.
  const std::string& error() const { return error_; }

 private:
  camera::CheckedVideoWriter writer_;
  std::string folder_;
  std::string error_;
  int64_t frames_ = 0;
};

// A replay draws frames at fixed steps of log time (one per frame_us), as a
// camera would have seen the scene live: every event time advances the
// picture through the frame instants up to it. A gap in the log over
// max_gap_us (two sessions, a paused recording) is skipped, restarting the
// frames at the event after it, not filled with identical frames.
class ReplayPacer {
 public:
  ReplayPacer(int64_t frame_us, int64_t max_gap_us);
  // Calls draw(t) for each frame instant t <= utime not drawn yet, in order;
  // stops early once draw returns false (the user quit).
  void AdvanceTo(int64_t utime, const std::function<bool(int64_t frame_utime)>& draw);

 private:
  int64_t frame_us_;
  int64_t max_gap_us_;
  bool started_ = false;
  int64_t next_frame_utime_ = 0;
};

// Longest stretch of log time a replay draws frame by frame.
inline constexpr int64_t kMaxReplayGapUs = 2'000'000;

// What a key (OpenCV's waitKey code) asks of the caller once the view has
// taken its part: zoom (+ - r), pan (h j k l), source toggles (1-4).
enum class KeyAction { kNone, kQuit, kScreenshot };
KeyAction ApplyKey(int key, RenderOptions* render, ViewState* view);

// "DIR/roomfix_viewer_<milliseconds>.png".
std::string ScreenshotPath(const std::string& dir, int64_t now_utime);

// Where frames are shown: a window, or nothing (headless).
class FrameDisplay {
 public:
  virtual ~FrameDisplay() = default;
  // Shows `frame` and serves the window for about wait_ms (keys change
  // *render and *view); false once the user quit or a signal came.
  virtual bool Show(const cv::Mat& frame, int wait_ms, RenderOptions* render, ViewState* view) = 0;
};

// Replays options.log into a node on an in-process bus, drawing at the
// ReplayPacer's instants into the video and the display (none: headless),
// then the last picture into options.png; a display keeps it up until the
// user quits. 0, or 1 with *error (an unreadable log, an unwritable PNG) or
// when the video could not be written (logged).
int ReplayIntoView(const Site& site, const ViewerNodeOptions& node_options, RenderOptions* render,
                   const ViewerAppOptions& options, FrameDisplay* display, std::string* error);

// Listens on `bus` for options.duration_s (or until a signal), drawing every
// frame_us of wall time into the video and the display, then the last
// picture into options.png. 0, or 1 with *error (an unwritable PNG), when
// LCM fails or the video could not be written (logged).
int RunLiveView(const Site& site, Bus* bus, const ViewerNodeOptions& node_options,
                RenderOptions* render, const ViewerAppOptions& options, FrameDisplay* display,
                std::string* error);

}  // namespace roomfix::viewer

#endif  // ROOMFIX_VIEWER_VIEWER_APP_H_
