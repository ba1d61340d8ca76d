#ifndef ROOMFIX_CORE_VISION_COLOUR_LEARNING_H_
#define ROOMFIX_CORE_VISION_COLOUR_LEARNING_H_

// Colour classes learned from a camera's own frames (docs/camera.md,
// "Colours from frames"): find the marker discs by shape and saturation,
// cluster their colours, and size each class's HSV box from the measured
// spread plus the drift a webcam's white balance, exposure and wear cause.
// Pure: frames in, boxes and figures out; no files, no camera.

#include <array>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "core/vision/marker_detector.h"
#include "core/world/site.h"

namespace roomfix::vision {

struct ColourLearningOptions {
  // The detector's colour space: with kNormalised/kAdaptive every pixel is
  // scaled by background_v_ref / (local floor V) before its class is looked
  // up (NormaliseIllumination), so boxes are learned on the same scaled
  // pixels or their V bounds would be wrong by the floor's brightness.
  LightingMode lighting = LightingMode::kAdaptive;
  double background_v_ref = 128.0;
  // Disc radii the search accepts, full-resolution pixels.
  double min_radius_px = 3.0;
  double max_radius_px = 120.0;
  // A pixel is a marker candidate above this saturation (OpenCV S, 0..255)
  // and above the floor's own: max(min_saturation, floor median + 3 sigma +
  // 15). The demo floor is S 23, a dark robot body 0, markers 130 and more.
  double min_saturation = 50.0;
  // Below this V (after normalisation) a pixel's hue is noise.
  double min_value = 25.0;
  // Drift the boxes must survive (docs/camera.md, "Colours a webcam keeps
  // apart"): the red and blue gains moving +-white_balance_drift in
  // opposition (auto white balance hunting between daylight and lamps),
  // brightness that normalisation does not remove (+-exposure_drift:
  // a floor clipped at 255, a marker's sheen), and markers keeping
  // 1 - saturation_loss of their saturation as they wear.
  double white_balance_drift = 0.12;
  double exposure_drift = 0.3;
  double saturation_loss = 0.25;
  // Pixel spread margin: the box holds the class's core pixels from the
  // spread_quantile to 1 - spread_quantile, widened by the drift.
  double spread_quantile = 0.005;
  // Two discs share a class when their core colours are within these
  // (hue units of 2 degrees; saturation units; V as a ratio).
  double cluster_hue = 8.0;
  double cluster_saturation = 70.0;
  double cluster_value_ratio = 1.8;
  // A box the background (every pixel away from the discs: floor, robot
  // bodies, lines) falls into by more than this share is refused.
  double max_background_share = 2e-4;

