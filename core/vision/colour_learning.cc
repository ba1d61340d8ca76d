#include "core/vision/colour_learning.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <numeric>
#include <opencv2/imgproc.hpp>
#include <set>
#include <utility>

namespace roomfix::vision {
namespace {

// Core pixels kept per disc for the boxes: enough for a 0.5 % quantile of a
// class seen in a few discs, bounded so a frame of large discs stays cheap.
constexpr int kMaxSamplesPerDisc = 600;
// Discs learning takes at most: the clustering's distance matrix is n^2
// floats (16 MB here) and its merges O(n^3) comparisons (seconds). A lab's
// frames hold tens to hundreds (the eight-robot tripod walk: 158).
constexpr size_t kMaxDiscs = 2000;
// The core, the inner 60 % of the radius, gives a disc's colour and
// coherence; the boxes learn from the inner 85 %, which holds the
// marker's shaded side (on a candy or a domed marker its hue and value
// move there) but not the edge's anti-aliased mix of marker and floor.
constexpr double kCoreFraction = 0.6;
constexpr double kSampleFraction = 0.85;
// A disc is a disc when, in the ring 1.2..1.6 radii around it, fewer than
// this share of pixels have its colour: a touching disc of the same colour
// covers under a sixth of the ring, a bar or a robot body of that colour
// at least a third.
constexpr double kMaxRingShare = 0.35;
// Hue quantisation of the detector's 6-bit lookup table, about one hue
// unit at marker saturations, plus one unit of rounding.
constexpr double kHueQuantisation = 2.0;
// Background histogram: H at full resolution, S and V in steps of 2.
constexpr int kSvStep = 2;
constexpr int kSvBins = 256 / kSvStep;

struct Hsv {
  uchar h, s, v;
};

// A disc with its core pixels (normalised BGR) for the boxes.
struct DiscSamples {
  FoundDisc disc;
  std::vector<cv::Vec3b> bgr;
};

// Background pixels counted by (H, S / 2, V / 2), then kept as the
// occupied cells only (a floor and a few bodies fill a few thousand).
struct BackgroundHistogram {
  std::vector<uint32_t> counts = std::vector<uint32_t>(180 * kSvBins * kSvBins, 0);
  struct Cell {
    int h, s, v;
    uint32_t n;
  };
  std::vector<Cell> cells;
  int64_t total = 0;
  void Add(const cv::Vec3b& p) {
    ++counts[(static_cast<size_t>(p[0]) * kSvBins + p[1] / kSvStep) * kSvBins + p[2] / kSvStep];
    ++total;
  }
  void Compact() {
    for (int h = 0; h < 180; ++h) {
      for (int s = 0; s < kSvBins; ++s) {
        for (int v = 0; v < kSvBins; ++v) {
          const uint32_t n = counts[(static_cast<size_t>(h) * kSvBins + s) * kSvBins + v];
          if (n > 0) cells.push_back({h, s * kSvStep + kSvStep / 2, v * kSvStep + kSvStep / 2, n});
        }
      }
    }
    counts.clear();
    counts.shrink_to_fit();
  }
};

Hsv ToHsv(const cv::Vec3b& bgr) {
  cv::Mat3b px(1, 1, bgr), hsv;
  cv::cvtColor(px, hsv, cv::COLOR_BGR2HSV);
  return {hsv(0, 0)[0], hsv(0, 0)[1], hsv(0, 0)[2]};
}

bool InHue(int lo, int hi, double h) {
  if (lo <= hi) return h >= lo && h <= hi;
  return h >= lo || h <= hi;
}

bool InBox(const LearnedClass& c, double h, double s, double v) {
  return s >= c.hsv_min[1] && s <= c.hsv_max[1] && v >= c.hsv_min[2] && v <= c.hsv_max[2] &&
         InHue(c.hsv_min[0], c.hsv_max[0], h);
}

// How far a colour lies outside a box: the largest per-channel distance
// (hue on its circle), 0 inside.
double BoxDistance(const LearnedClass& c, double h, double s, double v) {
  double d = 0.0;
  d = std::max(d, std::max(c.hsv_min[1] - s, s - c.hsv_max[1]));
  d = std::max(d, std::max(c.hsv_min[2] - v, v - c.hsv_max[2]));
  if (!InHue(c.hsv_min[0], c.hsv_max[0], h)) {
    d = std::max(d, std::min(std::abs(HueDifference(h, c.hsv_min[0])),
                             std::abs(HueDifference(h, c.hsv_max[0]))));
  }
  return d;
}

// Circular median of hues: the median of differences from the mean
// direction, which is well defined for a cluster narrower than 90 units.
double HueMedian(const std::vector<double>& hues) {
  if (hues.empty()) return 0.0;
  double sx = 0.0, sy = 0.0;
  for (double h : hues) {
    sx += std::cos(h * M_PI / 90.0);
    sy += std::sin(h * M_PI / 90.0);
  }
  const double mean = std::atan2(sy, sx) * 90.0 / M_PI;
  std::vector<double> d;
  d.reserve(hues.size());
  for (double h : hues) d.push_back(HueDifference(h, mean));
  std::nth_element(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(d.size() / 2), d.end());
  double m = mean + d[d.size() / 2];
  m = std::fmod(m + 180.0, 180.0);
  return m;
}

double Quantile(std::vector<double> values, double q) {
  if (values.empty()) return 0.0;
  const size_t k = std::min(values.size() - 1, static_cast<size_t>(q * (values.size() - 1) + 0.5));
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(k), values.end());
  return values[k];
}

// The saturation above which a pixel may be a marker: above the frame's
// own typical saturation (the floor dominates every frame) by 3 robust
// sigmas and 15 units, never below the option's floor.
double SaturationThreshold(const cv::Mat1b& s, double min_saturation) {
  std::vector<double> sample;
  for (int y = 0; y < s.rows; y += 4) {
    const uchar* p = s.ptr<uchar>(y);
    for (int x = 0; x < s.cols; x += 4) sample.push_back(p[x]);
  }
  const double median = Quantile(sample, 0.5);
  for (double& v : sample) v = std::abs(v - median);
  const double sigma = 1.4826 * Quantile(sample, 0.5);
  return std::max(min_saturation, median + 3.0 * sigma + 15.0);
}

// Distance-transform maxima of one hole-filled region: each an inscribed
// circle (centre, radius), larger first, none inside another's circle.
std::vector<cv::Vec3f> DiscCentres(const cv::Mat1b& region, double min_radius_px) {
  cv::Mat1f dist;
  cv::distanceTransform(region, dist, cv::DIST_L2, cv::DIST_MASK_PRECISE);
  const int k = 2 * static_cast<int>(std::ceil(min_radius_px)) + 1;
  cv::Mat1f dilated;
  cv::dilate(dist, dilated, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(k, k)));
  std::vector<cv::Vec3f> peaks;
  for (int y = 0; y < dist.rows; ++y) {
    for (int x = 0; x < dist.cols; ++x) {
      const float d = dist(y, x);
      if (d >= min_radius_px && d >= dilated(y, x)) peaks.push_back({float(x), float(y), d});
    }
  }
  std::sort(peaks.begin(), peaks.end(), [](const cv::Vec3f& a, const cv::Vec3f& b) {
    return a[2] > b[2] || (a[2] == b[2] && (a[1] < b[1] || (a[1] == b[1] && a[0] < b[0])));
  });
  std::vector<cv::Vec3f> kept;
  for (const cv::Vec3f& p : peaks) {
    const bool inside = std::any_of(kept.begin(), kept.end(), [&](const cv::Vec3f& q) {
      // Markers do not overlap: two maxima closer than 0.8 of their radii's
      // sum are one shape's (a plateau, a ridge).
      return std::hypot(p[0] - q[0], p[1] - q[1]) < 0.8 * (p[2] + q[2]);
    });
    if (!inside) kept.push_back(p);
  }
  return kept;
}

