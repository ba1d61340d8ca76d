// FrameImage implementations: already decoded BGR pixels, and JPEG bytes that
// libjpeg-turbo decodes on demand (reduced by DCT scaling, or a cropped
// full-resolution rectangle).
//
// libjpeg reports errors through a callback that must not return; the error
// manager here longjmps back to RunGuarded. The functions that run between
// setjmp and longjmp (the *Job runners) hold only trivially destructible
// locals, so no C++ destructor is skipped. Warnings (premature end of data,
// corrupt entropy data, ...) are errors too: libjpeg-turbo would otherwise pad
// the missing part with grey, and a grey half-frame must not be searched.

#include "camera_io/jpeg_image.h"

#include <fmt/format.h>
#include <jpeglib.h>
// After jpeglib.h: the message codes (JERR_*, JWRN_*).
#include <jerror.h>

#include <algorithm>
#include <csetjmp>
#include <cstdio>
#include <cstring>
#include <opencv2/imgproc.hpp>
#include <utility>

#include "camera_io/frame_image.h"

namespace roomfix::camera {
namespace {

// Frames larger than this are refused at the header (a corrupt header must not
// make us allocate gigabytes).
constexpr int64_t kMaxPixels = int64_t{1} << 27;  // 134 Mpx

struct ErrorManager {
  jpeg_error_mgr pub;  // first: libjpeg sees a jpeg_error_mgr*
  std::jmp_buf jump;
  char message[JMSG_LENGTH_MAX];
  // The kind of the failure, from libjpeg's message code (not its text);
  // kNone (zero, the Decompressor's memset) until one happens.
  FrameProblem problem;
};

template <typename... Args>
[[noreturn]] void Fail(ErrorManager* err, fmt::format_string<Args...> format, Args&&... args) {
  *fmt::format_to_n(err->message, sizeof(err->message) - 1, format, std::forward<Args>(args)...)
       .out = '\0';
  err->problem = FrameProblem::kUnreadable;
  std::longjmp(err->jump, 1);
}

// Data that stops early: libjpeg's end of input in a header or the body
// (JERR_INPUT_EOF, JWRN_JPEG_EOF) or a marker met inside entropy-coded data
// (JWRN_HIT_MARKER, what a frame cut short and padded shows).
FrameProblem ProblemOfCode(int msg_code) {
  switch (msg_code) {
    case JERR_INPUT_EOF:
    case JWRN_JPEG_EOF:
    case JWRN_HIT_MARKER:
      return FrameProblem::kTruncated;
    default:
      return FrameProblem::kUnreadable;
  }
}

[[noreturn]] void ErrorExit(j_common_ptr cinfo) {
  auto* err = reinterpret_cast<ErrorManager*>(cinfo->err);
  (*cinfo->err->format_message)(cinfo, err->message);
  err->problem = ProblemOfCode(cinfo->err->msg_code);
  std::longjmp(err->jump, 1);
}

// msg_level -1 is a warning (corrupt or truncated data): an error here.
// Levels >= 0 are trace messages: ignored.
void EmitMessage(j_common_ptr cinfo, int msg_level) {
  if (msg_level < 0) ErrorExit(cinfo);
}

void OutputMessage(j_common_ptr /*cinfo*/) {}

// One decompression: created, used and destroyed within one call.
class Decompressor {
 public:
  Decompressor() {
    std::memset(&cinfo_, 0, sizeof(cinfo_));
    std::memset(&err_, 0, sizeof(err_));
    cinfo_.err = jpeg_std_error(&err_.pub);
    err_.pub.error_exit = ErrorExit;
    err_.pub.emit_message = EmitMessage;
    err_.pub.output_message = OutputMessage;
  }
  ~Decompressor() { jpeg_destroy_decompress(&cinfo_); }
  Decompressor(const Decompressor&) = delete;
  Decompressor& operator=(const Decompressor&) = delete;

  jpeg_decompress_struct* cinfo() { return &cinfo_; }
  ErrorManager* err() { return &err_; }
  const char* message() const { return err_.message; }
  FrameProblem problem() const { return err_.problem; }

