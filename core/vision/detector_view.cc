#include "core/vision/detector_view.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>

namespace roomfix::vision {
namespace {

// The tracker's clock for its one frame: any time works (a fresh tracker
// plans a full-frame search for every robot), but not 0, its "never".
constexpr int64_t kViewUtime = 1'000'000;
// The dimmed frame keeps this fraction of its grey level, so the painted
// masks and the labels stand out while the scene stays recognisable.
constexpr double kDimFactor = 0.45;
const cv::Scalar kFoundBgr(255, 255, 255);
const cv::Scalar kRejectedBgr(60, 60, 255);
const cv::Scalar kTextShadowBgr(0, 0, 0);

// Text with a one-pixel dark shadow: readable on any mask colour.
void Label(cv::Mat* image, const std::string& text, cv::Point at, const cv::Scalar& colour) {
  constexpr double kFontScale = 0.35;
  cv::putText(*image, text, at + cv::Point(1, 1), cv::FONT_HERSHEY_SIMPLEX, kFontScale,
              kTextShadowBgr, 1, cv::LINE_AA);
  cv::putText(*image, text, at, cv::FONT_HERSHEY_SIMPLEX, kFontScale, colour, 1, cv::LINE_AA);
}

// Full-resolution pixel to the view image's pixel.
cv::Point2d ToView(const DetectorViewInput& in, double u_px, double v_px) {
  const double s = std::max(1, in.scale);
  return {(u_px - in.region_px.x + 0.5) / s - 0.5, (v_px - in.region_px.y + 0.5) / s - 0.5};
}

cv::Mat DimmedGrey(const cv::Mat& bgr) {
  cv::Mat grey, out;
  cv::cvtColor(bgr, grey, cv::COLOR_BGR2GRAY);
  grey.convertTo(grey, CV_8U, kDimFactor);
  cv::cvtColor(grey, out, cv::COLOR_GRAY2BGR);
  return out;
}

void PaintMasks(const std::vector<ColourClass>& classes, const DetectorDiagnostics& diagnostics,
                cv::Mat* out) {
  for (size_t k = 0; k < classes.size() && k < diagnostics.class_masks.size(); ++k) {
    const cv::Mat& mask = diagnostics.class_masks[k];
    if (mask.empty() || mask.size() != out->size()) continue;
    out->setTo(cv::Scalar(ClassPaintBgr(classes[k])), mask);
  }
}

void DrawBlobs(const DetectorViewInput& in, const std::vector<ColourClass>& classes,
               const DetectorView& view, cv::Mat* out) {
  const double s = std::max(1, in.scale);
  for (const Blob& b : view.blobs) {
    const cv::Point2d c = ToView(in, b.u_px, b.v_px);
    // Outside the marker's rim, so the mask's colour at its centre and edge
    // stays what the detector classified.
    const int r = static_cast<int>(std::lround(1.3 * b.radius_px / s + 2.0));
    cv::circle(*out, c, r, kFoundBgr, 1, cv::LINE_AA);
    Label(out, classes[b.class_index].name + " " + std::to_string(std::lround(b.area_px)),
          cv::Point(static_cast<int>(c.x) + r + 2, static_cast<int>(c.y) + 3), kFoundBgr);
  }
  for (const RejectedBlob& b : view.diagnostics.rejected) {
    const cv::Point2d c = ToView(in, b.u_px, b.v_px);
    cv::drawMarker(*out, c, kRejectedBgr, cv::MARKER_TILTED_CROSS, 7, 1);
    Label(out,
          classes[b.class_index].name + " " + BlobRejectName(b.reason) + " " +
              std::to_string(std::lround(b.area_px)),
          cv::Point(static_cast<int>(c.x) + 5, static_cast<int>(c.y) + 3), kRejectedBgr);
  }
}

// Why class k gave robot `spec` no blob: no pixels, or the dropped
// component most like a marker (the nearest to where the robot is
// expected, else the largest) and the limit it broke.
RobotDiagnosis ClassProblem(const MarkerDetector& detector, const DetectorView& view, int k,
                            const cv::Point2d* expected) {
  RobotDiagnosis d;
  d.class_index = k;
  const ColourClass& cls = detector.classes()[k];
  if (!(view.diagnostics.class_area_px[k] > 0.0)) {
    d.reason = RobotViewReason::kNoPixels;
    d.text = "no pixels of class " + cls.name;
    return d;
  }
  const RejectedBlob* best = nullptr;
  for (const RejectedBlob& r : view.diagnostics.rejected) {
    if (r.class_index != k || r.reason == BlobReject::kUnmeasurable) continue;
    const bool better =
        best == nullptr ||
        (expected != nullptr ? std::hypot(r.u_px - expected->x, r.v_px - expected->y) <
                                   std::hypot(best->u_px - expected->x, best->v_px - expected->y)
                             : r.area_px > best->area_px);
    if (better) best = &r;
  }
  if (best == nullptr) {
    d.reason = RobotViewReason::kNoBlob;
    d.value = view.diagnostics.class_area_px[k];
    d.text = "pixels of class " + cls.name + " but no measurable blob (" +
             std::to_string(std::lround(d.value)) + " px in all)";
    return d;
  }
  const std::string blob = "blob of class " + cls.name;
  switch (best->reason) {
    case BlobReject::kTooSmall:
      d.reason = RobotViewReason::kTooSmall;
      d.value = best->area_px;
      d.limit = cls.min_area_px;
      d.text = blob + fmt::format(" too small (area {:.0f} px vs min {:.0f} px)", d.value, d.limit);
      break;
    case BlobReject::kTooLarge:
      d.reason = RobotViewReason::kTooLarge;
      d.value = best->area_px;
      d.limit = cls.max_area_px;
      d.text = blob + fmt::format(" too large (area {:.0f} px vs max {:.0f} px)", d.value, d.limit);
      break;
    default:
      d.reason = RobotViewReason::kNotRound;
      d.value = best->circularity;
      d.limit = cls.min_circularity;
      d.text = blob + fmt::format(" not round enough (circularity {:.2f} vs min {:.2f})", d.value,
                                  d.limit);
      break;
  }
  return d;
}

RobotDiagnosis Diagnose(const MarkerDetector& detector, const DetectorViewInput& in,
                        const DetectorView& view, const TrackedRobotSpec& spec,
                        const RobotObservation& obs) {
  RobotDiagnosis d;
  const auto hint = in.expected_px.find(spec.robot_id);
  const cv::Point2d* expected = hint == in.expected_px.end() ? nullptr : &hint->second;
  if (obs.found) {
    d.reason = RobotViewReason::kFound;
    d.text = fmt::format("found at ({:.1f}, {:.1f}) px", obs.position.u_px, obs.position.v_px);
  } else if (obs.state == TrackState::kAmbiguous || obs.identity_problem == "code_seen_twice" ||
             obs.identity_problem == "interleaved_markers" ||
             obs.identity_problem == "too_many_blobs") {
    d.reason = RobotViewReason::kAmbiguous;
    d.text = "ambiguous: " + obs.note;
  } else if (obs.identity_problem == "marker_clipped") {
    d.reason = RobotViewReason::kOutOfView;
    d.text = "out of view: its markers are cut by the edge (" + obs.note + ")";
  } else if (expected != nullptr &&
             !cv::Rect2d(-0.5, -0.5, in.source_size.width, in.source_size.height)
                  .contains(*expected)) {
    d.reason = RobotViewReason::kOutOfView;
    d.text = fmt::format("out of the calibrated view (expected at {:.0f}, {:.0f} px)", expected->x,
                         expected->y);
  } else if (expected != nullptr && !cv::Rect2d(in.region_px.x - 0.5, in.region_px.y - 0.5,
                                                in.region_px.width, in.region_px.height)
                                         .contains(*expected)) {
    d.reason = RobotViewReason::kOutOfView;
    d.text = fmt::format("outside the region looked at (expected at {:.0f}, {:.0f} px)",
                         expected->x, expected->y);
  } else {
    for (const int k : {spec.position_class, spec.heading_class}) {
      // A spec naming no class of the detector (never from MakeCameraSetup)
      // has nothing to diagnose by colour.
      if (k < 0 || k >= static_cast<int>(detector.classes().size())) continue;
      const bool has_blob = std::any_of(view.blobs.begin(), view.blobs.end(),
                                        [k](const Blob& b) { return b.class_index == k; });
      if (!has_blob) {
        d = ClassProblem(detector, view, k, expected);
        break;
      }
    }
    if (d.class_index < 0) {
      d.reason = RobotViewReason::kNotPaired;
      d.text = "markers seen but not paired" + (obs.note.empty() ? "" : ": " + obs.note);
    }
  }
  d.robot_id = spec.robot_id;
  d.text = "robot " + std::to_string(spec.robot_id) + ": " + d.text;
  return d;
}

// The tracker's one full-frame search on the region, in the region's own
// coordinates so that a marker cut by the region's edge counts as clipped.
std::vector<RobotObservation> TrackOnce(const DetectorViewInput& in,
                                        const std::vector<Blob>& blobs) {
  RobotTracker tracker(in.robots, in.tracker, in.region_px.width, in.region_px.height);
  std::vector<Blob> local = blobs;
  for (Blob& b : local) {
    b.u_px -= in.region_px.x;
    b.v_px -= in.region_px.y;
  }
  std::vector<RobotObservation> obs =
      tracker.Update(kViewUtime, tracker.Plan(kViewUtime), local, {});
  for (RobotObservation& o : obs) {
    for (Blob* b : {&o.position, &o.heading}) {
      b->u_px += in.region_px.x;
      b->v_px += in.region_px.y;
    }
  }
  return obs;
}

}  // namespace

const char* RobotViewReasonName(RobotViewReason reason) {
  switch (reason) {
    case RobotViewReason::kFound:
      return "found";
    case RobotViewReason::kNoPixels:
      return "no_pixels";
    case RobotViewReason::kTooSmall:
      return "too_small";
    case RobotViewReason::kTooLarge:
      return "too_large";
    case RobotViewReason::kNotRound:
      return "not_round";
    case RobotViewReason::kAmbiguous:
      return "ambiguous";
    case RobotViewReason::kOutOfView:
      return "out_of_view";
    case RobotViewReason::kNotPaired:
      return "not_paired";
    case RobotViewReason::kNoBlob:
      return "no_blob";
  }
  return "unknown";
}

cv::Vec3b ClassPaintBgr(const ColourClass& c) {
  int h = (c.hsv_min[0] + c.hsv_max[0]) / 2;
  if (c.hsv_min[0] > c.hsv_max[0]) h = ((c.hsv_min[0] + c.hsv_max[0] + 180) / 2) % 180;
  cv::Mat3b hsv(1, 1, cv::Vec3b(static_cast<uchar>(h), 230, 240)), bgr;
  cv::cvtColor(hsv, bgr, cv::COLOR_HSV2BGR);
  return bgr(0, 0);
}

DetectorView RenderDetectorView(const MarkerDetector& detector, const DetectorViewInput& input) {
  DetectorView view;
  if (input.bgr.empty() || input.bgr.type() != CV_8UC3) return view;
  DetectorViewInput in = input;  // shares the pixels
  in.scale = std::max(1, in.scale);
  if (in.region_px.empty())
    in.region_px = cv::Rect(0, 0, in.bgr.cols * in.scale, in.bgr.rows * in.scale);
  if (in.source_size.empty()) in.source_size = in.region_px.size();
  ImageWindow window;
  window.offset_u_px = in.region_px.x;
  window.offset_v_px = in.region_px.y;
  window.scale = std::max(1, in.scale);
  view.blobs = detector.Detect(in.bgr, window, {}, &view.diagnostics);
  view.bgr = DimmedGrey(in.bgr);
  PaintMasks(detector.classes(), view.diagnostics, &view.bgr);
  DrawBlobs(in, detector.classes(), view, &view.bgr);

  const std::vector<RobotObservation> obs = TrackOnce(in, view.blobs);
  for (size_t i = 0; i < in.robots.size() && i < obs.size(); ++i) {
    view.robots.push_back(Diagnose(detector, in, view, in.robots[i], obs[i]));
    if (!obs[i].found) continue;
    const cv::Point2d c = ToView(in, obs[i].position.u_px, obs[i].position.v_px);
    // Left of the position marker: its blob's label is on the right.
    const int r = static_cast<int>(std::lround(1.3 * obs[i].position.radius_px / in.scale + 2.0));
    Label(&view.bgr, "R" + std::to_string(in.robots[i].robot_id),
          cv::Point(static_cast<int>(c.x) - r - 18, static_cast<int>(c.y) + 3), kFoundBgr);
  }
  if (in.list_reasons && !view.robots.empty()) {
    int y = view.bgr.rows - 6 - 12 * static_cast<int>(view.robots.size() - 1);
    for (const RobotDiagnosis& d : view.robots) {
      Label(&view.bgr, d.text, cv::Point(4, y),
            d.reason == RobotViewReason::kFound ? kFoundBgr : kRejectedBgr);
      y += 12;
    }
  }
  return view;
}

}  // namespace roomfix::vision
