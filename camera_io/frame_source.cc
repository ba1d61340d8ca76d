// Frame sources: a V4L2 webcam through OpenCV, a video file through OpenCV's
// FFmpeg backend, and a sorted list of image files. JPEG data (MJPEG webcam
// buffers, MJPEG video packets, .jpg files) stays compressed in a FrameImage
// until the detector decodes the part it needs.

#include "camera_io/frame_source.h"

#include <dirent.h>
#include <fmt/format.h>
#include <glob.h>
#include <sys/stat.h>
#include <time.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/videoio.hpp>
#include <thread>
#include <utility>

#include "camera_io/image_file.h"
#include "camera_io/jpeg_image.h"
#include "camera_io/v4l2_properties.h"

namespace roomfix::camera {
namespace {

int64_t ClockMicros(clockid_t clock) {
  timespec ts{};
  clock_gettime(clock, &ts);
  return int64_t{ts.tv_sec} * 1000000 + ts.tv_nsec / 1000;
}

int64_t NowUtime() { return ClockMicros(CLOCK_REALTIME); }

bool PathExists(const std::string& path) {
  struct stat st {};
  return stat(path.c_str(), &st) == 0;
}

bool IsDirectory(const std::string& path) {
  struct stat st {};
  return stat(path.c_str(), &st) == 0 && S_ISDIR(st.st_mode);
}

bool IsRegularFile(const std::string& path) {
  struct stat st {};
  return stat(path.c_str(), &st) == 0 && S_ISREG(st.st_mode);
}

std::string Lower(std::string text) {
  std::transform(text.begin(), text.end(), text.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return text;
}

std::string FourccText(int fourcc) {
  std::string text;
  for (int i = 0; i < 4; ++i) {
    const char c = static_cast<char>((fourcc >> (8 * i)) & 0xFF);
    text += std::isprint(static_cast<unsigned char>(c)) ? c : '?';
  }
  return text;
}

// Whether a Mat from OpenCV is a compressed buffer (one row or column of bytes
// starting with a JPEG start-of-image marker) rather than decoded pixels.
bool IsJpegBuffer(const cv::Mat& mat) {
  return !mat.empty() && mat.type() == CV_8UC1 && (mat.rows == 1 || mat.cols == 1) &&
         mat.isContinuous() && mat.total() >= 4 && mat.data[0] == 0xFF && mat.data[1] == 0xD8;
}

// JPEG bytes to a frame image; a buffer with no end-of-image marker is
// refused before decoding (a truncated transfer or file).
std::unique_ptr<FrameImage> WrapJpeg(std::vector<uint8_t> bytes, std::string* error,
                                     FrameProblem* problem) {
  if (bytes.empty()) {
    *error = "empty file";
    *problem = FrameProblem::kEmpty;
    return nullptr;
  }
  if (!JpegHasEndMarker(bytes)) {
    *error = "truncated JPEG (premature end of data: no end-of-image marker)";
    *problem = FrameProblem::kTruncated;
    return nullptr;
  }
  return MakeJpegImage(std::move(bytes), error, problem);
}

std::vector<uint8_t> MatBytes(const cv::Mat& mat) {
  return std::vector<uint8_t>(mat.data, mat.data + mat.total() * mat.elemSize());
}

// The capture time of a file frame: virtual (start + seq / fps) or, in real
// time, the read time after pacing to fps.
class FilePacer {
 public:
  explicit FilePacer(const CaptureSettings& settings) : settings_(settings) {}
  void Reset() { started_ = false; }
  int64_t Stamp(int64_t seq) {
    const double fps = settings_.fps > 0 ? settings_.fps : 30.0;
    if (!settings_.realtime) {
      return settings_.start_utime + std::llround(static_cast<double>(seq) * 1e6 / fps);
    }
    const int64_t now = NowUtime();
    if (!started_) {
      started_ = true;
      first_seq_ = seq;
      first_utime_ = now;
      return now;
    }
    const int64_t due =
        first_utime_ + std::llround(static_cast<double>(seq - first_seq_) * 1e6 / fps);
    if (due > now) std::this_thread::sleep_for(std::chrono::microseconds(due - now));
    return NowUtime();
  }

 private:
  CaptureSettings settings_;
  bool started_ = false;
  int64_t first_seq_ = 0;
  int64_t first_utime_ = 0;
};

// ---------------------------------------------------------------- V4L2

class V4l2Source : public FrameSource {
 public:
  V4l2Source(std::string path, int index, const CaptureSettings& settings)
      : path_(std::move(path)), index_(index), settings_(settings) {}

  bool Open(std::string* error) override {
    Close();
    if (!PathExists(path_)) {
      *error = "cannot open " + path_ + ": no such device";
      return false;
    }
    const bool opened =
        index_ >= 0 ? capture_.open(index_, cv::CAP_V4L2) : capture_.open(path_, cv::CAP_V4L2);
    if (!opened || !capture_.isOpened()) {
      *error = "cannot open " + path_ + ": the V4L2 backend refused it (busy, or not a camera)";
      capture_.release();
      return false;
    }
    refused_.clear();
    const std::string& format = settings_.pixel_format;
    if (format.size() == 4) {
      const int fourcc = cv::VideoWriter::fourcc(format[0], format[1], format[2], format[3]);
      capture_.set(cv::CAP_PROP_FOURCC, fourcc);
    } else if (!format.empty()) {
      refused_.push_back("pixel_format: " + format + " is not a four-character code");
    }
    capture_.set(cv::CAP_PROP_FRAME_WIDTH, settings_.width_px);
    capture_.set(cv::CAP_PROP_FRAME_HEIGHT, settings_.height_px);
    if (settings_.fps > 0) capture_.set(cv::CAP_PROP_FPS, settings_.fps);

    got_fourcc_ = FourccText(static_cast<int>(capture_.get(cv::CAP_PROP_FOURCC)));
    got_width_ = static_cast<int>(capture_.get(cv::CAP_PROP_FRAME_WIDTH));
    got_height_ = static_cast<int>(capture_.get(cv::CAP_PROP_FRAME_HEIGHT));
    got_fps_ = capture_.get(cv::CAP_PROP_FPS);
    if (format.size() == 4 && got_fourcc_ != format) {
      refused_.push_back("pixel_format: asked " + format + ", got " + got_fourcc_);
    }
    if (got_width_ != settings_.width_px || got_height_ != settings_.height_px) {
      refused_.push_back("size: asked " + std::to_string(settings_.width_px) + "x" +
                         std::to_string(settings_.height_px) + ", got " +
                         std::to_string(got_width_) + "x" + std::to_string(got_height_));
    }
    if (settings_.fps > 0 && std::fabs(got_fps_ - settings_.fps) > 0.5) {
      refused_.push_back(fmt::format("fps: asked {:g}, got {:g}", settings_.fps, got_fps_));
    }
    // MJPEG: the backend hands over the driver's compressed buffer as a 1xN
    // CV_8UC1 Mat when RGB conversion is off.
    raw_ = (got_fourcc_ == "MJPG" || got_fourcc_ == "JPEG") &&
           capture_.set(cv::CAP_PROP_CONVERT_RGB, 0);
    auto set = [this](int id, double value) { return capture_.set(id, value); };
    auto get = [this](int id) { return capture_.get(id); };
    for (std::string& line : ApplyCaptureProperties(settings_.properties, set, get)) {
      refused_.push_back(std::move(line));
    }
    return true;
  }

  void Close() override { capture_.release(); }

  ReadStatus Read(Frame* frame, std::string* error) override {
    frame->problem = FrameProblem::kNone;
    if (!capture_.isOpened()) {
      *error = path_ + " is not open";
      return ReadStatus::kDeviceLost;
    }
    if (!capture_.read(mat_)) {
      *error = "read failed on " + path_ +
               (PathExists(path_) ? " (the camera stopped streaming)" : " (device unplugged)");
      return ReadStatus::kDeviceLost;
    }
    const int64_t real_now = ClockMicros(CLOCK_REALTIME);
    const int64_t mono_now = ClockMicros(CLOCK_MONOTONIC);
    frame->seq = seq_++;
    frame->capture_utime = real_now;
    // The V4L2 buffer timestamp, normally on CLOCK_MONOTONIC: moved to the
    // epoch by the realtime - monotonic offset now; used only when plausible
    // (in the past, by less than a few seconds).
    const double buffer_ms = capture_.get(cv::CAP_PROP_POS_MSEC);
    if (buffer_ms > 0) {
      const int64_t buffer_us = std::llround(buffer_ms * 1000.0);
      constexpr int64_t kMaxAgeUs = 5000000;
      const int64_t age_mono = mono_now - buffer_us;
      const int64_t age_real = real_now - buffer_us;
      if (age_mono >= 0 && age_mono < kMaxAgeUs) {
        frame->capture_utime = real_now - age_mono;
      } else if (age_real >= 0 && age_real < kMaxAgeUs) {
        frame->capture_utime = buffer_us;  // a driver stamping on the realtime clock
      }
    }
    if (IsJpegBuffer(mat_)) {
      std::string reason;
      frame->image = WrapJpeg(MatBytes(mat_), &reason, &frame->problem);
      if (frame->image == nullptr) {
        *error = path_ + " frame " + std::to_string(frame->seq) + ": " + reason;
        return ReadStatus::kBadFrame;
      }
      return ReadStatus::kFrame;
    }
    if (mat_.empty() || mat_.type() != CV_8UC3) {
      *error = path_ + " frame " + std::to_string(frame->seq) + ": empty or undecodable buffer";
      frame->problem = FrameProblem::kEmpty;
      return ReadStatus::kBadFrame;
    }
    frame->image = MakeDecodedImage(mat_.clone());
    return ReadStatus::kFrame;
  }

  std::string Describe() const override {
    return fmt::format("v4l2 {} {}x{} {} {:g} fps{}", path_, got_width_, got_height_, got_fourcc_,
                       got_fps_, raw_ ? " (compressed)" : "");
  }
  bool live() const override { return true; }
  std::vector<std::string> refused_properties() const override { return refused_; }

 private:
  std::string path_;
  int index_;
  CaptureSettings settings_;
  cv::VideoCapture capture_;
  cv::Mat mat_;
  bool raw_ = false;
  std::string got_fourcc_ = "?";
  int got_width_ = 0;
  int got_height_ = 0;
  double got_fps_ = 0;
  int64_t seq_ = 0;
  std::vector<std::string> refused_;
};

// ---------------------------------------------------------------- video file

class VideoFileSource : public FrameSource {
 public:
  VideoFileSource(std::string path, const CaptureSettings& settings)
      : path_(std::move(path)), settings_(settings), pacer_(settings) {}

  bool Open(std::string* error) override {
    Close();
    if (!IsRegularFile(path_)) {
      *error = "cannot open video " + path_ + ": no such file";
      return false;
    }
    if (!OpenCapture(error)) return false;
    pacer_.Reset();
    return true;
  }

  void Close() override {
    capture_.release();
    pending_.release();
  }

  ReadStatus Read(Frame* frame, std::string* error) override {
    frame->problem = FrameProblem::kNone;
    if (!capture_.isOpened()) {
      *error = "video " + path_ + " is not open";
      return ReadStatus::kEndOfStream;
    }
    bool have = false;
    if (!pending_.empty()) {
      mat_ = pending_;
      pending_.release();
      have = true;
    } else {
      have = capture_.read(mat_);
    }
    if (!have && settings_.loop && frames_this_pass_ > 0) {
      if (!OpenCapture(error)) return ReadStatus::kEndOfStream;
      have = !pending_.empty() || capture_.read(mat_);
      if (!pending_.empty()) {
        mat_ = pending_;
        pending_.release();
      }
    }
    if (!have) {
      *error = "end of " + path_;
      return ReadStatus::kEndOfStream;
    }
    ++frames_this_pass_;
    frame->seq = seq_++;
    frame->capture_utime = pacer_.Stamp(frame->seq);
    std::string reason;
    if (raw_) {
      frame->image =
          IsJpegBuffer(mat_) ? WrapJpeg(MatBytes(mat_), &reason, &frame->problem) : nullptr;
      if (frame->image == nullptr && reason.empty()) {
        reason = "packet is not a JPEG frame";
        frame->problem = FrameProblem::kUnreadable;
      }
    } else if (!mat_.empty()) {
      frame->image = MakeDecodedImage(mat_.clone());
    } else {
      reason = "empty frame";
      frame->problem = FrameProblem::kEmpty;
    }
    if (frame->image == nullptr) {
      *error = path_ + " frame " + std::to_string(frame->seq) + ": " + reason;
      return ReadStatus::kBadFrame;
    }
    return ReadStatus::kFrame;
  }

  std::string Describe() const override {
    return "video " + path_ + (raw_ ? " (MJPEG packets, decoded on demand)" : " (decoded)");
  }
  bool live() const override { return false; }
  // Whether the MJPEG packets are read compressed (after Open).
  bool raw() const { return raw_; }

 private:
  // Opens the file; an MJPEG stream is tried in the FFmpeg backend's raw mode
  // (CAP_PROP_FORMAT = -1: one compressed packet per read), kept when the
  // first packet is a JPEG, else the file is opened again decoded.
  bool OpenCapture(std::string* error) {
    capture_.release();
    pending_.release();
    frames_this_pass_ = 0;
    raw_ = false;
    if (!capture_.open(path_, cv::CAP_FFMPEG) || !capture_.isOpened()) {
      *error = "cannot open video " + path_ + ": the FFmpeg backend cannot read it";
      return false;
    }
    const std::string fourcc =
        Lower(FourccText(static_cast<int>(capture_.get(cv::CAP_PROP_FOURCC))));
    const bool mjpeg = fourcc == "mjpg" || fourcc == "avi1" || fourcc == "jpeg" ||
                       fourcc == "mjpa" || fourcc == "mjpb" || fourcc == "dmb1";
    if (!mjpeg) return true;
    if (capture_.set(cv::CAP_PROP_FORMAT, -1) && capture_.read(pending_) &&
        IsJpegBuffer(pending_)) {
      raw_ = true;
      return true;
    }
    capture_.release();
    pending_.release();
    if (!capture_.open(path_, cv::CAP_FFMPEG) || !capture_.isOpened()) {
      *error = "cannot open video " + path_ + ": the FFmpeg backend cannot read it";
      return false;
    }
    return true;
  }

  std::string path_;
  CaptureSettings settings_;
  FilePacer pacer_;
  cv::VideoCapture capture_;
  cv::Mat mat_;
  cv::Mat pending_;  // the packet read while probing raw mode
  bool raw_ = false;
  int64_t frames_this_pass_ = 0;
  int64_t seq_ = 0;
};

// ---------------------------------------------------------------- image files

class ImageFilesSource : public FrameSource {
 public:
  ImageFilesSource(std::string pattern, const CaptureSettings& settings)
      : pattern_(std::move(pattern)), settings_(settings), pacer_(settings) {}

  bool Open(std::string* error) override {
    files_.clear();
    next_ = 0;
    pacer_.Reset();
    if (IsDirectory(pattern_)) {
      DIR* dir = opendir(pattern_.c_str());
      if (dir == nullptr) {
        *error = "cannot open folder " + pattern_;
        return false;
      }
      while (const dirent* entry = readdir(dir)) {
        const std::string name = entry->d_name;
        if (name.empty() || name[0] == '.') continue;
        const std::string path = pattern_ + "/" + name;
        if (IsRegularFile(path)) files_.push_back(path);
      }
      closedir(dir);
    } else {
      glob_t matches{};
      if (glob(pattern_.c_str(), 0, nullptr, &matches) == 0) {
        for (size_t i = 0; i < matches.gl_pathc; ++i) {
          if (IsRegularFile(matches.gl_pathv[i])) files_.emplace_back(matches.gl_pathv[i]);
        }
      }
      globfree(&matches);
    }
    std::sort(files_.begin(), files_.end());
    if (files_.empty()) {
      *error = "no image files match " + pattern_;
      return false;
    }
    return true;
  }

  void Close() override {}

  ReadStatus Read(Frame* frame, std::string* error) override {
    frame->problem = FrameProblem::kNone;
    if (files_.empty()) {
      *error = "no image files (not open)";
      return ReadStatus::kEndOfStream;
    }
    if (next_ >= files_.size()) {
      if (!settings_.loop) {
        *error = "end of " + pattern_;
        return ReadStatus::kEndOfStream;
      }
      next_ = 0;
    }
    const std::string& path = files_[next_++];
    frame->seq = seq_++;
    frame->capture_utime = pacer_.Stamp(frame->seq);
    frame->image.reset();
    std::string reason;
    std::vector<uint8_t> bytes;
    // Bounded read, then the size from the header before any decoding: a
    // frame over the camera's size is refused undecoded (kTooLargeText), so
    // a forged header claiming 100000 x 100000 px costs nothing.
    ImageHeader header;
    if (!ReadImageBytes(path, &bytes, &reason)) {
      frame->problem = FrameProblem::kUnreadable;
    } else if (bytes.empty()) {
      reason = "empty file";
      frame->problem = FrameProblem::kEmpty;
    } else if (!ReadImageHeader(bytes.data(), bytes.size(), &header, &reason, &frame->problem)) {
    } else if (header.width_px > settings_.width_px || header.height_px > settings_.height_px) {
      frame->problem = FrameProblem::kWrongSize;
      reason = header.format + " of " + std::to_string(header.width_px) + " x " +
               std::to_string(header.height_px) + " px is " + kTooLargeText + " of the camera's " +
               std::to_string(settings_.width_px) + " x " + std::to_string(settings_.height_px) +
               " px (not decoded)";
    } else if (header.format == "JPEG") {
      frame->image = WrapJpeg(std::move(bytes), &reason, &frame->problem);
    } else {
      cv::Mat bgr;
      if (DecodeImageChecked(bytes, settings_.width_px, settings_.height_px, cv::IMREAD_COLOR, &bgr,
                             &reason, &frame->problem)) {
        frame->image = MakeDecodedImage(std::move(bgr));
      }
    }
    if (frame->image == nullptr) {
      *error = path + ": " + reason;
      return ReadStatus::kBadFrame;
    }
    return ReadStatus::kFrame;
  }

  std::string Describe() const override {
    return "images " + pattern_ + " (" + std::to_string(files_.size()) + " files)";
  }
  bool live() const override { return false; }

 private:
  std::string pattern_;
  CaptureSettings settings_;
  FilePacer pacer_;
  std::vector<std::string> files_;
  size_t next_ = 0;
  int64_t seq_ = 0;
};

bool IsAllDigits(const std::string& text) {
  return !text.empty() && std::all_of(text.begin(), text.end(),
                                      [](unsigned char c) { return std::isdigit(c) != 0; });
}

}  // namespace

std::unique_ptr<FrameSource> MakeFrameSource(const std::string& device,
                                             const CaptureSettings& settings, std::string* error) {
  if (device.empty()) {
    *error = "no camera device given";
    return nullptr;
  }
  if (IsAllDigits(device) && device.size() < 6) {
    return std::make_unique<V4l2Source>("/dev/video" + device, std::stoi(device), settings);
  }
  if (device.rfind("/dev/video", 0) == 0) {
    return std::make_unique<V4l2Source>(device, -1, settings);
  }
  if (IsDirectory(device) || device.find_first_of("*?[") != std::string::npos) {
    return std::make_unique<ImageFilesSource>(device, settings);
  }
  return std::make_unique<VideoFileSource>(device, settings);
}

}  // namespace roomfix::camera
