#ifndef ROOMFIX_SIM_SIM_FRAME_SOURCE_H_
#define ROOMFIX_SIM_SIM_FRAME_SOURCE_H_

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "camera_io/frame_source.h"
#include "core/calib/camera_timing.h"
#include "sim/synthetic_camera.h"

namespace roomfix::sim {

struct SimSourceOptions {
  // Frames per second of the simulated camera.
  double fps = 30.0;
  // The simulation's t = 0 (the same instant roomfix_sim was given, so the
  // two agree on where the robot is), microseconds since the Unix epoch.
  int64_t start_utime = 0;
  // Real time: producer threads render (one) and encode (the other) each
  // frame from its start time on and hand it over at its timestamp, as a
  // camera captures in parallel with the processing; frames whose start has passed while the
  // renderer was busy are skipped (a gap in seq, counted in Frame::source_skipped), and when the
  // reader falls `queue_frames` behind the oldest waiting frame is discarded (a gap camera_proc
  // counts as its own drop), as a driver with full buffers does. Otherwise frames are rendered back
  // to back in Read, on a virtual clock, start + seq / fps, with no thread.
  bool realtime = true;
  // Frames rendered ahead of the reader (realtime only), at least 1.
  int queue_frames = 2;
  // 1..100: frames are handed over as JPEG, as a webcam's MJPEG stream is,
  // so the same decoding runs; 0: as BGR pixels. The webcam scenario's own
  // jpeg_quality overrides it (SyntheticCamera::JpegQuality).
  int jpeg_quality = 90;
  // Stop after this many seconds of simulated time (<= 0: never).
  double duration_s = 0.0;
  // Robots standing still where a person put them (a tripod with a robot's
  // markers at a surveyed point, `roomfix grab --tripod`): every frame
  // shows these instead of the site's simulated robots. Empty: the
  // simulation's robots.
  std::vector<RobotState> parked_robots;
  // Called from the producer thread when realtime: must be thread-safe.
  camera::Clock clock;
};

// The camera timing a synthetic scenario renders (the device is the
// physics): the webcam scenario's simulation.webcam readout, exposure and
// timestamp latency; every other scenario is a global shutter with exact
// timestamps (all 0).
calib::CameraTiming ScenarioTiming(const SimScenario& scenario, int height_px);

// The synthetic camera as a frame source: renders the site's simulated
// robots (sim/synthetic_camera.h) at each frame's capture time. A frame is a
// deterministic function of its seq, so which thread renders it changes
// nothing in its bytes.
class SimFrameSource final : public camera::FrameSource {
 public:
  SimFrameSource(std::shared_ptr<const SyntheticCamera> camera, SimSourceOptions options);
  // Stops and joins the producer threads.
  ~SimFrameSource() override;
  SimFrameSource(const SimFrameSource&) = delete;
  SimFrameSource& operator=(const SimFrameSource&) = delete;

  // Realtime: starts the producer threads (frames from the clock's present).
  bool Open(std::string* error) override;
  // Stops and joins the producer threads; frames not yet read are discarded.
  void Close() override;
  // Realtime: blocks until the producer has a frame (about one frame
  // interval while it keeps up).
  camera::ReadStatus Read(camera::Frame* frame, std::string* error) override;
  std::string Describe() const override;
  bool live() const override { return false; }
  std::optional<calib::CameraTiming> device_timing() const override;

  // Ground truth of the last frame read.
  const std::vector<MarkerTruth>& last_truth() const { return truth_; }
  // Frames skipped because rendering fell behind real time (realtime only).
  int64_t render_skipped() const;

 private:
  struct Rendered {
    camera::ReadStatus status = camera::ReadStatus::kFrame;
    camera::Frame frame;
    std::string error;
    std::vector<MarkerTruth> truth;
    // The rendered pixels until they are encoded.
    cv::Mat bgr;
  };
  int64_t CaptureUtime(int64_t seq) const;
  // Renders frame `seq` (stamp, pixels, truth, or kEndOfStream past
  // duration_s); no waiting.
  void RenderPixels(int64_t seq, Rendered* out) const;
  // The pixels to the frame's image (MJPEG, or BGR as they are).
  void Encode(Rendered* out) const;
  // Realtime: two stages, so that a frame's render and the previous frame's
  // encode run at once (each within a frame period even on a loaded core).
  void RenderLoop();
  void EncodeLoop();
  // Waits until the clock reaches `utime` or Close asks to stop; false when
  // stopping.
  bool WaitUntil(int64_t utime, std::unique_lock<std::mutex>* lock);

  std::shared_ptr<const SyntheticCamera> camera_;
  SimSourceOptions options_;
  int64_t next_seq_ = 0;
  std::vector<MarkerTruth> truth_;

  // The producer (realtime): guarded by mutex_.
  std::thread producer_;
  std::thread encoder_;
  // Rendered, not yet encoded (at most one).
  std::optional<Rendered> rendered_;
  mutable std::mutex mutex_;
  std::condition_variable changed_;
  std::deque<Rendered> queue_;
  bool stop_ = false;
  // The next frame the producer renders.
  int64_t produce_seq_ = 0;
  int64_t render_skipped_ = 0;
};

}  // namespace roomfix::sim

#endif  // ROOMFIX_SIM_SIM_FRAME_SOURCE_H_
