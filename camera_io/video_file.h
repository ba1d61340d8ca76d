#ifndef ROOMFIX_CAMERA_IO_VIDEO_FILE_H_
#define ROOMFIX_CAMERA_IO_VIDEO_FILE_H_

#include <cstdint>
#include <memory>
#include <opencv2/core.hpp>
#include <string>

namespace roomfix::camera {

// A video file written so that it is whole or absent. cv::VideoWriter
// reports nothing when a write fails: write() and release() return void, and
// on a full disk `render-camera --out FILE.avi` and `roomfix_viewer --video`
// printed success over a file that stopped short (issue #28). This writer
// fills a hidden partial file in the target's folder (PartialPathFor, with
// the pid and the target's extension) and, on Close, checks it before
// renaming it over the target: the file is opened again with
// cv::VideoCapture and its frames are read back and counted. Both containers
// it writes (AVI with MJPG, MP4) put their index at the end, written last,
// so a file that stopped short does not open or holds fewer frames than were
// written. Anything else leaves no file: the partial one is removed.
class CheckedVideoWriter {
 public:
  CheckedVideoWriter();
  ~CheckedVideoWriter();  // Removes a partial file that was not closed.
  CheckedVideoWriter(const CheckedVideoWriter&) = delete;
  CheckedVideoWriter& operator=(const CheckedVideoWriter&) = delete;

  // False with "PATH: cannot open a video writer (codec missing?)" or the
  // reason the partial file cannot be made.
  bool Open(const std::string& path, int fourcc, double fps, cv::Size size, std::string* error);
  bool is_open() const;
  void Write(const cv::Mat& frame);
  // Finishes, checks and renames. False with "PATH: cannot write: REASON"
  // ("the video stopped short: N of M frames readable (disk full?)").
  bool Close(std::string* error);
  int64_t frames() const { return frames_; }

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  std::string path_;
  std::string partial_;
  int64_t frames_ = 0;
};

}  // namespace roomfix::camera

#endif  // ROOMFIX_CAMERA_IO_VIDEO_FILE_H_
