#ifndef ROOMFIX_CAMERA_PROC_SIM_FRAME_SOURCE_H_
#define ROOMFIX_CAMERA_PROC_SIM_FRAME_SOURCE_H_

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "camera_proc/frame_source.h"
#include "sim/synthetic_camera.h"

namespace roomfix::camera {

struct SimSourceOptions {
  // Frames per second of the simulated camera.
  double fps = 30.0;
  // The simulation's t = 0 (the same instant roomfix_sim was given, so the
  // two agree on where the robot is), microseconds since the Unix epoch.
  int64_t start_utime = 0;
  // Real time: a frame is rendered when the clock reaches its capture time,
  // and frames whose time has passed while the previous one was processed
  // are skipped (a gap in seq, as a webcam drops them). Otherwise frames are
  // rendered back to back on a virtual clock, start + seq / fps.
  bool realtime = true;
  // 1..100: frames are handed over as JPEG, as a webcam's MJPEG stream is,
  // so the same decoding runs; 0: as BGR pixels. The webcam scenario's own
  // jpeg_quality overrides it (SyntheticCamera::JpegQuality).
  int jpeg_quality = 90;
  // Stop after this many seconds of simulated time (<= 0: never).
  double duration_s = 0.0;
  Clock clock;
};

// The synthetic camera as a frame source: renders the site's simulated
// robots (sim/synthetic_camera.h) at each frame's capture time.
class SimFrameSource final : public FrameSource {
 public:
  SimFrameSource(std::shared_ptr<const sim::SyntheticCamera> camera, SimSourceOptions options);
  bool Open(std::string* error) override;
  void Close() override {}
  ReadStatus Read(Frame* frame, std::string* error) override;
  std::string Describe() const override;
  bool live() const override { return false; }

  // Ground truth of the last frame rendered.
  const std::vector<sim::MarkerTruth>& last_truth() const { return truth_; }

 private:
  std::shared_ptr<const sim::SyntheticCamera> camera_;
  SimSourceOptions options_;
  int64_t next_seq_ = 0;
  std::vector<sim::MarkerTruth> truth_;
};

}  // namespace roomfix::camera

#endif  // ROOMFIX_CAMERA_PROC_SIM_FRAME_SOURCE_H_
