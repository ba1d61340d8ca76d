// roomfix_viewer: a live top-down view of the robots, the sensors and the
// processes' health, in a window or rendered to PNG / video without one.
#include <spdlog/spdlog.h>
#include <sys/stat.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <iostream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/videoio.hpp>
#include <string>
#include <vector>

#include "camera_proc/image_file.h"
#include "msgio/log.h"
#include "msgio/process.h"
#include "msgio/site_message.h"
#include "viewer/render.h"
#include "viewer/viewer_node.h"

// ROOMFIX_VIEWER_WINDOW (viewer/CMakeLists.txt): 1 when OpenCV's highgui is
// linked. Without it only --headless runs, and says so.
#if ROOMFIX_VIEWER_WINDOW
#include <opencv2/highgui.hpp>
#endif

namespace {

struct ViewerFlags {
  bool headless = false;
  std::string png;
  std::string video;
  std::string log;
  double duration_s = 0.0;
  double fps = 30.0;
  std::string screenshot_dir = ".";
};

// Longest stretch of log time a replay draws frame by frame; a longer gap
// is skipped.
constexpr int64_t kMaxReplayGapUs = 2'000'000;

bool EndsWith(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() &&
         s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

// Writes frames to a video file (.mp4, .avi) or, for a folder, numbered PNGs.
class FrameSink {
 public:
  bool Open(const std::string& target, double fps, cv::Size size, std::string* error) {
    if (EndsWith(target, ".mp4") || EndsWith(target, ".avi") || EndsWith(target, ".mkv")) {
      const int fourcc = EndsWith(target, ".avi") ? cv::VideoWriter::fourcc('M', 'J', 'P', 'G')
                                                  : cv::VideoWriter::fourcc('m', 'p', '4', 'v');
      writer_.open(target, fourcc, fps, size);
      if (!writer_.isOpened()) {
        *error = target + ": cannot open a video writer (codec missing?)";
        return false;
      }
      return true;
    }
    folder_ = target;
    if (::mkdir(folder_.c_str(), 0755) != 0 && errno != EEXIST) {
      *error = folder_ + ": cannot make the folder for the image sequence";
      return false;
    }
    return true;
  }
  bool Write(const cv::Mat& frame) {
    ++frames_;
    if (writer_.isOpened()) {
      writer_.write(frame);
      return true;
    }
    char name[32];
    std::snprintf(name, sizeof(name), "/frame_%06lld.png", static_cast<long long>(frames_));
    return roomfix::camera::WriteImageChecked(folder_ + name, frame, &error_);
  }
  int64_t frames() const { return frames_; }
  // Why the last image of a sequence could not be written.
  const std::string& error() const { return error_; }

 private:
  cv::VideoWriter writer_;
  std::string folder_;
  std::string error_;
  int64_t frames_ = 0;
};

std::string Timestamped(const std::string& dir) {
  char name[64];
  std::snprintf(name, sizeof(name), "/roomfix_viewer_%lld.png",
                static_cast<long long>(roomfix::NowUtime() / 1000));
  return dir + name;
}

}  // namespace

int main(int argc, char** argv) {
  roomfix::ProcessOptions process;
  roomfix::ViewerNodeOptions options;
  roomfix::viewer::RenderOptions render;
  ViewerFlags flags;
  CLI::App app{
      "roomfix_viewer: top-down view of the robots (every pose source), the range circles of "
      "each beacon's latest firing and every process's health; a window, or PNG/video "
      "without a display"};
  // --config is required live; a replayed log brings its own site (SITE).
  roomfix::AddProcessFlags(&app, &process, /*config_required=*/false);
  // The shared help says only "Site file"; the viewer's differs in when it
  // is needed.
  app.get_option("--config")
      ->description(
          "Site file (YAML). Required live; with --log the log's own site (SITE) is used when "
          "--config is absent, and a difference from it is a warning");
  app.add_flag("--headless", flags.headless, "No window: render to --png and/or --video");
  app.add_option("--png", flags.png, "Write the picture at the end (of the log, or --duration)");
  app.add_option("--video", flags.video,
                 "Write every frame: a .mp4/.avi file or a folder of numbered PNGs");
  app.add_option("--log", flags.log, "Replay this LCM log instead of listening live");
  app.add_option("--duration", flags.duration_s, "Live: stop after this many seconds")
      ->capture_default_str();
  app.add_option("--fps", flags.fps, "Frames per second of the window and the video")
      ->capture_default_str();
  app.add_option("--width", render.width_px, "Picture width, pixels")->capture_default_str();
  app.add_option("--height", render.height_px, "Picture height, pixels")->capture_default_str();
  app.add_option("--trail", options.trail_s, "Seconds of trail behind each pose")
      ->capture_default_str();
  app.add_option("--stale-after", options.stale_after_s,
                 "Mark a source or process stale after this long without a message, s")
      ->capture_default_str();
  app.add_option("--screenshot-dir", flags.screenshot_dir, "Where the 's' key saves pictures")
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);