// Same colour as the core for the ring test: saturated, hue within the
// clustering tolerance.
bool SameColour(const cv::Vec3b& hsv, double hue, double s_threshold, double hue_tolerance) {
  return hsv[1] > s_threshold && std::abs(HueDifference(hsv[0], hue)) <= hue_tolerance;
}

// A disc touching the frame's edge along a chord longer than this many
// radii is cut by it (cut 0.13 r deep or more: 3.5 px at 27 px): its
// area and centroid are not the disc's. A disc that only grazes the edge,
// as two of the labelled candies in smarties.png do, is whole.
constexpr double kMaxEdgeChord = 1.0;

// The longest run of the region's pixels along one of the frame's edges
// within 1.2 radii of (cx, cy). `region` has a one-pixel border and
// starts at box's corner.
double EdgeChordPx(const cv::Mat1b& region, const cv::Rect& box, const cv::Size& frame, double cx,
                   double cy, double r) {
  int longest = 0;
  auto count = [&](int x0, int y0, int dx, int dy, int n) {
    int run = 0;
    for (int i = 0; i < n; ++i) {
      const int fx = x0 + i * dx, fy = y0 + i * dy;  // frame pixel
      const bool near = std::hypot(fx - cx, fy - cy) <= 1.2 * r;
      const bool in = near && region(fy - box.y + 1, fx - box.x + 1) != 0;
      run = in ? run + 1 : 0;
      longest = std::max(longest, run);
    }
  };
  if (box.x == 0) count(0, box.y, 0, 1, box.height);
  if (box.y == 0) count(box.x, 0, 1, 0, box.width);
  if (box.x + box.width == frame.width) count(frame.width - 1, box.y, 0, 1, box.height);
  if (box.y + box.height == frame.height) count(box.x, frame.height - 1, 1, 0, box.width);
  return longest;
}

struct FrameDiscs {
  std::vector<DiscSamples> discs;
  cv::Mat3b norm;        // the normalised frame
  cv::Mat3b hsv;         // the normalised frame in HSV
  cv::Mat1b background;  // 255 where no disc is near
};

enum class Verdict { kDisc, kNoColour, kInBody };

// Measures one candidate disc (centre and radius in frame pixels) on the
// normalised frame: its core's median colour, its core samples, and
// whether it is a disc at all: kNoColour when its core is not one
// saturated colour, kInBody when too much of its surroundings has its
// colour (core_hsv is set then).
Verdict MeasureDisc(const cv::Mat3b& norm, const cv::Mat3b& hsv, double s_threshold, double cx,
                    double cy, double r, const ColourLearningOptions& o, DiscSamples* out) {
  const double core = std::max(1.0, kCoreFraction * r);
  std::vector<double> hues, sats, vals;
  std::vector<cv::Vec3b> bgr;
  const int x0 = std::max(0, static_cast<int>(std::floor(cx - 1.6 * r)));
  const int x1 = std::min(norm.cols - 1, static_cast<int>(std::ceil(cx + 1.6 * r)));
  const int y0 = std::max(0, static_cast<int>(std::floor(cy - 1.6 * r)));
  const int y1 = std::min(norm.rows - 1, static_cast<int>(std::ceil(cy + 1.6 * r)));
  for (int y = y0; y <= y1; ++y) {
    for (int x = x0; x <= x1; ++x) {
      const double d = std::hypot(x - cx, y - cy);
      if (d > kSampleFraction * r) continue;
      const cv::Vec3b& p = hsv(y, x);
      // A specular highlight or a printed mark is not the marker's colour
      // (its hue is noise).
      if (p[1] <= s_threshold || p[2] < o.min_value) continue;
      bgr.push_back(norm(y, x));
      if (d > core) continue;
      hues.push_back(p[0]);
      sats.push_back(p[1]);
      vals.push_back(p[2]);
    }
  }
  if (hues.size() < 3) return Verdict::kNoColour;
  const double hue = HueMedian(hues);
  const double sat = Quantile(sats, 0.5);
  const double val = Quantile(vals, 0.5);
  if (sat <= s_threshold || val < o.min_value) return Verdict::kNoColour;
  // A coherent colour: most core pixels within the clustering tolerance.
  const auto coherent = std::count_if(hues.begin(), hues.end(), [&](double h) {
    return std::abs(HueDifference(h, hue)) <= o.cluster_hue;
  });
  if (coherent < 0.8 * static_cast<double>(hues.size())) return Verdict::kNoColour;
  int ring = 0, ring_same = 0;
  for (int y = y0; y <= y1; ++y) {
    for (int x = x0; x <= x1; ++x) {
      const double d = std::hypot(x - cx, y - cy);
      if (d < 1.2 * r || d > 1.6 * r) continue;
      ++ring;
      if (SameColour(hsv(y, x), hue, s_threshold, o.cluster_hue)) ++ring_same;
    }
  }
  out->disc.u_px = cx;
  out->disc.v_px = cy;
  out->disc.radius_px = r;
  out->disc.core_hsv = {hue, sat, val};
  if (ring > 0 && ring_same > kMaxRingShare * ring) return Verdict::kInBody;
  // Evenly spaced samples, so large discs do not outweigh small ones.
  const size_t step = std::max<size_t>(1, bgr.size() / kMaxSamplesPerDisc);
  for (size_t i = 0; i < bgr.size(); i += step) out->bgr.push_back(bgr[i]);
  return Verdict::kDisc;
}

