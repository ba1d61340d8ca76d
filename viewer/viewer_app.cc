#include "viewer/viewer_app.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <sys/stat.h>

#include <algorithm>
#include <cerrno>
#include <opencv2/videoio.hpp>

#include "camera_io/image_file.h"
#include "msgio/log.h"
#include "msgio/process.h"

namespace roomfix::viewer {
namespace {

bool EndsWith(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() &&
         s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

// Renders, writes and shows the frames of one run; a video that cannot be
// written stops the run (as a signal would) and fails it.
class FramePipe {
 public:
  FramePipe(RenderOptions* render, const ViewerAppOptions& options, FrameDisplay* display,
            ViewState* view)
      : render_(render), options_(options), display_(display), view_(view) {}

  bool OpenVideo(std::string* error) {
    return options_.video.empty() ||
           video_.Open(options_.video, options_.fps,
                       cv::Size(render_->width_px, render_->height_px), error);
  }
  // Renders `state` for Show and WritePng, not into the video.
  void RenderOnly(const ViewState& state) { Render(state, *render_, &frame_); }
  // Renders `state` and writes it to the video, without showing it.
  void Draw(const ViewState& state) {
    RenderOnly(state);
    if (options_.video.empty() || video_failed_) return;
    if (!video_.Write(frame_)) {
      spdlog::error("cannot write frame {} of {}: {}; stopping", video_.frames(), options_.video,
                    video_.error());
      video_failed_ = true;
      RequestShutdown();
    }
  }
  bool Show(int wait_ms) {
    return display_ != nullptr && display_->Show(frame_, wait_ms, render_, view_);
  }
  bool WritePng(std::string* error) {
    return options_.png.empty() || camera::WriteImageChecked(options_.png, frame_, error);
  }
  // A video that stopped short (a full disk) fails here, and is removed.
  bool CloseVideo(std::string* error) { return options_.video.empty() || video_.Close(error); }
  bool video_failed() const { return video_failed_; }
  int64_t frames_written() const { return video_.frames(); }

 private:
  RenderOptions* render_;
  const ViewerAppOptions& options_;
  FrameDisplay* display_;
  ViewState* view_;
  cv::Mat frame_;
  FrameSink video_;
  bool video_failed_ = false;
};

}  // namespace

bool ViewerAppOptions::IsValid(std::string* error) const {
  if (!(fps > 0.0 && fps <= 240.0)) {
    *error = "--fps must be in (0, 240]";
    return false;
  }
  if (headless && png.empty() && video.empty()) {
    *error = "--headless needs --png or --video";
    return false;
  }
  return true;
}

int64_t ViewerAppOptions::frame_us() const { return static_cast<int64_t>(1e6 / fps); }

bool FrameSink::Open(const std::string& target, double fps, cv::Size size, std::string* error) {
  if (EndsWith(target, ".mp4") || EndsWith(target, ".avi") || EndsWith(target, ".mkv")) {
    const int fourcc = EndsWith(target, ".avi") ? cv::VideoWriter::fourcc('M', 'J', 'P', 'G')
                                                : cv::VideoWriter::fourcc('m', 'p', '4', 'v');
    return writer_.Open(target, fourcc, fps, size, error);
  }
  folder_ = target;
  if (::mkdir(folder_.c_str(), 0755) != 0 && errno != EEXIST) {
    *error = folder_ + ": cannot make the folder for the image sequence";
    return false;
  }
  return true;
}

bool FrameSink::Write(const cv::Mat& frame) {
  ++frames_;
  if (writer_.is_open()) {
    writer_.Write(frame);
    return true;
  }
  return camera::WriteImageChecked(fmt::format("{}/frame_{:06d}.png", folder_, frames_), frame,
                                   &error_);
}

bool FrameSink::Close(std::string* error) { return !writer_.is_open() || writer_.Close(error); }

ReplayPacer::ReplayPacer(int64_t frame_us, int64_t max_gap_us)
    : frame_us_(frame_us), max_gap_us_(max_gap_us) {}

void ReplayPacer::AdvanceTo(int64_t utime, const std::function<bool(int64_t)>& draw) {
  if (!started_ || utime - next_frame_utime_ > max_gap_us_) {
    next_frame_utime_ = utime;
    started_ = true;
  }
  while (next_frame_utime_ <= utime) {
    if (!draw(next_frame_utime_)) return;
    next_frame_utime_ += frame_us_;
  }
}

KeyAction ApplyKey(int key, RenderOptions* render, ViewState* view) {
  // Pan steps are a quarter metre at zoom 1, less when zoomed in.
  const double pan_step_m = 0.25 / render->zoom;
  switch (key & 0xFF) {
    case 'q':
    case 27:  // Esc
      return KeyAction::kQuit;
    case 's':
      return KeyAction::kScreenshot;
    case 'd':
      // The node sends the request at its next tick (it has the bus).
      view->detector_view_wanted = true;
      break;
    case '+':
    case '=':
      render->zoom = std::min(render->zoom * 1.25, 50.0);
      break;
    case '-':
      render->zoom = std::max(render->zoom * 0.8, 0.2);
      break;
    case 'r':
      render->zoom = 1.0;
      render->pan_x_m = render->pan_y_m = 0.0;
      break;
    case 'h':
      render->pan_x_m -= pan_step_m;
      break;
    case 'l':
      render->pan_x_m += pan_step_m;
      break;
    case 'k':
      render->pan_y_m += pan_step_m;
      break;
    case 'j':
      render->pan_y_m -= pan_step_m;
      break;
    case '1':
    case '2':
    case '3':
    case '4': {
      // Each key is its source's number (kSources).
      const auto source = static_cast<size_t>((key & 0xFF) - '0');
      view->visible[source] = !view->visible[source];
      break;
    }
    default:
      break;
  }
  return KeyAction::kNone;
}

std::string ScreenshotPath(const std::string& dir, int64_t now_utime) {
  return fmt::format("{}/roomfix_viewer_{}.png", dir, now_utime / 1000);
}

int ReplayIntoView(const Site& site, const ViewerNodeOptions& node_options, RenderOptions* render,
                   const ViewerAppOptions& options, FrameDisplay* display, std::string* error) {
  LoopbackBus bus;
  ViewerNode node(site, &bus, node_options, 0);
  FramePipe pipe(render, options, display, node.mutable_state());
  if (!pipe.OpenVideo(error)) return 1;
  const int64_t frame_us = options.frame_us();
  ReplayPacer pacer(frame_us, kMaxReplayGapUs);
  ReplayOptions replay;
  if (!options.video.empty() || display != nullptr) {
    replay.on_time = [&](int64_t utime) {
      // After a signal or a quit the rest of the log is read without
      // drawing, which takes no time.
      if (ShutdownRequested()) return;
      pacer.AdvanceTo(utime, [&](int64_t frame_utime) {
        if (ShutdownRequested()) return false;
        pipe.Draw(node.StateAt(frame_utime));
        pipe.Show(static_cast<int>(frame_us / 1000));
        return true;
      });
    };
  }
  const ReplaySummary summary = ReplayLog(options.log, &bus, replay);
  if (!summary.ok) {
    *error = summary.error;
    return 1;
  }
  if (summary.damaged) {
    spdlog::warn("{}: {}; replayed every good event", options.log, summary.damage);
  }
  pipe.RenderOnly(node.StateAt(summary.last_utime));
  if (!pipe.WritePng(error) || !pipe.CloseVideo(error)) return 1;
  // The last picture stays up until the user quits.
  while (pipe.Show(100)) {
  }
  spdlog::info("replayed {} events; {} frames written", summary.events_delivered,
               pipe.frames_written());
  return pipe.video_failed() ? 1 : 0;
}

int RunLiveView(const Site& site, Bus* bus, const ViewerNodeOptions& node_options,
                RenderOptions* render, const ViewerAppOptions& options, FrameDisplay* display,
                std::string* error) {
  ViewerNode node(site, bus, node_options, NowUtime());
  FramePipe pipe(render, options, display, node.mutable_state());
  if (!pipe.OpenVideo(error)) return 1;
  const int64_t frame_us = options.frame_us();
  int64_t next_frame = NowUtime();
  RunLoopOptions loop;
  loop.duration_s = options.duration_s;
  loop.tick_period_ms = std::max(1, static_cast<int>(frame_us / 1000));
  const int rc = RunLoop(
      bus,
      [&](int64_t now) {
        node.Tick(now);
        if (now < next_frame) return;
        next_frame = now + frame_us;
        pipe.Draw(node.StateAt(now));
        pipe.Show(1);
      },
      loop);
  pipe.RenderOnly(node.StateAt(NowUtime()));
  if (!pipe.WritePng(error) || !pipe.CloseVideo(error)) return 1;
  node.Stop(NowUtime());
  return pipe.video_failed() ? 1 : rc;
}

}  // namespace roomfix::viewer
