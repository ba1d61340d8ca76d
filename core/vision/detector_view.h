#ifndef ROOMFIX_CORE_VISION_DETECTOR_VIEW_H_
#define ROOMFIX_CORE_VISION_DETECTOR_VIEW_H_

#include <map>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "core/vision/marker_detector.h"
#include "core/vision/robot_tracker.h"

namespace roomfix::vision {

// Why a robot is or is not found in one frame, as the "what the detector
// sees" view states it (docs/camera.md). The numbers are the wire codes of
// detector_view_t.reason: never renumber.
enum class RobotViewReason {
  kFound = 0,
  kNoPixels = 1,   // no pixel of one of its classes (colour range, light)
  kTooSmall = 2,   // its class has blobs, all under the class's min area
  kTooLarge = 3,   // ... over its max area
  kNotRound = 4,   // ... under its min circularity
  kAmbiguous = 5,  // several candidates, its code seen twice, too many blobs
  kOutOfView = 6,  // expected outside the view, or its markers cut by its edge
  kNotPaired = 7,  // both classes have blobs, but no pair makes this robot
  kNoBlob = 8,     // its class has pixels but no component could be measured
};
inline constexpr int kMaxRobotViewReason = 8;
// "found", "no_pixels", "too_small", "too_large", "not_round", "ambiguous",
// "out_of_view", "not_paired", "no_blob".
const char* RobotViewReasonName(RobotViewReason reason);

struct RobotDiagnosis {
  int robot_id = 0;
  RobotViewReason reason = RobotViewReason::kNoPixels;
  // The class the reason is about (-1 when none): its name, the offending
  // blob's area or circularity and the class's limit it broke.
  int class_index = -1;
  double value = 0.0;
  double limit = 0.0;
  // One line for people: "no pixels of class orange", "blob of class orange
  // too small (area 40 px vs min 120 px)", ...
  std::string text;
};

struct DetectorViewInput {
  // The pixels looked at: the full-resolution rectangle `region_px` of the
  // frame, reduced by `scale` (1, 2, 4 or 8), BGR.
  cv::Mat bgr;
  cv::Rect region_px;
  int scale = 1;
  // The camera's robots and the tracker's options (the camera's setup): the
  // diagnosis runs a fresh tracker's full-frame search on this image, so it
  // is what a robot acquisition would decide, not a windowed track's.
  std::vector<TrackedRobotSpec> robots;
  TrackerOptions tracker;
  // Where another sensor expects a robot (robot id -> full-resolution
  // pixel; absent: unknown). A robot not found whose expected pixel lies
  // outside the calibrated image (`source_size`) or outside region_px is
  // out of view rather than missing its colours.
  std::map<int, cv::Point2d> expected_px;
  cv::Size source_size;
  // Also write each robot's line into the image (the CLI's overlay).
  bool list_reasons = false;
};

struct DetectorView {
  cv::Mat bgr;  // the overlay, the size of the input image
  std::vector<Blob> blobs;
  DetectorDiagnostics diagnostics;
  std::vector<RobotDiagnosis> robots;  // in the order of input.robots
};

// The colour a class's mask is painted in: the middle of its hue range,
// saturated and bright, whatever its S and V ranges (a class of dark
// colours is still visible on the dimmed frame).
cv::Vec3b ClassPaintBgr(const ColourClass& colour_class);

// Runs `detector` (with diagnostics: exactly what Detect does) on the input
// and renders what it saw: the frame dimmed to grey, each class's mask in
// its paint colour, found blobs circled and labelled with class and area
// (full-resolution px), dropped components crossed and labelled with why,
// robots found labelled with their id; plus a diagnosis per robot.
// Nothing but the image for an empty or non-BGR input (no robots listed).
DetectorView RenderDetectorView(const MarkerDetector& detector, const DetectorViewInput& input);

}  // namespace roomfix::vision

#endif  // ROOMFIX_CORE_VISION_DETECTOR_VIEW_H_