// The discs of one frame (frame index `index`) and its background mask.
FrameDiscs DiscsOfFrame(const cv::Mat& frame, int index, const ColourLearningOptions& o) {
  FrameDiscs out;
  out.norm = NormaliseIllumination(frame, o.lighting, o.background_v_ref);
  const cv::Mat3b& norm = out.norm;
  cv::Mat3b& hsv = out.hsv;
  cv::cvtColor(norm, hsv, cv::COLOR_BGR2HSV);
  cv::Mat1b channels[3];
  cv::split(hsv, channels);
  const double s_threshold = SaturationThreshold(channels[1], o.min_saturation);
  cv::Mat1b mask = (channels[1] > s_threshold) & (channels[2] >= o.min_value);
  // Fill holes (a specular highlight, a printed dot) so the distance
  // transform sees each disc whole.
  std::vector<std::vector<cv::Point>> contours;
  cv::findContours(mask, contours, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_SIMPLE);
  out.background = cv::Mat1b(frame.size(), uchar{255});
  const double min_area = 0.5 * M_PI * o.min_radius_px * o.min_radius_px;
  for (size_t c = 0; c < contours.size(); ++c) {
    if (cv::contourArea(contours[c]) < min_area) continue;
    const cv::Rect box = cv::boundingRect(contours[c]);
    if (box.x == 0 || box.y == 0 || box.x + box.width == frame.cols ||
        box.y + box.height == frame.rows) {
      // Cut by the frame's edge: whatever it is, it is neither a whole disc
      // to learn from nor background to keep out (a marker half in view).
      cv::drawContours(out.background, contours, static_cast<int>(c), cv::Scalar(0), cv::FILLED);
    }
    // One pixel of zeros around, so the distance transform measures to the
    // region's edge and a disc cut by the frame's edge is measured short.
    cv::Mat1b region = cv::Mat1b::zeros(box.height + 2, box.width + 2);
    cv::drawContours(region, contours, static_cast<int>(c), cv::Scalar(255), cv::FILLED, cv::LINE_8,
                     cv::noArray(), 0, cv::Point(1 - box.x, 1 - box.y));
    const std::vector<cv::Vec3f> centres = DiscCentres(region, o.min_radius_px);
    const cv::Moments m = cv::moments(region, true);
    std::vector<DiscSamples> discs;
    std::vector<double> body_hues;
    for (const cv::Vec3f& p : centres) {
      // The inscribed circle runs to the edge pixels' centres: +0.5 px.
      double r = p[2] + 0.5;
      double cx = box.x - 1 + p[0], cy = box.y - 1 + p[1];
      if (centres.size() == 1 && m.m00 > 0.0 &&
          std::abs(m.m00 - M_PI * r * r) < 0.35 * M_PI * r * r) {
        // One disc alone: its area and centroid beat the inscribed circle
        // (a dent from a highlight the fill missed shifts the maximum).
        cx = box.x - 1 + m.m10 / m.m00;
        cy = box.y - 1 + m.m01 / m.m00;
        r = std::sqrt(m.m00 / M_PI);
      }
      if (r > o.max_radius_px) continue;
      DiscSamples d;
      const Verdict verdict = MeasureDisc(norm, hsv, s_threshold, cx, cy, r, o, &d);
      if (verdict == Verdict::kInBody) body_hues.push_back(d.disc.core_hsv[0]);
      if (verdict != Verdict::kDisc) continue;
      d.disc.frame = index;
      d.disc.clipped = EdgeChordPx(region, box, frame.size(), cx, cy, r) > kMaxEdgeChord * r;
      discs.push_back(std::move(d));
    }
    // A region where some maxima sit inside a body of their colour is a
    // body (a bar, a robot's shell): its other maxima of that colour are
    // the body's ends, not discs.
    for (DiscSamples& d : discs) {
      const bool in_body = std::any_of(body_hues.begin(), body_hues.end(), [&](double h) {
        return std::abs(HueDifference(h, d.disc.core_hsv[0])) <= o.cluster_hue;
      });
      if (in_body) continue;
      cv::circle(out.background, cv::Point2d(d.disc.u_px, d.disc.v_px),
                 static_cast<int>(std::ceil(1.4 * d.disc.radius_px)), cv::Scalar(0), cv::FILLED);
      out.discs.push_back(std::move(d));
    }
  }
  return out;
}

double ClusterDistance(const std::array<double, 3>& a, const std::array<double, 3>& b,
                       const ColourLearningOptions& o) {
  const double dh = std::abs(HueDifference(a[0], b[0])) / o.cluster_hue;
  const double ds = std::abs(a[1] - b[1]) / o.cluster_saturation;
  const double dv = std::abs(std::log(std::max(1.0, a[2]) / std::max(1.0, b[2]))) /
                    std::log(o.cluster_value_ratio);
  return std::max({dh, ds, dv});
}

// Average-linkage agglomeration of the discs' core colours until the
// nearest two clusters are a unit apart. Labelled discs seed one cluster
// per label and never merge with another label's. The distances between
// clusters are kept in a matrix and updated by Lance and Williams' rule
// for average linkage, d(a + b, c) = (|a| d(a, c) + |b| d(b, c)) / (|a| +
// |b|), so each disc pair's distance is computed once: O(n^2) memory and
// distances, O(n^3) cheap comparisons (1000 discs: well under a second).
std::vector<std::vector<int>> Cluster(const std::vector<DiscSamples>& discs,
                                      const ColourLearningOptions& o) {
  std::vector<std::vector<int>> clusters;
  std::vector<std::string> labels;
  std::map<std::string, size_t> by_label;
  for (int i = 0; i < static_cast<int>(discs.size()); ++i) {
    if (discs[i].disc.clipped) continue;
    const std::string& label = discs[i].disc.label;
    if (!label.empty() && by_label.count(label) > 0) {
      clusters[by_label[label]].push_back(i);
      continue;
    }
    if (!label.empty()) by_label[label] = clusters.size();
    clusters.push_back({i});
    labels.push_back(label);
  }
  const size_t n = clusters.size();
  constexpr float kApart = std::numeric_limits<float>::infinity();  // two labels
  std::vector<float> d(n * n, 0.0f);
  for (size_t a = 0; a < n; ++a) {
    for (size_t b = a + 1; b < n; ++b) {
      float v = kApart;
      if (labels[a].empty() || labels[b].empty()) {
        double sum = 0.0;
        for (int i : clusters[a]) {
          for (int j : clusters[b]) {
            sum += ClusterDistance(discs[i].disc.core_hsv, discs[j].disc.core_hsv, o);
          }
        }
        v = static_cast<float>(sum / (clusters[a].size() * clusters[b].size()));
      }
      d[a * n + b] = d[b * n + a] = v;
    }
  }
  std::vector<bool> alive(n, true);
  for (;;) {
    float best = 1.0f;
    size_t ba = 0, bb = 0;
    for (size_t a = 0; a < n; ++a) {
      if (!alive[a]) continue;
      for (size_t b = a + 1; b < n; ++b) {
        if (alive[b] && d[a * n + b] < best) {
          best = d[a * n + b];
          ba = a;
          bb = b;
        }
      }
    }
    if (best >= 1.0f) break;
    const double na = static_cast<double>(clusters[ba].size());
    const double nb = static_cast<double>(clusters[bb].size());
    for (size_t c = 0; c < n; ++c) {
      if (!alive[c] || c == ba || c == bb) continue;
      const float dac = d[ba * n + c], dbc = d[bb * n + c];
      const float v = (dac == kApart || dbc == kApart)
                          ? kApart
                          : static_cast<float>((na * dac + nb * dbc) / (na + nb));
      d[ba * n + c] = d[c * n + ba] = v;
    }
    clusters[ba].insert(clusters[ba].end(), clusters[bb].begin(), clusters[bb].end());
    if (labels[ba].empty()) labels[ba] = labels[bb];
    alive[bb] = false;
  }
  std::vector<std::vector<int>> out;
  for (size_t a = 0; a < n; ++a) {
    if (alive[a]) out.push_back(std::move(clusters[a]));
  }
  return out;
}

