#include "core/calib/camera_timing.h"

#include <cmath>

namespace roomfix::calib {

bool CameraTiming::IsValid(std::string* error) const {
  if (!(readout_s >= 0.0) || !(exposure_s >= 0.0) || !(latency_s >= 0.0) ||
      !std::isfinite(readout_s) || !std::isfinite(exposure_s) || !std::isfinite(latency_s)) {
    *error = "camera timing: readout, exposure and latency must be finite and not negative";
    return false;
  }
  if (height_px <= 0) {
    *error = "camera timing: image height must be positive";
    return false;
  }
  return true;
}

int64_t RowMidExposureUtime(const CameraTiming& timing, int64_t capture_utime, double row_px) {
  const double h = static_cast<double>(timing.height_px);
  const double before_s =
      timing.latency_s + (h - 1.0 - row_px) * timing.readout_s / h + 0.5 * timing.exposure_s;
  if (before_s == 0.0) return capture_utime;
  return capture_utime - static_cast<int64_t>(std::llround(before_s * 1e6));
}

}  // namespace roomfix::calib
