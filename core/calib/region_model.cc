#include "core/calib/region_model.h"

#include <algorithm>
#include <cmath>
#include <sstream>

namespace roomfix::calib {
namespace {

// Pixel coordinates closer than this do not determine a slope.
constexpr double kMinSpreadPx = 1.0;

int Band(double value, const std::array<double, 2>& boundaries) {
  if (value < boundaries[0]) return 0;
  return value < boundaries[1] ? 1 : 2;
}

// [lo, hi) of band `i` of an axis of `size` pixels.
void BandRange(int i, const std::array<double, 2>& boundaries, int size, double* lo, double* hi) {
  *lo = i == 0 ? 0.0 : boundaries[static_cast<size_t>(i - 1)];
  *hi = i == 2 ? static_cast<double>(size) : boundaries[static_cast<size_t>(i)];
}

std::string Num(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

bool OutsideImage(const RegionModel& m, double u_px, double v_px) {
  const double margin = CameraModel::kPixelMarginPx;
  return u_px < -margin || v_px < -margin || u_px > m.width_px + margin ||
         v_px > m.height_px + margin;
}

bool CheckHeight(const RegionModel& m, double height_m, std::string* error) {
  if (!std::isfinite(height_m)) {
    *error = "height is not a finite number";
    return false;
  }
  if (std::abs(height_m - m.calibration_height_m) > RegionModel::kHeightToleranceM) {
    *error = "height " + Num(height_m) + " m differs from the calibration height " +
             Num(m.calibration_height_m) +
             " m: the 9-region model is valid only at the height it was calibrated at";
    return false;
  }
  return true;
}

}  // namespace

int RegionModel::RegionIndex(double u_px, double v_px) const {
  return 3 * Band(v_px, v_boundaries_px) + Band(u_px, u_boundaries_px);
}

void RegionModel::Map(double u_px, double v_px, double* x_m, double* y_m) const {
  const Region& r = regions[static_cast<size_t>(RegionIndex(u_px, v_px))];
  *x_m = (u_px - r.x.os1_px) / r.x.c_px_per_m + r.x.os2_m;
  *y_m = (v_px - r.y.os1_px) / r.y.c_px_per_m + r.y.os2_m;
}

bool RegionModel::MapAtHeight(double u_px, double v_px, double height_m, double* x_m, double* y_m,
                              std::string* error) const {
  if (!std::isfinite(u_px) || !std::isfinite(v_px)) {
    *error = "pixel is not finite";
    return false;
  }
  if (!CheckHeight(*this, height_m, error)) return false;
  if (OutsideImage(*this, u_px, v_px)) {
    *error = "pixel (" + Num(u_px) + ", " + Num(v_px) + ") is outside the " +
             std::to_string(width_px) + " x " + std::to_string(height_px) + " image";
    return false;
  }
  Map(u_px, v_px, x_m, y_m);
  return true;
}

bool RegionModel::InverseAtHeight(double x_m, double y_m, double height_m, double* u_px,
                                  double* v_px, std::string* error) const {
  if (!std::isfinite(x_m) || !std::isfinite(y_m)) {
    *error = "floor point is not finite";
    return false;
  }
  if (!CheckHeight(*this, height_m, error)) return false;
  double best_outside = INFINITY;
  double best_u = 0.0, best_v = 0.0;
  for (int i = 0; i < 9; ++i) {
    const Region& r = regions[static_cast<size_t>(i)];
    const double u = r.x.os1_px + r.x.c_px_per_m * (x_m - r.x.os2_m);
    const double v = r.y.os1_px + r.y.c_px_per_m * (y_m - r.y.os2_m);
    double u_lo, u_hi, v_lo, v_hi;
    BandRange(i % 3, u_boundaries_px, width_px, &u_lo, &u_hi);
    BandRange(i / 3, v_boundaries_px, height_px, &v_lo, &v_hi);
    // Edge regions reach beyond the image (RegionIndex sends outside pixels
    // to them).
    if (i % 3 == 0) u_lo = -INFINITY;
    if (i % 3 == 2) u_hi = INFINITY;
    if (i / 3 == 0) v_lo = -INFINITY;
    if (i / 3 == 2) v_hi = INFINITY;
    const double du = std::max({u_lo - u, u - u_hi, 0.0});
    const double dv = std::max({v_lo - v, v - v_hi, 0.0});
    const double outside = std::hypot(du, dv);
    if (outside < best_outside) {
      best_outside = outside;
      best_u = u;
      best_v = v;
    }
    if (outside == 0.0) break;
  }
  if (OutsideImage(*this, best_u, best_v)) {
    *error = "floor point (" + Num(x_m) + ", " + Num(y_m) + ") maps outside the image";
    return false;
  }
  *u_px = best_u;
  *v_px = best_v;
  return true;
}

bool RegionModel::IsValid(std::string* error) const {
  if (width_px <= 0 || height_px <= 0) {
    *error = "image size must be positive";
    return false;
  }
  const bool u_ok = 0 < u_boundaries_px[0] && u_boundaries_px[0] < u_boundaries_px[1] &&
                    u_boundaries_px[1] < width_px;
  const bool v_ok = 0 < v_boundaries_px[0] && v_boundaries_px[0] < v_boundaries_px[1] &&
                    v_boundaries_px[1] < height_px;
  if (!u_ok || !v_ok) {
    *error = "region boundaries must be increasing and inside the image";
    return false;
  }
  if (!std::isfinite(calibration_height_m)) {
    *error = "calibration height is not finite";
    return false;
  }
  for (int i = 0; i < 9; ++i) {
    for (const RegionAxis* a :
         {&regions[static_cast<size_t>(i)].x, &regions[static_cast<size_t>(i)].y}) {
      if (!std::isfinite(a->os1_px) || !std::isfinite(a->os2_m) || !std::isfinite(a->c_px_per_m) ||
          a->c_px_per_m == 0.0) {
        *error =
            "region " + DescribeRegion(*this, i) + ": os1, C and os2 must be finite, C non-zero";
        return false;
      }
    }
  }
  return true;
}

RegionModel ThirdsRegionModel(int width_px, int height_px) {
  RegionModel m;
  m.width_px = width_px;
  m.height_px = height_px;
  m.u_boundaries_px = {width_px / 3.0, 2.0 * width_px / 3.0};
  m.v_boundaries_px = {height_px / 3.0, 2.0 * height_px / 3.0};
  return m;
}

std::string DescribeRegion(const RegionModel& model, int index) {
  double u_lo, u_hi, v_lo, v_hi;
  BandRange(index % 3, model.u_boundaries_px, model.width_px, &u_lo, &u_hi);
  BandRange(index / 3, model.v_boundaries_px, model.height_px, &v_lo, &v_hi);
  return "row " + std::to_string(index / 3) + ", col " + std::to_string(index % 3) + " (u " +
         Num(u_lo) + ".." + Num(u_hi) + " px, v " + Num(v_lo) + ".." + Num(v_hi) + " px)";
}

RegionFitSummary FitRegions(const std::vector<Correspondence>& points, const RegionModel& layout) {
  RegionFitSummary s;
  s.model = layout;
  std::string why;
  RegionModel check = layout;
  for (Region& r : check.regions) r = Region{};  // only the layout is checked here
  if (!check.IsValid(&why)) {
    s.message = "invalid region layout: " + why;
    return s;
  }
  if (points.empty()) {
    s.message = "no calibration points";
    return s;
  }
  for (size_t i = 0; i < points.size(); ++i) {
    const Correspondence& p = points[i];
    if (!std::isfinite(p.u_px) || !std::isfinite(p.v_px) || !std::isfinite(p.x_m) ||
        !std::isfinite(p.y_m) || !std::isfinite(p.height_m)) {
      s.message = "point " + std::to_string(i) + " has a value that is not finite";
      return s;
    }
    if (OutsideImage(layout, p.u_px, p.v_px)) {
      s.message = "point " + std::to_string(i) + " pixel (" + Num(p.u_px) + ", " + Num(p.v_px) +
                  ") is outside the " + std::to_string(layout.width_px) + " x " +
                  std::to_string(layout.height_px) + " image";
      return s;
    }
    if (std::abs(p.height_m - points[0].height_m) > RegionModel::kHeightToleranceM) {
      s.message = "inconsistent heights: point 0 is at " + Num(points[0].height_m) + " m, point " +
                  std::to_string(i) + " at " + Num(p.height_m) +
                  " m; the 9-region model is one table for one marker height";
      return s;
    }
  }
  s.model.calibration_height_m = points[0].height_m;

  for (int region = 0; region < 9; ++region) {
    // Axis 0: x on u; axis 1: y on v.
    for (int axis = 0; axis < 2; ++axis) {
      double sum_p = 0, sum_w = 0, n = 0, lo = INFINITY, hi = -INFINITY;
      for (const Correspondence& p : points) {
        if (layout.RegionIndex(p.u_px, p.v_px) != region) continue;
        const double px = axis == 0 ? p.u_px : p.v_px;
        sum_p += px;
        sum_w += axis == 0 ? p.x_m : p.y_m;
        lo = std::min(lo, px);
        hi = std::max(hi, px);
        ++n;
      }
      if (n < 2 || hi - lo < kMinSpreadPx) {
        s.message =
            "region " + DescribeRegion(layout, region) + ": " +
            (axis == 0 ? "x needs 2 points of distinct u" : "y needs 2 points of distinct v") +
            ", has " + std::to_string(static_cast<int>(n)) +
            (n >= 2 ? " at the same pixel coordinate" : "") + "; add calibration points there";
        return s;
      }
      const double mean_p = sum_p / n, mean_w = sum_w / n;
      // Centred sums: slope = S_pw / S_pp (floor metres per pixel).
      double s_pp = 0, s_pw = 0;
      for (const Correspondence& p : points) {
        if (layout.RegionIndex(p.u_px, p.v_px) != region) continue;
        const double dp = (axis == 0 ? p.u_px : p.v_px) - mean_p;
        s_pp += dp * dp;
        s_pw += dp * ((axis == 0 ? p.x_m : p.y_m) - mean_w);
      }
      const double slope_m_per_px = s_pw / s_pp;
      if (!(std::abs(slope_m_per_px) > 0.0)) {
        s.message = "region " + DescribeRegion(layout, region) + ": " +
                    (axis == 0 ? "x does not change with u" : "y does not change with v");
        return s;
      }
      double lo_px, hi_px;
      if (axis == 0) {
        BandRange(region % 3, layout.u_boundaries_px, layout.width_px, &lo_px, &hi_px);
      } else {
        BandRange(region / 3, layout.v_boundaries_px, layout.height_px, &lo_px, &hi_px);
      }
      RegionAxis a;
      a.os1_px = 0.5 * (lo_px + hi_px);
      a.c_px_per_m = 1.0 / slope_m_per_px;
      a.os2_m = mean_w + slope_m_per_px * (a.os1_px - mean_p);
      Region& r = s.model.regions[static_cast<size_t>(region)];
      (axis == 0 ? r.x : r.y) = a;
    }
  }

  double sum2 = 0;
  for (size_t i = 0; i < points.size(); ++i) {
    const Correspondence& p = points[i];
    double x, y, u = NAN, v = NAN;
    s.model.Map(p.u_px, p.v_px, &x, &y);
    const double d = std::hypot(x - p.x_m, y - p.y_m);
    std::string ignored;
    s.residual_m.push_back(d);
    s.residual_px.push_back(s.model.InverseAtHeight(p.x_m, p.y_m, p.height_m, &u, &v, &ignored)
                                ? std::hypot(u - p.u_px, v - p.v_px)
                                : INFINITY);
    sum2 += d * d;
    if (d > s.max_m || s.worst_index < 0) {
      s.max_m = d;
      s.worst_index = static_cast<int>(i);
    }
  }
  s.rms_m = std::sqrt(sum2 / static_cast<double>(points.size()));
  s.usable = true;
  s.message = "fitted 9 regions to " + std::to_string(points.size()) + " points at " +
              Num(s.model.calibration_height_m) + " m";
  return s;
}

}  // namespace roomfix::calib