// A colour's hue, saturation and value after the white-balance budget
// moves its red and blue gains by +g and -g (sign +1) or -g and +g (-1).
Hsv WhiteBalanced(const cv::Vec3b& bgr, double g, int sign) {
  const cv::Vec3b moved(cv::saturate_cast<uchar>(bgr[0] * (1.0 - sign * g)), bgr[1],
                        cv::saturate_cast<uchar>(bgr[2] * (1.0 + sign * g)));
  return ToHsv(moved);
}

// The raw extent of a cluster's core pixels (no margins), around its median.
struct Extent {
  std::array<double, 3> median{};
  std::array<double, 3> lo{};  // hue as an offset from the median
  std::array<double, 3> hi{};
  // S and V at the 5 % quantile: how far a box's floor may rise to keep
  // the background out (a twentieth of the class's pixels then lost: the
  // chroma-blurred rims JPEG's 4:2:0 leaves on small markers).
  std::array<double, 3> floor_limit{};
};

constexpr double kMaxFloorLoss = 0.05;

Extent MeasureExtent(const std::vector<Hsv>& px, double q) {
  std::vector<double> h, s, v;
  for (const Hsv& p : px) {
    h.push_back(p.h);
    s.push_back(p.s);
    v.push_back(p.v);
  }
  Extent e;
  e.median = {HueMedian(h), Quantile(s, 0.5), Quantile(v, 0.5)};
  for (double& x : h) x = HueDifference(x, e.median[0]);
  e.lo = {Quantile(h, q), Quantile(s, q), Quantile(v, q)};
  e.hi = {Quantile(h, 1.0 - q), Quantile(s, 1.0 - q), Quantile(v, 1.0 - q)};
  e.floor_limit = {0.0, Quantile(s, kMaxFloorLoss), Quantile(v, kMaxFloorLoss)};
  return e;
}

int WrapHue(double h) {
  int v = static_cast<int>(std::lround(h)) % 180;
  return v < 0 ? v + 180 : v;
}

// The box around an extent, widened by the drift budget.
LearnedClass BoxFromExtent(const Extent& e, const cv::Vec3b& median_bgr,
                           const ColourLearningOptions& o) {
  LearnedClass c;
  c.median_hsv = e.median;
  const Hsv plus = WhiteBalanced(median_bgr, o.white_balance_drift, +1);
  const Hsv minus = WhiteBalanced(median_bgr, o.white_balance_drift, -1);
  const double dh_plus = HueDifference(plus.h, e.median[0]);
  const double dh_minus = HueDifference(minus.h, e.median[0]);
  c.white_balance_hue_shift = std::max(std::abs(dh_plus), std::abs(dh_minus));
  const double h_lo = e.lo[0] + std::min({0.0, dh_plus, dh_minus}) - kHueQuantisation;
  const double h_hi = e.hi[0] + std::max({0.0, dh_plus, dh_minus}) + kHueQuantisation;
  if (h_hi - h_lo >= 179.0) {
    c.hsv_min[0] = 0;
    c.hsv_max[0] = 179;
  } else {
    c.hsv_min[0] = WrapHue(e.median[0] + h_lo);
    c.hsv_max[0] = WrapHue(e.median[0] + h_hi);
  }
  const double s_wb =
      std::min<double>({0.0, double(plus.s) - e.median[1], double(minus.s) - e.median[1]});
  c.hsv_min[1] = std::clamp(
      static_cast<int>(std::floor((e.lo[1] + s_wb) * (1.0 - o.saturation_loss))), 1, 255);
  c.hsv_max[1] = 255;
  c.hsv_min[2] =
      std::clamp(static_cast<int>(std::floor(e.lo[2] * (1.0 - o.exposure_drift))), 1, 255);
  c.hsv_max[2] = 255;
  return c;
}

// Where two classes' colours part on one channel: the cut between their
// medians that the fewest of their pixels fall on the wrong side of.
struct Cut {
  int channel = -1;
  double at = 0.0;      // hue, S or V; pixels of the lower class lie below
  bool a_below = true;  // class a is the lower one (on hue: anticlockwise)
  double error = 1.0;   // share of a's plus share of b's on the wrong side
};

double Coordinate(const Hsv& p, int channel, double hue_origin) {
  if (channel == 0) return HueDifference(p.h, hue_origin);
  return channel == 1 ? p.s : p.v;
}

// The medians must stand apart by more than the drift moves them, or no
// cut survives the lab's light: on hue by the white-balance shifts of both
// colours and two units more; on S by the saturation a worn marker loses;
// on V by the exposure the normalisation leaves.
bool ApartOn(int channel, const Extent& ea, const Extent& eb, double wb_shift,
             const ColourLearningOptions& o) {
  if (channel == 0) {
    return std::abs(HueDifference(ea.median[0], eb.median[0])) >= wb_shift + kHueQuantisation;
  }
  const double lo = std::min(ea.median[channel], eb.median[channel]);
  const double hi = std::max(ea.median[channel], eb.median[channel]);
  const double drift = channel == 1 ? o.saturation_loss : o.exposure_drift;
  return hi > std::max(1.0, lo) * (1.0 + drift) / (1.0 - drift);
}

// How far the drift moves a channel between two classes: hue by the
// white-balance shift plus the table's quantisation, S by the wear of the
// less saturated, V by the exposure of the darker.
double DriftScale(int channel, const Extent& ea, const Extent& eb, double wb_shift,
                  const ColourLearningOptions& o) {
  if (channel == 0) return wb_shift + kHueQuantisation;
  const double lo = std::max(1.0, std::min(ea.median[channel], eb.median[channel]));
  return std::max(1.0, lo * (channel == 1 ? o.saturation_loss : o.exposure_drift));
}