  std::string error;
  if (!options.IsValid(&error) || !render.IsValid(&error)) {
    std::cerr << "roomfix_viewer: " << error << "\n";
    return 1;
  }
  if (!(flags.fps > 0.0 && flags.fps <= 240.0)) {
    std::cerr << "roomfix_viewer: --fps must be in (0, 240]\n";
    return 1;
  }
  if (flags.headless && flags.png.empty() && flags.video.empty()) {
    std::cerr << "roomfix_viewer: --headless needs --png or --video\n";
    return 1;
  }
  if (!flags.headless && !ROOMFIX_VIEWER_WINDOW) {
    std::cerr << "roomfix_viewer: built without a window (OpenCV highgui); use --headless "
                 "--png FILE or --video FILE\n";
    return 1;
  }
  if (!flags.headless && std::getenv("DISPLAY") == nullptr) {
    std::cerr << "roomfix_viewer: no display (DISPLAY is not set); use --headless --png FILE\n";
    return 1;
  }
  if (flags.log.empty() && process.config_path.empty()) {
    std::cerr << "roomfix_viewer: --config is required to view live (a --log brings its own "
                 "site)\n";
    return 1;
  }
  // A replay takes the log's site unless --config is given, and then warns
  // where the two differ; it says on stderr which one it draws.
  std::string config_path = process.config_path;
  if (!flags.log.empty()) {
    process.lcm_url = "memq://";  // no network for a replay
    process.config_path.clear();
  }
  auto ctx = roomfix::StartProcess("roomfix_viewer", process, &error);
  if (ctx == nullptr) {
    std::cerr << "roomfix_viewer: " << error << "\n";
    return 1;
  }
  if (!flags.log.empty()) {
    roomfix::LoadedSite site;
    std::string used;
    std::vector<std::string> warnings;
    if (!roomfix::ResolveToolSite(config_path, flags.log, &site, &used, &warnings, &error)) {
      std::cerr << "roomfix_viewer: " << error << "\n";
      return 1;
    }
    std::cerr << "roomfix_viewer: " << used << "\n";
    for (const auto& w : warnings) std::cerr << "roomfix_viewer: warning: " << w << "\n";
    ctx->site = site.site;
  }
  if (process.check) {
    std::cout << "roomfix_viewer: ok: " << (flags.headless ? "headless" : "window") << ", "
              << render.width_px << "x" << render.height_px << ", "
              << (flags.log.empty() ? "live on " + process.lcm_url : "replaying " + flags.log)
              << "\n";
    return 0;
  }

  cv::Mat frame;
  FrameSink video;
  if (!flags.video.empty() &&
      !video.Open(flags.video, flags.fps, cv::Size(render.width_px, render.height_px), &error)) {
    std::cerr << "roomfix_viewer: " << error << "\n";
    return 1;
  }
  const auto frame_us = static_cast<int64_t>(1e6 / flags.fps);

#if ROOMFIX_VIEWER_WINDOW
  // Mouse: the wheel zooms, a drag pans (by the floor's own scale).
  struct Mouse {
    roomfix::viewer::RenderOptions* render;
    const roomfix::Site* site;
    int drag_x = -1;
    int drag_y = -1;
  } mouse{&render, &ctx->site};
  if (!flags.headless) {
    cv::namedWindow("roomfix_viewer", cv::WINDOW_AUTOSIZE);
    cv::setMouseCallback(
        "roomfix_viewer",
        [](int event, int x, int y, int mouse_flags, void* user) {
          auto* m = static_cast<Mouse*>(user);
          roomfix::viewer::RenderOptions* r = m->render;
          if (event == cv::EVENT_MOUSEWHEEL) {
            r->zoom = std::clamp(r->zoom * (cv::getMouseWheelDelta(mouse_flags) > 0 ? 1.25 : 0.8),
                                 0.2, 50.0);
          } else if (event == cv::EVENT_LBUTTONDOWN) {
            m->drag_x = x;
            m->drag_y = y;
          } else if (event == cv::EVENT_MOUSEMOVE && (mouse_flags & cv::EVENT_FLAG_LBUTTON) &&
                     m->drag_x >= 0) {
            const double scale = roomfix::viewer::MakeFloorMapping(*m->site, *r).scale_px_per_m;
            if (scale > 0) {
              r->pan_x_m -= (x - m->drag_x) / scale;
              r->pan_y_m += (y - m->drag_y) / scale;
            }
            m->drag_x = x;
            m->drag_y = y;
          } else if (event == cv::EVENT_LBUTTONUP) {
            m->drag_x = -1;
          }
        },
        &mouse);
  }
#endif
  // Keys, the same for a live view and a replay: zoom, pan, toggles,
  // screenshot, quit.
  roomfix::viewer::ViewState* view = nullptr;
  auto handle_key = [&](int key) {
    switch (key & 0xFF) {
      case 'q':
      case 27:
        roomfix::RequestShutdown();
        break;
      case '+':
      case '=':
        render.zoom = std::min(render.zoom * 1.25, 50.0);
        break;
      case '-':
        render.zoom = std::max(render.zoom * 0.8, 0.2);
        break;
      case 'r':
        render.zoom = 1.0;
        render.pan_x_m = render.pan_y_m = 0.0;
        break;
      case 'h':
        render.pan_x_m -= 0.25 / render.zoom;
        break;
      case 'l':
        render.pan_x_m += 0.25 / render.zoom;
        break;
      case 'k':
        render.pan_y_m += 0.25 / render.zoom;
        break;
      case 'j':
        render.pan_y_m -= 0.25 / render.zoom;
        break;
      case '1':
      case '2':
      case '3':
      case '4':
        view->visible[(key & 0xFF) - '1'] = !view->visible[(key & 0xFF) - '1'];
        break;
      case 's': {
        const std::string path = Timestamped(flags.screenshot_dir);
        std::string why;
        if (roomfix::camera::WriteImageChecked(path, frame, &why)) {
          spdlog::info("screenshot: {}", path);
        } else {
          spdlog::warn("screenshot not saved: {}", why);
        }
        break;
      }
      default:
        break;
    }
  };
  // Shows a frame and serves the window for wait_ms; false once the user
  // quit (key, closed window) or a signal came.
  auto show = [&](int wait_ms) {
#if ROOMFIX_VIEWER_WINDOW
    cv::imshow("roomfix_viewer", frame);
    const int key = cv::waitKey(std::max(1, wait_ms));
    if (key >= 0) handle_key(key);
    if (cv::getWindowProperty("roomfix_viewer", cv::WND_PROP_VISIBLE) < 1) {
      roomfix::RequestShutdown();
    }
    return !roomfix::ShutdownRequested();
#else
    // Unreachable: without a window the viewer runs --headless only.
    (void)wait_ms;
    (void)handle_key;
    return false;
#endif
  };
  bool video_failed = false;
  auto write_video = [&] {
    if (flags.video.empty() || video_failed) return;
    if (!video.Write(frame)) {
      spdlog::error("cannot write frame {} of {}: {}; stopping", video.frames(), flags.video,
                    video.error());
      video_failed = true;
      roomfix::RequestShutdown();
    }
  };

