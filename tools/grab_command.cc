// roomfix grab: test frames from a site camera's own stream, opened as
// camera_proc opens it (sim/sim_camera_source.h MakeCameraSource: the
// device with the site's size, format, rate and properties), so that
// calibration and colour frames are the pixels camera_proc will see.
#include <fmt/format.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <memory>
#include <mutex>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "camera_io/camera_source.h"
#include "camera_io/frame_source.h"
#include "camera_io/image_file.h"
#include "core/world/file_io.h"
#include "core/world/site.h"
#include "msgio/process.h"
#include "sim/sim_camera_source.h"
#include "tools/commands.h"
#include "tools/flag_checks.h"

namespace roomfix {
namespace {

constexpr char kName[] = "roomfix grab: ";

struct GrabOptions {
  std::string site;
  std::optional<int> camera_id;
  std::string out;
  int count = 1;
  double every_s = 0.0;
  std::optional<int> skip;
  double timeout_s = 10.0;
  // --tripod X,Y: the camera's first robot's markers stand at this surveyed
  // floor point (as typed, for the file name). The first robot's, as in
  // `render-camera --tripod-grid`: points.csv has no robot column, and
  // calibrate and colours read it as the first robot's markers.
  std::string tripod;
};

// --tripod's point, parsed; the robot whose markers stand there.
struct TripodPoint {
  double x_m = 0.0;
  double y_m = 0.0;
  const CameraRobot* robot = nullptr;
};

bool ParseTripod(const GrabOptions& f, const Site& site, const Camera& camera, TripodPoint* p,
                 std::string* error) {
  // The whole text one finite number, in range (what std::stod accepts).
  const auto number = [](const std::string& text, double* value) {
    char* end = nullptr;
    errno = 0;
    *value = std::strtod(text.c_str(), &end);
    return end != text.c_str() && end == text.c_str() + text.size() && errno != ERANGE &&
           std::isfinite(*value);
  };
  const size_t comma = f.tripod.find(',');
  if (comma == std::string::npos || !number(f.tripod.substr(0, comma), &p->x_m) ||
      !number(f.tripod.substr(comma + 1), &p->y_m)) {
    *error = "--tripod " + f.tripod + ": expected X,Y in metres, e.g. 1.5,0.5";
    return false;
  }
  const Room& room = site.room;
  if (p->x_m < room.min_x_m || p->x_m > room.min_x_m + room.size_x_m || p->y_m < room.min_y_m ||
      p->y_m > room.min_y_m + room.size_y_m) {
    *error = "--tripod " + f.tripod + " is outside the room";
    return false;
  }
  if (camera.robots.empty()) {
    *error = "camera " + std::to_string(camera.id) +
             " has no robot whose markers the tripod could carry";
    return false;
  }
  p->robot = &camera.robots.front();
  return true;
}

// The frame's file name without its extension: frame_NNNN, or with
// --tripod tripod_X_Y (the point as typed; _N after it when several).
std::string FrameStem(const GrabOptions& f, int index) {
  if (f.tripod.empty()) {
    return fmt::format("frame_{:04d}", index);
  }
  std::string point = f.tripod;
  std::replace(point.begin(), point.end(), ',', '_');
  return "tripod_" + point + (f.count > 1 ? "_" + std::to_string(index) : std::string());
}

// Appends the frames to DIR/points.csv (image,x_m,y_m,height_m: the
// tripod's marker at its height, as `roomfix calibrate --marker-images` and
// `roomfix colours` read it), with the header when the file is new; a row
// for a file already listed is replaced (the point grabbed again).
bool RecordTripod(const GrabOptions& f, const TripodPoint& p, const std::vector<std::string>& files,
                  std::string* error) {
  const std::string path = f.out + "/points.csv";
  std::vector<std::string> lines;
  {
    std::ifstream in(path);
    for (std::string line; std::getline(in, line);) {
      if (line.empty() || line.rfind("image,", 0) == 0) continue;
      const std::string file = line.substr(0, line.find(','));
      if (std::find(files.begin(), files.end(), file) == files.end()) lines.push_back(line);
    }
  }
  std::ostringstream csv;
  csv << "image,x_m,y_m,height_m\n";
  for (const std::string& line : lines) csv << line << "\n";
  for (const std::string& file : files) {
    csv << file << "," << p.x_m << "," << p.y_m << "," << p.robot->marker_height_m << "\n";
  }
  return WriteOutputFile(path, csv.str(), error);
}

// One written frame: a row of frames.csv.
struct GrabRow {
  std::string file;
  int64_t seq = 0;
  int64_t capture_utime = 0;
  int width_px = 0;
  int height_px = 0;
  std::string format;  // "jpeg": the source's bytes; "raw": decoded pixels as PNG
};

using SteadyClock = std::chrono::steady_clock;

// A V4L2 read can block in the driver with no way to cancel it (a camera
// that stopped streaming without going away), so a hung Read is caught from
// another thread: armed around each Read, it ends the process with the
// reason when the deadline passes. Nothing else is in flight then (the main
// thread is inside Read), so a quick exit loses nothing but frames.csv.
class ReadWatchdog {
 public:
  explicit ReadWatchdog(std::string what) : what_(std::move(what)), thread_([this] { Run(); }) {}
  ~ReadWatchdog() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stop_ = true;
    }
    changed_.notify_all();
    thread_.join();
  }
  ReadWatchdog(const ReadWatchdog&) = delete;
  ReadWatchdog& operator=(const ReadWatchdog&) = delete;

