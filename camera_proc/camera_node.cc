#include "camera_proc/camera_node.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <unordered_map>
#include <utility>

#include "core/calib/marker_projection.h"
#include "core/calib/pose_covariance.h"
#include "core/vision/detector_view.h"
#include "msgio/message_conversions.h"
#include "msgio/received.h"
#include "msgio/time_limits.h"
#include "msgio/wire_check.h"
#include "roomfix/detector_view_request_t.hpp"
#include "roomfix/detector_view_t.hpp"

namespace roomfix {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

int64_t SteadyMicros() {
  return std::chrono::duration_cast<std::chrono::microseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

int ClassIndex(const std::vector<vision::ColourClass>& classes, const std::string& name) {
  for (size_t i = 0; i < classes.size(); ++i) {
    if (classes[i].name == name) return static_cast<int>(i);
  }
  return -1;
}

// Radius in pixels of a disc of radius_m at (x, y, height) seen by the lens:
// the mean distance of four projected rim points from the projected centre.
double ImageRadiusPx(const calib::CameraModel& lens, double x_m, double y_m, double height_m,
                     double radius_m) {
  double u0 = 0, v0 = 0;
  if (!lens.ProjectToPixel(Eigen::Vector3d(x_m, y_m, height_m), &u0, &v0)) return 0.0;
  double sum = 0.0;
  int n = 0;
  for (int i = 0; i < 4; ++i) {
    const double a = i * M_PI / 2.0;
    double u = 0, v = 0;
    if (lens.ProjectToPixel(
            Eigen::Vector3d(x_m + radius_m * std::cos(a), y_m + radius_m * std::sin(a), height_m),
            &u, &v)) {
      sum += std::hypot(u - u0, v - v0);
      ++n;
    }
  }
  return n > 0 ? sum / n : 0.0;
}

// A frame's blobs, each marker once: a blob within a pixel of an earlier one
// of its class is the same marker measured by two searches (the earlier is
// kept). Blobs are hashed by class and 1-px cell, and a new one is compared
// with the 3 x 3 cells around it only, so a frame of thousands of coloured
// specks costs time linear in their number.
class UniqueBlobs {
 public:
  void Add(const vision::Blob& b) {
    const int64_t cu = static_cast<int64_t>(std::floor(b.u_px));
    const int64_t cv = static_cast<int64_t>(std::floor(b.v_px));
    for (int64_t du = -1; du <= 1; ++du) {
      for (int64_t dv = -1; dv <= 1; ++dv) {
        const auto it = cells_.find(Key(b.class_index, cu + du, cv + dv));
        if (it == cells_.end()) continue;
        for (const size_t k : it->second) {
          const vision::Blob& a = blobs_[k];
          if (a.class_index == b.class_index &&
              std::hypot(a.u_px - b.u_px, a.v_px - b.v_px) < 1.0) {
            return;
          }
        }
      }
    }
    cells_[Key(b.class_index, cu, cv)].push_back(blobs_.size());
    blobs_.push_back(b);
  }
  std::vector<vision::Blob> Take() { return std::move(blobs_); }

 private:
  // Class and cell in one key; cells are offset so that any pixel of an
  // image up to 2^20 px across maps to a distinct non-negative pair.
  static int64_t Key(int class_index, int64_t cu, int64_t cv) {
    constexpr int64_t kOffset = 1 << 20;
    return ((static_cast<int64_t>(class_index) * (2 * kOffset) + (cu + kOffset)) * (2 * kOffset)) +
           (cv + kOffset);
  }
  std::vector<vision::Blob> blobs_;
  std::unordered_map<int64_t, std::vector<size_t>> cells_;
};

}  // namespace

bool CameraNodeOptions::IsValid(std::string* error) const {
  if (full_search_scale != 1 && full_search_scale != 2 && full_search_scale != 4 &&
      full_search_scale != 8) {
    *error = "full search scale must be 1, 2, 4 or 8, not " + std::to_string(full_search_scale);
    return false;
  }
  if (!(max_speed_mps > 0.0) || !std::isfinite(max_speed_mps)) {
    *error = "maximum speed must be positive";
    return false;
  }
  if (!(centroid_sigma_px > 0.0) || !std::isfinite(centroid_sigma_px)) {
    *error = "centroid sigma must be positive";
    return false;
  }
  if (!(blur_sigma_fraction >= 0.0) || !std::isfinite(blur_sigma_fraction)) {
    *error = "blur sigma fraction must not be negative";
    return false;
  }
  if (!(velocity_span_s > 0.0) || !std::isfinite(velocity_span_s)) {
    *error = "velocity span must be positive";
    return false;
  }
  if (!(blur_sigma_px >= 0.0)) {
    *error = "blur sigma must not be negative";
    return false;
  }
  if (max_blobs_per_frame < 2) {
    *error = "max blobs per frame must be at least 2";
    return false;
  }
  if (absent_search_period_frames < 1 || absent_search_period_frames > 300) {
    *error = "absent search period must lie in [1, 300] frames";
    return false;
  }
  if (!(detector_view_hz >= 0.0) || !std::isfinite(detector_view_hz) ||
      detector_view_hz > detector_view_max_hz) {
    *error = "detector view rate must lie in [0, detector_view_max_hz] Hz";
    return false;
  }
  if (!(detector_view_max_hz > 0.0) || !std::isfinite(detector_view_max_hz) ||
      !(detector_view_max_duration_s > 0.0) || !std::isfinite(detector_view_max_duration_s)) {
    *error = "detector view maximum rate and duration must be positive";
    return false;
  }
  if (detector_view_max_width_px < 64) {
    *error = "detector view maximum width must be at least 64 px";
    return false;
  }
  if (device_timing && !device_timing->IsValid(error)) {
    *error = "device timing: " + *error;
    return false;
  }
  return true;
}

bool MakeCameraSetup(const Room& room, const Camera& camera, const calib::CameraModel& lens,
                     const CameraNodeOptions& options, CameraSetup* setup, std::string* error) {
  *setup = CameraSetup{};
  if (camera.marker_classes.empty()) {
    *error = "camera " + std::to_string(camera.id) + " has no marker classes";
    return false;
  }
  // The camera sees a marker largest straight below it and smallest at the
  // floor's far corners; the area filter spans both with a margin for
  // partial occlusion (half the radius) and for blur (1.8 times).
  const Eigen::Vector3d& mount = lens.pose.position_m;
  double far_x = mount.x(), far_y = mount.y();
  for (const double x : {room.min_x_m, room.min_x_m + room.size_x_m}) {
    for (const double y : {room.min_y_m, room.min_y_m + room.size_y_m}) {
      if (std::hypot(x - mount.x(), y - mount.y()) >
          std::hypot(far_x - mount.x(), far_y - mount.y())) {
        far_x = x;
        far_y = y;
      }
    }
  }
  const double min_height_m = 0.0;
  double max_height_m = 0.0;
  for (const CameraRobot& r : camera.robots) {
    max_height_m = std::max(max_height_m, r.marker_height_m);
  }
  const MarkerCode& code = camera.marker_code;
  for (const MarkerClass& mc : camera.marker_classes) {
    vision::ColourClass c;
    c.name = mc.name;
    c.hsv_min = mc.hsv_min;
    c.hsv_max = mc.hsv_max;
    // With a marker code a class is seen at both roles' sizes: the filter
    // spans the small one far away to the large one below the lens.
    const double radius_m = code.enabled()        ? code.position_diameter_m / 2.0
                            : mc.diameter_m > 0.0 ? mc.diameter_m / 2.0
                                                  : 0.05;
    const double small_radius_m = code.enabled() ? code.heading_diameter_m / 2.0 : radius_m;
    const double near_px = ImageRadiusPx(lens, mount.x(), mount.y(), max_height_m, radius_m);
    // A far corner may lie outside the image; the marker is then never seen
    // smaller than at the image's edge, which a quarter of the near radius
    // bounds for a 120-degree lens.
    double far_px = ImageRadiusPx(lens, far_x, far_y, min_height_m, small_radius_m);
    if (!(far_px > 0.0)) far_px = 0.25 * near_px * small_radius_m / radius_m;
    c.min_area_px = std::max(6.0, M_PI * std::pow(0.5 * far_px, 2));
    c.max_area_px = std::max(c.min_area_px * 4.0, M_PI * std::pow(1.8 * near_px + 2.0, 2));
    c.min_circularity = 0.6;
    setup->classes.push_back(c);
  }
  for (const CameraRobot& r : camera.robots) {
    vision::TrackedRobotSpec spec;
    spec.robot_id = r.robot_id;
    spec.position_class = ClassIndex(setup->classes, r.position_marker);
    spec.heading_class = ClassIndex(setup->classes, r.heading_marker);
    if (spec.position_class < 0 || spec.heading_class < 0) {
      *error = "robot " + std::to_string(r.robot_id) + " names a marker class the camera lacks";
      return false;
    }
    const double position_radius_m = PositionMarkerDiameterM(camera, r) / 2.0;
    spec.position_radius_px =
        ImageRadiusPx(lens, mount.x(), mount.y(), r.marker_height_m, position_radius_m);
    setup->robots.push_back(spec);
    setup->marker_height_m.push_back(r.marker_height_m);
    setup->position_radius_m.push_back(position_radius_m);
    setup->heading_radius_m.push_back(HeadingMarkerDiameterM(camera, r) / 2.0);
  }
  if (code.enabled()) {
    setup->tracker.identify_by_code = true;
    setup->tracker.heading_offset_radii = code.heading_offset_m / (code.position_diameter_m / 2.0);
    setup->tracker.heading_size_ratio = code.heading_diameter_m / code.position_diameter_m;
  }
  // Pixels per metre on the floor are largest straight below the lens.
  double px_per_m = 0.0;
  if (!setup->robots.empty()) {
    const double h = setup->marker_height_m.front();
    px_per_m = ImageRadiusPx(lens, mount.x(), mount.y(), h, 0.1) / 0.1;
  }
  setup->tracker.max_speed_px_per_s = std::max(50.0, options.max_speed_mps * px_per_m);
  setup->tracker.refuse_clipped = options.refuse_clipped_markers;
  setup->tracker.absent_search_period_frames = options.absent_search_period_frames;
  setup->tracker.max_blobs = options.max_blobs_per_frame;
  return setup->tracker.IsValid(error);
}

CameraNode::CameraNode(const Site& site, const Camera& camera,
                       std::optional<calib::Calibration> calibration, Bus* bus,
                       const CameraNodeOptions& options, int64_t start_utime)
    : camera_(camera),
      site_(site),
      calibration_(std::move(calibration)),
      bus_(bus),
      options_(options),
      status_("camera_proc", start_utime) {
  if (!options_.steady_clock) options_.steady_clock = SteadyMicros;
  timing_.readout_s = camera.readout_s;
  timing_.exposure_s = camera.exposure_s;
  timing_.latency_s = camera.timestamp_latency_s;
  timing_.height_px = camera.height_px;
  if (options_.device_timing) {
    // The device decides: a synthetic clean frame is exact whatever the
    // site's camera says, and shifting its poses by the site's readout and
    // latency would misplace them (about 5 mm at 18 cm/s for 28 ms).
    const calib::CameraTiming& d = *options_.device_timing;
    if (d.readout_s != timing_.readout_s || d.exposure_s != timing_.exposure_s ||
        d.latency_s != timing_.latency_s) {
      spdlog::warn(
          "camera {}: the device defines its own timing (readout {:.1f} ms, exposure {:.1f} ms, "
          "timestamp latency {:.1f} ms), not the site's (readout_s {:.1f} ms, exposure_s "
          "{:.1f} ms, timestamp_latency_s {:.1f} ms); using the device's",
          camera.id, d.readout_s * 1e3, d.exposure_s * 1e3, d.latency_s * 1e3,
          timing_.readout_s * 1e3, timing_.exposure_s * 1e3, timing_.latency_s * 1e3);
    }
    timing_.readout_s = d.readout_s;
    timing_.exposure_s = d.exposure_s;
    timing_.latency_s = d.latency_s;
  }
  // The lens that sizes windows and blobs: the calibrated one when there is
  // a full model, else the nominal lens at the mount position.
  calib::CameraModel lens = calib::NominalCamera(camera.mount_position_m, camera.field_of_view_deg,
                                                 camera.width_px, camera.height_px);
  if (calibration_ && calibration_->model == calib::Calibration::Model::kFull) {
    lens = calibration_->camera;
  }
  if (!MakeCameraSetup(site.room, camera, lens, options_, &setup_, &setup_error_)) return;
  // The 9-region table holds at its calibration height only: a robot whose
  // markers sit elsewhere would be mapped wrong on every frame.
  if (calibration_ && calibration_->model == calib::Calibration::Model::kRegions) {
    for (size_t i = 0; i < setup_.robots.size(); ++i) {
      const double h = setup_.marker_height_m[i];
      if (std::abs(h - calibration_->regions.calibration_height_m) >
          calib::RegionModel::kHeightToleranceM) {
        setup_error_ = "robot " + std::to_string(setup_.robots[i].robot_id) + "'s markers are " +
                       std::to_string(h) + " m high but the 9-region calibration holds at " +
                       std::to_string(calibration_->regions.calibration_height_m) +
                       " m only; recalibrate at that height or use the full model";
        return;
      }
    }
  }
  vision::DetectorOptions detector_options;
  detector_options.lighting = options_.lighting;
  detector_options.blur_sigma_px = options_.blur_sigma_px;
  if (!detector_options.IsValid(&setup_error_)) return;
  detector_ = std::make_unique<vision::MarkerDetector>(setup_.classes, detector_options);
  tracker_ = std::make_unique<vision::RobotTracker>(setup_.robots, setup_.tracker, camera.width_px,
                                                    camera.height_px);
  subscriptions_.Add(bus_->Subscribe<detector_view_request_t>(
      kDetectorViewRequestChannel,
      [this](const detector_view_request_t& m, const MessageInfo& info) {
        OnDetectorViewRequest(m, info);
      }));
  // Hints need the floor-to-pixel direction, so a calibration.
  if (calibration_) {
    for (const std::string& channel : options_.hint_channels) {
      subscriptions_.Add(bus_->Subscribe<pose2d_t>(
          channel, [this](const pose2d_t& p, const MessageInfo& info) { OnHint(p, info); }));
    }
  }
}

void CameraNode::OnHint(const pose2d_t& msg, const MessageInfo& info) {
  // A hint moves a robot's search window: one with an absurd time, for a
  // robot the site does not have, or with an infinity in it is refused and
  // counted, never followed.
  Pose2d pose;
  std::string why;
  InputProblem problem = InputProblem::kNone;
  if (!ReceivePose(msg, site_, info.recv_utime, &pose, &why, &problem)) {
    status_.Reject(InputProblemCounter(problem));
    return;
  }
  if (pose.status == PoseStatus::kLost) return;
  for (size_t i = 0; i < setup_.robots.size(); ++i) {
    if (setup_.robots[i].robot_id != pose.robot_id) continue;
    const double h = setup_.marker_height_m[i];
    double u = 0, v = 0, u1 = 0, v1 = 0;
    std::string error;
    // Radius on the floor: 3 sigma of the larger axis, clamped; in pixels
    // by the local scale (one floor step of 0.1 m imaged).
    double var = std::max(pose.covariance[0][0], pose.covariance[1][1]);
    // ReceivePose has refused a non-finite covariance; a negative variance
    // (a forged one) searches at the smallest radius.
    if (var < 0.0) var = 0.0;
    const double radius_m =
        std::clamp(3.0 * std::sqrt(var), options_.hint_min_radius_m, options_.hint_max_radius_m);
    if (!calibration_->FloorToPixel(pose.x_m, pose.y_m, h, &u, &v, &error) ||
        !calibration_->FloorToPixel(pose.x_m + 0.1, pose.y_m, h, &u1, &v1, &error)) {
      return;
    }
    const double px_per_m = std::hypot(u1 - u, v1 - v) / 0.1;
    tracker_->SetHint(pose.robot_id, u, v, radius_m * px_per_m, pose.utime);
    hint_px_[pose.robot_id] = {u, v, pose.utime};
    status_.Count("hints");
  }
}

bool CameraNode::ok(std::string* error) const {
  if (!setup_error_.empty()) {
    *error = setup_error_;
    return false;
  }
  return true;
}

bool CameraNode::SearchFullFrame(camera::FrameImage* image, std::vector<vision::Blob>* blobs,
                                 std::string* error) {
  const int scale = options_.full_search_scale;
  cv::Mat reduced;
  if (!image->DecodeReduced(scale, &reduced, error)) return false;
  vision::ImageWindow whole;
  whole.scale = scale;
  std::vector<vision::Blob> coarse = detector_->Detect(reduced, whole);
  // A frame with more blobs than the tracker takes identifies no robot
  // (too_many_blobs): re-measuring each at full resolution (a window decode
  // and a detection per blob, about 1.4 ms each) would only delay that.
  if (scale == 1 || coarse.size() > static_cast<size_t>(options_.max_blobs_per_frame)) {
    *blobs = std::move(coarse);
    return true;
  }
  // Each blob found on the reduced view is re-measured on a full-resolution
  // window a few radii across (the reduced view's centroid is good to about
  // a quarter of the scale; the full-resolution one to a hundredth of a
  // pixel).
  blobs->clear();
  for (vision::Blob& b : coarse) {
    const double half = 2.5 * b.radius_px + 3.0 * scale + 4.0;
    const cv::Rect rect(
        static_cast<int>(std::floor(b.u_px - half)), static_cast<int>(std::floor(b.v_px - half)),
        static_cast<int>(std::ceil(2.0 * half)) + 1, static_cast<int>(std::ceil(2.0 * half)) + 1);
    const cv::Rect clipped = rect & cv::Rect(0, 0, image->width_px(), image->height_px());
    cv::Mat window;
    if (clipped.empty() || !image->DecodeRegion(clipped, &window, error)) return false;
    vision::ImageWindow w;
    w.offset_u_px = clipped.x;
    w.offset_v_px = clipped.y;
    vision::Blob refined = b;
    if (detector_->Refine(window, w, b.class_index, &refined)) blobs->push_back(refined);
  }
  return true;
}

bool CameraNode::AcceptFrame(const camera::Frame& frame, int64_t now_utime) {
  status_.AddInputs();
  // A gap in the source's numbering is frames the camera dropped, less the
  // ones that came but were unreadable (counted as such in OnBadFrame).
  // The source's own skips (a synthetic renderer behind real time) are
  // counted apart: they are not frames camera_proc failed to keep up with.
  if (frame.source_skipped > 0) status_.Count("source_skipped_frames", frame.source_skipped);
  if (last_seq_ >= 0 && frame.seq > last_seq_ + 1) {
    const int64_t dropped = frame.seq - last_seq_ - 1 - bad_since_last_ - frame.source_skipped;
    if (dropped > 0) status_.AddDropped(dropped);
  }
  bad_since_last_ = 0;
  last_seq_ = frame.seq;
  // A frame handed over more than two frame periods after its capture
  // waited behind a slow one: the pipeline is not keeping up.
  if (camera_.fps > 0.0 && now_utime - frame.capture_utime > 2.0e6 / camera_.fps) {
    status_.Count("late_frames");
  }
  const camera::FrameImage* image = frame.image.get();
  if (image->width_px() != camera_.width_px || image->height_px() != camera_.height_px) {
    status_.Reject("wrong_frame_size");
    status_.SetError("frame " + std::to_string(frame.seq) + " is " +
                         std::to_string(image->width_px()) + "x" +
                         std::to_string(image->height_px()) + ", the site says " +
                         std::to_string(camera_.width_px) + "x" + std::to_string(camera_.height_px),
                     now_utime);
    return false;
  }
  return true;
}

bool CameraNode::DetectBlobs(const camera::Frame& frame,
                             const std::vector<vision::SearchPlan>& plans, bool full,
                             std::vector<vision::Blob>* all, int64_t now_utime) {
  camera::FrameImage* image = frame.image.get();
  std::string error;
  std::vector<vision::Blob> full_blobs;
  std::vector<std::vector<vision::Blob>> window_blobs(plans.size());
  bool decoded = true;
  if (full) decoded = SearchFullFrame(image, &full_blobs, &error);
  for (size_t i = 0; decoded && i < plans.size(); ++i) {
    if (plans[i].full_frame || plans[i].window.empty()) continue;
    cv::Mat window;
    if (!image->DecodeRegion(plans[i].window, &window, &error)) {
      decoded = false;
      break;
    }
    vision::ImageWindow w;
    w.offset_u_px = plans[i].window.x;
    w.offset_v_px = plans[i].window.y;
    const vision::TrackedRobotSpec& spec = tracker_->robots()[i];
    // With a marker code every class may be a neighbour's marker: all are
    // searched, so a pairing with a neighbour's marker is seen, not missed.
    window_blobs[i] = setup_.tracker.identify_by_code
                          ? detector_->Detect(window, w)
                          : detector_->Detect(window, w, {spec.position_class, spec.heading_class});
  }
  if (!decoded) {
    status_.Reject("corrupt_frame");
    status_.SetError("frame " + std::to_string(frame.seq) + ": " + error, now_utime);
    return false;
  }
  // Every blob seen, once: a robot's markers may be in its window and in the
  // full-frame search of the same frame. A window's own measurement is kept
  // (windows first), so the tracker gets the same blob for a tracked robot
  // whether it reads the lists made here or the published MARKER_PIXELS.
  UniqueBlobs unique;
  for (const auto& list : window_blobs) {
    for (const vision::Blob& b : list) unique.Add(b);
  }
  for (const vision::Blob& b : full_blobs) unique.Add(b);
  *all = unique.Take();
  return true;
}

MarkerPixels CameraNode::MarkerPixelsOf(const camera::Frame& frame, bool full,
                                        const std::vector<vision::Blob>& all) {
  MarkerPixels msg;
  msg.utime = frame.capture_utime;
  msg.camera_id = camera_.id;
  msg.frame_seq = frame.seq;
  msg.width_px = frame.image->width_px();
  msg.height_px = frame.image->height_px();
  msg.search_mode = full ? SearchMode::kFullFrame : SearchMode::kRegionOfInterest;
  for (const vision::Blob& b : all) {
    PixelMarker m;
    m.colour_class = setup_.classes[static_cast<size_t>(b.class_index)].name;
    m.robot_id = -1;
    m.role = MarkerRole::kNone;
    for (const vision::RobotObservation& o : observations_) {
      auto same = [&](const vision::Blob& x) {
        return x.class_index == b.class_index && std::hypot(x.u_px - b.u_px, x.v_px - b.v_px) < 1.0;
      };
      if (o.found && same(o.position)) {
        m.robot_id = o.robot_id;
        m.role = MarkerRole::kPosition;
      } else if (o.found && o.has_heading && same(o.heading)) {
        m.robot_id = o.robot_id;
        m.role = MarkerRole::kHeading;
      }
    }
    m.u_px = b.u_px;
    m.v_px = b.v_px;
    m.radius_px = b.radius_px;
    m.circularity = b.circularity;
    m.area_px = b.area_px;
    msg.markers.push_back(m);
  }
  // Every receiver refuses a MARKER_PIXELS over the wire cap, so a frame
  // full of colour noise would otherwise lose the robots' own markers too:
  // those go first, and what does not fit is counted, not sent.
  if (msg.markers.size() > static_cast<size_t>(wire_cap::kMarkersPerFrame)) {
    std::stable_partition(msg.markers.begin(), msg.markers.end(),
                          [](const PixelMarker& m) { return m.robot_id >= 0; });
    status_.Count("markers_not_published",
                  static_cast<int64_t>(msg.markers.size()) - wire_cap::kMarkersPerFrame);
    msg.markers.resize(static_cast<size_t>(wire_cap::kMarkersPerFrame));
  }
  return msg;
}

void CameraNode::OnFrame(camera::Frame* frame, int64_t now_utime) {
  if (tracker_ == nullptr || frame->image == nullptr) return;
  const int64_t begin_us = options_.steady_clock();
  if (!AcceptFrame(*frame, now_utime)) return;

  std::vector<vision::SearchPlan> plans = tracker_->Plan(frame->capture_utime);
  if (options_.always_full_search) {
    for (vision::SearchPlan& p : plans) p.full_frame = true;
  }
  bool full = false;
  for (const vision::SearchPlan& p : plans) full = full || p.full_frame;
  std::vector<vision::Blob> all;
  if (!DetectBlobs(*frame, plans, full, &all, now_utime)) return;
  Track(frame->capture_utime, plans, all, now_utime);

  MarkerPixels msg = MarkerPixelsOf(*frame, full, all);
  for (const vision::RobotObservation& o : observations_) {
    if (!o.found) continue;
    detector_->ObserveTracked(o.position);
    if (o.has_heading) detector_->ObserveTracked(o.heading);
  }
  const int64_t elapsed_us = options_.steady_clock() - begin_us;
  // Capture to end of detection: the wait before the frame reached us (for
  // a live source) plus the work on it.
  msg.processing_time_us = static_cast<int32_t>(
      std::clamp<int64_t>(std::max<int64_t>(0, now_utime - frame->capture_utime) + elapsed_us, 0,
                          std::numeric_limits<int32_t>::max()));
  status_.SetCounter("last_frame_us", elapsed_us);
  if (bus_->Publish(kMarkerPixelsChannel, ToMessage(msg))) status_.AddOutputs();
  // The pose's latency is the recorded processing time, so a replay from
  // MARKER_PIXELS (OnMarkerPixels) gives the same number.
  if (calibration_) PublishPoses(msg.utime, msg.frame_seq, msg.processing_time_us);
  last_pixels_ = std::move(msg);
  PublishLowRateViews(*frame, now_utime);
}

void CameraNode::OnMarkerPixels(const marker_pixels_t& msg, int64_t now_utime) {
  if (tracker_ == nullptr) return;
  // Another camera's pixels are another node's input.
  if (msg.camera_id != camera_.id) return;
  status_.AddInputs();
  // A frame dated far from its log time would move the tracker's clock and
  // publish poses at that time (the same window as every node's input).
  if (!UtimeNear(msg.utime, now_utime)) {
    status_.Reject("utime_out_of_range");
    return;
  }
  if (last_seq_ >= 0 && msg.frame_seq > last_seq_ + 1)
    status_.AddDropped(msg.frame_seq - last_seq_ - 1);
  last_seq_ = msg.frame_seq;
  if (msg.width_px != camera_.width_px || msg.height_px != camera_.height_px) {
    status_.Reject("wrong_frame_size");
    status_.SetError("marker pixels of frame " + std::to_string(msg.frame_seq) + " are for " +
                         std::to_string(msg.width_px) + "x" + std::to_string(msg.height_px) +
                         ", the site says " + std::to_string(camera_.width_px) + "x" +
                         std::to_string(camera_.height_px),
                     now_utime);
    return;
  }
  std::vector<vision::SearchPlan> plans = tracker_->Plan(msg.utime);
  bool full = false;
  for (const vision::SearchPlan& p : plans) full = full || p.full_frame;
  // The live node searched as its tracker planned; a different plan here
  // means the trackers' states differ (a hint heard at another moment).
  if (full != (msg.search_mode == marker_pixels_t::SEARCH_FULL_FRAME)) {
    status_.Count("search_mode_differs");
  }
  // A capped message lost markers no robot had taken (the robots' go first):
  // a full-frame search here sees fewer look-alikes than the live one did.
  if (msg.num_markers >= wire_cap::kMarkersPerFrame) status_.Count("capped_frames");
  std::vector<vision::Blob> blobs;
  blobs.reserve(msg.markers.size());
  for (const marker_t& m : msg.markers) {
    vision::Blob b;
    b.class_index = ClassIndex(setup_.classes, m.colour_class);
    if (b.class_index < 0) {
      status_.Reject("unknown_marker_class");
      continue;
    }
    // A recorded message is outside input: a centre or size that is not a
    // finite number would poison the track (and its window) for good.
    if (!std::isfinite(m.u_px) || !std::isfinite(m.v_px) || !std::isfinite(m.radius_px) ||
        !std::isfinite(m.circularity) || !std::isfinite(m.area_px)) {
      status_.Reject("non_finite_marker");
      continue;
    }
    b.u_px = m.u_px;
    b.v_px = m.v_px;
    b.radius_px = m.radius_px;
    b.circularity = m.circularity;
    b.area_px = m.area_px;
    blobs.push_back(b);
  }
  Track(msg.utime, plans, blobs, now_utime);
  if (calibration_) {
    // The frame's output here is its POSE_CAMERA set (live: MARKER_PIXELS).
    PublishPoses(msg.utime, msg.frame_seq, msg.processing_time_us);
    status_.AddOutputs();
  }
}

void CameraNode::Track(int64_t capture_utime, const std::vector<vision::SearchPlan>& plans,
                       const std::vector<vision::Blob>& blobs, int64_t now_utime) {
  // The tracker's lists from the frame's blobs: every blob for a full-frame
  // search; for robot i's window, the blobs of its two classes whose centre
  // lies in the window (a window's detection yields exactly those).
  bool full = false;
  for (const vision::SearchPlan& p : plans) full = full || p.full_frame;
  std::vector<vision::Blob> full_blobs;
  if (full) full_blobs = blobs;
  std::vector<std::vector<vision::Blob>> window_blobs(plans.size());
  for (size_t i = 0; i < plans.size(); ++i) {
    if (plans[i].full_frame || plans[i].window.empty()) continue;
    const vision::TrackedRobotSpec& spec = tracker_->robots()[i];
    const cv::Rect& r = plans[i].window;
    for (const vision::Blob& b : blobs) {
      if (!setup_.tracker.identify_by_code && b.class_index != spec.position_class &&
          b.class_index != spec.heading_class) {
        continue;
      }
      if (b.u_px >= r.x - 0.5 && b.u_px <= r.x + r.width - 0.5 && b.v_px >= r.y - 0.5 &&
          b.v_px <= r.y + r.height - 0.5) {
        window_blobs[i].push_back(b);
      }
    }
  }
  observations_ = tracker_->Update(capture_utime, plans, full_blobs, window_blobs);
  ++frames_processed_;
  status_.Count(full ? "full_searches" : "window_searches");
  // A line per robot when its state changes, so STATUS and the log say why
  // a robot is not tracked (ambiguous start-up, lost) without one per frame.
  last_states_.resize(observations_.size(), -1);
  for (size_t i = 0; i < observations_.size(); ++i) {
    const vision::RobotObservation& o = observations_[i];
    const int state = static_cast<int>(o.state);
    if (state != last_states_[i]) {
      const std::string note =
          std::string(vision::TrackStateName(o.state)) + (o.note.empty() ? "" : ": " + o.note);
      if (o.state == vision::TrackState::kAmbiguous || o.state == vision::TrackState::kLost) {
        status_.SetError("robot " + std::to_string(o.robot_id) + " " + note, now_utime);
        spdlog::warn("robot {} {}", o.robot_id, note);
      } else {
        spdlog::info("robot {} {}", o.robot_id, note);
      }
      last_states_[i] = state;
    }
    if (o.state == vision::TrackState::kAmbiguous) status_.Count("ambiguous_frames");
    // Identification doubts (marker code): each counted by its kind.
    if (!o.identity_problem.empty()) status_.Count(o.identity_problem);
    if (!o.found) status_.Count("robot_not_found");
  }
}

void CameraNode::MaybePublishPreview(const camera::Frame& frame) {
  if (!(options_.preview_hz > 0.0)) return;
  const int64_t period_us = static_cast<int64_t>(1e6 / options_.preview_hz);
  if (last_preview_utime_ != 0 && frame.capture_utime - last_preview_utime_ < period_us) return;
  last_preview_utime_ = frame.capture_utime;
  cv::Mat small;
  std::string error;
  if (!frame.image->DecodeReduced(4, &small, &error)) return;
  PreviewImage preview;
  preview.utime = frame.capture_utime;
  preview.camera_id = camera_.id;
  preview.frame_seq = frame.seq;
  preview.width_px = small.cols;
  preview.height_px = small.rows;
  preview.source_width_px = frame.image->width_px();
  preview.source_height_px = frame.image->height_px();
  preview.format = "jpeg";
  std::vector<uint8_t> bytes;
  if (!cv::imencode(".jpg", small, bytes, {cv::IMWRITE_JPEG_QUALITY, 70})) return;
  preview.data.assign(bytes.begin(), bytes.end());
  bus_->Publish(kCameraPreviewChannel, ToMessage(preview));
}

// The reasons cross the wire by their numbers.
static_assert(static_cast<int8_t>(vision::RobotViewReason::kFound) ==
              detector_view_robot_t::REASON_FOUND);
static_assert(static_cast<int8_t>(vision::RobotViewReason::kOutOfView) ==
              detector_view_robot_t::REASON_OUT_OF_VIEW);
static_assert(vision::kMaxRobotViewReason == detector_view_robot_t::REASON_NO_BLOB);

void CameraNode::PublishLowRateViews(const camera::Frame& frame, int64_t now_utime) {
  MaybePublishPreview(frame);
  MaybePublishDetectorView(frame, now_utime);
}

bool CameraNode::CheckDetectorViewRequest(const DetectorViewRequest& r, std::string* reason,
                                          std::string* error) const {
  if (r.camera_id < -1) {
    *reason = "detector_view_bad_camera";
    *error = "camera id " + std::to_string(r.camera_id) + " (-1 is every camera)";
    return false;
  }
  if (!std::isfinite(r.duration_s) || r.duration_s < 0.0 ||
      r.duration_s > options_.detector_view_max_duration_s) {
    *reason = "detector_view_bad_duration";
    *error = "duration " + std::to_string(r.duration_s) + " s outside [0, " +
             std::to_string(options_.detector_view_max_duration_s) + "]";
    return false;
  }
  // A stop (duration 0) needs no rate.
  if (r.duration_s > 0.0 && (!std::isfinite(r.rate_hz) || !(r.rate_hz > 0.0))) {
    *reason = "detector_view_bad_rate";
    *error = "rate " + std::to_string(r.rate_hz) + " Hz is not positive";
    return false;
  }
  // No region (0 x 0) is the whole frame; anything else lies inside it and
  // is big enough to show a marker.
  constexpr int kMinRegionPx = 16;
  const bool whole = r.region_width_px == 0 && r.region_height_px == 0;
  if (!whole &&
      (r.region_u_px < 0 || r.region_v_px < 0 || r.region_width_px < kMinRegionPx ||
       r.region_height_px < kMinRegionPx || r.region_width_px > camera_.width_px - r.region_u_px ||
       r.region_height_px > camera_.height_px - r.region_v_px)) {
    *reason = "detector_view_bad_region";
    *error = "region " + std::to_string(r.region_width_px) + "x" +
             std::to_string(r.region_height_px) + " at (" + std::to_string(r.region_u_px) + ", " +
             std::to_string(r.region_v_px) + ") does not lie within the " +
             std::to_string(camera_.width_px) + "x" + std::to_string(camera_.height_px) +
             " frame (or is under " + std::to_string(kMinRegionPx) + " px)";
    return false;
  }
  return true;
}

void CameraNode::OnDetectorViewRequest(const detector_view_request_t& msg,
                                       const MessageInfo& info) {
  const DetectorViewRequest r = FromMessage(msg);
  // Another camera's request is ordinary traffic on a shared channel.
  if (r.camera_id >= 0 && r.camera_id != camera_.id) {
    status_.Count("detector_view_other_camera");
    return;
  }
  std::string reason, error;
  if (!UtimeNear(r.utime, info.recv_utime)) {
    reason = "utime_out_of_range";
    error = "its utime is far from the clock";
  } else if (CheckDetectorViewRequest(r, &reason, &error)) {
    status_.Count("detector_view_requests");
    detector_view_until_utime_ = info.recv_utime + static_cast<int64_t>(r.duration_s * 1e6);
    detector_view_request_hz_ = std::min(r.rate_hz, options_.detector_view_max_hz);
    detector_view_region_ =
        cv::Rect(r.region_u_px, r.region_v_px, r.region_width_px, r.region_height_px);
    last_detector_view_utime_ = 0;  // the first view with the next frame
    return;
  }
  status_.Reject(reason);
  status_.SetError("detector view request refused: " + error, info.recv_utime);
}

void CameraNode::MaybePublishDetectorView(const camera::Frame& frame, int64_t now_utime) {
  const bool asked = now_utime < detector_view_until_utime_;
  const double hz = std::max(options_.detector_view_hz, asked ? detector_view_request_hz_ : 0.0);
  if (!(hz > 0.0)) return;
  const int64_t period_us = static_cast<int64_t>(1e6 / hz);
  if (last_detector_view_utime_ != 0 &&
      frame.capture_utime - last_detector_view_utime_ < period_us) {
    return;
  }
  last_detector_view_utime_ = frame.capture_utime;
  camera::FrameImage* image = frame.image.get();
  vision::DetectorViewInput in;
  in.source_size = cv::Size(image->width_px(), image->height_px());
  in.region_px = asked && !detector_view_region_.empty()
                     ? detector_view_region_
                     : cv::Rect(cv::Point(0, 0), in.source_size);
  in.scale = 1;
  while (in.scale < 8 && in.region_px.width > options_.detector_view_max_width_px * in.scale) {
    in.scale *= 2;
  }
  std::string error;
  const bool whole = in.region_px.size() == in.source_size;
  cv::Mat pixels;
  if (whole ? !image->DecodeReduced(in.scale, &in.bgr, &error)
            : !image->DecodeRegion(in.region_px, &pixels, &error)) {
    status_.Count("detector_view_undecodable");
    return;
  }
  if (!whole) {
    cv::resize(pixels, in.bgr, cv::Size(), 1.0 / in.scale, 1.0 / in.scale, cv::INTER_AREA);
  }
  in.robots = setup_.robots;
  in.tracker = setup_.tracker;
  // A hint another sensor gave within the tracker's own hint age says where
  // a robot should be: beyond the view, it is out of view, not discoloured.
  for (const auto& [id, hint] : hint_px_) {
    if (std::abs(frame.capture_utime - hint.utime) <= setup_.tracker.hint_max_age_s * 1e6) {
      in.expected_px[id] = cv::Point2d(hint.u_px, hint.v_px);
    }
  }
  const vision::DetectorView view = vision::RenderDetectorView(*detector_, in);
  DetectorViewImage msg;
  msg.utime = frame.capture_utime;
  msg.camera_id = camera_.id;
  msg.frame_seq = frame.seq;
  msg.width_px = view.bgr.cols;
  msg.height_px = view.bgr.rows;
  msg.source_width_px = in.source_size.width;
  msg.source_height_px = in.source_size.height;
  msg.region_u_px = in.region_px.x;
  msg.region_v_px = in.region_px.y;
  msg.region_width_px = in.region_px.width;
  msg.region_height_px = in.region_px.height;
  msg.scale = in.scale;
  msg.format = "png";
  if (!cv::imencode(".png", view.bgr, msg.data) ||
      msg.data.size() > static_cast<size_t>(wire_cap::kDetectorViewBytes)) {
    status_.Count("detector_view_not_encoded");
    return;
  }
  for (const vision::RobotDiagnosis& d : view.robots) {
    DetectorViewRobot r;
    r.robot_id = d.robot_id;
    r.reason = static_cast<int8_t>(d.reason);
    if (d.class_index >= 0) r.colour_class = setup_.classes[d.class_index].name;
    r.value = d.value;
    r.limit = d.limit;
    r.text = d.text.substr(0, wire_cap::kDetectorViewTextBytes - 1);
    msg.robots.push_back(r);
  }
  if (bus_->Publish(kDetectorViewChannel, ToMessage(msg))) status_.Count("detector_views");
}

bool CameraNode::MapMarker(const vision::Blob& blob, double radius_m, double height_m, double* x_m,
                           double* y_m) const {
  if (calibration_->model == calib::Calibration::Model::kFull && options_.correct_disc_centroid) {
    return calib::DiscCentroidToFloor(calibration_->camera, blob.u_px, blob.v_px, radius_m,
                                      height_m, x_m, y_m);
  }
  std::string error;
  return calibration_->PixelToFloor(blob.u_px, blob.v_px, height_m, x_m, y_m, &error);
}

void CameraNode::ObserveCaptureTime(int64_t capture_utime, int64_t frame_seq) {
  if (last_capture_seq_ >= 0 && frame_seq == last_capture_seq_ + 1 &&
      capture_utime > last_capture_utime_) {
    // Exponential averages over about 100 frames: long enough to make the
    // spread stable, short enough to follow a camera that changes its rate.
    const double d = static_cast<double>(capture_utime - last_capture_utime_);
    const double alpha = intervals_ < 100 ? 1.0 / static_cast<double>(intervals_ + 1) : 0.01;
    const double delta = d - interval_mean_us_;
    interval_mean_us_ += alpha * delta;
    interval_var_us2_ = (1.0 - alpha) * (interval_var_us2_ + alpha * delta * delta);
    ++intervals_;
  }
  last_capture_seq_ = frame_seq;
  last_capture_utime_ = capture_utime;
}

double CameraNode::TimingSigmaS() const {
  if (intervals_ < 10) return 0.0;
  // An interval is the difference of two independent jitters: var / 2 each.
  // Rounded to 0.1 ms, finer than 100 intervals resolve: the stamps' own
  // microsecond rounding (a fraction of a microsecond) is then no jitter,
  // and an ideal camera's covariance stays exactly sigma_px^2 J J^T.
  const double sigma_us = std::sqrt(interval_var_us2_ / 2.0);
  return std::round(sigma_us / 100.0) * 100.0 * 1e-6;
}

Eigen::Vector2d CameraNode::Velocity(size_t robot) const {
  if (robot >= recent_poses_.size() || recent_poses_[robot].size() < 2) {
    return Eigen::Vector2d::Zero();
  }
  const PoseSample& a = recent_poses_[robot].front();
  const PoseSample& b = recent_poses_[robot].back();
  const double dt_s = static_cast<double>(b.utime - a.utime) * 1e-6;
  // Over less than a third of the span the centroid noise dominates.
  if (!(dt_s >= options_.velocity_span_s / 3.0)) return Eigen::Vector2d::Zero();
  return Eigen::Vector2d((b.x_m - a.x_m) / dt_s, (b.y_m - a.y_m) / dt_s);
}

void CameraNode::PublishPoses(int64_t capture_utime, int64_t frame_seq, int64_t latency_us) {
  // A recorded processing time is a log's word (OnMarkerPixels): never a
  // negative latency on the bus.
  latency_us = std::max<int64_t>(latency_us, 0);
  ObserveCaptureTime(capture_utime, frame_seq);
  recent_poses_.resize(observations_.size());
  const double timing_sigma_s = TimingSigmaS();
  for (size_t i = 0; i < observations_.size(); ++i) {
    const vision::RobotObservation& o = observations_[i];
    const double height_m = setup_.marker_height_m[i];
    Pose2d p;
    p.utime = capture_utime;
    p.source = PoseSource::kCamera;
    p.camera_id = camera_.id;
    p.robot_id = o.robot_id;
    p.measurement_seq = frame_seq;
    p.z_m = height_m;
    p.x_m = p.y_m = p.heading_rad = kNaN;
    for (auto& row : p.covariance) {
      for (double& c : row) c = kNaN;
    }
    p.status = PoseStatus::kLost;
    double x = 0, y = 0;
    std::string error;
    if (o.found && MapMarker(o.position, setup_.position_radius_m[i], height_m, &x, &y)) {
      // The pose's time is the position marker's own: the middle of the
      // exposure of its centroid's row (calib/camera_timing.h).
      p.utime = calib::RowMidExposureUtime(timing_, capture_utime, o.position.v_px);
      p.x_m = x;
      p.y_m = y;
      p.num_measurements = 1;
      const Eigen::Vector2d velocity = Velocity(i);
      // Covariance (calib/pose_covariance.h): the calibration's measured
      // pixel noise through the mapping's Jacobian J = d(x, y)/d(u, v) (by
      // central differences), plus the streak, the timestamp jitter and the
      // robot's tilt. sigma_px is the calibration's figure for this robot's
      // markers (robot_pixel_sigma_px, measured on its own markers), else its
      // pixel_sigma_px (the fit's centroid noise plus its own model error,
      // calibration_file.h), else the assumed centroid_sigma_px.
      const double h_px = 0.5;
      double xu0, yu0, xu1, yu1, xv0, yv0, xv1, yv1;
      const bool jac = calibration_->PixelToFloor(o.position.u_px - h_px, o.position.v_px, height_m,
                                                  &xu0, &yu0, &error) &&
                       calibration_->PixelToFloor(o.position.u_px + h_px, o.position.v_px, height_m,
                                                  &xu1, &yu1, &error) &&
                       calibration_->PixelToFloor(o.position.u_px, o.position.v_px - h_px, height_m,
                                                  &xv0, &yv0, &error) &&
                       calibration_->PixelToFloor(o.position.u_px, o.position.v_px + h_px, height_m,
                                                  &xv1, &yv1, &error);
      calib::PoseNoiseInputs noise;
      if (jac) {
        noise.floor_per_px << (xu1 - xu0) / (2 * h_px), (xv1 - xv0) / (2 * h_px),
            (yu1 - yu0) / (2 * h_px), (yv1 - yv0) / (2 * h_px);
      }
      const double robot_sigma_px = calibration_->PixelSigmaFor(camera_.robots[i].robot_id);
      noise.pixel_sigma_px = robot_sigma_px > 0.0 ? robot_sigma_px : options_.centroid_sigma_px;
      noise.velocity_mps = velocity;
      noise.exposure_s = timing_.exposure_s;
      noise.blur_sigma_fraction = options_.blur_sigma_fraction;
      noise.timing_sigma_s = timing_sigma_s;
      noise.marker_height_m = height_m;
      noise.tilt_sigma_rad = camera_.robots[i].tilt_sigma_deg * M_PI / 180.0;
      const Eigen::Matrix2d cov = calib::PositionCovariance(noise);
      for (int r = 0; r < 2; ++r) {
        for (int c = 0; c < 2; ++c) p.covariance[r][c] = cov(r, c);
      }
      p.status = PoseStatus::kDegraded;
      double hx = 0, hy = 0;
      if (o.has_heading && MapMarker(o.heading, setup_.heading_radius_m[i], height_m, &hx, &hy)) {
        // Under a rolling shutter the heading marker was seen at its own
        // row's time: moved to the position marker's time along the
        // velocity (1.4 ms for 50 rows of a 30 ms readout, 0.3 mm at 20 cm/s).
        const int64_t head_utime =
            calib::RowMidExposureUtime(timing_, capture_utime, o.heading.v_px);
        if (head_utime != p.utime) {
          const double shift_s = static_cast<double>(p.utime - head_utime) * 1e-6;
          hx += velocity.x() * shift_s;
          hy += velocity.y() * shift_s;
        }
        const double dx = hx - x, dy = hy - y;
        const double d2 = dx * dx + dy * dy;
        if (d2 > 1e-6) {
          p.heading_rad = std::atan2(dy, dx);
          p.num_measurements = 2;
          p.status = PoseStatus::kOk;
          // Both centroids move by about sigma * |J| each, perpendicular to
          // the baseline: var(heading) = 2 sigma_m^2 / d^2, from the errors
          // that differ between the two markers (not the tilt, not the time).
          const double sigma_m2 = calib::MarkerRelativeCovariance(noise).trace() / 2.0;
          p.covariance[2][2] = 2.0 * sigma_m2 / d2;
          p.covariance[0][2] = p.covariance[2][0] = 0.0;
          p.covariance[1][2] = p.covariance[2][1] = 0.0;
        }
      }
      p.residual_m = 0.0;
      std::deque<PoseSample>& recent = recent_poses_[i];
      recent.push_back({p.utime, x, y});
      while (recent.size() > 2 && static_cast<double>(p.utime - recent.front().utime) * 1e-6 >
                                      options_.velocity_span_s) {
        recent.pop_front();
      }
    } else {
      recent_poses_[i].clear();
    }
    p.latency_us = latency_us;
    if (bus_->Publish(kCameraPoseChannel, ToMessage(p))) status_.Count("poses");
  }
}

void CameraNode::OnBadFrame(const std::string& reason, const std::string& error,
                            int64_t now_utime) {
  status_.Reject(reason);
  ++bad_since_last_;
  status_.SetError(error, now_utime);
  spdlog::warn("{}", error);
}

void CameraNode::OnSourceUp(const std::string& description, const std::vector<std::string>& refused,
                            int64_t now_utime) {
  status_.SetState(process_status_t::STATE_RUNNING);
  for (const std::string& r : refused) {
    status_.Count("refused_properties");
    status_.SetError("camera refused " + r, now_utime);
    spdlog::warn("camera refused {}", r);
  }
  spdlog::info("reading {}", description);
  status_.Publish(bus_, now_utime);
}

void CameraNode::OnSourceDown(const std::string& error, int64_t now_utime) {
  status_.SetState(process_status_t::STATE_DEGRADED);
  status_.Count("source_lost");
  status_.SetError(error, now_utime);
  status_.Publish(bus_, now_utime);
}

void CameraNode::OnSetupProblem(const std::string& counter, const std::string& error,
                                int64_t now_utime) {
  status_.Count(counter);
  status_.SetError(error, now_utime);
}

void CameraNode::OnEndOfStream(int64_t now_utime) {
  spdlog::info("end of the frame source after {} frames", frames_processed_);
  status_.Publish(bus_, now_utime);
}

void CameraNode::Tick(int64_t now_utime) { status_.MaybePublish(bus_, now_utime); }

void CameraNode::Stop(int64_t now_utime) {
  status_.SetState(process_status_t::STATE_STOPPING);
  status_.Publish(bus_, now_utime);
}

}  // namespace roomfix
