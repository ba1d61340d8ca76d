#include "sim/sim_frame_source.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <opencv2/imgcodecs.hpp>
#include <utility>

namespace roomfix::sim {

using camera::Frame;
using camera::ReadStatus;

namespace {

int64_t WallUtime() {
  return std::chrono::duration_cast<std::chrono::microseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

}  // namespace

calib::CameraTiming ScenarioTiming(const SimScenario& scenario, int height_px) {
  calib::CameraTiming timing;
  timing.height_px = height_px;
  // Only the webcam scenario renders rows at their own times, integrates
  // over an exposure and stamps late (SyntheticCamera::Render and
  // TimestampDelayS); the others render every row at the frame's instant.
  if (scenario.webcam_effects) {
    timing.readout_s = scenario.webcam.readout_s;
    timing.exposure_s = scenario.webcam.exposure_s;
    timing.latency_s = scenario.webcam.timestamp_latency_s;
  }
  return timing;
}

SimFrameSource::SimFrameSource(std::shared_ptr<const SyntheticCamera> camera,
                               SimSourceOptions options)
    : camera_(std::move(camera)), options_(std::move(options)) {
  if (!options_.clock) options_.clock = WallUtime;
  options_.queue_frames = std::max(1, options_.queue_frames);
}

SimFrameSource::~SimFrameSource() { Close(); }

bool SimFrameSource::Open(std::string* error) {
  if (camera_ == nullptr) {
    *error = "no synthetic camera";
    return false;
  }
  if (!(options_.fps > 0.0)) {
    *error = "the simulated camera needs a positive frame rate";
    return false;
  }
  if (options_.realtime && !producer_.joinable()) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stop_ = false;
      queue_.clear();
      rendered_.reset();
    }
    producer_ = std::thread(&SimFrameSource::RenderLoop, this);
    encoder_ = std::thread(&SimFrameSource::EncodeLoop, this);
  }
  return true;
}

void SimFrameSource::Close() {
  if (!producer_.joinable()) return;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  changed_.notify_all();
  producer_.join();
  encoder_.join();
  std::lock_guard<std::mutex> lock(mutex_);
  queue_.clear();
  rendered_.reset();
}

int64_t SimFrameSource::render_skipped() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return render_skipped_;
}

int64_t SimFrameSource::CaptureUtime(int64_t seq) const {
  return options_.start_utime + static_cast<int64_t>(std::llround(seq * 1e6 / options_.fps));
}

void SimFrameSource::RenderPixels(int64_t seq, Rendered* out) const {
  // The frame starts (row 0 is read) at start + seq / fps; its timestamp is
  // the last row's read time plus the latency and jitter (the webcam
  // scenario; 0 otherwise).
  const int64_t capture = CaptureUtime(seq);
  const double t_s = (capture - options_.start_utime) * 1e-6;
  if (options_.duration_s > 0.0 && t_s > options_.duration_s) {
    out->status = ReadStatus::kEndOfStream;
    return;
  }
  camera_->Render(
      t_s, seq,
      options_.parked_robots.empty() ? camera_->SimulatedRobots(t_s) : options_.parked_robots,
      &out->bgr, &out->truth);
  out->frame.capture_utime = capture + std::llround(camera_->TimestampDelayS(seq) * 1e6);
  out->frame.seq = seq;
  out->status = ReadStatus::kFrame;
}

void SimFrameSource::Encode(Rendered* out) const {
  if (out->status != ReadStatus::kFrame) return;
  if (camera_->JpegQuality(options_.jpeg_quality) > 0) {
    std::vector<uint8_t> bytes;
    if (!camera_->Encode(out->bgr, options_.jpeg_quality, &bytes)) {
      out->error = "cannot encode synthetic frame " + std::to_string(out->frame.seq);
      out->frame.problem = camera::FrameProblem::kUnreadable;
      out->status = ReadStatus::kBadFrame;
      return;
    }
    out->frame.image = camera::MakeJpegImage(std::move(bytes), &out->error, &out->frame.problem);
    if (out->frame.image == nullptr) out->status = ReadStatus::kBadFrame;
  } else {
    out->frame.image = camera::MakeDecodedImage(std::move(out->bgr));
  }
  out->bgr.release();
}

bool SimFrameSource::WaitUntil(int64_t utime, std::unique_lock<std::mutex>* lock) {
  // The clock may be any (a test's); re-read it after each wake-up, which
  // is at most the remaining wait.
  while (!stop_) {
    const int64_t wait_us = utime - options_.clock();
    if (wait_us <= 0) return true;
    changed_.wait_for(*lock, std::chrono::microseconds(wait_us));
  }
  return false;
}