 private:
  jpeg_decompress_struct cinfo_;
  ErrorManager err_;
};

// Runs fn(arg); false when libjpeg (or fn, through Fail) gave up.
bool RunGuarded(ErrorManager* err, void (*fn)(void*), void* arg) {
  if (setjmp(err->jump) != 0) return false;
  fn(arg);
  return true;
}

// Creates the decompressor on the bytes and reads the header.
void StartHeader(Decompressor* d, const uint8_t* data, size_t size) {
  jpeg_decompress_struct* c = d->cinfo();
  jpeg_create_decompress(c);
  jpeg_mem_src(c, data, static_cast<unsigned long>(size));
  jpeg_read_header(c, TRUE);
}

void SetOutput(jpeg_decompress_struct* c, const JpegDecodeOptions& options) {
  c->out_color_space = JCS_EXT_BGR;
  c->dct_method = options.fast_dct ? JDCT_IFAST : JDCT_ISLOW;
  c->do_fancy_upsampling = options.fancy_upsampling ? TRUE : FALSE;
}

struct HeaderJob {
  Decompressor* d;
  const uint8_t* data;
  size_t size;
  int width;
  int height;
};

void RunHeader(void* arg) {
  auto* job = static_cast<HeaderJob*>(arg);
  StartHeader(job->d, job->data, job->size);
  jpeg_decompress_struct* c = job->d->cinfo();
  if (c->jpeg_color_space != JCS_GRAYSCALE && c->jpeg_color_space != JCS_YCbCr &&
      c->jpeg_color_space != JCS_RGB) {
    Fail(job->d->err(), "unsupported JPEG colour space (CMYK/YCCK)");
  }
  if (c->image_width == 0 || c->image_height == 0 ||
      int64_t{c->image_width} * c->image_height > kMaxPixels) {
    Fail(job->d->err(), "JPEG image size out of range ({} x {} px)", c->image_width,
         c->image_height);
  }
  job->width = static_cast<int>(c->image_width);
  job->height = static_cast<int>(c->image_height);
}

struct ReducedJob {
  Decompressor* d;
  const uint8_t* data;
  size_t size;
  JpegDecodeOptions options;
  int scale;
  uint8_t* out;
  size_t out_step;
  int out_width;
  int out_height;
};

void RunReduced(void* arg) {
  auto* job = static_cast<ReducedJob*>(arg);
  StartHeader(job->d, job->data, job->size);
  jpeg_decompress_struct* c = job->d->cinfo();
  SetOutput(c, job->options);
  c->scale_num = 1;
  c->scale_denom = static_cast<unsigned int>(job->scale);
  jpeg_start_decompress(c);
  if (static_cast<int>(c->output_width) != job->out_width ||
      static_cast<int>(c->output_height) != job->out_height || c->output_components != 3) {
    Fail(job->d->err(), "JPEG output size differs from its header");
  }
  constexpr int kRowsPerCall = 16;
  JSAMPROW rows[kRowsPerCall];
  while (c->output_scanline < c->output_height) {
    const int first = static_cast<int>(c->output_scanline);
    const int n = std::min(kRowsPerCall, job->out_height - first);
    for (int i = 0; i < n; ++i) rows[i] = job->out + (first + i) * job->out_step;
    if (jpeg_read_scanlines(c, rows, static_cast<JDIMENSION>(n)) == 0) {
      Fail(job->d->err(), "JPEG decoder returned no rows");
    }
  }
  jpeg_finish_decompress(c);
}

struct RegionJob {
  Decompressor* d;
  const uint8_t* data;
  size_t size;
  JpegDecodeOptions options;
  int x, y, width, height;  // clipped, non-empty
  uint8_t* row;             // image_width * 3 bytes
  uint8_t* out;
  size_t out_step;
};

void RunRegion(void* arg) {
  auto* job = static_cast<RegionJob*>(arg);
  StartHeader(job->d, job->data, job->size);
  jpeg_decompress_struct* c = job->d->cinfo();
  SetOutput(c, job->options);
  jpeg_start_decompress(c);
  // Widens to iMCU column boundaries: xoffset down, width up.
  JDIMENSION xoffset = static_cast<JDIMENSION>(job->x);
  JDIMENSION width = static_cast<JDIMENSION>(job->width);
  jpeg_crop_scanline(c, &xoffset, &width);
  if (static_cast<int>(xoffset) > job->x ||
      static_cast<int>(xoffset + width) < job->x + job->width || c->output_components != 3) {
    Fail(job->d->err(), "JPEG crop does not cover the rectangle");
  }
  if (job->y > 0 &&
      jpeg_skip_scanlines(c, static_cast<JDIMENSION>(job->y)) != static_cast<JDIMENSION>(job->y)) {
    Fail(job->d->err(), "JPEG decoder could not skip to the rectangle");
  }
  const size_t skip_bytes = static_cast<size_t>(job->x - static_cast<int>(xoffset)) * 3;
  const size_t copy_bytes = static_cast<size_t>(job->width) * 3;
  for (int r = 0; r < job->height; ++r) {
    JSAMPROW row = job->row;
    if (jpeg_read_scanlines(c, &row, 1) != 1) Fail(job->d->err(), "JPEG decoder returned no rows");
    std::memcpy(job->out + r * job->out_step, job->row + skip_bytes, copy_bytes);
  }
  // The rows below the rectangle are not decoded.
  jpeg_abort_decompress(c);
}

std::string DecodeError(const char* message) {
  return std::string("JPEG decode failed (truncated or corrupt data): ") + message;
}

class JpegImage : public FrameImage {
 public:
  JpegImage(std::vector<uint8_t> bytes, int width, int height, const JpegDecodeOptions& options)
      : bytes_(std::move(bytes)), options_(options) {
    width_px_ = width;
    height_px_ = height;
  }

