#ifndef ROOMFIX_CORE_CALIB_CAMERA_TIMING_H_
#define ROOMFIX_CORE_CALIB_CAMERA_TIMING_H_

#include <cstdint>
#include <string>

namespace roomfix::calib {

// How a camera exposes and stamps its frames (the site's cameras[].readout_s,
// exposure_s, timestamp_latency_s). A UVC webcam reads row r of H at
// t_read(r) = t_start + r * readout_s / H after integrating light over
// [t_read(r) - exposure_s, t_read(r)], and stamps the buffer when its last row
// has arrived, plus a latency: capture = t_read(H - 1) + latency_s (+ jitter,
// which no camera reports).
struct CameraTiming {
  double readout_s = 0.0;
  double exposure_s = 0.0;
  double latency_s = 0.0;
  int height_px = 0;

  bool IsValid(std::string* error) const;
};

// The middle of row `row_px`'s exposure (row_px may be fractional: a
// centroid), microseconds, for a frame stamped `capture_utime`:
//   capture - latency_s - (H - 1 - r) * readout_s / H - exposure_s / 2.
// Why a blob's centroid row: the row time is affine in r, so the intensity-
// weighted mean time of a blob's pixels is the time of its centroid's row;
// and a disc moving at constant velocity through a rolling shutter images as
// an affine map of itself, whose centroid is the image of the disc's centre
// at exactly that time (docs/camera.md, "Time of a marker"). Rounded to the
// microsecond. With all three figures 0 it returns capture_utime.
int64_t RowMidExposureUtime(const CameraTiming& timing, int64_t capture_utime, double row_px);

}  // namespace roomfix::calib

#endif  // ROOMFIX_CORE_CALIB_CAMERA_TIMING_H_