Cut BestCut(const std::vector<Hsv>& pa, const std::vector<Hsv>& pb, const Extent& ea,
            const Extent& eb, double wb_shift, const ColourLearningOptions& o) {
  Cut best;
  double best_margin = 0.0;
  for (int k = 0; k < 3; ++k) {
    if (!ApartOn(k, ea, eb, wb_shift, o)) continue;
    // Hue in offsets from a's median, so the cut lies on the short arc.
    const double origin = ea.median[0];
    const double ma = k == 0 ? 0.0 : ea.median[k];
    const double mb = k == 0 ? HueDifference(eb.median[0], origin) : eb.median[k];
    const bool a_below = ma < mb;
    std::vector<std::pair<double, double>> errors;  // (cut, error)
    for (double at = std::min(ma, mb) + 0.5; at < std::max(ma, mb); at += 1.0) {
      int wrong_a = 0, wrong_b = 0;
      for (const Hsv& p : pa) wrong_a += (Coordinate(p, k, origin) < at) != a_below;
      for (const Hsv& p : pb) wrong_b += (Coordinate(p, k, origin) < at) == a_below;
      errors.emplace_back(at, static_cast<double>(wrong_a) / std::max<size_t>(1, pa.size()) +
                                  static_cast<double>(wrong_b) / std::max<size_t>(1, pb.size()));
    }
    if (errors.empty()) continue;
    // Of the cuts within half a percent of the least error, the middle
    // one: the widest margin on both sides (brown and orange candies part
    // anywhere between V 80 and 200).
    double least = 1.0;
    for (const auto& e : errors) least = std::min(least, e.second);
    double first = 0.0, last = 0.0;
    bool seen = false;
    for (const auto& e : errors) {
      if (e.second > least + 0.005) continue;
      if (!seen) first = e.first;
      last = e.first;
      seen = true;
    }
    // Between channels: the least error, and of equal errors the widest
    // range of good cuts in units of what the drift moves that channel.
    const double margin = (last - first + 1.0) / DriftScale(k, ea, eb, wb_shift, o);
    if (least < best.error - 0.005 || (least <= best.error + 0.005 && margin > best_margin)) {
      const double at = 0.5 * (first + last);
      best = {k, k == 0 ? at + origin : at, a_below, least};
      best_margin = margin;
    }
  }
  return best;
}

// Two overlapping boxes are cut apart where their pixels part best; false
// when no channel parts their medians by more than the drift, or when the
// best cut leaves more than a quarter of their pixels (both classes'
// shares summed) on the wrong side. Up to that a blob is still found: the
// mask's smoothing keeps a disc whose pixels are mostly its class's (the
// orange and red candies of smarties.png share hue 1 to 5 and lose 12 %
// at the best cut), and the class is reported fragile.
constexpr double kMaxCutError = 0.25;

bool Separate(const Cut& cut, LearnedClass* a, LearnedClass* b) {
  if (cut.channel < 0 || cut.error > kMaxCutError) return false;
  LearnedClass* low = cut.a_below ? a : b;
  LearnedClass* high = cut.a_below ? b : a;
  const int k = cut.channel;
  // Integers in the box: the low one ends at floor(cut), the high one
  // starts at the next unit.
  const int edge = static_cast<int>(std::floor(cut.at));
  if (k == 0) {
    low->hsv_max[0] = WrapHue(edge);
    high->hsv_min[0] = WrapHue(edge + 1);
  } else {
    low->hsv_max[k] = std::min(low->hsv_max[k], edge);
    high->hsv_min[k] = std::max(high->hsv_min[k], edge + 1);
  }
  return true;
}

bool BoxesOverlap(const LearnedClass& a, const LearnedClass& b) {
  MarkerClass ma, mb;
  ma.hsv_min = a.hsv_min;
  ma.hsv_max = a.hsv_max;
  mb.hsv_min = b.hsv_min;
  mb.hsv_max = b.hsv_max;
  return HsvRangesOverlap(ma, mb);
}

std::string DescribeExtent(const Extent& e) {
  auto r = [](double x) { return std::to_string(static_cast<int>(std::lround(x))); };
  return "H " + r(WrapHue(e.median[0] + e.lo[0])) + ".." + r(WrapHue(e.median[0] + e.hi[0])) +
         ", S " + r(e.lo[1]) + ".." + r(e.hi[1]) + ", V " + r(e.lo[2]) + ".." + r(e.hi[2]);
}

// Background pixels inside a box (share) and the background's distance to
// it (its 1/10000 quantile).
void MeasureBackground(const BackgroundHistogram& bg, LearnedClass* c) {
  int64_t inside = 0;
  std::map<int, int64_t> by_distance;
  for (const BackgroundHistogram::Cell& cell : bg.cells) {
    const double d = BoxDistance(*c, cell.h, cell.s, cell.v);
    if (d <= 0.0) inside += cell.n;
    by_distance[static_cast<int>(d)] += cell.n;
  }
  c->background_share = bg.total > 0 ? static_cast<double>(inside) / bg.total : 0.0;
  const int64_t wanted = std::max<int64_t>(1, bg.total / 10000);
  int64_t seen = 0;
  c->background_gap_hsv = 0.0;
  for (const auto& [d, n] : by_distance) {
    seen += n;
    if (seen >= wanted) {
      c->background_gap_hsv = d;
      break;
    }
  }
}

// Raises a box's S (then V) floor until the background stays out, never
// above the class's own 5 % quantile. False when it cannot.
bool KeepBackgroundOut(const BackgroundHistogram& bg, const Extent& e, double max_share,
                       LearnedClass* c) {
  MeasureBackground(bg, c);
  for (int k = 1; k < 3 && c->background_share > max_share; ++k) {
    const int limit = static_cast<int>(std::floor(e.floor_limit[k]));
    while (c->background_share > max_share && c->hsv_min[k] + kSvStep <= limit) {
      c->hsv_min[k] += kSvStep;
      MeasureBackground(bg, c);
    }
  }
  return c->background_share <= max_share;
}

std::string Percent(double share) { return fmt::format("{:.3g} %", 100.0 * share); }

struct Learned {
  std::vector<DiscSamples> discs;
  BackgroundHistogram background;
};

void AddBackground(const cv::Mat3b& hsv, const cv::Mat1b& background, int step,
                   BackgroundHistogram* out) {
  for (int y = 0; y < hsv.rows; y += step) {
    const uchar* b = background.ptr<uchar>(y);
    const cv::Vec3b* p = hsv.ptr<cv::Vec3b>(y);
    for (int x = 0; x < hsv.cols; x += step) {
      if (b[x]) out->Add(p[x]);
    }
  }
}

Learned Collect(const std::vector<cv::Mat>& frames, const ColourLearningOptions& o) {
  Learned l;
  for (size_t f = 0; f < frames.size(); ++f) {
    if (frames[f].empty() || frames[f].type() != CV_8UC3) continue;
    FrameDiscs fd = DiscsOfFrame(frames[f], static_cast<int>(f), o);
    AddBackground(fd.hsv, fd.background, 1, &l.background);
    // The background under the white-balance budget too: a grey floor
    // turns reddish or bluish with it (S 23 becomes S 60 at 12 %), and a
    // box must keep it out then as well. On every second pixel each way.
    for (int sign : {+1, -1}) {
      cv::Mat3b moved, hsv;
      cv::multiply(
          fd.norm,
          cv::Scalar(1.0 - sign * o.white_balance_drift, 1.0, 1.0 + sign * o.white_balance_drift),
          moved);
      cv::cvtColor(moved, hsv, cv::COLOR_BGR2HSV);
      AddBackground(hsv, fd.background, 2, &l.background);
    }
    for (DiscSamples& d : fd.discs) l.discs.push_back(std::move(d));
  }
  l.background.Compact();
  return l;
}

