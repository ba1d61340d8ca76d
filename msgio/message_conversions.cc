#include "msgio/message_conversions.h"

#include <cstddef>

namespace roomfix {

// The enums mirror the generated constants by value; a .lcm change that
// renumbers one stops the build here.
static_assert(static_cast<int8_t>(PoseSource::kUnknown) == pose2d_t::SOURCE_UNKNOWN);
static_assert(static_cast<int8_t>(PoseSource::kCamera) == pose2d_t::SOURCE_CAMERA);
static_assert(static_cast<int8_t>(PoseSource::kUltrasound) == pose2d_t::SOURCE_ULTRASOUND);
static_assert(static_cast<int8_t>(PoseSource::kFused) == pose2d_t::SOURCE_FUSED);
static_assert(static_cast<int8_t>(PoseSource::kGroundTruth) == pose2d_t::SOURCE_GROUND_TRUTH);
static_assert(kNumPoseSources == pose2d_t::SOURCE_GROUND_TRUTH + 1);
static_assert(static_cast<int8_t>(PoseStatus::kOk) == pose2d_t::STATUS_OK);
static_assert(static_cast<int8_t>(PoseStatus::kDegraded) == pose2d_t::STATUS_DEGRADED);
static_assert(static_cast<int8_t>(PoseStatus::kLost) == pose2d_t::STATUS_LOST);
static_assert(static_cast<int8_t>(MarkerRole::kNone) == marker_t::ROLE_NONE);
static_assert(static_cast<int8_t>(MarkerRole::kPosition) == marker_t::ROLE_POSITION);
static_assert(static_cast<int8_t>(MarkerRole::kHeading) == marker_t::ROLE_HEADING);
static_assert(static_cast<int8_t>(SearchMode::kFullFrame) == marker_pixels_t::SEARCH_FULL_FRAME);
static_assert(static_cast<int8_t>(SearchMode::kRegionOfInterest) ==
              marker_pixels_t::SEARCH_REGION_OF_INTEREST);

namespace {

// Each Copy* below copies every field between a generated type and the struct
// of msgio/messages.h with the same field names, in either direction, so
// that a field is listed once; an enum and the generated int8 cross by value.
template <typename To, typename From>
void Assign(To* to, const From& from) {
  *to = static_cast<To>(from);
}

template <typename From, typename To>
void CopyPose(const From& from, To* to) {
  Assign(&to->utime, from.utime);
  Assign(&to->source, from.source);
  Assign(&to->camera_id, from.camera_id);
  Assign(&to->robot_id, from.robot_id);
  Assign(&to->measurement_seq, from.measurement_seq);
  Assign(&to->x_m, from.x_m);
  Assign(&to->y_m, from.y_m);
  Assign(&to->z_m, from.z_m);
  Assign(&to->heading_rad, from.heading_rad);
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) Assign(&to->covariance[r][c], from.covariance[r][c]);
  }
  Assign(&to->residual_m, from.residual_m);
  Assign(&to->num_measurements, from.num_measurements);
  Assign(&to->status, from.status);
  Assign(&to->latency_us, from.latency_us);
}

template <typename From, typename To>
void CopyMarkerPixels(const From& from, To* to) {
  Assign(&to->utime, from.utime);
  Assign(&to->camera_id, from.camera_id);
  Assign(&to->frame_seq, from.frame_seq);
  Assign(&to->width_px, from.width_px);
  Assign(&to->height_px, from.height_px);
  Assign(&to->search_mode, from.search_mode);
  Assign(&to->processing_time_us, from.processing_time_us);
  to->markers.resize(from.markers.size());
  for (size_t i = 0; i < from.markers.size(); ++i) {
    const auto& m = from.markers[i];
    auto& out = to->markers[i];
    out.colour_class = m.colour_class;
    Assign(&out.robot_id, m.robot_id);
    Assign(&out.role, m.role);
    Assign(&out.u_px, m.u_px);
    Assign(&out.v_px, m.v_px);
    Assign(&out.radius_px, m.radius_px);
    Assign(&out.circularity, m.circularity);
    Assign(&out.area_px, m.area_px);
  }
}

