#ifndef ROOMFIX_CAMERA_IO_V4L2_PROPERTIES_H_
#define ROOMFIX_CAMERA_IO_V4L2_PROPERTIES_H_

// Internal to camera_io: applying the site file's camera properties to a
// capture device and reporting what the device refused or changed. Separated
// from cv::VideoCapture by a setter/getter pair so it is tested without a
// camera.

#include <functional>
#include <map>
#include <string>
#include <vector>

namespace roomfix::camera {

// Sets an OpenCV capture property (cv::CAP_PROP_*); false when refused.
using PropertySetter = std::function<bool(int property, double value)>;
// Reads one back; OpenCV's V4L2 backend gives -1 for an unsupported control.
using PropertyGetter = std::function<double(int property)>;

// The cv::CAP_PROP_* for a site-file property name (brightness, contrast,
// saturation, hue, gamma, sharpness, exposure), or -1 for an unknown name.
int CapturePropertyId(const std::string& name);

// Sets each property and reads it back. Returns one line per property that was
// unknown ("focus: unknown property"), refused ("gamma: not supported") or
// changed ("exposure: asked 156, got 250"); empty when all were taken as
// asked. An exposure first switches auto-exposure to manual
// (cv::CAP_PROP_AUTO_EXPOSURE = 1, V4L2_EXPOSURE_MANUAL, through OpenCV's V4L2
// backend, which passes the value unnormalised); a refusal of that is reported
// as "exposure: cannot turn auto-exposure off".
std::vector<std::string> ApplyCaptureProperties(const std::map<std::string, double>& properties,
                                                const PropertySetter& set,
                                                const PropertyGetter& get);

}  // namespace roomfix::camera

#endif  // ROOMFIX_CAMERA_IO_V4L2_PROPERTIES_H_
