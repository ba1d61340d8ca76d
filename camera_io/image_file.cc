#include "camera_io/image_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <opencv2/imgcodecs.hpp>

#include "camera_io/jpeg_image.h"
#include "core/world/file_io.h"

namespace roomfix::camera {
namespace {

uint32_t Be32(const uint8_t* p) {
  return (uint32_t{p[0]} << 24) | (uint32_t{p[1]} << 16) | (uint32_t{p[2]} << 8) | p[3];
}
uint32_t Le32(const uint8_t* p) {
  return uint32_t{p[0]} | (uint32_t{p[1]} << 8) | (uint32_t{p[2]} << 16) | (uint32_t{p[3]} << 24);
}
uint16_t Le16(const uint8_t* p) { return static_cast<uint16_t>(p[0] | (p[1] << 8)); }

bool Fail(std::string* error, const std::string& text) {
  if (error != nullptr) *error = text;
  return false;
}

// Fail, saying the kind of failure as well as its text.
bool Fail(std::string* error, FrameProblem* problem, FrameProblem kind, const std::string& text) {
  if (problem != nullptr) *problem = kind;
  return Fail(error, text);
}

// Sizes above INT32_MAX are reported as that: they are refused as too large
// by the caller either way.
int Clamp(uint64_t v) { return v > 0x7FFFFFFF ? 0x7FFFFFFF : static_cast<int>(v); }

bool ReadPng(const uint8_t* d, size_t n, ImageHeader* h, std::string* error,
             FrameProblem* problem) {
  // Signature (8), IHDR length (4), "IHDR" (4), width (4), height (4).
  if (n < 24 || std::memcmp(d + 12, "IHDR", 4) != 0) {
    return Fail(error, problem, FrameProblem::kTruncated, "truncated PNG header (no IHDR chunk)");
  }
  h->format = "PNG";
  h->width_px = Clamp(Be32(d + 16));
  h->height_px = Clamp(Be32(d + 20));
  return true;
}

// The first start-of-frame marker (SOF0-SOF15 except DHT C4, JPG C8, DAC
// CC) holds the height and width; segments before it are skipped by their
// lengths.
// libjpeg's own header parser, not a walk by hand: see ReadJpegSize.
bool ReadJpeg(const uint8_t* d, size_t n, ImageHeader* h, std::string* error,
              FrameProblem* problem) {
  h->format = "JPEG";
  return ReadJpegSize(d, n, &h->width_px, &h->height_px, error, problem);
}

bool ReadBmp(const uint8_t* d, size_t n, ImageHeader* h, std::string* error,
             FrameProblem* problem) {
  if (n < 26) return Fail(error, problem, FrameProblem::kTruncated, "truncated BMP header");
  const uint32_t dib = Le32(d + 14);
  h->format = "BMP";
  if (dib == 12) {  // BITMAPCOREHEADER: 16-bit sizes
    h->width_px = Le16(d + 18);
    h->height_px = Le16(d + 20);
    return true;
  }
  // BITMAPINFOHEADER and later: signed 32-bit; a negative height means top-down.
  const int64_t w = static_cast<int32_t>(Le32(d + 18));
  const int64_t hh = static_cast<int32_t>(Le32(d + 22));
  h->width_px = Clamp(static_cast<uint64_t>(w < 0 ? 0 : w));
  h->height_px = Clamp(static_cast<uint64_t>(hh < 0 ? -hh : hh));
  return true;
}

// "P6\n# comment\n640 480\n255\n": the first two numbers after the magic.
bool ReadPnm(const uint8_t* d, size_t n, ImageHeader* h, std::string* error,
             FrameProblem* problem) {
  size_t i = 2;
  uint64_t values[2] = {0, 0};
  for (int k = 0; k < 2; ++k) {
    for (;;) {
      while (i < n && std::isspace(d[i])) ++i;
      if (i < n && d[i] == '#') {
        while (i < n && d[i] != '\n') ++i;
        continue;
      }
      break;
    }
    if (i >= n || !std::isdigit(d[i])) {
      return Fail(error, problem, FrameProblem::kTruncated, "truncated or corrupt PNM header");
    }
    int digits = 0;
    while (i < n && std::isdigit(d[i])) {
      if (++digits > 10) {
        return Fail(error, problem, FrameProblem::kUnreadable,
                    "corrupt PNM header (size over 10 digits)");
      }
      values[k] = values[k] * 10 + static_cast<uint64_t>(d[i] - '0');
      ++i;
    }
  }
  h->format = "PNM";
  h->width_px = Clamp(values[0]);
  h->height_px = Clamp(values[1]);
  return true;
}

}  // namespace

bool ReadImageHeader(const uint8_t* data, size_t size, ImageHeader* header, std::string* error,
                     FrameProblem* problem) {
  static const uint8_t kPng[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
  ImageHeader h;
  bool ok = false;
  if (size >= 8 && std::memcmp(data, kPng, 8) == 0) {
    ok = ReadPng(data, size, &h, error, problem);
  } else if (size >= 3 && data[0] == 0xFF && data[1] == 0xD8 && data[2] == 0xFF) {
    ok = ReadJpeg(data, size, &h, error, problem);
  } else if (size >= 2 && data[0] == 'B' && data[1] == 'M') {
    ok = ReadBmp(data, size, &h, error, problem);
  } else if (size >= 2 && data[0] == 'P' && data[1] >= '1' && data[1] <= '6') {
    ok = ReadPnm(data, size, &h, error, problem);
  } else {
    return Fail(error, problem, FrameProblem::kUnreadable,
                "not an image format read here (PNG, JPEG, BMP, PNM)");
  }
  if (!ok) return false;
  if (h.width_px <= 0 || h.height_px <= 0) {
    return Fail(error, problem, FrameProblem::kUnreadable,
                h.format + " header states " + std::to_string(h.width_px) + " x " +
                    std::to_string(h.height_px) + " px");
  }
  *header = h;
  return true;
}

bool ReadImageBytes(const std::string& path, std::vector<uint8_t>* bytes, std::string* error) {
  // Not ReadConfigFile: that returns a string and words its cap for
  // configuration files; the checks are the same.
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC | O_NOCTTY);
  if (fd < 0) return Fail(error, std::string("cannot open: ") + std::strerror(errno));
  struct stat st {};
  if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
    ::close(fd);
    return Fail(error,
                S_ISDIR(st.st_mode) ? "not a regular file (a folder)" : "not a regular file");
  }
  const std::string over =
      " bytes, over the " + ByteSizeText(kMaxImageFileBytes) + " cap for image files";
  if (static_cast<unsigned long long>(st.st_size) > kMaxImageFileBytes) {
    ::close(fd);
    return Fail(error, std::to_string(st.st_size) + over);
  }
  std::vector<uint8_t> out(static_cast<size_t>(st.st_size));
  size_t done = 0;
  for (;;) {
    if (done == out.size()) {
      // The file may have grown since fstat: allow up to the cap.
      if (out.size() >= kMaxImageFileBytes + 1) break;
      out.resize(std::min(kMaxImageFileBytes + 1, out.size() + 65536));
    }
    const ssize_t n = ::read(fd, out.data() + done, out.size() - done);
    if (n == 0) break;
    if (n < 0) {
      if (errno == EINTR) continue;
      const int e = errno;
      ::close(fd);
      return Fail(error, std::string("cannot read: ") + std::strerror(e));
    }
    done += static_cast<size_t>(n);
  }
  ::close(fd);
  if (done > kMaxImageFileBytes) return Fail(error, std::to_string(done) + "+" + over);
  out.resize(done);
  *bytes = std::move(out);
  return true;
}

