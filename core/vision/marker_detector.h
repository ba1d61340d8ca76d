#ifndef ROOMFIX_CORE_VISION_MARKER_DETECTOR_H_
#define ROOMFIX_CORE_VISION_MARKER_DETECTOR_H_

#include <array>
#include <cstdint>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace roomfix::vision {

// A colour class in OpenCV's 8-bit HSV: H in [0, 179], S and V in [0, 255].
// hue_min > hue_max wraps through 0 (reds).
struct ColourClass {
  std::string name;
  std::array<int, 3> hsv_min{};
  std::array<int, 3> hsv_max{};
  // Expected blob area in full-resolution pixels; blobs outside are dropped.
  double min_area_px = 20.0;
  double max_area_px = 1e6;
  // 4 pi area / perimeter^2 below this is not a marker (1 for a disc).
  double min_circularity = 0.6;
};

// How pixels of the given image map to the full-resolution frame: the image
// is the full frame's rectangle starting at (offset_u_px, offset_v_px),
// shrunk by `scale` (2 for a half-size decode). Pixel centres map as
// u_full = offset_u_px + (u + 0.5) * scale - 0.5.
struct ImageWindow {
  int offset_u_px = 0;
  int offset_v_px = 0;
  int scale = 1;
};

// One blob of one class, in full-resolution coordinates (u right, v down,
// origin at the centre of the top-left pixel).
struct Blob {
  int class_index = -1;
  double u_px = 0.0;
  double v_px = 0.0;
  double radius_px = 0.0;    // radius of the disc with the blob's area
  double circularity = 0.0;  // 4 pi area / perimeter^2
  double area_px = 0.0;      // full-resolution pixels
  // Mean colour of the blob's core (OpenCV HSV), for adaptive thresholds.
  std::array<double, 3> mean_hsv{};
};

// Why a connected component of a class's mask is not a blob.
enum class BlobReject {
  kTooSmall,      // measured area under the class's min_area_px
  kTooLarge,      // over its max_area_px
  kNotRound,      // circularity under its min_circularity
  kUnmeasurable,  // no core pixel survived to take its colour from
};
// "too_small", "too_large", "not_round", "unmeasurable".
const char* BlobRejectName(BlobReject reason);

// A component Detect dropped, in full-resolution coordinates. Components
// dropped by the loose pre-filter (under half the minimum or over twice the
// maximum area) are never measured: their area is the pixel count, their
// centre the bounding box's and their circularity 0.
struct RejectedBlob {
  int class_index = -1;
  double u_px = 0.0;
  double v_px = 0.0;
  double area_px = 0.0;
  double circularity = 0.0;
  BlobReject reason = BlobReject::kTooSmall;
};

// What one Detect call saw besides its blobs.
struct DetectorDiagnostics {
  // Per class of the detector: its mask (255 = the class, after the blur and
  // majority threshold), the size of the image searched; empty for a class
  // not searched.
  std::vector<cv::Mat> class_masks;
  // Per class: pixels of its mask, in full-resolution pixels (times scale^2).
  std::vector<double> class_area_px;
  // Dropped components, at most kMaxRejected (a frame of coloured specks
  // would otherwise list thousands); `rejected_not_listed` counts the rest.
  static constexpr size_t kMaxRejected = 256;
  std::vector<RejectedBlob> rejected;
  int64_t rejected_not_listed = 0;
};

// How classification copes with lighting (see docs/camera.md for which works).
enum class LightingMode {
  kFixed,       // the site file's HSV ranges as they are (the reference)
  kNormalised,  // V (and S) judged against the local background brightness
  kAdaptive,    // kNormalised, plus ranges that follow each tracked marker's colour
};

struct DetectorOptions {
  LightingMode lighting = LightingMode::kNormalised;
  // Gaussian smoothing of the class masks, full-resolution pixels; 0 = none.
  double blur_sigma_px = 1.0;
  // kNormalised/kAdaptive: V (HSV value, 0..255) of the floor under the
  // lighting the class ranges were tuned in. Each pixel is scaled by
  // background_v_ref / (local floor V) before its class is looked up.
  double background_v_ref = 128.0;