void Label(const std::vector<KnownMarker>& known, std::vector<DiscSamples>* discs) {
  for (const KnownMarker& k : known) {
    DiscSamples* best = nullptr;
    double best_d = k.reach_px;
    for (DiscSamples& d : *discs) {
      if (d.disc.frame != k.frame) continue;
      const double dist = std::hypot(d.disc.u_px - k.u_px, d.disc.v_px - k.v_px);
      if (dist <= best_d && dist >= k.min_distance_px) {
        best_d = dist;
        best = &d;
      }
    }
    if (best != nullptr) best->disc.label = k.class_name;
  }
}

// The name of an unlabelled cluster: the one site box its median colour
// lies in, else empty.
std::string SiteName(const std::array<double, 3>& hsv, const std::vector<MarkerClass>& site) {
  std::string name;
  int matches = 0;
  for (const MarkerClass& m : site) {
    LearnedClass box;
    box.hsv_min = m.hsv_min;
    box.hsv_max = m.hsv_max;
    if (InBox(box, hsv[0], hsv[1], hsv[2])) {
      name = m.name;
      ++matches;
    }
  }
  return matches == 1 ? name : std::string();
}

// The gap from a's pixels (their extent) to b's box on one channel, hue
// on its circle; 0 or less when they meet.
double ExtentToBoxGap(const Extent& ea, const LearnedClass& b, int k) {
  if (k > 0) return std::max(b.hsv_min[k] - ea.hi[k], ea.lo[k] - b.hsv_max[k]);
  const double lo = ea.median[0] + ea.lo[0], hi = ea.median[0] + ea.hi[0];
  if (InHue(b.hsv_min[0], b.hsv_max[0], WrapHue(lo)) ||
      InHue(b.hsv_min[0], b.hsv_max[0], WrapHue(hi)) ||
      (HueDifference(b.hsv_min[0], ea.median[0]) >= ea.lo[0] &&
       HueDifference(b.hsv_min[0], ea.median[0]) <= ea.hi[0])) {
    return 0.0;
  }
  return std::min(std::abs(HueDifference(b.hsv_min[0], hi)),
                  std::abs(HueDifference(lo, b.hsv_max[0])));
}

// Per class: its pixels outside its box and inside another's, and its
// margin to the nearest other class (ExtentToBoxGap against DriftScale).
void Report(const std::vector<std::vector<Hsv>>& pixels, const std::vector<Extent>& extents,
            const ColourLearningOptions& o, std::vector<LearnedClass>* classes) {
  const char* channels[] = {"hue", "saturation", "value"};
  for (size_t a = 0; a < classes->size(); ++a) {
    LearnedClass& c = (*classes)[a];
    int outside = 0, confused = 0;
    for (const Hsv& p : pixels[a]) {
      if (!InBox(c, p.h, p.s, p.v)) ++outside;
      for (size_t b = 0; b < classes->size(); ++b) {
        if (b != a && InBox((*classes)[b], p.h, p.s, p.v)) {
          ++confused;
          break;
        }
      }
    }
    const double n = static_cast<double>(std::max<size_t>(1, pixels[a].size()));
    c.own_outside_share = outside / n;
    c.own_in_neighbour_share = confused / n;
    double nearest = 1e9;
    for (size_t b = 0; b < classes->size(); ++b) {
      if (b == a) continue;
      const double wb = std::max(c.white_balance_hue_shift, (*classes)[b].white_balance_hue_shift);
      // The channel on which a's pixels stand furthest from b's box, in
      // units of the drift there.
      int best = 0;
      double best_ratio = -1e9, best_gap = 0.0, best_scale = 1.0;
      for (int k = 0; k < 3; ++k) {
        const double gap = ExtentToBoxGap(extents[a], (*classes)[b], k);
        const double scale = DriftScale(k, extents[a], extents[b], wb, o);
        if (gap / scale > best_ratio) {
          best = k;
          best_ratio = gap / scale;
          best_gap = gap;
          best_scale = scale;
        }
      }
      if (best_ratio < nearest) {
        nearest = best_ratio;
        c.nearest_neighbour = (*classes)[b].name;
        c.neighbour_channel = channels[best];
        c.neighbour_gap_hsv = std::max(0.0, best_gap);
        c.neighbour_drift_hsv = best_scale;
      }
    }
  }
}

void JudgeFragile(std::vector<LearnedClass>* classes) {
  auto n = [](double x) { return std::to_string(static_cast<int>(std::lround(x))); };
  for (LearnedClass& c : *classes) {
    std::vector<std::string> why;
    if (c.own_outside_share > 0.01) {
      why.push_back(Percent(c.own_outside_share) + " of its own pixels fall outside its box");
    }
    if (c.own_in_neighbour_share > 0.001) {
      why.push_back(Percent(c.own_in_neighbour_share) + " of its pixels fall in " +
                    c.nearest_neighbour + "'s box");
    }
    if (!c.nearest_neighbour.empty() && c.neighbour_gap_hsv < c.neighbour_drift_hsv) {
      why.push_back("its pixels lie " + n(c.neighbour_gap_hsv) + " " + c.neighbour_channel +
                    " units from " + c.nearest_neighbour + "'s box, less than the " +
                    n(c.neighbour_drift_hsv) + " the drift budget moves them");
    }
    c.fragile.clear();
    for (const std::string& w : why) c.fragile += (c.fragile.empty() ? "" : "; ") + w;
  }
}

std::string WhyNotApart(const LearnedClass& a, const LearnedClass& b, const Extent& ea,
                        const Extent& eb, const Cut& cut, const ColourLearningOptions& o) {
  auto n = [](double x) { return std::to_string(static_cast<int>(std::lround(x))); };
  const std::string names = "'" + a.name + "' and '" + b.name + "' cannot be told apart: ";
  const std::string colours = " (" + DescribeExtent(ea) + " against " + DescribeExtent(eb) + ")";
  if (cut.channel < 0) {
    return names + "their hues lie " + n(std::abs(HueDifference(ea.median[0], eb.median[0]))) +
           " units apart, within the " +
           n(std::max(a.white_balance_hue_shift, b.white_balance_hue_shift)) +
           "-unit shift a white balance drift of " + n(100.0 * o.white_balance_drift) +
           " % causes (plus 2), and their saturation and value differ by less than wear and "
           "exposure move them" +
           colours +
           ". Replace one with a colour of another hue, or fix the camera's white balance "
           "(docs/camera.md) and state the smaller drift";
  }
  const char* channel[] = {"hue", "saturation", "value"};
  return names + "their colours overlap: the best cut, on " + channel[cut.channel] + " at " +
         n(cut.at) + ", leaves " + Percent(cut.error) + " of their pixels on the wrong side" +
         colours + ". Replace one with a colour of another hue";
}

}  // namespace

