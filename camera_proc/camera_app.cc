#include "camera_proc/camera_app.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <thread>

#include "msgio/process.h"

namespace roomfix {

bool CameraLoopOptions::IsValid(std::string* error) const {
  if (!(duration_s >= 0.0)) {
    *error = "the duration must be >= 0 s";
    return false;
  }
  if (!(reopen_max_s > 0.0)) {
    *error = "the longest reopen wait must be > 0 s, not " + std::to_string(reopen_max_s);
    return false;
  }
  return true;
}

int RunCameraSource(camera::FrameSource* source, CameraNode* node, Bus* bus,
                    const CameraLoopOptions& options, std::string* error) {
  using Seconds = std::chrono::duration<double>;
  const auto stop_at = std::chrono::steady_clock::now() + Seconds(options.duration_s);
  auto timed_out = [&] {
    return options.duration_s > 0.0 && std::chrono::steady_clock::now() >= stop_at;
  };
  double backoff_s = options.first_reopen_s;
  bool open = false;
  int rc = 0;
  bool ended = false;
  while (!ended && !ShutdownRequested() && !timed_out()) {
    const int64_t now = NowUtime();
    if (!open) {
      if (source->Open(error)) {
        open = true;
        backoff_s = options.first_reopen_s;
        node->OnSourceUp(source->Describe(), source->refused_properties(), now);
        continue;
      }
      if (!source->live()) {
        rc = 1;
        break;
      }
      node->OnSourceDown(*error, now);
      spdlog::warn("{}; retrying in {:.1f} s", *error, backoff_s);
      node->Tick(now);
      Seconds wait(backoff_s);
      if (options.duration_s > 0.0) {
        wait = std::min<Seconds>(wait, stop_at - std::chrono::steady_clock::now());
      }
      if (wait.count() > 0.0) std::this_thread::sleep_for(wait);
      backoff_s = std::min(options.reopen_max_s, backoff_s * 2.0);
      continue;
    }
    // Never blocks (see hint_drain_budget_us).
    if (DrainBus(bus, options.hint_drain_budget_us) < 0) {
      spdlog::error("LCM failed: {}", bus->stats().last_error);
      error->clear();  // logged: not a source's reason
      rc = 1;
      break;
    }
    camera::Frame frame;
    const camera::ReadStatus status = source->Read(&frame, error);
    const int64_t read_utime = NowUtime();
    switch (status) {
      case camera::ReadStatus::kFrame:
        node->OnFrame(&frame, read_utime);
        break;
      case camera::ReadStatus::kBadFrame:
        node->OnBadFrame(camera::FrameProblemCounter(frame.problem), *error, read_utime);
        break;
      case camera::ReadStatus::kEndOfStream:
        node->OnEndOfStream(read_utime);
        ended = true;
        break;
      case camera::ReadStatus::kDeviceLost:
        spdlog::warn("{}; reopening", *error);
        source->Close();
        open = false;
        node->OnSourceDown(*error, read_utime);
        break;
    }
    node->Tick(read_utime);
  }
  node->Stop(NowUtime());
  // Joins a synthetic camera's renderer before the summary.
  source->Close();
  spdlog::info("stopped: {} frames processed, {} dropped, {} skipped by the source",
               node->frames_processed(), node->status().dropped(),
               node->status().counter("source_skipped_frames"));
  return rc;
}

}  // namespace roomfix
