// roomfix_viewer: a live top-down view of the robots, the sensors and the
// processes' health, in a window or rendered to PNG / video without one.
// Flags and the window here; the runs are in viewer_app.h.
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cstdlib>
#include <iostream>
#include <string>
#include <vector>

#include "camera_io/image_file.h"
#include "msgio/process.h"
#include "msgio/site_message.h"
#include "viewer/viewer_app.h"

// ROOMFIX_VIEWER_WINDOW (viewer/CMakeLists.txt): 1 when OpenCV's highgui is
// linked. Without it only --headless runs, and says so.
#if ROOMFIX_VIEWER_WINDOW
#include <opencv2/highgui.hpp>
#endif

namespace {

namespace viewer = roomfix::viewer;

#if ROOMFIX_VIEWER_WINDOW
// The window: keys (viewer::ApplyKey), the mouse (the wheel zooms, a drag
// pans by the floor's own scale), screenshots; closing it quits.
class Window final : public viewer::FrameDisplay {
 public:
  Window(const roomfix::Site& site, viewer::RenderOptions* render, std::string screenshot_dir)
      : site_(site), render_(render), screenshot_dir_(std::move(screenshot_dir)) {
    cv::namedWindow(kName, cv::WINDOW_AUTOSIZE);
    cv::setMouseCallback(kName, &Window::OnMouse, this);
  }
  bool Show(const cv::Mat& frame, int wait_ms, viewer::RenderOptions* render,
            viewer::ViewState* view) override {
    cv::imshow(kName, frame);
    const int key = cv::waitKey(std::max(1, wait_ms));
    if (key >= 0) {
      const viewer::KeyAction action = viewer::ApplyKey(key, render, view);
      if (action == viewer::KeyAction::kQuit) roomfix::RequestShutdown();
      if (action == viewer::KeyAction::kScreenshot) Screenshot(frame);
    }
    if (cv::getWindowProperty(kName, cv::WND_PROP_VISIBLE) < 1) roomfix::RequestShutdown();
    return !roomfix::ShutdownRequested();
  }

 private:
  static constexpr const char* kName = "roomfix_viewer";
  void Screenshot(const cv::Mat& frame) const {
    const std::string path = viewer::ScreenshotPath(screenshot_dir_, roomfix::NowUtime());
    std::string why;
    if (roomfix::camera::WriteImageChecked(path, frame, &why)) {
      spdlog::info("screenshot: {}", path);
    } else {
      spdlog::warn("screenshot not saved: {}", why);
    }
  }
  static void OnMouse(int event, int x, int y, int mouse_flags, void* user) {
    auto* w = static_cast<Window*>(user);
    viewer::RenderOptions* r = w->render_;
    if (event == cv::EVENT_MOUSEWHEEL) {
      r->zoom =
          std::clamp(r->zoom * (cv::getMouseWheelDelta(mouse_flags) > 0 ? 1.25 : 0.8), 0.2, 50.0);
    } else if (event == cv::EVENT_LBUTTONDOWN) {
      w->drag_x_ = x;
      w->drag_y_ = y;
    } else if (event == cv::EVENT_MOUSEMOVE && (mouse_flags & cv::EVENT_FLAG_LBUTTON) &&
               w->drag_x_ >= 0) {
      const double scale = viewer::MakeFloorMapping(w->site_, *r).scale_px_per_m;
      if (scale > 0) {
        r->pan_x_m -= (x - w->drag_x_) / scale;
        r->pan_y_m += (y - w->drag_y_) / scale;
      }
      w->drag_x_ = x;
      w->drag_y_ = y;
    } else if (event == cv::EVENT_LBUTTONUP) {
      w->drag_x_ = -1;
    }
  }
  const roomfix::Site& site_;
  viewer::RenderOptions* render_;
  std::string screenshot_dir_;
  int drag_x_ = -1;
  int drag_y_ = -1;
};
#endif

void AddFlags(CLI::App* app, viewer::ViewerAppOptions* flags, roomfix::ViewerNodeOptions* options,
              viewer::RenderOptions* render) {
  // The shared help says only "Site file"; the viewer's differs in when it
  // is needed.
  app->get_option("--config")
      ->description(
          "Site file (YAML). Required live; with --log the log's own site (SITE) is used when "
          "--config is absent, and a difference from it is a warning");
  app->add_flag("--headless", flags->headless, "No window: render to --png and/or --video");
  app->add_option("--png", flags->png, "Write the picture at the end (of the log, or --duration)");
  app->add_option("--video", flags->video,
                  "Write every frame: a .mp4/.avi file or a folder of numbered PNGs");
  app->add_option("--log", flags->log, "Replay this LCM log instead of listening live");
  app->add_option("--duration", flags->duration_s, "Live: stop after this many seconds")
      ->capture_default_str();
  app->add_option("--fps", flags->fps, "Frames per second of the window and the video")
      ->capture_default_str();
  app->add_option("--width", render->width_px, "Picture width, pixels")->capture_default_str();
  app->add_option("--height", render->height_px, "Picture height, pixels")->capture_default_str();
  app->add_option("--trail", options->trail_s, "Seconds of trail behind each pose")
      ->capture_default_str();
  app->add_option("--stale-after", options->stale_after_s,
                  "Mark a source or process stale after this long without a message, s")
      ->capture_default_str();
  app->add_flag("--detector-view", options->detector_view_at_start,
                "Ask every camera for what its detector sees (CAMERA_DETECTOR_VIEW, over the "
                "preview, with why each robot is not found) at start; the 'd' key asks again");
  app->add_option("--screenshot-dir", flags->screenshot_dir, "Where the 's' key saves pictures")
      ->capture_default_str();
}

// Why the viewer cannot run as asked, beyond the options' own checks; "" if
// it can.
std::string CannotRun(const viewer::ViewerAppOptions& flags, const std::string& config_path) {
  if (!flags.headless && !ROOMFIX_VIEWER_WINDOW) {
    return "built without a window (OpenCV highgui); use --headless --png FILE or --video FILE";
  }
  if (!flags.headless && std::getenv("DISPLAY") == nullptr) {
    return "no display (DISPLAY is not set); use --headless --png FILE";
  }
  if (flags.log.empty() && config_path.empty()) {
    return "--config is required to view live (a --log brings its own site)";
  }
  return "";
}

constexpr char kProcessName[] = "roomfix_viewer";

}  // namespace