  void Arm(SteadyClock::time_point deadline, int written) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      deadline_ = deadline;
      written_ = written;
    }
    changed_.notify_all();
  }
  void Disarm() {
    std::lock_guard<std::mutex> lock(mutex_);
    deadline_.reset();
  }

 private:
  void Run() {
    std::unique_lock<std::mutex> lock(mutex_);
    while (!stop_) {
      if (!deadline_) {
        changed_.wait(lock);
        continue;
      }
      const SteadyClock::time_point deadline = *deadline_;
      changed_.wait_until(lock, deadline);
      if (!stop_ && deadline_ && *deadline_ == deadline && SteadyClock::now() >= deadline) {
        std::fprintf(stderr, "%s%s (%d frames written; frames.csv not written)\n", kName,
                     what_.c_str(), written_);
        std::fflush(stdout);
        std::fflush(stderr);
        std::_Exit(1);
      }
    }
  }

  std::string what_;
  std::mutex mutex_;
  std::condition_variable changed_;
  std::optional<SteadyClock::time_point> deadline_;
  int written_ = 0;
  bool stop_ = false;
  std::thread thread_;  // last: starts once the members above exist
};

// Makes the folder and proves it takes a file, before the camera is opened.
bool PrepareOutDir(const std::string& dir, std::string* error) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec || !std::filesystem::is_directory(dir)) {
    *error = dir + ": cannot make the folder: " + (ec ? ec.message() : "not a folder");
    return false;
  }
  const std::string probe = dir + "/.roomfix_grab_probe";
  std::string why;
  if (!WriteOutputFile(probe, "", &why)) {
    *error = dir + ": not writable: " + why;
    return false;
  }
  std::filesystem::remove(probe, ec);
  return true;
}

// Writes the frame as DIR/frame_NNNN.jpg (a JPEG source's own bytes, not
// re-encoded: the compression camera_proc sees stays in the file) or .png
// (decoded pixels, lossless).
bool WriteFrame(const camera::Frame& frame, const std::string& dir, const std::string& stem,
                GrabRow* row, std::string* error) {
  camera::FrameImage& image = *frame.image;
  row->seq = frame.seq;
  row->capture_utime = frame.capture_utime;
  row->width_px = image.width_px();
  row->height_px = image.height_px();
  if (const std::vector<uint8_t>* bytes = image.jpeg_bytes()) {
    row->file = std::string(stem) + ".jpg";
    row->format = "jpeg";
    return WriteOutputFile(dir + "/" + row->file, std::string(bytes->begin(), bytes->end()), error);
  }
  row->file = std::string(stem) + ".png";
  row->format = "raw";
  cv::Mat bgr;
  if (!image.DecodeRegion(cv::Rect(0, 0, image.width_px(), image.height_px()), &bgr, error)) {
    *error = row->file + ": " + *error;
    return false;
  }
  return camera::WriteImageChecked(dir + "/" + row->file, bgr, error);
}

std::string FramesCsv(const std::vector<GrabRow>& rows) {
  std::ostringstream csv;
  csv << "file,frame_seq,capture_utime,width_px,height_px,format\n";
  for (const GrabRow& r : rows) {
    csv << r.file << "," << r.seq << "," << r.capture_utime << "," << r.width_px << ","
        << r.height_px << "," << r.format << "\n";
  }
  return csv.str();
}

// What was asked of the device and what it refused, as camera_proc logs it.
void PrintSource(const CameraChoice& choice, const camera::FrameSource& source, int skip) {
  const Camera& camera = choice.camera;
  std::cout << "camera " << camera.id << ": " << source.Describe() << "\n";
  std::cout << "  site asks " << camera.width_px << "x" << camera.height_px << " "
            << camera.pixel_format << " at " << camera.fps << " fps\n";
  std::cout << "  properties: ";
  if (!source.live()) {
    std::cout << "not applied (" << (IsSimDevice(choice.device) ? "the synthetic camera" : "a file")
              << " has no controls)\n";
  } else if (camera.properties.empty()) {
    std::cout << "none in the site file\n";
  } else {
    const char* sep = "";
    for (const auto& [name, value] : camera.properties) {
      std::cout << sep << name << " " << value;
      sep = ", ";
    }
    std::cout << "\n";
  }
  const std::vector<std::string> refused = source.refused_properties();
  for (const std::string& line : refused) std::cout << "  refused: " << line << "\n";
  if (source.live() && !refused.empty()) {
    std::cout << "  (camera_proc runs with the same refusals: fix them before calibrating)\n";
  }
  std::cout << "  skipping " << skip << " frames"
            << (source.live() ? " (auto-exposure settling)" : "") << "\n";
}