  bool encoded() const override { return true; }
  const std::vector<uint8_t>* jpeg_bytes() const override { return &bytes_; }

  bool DecodeRegion(const cv::Rect& rect, cv::Mat* out, std::string* error) override {
    const cv::Rect clipped = rect & cv::Rect(0, 0, width_px_, height_px_);
    if (clipped.empty()) {
      *out = cv::Mat(0, 0, CV_8UC3);
      return true;
    }
    out->create(clipped.height, clipped.width, CV_8UC3);
    row_.resize(static_cast<size_t>(width_px_) * 3);
    Decompressor d;
    RegionJob job{&d,          bytes_.data(), bytes_.size(), options_,
                  clipped.x,   clipped.y,     clipped.width, clipped.height,
                  row_.data(), out->data,     out->step[0]};
    if (!RunGuarded(d.err(), RunRegion, &job)) {
      if (error != nullptr) *error = DecodeError(d.message());
      return false;
    }
    return true;
  }

  bool DecodeReduced(int scale, cv::Mat* out, std::string* error) override {
    if (scale != 1 && scale != 2 && scale != 4 && scale != 8) {
      if (error != nullptr) *error = "scale must be 1, 2, 4 or 8, not " + std::to_string(scale);
      return false;
    }
    const int w = (width_px_ + scale - 1) / scale;
    const int h = (height_px_ + scale - 1) / scale;
    out->create(h, w, CV_8UC3);
    Decompressor d;
    ReducedJob job{&d, bytes_.data(), bytes_.size(), options_, scale, out->data, out->step[0], w,
                   h};
    if (!RunGuarded(d.err(), RunReduced, &job)) {
      if (error != nullptr) *error = DecodeError(d.message());
      return false;
    }
    return true;
  }

 private:
  std::vector<uint8_t> bytes_;
  JpegDecodeOptions options_;
  std::vector<uint8_t> row_;
};

class DecodedImage : public FrameImage {
 public:
  explicit DecodedImage(cv::Mat bgr) : bgr_(std::move(bgr)) {
    width_px_ = bgr_.cols;
    height_px_ = bgr_.rows;
  }

  bool encoded() const override { return false; }

  // A view of the frame's pixels (no copy).
  bool DecodeRegion(const cv::Rect& rect, cv::Mat* out, std::string* error) override {
    if (bgr_.empty()) {
      if (error != nullptr) *error = "empty image";
      return false;
    }
    const cv::Rect clipped = rect & cv::Rect(0, 0, width_px_, height_px_);
    *out = clipped.empty() ? cv::Mat(0, 0, CV_8UC3) : bgr_(clipped);
    return true;
  }

