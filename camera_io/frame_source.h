#ifndef ROOMFIX_CAMERA_IO_FRAME_SOURCE_H_
#define ROOMFIX_CAMERA_IO_FRAME_SOURCE_H_

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "camera_io/frame_image.h"
#include "camera_io/frame_problem.h"
#include "core/calib/camera_timing.h"

namespace roomfix::camera {

struct Frame {
  // Capture time (microseconds since the Unix epoch): the driver's buffer
  // timestamp for V4L2 when it is on the realtime clock, otherwise the time
  // the frame was read; for files and the sim, the source's virtual clock.
  int64_t capture_utime = 0;
  // 0, 1, 2 ... from the source; a gap means frames were dropped.
  int64_t seq = 0;
  // Of the gap in seq before this frame, the frames the source itself
  // skipped (the synthetic camera's renderer fell behind real time): not
  // frames camera_proc dropped.
  int64_t source_skipped = 0;
  std::unique_ptr<FrameImage> image;
  // With ReadStatus::kBadFrame, why the frame that arrived (it has its seq
  // and capture_utime) has no image; the error text says the detail.
  FrameProblem problem = FrameProblem::kNone;
};

enum class ReadStatus {
  kFrame,        // *frame holds a frame
  kBadFrame,     // this frame was unreadable: frame->problem says the kind,
                 // *error the detail; go on
  kEndOfStream,  // a file or folder ran out
  kDeviceLost,   // the device went away; Close(), then Open() again later
};

// Camera settings from the site file.
struct CaptureSettings {
  int width_px = 1920;
  int height_px = 1080;
  double fps = 30.0;
  std::string pixel_format = "MJPG";
  // brightness, contrast, saturation, hue, gamma, sharpness, exposure;
  // an exposure turns auto-exposure off.
  std::map<std::string, double> properties;
  // Files: play at fps in real time (true) or as fast as read, stamping
  // frames start_utime + seq / fps (false).
  bool realtime = false;
  int64_t start_utime = 0;
  // Whether a file or folder starts again at the end instead of ending.
  bool loop = false;
};

class FrameSource {
 public:
  virtual ~FrameSource() = default;
  // False with a reason (missing device, unreadable file, no images match).
  virtual bool Open(std::string* error) = 0;
  virtual void Close() = 0;
  // Blocks for at most about one frame interval.
  virtual ReadStatus Read(Frame* frame, std::string* error) = 0;
  // "v4l2 /dev/video0 1920x1080 MJPG 30 fps", "video run.avi", ...
  virtual std::string Describe() const = 0;
  // Whether the source is a live device that may come back after it is lost.
  virtual bool live() const = 0;
  // Properties the camera refused or changed, with what it reported back
  // ("exposure: asked 156, got 250"), filled by Open().
  virtual std::vector<std::string> refused_properties() const { return {}; }
  // The exposure and timestamp timing the device itself defines (a
  // synthetic scenario renders its own physics); empty for a real camera or
  // a file, whose timing only the site's cameras[] keys can state.
  virtual std::optional<calib::CameraTiming> device_timing() const { return std::nullopt; }
};

// Chooses by the device string: "/dev/video*" (or a bare number) opens a V4L2
// webcam through OpenCV; a folder, or a pattern with * or ?, a sorted list of
// images (JPEG files stay compressed until searched); any other path a video
// file (OpenCV's FFmpeg backend; MJPEG streams are read compressed when the
// backend can). "sim:" sources are made by camera_proc itself (they need the
// site). nullptr with a reason for an empty string.
std::unique_ptr<FrameSource> MakeFrameSource(const std::string& device,
                                             const CaptureSettings& settings, std::string* error);

// The current time in microseconds since the Unix epoch (replaceable in tests
// of the sources' pacing).
using Clock = std::function<int64_t()>;

}  // namespace roomfix::camera

#endif  // ROOMFIX_CAMERA_IO_FRAME_SOURCE_H_
