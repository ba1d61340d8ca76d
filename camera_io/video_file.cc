#include "camera_io/video_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <opencv2/videoio.hpp>

#include "core/world/file_io.h"

namespace roomfix::camera {

struct CheckedVideoWriter::Impl {
  cv::VideoWriter writer;
};

CheckedVideoWriter::CheckedVideoWriter() : impl_(std::make_unique<Impl>()) {}

CheckedVideoWriter::~CheckedVideoWriter() {
  if (impl_->writer.isOpened()) impl_->writer.release();
  if (!partial_.empty()) ::unlink(partial_.c_str());
}

bool CheckedVideoWriter::is_open() const { return impl_->writer.isOpened(); }

bool CheckedVideoWriter::Open(const std::string& path, int fourcc, double fps, cv::Size size,
                              std::string* error) {
  path_ = path;
  frames_ = 0;
  const size_t dot = path.rfind('.');
  const size_t slash = path.rfind('/');
  const std::string ext = dot == std::string::npos || (slash != std::string::npos && dot < slash)
                              ? ""
                              : path.substr(dot);
  partial_ = PartialPathFor(path) + "-" + std::to_string(::getpid()) + ext;
  // Made here first so that a folder we cannot write to is named as such.
  const int fd = ::open(partial_.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666);
  if (fd < 0) {
    *error = path + ": cannot write: " + std::strerror(errno);
    partial_.clear();
    return false;
  }
  ::close(fd);
  if (!impl_->writer.open(partial_, fourcc, fps, size) || !impl_->writer.isOpened()) {
    *error = path + ": cannot open a video writer (codec missing?)";
    ::unlink(partial_.c_str());
    partial_.clear();
    return false;
  }
  return true;
}

void CheckedVideoWriter::Write(const cv::Mat& frame) {
  impl_->writer.write(frame);
  ++frames_;
}

bool CheckedVideoWriter::Close(std::string* error) {
  if (partial_.empty()) {
    *error = path_ + ": cannot write: the video was not opened";
    return false;
  }
  impl_->writer.release();
  auto fail = [&](const std::string& why) {
    *error = path_ + ": cannot write: " + why;
    ::unlink(partial_.c_str());
    partial_.clear();
    return false;
  };
  // Flushed to the disk first: with delayed allocation a full disk shows
  // only at write-back.
  const int fd = ::open(partial_.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return fail(std::strerror(errno));
  if (::fsync(fd) != 0) {
    const int err = errno;
    ::close(fd);
    return fail(std::strerror(err));
  }
  ::close(fd);
  int64_t readable = 0;
  {
    cv::VideoCapture check(partial_);
    if (check.isOpened()) {
      while (readable < frames_ && check.grab()) ++readable;
    }
  }
  if (readable != frames_) {
    return fail("the video stopped short: " + std::to_string(readable) + " of " +
                std::to_string(frames_) + " frames readable (disk full?)");
  }
  // A link is replaced at the file it names; a device (/dev/null) cannot be
  // replaced, and would hold nothing anyway: the checked video is dropped.
  std::string target = path_;
  if (char* real = ::realpath(path_.c_str(), nullptr)) {
    target = real;
    std::free(real);
  }
  struct stat st {};
  if (::stat(target.c_str(), &st) == 0 && !S_ISREG(st.st_mode)) {
    ::unlink(partial_.c_str());
    partial_.clear();
    return true;
  }
  if (std::rename(partial_.c_str(), target.c_str()) != 0) return fail(std::strerror(errno));
  partial_.clear();
  return true;
}

}  // namespace roomfix::camera