bool DecodeImageChecked(const std::vector<uint8_t>& bytes, int max_width_px, int max_height_px,
                        int flags, cv::Mat* image, std::string* error, FrameProblem* problem) {
  if (bytes.empty()) return Fail(error, problem, FrameProblem::kEmpty, "empty file");
  ImageHeader h;
  if (!ReadImageHeader(bytes.data(), bytes.size(), &h, error, problem)) return false;
  if (h.width_px > max_width_px || h.height_px > max_height_px) {
    return Fail(error, problem, FrameProblem::kWrongSize,
                h.format + " of " + std::to_string(h.width_px) + " x " +
                    std::to_string(h.height_px) + " px is " + kTooLargeText + " of " +
                    std::to_string(max_width_px) + " x " + std::to_string(max_height_px) +
                    " px (not decoded)");
  }
  try {
    cv::Mat decoded = cv::imdecode(bytes, flags);
    if (decoded.empty()) {
      return Fail(error, problem, FrameProblem::kUnreadable,
                  "not a readable " + h.format + " image");
    }
    *image = std::move(decoded);
  } catch (const cv::Exception& e) {
    return Fail(error, problem, FrameProblem::kUnreadable,
                "not a readable " + h.format + " image: OpenCV: " + e.msg);
  }
  return true;
}

bool ReadImageChecked(const std::string& path, int max_width_px, int max_height_px, int flags,
                      cv::Mat* image, std::string* error) {
  std::vector<uint8_t> bytes;
  std::string why;
  if (!ReadImageBytes(path, &bytes, &why) ||
      !DecodeImageChecked(bytes, max_width_px, max_height_px, flags, image, &why)) {
    return Fail(error, path + ": " + why);
  }
  return true;
}

bool WriteImageChecked(const std::string& path, const cv::Mat& image, std::string* error,
                       const std::vector<int>& params) {
  const size_t dot = path.rfind('.');
  const size_t slash = path.rfind('/');
  // /dev/full and other names without an extension are written as PNG.
  const std::string ext = dot != std::string::npos && (slash == std::string::npos || dot > slash)
                              ? path.substr(dot)
                              : ".png";
  std::vector<uint8_t> buffer;
  try {
    if (!cv::imencode(ext, image, buffer, params)) {
      return Fail(error, path + ": cannot write: OpenCV cannot encode " + ext);
    }
  } catch (const cv::Exception& e) {
    return Fail(error, path + ": cannot write: OpenCV: " + e.msg);
  }
  return WriteOutputFile(path, std::string(buffer.begin(), buffer.end()), error);
}

}  // namespace roomfix::camera
