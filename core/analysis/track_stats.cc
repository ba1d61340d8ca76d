#include "core/analysis/track_stats.h"

#include <algorithm>
#include <cmath>

namespace roomfix::analysis {
namespace {

// Bins of width w needed to cover [lo, hi), 0 for the fail-safe cases. A
// range that is a whole number of bins up to rounding error (0.3 / 0.1) gets
// no extra, nearly empty bin.
int64_t BinCount(double lo, double hi, double w) {
  if (!std::isfinite(lo) || !std::isfinite(hi) || !std::isfinite(w) || w <= 0.0 || hi <= lo) {
    return 0;
  }
  const double bins = std::ceil((hi - lo) / w - 1e-9);
  if (!(bins >= 1.0) || bins > static_cast<double>(kMaxHistogramBins)) return 0;
  return static_cast<int64_t>(bins);
}

// Bin of a non-NaN v among n bins from lo: -1 below, n above (also for inf).
int64_t BinOf(double v, double lo, double w, int64_t n) {
  if (v < lo) return -1;
  const double k = std::floor((v - lo) / w);
  if (!(k < static_cast<double>(n))) return n;
  return static_cast<int64_t>(k);
}

struct MeanStd {
  double mean = 0.0, std = 0.0;
};

// Two passes: the one-pass sum of squares loses the millimetre spread of a
// fix several metres from the origin to cancellation.
MeanStd ComputeMeanStd(const std::vector<double>& v) {
  MeanStd m;
  if (v.empty()) return m;
  double sum = 0.0;
  for (double x : v) sum += x;
  m.mean = sum / static_cast<double>(v.size());
  if (v.size() < 2) return m;
  double sum2 = 0.0;
  for (double x : v) sum2 += (x - m.mean) * (x - m.mean);
  m.std = std::sqrt(sum2 / static_cast<double>(v.size() - 1));
  return m;
}

// b - a for b >= a in milliseconds, without the signed overflow of garbage
// utimes far apart.
double IntervalMs(int64_t a, int64_t b) {
  return static_cast<double>(static_cast<uint64_t>(b) - static_cast<uint64_t>(a)) * 1e-3;
}

bool IsFinite(const TimedPosition& p) { return std::isfinite(p.x_m) && std::isfinite(p.y_m); }

// InterpolateTrack needs a sorted track; logs hold fixes in arrival order.
const std::vector<TimedPosition>& SortedByTime(const std::vector<TimedPosition>& track,
                                               std::vector<TimedPosition>* storage) {
  const auto earlier = [](const TimedPosition& a, const TimedPosition& b) {
    return a.utime < b.utime;
  };
  if (std::is_sorted(track.begin(), track.end(), earlier)) return track;
  *storage = track;
  std::stable_sort(storage->begin(), storage->end(), earlier);
  return *storage;
}

}  // namespace

Histogram MakeHistogram(const std::vector<double>& values, double lo, double hi, double bin_width) {
  Histogram h;
  const int64_t n = BinCount(lo, hi, bin_width);
  if (n == 0) return h;
  h.lo = lo;
  h.bin_width = bin_width;
  h.counts.assign(static_cast<size_t>(n), 0);
  for (double v : values) {
    if (std::isnan(v)) continue;
    const int64_t k = BinOf(v, lo, bin_width, n);
    if (k < 0) {
      ++h.below;
    } else if (k >= n) {
      ++h.above;
    } else {
      ++h.counts[static_cast<size_t>(k)];
    }
  }
  return h;
}

Histogram2D MakeHistogram2D(const std::vector<double>& xs, const std::vector<double>& ys,
                            double x_lo, double x_hi, double y_lo, double y_hi, double bin_m) {
  Histogram2D h;
  const int64_t nx = BinCount(x_lo, x_hi, bin_m);
  const int64_t ny = BinCount(y_lo, y_hi, bin_m);
  if (xs.size() != ys.size() || nx == 0 || ny == 0 || nx * ny > kMaxHistogramBins) return h;
  h.x_lo = x_lo;
  h.y_lo = y_lo;
  h.bin_m = bin_m;
  h.nx = static_cast<int>(nx);
  h.ny = static_cast<int>(ny);
  h.counts.assign(static_cast<size_t>(nx * ny), 0);
  for (size_t i = 0; i < xs.size(); ++i) {
    if (std::isnan(xs[i]) || std::isnan(ys[i])) continue;
    const int64_t ix = BinOf(xs[i], x_lo, bin_m, nx);
    const int64_t iy = BinOf(ys[i], y_lo, bin_m, ny);
    if (ix < 0 || ix >= nx || iy < 0 || iy >= ny) {
      ++h.outside;
    } else {
      ++h.counts[static_cast<size_t>(iy * nx + ix)];
    }
  }
  return h;
}

Repeatability ComputeRepeatability(const std::vector<TimedPosition>& samples, double tolerance_m,
                                   double bin_m) {
  Repeatability r;
  r.tolerance_m = tolerance_m;
  std::vector<double> xs, ys;
  for (const TimedPosition& p : samples) {
    if (!IsFinite(p)) continue;
    xs.push_back(p.x_m);
    ys.push_back(p.y_m);
  }
  r.n = static_cast<int>(xs.size());
  if (r.n == 0) return r;
  const MeanStd mx = ComputeMeanStd(xs);
  const MeanStd my = ComputeMeanStd(ys);
  r.mean_x_m = mx.mean;
  r.mean_y_m = my.mean;
  r.std_x_m = mx.std;
  r.std_y_m = my.std;
  int outside = 0;
  for (size_t i = 0; i < xs.size(); ++i) {
    const double dx = std::abs(xs[i] - mx.mean);
    const double dy = std::abs(ys[i] - my.mean);
    r.max_deviation_m = std::max({r.max_deviation_m, dx, dy});
    if (dx > tolerance_m || dy > tolerance_m) ++outside;
  }
  r.share_outside = static_cast<double>(outside) / r.n;
  if (tolerance_m > 0.0 && bin_m > 0.0) {
    const double half_m = 2.0 * tolerance_m;
    r.histogram = MakeHistogram2D(xs, ys, std::floor((mx.mean - half_m) / bin_m) * bin_m,
                                  std::ceil((mx.mean + half_m) / bin_m) * bin_m,
                                  std::floor((my.mean - half_m) / bin_m) * bin_m,
                                  std::ceil((my.mean + half_m) / bin_m) * bin_m, bin_m);
  }
  return r;
}

bool LooksStatic(const std::vector<TimedPosition>& samples, double max_extent_m) {
  std::vector<double> xs, ys;
  for (const TimedPosition& p : samples) {
    if (!IsFinite(p)) continue;
    xs.push_back(p.x_m);
    ys.push_back(p.y_m);
  }
  if (xs.empty()) return false;
  const double median_x = Percentile(xs, 0.5);
  const double median_y = Percentile(ys, 0.5);
  std::vector<double> distances;
  for (size_t i = 0; i < xs.size(); ++i) {
    distances.push_back(std::hypot(xs[i] - median_x, ys[i] - median_y));
  }
  // Nearest rank: the ceil(0.9 n)-th nearest fix, so at least 90% are within.
  return Percentile(distances, 0.9) <= max_extent_m;
}

Timing ComputeTiming(const std::vector<int64_t>& utimes, double frame_rate_hz) {
  Timing t;
  if (std::isfinite(frame_rate_hz) && frame_rate_hz > 0.0) t.frame_period_ms = 1e3 / frame_rate_hz;
  if (utimes.size() < 2) return t;
  std::vector<int64_t> sorted = utimes;
  std::sort(sorted.begin(), sorted.end());
  std::vector<double> intervals_ms;
  for (size_t i = 1; i < sorted.size(); ++i) {
    intervals_ms.push_back(IntervalMs(sorted[i - 1], sorted[i]));
  }
  t.intervals = static_cast<int>(intervals_ms.size());
  const MeanStd m = ComputeMeanStd(intervals_ms);
  t.mean_ms = m.mean;
  t.std_ms = m.std;
  const auto [min_it, max_it] = std::minmax_element(intervals_ms.begin(), intervals_ms.end());
  t.min_ms = *min_it;
  t.max_ms = *max_it;
  t.median_ms = Percentile(intervals_ms, 0.5);
  if (t.mean_ms > 0.0) t.rate_hz = 1e3 / t.mean_ms;

  constexpr double kShownShare = 0.995;
  constexpr double kMinBins = 10.0;
  // With few intervals the 99.5th percentile is the longest one: a single
  // hour-long gap (two sessions merged) would make millions of 1 ms bins.
  // The figure is about the sampling rhythm, so it stops at 20 medians (and
  // never beyond 10 000 bins); longer gaps are counted in `above`.
  const double cap_ms = std::min(std::max(20.0 * t.median_ms, kMinBins), 10000.0);
  const double hi_ms =
      std::min(std::max(std::floor(Percentile(intervals_ms, kShownShare)) + 1.0, kMinBins), cap_ms);
  t.interval_ms = MakeHistogram(intervals_ms, 0.0, hi_ms, 1.0);
  if (t.frame_period_ms > 0.0) {
    std::vector<double> frames;
    for (double ms : intervals_ms) frames.push_back(std::round(ms / t.frame_period_ms));
    const double hi_frames = std::min(std::max(Percentile(frames, kShownShare) + 1.0, kMinBins),
                                      std::max(std::ceil(cap_ms / t.frame_period_ms), kMinBins));
    t.interval_frames = MakeHistogram(frames, 0.0, hi_frames, 1.0);
  }
  return t;
}

LatencySummary SummariseLatency(const std::vector<double>& latencies_ms) {
  LatencySummary s;
  std::vector<double> finite;
  for (double v : latencies_ms) {
    if (std::isfinite(v)) finite.push_back(v);
  }
  if (finite.empty()) return s;
  s.n = static_cast<int>(finite.size());
  s.mean_ms = ComputeMeanStd(finite).mean;
  s.median_ms = Percentile(finite, 0.5);
  s.p95_ms = Percentile(finite, 0.95);
  s.max_ms = *std::max_element(finite.begin(), finite.end());
  return s;
}

Motion ComputeMotion(const std::vector<TimedPosition>& track) {
  Motion m;
  const TimedPosition* first = nullptr;
  const TimedPosition* last = nullptr;
  std::vector<double> speeds_mps;
  for (const TimedPosition& p : track) {
    if (!IsFinite(p)) continue;
    if (last == nullptr) {
      first = last = &p;
      continue;
    }
    if (p.utime <= last->utime) continue;
    const double length_m = std::hypot(p.x_m - last->x_m, p.y_m - last->y_m);
    m.distance_m += length_m;
    speeds_mps.push_back(length_m / (IntervalMs(last->utime, p.utime) * 1e-3));
    last = &p;
  }
  if (last == nullptr) return m;
  m.steps = static_cast<int>(speeds_mps.size());
  m.duration_s = IntervalMs(first->utime, last->utime) * 1e-3;
  const MeanStd s = ComputeMeanStd(speeds_mps);
  m.mean_speed_mps = s.mean;
  m.std_speed_mps = s.std;
  if (!speeds_mps.empty())
    m.max_speed_mps = *std::max_element(speeds_mps.begin(), speeds_mps.end());
  return m;
}

std::vector<ErrorSample> ErrorsOverTime(const std::vector<TimedPosition>& estimates,
                                        const std::vector<TimedPosition>& reference,
                                        int64_t max_gap_us) {
  std::vector<TimedPosition> storage;
  const std::vector<TimedPosition>& ref = SortedByTime(reference, &storage);
  std::vector<ErrorSample> samples;
  for (const TimedPosition& e : estimates) {
    double x_m = 0.0, y_m = 0.0;
    if (!IsFinite(e) || !InterpolateTrack(ref, e.utime, max_gap_us, &x_m, &y_m)) continue;
    const double dx_m = e.x_m - x_m;
    const double dy_m = e.y_m - y_m;
    samples.push_back({e.utime, std::hypot(dx_m, dy_m), dx_m, dy_m});
  }
  return samples;
}

TrackOffset CompareTracks(const std::vector<TimedPosition>& track,
                          const std::vector<TimedPosition>& reference, int64_t max_gap_us) {
  std::vector<TimedPosition> storage;
  const std::vector<TimedPosition>& ref = SortedByTime(reference, &storage);
  const std::vector<ErrorSample> errors = ErrorsOverTime(track, ref, max_gap_us);
  TrackOffset o;
  o.matched = static_cast<int>(errors.size());
  std::vector<double> dxs, dys;
  for (const ErrorSample& e : errors) {
    dxs.push_back(e.dx_m);
    dys.push_back(e.dy_m);
  }
  const MeanStd mx = ComputeMeanStd(dxs);
  const MeanStd my = ComputeMeanStd(dys);
  o.mean_dx_m = mx.mean;
  o.mean_dy_m = my.mean;
  o.std_dx_m = mx.std;
  o.std_dy_m = my.std;
  std::vector<TimedPosition> corrected = track;
  for (TimedPosition& p : corrected) {
    p.x_m -= o.mean_dx_m;
    p.y_m -= o.mean_dy_m;
  }
  o.error_after_offset = CompareToReference(corrected, ref, max_gap_us);
  return o;
}

}  // namespace roomfix::analysis
