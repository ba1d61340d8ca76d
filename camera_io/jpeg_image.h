#ifndef ROOMFIX_CAMERA_IO_JPEG_IMAGE_H_
#define ROOMFIX_CAMERA_IO_JPEG_IMAGE_H_

// Internal to camera_io: the libjpeg-turbo decode options behind
// MakeJpegImage (frame_image.h), exposed so a test can measure them.

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "camera_io/frame_image.h"

namespace roomfix::camera {

struct JpegDecodeOptions {
  // JDCT_IFAST (true) or JDCT_ISLOW (false). libjpeg-turbo's SIMD IFAST is
  // slightly faster and differs from ISLOW by about one grey level on average.
  bool fast_dct = true;
  // Triangular ("fancy") chroma upsampling (true) or replication (false).
  // Replication is a little faster but moves colour edges by up to half a
  // pixel, and the marker centroid is measured on colour: on 1080p
  // quality-90 frames of the synthetic camera the centroid error is
  // 0.094 px RMS with replication and 0.033 px with triangular upsampling,
  // for under 0.1 ms more per frame (roomfix_bench camera).
  bool fancy_upsampling = true;
};

// MakeJpegImage with explicit decode options.
std::unique_ptr<FrameImage> MakeJpegImageWithOptions(std::vector<uint8_t> bytes,
                                                     const JpegDecodeOptions& options,
                                                     std::string* error,
                                                     FrameProblem* problem = nullptr);

// The pixel size libjpeg itself will decode, read by libjpeg's own header
// parser with its warnings taken as errors. A walk of the marker segments by
// hand can be led astray (FF 00 and TEM have no length; libjpeg skips
// extraneous bytes to the next marker), so a file can show such a walk a
// small dummy frame header while the decoder reads a huge real one. False
// with libjpeg's reason for anything libjpeg would not read cleanly, and
// its kind in *problem when given (from libjpeg's message code).
bool ReadJpegSize(const uint8_t* data, size_t size, int* width_px, int* height_px,
                  std::string* error, FrameProblem* problem = nullptr);

// Whether `bytes` end with a JPEG end-of-image marker (FF D9), ignoring zero
// padding after it (some UVC cameras pad their buffers). A cheap check for a
// truncated frame before any decoding; a body corrupt in the middle is only
// found by decoding.
bool JpegHasEndMarker(const std::vector<uint8_t>& bytes);

}  // namespace roomfix::camera

#endif  // ROOMFIX_CAMERA_IO_JPEG_IMAGE_H_
