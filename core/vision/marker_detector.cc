#include "core/vision/marker_detector.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <opencv2/core/hal/intrin.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>
#include <utility>

namespace roomfix::vision {
namespace {

// Colour look-up table: 6 bits per BGR channel. A cell spans 4 DN per
// channel, so a class boundary moves by at most 2 DN of BGR against an exact
// per-pixel HSV test; the sub-pixel measurement below works on the raw
// colours, so this only decides which pixels seed a blob.
constexpr int kLutBits = 6;
constexpr int kLutShift = 8 - kLutBits;
constexpr int kLutSide = 1 << kLutBits;
constexpr int kLutSize = kLutSide * kLutSide * kLutSide;
constexpr int kClassesPerBank = 8;

inline int LutIndex(int b, int g, int r) {
  return ((b >> kLutShift) << (2 * kLutBits)) | ((g >> kLutShift) << kLutBits) | (r >> kLutShift);
}

bool InHsvRange(const ColourClass& c, int h, int s, int v) {
  if (s < c.hsv_min[1] || s > c.hsv_max[1] || v < c.hsv_min[2] || v > c.hsv_max[2]) return false;
  if (c.hsv_min[0] <= c.hsv_max[0]) return h >= c.hsv_min[0] && h <= c.hsv_max[0];
  return h >= c.hsv_min[0] || h <= c.hsv_max[0];  // wraps through 0 (reds)
}

// Hue difference a - b on OpenCV's 180-step circle, in [-90, 90).
double HueDiff(double a, double b) {
  double d = std::fmod(a - b + 270.0, 180.0);
  if (d < 0) d += 180.0;
  return d - 90.0;
}

std::array<double, 3> BgrToHsv(double b, double g, double r) {
  cv::Mat3b px(1, 1,
               cv::Vec3b(cv::saturate_cast<uchar>(b), cv::saturate_cast<uchar>(g),
                         cv::saturate_cast<uchar>(r)));
  cv::Mat3b hsv;
  cv::cvtColor(px, hsv, cv::COLOR_BGR2HSV);
  const cv::Vec3b& v = hsv(0, 0);
  return {static_cast<double>(v[0]), static_cast<double>(v[1]), static_cast<double>(v[2])};
}

double MedianOf(std::vector<float>* values) {
  if (values->empty()) return 0.0;
  auto mid = values->begin() + static_cast<std::ptrdiff_t>(values->size() / 2);
  std::nth_element(values->begin(), mid, values->end());
  return *mid;
}

// Gains are 10.6 fixed point: 64 is 1. With the gain held to [0.25, 4]
// (16..256), channel * gain fits 16 bits, so a row is scaled 8 or 16 pixels
// at a time with OpenCV's universal intrinsics.
constexpr int kGainShift = 6;
constexpr double kMinGain = 0.25;
constexpr double kMaxGain = 4.0;

// Illumination normalisation (kNormalised, kAdaptive). The floor's
// brightness is estimated on a coarse grid of ~32 full-resolution pixels:
// each cell's mean V = max(B, G, R) over a sparse sample of its pixels, then
// a 5x5-cell median, so markers (a few cells at most) and thin lines do not
// pull the estimate. Each pixel is later multiplied by
// gain = background_v_ref / floor V, which moves V and leaves H and S alone
// (both are ratios of the channels), so the ranges are judged as if the
// floor sat at its reference brightness. Returns the per-pixel gain,
// bilinear between cell centres, so gradients and flicker bands are followed
// smoothly. Fails (wrong gain) where the floor is not the commonest thing
// within ~2 cells, e.g. under a large coloured object.
cv::Mat1w EstimateGain(const cv::Mat& bgr, int scale, double background_v_ref) {
  const int cell = std::max(4, 32 / std::max(1, scale));
  const int gw = std::max(1, bgr.cols / cell);
  const int gh = std::max(1, bgr.rows / cell);
  const int step = std::max(1, cell / 8);
  cv::Mat1f sum(gh, gw, 0.0f);
  cv::Mat1i count(gh, gw, 0);
  for (int y = step / 2; y < bgr.rows; y += step) {
    const int cy = std::min(gh - 1, y * gh / bgr.rows);
    const cv::Vec3b* p = bgr.ptr<cv::Vec3b>(y);
    float* s = sum.ptr<float>(cy);
    int* n = count.ptr<int>(cy);
    for (int x = step / 2; x < bgr.cols; x += step) {
      const int cx = std::min(gw - 1, x * gw / bgr.cols);
      s[cx] += std::max({p[x][0], p[x][1], p[x][2]});
      n[cx] += 1;
    }
  }
  cv::Mat1b v(gh, gw);
  for (int y = 0; y < gh; ++y) {
    for (int x = 0; x < gw; ++x) {
      v(y, x) = cv::saturate_cast<uchar>(count(y, x) > 0 ? sum(y, x) / count(y, x) : 0.0f);
    }
  }
  cv::Mat1b floor_v;
  if (gw >= 5 && gh >= 5) {
    cv::medianBlur(v, floor_v, 5);
  } else {
    // Too few cells for a local median (a small window): one gain for all.
    std::vector<float> values(v.begin(), v.end());
    floor_v = cv::Mat1b(gh, gw, cv::saturate_cast<uchar>(MedianOf(&values)));
  }
  cv::Mat1w gain_small(gh, gw);
  for (int y = 0; y < gh; ++y) {
    for (int x = 0; x < gw; ++x) {
      const double g =
          std::clamp(background_v_ref / std::max<double>(1.0, floor_v(y, x)), kMinGain, kMaxGain);
      gain_small(y, x) = static_cast<uint16_t>(std::lround(g * (1 << kGainShift)));
    }
  }
  cv::Mat1w gain;
  cv::resize(gain_small, gain, bgr.size(), 0, 0, cv::INTER_LINEAR);
  return gain;
}

inline uchar ScaleChannel(int c, int gain) {
  return static_cast<uchar>(std::min(255, (c * gain + (1 << (kGainShift - 1))) >> kGainShift));
}

inline cv::Vec3b ApplyGain(const cv::Vec3b& c, int gain) {
  return cv::Vec3b(ScaleChannel(c[0], gain), ScaleChannel(c[1], gain), ScaleChannel(c[2], gain));
}

// out = min(255, in * gain) for one BGR row of n pixels.
void ScaleRow(const uchar* in, const uint16_t* gain, int n, uchar* out) {
  int x = 0;
#if CV_SIMD
  const int lanes = cv::v_uint8::nlanes;
  const cv::v_uint16 half = cv::vx_setall_u16(1 << (kGainShift - 1));
  for (; x + lanes <= n; x += lanes) {
    cv::v_uint8 b, g, r;
    cv::v_load_deinterleave(in + 3 * x, b, g, r);
    const cv::v_uint16 g0 = cv::vx_load(gain + x);
    const cv::v_uint16 g1 = cv::vx_load(gain + x + lanes / 2);
    cv::v_uint8* channels[3] = {&b, &g, &r};
    for (cv::v_uint8* c : channels) {
      cv::v_uint16 lo, hi;
      cv::v_expand(*c, lo, hi);
      lo = cv::v_shr<kGainShift>(cv::v_mul_wrap(lo, g0) + half);
      hi = cv::v_shr<kGainShift>(cv::v_mul_wrap(hi, g1) + half);
      *c = cv::v_pack(lo, hi);  // saturates at 255
    }
    cv::v_store_interleave(out + 3 * x, b, g, r);
  }
#endif
  for (; x < n; ++x) {
    for (int k = 0; k < 3; ++k) out[3 * x + k] = ScaleChannel(in[3 * x + k], gain[x]);
  }
}

// Chain-code perimeter correction. The contour through the boundary pixels'
// centres is an 8-connected chain: on a circle it is 5.5% longer than the
// curve it follows (the mean of cos t + (sqrt2 - 1) sin t over the octant),
// and it runs half a pixel inside the pixel edges, which for a convex shape
// shortens it by 2 pi * 0.5. With both corrections a digital disc of radius
// 4 px measures a circularity near 1 instead of ~0.8.
constexpr double kChainLengthBias = 1.055;

double Circularity(const cv::Mat1b& component_mask, double pixel_area) {
  std::vector<std::vector<cv::Point>> contours;
  cv::findContours(component_mask, contours, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_NONE);
  double perimeter = 0.0;
  for (const auto& c : contours) perimeter += cv::arcLength(c, true);
  perimeter = perimeter / kChainLengthBias + M_PI;
  return std::min(1.0, 4.0 * M_PI * pixel_area / (perimeter * perimeter));
}

// Zones around a blob, by distance from its mask (image pixels).
constexpr float kCoreDepthPx = 2.0f;  // core: at least this far inside
constexpr float kSoftReachPx = 2.0f;  // soft coverage up to this far outside
constexpr float kRingInnerPx = 3.0f;  // background ring
constexpr float kRingOuterPx = 5.0f;
// Residual (DN) off the line through b and m beyond which a pixel is not a
// mix of the two (noise of 2-3 DN per channel stays well below).
constexpr double kResidualDn = 10.0;
constexpr double kResidualFraction = 0.05;  // of |m - b|
constexpr double kConeTan2 = 0.3 * 0.3;

// How far the measured extent may grow beyond the classified component:
// a quarter of its size, at most 16 px.
int GrowReachPx(const cv::Rect& bbox) {
  return std::min(16, static_cast<int>(0.25 * std::max(bbox.width, bbox.height)));
}

// The window Measure works in: the component, its growth and the ring.
cv::Rect MeasureWindow(const cv::Rect& bbox, cv::Size image) {
  const int pad = GrowReachPx(bbox) + static_cast<int>(kRingOuterPx) + 1;
  return cv::Rect(bbox.x - pad, bbox.y - pad, bbox.width + 2 * pad, bbox.height + 2 * pad) &
         cv::Rect(0, 0, image.width, image.height);
}
// Below this |m - b| (DN) the unmixing is too noisy: binary moments instead.
constexpr double kMinContrastDn = 12.0;

struct Measurement {
  double x = 0.0, y = 0.0;  // image pixels
  double area = 0.0;        // image pixels
  double circularity = 0.0;
  cv::Vec3d core_bgr;  // mean colour of the core (gain applied when given)
};

// One 8-connected component of a class mask.
struct Component {
  cv::Rect bbox;  // image pixels
  int pixels = 0;
  cv::Mat1i labels;  // labels of the rectangle it was found in
  cv::Point origin;  // that rectangle's top-left, image pixels
  int label = 0;