  bool DecodeReduced(int scale, cv::Mat* out, std::string* error) override {
    if (bgr_.empty()) {
      if (error != nullptr) *error = "empty image";
      return false;
    }
    if (scale != 1 && scale != 2 && scale != 4 && scale != 8) {
      if (error != nullptr) *error = "scale must be 1, 2, 4 or 8, not " + std::to_string(scale);
      return false;
    }
    if (scale == 1) {
      *out = bgr_;  // a view
      return true;
    }
    // Pads the right and bottom edges by replication to whole blocks (as a
    // JPEG encoder does), so output pixel (i, j) is the mean of input block
    // [i * scale, (i + 1) * scale) x [j * scale, (j + 1) * scale), as in the
    // JPEG path, with no drift across the frame.
    const int pad_x = (scale - width_px_ % scale) % scale;
    const int pad_y = (scale - height_px_ % scale) % scale;
    const cv::Size size((width_px_ + pad_x) / scale, (height_px_ + pad_y) / scale);
    if (pad_x == 0 && pad_y == 0) {
      cv::resize(bgr_, *out, size, 0, 0, cv::INTER_AREA);
    } else {
      cv::Mat padded;
      cv::copyMakeBorder(bgr_, padded, 0, pad_y, 0, pad_x, cv::BORDER_REPLICATE);
      cv::resize(padded, *out, size, 0, 0, cv::INTER_AREA);
    }
    return true;
  }

 private:
  cv::Mat bgr_;
};

}  // namespace

std::unique_ptr<FrameImage> MakeDecodedImage(cv::Mat bgr) {
  // Grey and BGRA frames become BGR, so every FrameImage gives CV_8UC3.
  if (!bgr.empty() && bgr.depth() == CV_8U && bgr.channels() != 3) {
    cv::Mat converted;
    if (bgr.channels() == 1) {
      cv::cvtColor(bgr, converted, cv::COLOR_GRAY2BGR);
    } else if (bgr.channels() == 4) {
      cv::cvtColor(bgr, converted, cv::COLOR_BGRA2BGR);
    }
    bgr = converted;
  } else if (!bgr.empty() && bgr.type() != CV_8UC3) {
    bgr = cv::Mat();  // unsupported depth: an image whose decodes fail
  }
  return std::make_unique<DecodedImage>(std::move(bgr));
}

std::unique_ptr<FrameImage> MakeJpegImageWithOptions(std::vector<uint8_t> bytes,
                                                     const JpegDecodeOptions& options,
                                                     std::string* error, FrameProblem* problem) {
  int width_px = 0;
  int height_px = 0;
  if (!ReadJpegSize(bytes.data(), bytes.size(), &width_px, &height_px, error, problem)) {
    return nullptr;
  }
  return std::make_unique<JpegImage>(std::move(bytes), width_px, height_px, options);
}

bool ReadJpegSize(const uint8_t* data, size_t size, int* width_px, int* height_px,
                  std::string* error, FrameProblem* problem) {
  if (size == 0) {
    if (error != nullptr) *error = "empty JPEG data (0 bytes)";
    if (problem != nullptr) *problem = FrameProblem::kEmpty;
    return false;
  }
  Decompressor d;
  HeaderJob job{&d, data, size, 0, 0};
  if (!RunGuarded(d.err(), RunHeader, &job)) {
    if (error != nullptr) *error = std::string("not a readable JPEG: ") + d.message();
    if (problem != nullptr) *problem = d.problem();
    return false;
  }
  *width_px = job.width;
  *height_px = job.height;
  return true;
}

std::unique_ptr<FrameImage> MakeJpegImage(std::vector<uint8_t> bytes, std::string* error,
                                          FrameProblem* problem) {
  return MakeJpegImageWithOptions(std::move(bytes), JpegDecodeOptions{}, error, problem);
}

bool JpegHasEndMarker(const std::vector<uint8_t>& bytes) {
  size_t end = bytes.size();
  while (end > 0 && bytes[end - 1] == 0) --end;
  return end >= 4 && bytes[end - 2] == 0xFF && bytes[end - 1] == 0xD9;
}

}  // namespace roomfix::camera
