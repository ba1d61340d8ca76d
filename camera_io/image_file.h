#ifndef ROOMFIX_CAMERA_IO_IMAGE_FILE_H_
#define ROOMFIX_CAMERA_IO_IMAGE_FILE_H_

#include <cstddef>
#include <cstdint>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "camera_io/frame_problem.h"

namespace roomfix::camera {

// Image files from outside (frame folders, calibration images) are checked
// before any pixel is decoded: a 57-byte PNG header may claim 100000 x
// 100000 pixels, and a few MB of PNG can decode to gigabytes. OpenCV 4.6
// has no public header-only reader (imdecode checks only its own 1
// gigapixel limit, by throwing), so the size is read here from the header of
// the formats the project reads, and any other format is refused.

// The largest image file read at all: 64 MiB (a 4K BMP is 25 MB; the
// project's frames and calibration images are under 3 MB).
inline constexpr size_t kMaxImageFileBytes = size_t{64} << 20;
// The largest image a tool decodes when no camera size bounds it (calibrate
// --image, --chessboard, --marker-images): 8192 x 8192 (64 megapixels,
// 192 MB as BGR).
inline constexpr int kMaxToolImageSidePx = 8192;

struct ImageHeader {
  std::string format;  // "PNG", "JPEG", "BMP", "PNM"
  int width_px = 0;
  int height_px = 0;
};

// The format and pixel size from the first bytes of an image: PNG (IHDR),
// JPEG (the first SOF marker), BMP (the DIB header), PNM (P1-P6). False with
// a reason for any other format, or a header that is truncated or states a
// size of zero or less; *problem (when given) says its kind (kTruncated for a
// header cut short, kUnreadable otherwise).
bool ReadImageHeader(const uint8_t* data, size_t size, ImageHeader* header, std::string* error,
                     FrameProblem* problem = nullptr);

// Reads a regular file of at most kMaxImageFileBytes (the cap enforced
// while reading). False with a reason ("not a regular file (a FIFO)",
// "N bytes, over the 64 MiB cap for image files", an errno text).
bool ReadImageBytes(const std::string& path, std::vector<uint8_t>* bytes, std::string* error);

// Decodes `bytes` with OpenCV (`flags` as for cv::imdecode) after checking
// from the header that the image is at most max_width_px x max_height_px.
// Whatever OpenCV throws is caught. False with a reason and, when `problem`
// is given, its kind (kWrongSize for an image over the limits; its reason
// contains kTooLargeText).
bool DecodeImageChecked(const std::vector<uint8_t>& bytes, int max_width_px, int max_height_px,
                        int flags, cv::Mat* image, std::string* error,
                        FrameProblem* problem = nullptr);
// ReadImageBytes then DecodeImageChecked; the reason is prefixed "PATH: ".
bool ReadImageChecked(const std::string& path, int max_width_px, int max_height_px, int flags,
                      cv::Mat* image, std::string* error);

// In a reason, marks an image refused for its size, for a person reading it
// (code uses FrameProblem::kWrongSize).
inline constexpr char kTooLargeText[] = "larger than the limit";

// Encodes `image` by the extension of `path` (cv::imencode, exceptions
// caught) and writes it with every step checked (WriteOutputFile). False with
// "PATH: cannot write: REASON" (e.g. No space left on device for /dev/full).
bool WriteImageChecked(const std::string& path, const cv::Mat& image, std::string* error,
                       const std::vector<int>& params = {});

}  // namespace roomfix::camera

#endif  // ROOMFIX_CAMERA_IO_IMAGE_FILE_H_