struct GrabLoopResult {
  std::vector<GrabRow> rows;
  int bad_frames = 0;
  std::string failure;  // "" when all frames were written
};

// Reads frames, skips the first `skip` good ones, then writes one whenever
// its capture time is `every` past the last written one's: a live camera is
// read all the while (a driver's queued frames are not minutes old), and a
// file's virtual clock (seq / fps) spaces its frames as the camera would.
GrabLoopResult GrabLoop(const GrabOptions& f, int skip, camera::FrameSource* source,
                        const std::string& device) {
  GrabLoopResult result;
  const auto timeout =
      std::chrono::duration_cast<SteadyClock::duration>(std::chrono::duration<double>(f.timeout_s));
  std::ostringstream what;
  what << "no frame from " << device << " in " << f.timeout_s << " s (--timeout)";
  ReadWatchdog watchdog(what.str());
  const int64_t every_us = std::llround(f.every_s * 1e6);
  int skipped = 0;
  int64_t next_due_utime = 0;
  auto last_good = SteadyClock::now();
  while (static_cast<int>(result.rows.size()) < f.count) {
    // Ctrl-C in a long `--every` session keeps what was written, with its
    // frames.csv.
    if (ShutdownRequested()) {
      result.failure = "interrupted: " + std::to_string(result.rows.size()) + " of " +
                       std::to_string(f.count) + " frames written";
      return result;
    }
    camera::Frame frame;
    std::string error;
    watchdog.Arm(last_good + timeout, static_cast<int>(result.rows.size()));
    const camera::ReadStatus status = source->Read(&frame, &error);
    watchdog.Disarm();
    if (status == camera::ReadStatus::kBadFrame) {
      ++result.bad_frames;
      std::cerr << kName << "bad frame: " << error << "\n";
      // A device that delivers only bad frames must not keep grab going.
      if (SteadyClock::now() >= last_good + timeout) {
        result.failure = what.str();
        return result;
      }
      continue;
    }
    if (status != camera::ReadStatus::kFrame) {
      result.failure = error + ": " + std::to_string(result.rows.size()) + " of " +
                       std::to_string(f.count) + " frames written";
      return result;
    }
    last_good = SteadyClock::now();
    if (skipped < skip) {
      ++skipped;
      continue;
    }
    if (!result.rows.empty() && frame.capture_utime < next_due_utime) continue;
    GrabRow row;
    if (!WriteFrame(frame, f.out, FrameStem(f, static_cast<int>(result.rows.size())), &row,
                    &error)) {
      result.failure = error;
      return result;
    }
    std::cout << "  " << row.file << ": frame " << row.seq << ", " << row.width_px << "x"
              << row.height_px << ", " << row.format << "\n";
    result.rows.push_back(row);
    next_due_utime = frame.capture_utime + every_us;
    // Time spent writing is not the device's.
    last_good = SteadyClock::now();
  }
  return result;
}

