#include "camera_proc/sim_frame_source.h"

#include <chrono>
#include <cmath>
#include <opencv2/imgcodecs.hpp>
#include <thread>
#include <utility>

namespace roomfix::camera {
namespace {

int64_t WallUtime() {
  return std::chrono::duration_cast<std::chrono::microseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

}  // namespace

SimFrameSource::SimFrameSource(std::shared_ptr<const sim::SyntheticCamera> camera,
                               SimSourceOptions options)
    : camera_(std::move(camera)), options_(std::move(options)) {
  if (!options_.clock) options_.clock = WallUtime;
}

bool SimFrameSource::Open(std::string* error) {
  if (camera_ == nullptr) {
    *error = "no synthetic camera";
    return false;
  }
  if (!(options_.fps > 0.0)) {
    *error = "the simulated camera needs a positive frame rate";
    return false;
  }
  return true;
}

ReadStatus SimFrameSource::Read(Frame* frame, std::string* error) {
  const double period_us = 1e6 / options_.fps;
  auto capture_of = [&](int64_t seq) {
    return options_.start_utime + static_cast<int64_t>(std::llround(seq * period_us));
  };
  if (options_.realtime) {
    const int64_t now = options_.clock();
    // Frames whose exposure is already over were missed while the last one
    // was processed: skip to the newest, as a camera's driver would.
    if (now > capture_of(next_seq_)) {
      const int64_t newest =
          static_cast<int64_t>(std::floor((now - options_.start_utime) / period_us));
      next_seq_ = std::max(next_seq_, newest);
    }
    const int64_t wait = capture_of(next_seq_) - options_.clock();
    if (wait > 0) std::this_thread::sleep_for(std::chrono::microseconds(wait));
  }
  const int64_t seq = next_seq_++;
  // The frame starts (row 0 is read) at start + seq / fps; its timestamp is
  // the last row's read time plus the latency and jitter (the webcam
  // scenario; 0 otherwise), and the frame is not handed over before it.
  const int64_t capture = capture_of(seq);
  const double t_s = (capture - options_.start_utime) * 1e-6;
  if (options_.duration_s > 0.0 && t_s > options_.duration_s) return ReadStatus::kEndOfStream;
  const int64_t stamp = capture + std::llround(camera_->TimestampDelayS(seq) * 1e6);
  cv::Mat bgr;
  camera_->Render(t_s, seq, camera_->SimulatedRobots(t_s), &bgr, &truth_);
  if (options_.realtime && stamp > capture) {
    const int64_t wait = stamp - options_.clock();
    if (wait > 0) std::this_thread::sleep_for(std::chrono::microseconds(wait));
  }
  frame->capture_utime = stamp;
  frame->seq = seq;
  if (camera_->JpegQuality(options_.jpeg_quality) > 0) {
    std::vector<uint8_t> bytes;
    if (!camera_->Encode(bgr, options_.jpeg_quality, &bytes)) {
      *error = "cannot encode synthetic frame " + std::to_string(seq);
      return ReadStatus::kBadFrame;
    }
    frame->image = MakeJpegImage(std::move(bytes), error);
    if (frame->image == nullptr) return ReadStatus::kBadFrame;
  } else {
    frame->image = MakeDecodedImage(std::move(bgr));
  }
  return ReadStatus::kFrame;
}

std::string SimFrameSource::Describe() const {
  return "synthetic camera " + std::to_string(camera_->width_px()) + "x" +
         std::to_string(camera_->height_px()) + " at " + std::to_string(options_.fps) + " fps" +
         (camera_->JpegQuality(options_.jpeg_quality) > 0
              ? " (JPEG " + std::to_string(camera_->JpegQuality(options_.jpeg_quality)) + ")"
              : " (raw)") +
         (camera_->scenario().webcam_effects ? ", webcam effects" : "");
}

}  // namespace roomfix::camera