  bool Contains(int x, int y) const {
    const int lx = x - origin.x, ly = y - origin.y;
    return lx >= 0 && ly >= 0 && lx < labels.cols && ly < labels.rows && labels(ly, lx) == label;
  }
};

// Connected components of a sparse mask (markers cover ~1% of a frame):
// blocks of kBlock px holding any mask pixel are grouped first, then each
// group's rectangle is labelled on its own. Pixels that are 8-connected lie
// in 8-adjacent blocks, so every component falls in exactly one group; this
// labels a few percent of the frame instead of all of it.
std::vector<Component> SparseComponents(const cv::Mat1b& mask) {
  constexpr int kBlock = 16;
  std::vector<Component> out;
  std::vector<cv::Point> points;
  cv::findNonZero(mask, points);
  if (points.empty()) return out;
  cv::Mat1b coarse((mask.rows + kBlock - 1) / kBlock, (mask.cols + kBlock - 1) / kBlock, uchar{0});
  for (const cv::Point& p : points) coarse(p.y / kBlock, p.x / kBlock) = 255;
  cv::Mat1i coarse_labels, coarse_stats, stats;
  cv::Mat1d centroids;
  const int groups =
      cv::connectedComponentsWithStats(coarse, coarse_labels, coarse_stats, centroids, 8, CV_32S);
  for (int c = 1; c < groups; ++c) {
    const cv::Rect blocks(coarse_stats(c, cv::CC_STAT_LEFT), coarse_stats(c, cv::CC_STAT_TOP),
                          coarse_stats(c, cv::CC_STAT_WIDTH), coarse_stats(c, cv::CC_STAT_HEIGHT));
    const cv::Rect rect = cv::Rect(blocks.x * kBlock, blocks.y * kBlock, blocks.width * kBlock,
                                   blocks.height * kBlock) &
                          cv::Rect(0, 0, mask.cols, mask.rows);
    cv::Mat1b sub = mask(rect).clone();
    // Another group's blocks inside this rectangle are not this group's.
    for (int by = blocks.y; by < blocks.y + blocks.height; ++by) {
      for (int bx = blocks.x; bx < blocks.x + blocks.width; ++bx) {
        if (coarse_labels(by, bx) == 0 || coarse_labels(by, bx) == c) continue;
        const cv::Rect b = cv::Rect(bx * kBlock - rect.x, by * kBlock - rect.y, kBlock, kBlock) &
                           cv::Rect(0, 0, rect.width, rect.height);
        sub(b).setTo(0);
      }
    }
    Component proto;
    proto.origin = rect.tl();
    const int n = cv::connectedComponentsWithStats(sub, proto.labels, stats, centroids, 8, CV_32S);
    for (int j = 1; j < n; ++j) {
      Component comp = proto;  // shares the label image
      comp.label = j;
      comp.pixels = stats(j, cv::CC_STAT_AREA);
      comp.bbox = cv::Rect(rect.x + stats(j, cv::CC_STAT_LEFT), rect.y + stats(j, cv::CC_STAT_TOP),
                           stats(j, cv::CC_STAT_WIDTH), stats(j, cv::CC_STAT_HEIGHT));
      out.push_back(comp);
    }
  }
  return out;
}

// The stages of Measure (below), each on the component's window `roi`.

// The deepest core depth (kCoreDepthPx + 1, kCoreDepthPx, then 1 px) that
// still holds 5 pixels: a small blob at reduced scale may have no pixel 3 px
// deep, and a core of fewer pixels gives a median no better than one pixel.
float CoreDepth(const cv::Mat1f& dist_in) {
  float core_depth = 1.0f;
  for (float depth : {kCoreDepthPx + 1.0f, kCoreDepthPx, 1.0f}) {
    core_depth = depth;
    int count = 0;
    for (int y = 0; y < dist_in.rows; ++y)
      for (int x = 0; x < dist_in.cols; ++x) count += dist_in(y, x) >= depth ? 1 : 0;
    if (count >= 5) break;
  }
  return core_depth;
}

// The marker colour m: the per-channel median of the raw core pixels (never
// mixed with the floor, and the median ignores a specular highlight), and
// the mean core colour with the gain applied (what classification saw),
// into `core_bgr`. False when no pixel reaches `core_depth` (a component
// eroded away by the padding), which leaves the blob unmeasured.
bool MarkerColour(const cv::Mat& bgr, const cv::Rect& roi, const cv::Mat1f& dist_in,
                  float core_depth, const cv::Mat1w& gain, cv::Vec3d* m, cv::Vec3d* core_bgr) {
  std::array<std::vector<float>, 3> core_c;
  cv::Vec3d core_sum(0, 0, 0);
  for (int y = 0; y < roi.height; ++y) {
    const cv::Vec3b* p = bgr.ptr<cv::Vec3b>(roi.y + y) + roi.x;
    const uint16_t* g = gain.empty() ? nullptr : gain.ptr<uint16_t>(roi.y + y) + roi.x;
    for (int x = 0; x < roi.width; ++x) {
      if (dist_in(y, x) < core_depth) continue;
      for (int k = 0; k < 3; ++k) core_c[k].push_back(p[x][k]);
      const cv::Vec3b c = g ? ApplyGain(p[x], g[x]) : p[x];
      core_sum += cv::Vec3d(c[0], c[1], c[2]);
    }
  }
  if (core_c[0].empty()) return false;
  *core_bgr = core_sum / static_cast<double>(core_c[0].size());
  for (int k = 0; k < 3; ++k) (*m)[k] = MedianOf(&core_c[k]);
  return true;
}

// Background: the per-channel median of the ring kRingInnerPx..kRingOuterPx
// outside `region`, other blobs left out (a grid line through the ring is a
// minority and does not move the median). Leaves the distance from `region`
// in `dist_out` (the soft reach of the centroid needs it) even when the ring
// is empty (a blob filling its window), which returns false.
bool RingMedian(const cv::Mat& bgr, const cv::Rect& roi, const cv::Mat1b& other_local,
                const cv::Mat1b& region, cv::Mat1f* dist_out, cv::Vec3d* b) {
  cv::Mat1b outside;
  cv::bitwise_not(region, outside);
  cv::distanceTransform(outside, *dist_out, cv::DIST_L2, cv::DIST_MASK_PRECISE);
  std::array<std::vector<float>, 3> ring_c;
  for (int y = 0; y < roi.height; ++y) {
    const cv::Vec3b* p = bgr.ptr<cv::Vec3b>(roi.y + y) + roi.x;
    const uchar* o = other_local.ptr<uchar>(y);
    const float* dout = dist_out->ptr<float>(y);
    for (int x = 0; x < roi.width; ++x) {
      if (o[x] || dout[x] < kRingInnerPx || dout[x] > kRingOuterPx) continue;
      for (int k = 0; k < 3; ++k) ring_c[k].push_back(p[x][k]);
    }
  }
  if (ring_c[0].empty()) return false;
  for (int k = 0; k < 3; ++k) (*b)[k] = MedianOf(&ring_c[k]);
  return true;
}

// The two colours a pixel is unmixed between.
struct Unmixing {
  cv::Vec3d m;        // marker (core median)
  cv::Vec3d b;        // floor (ring median)
  cv::Vec3d d;        // m - b
  double d2 = 0.0;    // |m - b|^2
  bool soft = false;  // a ring was found and |m - b| >= kMinContrastDn
};

// Re-estimates the floor colour around `region` and whether the unmixing
// applies. An empty ring keeps the previous floor colour but turns the
// unmixing off, as does a contrast below kMinContrastDn (noise on a is
// sigma / |m - b|): the centroid then falls back to binary moments.
void FitFloor(const cv::Mat& bgr, const cv::Rect& roi, const cv::Mat1b& other_local,
              const cv::Mat1b& region, cv::Mat1f* dist_out, Unmixing* mix) {
  mix->soft = RingMedian(bgr, roi, other_local, region, dist_out, &mix->b);
  mix->d = mix->m - mix->b;
  mix->d2 = mix->d.dot(mix->d);
  mix->soft = mix->soft && mix->d2 >= kMinContrastDn * kMinContrastDn;
}

// Coverage a = (c - b).(m - b) / |m - b|^2 of pixel `px`, and in `residual`
// the distance of c from the line through b and m (how far it is from being
// a mix of the two).
double Unmix(const cv::Vec3b& px, const Unmixing& mix, double* residual) {
  const cv::Vec3d c(px[0] - mix.b[0], px[1] - mix.b[1], px[2] - mix.b[2]);
  const double a = c.dot(mix.d) / mix.d2;
  *residual = cv::norm(c - a * mix.d);
  return a;
}

// The marker's extent: the classified component `comp`, grown by up to
// grow_px through neighbouring pixels that hold at least half the marker's
// colour along m - b, into `region` (which holds `comp` on entry).
// Classification by fixed ranges can leave out a shaded or hue-shifted part
// of a real marker (the red-shifted underside of a glossy candy); the
// unmixing still sees it as marker against the floor. A pixel of another
// blob never joins.
void GrowRegion(const cv::Mat& bgr, const cv::Rect& roi, const cv::Mat1b& comp,
                const cv::Mat1b& other_local, int grow_px, const Unmixing& mix, cv::Mat1b* region) {
  cv::Mat1b candidate(roi.size());
  for (int y = 0; y < roi.height; ++y) {
    const cv::Vec3b* p = bgr.ptr<cv::Vec3b>(roi.y + y) + roi.x;
    const uchar* o = other_local.ptr<uchar>(y);
    for (int x = 0; x < roi.width; ++x) {
      double residual = 0.0;
      const double a = Unmix(p[x], mix, &residual);
      // Within a cone round m - b: residual <= 0.3 |c - b| (17 degrees).
      // A darker or differently hued object (another candy, a shadow)
      // projects onto m - b too, but far off its direction.
      const double along = a * std::sqrt(mix.d2);
      candidate(y, x) =
          (!o[x] && a >= 0.5 && residual * residual <= kConeTan2 * along * along) ? 255 : 0;
    }
  }
  const cv::Mat kernel = cv::getStructuringElement(cv::MORPH_RECT, cv::Size(3, 3));
  for (int i = 0; i < grow_px; ++i) {
    cv::Mat1b grown;
    cv::dilate(*region, grown, kernel);
    cv::bitwise_and(grown, candidate, grown);
    cv::bitwise_or(grown, comp, grown);
    if (cv::countNonZero(grown != *region) == 0) break;
    *region = grown;
  }
}

// Holes (a specular highlight, a hue-shifted patch the growth did not
// reach) belong to the marker: filled, so the outline alone is judged.
void FillHoles(cv::Mat1b* region) {
  std::vector<std::vector<cv::Point>> contours;
  cv::findContours(region->clone(), contours, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_SIMPLE);
  cv::drawContours(*region, contours, -1, cv::Scalar(255), cv::FILLED);
}

// The coverage-weighted centroid and area into `out`: core pixels count as
// 1 (clamping their noise would bias the area low), other pixels of the
// region and pixels up to kSoftReachPx outside it by their unmixed coverage
// clamped to [0, 1]. A pixel whose colour is far from the line through b and
// m is not a mix of the two (a grid line or shadow under the edge, a
// hue-shifted part of the marker): it counts by membership of the region
// instead. Without the unmixing (mix.soft false) every pixel counts by
// membership. False when nothing counts.
bool CoverageCentroid(const cv::Mat& bgr, const cv::Rect& roi, const cv::Mat1b& region,
                      const cv::Mat1b& other_local, const cv::Mat1f& dist_in, float core_depth,
                      const cv::Mat1f& dist_out, const Unmixing& mix, Measurement* out) {
  const double max_residual = kResidualDn + kResidualFraction * std::sqrt(mix.d2);
  double sa = 0.0, sx = 0.0, sy = 0.0;
  for (int y = 0; y < roi.height; ++y) {
    const cv::Vec3b* p = bgr.ptr<cv::Vec3b>(roi.y + y) + roi.x;
    const uchar* o = other_local.ptr<uchar>(y);
    for (int x = 0; x < roi.width; ++x) {
      double a = 0.0;
      const bool in_region = region(y, x) != 0;
      if (dist_in(y, x) >= core_depth) {
        a = 1.0;
      } else if (!mix.soft) {
        a = in_region ? 1.0 : 0.0;
      } else if (in_region || (!o[x] && dist_out(y, x) <= kSoftReachPx)) {
        double residual = 0.0;
        a = Unmix(p[x], mix, &residual);
        a = residual > max_residual ? (in_region ? 1.0 : 0.0) : std::clamp(a, 0.0, 1.0);
      }
      sa += a;
      sx += a * x;
      sy += a * y;
    }
  }
  if (sa <= 0.0) return false;
  out->area = sa;
  out->x = roi.x + sx / sa;
  out->y = roi.y + sy / sa;
  return true;
}

// Sub-pixel measurement of one connected component by linear unmixing.
//
// Why it works: a camera pixel integrates the light over its footprint, so
// an edge pixel that a fraction a of the marker covers reads
//   c = a m + (1 - a) b
// (m: marker colour, b: floor colour, in linear sensor units). Then
// c - b = a (m - b), and projecting onto m - b gives a exactly:
//   a = (c - b).(m - b) / |m - b|^2.
// The projection (rather than one channel) uses all three channels, so the
// noise on a is sigma / |m - b| and does not depend on which channel holds
// the contrast. The coverage-weighted centroid sum(a x) / sum(a) is the
// centroid of the marker's image up to where inside each edge pixel the
// covered part lies, which averages out round a disc (error ~1e-3 px),
// whereas a binary mask moves the centroid by whole pixels along the edge.
// m is the median of the core (pixels at least 2 px inside, never mixed);
// b the median of a ring 3..5 px outside. Failure modes: a floor that is not
// uniform under the edge (a grid line, a shadow) breaks c = a m + (1-a) b for
// those pixels; the median keeps b right when a line crosses the ring, and an
// edge pixel on the line itself, whose colour lies off the line through b
// and m (residual > kResidualDn + 5% |m - b|), counts by region membership
// (0 or 1) instead of a wrong a: a bounded error, not a systematic pull. A
// colour too close to the floor's (|m - b| < kMinContrastDn) falls back to
// binary moments of the region. A gamma-encoded
// image is not linear in a, which biases the radius but not the centroid of
// a symmetric disc. Pixels of other blobs and beyond kSoftReachPx never count;
// core pixels count as 1 (clamping their noise would bias the area low).
bool Measure(const cv::Mat& bgr, const cv::Mat1b& comp, const cv::Rect& roi, int grow_px,
             const cv::Mat1b& other_local, const cv::Mat1w& gain, Measurement* out) {
  // Depth inside the component (the ROI border counts as outside only where
  // the image continues, hence the zero padding).
  cv::Mat1b comp_padded;
  cv::copyMakeBorder(comp, comp_padded, 1, 1, 1, 1, cv::BORDER_CONSTANT, 0);
  cv::Mat1f dist_in_padded;
  cv::distanceTransform(comp_padded, dist_in_padded, cv::DIST_L2, cv::DIST_MASK_PRECISE);
  const cv::Mat1f dist_in = dist_in_padded(cv::Rect(1, 1, roi.width, roi.height));

  const float core_depth = CoreDepth(dist_in);
  Unmixing mix;
  if (!MarkerColour(bgr, roi, dist_in, core_depth, gain, &mix.m, &out->core_bgr)) return false;

  // The floor round the classified component decides whether it may grow;
  // the floor is estimated again round what it grew to, then round the
  // filled outline, so the ring never overlaps the marker.
  cv::Mat1f dist_out;
  FitFloor(bgr, roi, other_local, comp, &dist_out, &mix);
  cv::Mat1b region = comp.clone();
  if (mix.soft && grow_px > 0) {
    GrowRegion(bgr, roi, comp, other_local, grow_px, mix, &region);
    FitFloor(bgr, roi, other_local, region, &dist_out, &mix);
  } else {
    cv::Vec3d unused;
    RingMedian(bgr, roi, other_local, region, &dist_out, &unused);  // dist_out for the region
  }
  FillHoles(&region);
  if (mix.soft) FitFloor(bgr, roi, other_local, region, &dist_out, &mix);
  out->circularity = Circularity(region, cv::countNonZero(region));
  return CoverageCentroid(bgr, roi, region, other_local, dist_in, core_depth, dist_out, mix, out);
}

}  // namespace

double HueDifference(double a, double b) { return HueDiff(a, b); }

cv::Mat NormaliseIllumination(const cv::Mat& bgr, LightingMode lighting, double background_v_ref) {
  if (bgr.empty() || bgr.type() != CV_8UC3 || lighting == LightingMode::kFixed) {
    return bgr.clone();
  }
  const cv::Mat1w gain = EstimateGain(bgr, 1, background_v_ref);
  cv::Mat out(bgr.size(), CV_8UC3);
  for (int y = 0; y < bgr.rows; ++y) {
    ScaleRow(bgr.ptr<uchar>(y), gain.ptr<uint16_t>(y), bgr.cols, out.ptr<uchar>(y));
  }
  return out;
}

const char* BlobRejectName(BlobReject reason) {
  switch (reason) {
    case BlobReject::kTooSmall:
      return "too_small";
    case BlobReject::kTooLarge:
      return "too_large";
    case BlobReject::kNotRound:
      return "not_round";
    case BlobReject::kUnmeasurable:
      return "unmeasurable";
  }
  return "unknown";
}

bool DetectorOptions::IsValid(std::string* error) const {
  if (!(blur_sigma_px >= 0.0) || !std::isfinite(blur_sigma_px)) {
    *error = "detector blur_sigma_px must be >= 0 and finite";
    return false;
  }
  if (!(background_v_ref > 0.0 && background_v_ref <= 255.0)) {
    *error = "detector background_v_ref must be in (0, 255] (HSV value)";
    return false;
  }
  return true;
}

MarkerDetector::MarkerDetector(std::vector<ColourClass> classes, DetectorOptions options)
    : classes_(std::move(classes)), options_(options), stats_(classes_.size()) {
  // HSV of every LUT cell's centre colour, once.
  cv::Mat3b cells(kLutSide * kLutSide, kLutSide);
  const int half = 1 << (kLutShift - 1);
  for (int i = 0; i < kLutSize; ++i) {
    const int b = (i >> (2 * kLutBits)) & (kLutSide - 1);
    const int g = (i >> kLutBits) & (kLutSide - 1);
    const int r = i & (kLutSide - 1);
    cells(i / kLutSide, i % kLutSide) = cv::Vec3b(static_cast<uchar>((b << kLutShift) + half),
                                                  static_cast<uchar>((g << kLutShift) + half),
                                                  static_cast<uchar>((r << kLutShift) + half));
  }
  cv::Mat3b hsv;
  cv::cvtColor(cells, hsv, cv::COLOR_BGR2HSV);
  cell_hsv_.assign(hsv.datastart, hsv.dataend);
  const int banks = (static_cast<int>(classes_.size()) + kClassesPerBank - 1) / kClassesPerBank;
  lut_banks_.resize(banks);
  for (int bank = 0; bank < banks; ++bank) BuildLutBank(bank);
}

// Adaptive acceptance (kAdaptive): within kSigmas of the running colour of
// confirmed blobs, with the spread held between a floor (a few confirmed
// blobs of one colour would otherwise give a range too tight for noise) and
// a ceiling, and never inside another class's range.
namespace {
constexpr int kMinObservations = 3;
constexpr double kSigmas = 3.0;
constexpr std::array<double, 3> kMinSigma = {3.0, 12.0, 12.0};
constexpr std::array<double, 3> kMaxSigma = {8.0, 40.0, 40.0};
constexpr int kStatsWindow = 50;  // exponential forgetting, so ranges follow drift
}  // namespace

bool MarkerDetector::AcceptsHsv(int class_index, int h, int s, int v) const {
  const ColourClass& c = classes_[class_index];
  if (InHsvRange(c, h, s, v)) return true;
  if (options_.lighting != LightingMode::kAdaptive) return false;
  const ColourStats& st = stats_[class_index];
  if (st.count < kMinObservations) return false;
  const std::array<double, 3> diff = {HueDiff(h, st.mean[0]), s - st.mean[1], v - st.mean[2]};
  for (int k = 0; k < 3; ++k) {
    const double sigma = std::clamp(std::sqrt(st.var[k]), kMinSigma[k], kMaxSigma[k]);
    if (std::abs(diff[k]) > kSigmas * sigma) return false;
  }
  for (int j = 0; j < static_cast<int>(classes_.size()); ++j) {
    if (j != class_index && InHsvRange(classes_[j], h, s, v)) return false;
  }
  return true;
}

void MarkerDetector::BuildLutBank(int bank) {
  std::vector<unsigned char>& lut = lut_banks_[bank];
  lut.assign(kLutSize, 0);
  const int first = bank * kClassesPerBank;
  const int last = std::min<int>(first + kClassesPerBank, static_cast<int>(classes_.size()));
  for (int i = 0; i < kLutSize; ++i) {
    const int h = cell_hsv_[3 * i], s = cell_hsv_[3 * i + 1], v = cell_hsv_[3 * i + 2];
    unsigned char bits = 0;
    for (int k = first; k < last; ++k) {
      if (AcceptsHsv(k, h, s, v)) bits |= static_cast<unsigned char>(1u << (k - first));
    }
    lut[i] = bits;
  }
}

std::vector<Blob> MarkerDetector::Detect(const cv::Mat& bgr, const ImageWindow& window,
                                         const std::vector<int>& class_indices) const {
  return Detect(bgr, window, class_indices, nullptr);
}

std::vector<Blob> MarkerDetector::Detect(const cv::Mat& bgr, const ImageWindow& window,
                                         const std::vector<int>& class_indices,
                                         DetectorDiagnostics* diagnostics) const {
  std::vector<Blob> blobs;
  if (diagnostics != nullptr) {
    *diagnostics = DetectorDiagnostics{};
    diagnostics->class_masks.resize(classes_.size());
    diagnostics->class_area_px.assign(classes_.size(), 0.0);
  }
  if (bgr.empty() || bgr.type() != CV_8UC3 || classes_.empty()) return blobs;
  std::vector<int> wanted;
  if (class_indices.empty()) {
    for (int k = 0; k < static_cast<int>(classes_.size()); ++k) wanted.push_back(k);
  } else {
    for (int k : class_indices) {
      if (k >= 0 && k < static_cast<int>(classes_.size())) wanted.push_back(k);
    }
    std::sort(wanted.begin(), wanted.end());
    wanted.erase(std::unique(wanted.begin(), wanted.end()), wanted.end());
  }
  const int scale = std::max(1, window.scale);

  cv::Mat1w gain;
  if (options_.lighting != LightingMode::kFixed) {
    gain = EstimateGain(bgr, scale, options_.background_v_ref);
  }

  cv::Mat1b bits(bgr.size());
  std::vector<uchar> row(3 * static_cast<size_t>(bgr.cols));
  for (size_t wi = 0; wi < wanted.size();) {
    const int bank = wanted[wi] / kClassesPerBank;
    // Classify every pixel once per bank: one table look-up per pixel.
    const unsigned char* lut = lut_banks_[bank].data();
    for (int y = 0; y < bgr.rows; ++y) {
      const cv::Vec3b* p = bgr.ptr<cv::Vec3b>(y);
      uchar* o = bits.ptr<uchar>(y);
      if (gain.empty()) {
        for (int x = 0; x < bgr.cols; ++x) o[x] = lut[LutIndex(p[x][0], p[x][1], p[x][2])];
      } else {
        ScaleRow(bgr.ptr<uchar>(y), gain.ptr<uint16_t>(y), bgr.cols, row.data());
        for (int x = 0; x < bgr.cols; ++x) {
          o[x] = lut[LutIndex(row[3 * x], row[3 * x + 1], row[3 * x + 2])];
        }
      }
    }
    for (; wi < wanted.size() && wanted[wi] / kClassesPerBank == bank; ++wi) {
      DetectClass(bgr, window, gain, bits, wanted[wi], &blobs, diagnostics);
    }
  }
  std::sort(blobs.begin(), blobs.end(), [](const Blob& a, const Blob& b) {
    if (a.class_index != b.class_index) return a.class_index < b.class_index;
    return a.area_px > b.area_px;
  });
  return blobs;
}

namespace {
void AddReject(DetectorDiagnostics* diagnostics, const RejectedBlob& r) {
  if (diagnostics == nullptr) return;
  if (diagnostics->rejected.size() >= DetectorDiagnostics::kMaxRejected) {
    ++diagnostics->rejected_not_listed;
    return;
  }
  diagnostics->rejected.push_back(r);
}
}  // namespace

void MarkerDetector::DetectClass(const cv::Mat& bgr, const ImageWindow& window,
                                 const cv::Mat1w& gain, const cv::Mat1b& bits, int k,
                                 std::vector<Blob>* blobs, DetectorDiagnostics* diagnostics) const {
  const int scale = std::max(1, window.scale);
  const double s2 = static_cast<double>(scale) * scale;
  const double sigma = options_.blur_sigma_px / scale;
  const ColourClass& cls = classes_[k];
  const uchar bit = static_cast<uchar>(1u << (k % kClassesPerBank));
  cv::Mat1b mask;
  cv::bitwise_and(bits, cv::Scalar(bit), mask);
  cv::compare(mask, 0, mask, cv::CMP_NE);
  if (sigma >= 0.3) {
    // Smoothing then a majority threshold: removes speckle, fills pinholes.
    cv::GaussianBlur(mask, mask, cv::Size(0, 0), sigma, sigma, cv::BORDER_REPLICATE);
    cv::threshold(mask, mask, 127, 255, cv::THRESH_BINARY);
  }
  if (diagnostics != nullptr) {
    diagnostics->class_masks[k] = mask.clone();
    diagnostics->class_area_px[k] = cv::countNonZero(mask) * s2;
  }
  // Image pixel to full-resolution pixel (centres).
  auto full_u = [&](double x) { return window.offset_u_px + (x + 0.5) * scale - 0.5; };
  auto full_v = [&](double y) { return window.offset_v_px + (y + 0.5) * scale - 0.5; };
  for (const Component& c : SparseComponents(mask)) {
    const double pixels = c.pixels * s2;
    // Loose pre-filter on the binary area; the exact test is on the
    // measured area below.
    if (pixels < 0.5 * cls.min_area_px || pixels > 2.0 * cls.max_area_px) {
      AddReject(diagnostics,
                {k, full_u(c.bbox.x + 0.5 * (c.bbox.width - 1)),
                 full_v(c.bbox.y + 0.5 * (c.bbox.height - 1)), pixels, 0.0,
                 pixels < 0.5 * cls.min_area_px ? BlobReject::kTooSmall : BlobReject::kTooLarge});
      continue;
    }
    // The component, and the pixels of other classes and of other blobs
    // of this class (which never count for it), in the window Measure
    // works in.
    const cv::Rect pad_rect = MeasureWindow(c.bbox, bgr.size());
    cv::Mat1b comp(pad_rect.size()), other_local(pad_rect.size());
    const uchar other_bits = static_cast<uchar>(~bit);
    for (int y = 0; y < pad_rect.height; ++y) {
      const uchar* in = bits.ptr<uchar>(pad_rect.y + y) + pad_rect.x;
      const uchar* m = mask.ptr<uchar>(pad_rect.y + y) + pad_rect.x;
      uchar* cp = comp.ptr<uchar>(y);
      uchar* o = other_local.ptr<uchar>(y);
      for (int x = 0; x < pad_rect.width; ++x) {
        const bool mine = m[x] && c.Contains(pad_rect.x + x, pad_rect.y + y);
        cp[x] = mine ? 255 : 0;
        o[x] = ((in[x] & other_bits) || (m[x] && !mine)) ? 255 : 0;
      }
    }
    Measurement meas;
    if (!Measure(bgr, comp, pad_rect, GrowReachPx(c.bbox), other_local, gain, &meas)) {
      AddReject(diagnostics, {k, full_u(c.bbox.x + 0.5 * (c.bbox.width - 1)),
                              full_v(c.bbox.y + 0.5 * (c.bbox.height - 1)), pixels, 0.0,
                              BlobReject::kUnmeasurable});
      continue;
    }
    const double area = meas.area * s2;
    const bool small = area<cls.min_area_px, large = area> cls.max_area_px;
    if (small || large || meas.circularity < cls.min_circularity) {
      AddReject(diagnostics, {k, full_u(meas.x), full_v(meas.y), area, meas.circularity,
                              small   ? BlobReject::kTooSmall
                              : large ? BlobReject::kTooLarge
                                      : BlobReject::kNotRound});
      continue;
    }
    Blob blob;
    blob.class_index = k;
    blob.u_px = full_u(meas.x);
    blob.v_px = full_v(meas.y);
    blob.area_px = area;
    blob.radius_px = std::sqrt(area / M_PI);
    blob.circularity = meas.circularity;
    blob.mean_hsv = BgrToHsv(meas.core_bgr[0], meas.core_bgr[1], meas.core_bgr[2]);
    blobs->push_back(blob);
  }
}

bool MarkerDetector::Refine(const cv::Mat& bgr, const ImageWindow& window, int class_index,
                            Blob* blob) const {
  if (blob == nullptr || class_index < 0 || class_index >= static_cast<int>(classes_.size())) {
    return false;
  }
  const std::vector<Blob> found = Detect(bgr, window, {class_index});
  // The reduced-scale position is good to about a reduced pixel; accept the
  // nearest blob within the larger of the blob's radius and 4 px.
  const double reach = std::max(4.0, blob->radius_px);
  const Blob* best = nullptr;
  double best_d2 = reach * reach;
  for (const Blob& b : found) {
    const double du = b.u_px - blob->u_px, dv = b.v_px - blob->v_px;
    const double d2 = du * du + dv * dv;
    if (d2 <= best_d2) {
      best_d2 = d2;
      best = &b;
    }
  }
  if (best == nullptr) return false;
  *blob = *best;
  return true;
}

void MarkerDetector::ObserveTracked(const Blob& blob) {
  if (options_.lighting != LightingMode::kAdaptive) return;
  const int k = blob.class_index;
  if (k < 0 || k >= static_cast<int>(classes_.size())) return;
  ColourStats& st = stats_[k];
  st.count += 1;
  // Exponentially weighted mean and variance (West's update); the first
  // kStatsWindow blobs are a plain running mean.
  const double w = 1.0 / std::min(st.count, kStatsWindow);
  const std::array<double, 3> diff = {HueDiff(blob.mean_hsv[0], st.mean[0]),
                                      blob.mean_hsv[1] - st.mean[1], blob.mean_hsv[2] - st.mean[2]};
  for (int c = 0; c < 3; ++c) {
    if (st.count == 1) {
      st.mean[c] = blob.mean_hsv[c];
      st.var[c] = 0.0;
      continue;
    }
    const double incr = w * diff[c];
    st.mean[c] += incr;
    st.var[c] = (1.0 - w) * (st.var[c] + diff[c] * incr);
  }
  st.mean[0] = std::fmod(st.mean[0] + 180.0, 180.0);
  // Rebuilding a bank costs a few milliseconds (every cell of the table is
  // re-judged), so it is rebuilt only when the statistics have moved: the
  // mean by more than half a sigma or a sigma by more than a quarter, on any
  // channel. A marker under steady light then never pays for it; one whose
  // colour drifts pays once per half sigma of drift.
  if (st.count < kMinObservations) return;
  bool moved = !st.built;
  std::array<double, 3> sigma{};
  for (int c = 0; c < 3; ++c) {
    sigma[c] = std::clamp(std::sqrt(st.var[c]), kMinSigma[c], kMaxSigma[c]);
    if (!st.built) continue;
    const double shift = c == 0 ? std::abs(HueDiff(st.mean[0], st.built_mean[0]))
                                : std::abs(st.mean[c] - st.built_mean[c]);
    moved = moved || shift > 0.5 * st.built_sigma[c] ||
            std::abs(sigma[c] - st.built_sigma[c]) > 0.25 * st.built_sigma[c];
  }
  if (!moved) return;
  st.built = true;
  st.built_mean = st.mean;
  st.built_sigma = sigma;
  BuildLutBank(k / kClassesPerBank);
}

std::vector<Blob> DetectReference(const cv::Mat& bgr, const std::vector<ColourClass>& classes) {
  std::vector<Blob> blobs;
  if (bgr.empty() || bgr.type() != CV_8UC3) return blobs;
  cv::Mat hsv;
  cv::cvtColor(bgr, hsv, cv::COLOR_BGR2HSV);
  for (int k = 0; k < static_cast<int>(classes.size()); ++k) {
    const ColourClass& c = classes[k];
    cv::Mat mask;
    if (c.hsv_min[0] <= c.hsv_max[0]) {
      cv::inRange(hsv, cv::Scalar(c.hsv_min[0], c.hsv_min[1], c.hsv_min[2]),
                  cv::Scalar(c.hsv_max[0], c.hsv_max[1], c.hsv_max[2]), mask);
    } else {
      cv::Mat low, high;
      cv::inRange(hsv, cv::Scalar(c.hsv_min[0], c.hsv_min[1], c.hsv_min[2]),
                  cv::Scalar(179, c.hsv_max[1], c.hsv_max[2]), high);
      cv::inRange(hsv, cv::Scalar(0, c.hsv_min[1], c.hsv_min[2]),
                  cv::Scalar(c.hsv_max[0], c.hsv_max[1], c.hsv_max[2]), low);
      cv::bitwise_or(low, high, mask);
    }
    cv::GaussianBlur(mask, mask, cv::Size(5, 5), 0);
    cv::SimpleBlobDetector::Params params;
    params.filterByColor = true;
    params.blobColor = 255;
    params.filterByArea = true;
    params.minArea = static_cast<float>(c.min_area_px);
    params.maxArea = static_cast<float>(c.max_area_px);
    params.filterByCircularity = true;
    params.minCircularity = static_cast<float>(c.min_circularity);
    params.filterByInertia = false;
    params.filterByConvexity = false;
    cv::Ptr<cv::SimpleBlobDetector> detector = cv::SimpleBlobDetector::create(params);
    std::vector<cv::KeyPoint> keypoints;
    detector->detect(mask, keypoints);
    for (const cv::KeyPoint& kp : keypoints) {
      Blob b;
      b.class_index = k;
      b.u_px = kp.pt.x;
      b.v_px = kp.pt.y;
      b.radius_px = kp.size / 2.0;
      b.area_px = M_PI * b.radius_px * b.radius_px;
      b.circularity = 1.0;  // passed the filter; the detector does not say more
      blobs.push_back(b);
    }
  }
  std::sort(blobs.begin(), blobs.end(), [](const Blob& a, const Blob& b) {
    if (a.class_index != b.class_index) return a.class_index < b.class_index;
    return a.area_px > b.area_px;
  });
  return blobs;
}

}  // namespace roomfix::vision