int main(int argc, char** argv) {
  roomfix::ProcessOptions process;
  roomfix::ViewerNodeOptions options;
  viewer::RenderOptions render;
  viewer::ViewerAppOptions flags;
  CLI::App app{
      "roomfix_viewer: top-down view of the robots (every pose source), the range circles of "
      "each beacon's latest firing and every process's health; a window, or PNG/video "
      "without a display"};
  // --config is required live; a replayed log brings its own site (SITE).
  roomfix::AddProcessFlags(&app, &process, /*config_required=*/false);
  AddFlags(&app, &flags, &options, &render);
  CLI11_PARSE(app, argc, argv);
  std::string error;
  if (!options.IsValid(&error) || !render.IsValid(&error) || !flags.IsValid(&error)) {
    return roomfix::PrintFailure(kProcessName, error);
  }
  if (const std::string why = CannotRun(flags, process.config_path); !why.empty())
    return roomfix::PrintFailure(kProcessName, why);
  // A replay takes the log's site unless --config is given, and then warns
  // where the two differ; it says on stderr which one it draws.
  const std::string config_path = process.config_path;
  if (!flags.log.empty()) {
    process.lcm_url = "memq://";  // no network for a replay
    process.config_path.clear();
  }
  auto ctx = roomfix::StartProcess("roomfix_viewer", process, &error);
  if (ctx == nullptr) return roomfix::PrintFailure(kProcessName, error);
  // The site with the texts it carries: the footprints use the calibration
  // texts, never a file the site names (a log's names paths of its host).
  roomfix::LoadedSite site;
  if (!flags.log.empty()) {
    roomfix::ToolSite resolved = roomfix::ResolveToolSite(config_path, flags.log);
    if (!resolved.known) return roomfix::PrintFailure(kProcessName, resolved.error);
    site = std::move(resolved.site);
    std::cerr << "roomfix_viewer: " << resolved.line << "\n";
    for (const auto& w : resolved.warnings) std::cerr << "roomfix_viewer: warning: " << w << "\n";
  } else if (!roomfix::LoadSiteWithTexts(config_path, &site, &error)) {
    return roomfix::PrintFailure(kProcessName, error);
  }
  ctx->site = site.site;
  options.calibration_texts = roomfix::CalibrationTextsById(site);
  if (process.check) {
    std::cout << "roomfix_viewer: ok: " << (flags.headless ? "headless" : "window") << ", "
              << render.width_px << "x" << render.height_px << ", "
              << (flags.log.empty() ? "live on " + process.lcm_url : "replaying " + flags.log)
              << "\n";
    return 0;
  }
  std::unique_ptr<viewer::FrameDisplay> display;
#if ROOMFIX_VIEWER_WINDOW
  if (!flags.headless) display = std::make_unique<Window>(ctx->site, &render, flags.screenshot_dir);
#endif
  const int rc = flags.log.empty() ? viewer::RunLiveView(ctx->site, ctx->bus.get(), options,
                                                         &render, flags, display.get(), &error)
                                   : viewer::ReplayIntoView(ctx->site, options, &render, flags,
                                                            display.get(), &error);
  if (rc != 0 && !error.empty()) roomfix::PrintFailure(kProcessName, error);
  return rc;
}