bool ColourLearningOptions::IsValid(std::string* error) const {
  auto fail = [&](const std::string& what) {
    *error = "colour learning: " + what;
    return false;
  };
  if (!(background_v_ref > 0.0 && background_v_ref <= 255.0))
    return fail("background_v_ref must be in (0, 255]");
  if (!(min_radius_px >= 1.0 && max_radius_px >= min_radius_px && std::isfinite(max_radius_px))) {
    return fail("radii must satisfy 1 <= min_radius_px <= max_radius_px (finite)");
  }
  if (!(min_saturation >= 0.0 && min_saturation < 255.0))
    return fail("min_saturation must be in [0, 255)");
  if (!(min_value >= 0.0 && min_value < 255.0)) return fail("min_value must be in [0, 255)");
  for (double d : {white_balance_drift, exposure_drift, saturation_loss}) {
    if (!(d >= 0.0 && d < 1.0)) return fail("drifts and saturation_loss must be in [0, 1)");
  }
  if (!(spread_quantile >= 0.0 && spread_quantile < 0.5))
    return fail("spread_quantile must be in [0, 0.5)");
  if (!(cluster_hue > 0.0 && cluster_saturation > 0.0 && cluster_value_ratio > 1.0)) {
    return fail("cluster tolerances must be positive (value ratio above 1)");
  }
  if (!(max_background_share >= 0.0 && max_background_share < 1.0))
    return fail("max_background_share must be in [0, 1)");
  return true;
}

std::vector<FoundDisc> FindDiscs(const std::vector<cv::Mat>& frames,
                                 const ColourLearningOptions& options) {
  std::vector<FoundDisc> out;
  for (size_t f = 0; f < frames.size(); ++f) {
    if (frames[f].empty() || frames[f].type() != CV_8UC3) continue;
    for (DiscSamples& d : DiscsOfFrame(frames[f], static_cast<int>(f), options).discs) {
      out.push_back(d.disc);
    }
  }
  return out;
}

ColourLearning LearnColours(const std::vector<cv::Mat>& frames,
                            const std::vector<KnownMarker>& known,
                            const std::vector<MarkerClass>& site_classes,
                            const ColourLearningOptions& o, int min_classes) {
  ColourLearning result;
  result.frames = static_cast<int>(frames.size());
  Learned l = Collect(frames, o);
  result.background_pixels = l.background.total;
  Label(known, &l.discs);
  auto finish = [&](const std::string& refusal) {
    for (const DiscSamples& d : l.discs) result.discs.push_back(d.disc);
    result.refusal = refusal;
    return result;
  };
  if (l.discs.size() > kMaxDiscs) {
    return finish(std::to_string(l.discs.size()) + " discs found, over the " +
                  std::to_string(kMaxDiscs) +
                  " learning takes: fewer frames, or a floor without coloured dots");
  }
  const std::vector<std::vector<int>> clusters = Cluster(l.discs, o);
  if (clusters.empty()) {
    return finish(l.discs.empty() ? "no marker disc found: no saturated round region of " +
                                        std::to_string(static_cast<int>(o.min_radius_px)) + " to " +
                                        std::to_string(static_cast<int>(o.max_radius_px)) +
                                        " px radius in any frame"
                                  : "every marker disc found is cut by the image's edge");
  }
  if (static_cast<int>(clusters.size()) < min_classes) {
    return finish("only " + std::to_string(clusters.size()) + " colour found where " +
                  std::to_string(min_classes) +
                  " classes are needed: each class needs markers of " + "its colour in view");
  }
  std::vector<Extent> extents;
  std::vector<std::vector<Hsv>> pixels(clusters.size());
  int unnamed = 0;
  for (size_t k = 0; k < clusters.size(); ++k) {
    std::vector<cv::Vec3b> bgr;
    double r_min = 1e9, r_max = 0.0;
    for (int i : clusters[k]) {
      l.discs[i].disc.cluster = static_cast<int>(k);
      r_min = std::min(r_min, l.discs[i].disc.radius_px);
      r_max = std::max(r_max, l.discs[i].disc.radius_px);
      for (const cv::Vec3b& p : l.discs[i].bgr) {
        bgr.push_back(p);
        pixels[k].push_back(ToHsv(p));
      }
    }
    extents.push_back(MeasureExtent(pixels[k], o.spread_quantile));
    std::vector<double> b, g, r;
    for (const cv::Vec3b& p : bgr) {
      b.push_back(p[0]);
      g.push_back(p[1]);
      r.push_back(p[2]);
    }
    const cv::Vec3b median_bgr(cv::saturate_cast<uchar>(Quantile(b, 0.5)),
                               cv::saturate_cast<uchar>(Quantile(g, 0.5)),
                               cv::saturate_cast<uchar>(Quantile(r, 0.5)));
    LearnedClass c = BoxFromExtent(extents.back(), median_bgr, o);
    c.discs = static_cast<int>(clusters[k].size());
    c.core_pixels = static_cast<int>(pixels[k].size());
    c.min_radius_px = r_min;
    c.max_radius_px = r_max;
    for (int i : clusters[k]) {
      if (!l.discs[i].disc.label.empty()) c.name = l.discs[i].disc.label;
    }
    result.classes.push_back(c);
  }
  // Unlabelled clusters take a site class's name when theirs is the only
  // median in that class's box; two in one box (two reds) are both
  // colour_N, for the person to name.
  std::map<std::string, int> site_matches;
  for (const LearnedClass& c : result.classes) {
    if (c.name.empty()) ++site_matches[SiteName(c.median_hsv, site_classes)];
  }
  for (LearnedClass& c : result.classes) {
    if (!c.name.empty()) continue;
    const std::string site = SiteName(c.median_hsv, site_classes);
    c.name =
        !site.empty() && site_matches[site] == 1 ? site : "colour_" + std::to_string(++unnamed);
  }
  for (size_t a = 0; a < result.classes.size(); ++a) {
    for (size_t b = a + 1; b < result.classes.size(); ++b) {
      LearnedClass& ca = result.classes[a];
      LearnedClass& cb = result.classes[b];
      if (ca.name == cb.name) {
        return finish("two colours took the name '" + ca.name + "' (" + DescribeExtent(extents[a]) +
                      " and " + DescribeExtent(extents[b]) +
                      "): label the markers, or name the clusters");
      }
      if (!BoxesOverlap(ca, cb)) continue;
      const Cut cut = BestCut(pixels[a], pixels[b], extents[a], extents[b],
                              std::max(ca.white_balance_hue_shift, cb.white_balance_hue_shift), o);
      if (!Separate(cut, &ca, &cb) || BoxesOverlap(ca, cb)) {
        return finish(WhyNotApart(ca, cb, extents[a], extents[b], cut, o));
      }
    }
  }
  for (size_t k = 0; k < result.classes.size(); ++k) {
    LearnedClass& c = result.classes[k];
    if (!KeepBackgroundOut(l.background, extents[k], o.max_background_share, &c)) {
      return finish("the floor or the robots' bodies fall into '" + c.name + "'s box (" +
                    Percent(c.background_share) + " of the background pixels, " +
                    DescribeExtent(extents[k]) +
                    "): a marker of a more saturated colour, or a floor of another colour, is "
                    "needed");
    }
  }
  Report(pixels, extents, o, &result.classes);
  JudgeFragile(&result.classes);
  return finish("");
}