  // A replay drives the same node through an in-process bus on log time.
  if (!flags.log.empty()) {
    roomfix::LoopbackBus bus;
    roomfix::ViewerNode node(ctx->site, &bus, options, 0);
    view = node.mutable_state();
    bool started = false;
    int64_t next_frame = 0;
    roomfix::ReplayOptions replay;
    if (!flags.video.empty() || !flags.headless) {
      replay.on_time = [&](int64_t utime) {
        // After a signal or a quit the rest of the log is read without
        // drawing, which takes no time.
        if (roomfix::ShutdownRequested()) return;
        // A gap in the log (two sessions, a paused recording) is skipped,
        // not filled with identical frames.
        if (!started || utime - next_frame > kMaxReplayGapUs) {
          next_frame = utime;
          started = true;
        }
        while (next_frame <= utime && !roomfix::ShutdownRequested()) {
          roomfix::viewer::Render(node.StateAt(next_frame), render, &frame);
          write_video();
          if (!flags.headless) show(static_cast<int>(frame_us / 1000));
          next_frame += frame_us;
        }
      };
    }
    const roomfix::ReplaySummary summary = roomfix::ReplayLog(flags.log, &bus, replay);
    if (!summary.ok) {
      std::cerr << "roomfix_viewer: " << summary.error << "\n";
      return 1;
    }
    if (summary.damaged) {
      spdlog::warn("{}: {}; replayed every good event", flags.log, summary.damage);
    }
    roomfix::viewer::Render(node.StateAt(summary.last_utime), render, &frame);
    std::string png_error;
    if (!flags.png.empty() && !roomfix::camera::WriteImageChecked(flags.png, frame, &png_error)) {
      std::cerr << "roomfix_viewer: " << png_error << "\n";
      return 1;
    }
    // The last picture stays up until the user quits.
    if (!flags.headless) {
      while (show(100)) {
      }
    }
    spdlog::info("replayed {} events; {} frames written", summary.events_delivered, video.frames());
    return video_failed ? 1 : 0;
  }

  roomfix::ViewerNode node(ctx->site, ctx->bus.get(), options, roomfix::NowUtime());
  view = node.mutable_state();
  int64_t next_frame = roomfix::NowUtime();
  roomfix::RunLoopOptions loop;
  loop.duration_s = flags.duration_s;
  loop.tick_period_ms = std::max(1, static_cast<int>(frame_us / 1000));
  const int rc = roomfix::RunLoop(
      ctx->bus.get(),
      [&](int64_t now) {
        node.Tick(now);
        if (now < next_frame) return;
        next_frame = now + frame_us;
        roomfix::viewer::Render(node.StateAt(now), render, &frame);
        write_video();
        if (flags.headless) return;
        show(1);
      },
      loop);
  roomfix::viewer::Render(node.StateAt(roomfix::NowUtime()), render, &frame);
  std::string png_error;
  if (!flags.png.empty() && !roomfix::camera::WriteImageChecked(flags.png, frame, &png_error)) {
    std::cerr << "roomfix_viewer: " << png_error << "\n";
    return 1;
  }
  node.Stop(roomfix::NowUtime());
  return video_failed ? 1 : rc;
}