  // False with a reason: a negative or non-finite blur, a reference V
  // outside (0, 255].
  bool IsValid(std::string* error) const;
};

// Finds coloured blobs. Stateless apart from its options and classes; one
// instance serves full-frame and region searches at any scale.
class MarkerDetector {
 public:
  MarkerDetector(std::vector<ColourClass> classes, DetectorOptions options);

  // Blobs of the classes in `class_indices` (all classes when empty) in a
  // BGR (CV_8UC3) image, sorted by class then descending area. Centroids are
  // sub-pixel and, at scale 1, accurate to a small fraction of a pixel on an
  // anti-aliased disc (edge pixels weighted by how much of the marker's
  // colour they hold). Returns an empty list for an empty image.
  std::vector<Blob> Detect(const cv::Mat& bgr, const ImageWindow& window,
                           const std::vector<int>& class_indices = {}) const;
  // The same search (one code path: Detect is this with no diagnostics),
  // also saying what it saw on the way: each searched class's mask and
  // every component it dropped, with why (the "what the detector sees"
  // view, core/vision/detector_view.h). Costs a mask copy per class.
  std::vector<Blob> Detect(const cv::Mat& bgr, const ImageWindow& window,
                           const std::vector<int>& class_indices,
                           DetectorDiagnostics* diagnostics) const;

  // Re-measures one blob found at a reduced scale on a full-resolution
  // window around it (the node decodes that window).
  bool Refine(const cv::Mat& bgr, const ImageWindow& window, int class_index, Blob* blob) const;

  // kAdaptive only (a no-op otherwise): a blob the tracker confirmed as a
  // marker; later searches for its class accept colours near the running
  // statistics of such blobs as well as the site file's range, so a marker
  // whose colour drifts with the light stays found. The range never grows
  // into another class's range.
  void ObserveTracked(const Blob& blob);

  const std::vector<ColourClass>& classes() const { return classes_; }

 private:
  std::vector<ColourClass> classes_;
  DetectorOptions options_;
  // Per class: running mean and spread of confirmed blobs' colour (kAdaptive).
  struct ColourStats {
    int count = 0;
    std::array<double, 3> mean{};
    std::array<double, 3> var{};
    // The mean and (clamped) sigma the lookup table was last built with.
    bool built = false;
    std::array<double, 3> built_mean{};
    std::array<double, 3> built_sigma{};
  };
  std::vector<ColourStats> stats_;
  // Detect's work for class k on the frame's classified `bits` (its bank).
  void DetectClass(const cv::Mat& bgr, const ImageWindow& window, const cv::Mat1w& gain,
                   const cv::Mat1b& bits, int k, std::vector<Blob>* blobs,
                   DetectorDiagnostics* diagnostics) const;
  // Class membership by colour: 64^3 cells of the BGR cube (6 bits per
  // channel), one bit per class; classes 8k..8k+7 are in bank k.
  std::vector<std::vector<unsigned char>> lut_banks_;
  std::vector<unsigned char> cell_hsv_;  // HSV of each cell's centre colour
  void BuildLutBank(int bank);
  bool AcceptsHsv(int class_index, int h, int s, int v) const;
};

// Hue difference a - b on OpenCV's 180-step hue circle, in [-90, 90).
double HueDifference(double a, double b);

// The image as kNormalised and kAdaptive classify it: each pixel scaled by
// background_v_ref / (its neighbourhood's floor V), the gain Detect applies
// (a copy of `bgr` for kFixed). Tools that learn or show classes use it so
// that they see the colours the detector looks up.
cv::Mat NormaliseIllumination(const cv::Mat& bgr, LightingMode lighting, double background_v_ref);

// The reference pipeline, for the benchmark: full-frame HSV conversion,
// inRange per class, 5x5 Gaussian blur, cv::SimpleBlobDetector on the mask.
std::vector<Blob> DetectReference(const cv::Mat& bgr, const std::vector<ColourClass>& classes);

}  // namespace roomfix::vision

#endif  // ROOMFIX_CORE_VISION_MARKER_DETECTOR_H_