ColourLearning LearnColoursForAll(const std::vector<std::vector<cv::Mat>>& sets,
                                  const std::vector<std::vector<KnownMarker>>& known,
                                  const std::vector<MarkerClass>& site_classes,
                                  const ColourLearningOptions& options, int min_classes) {
  std::vector<cv::Mat> frames;
  std::vector<KnownMarker> all_known;
  for (size_t s = 0; s < sets.size(); ++s) {
    const int offset = static_cast<int>(frames.size());
    if (s < known.size()) {
      for (KnownMarker k : known[s]) {
        k.frame += offset;
        all_known.push_back(k);
      }
    }
    frames.insert(frames.end(), sets[s].begin(), sets[s].end());
  }
  return LearnColours(frames, all_known, site_classes, options, min_classes);
}

namespace {

// The learned class nearest a colour within 1.5 clustering units, or -1.
int NearestClass(const std::array<double, 3>& hsv, const std::vector<LearnedClass>& classes,
                 const ColourLearningOptions& o) {
  int nearest = -1;
  double best = 1.5;
  for (size_t k = 0; k < classes.size(); ++k) {
    const double dist = ClusterDistance(hsv, classes[k].median_hsv, o);
    if (dist < best) {
      best = dist;
      nearest = static_cast<int>(k);
    }
  }
  return nearest;
}

}  // namespace

std::vector<KnownMarker> LabelByNearestClass(const std::vector<cv::Mat>& frames,
                                             const std::vector<LearnedClass>& classes,
                                             const ColourLearningOptions& options) {
  std::vector<KnownMarker> known;
  for (const FoundDisc& d : FindDiscs(frames, options)) {
    const int k = d.clipped ? -1 : NearestClass(d.core_hsv, classes, options);
    if (k >= 0) known.push_back({d.frame, d.u_px, d.v_px, 0.5 * d.radius_px, 0.0, classes[k].name});
  }
  return known;
}

std::vector<ColourClass> ToColourClasses(const std::vector<LearnedClass>& classes) {
  std::vector<ColourClass> out;
  for (const LearnedClass& c : classes) {
    ColourClass k;
    k.name = c.name;
    k.hsv_min = c.hsv_min;
    k.hsv_max = c.hsv_max;
    k.min_area_px = M_PI * std::pow(0.5 * c.min_radius_px, 2);
    k.max_area_px = M_PI * std::pow(1.8 * c.max_radius_px, 2);
    out.push_back(k);
  }
  return out;
}

namespace {

// A marker the check looks for: where, how near a blob must be, its class.
struct Target {
  int frame;
  double u_px, v_px, reach_px;
  int class_index;
};

int ClassIndex(const std::vector<LearnedClass>& classes, const std::string& name) {
  for (size_t c = 0; c < classes.size(); ++c) {
    if (classes[c].name == name) return static_cast<int>(c);
  }
  return -1;
}

// The markers to look for: every known marker at a known place (found as
// a disc or not: a marker the light has washed out is a failure too), the
// discs known markers named by distance (heading markers), and without
// known markers every disc of a colour near a learned class's.
std::vector<Target> Targets(const Learned& l, const std::vector<KnownMarker>& known,
                            const std::vector<LearnedClass>& classes,
                            const ColourLearningOptions& o, int* unmatched) {
  std::vector<Target> targets;
  for (const KnownMarker& k : known) {
    const int c = ClassIndex(classes, k.class_name);
    if (c >= 0 && k.min_distance_px <= 0.0) {
      targets.push_back({k.frame, k.u_px, k.v_px, std::max(3.0, k.reach_px), c});
    }
  }
  for (const DiscSamples& s : l.discs) {
    if (s.disc.clipped) continue;
    int c = -1;
    if (!known.empty()) {
      const bool by_place = std::any_of(known.begin(), known.end(), [&](const KnownMarker& k) {
        return k.min_distance_px > 0.0 && k.class_name == s.disc.label && k.frame == s.disc.frame;
      });
      if (by_place) c = ClassIndex(classes, s.disc.label);
    } else {
      c = NearestClass(s.disc.core_hsv, classes, o);
    }
    if (c >= 0) {
      targets.push_back({s.disc.frame, s.disc.u_px, s.disc.v_px, 0.5 * s.disc.radius_px, c});
    } else if (known.empty()) {
      ++*unmatched;
    }
  }
  return targets;
}

}  // namespace

std::vector<ClassCheck> CheckColours(const std::vector<cv::Mat>& frames,
                                     const std::vector<KnownMarker>& known,
                                     const std::vector<LearnedClass>& classes,
                                     const ColourLearningOptions& o, int* unmatched_discs) {
  int unmatched = 0;
  std::vector<ClassCheck> checks(classes.size());
  for (size_t k = 0; k < classes.size(); ++k) checks[k].name = classes[k].name;
  Learned l = Collect(frames, o);
  Label(known, &l.discs);
  DetectorOptions d;
  d.lighting = o.lighting == LightingMode::kAdaptive ? LightingMode::kNormalised : o.lighting;
  d.background_v_ref = o.background_v_ref;
  const MarkerDetector detector(ToColourClasses(classes), d);
  std::vector<std::vector<Blob>> blobs(frames.size());
  for (size_t f = 0; f < frames.size(); ++f) blobs[f] = detector.Detect(frames[f], ImageWindow{});
  for (const Target& t : Targets(l, known, classes, o, &unmatched)) {
    if (t.frame < 0 || t.frame >= static_cast<int>(frames.size())) continue;
    ++checks[t.class_index].discs;
    bool found = false, other = false;
    for (const Blob& b : blobs[t.frame]) {
      if (std::hypot(b.u_px - t.u_px, b.v_px - t.v_px) > t.reach_px) continue;
      (b.class_index == t.class_index ? found : other) = true;
    }
    if (found) ++checks[t.class_index].found;
    if (other) ++checks[t.class_index].found_as_other;
  }
  if (unmatched_discs != nullptr) *unmatched_discs = unmatched;
  return checks;
}

}  // namespace roomfix::vision