template <typename From, typename To>
void CopyImage(const From& from, To* to) {
  Assign(&to->utime, from.utime);
  Assign(&to->camera_id, from.camera_id);
  Assign(&to->frame_seq, from.frame_seq);
  Assign(&to->width_px, from.width_px);
  Assign(&to->height_px, from.height_px);
  Assign(&to->source_width_px, from.source_width_px);
  Assign(&to->source_height_px, from.source_height_px);
  to->format = from.format;
  to->data = from.data;
}

template <typename From, typename To>
void CopyDetectorView(const From& from, To* to) {
  Assign(&to->utime, from.utime);
  Assign(&to->camera_id, from.camera_id);
  Assign(&to->frame_seq, from.frame_seq);
  Assign(&to->width_px, from.width_px);
  Assign(&to->height_px, from.height_px);
  Assign(&to->source_width_px, from.source_width_px);
  Assign(&to->source_height_px, from.source_height_px);
  Assign(&to->region_u_px, from.region_u_px);
  Assign(&to->region_v_px, from.region_v_px);
  Assign(&to->region_width_px, from.region_width_px);
  Assign(&to->region_height_px, from.region_height_px);
  Assign(&to->scale, from.scale);
  to->format = from.format;
  to->data = from.data;
  to->robots.resize(from.robots.size());
  for (size_t i = 0; i < from.robots.size(); ++i) {
    const auto& r = from.robots[i];
    auto& out = to->robots[i];
    Assign(&out.robot_id, r.robot_id);
    Assign(&out.reason, r.reason);
    out.colour_class = r.colour_class;
    Assign(&out.value, r.value);
    Assign(&out.limit, r.limit);
    out.text = r.text;
  }
}

template <typename From, typename To>
void CopyDetectorViewRequest(const From& from, To* to) {
  Assign(&to->utime, from.utime);
  Assign(&to->camera_id, from.camera_id);
  Assign(&to->region_u_px, from.region_u_px);
  Assign(&to->region_v_px, from.region_v_px);
  Assign(&to->region_width_px, from.region_width_px);
  Assign(&to->region_height_px, from.region_height_px);
  Assign(&to->rate_hz, from.rate_hz);
  Assign(&to->duration_s, from.duration_s);
}

}  // namespace

pose2d_t ToMessage(const Pose2d& pose) {
  pose2d_t msg{};
  CopyPose(pose, &msg);
  return msg;
}

Pose2d FromMessage(const pose2d_t& msg) {
  Pose2d pose;
  CopyPose(msg, &pose);
  return pose;
}

marker_pixels_t ToMessage(const MarkerPixels& pixels) {
  marker_pixels_t msg{};
  CopyMarkerPixels(pixels, &msg);
  msg.num_markers = static_cast<int32_t>(msg.markers.size());
  return msg;
}

MarkerPixels FromMessage(const marker_pixels_t& msg) {
  MarkerPixels pixels;
  CopyMarkerPixels(msg, &pixels);
  return pixels;
}

image_t ToMessage(const PreviewImage& image) {
  image_t msg{};
  CopyImage(image, &msg);
  msg.num_bytes = static_cast<int32_t>(msg.data.size());
  return msg;
}

PreviewImage FromMessage(const image_t& msg) {
  PreviewImage image;
  CopyImage(msg, &image);
  return image;
}

detector_view_t ToMessage(const DetectorViewImage& view) {
  detector_view_t msg{};
  CopyDetectorView(view, &msg);
  msg.num_bytes = static_cast<int32_t>(msg.data.size());
  msg.num_robots = static_cast<int32_t>(msg.robots.size());
  return msg;
}

DetectorViewImage FromMessage(const detector_view_t& msg) {
  DetectorViewImage view;
  CopyDetectorView(msg, &view);
  return view;
}

detector_view_request_t ToMessage(const DetectorViewRequest& request) {
  detector_view_request_t msg{};
  CopyDetectorViewRequest(request, &msg);
  return msg;
}

DetectorViewRequest FromMessage(const detector_view_request_t& msg) {
  DetectorViewRequest request;
  CopyDetectorViewRequest(msg, &request);
  return request;
}

}  // namespace roomfix
