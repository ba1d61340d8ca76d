#include "camera_io/v4l2_properties.h"

#include <fmt/format.h>

#include <cmath>
#include <opencv2/videoio.hpp>

namespace roomfix::camera {
namespace {

// V4L2_EXPOSURE_MANUAL in the V4L2_CID_EXPOSURE_AUTO menu (0 auto, 1 manual,
// 2 shutter priority, 3 aperture priority); OpenCV's V4L2 backend passes
// CAP_PROP_AUTO_EXPOSURE through as that menu index.
constexpr double kV4l2ExposureManual = 1.0;
// V4L2 controls are integers: a read-back within this of the request is taken.
constexpr double kReadBackTolerance = 0.5;

}  // namespace

int CapturePropertyId(const std::string& name) {
  static const std::map<std::string, int> kIds = {
      {"brightness", cv::CAP_PROP_BRIGHTNESS},
      {"contrast", cv::CAP_PROP_CONTRAST},
      {"saturation", cv::CAP_PROP_SATURATION},
      {"hue", cv::CAP_PROP_HUE},
      {"gamma", cv::CAP_PROP_GAMMA},
      {"sharpness", cv::CAP_PROP_SHARPNESS},
      {"exposure", cv::CAP_PROP_EXPOSURE},
      {"gain", cv::CAP_PROP_GAIN},
      {"white_balance", cv::CAP_PROP_WB_TEMPERATURE},
      {"focus", cv::CAP_PROP_FOCUS},
  };
  const auto it = kIds.find(name);
  return it == kIds.end() ? -1 : it->second;
}

std::vector<std::string> ApplyCaptureProperties(const std::map<std::string, double>& properties,
                                                const PropertySetter& set,
                                                const PropertyGetter& get) {
  std::vector<std::string> refused;
  for (const auto& [name, value] : properties) {
    const int id = CapturePropertyId(name);
    if (id < 0) {
      refused.push_back(name + ": unknown property");
      continue;
    }
    if (id == cv::CAP_PROP_EXPOSURE && !set(cv::CAP_PROP_AUTO_EXPOSURE, kV4l2ExposureManual)) {
      refused.push_back(name + ": cannot turn auto-exposure off");
      continue;
    }
    // A camera ignores a manual white balance or focus while its automatic
    // one runs (V4L2_CID_AUTO_WHITE_BALANCE, V4L2_CID_FOCUS_AUTO): off first.
    if (id == cv::CAP_PROP_WB_TEMPERATURE && !set(cv::CAP_PROP_AUTO_WB, 0.0)) {
      refused.push_back(name + ": cannot turn automatic white balance off");
      continue;
    }
    if (id == cv::CAP_PROP_FOCUS && !set(cv::CAP_PROP_AUTOFOCUS, 0.0)) {
      refused.push_back(name + ": cannot turn autofocus off");
      continue;
    }
    if (!set(id, value)) {
      refused.push_back(name + ": not supported");
      continue;
    }
    const double got = get(id);
    if (!std::isfinite(got) || std::fabs(got - value) > kReadBackTolerance) {
      refused.push_back(fmt::format("{}: asked {:g}, got {:g}", name, value, got));
    }
  }
  return refused;
}

}  // namespace roomfix::camera
