#ifndef ROOMFIX_MSGIO_MESSAGES_H_
#define ROOMFIX_MSGIO_MESSAGES_H_

// The messages the processes build, as plain structs without the generated
// code. Each mirrors one generated type field for field (same names, same
// units; the meanings are in lcmtypes/<type>.lcm), with typed enums for the
// generated integer constants and counts that follow from the vectors.
// msgio/message_conversions.h turns each into its generated type and back:
// those functions are the only code that fills a generated message field by
// field, so a field added to a .lcm file is added in two places (the struct
// and its conversion) and a test fails until both are done.

#include <array>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "core/world/pose_source.h"
#include "core/world/site.h"

namespace roomfix {

// pose2d_t::STATUS_*.
enum class PoseStatus : int8_t {
  kOk = 0,
  kDegraded = 1,
  kLost = 2,
};

// A pose2d_t. What a producer does not state is unknown: position, heading
// and covariance start as NaN and the status as lost, so a lost pose needs
// only its header fields; camera_id starts as kNoCameraId (not a camera's
// pose).
struct Pose2d {
  using Covariance = std::array<std::array<double, 3>, 3>;
  static constexpr double kUnknown = std::numeric_limits<double>::quiet_NaN();

  int64_t utime = 0;
  PoseSource source = PoseSource::kUnknown;
  int32_t camera_id = kNoCameraId;
  int32_t robot_id = -1;
  int64_t measurement_seq = -1;
  double x_m = kUnknown;
  double y_m = kUnknown;
  double z_m = kUnknown;
  double heading_rad = kUnknown;
  // (x_m, y_m, heading_rad), row-major: m^2, m*rad, rad^2.
  Covariance covariance = {{{kUnknown, kUnknown, kUnknown},
                            {kUnknown, kUnknown, kUnknown},
                            {kUnknown, kUnknown, kUnknown}}};
  double residual_m = 0.0;
  int32_t num_measurements = 0;
  PoseStatus status = PoseStatus::kLost;
  int64_t latency_us = 0;
};

// marker_t::ROLE_*.
enum class MarkerRole : int8_t {
  kNone = 0,
  kPosition = 1,
  kHeading = 2,
};

// marker_pixels_t::SEARCH_*.
enum class SearchMode : int8_t {
  kFullFrame = 0,
  kRegionOfInterest = 1,
};

// A marker_t: one blob found in a frame.
struct PixelMarker {
  std::string colour_class;
  int32_t robot_id = -1;
  MarkerRole role = MarkerRole::kNone;
  double u_px = 0.0;
  double v_px = 0.0;
  double radius_px = 0.0;
  double circularity = 0.0;
  double area_px = 0.0;
};

// A marker_pixels_t (num_markers is markers.size()).
struct MarkerPixels {
  int64_t utime = 0;
  int32_t camera_id = 0;
  int64_t frame_seq = 0;
  int32_t width_px = 0;
  int32_t height_px = 0;
  SearchMode search_mode = SearchMode::kFullFrame;
  int32_t processing_time_us = 0;
  std::vector<PixelMarker> markers;
};

// An image_t: a camera's reduced preview (num_bytes is data.size()).
struct PreviewImage {
  int64_t utime = 0;
  int32_t camera_id = 0;
  int64_t frame_seq = 0;
  int32_t width_px = 0;
  int32_t height_px = 0;
  int32_t source_width_px = 0;
  int32_t source_height_px = 0;
  std::string format;
  std::vector<uint8_t> data;
};

// A detector_view_robot_t: why the detector finds a robot or not. `reason`
// is one of detector_view_robot_t's REASON_ constants (the numbers of
// vision::RobotViewReason).
struct DetectorViewRobot {
  int32_t robot_id = 0;
  int8_t reason = 0;
  std::string colour_class;
  double value = 0.0;
  double limit = 0.0;
  std::string text;
};

// A detector_view_t: what a camera's detector sees, as a small image (PNG),
// with a line per robot (num_bytes and num_robots are the vectors' sizes).
struct DetectorViewImage {
  int64_t utime = 0;
  int32_t camera_id = 0;
  int64_t frame_seq = 0;
  int32_t width_px = 0;
  int32_t height_px = 0;
  int32_t source_width_px = 0;
  int32_t source_height_px = 0;
  int32_t region_u_px = 0;
  int32_t region_v_px = 0;
  int32_t region_width_px = 0;
  int32_t region_height_px = 0;
  int32_t scale = 1;
  std::string format;
  std::vector<uint8_t> data;
  std::vector<DetectorViewRobot> robots;
};

// A detector_view_request_t: camera_id -1 is every camera; a region of zero
// width or height is the whole frame; duration 0 stops.
struct DetectorViewRequest {
  int64_t utime = 0;
  int32_t camera_id = -1;
  int32_t region_u_px = 0;
  int32_t region_v_px = 0;
  int32_t region_width_px = 0;
  int32_t region_height_px = 0;
  double rate_hz = 1.0;
  double duration_s = 10.0;
};

}  // namespace roomfix

#endif  // ROOMFIX_MSGIO_MESSAGES_H_