  bool IsValid(std::string* error) const;
};

// One marker disc found by shape and saturation.
struct FoundDisc {
  int frame = 0;
  double u_px = 0.0;
  double v_px = 0.0;
  double radius_px = 0.0;
  // Median OpenCV HSV of the disc's core (inner 60 % of its radius), on the
  // normalised image.
  std::array<double, 3> core_hsv{};
  // Cut by the image's edge: reported, never learned from.
  bool clipped = false;
  // The cluster it joined (ColourLearning::classes index), -1 if none.
  int cluster = -1;
  // A known marker's name (LabelDiscs), empty when not labelled.
  std::string label;
};

// A marker at a known place in a frame: a tripod or a parked robot's
// marker projected through the calibration, or a labelled photo.
struct KnownMarker {
  int frame = 0;
  double u_px = 0.0;
  double v_px = 0.0;
  // The nearest disc within this distance, and at least min_distance_px
  // away, takes the name (a heading marker is the disc near a robot's
  // position marker that is not the position marker itself).
  double reach_px = 10.0;
  double min_distance_px = 0.0;
  std::string class_name;
};

// One proposed class and how safe it is.
struct LearnedClass {
  std::string name;  // from labels or the site's boxes; "colour_N" otherwise
  std::array<int, 3> hsv_min{};
  std::array<int, 3> hsv_max{};
  std::array<double, 3> median_hsv{};
  int discs = 0;
  int core_pixels = 0;
  // The radii of its discs: the detector's area limits (ToColourClasses).
  double min_radius_px = 0.0;
  double max_radius_px = 0.0;
  // Share of this class's own core pixels outside its box (they would be
  // lost) and inside another class's box (they would be confused).
  double own_outside_share = 0.0;
  double own_in_neighbour_share = 0.0;
  // The nearest other class: how far this class's pixels (their spread
  // quantiles) lie from its box on the channel that parts them best (HSV
  // units, hue on its circle), and how far the drift budget moves this
  // colour on that channel. A gap below the drift is fragile.
  std::string nearest_neighbour;
  std::string neighbour_channel;  // "hue", "saturation" or "value"
  double neighbour_gap_hsv = 0.0;
  double neighbour_drift_hsv = 0.0;
  // Background pixels inside the box (share of all background pixels), and
  // the background's distance to the box (the 1/10000 quantile of each
  // pixel's largest per-channel distance, HSV units).
  double background_share = 0.0;
  double background_gap_hsv = 0.0;
  // The hue shift the white-balance budget causes for this colour.
  double white_balance_hue_shift = 0.0;
  // Why it is fragile (a margin below its drift), empty when it is not.
  std::string fragile;
};

struct ColourLearning {
  std::vector<FoundDisc> discs;
  std::vector<LearnedClass> classes;
  int frames = 0;
  int64_t background_pixels = 0;
  // Why no classes could be proposed, empty on success.
  std::string refusal;
};

// Every marker disc in the frames (BGR, CV_8UC3, any size): saturated,
// hole-filled regions, split into discs at their distance transform's
// maxima; a disc is kept when its core colour is coherent and its
// surroundings of the same colour are few (a bar or a body is not a disc).
std::vector<FoundDisc> FindDiscs(const std::vector<cv::Mat>& frames,
                                 const ColourLearningOptions& options);

// Learns classes from `frames`. Known markers label the clusters they fall
// in (two names in one cluster refuse); a cluster with no label takes the
// name of the one `site_classes` box its median lies in, else "colour_N".
// Refuses (ColourLearning::refusal) with no disc, with one colour only
// when min_classes > 1, with two clusters whose colours overlap, or with a
// box the background cannot be kept out of.
ColourLearning LearnColours(const std::vector<cv::Mat>& frames,
                            const std::vector<KnownMarker>& known,
                            const std::vector<MarkerClass>& site_classes,
                            const ColourLearningOptions& options, int min_classes = 1);

// Boxes that hold for every set of frames (each a lighting): learned on all
// discs at once with the same labels. Set `sets[i]` refuses like
// LearnColours.
ColourLearning LearnColoursForAll(const std::vector<std::vector<cv::Mat>>& sets,
                                  const std::vector<std::vector<KnownMarker>>& known,
                                  const std::vector<MarkerClass>& site_classes,
                                  const ColourLearningOptions& options, int min_classes = 1);

// Whether `classes` still find each class's discs in `frames` (other
// light): per class, the discs of that colour (matched to the nearest
// learned colour or by `known`) and how many the detector with those
// classes finds as that class.
struct ClassCheck {
  std::string name;
  int discs = 0;
  int found = 0;
  int found_as_other = 0;
  bool holds() const { return discs > 0 && found == discs && found_as_other == 0; }
};
// `unmatched_discs` (when given) counts the discs of a colour near no
// learned class's (without known places): a marker the other light has
// moved out of reach of its class, or something new in view.
std::vector<ClassCheck> CheckColours(const std::vector<cv::Mat>& frames,
                                     const std::vector<KnownMarker>& known,
                                     const std::vector<LearnedClass>& classes,
                                     const ColourLearningOptions& options,
                                     int* unmatched_discs = nullptr);

// Markers for frames with no known places (other light): every whole disc
// whose core colour is within 1.5 clustering units of a learned class's
// median, named after that class, so LearnColoursForAll learns each
// class from its own discs under every light.
std::vector<KnownMarker> LabelByNearestClass(const std::vector<cv::Mat>& frames,
                                             const std::vector<LearnedClass>& classes,
                                             const ColourLearningOptions& options);

// The learned classes as the detector's: areas from half the smallest
// disc's radius to 1.8 times the largest's (the bounds camera_proc derives
// from the lens, docs/camera.md), the default circularity.
std::vector<ColourClass> ToColourClasses(const std::vector<LearnedClass>& classes);

}  // namespace roomfix::vision

#endif  // ROOMFIX_CORE_VISION_COLOUR_LEARNING_H_
