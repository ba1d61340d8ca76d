#ifndef ROOMFIX_CAMERA_IO_FRAME_IMAGE_H_
#define ROOMFIX_CAMERA_IO_FRAME_IMAGE_H_

// A frame's or image file's pixels, decoded on demand (libjpeg-turbo for
// JPEG, camera_io/jpeg_image.cc): apart from frame_source.h, so that code
// that decodes images (the viewer's renderer) does not link the capture
// devices.

#include <cstdint>
#include <memory>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "camera_io/frame_problem.h"

namespace roomfix::camera {

// One frame's pixels, decoded only as far as a caller asks: a webcam's MJPEG
// frame stays compressed until the detector asks for a reduced-size view (the
// full-frame search) or a full-resolution rectangle (the region search), and
// libjpeg-turbo decodes just that (DCT scaling; cropped, skipped scanlines).
class FrameImage {
 public:
  virtual ~FrameImage() = default;
  int width_px() const { return width_px_; }
  int height_px() const { return height_px_; }
  // Whether the pixels are still compressed (JPEG).
  virtual bool encoded() const = 0;
  // The JPEG data as the source delivered it (a webcam's MJPEG buffer, a
  // .jpg file, a video's MJPEG packet), for a tool that saves frames
  // without re-encoding them (`roomfix grab`); nullptr when not encoded.
  virtual const std::vector<uint8_t>* jpeg_bytes() const { return nullptr; }
  // BGR (CV_8UC3) of the full-resolution rectangle `rect`, clipped to the
  // image; *out is exactly the clipped rectangle. False with a reason
  // (corrupt or truncated data) when the pixels cannot be had.
  virtual bool DecodeRegion(const cv::Rect& rect, cv::Mat* out, std::string* error) = 0;
  // The whole frame shrunk by `scale` (1, 2, 4 or 8), each output pixel the
  // mean of scale x scale input pixels (JPEG: DCT scaling, which is close
  // to that). Size is ceil(width / scale) x ceil(height / scale).
  virtual bool DecodeReduced(int scale, cv::Mat* out, std::string* error) = 0;

 protected:
  int width_px_ = 0;
  int height_px_ = 0;
};

// A frame that is already BGR pixels (video files, image files, the sim).
std::unique_ptr<FrameImage> MakeDecodedImage(cv::Mat bgr);
// A JPEG frame. Reads the header only; nullptr with a reason when the data is
// empty, not a JPEG, or its header is corrupt or truncated. A frame whose
// body is truncated or corrupt fails later, at DecodeRegion/DecodeReduced
// (libjpeg-turbo's warnings, such as premature end of data, are errors here:
// a grey half-frame must not be searched). *problem, when given, says the
// kind of a header failure (kEmpty, kTruncated or kUnreadable).
std::unique_ptr<FrameImage> MakeJpegImage(std::vector<uint8_t> bytes, std::string* error,
                                          FrameProblem* problem = nullptr);

}  // namespace roomfix::camera

#endif  // ROOMFIX_CAMERA_IO_FRAME_IMAGE_H_