int RunGrab(const GrabOptions& f) {
  if (f.count <= 0) {
    std::cerr << kName << "--count must be at least 1, not " << f.count << "\n";
    return 1;
  }
  if (f.skip && *f.skip < 0) {
    std::cerr << kName << "--skip must be 0 or more, not " << *f.skip << "\n";
    return 1;
  }
  if (f.camera_id && *f.camera_id < 0) {
    std::cerr << kName << "--camera must be a site camera's id (0 or more), not " << *f.camera_id
              << "\n";
    return 1;
  }
  Site site;
  std::string error;
  if (!LoadSite(f.site, &site, &error)) {
    std::cerr << kName << error << "\n";
    return 1;
  }
  CameraSourceOptions options;
  SimCameraOptions sim_options;
  options.camera_id = f.camera_id.value_or(-1);
  // Frames are grabbed to make or check a calibration: the site's file may
  // not exist yet, and grab does not use it.
  options.calibration_path = "none";
  CameraChoice choice;
  TripodPoint tripod;
  if (!ChooseCamera(site, options, &choice, &error) ||
      (!f.tripod.empty() && !ParseTripod(f, site, choice.camera, &tripod, &error))) {
    std::cerr << kName << f.site << ": " << error << "\n";
    return 1;
  }
  if (!f.tripod.empty()) {
    // On the synthetic camera the simulator stands the tripod there.
    sim_options.parked_robots.push_back({tripod.robot->robot_id, tripod.x_m, tripod.y_m, 0.0});
  }
  if (!PrepareOutDir(f.out, &error)) {
    std::cerr << kName << error << "\n";
    return 1;
  }
  const int64_t now_utime = std::chrono::duration_cast<std::chrono::microseconds>(
                                std::chrono::system_clock::now().time_since_epoch())
                                .count();
  std::unique_ptr<camera::FrameSource> source;
  std::string summary;
  if (!MakeCameraSource(site, choice, options, sim_options, now_utime, false, &source, &summary,
                        &error) ||
      !source->Open(&error)) {
    std::cerr << kName << "camera " << choice.camera.id << ": " << error << "\n";
    return 1;
  }
  // About a second of frames lets a webcam's auto-exposure and white balance
  // settle after the stream starts; files and the synthetic camera have
  // nothing to settle.
  const int skip =
      f.skip ? *f.skip
             : (source->live() ? std::max(1, static_cast<int>(std::lround(choice.camera.fps * 1.0)))
                               : 0);
  PrintSource(choice, *source, skip);
  InstallShutdownHandlers();
  const GrabLoopResult result = GrabLoop(f, skip, source.get(), choice.device);
  source->Close();
  std::vector<std::string> files;
  for (const GrabRow& r : result.rows) files.push_back(r.file);
  if (!result.rows.empty() &&
      (!WriteOutputFile(f.out + "/frames.csv", FramesCsv(result.rows), &error) ||
       (!f.tripod.empty() && !RecordTripod(f, tripod, files, &error)))) {
    std::cerr << kName << error << "\n";
    return 1;
  }
  const Camera& camera = choice.camera;
  const auto wrong_size =
      std::count_if(result.rows.begin(), result.rows.end(), [&](const GrabRow& r) {
        return r.width_px != camera.width_px || r.height_px != camera.height_px;
      });
  std::cout << "wrote " << result.rows.size() << " frames"
            << (result.rows.empty() ? "" : " and frames.csv") << " to " << f.out;
  if (result.bad_frames > 0) std::cout << "; " << result.bad_frames << " bad frames passed over";
  std::cout << "\n";
  if (!result.failure.empty()) {
    std::cerr << kName << result.failure << "\n";
    return 1;
  }
  if (wrong_size > 0) {
    const GrabRow& r = *std::find_if(result.rows.begin(), result.rows.end(), [&](const GrabRow& x) {
      return x.width_px != camera.width_px || x.height_px != camera.height_px;
    });
    std::cerr << kName << wrong_size << " of " << result.rows.size() << " frames are " << r.width_px
              << "x" << r.height_px << ", not camera " << camera.id << "'s " << camera.width_px
              << "x" << camera.height_px
              << " in the site file: a calibration made for the site's size would not apply "
                 "to them\n";
    return 1;
  }
  return 0;
}

}  // namespace

void AddGrabCommand(CLI::App* app, int* exit_code) {
  auto* cmd = app->add_subcommand(
      "grab",
      "Save frames from a site camera's device, opened as camera_proc opens it (size, format, "
      "rate and properties from the site file): JPEG frames as the camera sent them, raw ones "
      "as PNG, and frames.csv");
  auto f = std::make_shared<GrabOptions>();
  cmd->add_option("--site", f->site, "Site file")->required();
  cmd->add_option("--camera", f->camera_id, "Camera id in the site file (default: the first)");
  cmd->add_option("--out", f->out, "Folder for frame_NNNN.jpg/.png and frames.csv")->required();
  cmd->add_option("--count", f->count, "Frames to write")->capture_default_str();
  cmd->add_option("--every", f->every_s,
                  "Seconds of capture time between written frames (0: consecutive frames)")
      ->capture_default_str()
      ->check(FiniteAtLeast(0.0, "a number of seconds >= 0"));
  cmd->add_option("--skip", f->skip,
                  "Frames to pass over first (default: a second's worth on a live camera, for "
                  "auto-exposure to settle; 0 for files and sim:)");
  cmd->add_option("--timeout", f->timeout_s,
                  "Give up when the device delivers no frame for this many seconds")
      ->capture_default_str()
      ->check(FiniteAbove(0.0, "a number of seconds > 0"));
  cmd->add_option(
      "--tripod", f->tripod,
      "X,Y: the camera's first robot's markers stand on a tripod at this surveyed floor "
      "point (m): the "
      "frames are named tripod_X_Y and added to DIR/points.csv for roomfix calibrate "
      "--marker-images and roomfix colours (on a sim: camera the simulator stands "
      "them there)");
  cmd->callback([f, exit_code] { *exit_code = RunGrab(*f); });
}

}  // namespace roomfix