void SimFrameSource::RenderLoop() {
  const double period_us = 1e6 / options_.fps;
  int64_t skipped = 0;
  std::unique_lock<std::mutex> lock(mutex_);
  // Reopened, the numbering goes on: a seq is never handed over twice.
  int64_t& seq = produce_seq_;
  while (!stop_) {
    // A frame whose start has passed by a whole period was missed while the
    // last one rendered: skip to the newest, as a camera's driver would.
    const int64_t now = options_.clock();
    if (now > CaptureUtime(seq)) {
      const int64_t newest =
          static_cast<int64_t>(std::floor((now - options_.start_utime) / period_us));
      if (newest > seq) {
        skipped += newest - seq;
        render_skipped_ += newest - seq;
        seq = newest;
      }
    }
    if (!WaitUntil(CaptureUtime(seq), &lock)) break;
    Rendered item;
    lock.unlock();
    RenderPixels(seq, &item);
    lock.lock();
    item.frame.source_skipped = skipped;
    skipped = 0;
    // The encoder takes one frame at a time; waiting for it is falling
    // behind, which the next frame's skip check sees.
    changed_.wait(lock, [&] { return !rendered_.has_value() || stop_; });
    if (stop_) break;
    const bool end = item.status == ReadStatus::kEndOfStream;
    rendered_ = std::move(item);
    changed_.notify_all();
    if (end) break;
    ++seq;
  }
}

void SimFrameSource::EncodeLoop() {
  std::unique_lock<std::mutex> lock(mutex_);
  while (!stop_) {
    changed_.wait(lock, [&] { return rendered_.has_value() || stop_; });
    if (stop_) break;
    Rendered item = std::move(*rendered_);
    rendered_.reset();
    changed_.notify_all();
    lock.unlock();
    Encode(&item);
    lock.lock();
    // Handed over at its timestamp, not before (a camera cannot deliver a
    // frame before its last row is read).
    const bool end = item.status == ReadStatus::kEndOfStream;
    if (!end && !WaitUntil(item.frame.capture_utime, &lock)) break;
    if (static_cast<int>(queue_.size()) >= options_.queue_frames) {
      // The reader is behind: the oldest frame goes (camera_proc's drop),
      // but the renderer's own skips before it stay counted as such.
      const int64_t carried = queue_.front().frame.source_skipped;
      queue_.pop_front();
      if (!queue_.empty()) {
        queue_.front().frame.source_skipped += carried;
      } else {
        item.frame.source_skipped += carried;
      }
    }
    queue_.push_back(std::move(item));
    changed_.notify_all();
    if (end) break;
  }
}

ReadStatus SimFrameSource::Read(Frame* frame, std::string* error) {
  Rendered item;
  if (options_.realtime) {
    std::unique_lock<std::mutex> lock(mutex_);
    if (!producer_.joinable()) {
      *error = "the synthetic camera is not open";
      return ReadStatus::kDeviceLost;
    }
    changed_.wait(lock, [&] { return !queue_.empty() || stop_; });
    if (queue_.empty()) {
      *error = "the synthetic camera was closed";
      return ReadStatus::kDeviceLost;
    }
    // The end stays queued, so every later Read says so too.
    if (queue_.front().status == ReadStatus::kEndOfStream) return ReadStatus::kEndOfStream;
    item = std::move(queue_.front());
    queue_.pop_front();
  } else {
    RenderPixels(next_seq_++, &item);
    Encode(&item);
  }
  if (item.status == ReadStatus::kEndOfStream) return item.status;
  truth_ = std::move(item.truth);
  *frame = std::move(item.frame);
  if (item.status == ReadStatus::kBadFrame) *error = item.error;
  return item.status;
}

std::optional<calib::CameraTiming> SimFrameSource::device_timing() const {
  return ScenarioTiming(camera_->scenario(), camera_->height_px());
}

std::string SimFrameSource::Describe() const {
  return "synthetic camera " + std::to_string(camera_->width_px()) + "x" +
         std::to_string(camera_->height_px()) + " at " + std::to_string(options_.fps) + " fps" +
         (camera_->JpegQuality(options_.jpeg_quality) > 0
              ? " (JPEG " + std::to_string(camera_->JpegQuality(options_.jpeg_quality)) + ")"
              : " (raw)") +
         (camera_->scenario().webcam_effects ? ", webcam effects" : "");
}

}  // namespace roomfix::sim
