#include "viewer/render.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <ctime>
#include <functional>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <string>
#include <utility>
#include <vector>

#include "camera_io/image_file.h"

namespace roomfix::viewer {
namespace {

// Bounds of RenderOptions::IsValid, and what Render clamps invalid options to.
constexpr int kMinSidePx = 64;
constexpr int kMaxSidePx = 8192;
constexpr int kMinFloorPx = 64;
constexpr double kMinZoom = 0.01;
constexpr double kMaxZoom = 1000.0;
constexpr double kMaxPanM = 1e4;
// Room margin at zoom 1, each side.
constexpr double kMarginM = 0.3;
// Rooms beyond this (or NaN) are nonsense; the mapping then shows 1 x 1 m.
constexpr double kMaxRoomM = 1e6;

// Drawing is clipped (in double, before any conversion to int) to the floor
// area grown by this, so that thick lines and discs at the edge still show
// and no coordinate handed to OpenCV can overflow.
constexpr double kClipMarginPx = 32.0;
// Circles larger than this (a garbage range) are not drawn: the part of such
// a circle inside the picture is a straight line no one can read anyway.
constexpr double kMaxCircleRadiusPx = 1e7;

constexpr int kDiscRadiusPx = 6;
constexpr int kReceiverHalfPx = 5;
constexpr int kArrowLengthPx = 16;
// Trails: points closer than this to the last drawn one are skipped (a 40 Hz
// track moves ~1 px a sample, and each anti-aliased 2 px segment costs about
// a microsecond: 40 tracks of 10 s took ~5 ms a frame at 2 px); at most
// this many points are looked at per track (a garbage state with a
// million-point trail stays cheap); ages are drawn in this many shades (one
// polyline per shade and run).
constexpr double kTrailMinStepPx = 3.0;
constexpr size_t kMaxTrailPoints = 20000;
constexpr int kTrailShades = 10;
// The oldest trail point keeps this much of its colour (fully faded would be
// invisible and look like a gap).
constexpr double kTrailMinAlpha = 0.12;

// Previews are decoded only when JPEG or PNG and at most this large
// (declared size): a hostile header must not make imdecode allocate
// gigabytes.
constexpr int kMaxPreviewSidePx = 4096;
constexpr size_t kMaxPreviewBytes = 16u << 20;
constexpr int kMarkerRingGapPx = 3;

constexpr int kFont = cv::FONT_HERSHEY_SIMPLEX;
constexpr double kFontScale = 0.42;
constexpr double kSmallFontScale = 0.37;
constexpr int kLinePx = 17;
constexpr int kPanelPadPx = 10;

const cv::Scalar kOutsideColour(226, 226, 222);
const cv::Scalar kGridColour(214, 212, 206);
const cv::Scalar kGridMetreColour(196, 194, 188);
const cv::Scalar kOutlineColour(70, 70, 70);
const cv::Scalar kAxisColour(90, 90, 90);
const cv::Scalar kTextColour(40, 40, 40);
const cv::Scalar kMutedTextColour(120, 120, 120);
const cv::Scalar kPanelColour(244, 244, 244);
const cv::Scalar kPanelRuleColour(200, 200, 200);
const cv::Scalar kStaleMarkColour(60, 60, 60);
const cv::Scalar kRunningColour(40, 150, 40);
const cv::Scalar kDegradedColour(0, 130, 240);
const cv::Scalar kWhite(255, 255, 255);

// A number for the panel: "-" when unknown (NaN) or not finite, compact when
// huge, so a garbage value cannot widen a column.
std::string Number(double value, int decimals) {
  if (!std::isfinite(value)) return "-";
  if (std::fabs(value) >= 1e5) return fmt::format("{:.2g}", value);
  return fmt::format("{:.{}f}", value, decimals);
}

// Hershey fonts draw printable ASCII; anything else (a process name in UTF-8,
// control bytes from a broken heartbeat) shows as '?'. Long text is cut.
std::string Printable(const std::string& text, size_t max_chars = 120) {
  std::string out;
  out.reserve(std::min(text.size(), max_chars));
  for (char c : text) {
    if (out.size() >= max_chars) break;
    out.push_back(c >= 32 && c < 127 ? c : '?');
  }
  return out;
}

int TextWidth(const std::string& text, double scale, int thickness = 1) {
  int baseline = 0;
  return cv::getTextSize(text, kFont, scale, thickness, &baseline).width;
}

// Cuts text to fit max_px, ending in "..".
std::string Fit(const std::string& text, double scale, int max_px) {
  std::string s = Printable(text);
  if (TextWidth(s, scale) <= max_px) return s;
  size_t lo = 0;
  size_t hi = s.size();
  while (lo < hi) {
    const size_t mid = (lo + hi + 1) / 2;
    if (TextWidth(s.substr(0, mid) + "..", scale) <= max_px) {
      lo = mid;
    } else {
      hi = mid - 1;
    }
  }
  return s.substr(0, lo) + "..";
}

void Text(cv::Mat& image, const std::string& text, cv::Point origin, double scale,
          const cv::Scalar& colour, int thickness = 1) {
  cv::putText(image, text, origin, kFont, scale, colour, thickness, cv::LINE_AA);
}

// Text over drawing (labels on the floor): a light halo keeps it readable
// over grid lines and trails.
void HaloText(cv::Mat& image, const std::string& text, cv::Point origin, double scale,
              const cv::Scalar& colour) {
  cv::putText(image, text, origin, kFont, scale, kWhite, 3, cv::LINE_AA);
  cv::putText(image, text, origin, kFont, scale, colour, 1, cv::LINE_AA);
}

cv::Scalar Blend(const cv::Scalar& from, const cv::Scalar& to, double t) {
  return from * (1.0 - t) + to * t;
}

bool Finite(double a, double b) { return std::isfinite(a) && std::isfinite(b); }

double AgeS(int64_t now_utime, int64_t utime) {
  // In double: int64 subtraction of garbage times could overflow.
  return (static_cast<double>(now_utime) - static_cast<double>(utime)) * 1e-6;
}

RenderOptions Sanitized(const RenderOptions& o) {
  RenderOptions s = o;
  s.width_px = std::clamp(o.width_px, kMinSidePx, kMaxSidePx);
  s.height_px = std::clamp(o.height_px, kMinSidePx, kMaxSidePx);
  s.panel_px = std::clamp(o.panel_px, 0, s.width_px - kMinFloorPx);
  s.zoom = std::isfinite(o.zoom) && o.zoom > 0 ? std::clamp(o.zoom, kMinZoom, kMaxZoom) : 1.0;
  s.pan_x_m = std::isfinite(o.pan_x_m) ? std::clamp(o.pan_x_m, -kMaxPanM, kMaxPanM) : 0.0;
  s.pan_y_m = std::isfinite(o.pan_y_m) ? std::clamp(o.pan_y_m, -kMaxPanM, kMaxPanM) : 0.0;
  return s;
}

bool SaneRoom(const Room& room) {
  for (double v : {room.min_x_m, room.min_y_m, room.size_x_m, room.size_y_m}) {
    if (!std::isfinite(v) || std::fabs(v) > kMaxRoomM) return false;
  }
  return room.size_x_m >= 0 && room.size_y_m >= 0;
}

// The floor area of the picture, with its mapping and the clip rectangle.
struct Canvas {
  cv::Mat image;  // the floor area (a view into the whole picture)
  FloorMapping map;
  double clip_min_u = 0, clip_min_v = 0, clip_max_u = 0, clip_max_v = 0;

  Canvas(cv::Mat floor, const FloorMapping& mapping) : image(std::move(floor)), map(mapping) {
    clip_min_u = -kClipMarginPx;
    clip_min_v = -kClipMarginPx;
    clip_max_u = image.cols + kClipMarginPx;
    clip_max_v = image.rows + kClipMarginPx;
  }

  bool Inside(cv::Point2d p, double grow = 0) const {
    return p.x >= clip_min_u - grow && p.x <= clip_max_u + grow && p.y >= clip_min_v - grow &&
           p.y <= clip_max_v + grow;
  }

  // Liang-Barsky clip of a segment to the clip rectangle. False when nothing
  // is left or an end is not finite; *a and *b are moved onto the border.
  bool Clip(cv::Point2d* a, cv::Point2d* b) const {
    if (!Finite(a->x, a->y) || !Finite(b->x, b->y)) return false;
    const double dx = b->x - a->x;
    const double dy = b->y - a->y;
    double t0 = 0.0;
    double t1 = 1.0;
    const double p[4] = {-dx, dx, -dy, dy};
    const double q[4] = {a->x - clip_min_u, clip_max_u - a->x, a->y - clip_min_v,
                         clip_max_v - a->y};
    for (int i = 0; i < 4; ++i) {
      if (p[i] == 0.0) {
        if (q[i] < 0) return false;
        continue;
      }
      const double r = q[i] / p[i];
      if (p[i] < 0) {
        t0 = std::max(t0, r);
      } else {
        t1 = std::min(t1, r);
      }
      if (t0 > t1) return false;
    }
    const cv::Point2d start = *a;
    *a = start + cv::Point2d(dx, dy) * t0;
    *b = start + cv::Point2d(dx, dy) * t1;
    return true;
  }

  void Line(cv::Point2d a, cv::Point2d b, const cv::Scalar& colour, int thickness,
            int line_type = cv::LINE_AA) {
    if (!Clip(&a, &b)) return;
    cv::line(image, ToInt(a), ToInt(b), colour, thickness, line_type);
  }

  // Only for points inside the clip rectangle (grown by a little).
  static cv::Point ToInt(cv::Point2d p) { return cv::Point(cvRound(p.x), cvRound(p.y)); }
};

// Collects a polyline point by point, clipping each segment and drawing each
// unbroken run with one cv::polylines call (one call per segment costs
// several times more at 30 fps).
class PolylineRun {
 public:
  PolylineRun(Canvas* canvas, cv::Scalar colour, int thickness, int line_type)
      : canvas_(canvas), colour_(std::move(colour)), thickness_(thickness), line_type_(line_type) {}
  ~PolylineRun() { Flush(); }

  void SetColour(const cv::Scalar& colour) {
    if (colour == colour_) return;
    Flush();
    colour_ = colour;
  }

  void Segment(cv::Point2d a, cv::Point2d b) {
    const cv::Point2d a0 = a;
    const cv::Point2d b0 = b;
    if (!canvas_->Clip(&a, &b)) {
      Flush();
      return;
    }
    const cv::Point ia = Canvas::ToInt(a);
    const cv::Point ib = Canvas::ToInt(b);
    if (points_.empty() || a != a0 || points_.back() != ia) {
      Flush();
      points_.push_back(ia);
    }
    points_.push_back(ib);
    if (b != b0) Flush();
  }

  void Flush() {
    if (points_.size() >= 2) {
      cv::polylines(canvas_->image, points_, false, colour_, thickness_, line_type_);
    }
    points_.clear();
  }

 private:
  Canvas* canvas_;
  cv::Scalar colour_;
  int thickness_;
  int line_type_;
  std::vector<cv::Point> points_;
};

// A circle given in pixels, drawn as a polyline (clipped like every line) so
// that huge and far circles cost nothing and dashes are possible. Solid
// circles use chords of at most 0.25 px sagitta; dashed ones ~6 px dashes.
void Circle(Canvas* canvas, cv::Point2d centre, double radius_px, const cv::Scalar& colour,
            int thickness, int line_type, bool dashed) {
  if (!Finite(centre.x, centre.y) || !std::isfinite(radius_px) || radius_px < 0 ||
      radius_px > kMaxCircleRadiusPx) {
    return;
  }
  // Wholly outside the clip rectangle, or the rectangle wholly inside it.
  if (centre.x + radius_px < canvas->clip_min_u || centre.x - radius_px > canvas->clip_max_u ||
      centre.y + radius_px < canvas->clip_min_v || centre.y - radius_px > canvas->clip_max_v) {
    return;
  }
  double far_corner_sq = 0;
  for (double u : {canvas->clip_min_u, canvas->clip_max_u}) {
    for (double v : {canvas->clip_min_v, canvas->clip_max_v}) {
      far_corner_sq = std::max(far_corner_sq,
                               (u - centre.x) * (u - centre.x) + (v - centre.y) * (v - centre.y));
    }
  }
  if (radius_px * radius_px > far_corner_sq) return;
  if (radius_px < 1.0) {
    cv::circle(canvas->image, Canvas::ToInt(centre), 1, colour, cv::FILLED, cv::LINE_AA);
    return;
  }
  constexpr double kTwoPi = 2.0 * CV_PI;
  const int n =
      dashed ? std::clamp(static_cast<int>(std::ceil(kTwoPi * radius_px / 6.0)), 16, 8192)
             : std::clamp(static_cast<int>(std::ceil(CV_PI * std::sqrt(2 * radius_px))), 24, 2048);
  const int steps = dashed ? n - (n % 2) : n;
  PolylineRun run(canvas, colour, thickness, line_type);
  cv::Point2d previous = centre + cv::Point2d(radius_px, 0);
  for (int i = 1; i <= steps; ++i) {
    const double angle = kTwoPi * i / steps;
    const cv::Point2d p =
        centre + cv::Point2d(radius_px * std::cos(angle), radius_px * std::sin(angle));
    if (!dashed || i % 2 == 1) {
      run.Segment(previous, p);
    } else {
      run.Flush();
    }
    previous = p;
  }
}

// --- the static background ------------------------------------------------

void DrawGrid(Canvas* c, const Room& room) {
  if (!SaneRoom(room)) return;
  const FloorMapping& m = c->map;
  // Visible part of the room, metres.
  double vx0 = 0, vy0 = 0, vx1 = 0, vy1 = 0;
  m.ToFloor({c->clip_min_u, c->clip_max_v}, &vx0, &vy0);
  m.ToFloor({c->clip_max_u, c->clip_min_v}, &vx1, &vy1);
  const double x0 = std::max(room.min_x_m, vx0);
  const double x1 = std::min(room.min_x_m + room.size_x_m, vx1);
  const double y0 = std::max(room.min_y_m, vy0);
  const double y1 = std::min(room.min_y_m + room.size_y_m, vy1);
  if (!(x0 <= x1 && y0 <= y1)) return;

  // The site's grid; coarsened (doubled) while its lines would be closer
  // than 8 px, so a far zoom-out is not a grey wash and the loops stay short.
  double grid_m = std::isfinite(room.grid_m) && room.grid_m > 0 ? room.grid_m : 0.5;
  for (int i = 0; i < 64 && grid_m * m.scale_px_per_m < 8.0; ++i) grid_m *= 2;
  if (grid_m * m.scale_px_per_m < 8.0) return;
  const double metre_step = grid_m <= 1.0 ? 1.0 : std::ceil(grid_m);
  auto is_metre = [&](double v) {
    return std::fabs(v / metre_step - std::round(v / metre_step)) < 1e-6;
  };

  const cv::Point2d bottom_left = m.ToPixel(room.min_x_m, room.min_y_m);
  const cv::Point2d top_right =
      m.ToPixel(room.min_x_m + room.size_x_m, room.min_y_m + room.size_y_m);
  const bool label_metres = metre_step * m.scale_px_per_m >= 28.0;
  // Bounded twice over: the lines are >= 8 px apart within the visible part.
  int lines = 0;
  for (double k = std::ceil(x0 / grid_m); k * grid_m <= x1 + 1e-9 && lines < 4096;
       k += 1.0, ++lines) {
    const double x = k * grid_m;
    const double u = m.ToPixel(x, 0).x;
    const bool metre = is_metre(x);
    c->Line({u, bottom_left.y}, {u, top_right.y}, metre ? kGridMetreColour : kGridColour, 1,
            cv::LINE_8);
    if (metre && label_metres && c->Inside({u, bottom_left.y + 16})) {
      const std::string label = fmt::format("{:g}", std::round(x * 100) / 100);
      Text(c->image, label,
           Canvas::ToInt({u - TextWidth(label, kSmallFontScale) / 2.0, bottom_left.y + 16}),
           kSmallFontScale, kMutedTextColour);
    }
  }
  lines = 0;
  for (double k = std::ceil(y0 / grid_m); k * grid_m <= y1 + 1e-9 && lines < 4096;
       k += 1.0, ++lines) {
    const double y = k * grid_m;
    const double v = m.ToPixel(0, y).y;
    const bool metre = is_metre(y);
    c->Line({bottom_left.x, v}, {top_right.x, v}, metre ? kGridMetreColour : kGridColour, 1,
            cv::LINE_8);
    if (metre && label_metres) {
      const std::string label = fmt::format("{:g}", std::round(y * 100) / 100);
      const cv::Point2d at(bottom_left.x - 8 - TextWidth(label, kSmallFontScale), v + 4);
      if (c->Inside(at))
        Text(c->image, label, Canvas::ToInt(at), kSmallFontScale, kMutedTextColour);
    }
  }
}

void DrawRoom(Canvas* c, const Room& room) {
  if (!SaneRoom(room)) return;
  const FloorMapping& m = c->map;
  const double x1 = room.min_x_m + room.size_x_m;
  const double y1 = room.min_y_m + room.size_y_m;
  const cv::Point2d p00 = m.ToPixel(room.min_x_m, room.min_y_m);
  const cv::Point2d p11 = m.ToPixel(x1, y1);
  // The room's floor, lighter than around it; the rectangle clipped first.
  const double u0 = std::clamp(p00.x, c->clip_min_u, c->clip_max_u);
  const double u1 = std::clamp(p11.x, c->clip_min_u, c->clip_max_u);
  const double v0 = std::clamp(p11.y, c->clip_min_v, c->clip_max_v);
  const double v1 = std::clamp(p00.y, c->clip_min_v, c->clip_max_v);
  if (u0 < u1 && v0 < v1) {
    cv::rectangle(c->image, Canvas::ToInt({u0, v0}), Canvas::ToInt({u1, v1}), FloorColour(),
                  cv::FILLED);
  }
  DrawGrid(c, room);
  const cv::Point2d p10 = m.ToPixel(x1, room.min_y_m);
  const cv::Point2d p01 = m.ToPixel(room.min_x_m, y1);
  c->Line(p00, p10, kOutlineColour, 2);
  c->Line(p10, p11, kOutlineColour, 2);
  c->Line(p11, p01, kOutlineColour, 2);
  c->Line(p01, p00, kOutlineColour, 2);
}

void DrawAxes(Canvas* c) {
  const cv::Point2d o = c->map.ToPixel(0, 0);
  if (!c->Inside(o)) return;
  const cv::Point io = Canvas::ToInt(o);
  cv::arrowedLine(c->image, io, io + cv::Point(40, 0), kAxisColour, 2, cv::LINE_AA, 0, 0.25);
  cv::arrowedLine(c->image, io, io - cv::Point(0, 40), kAxisColour, 2, cv::LINE_AA, 0, 0.25);
  cv::circle(c->image, io, 4, kAxisColour, cv::FILLED, cv::LINE_AA);
  HaloText(c->image, "x", io + cv::Point(44, 5), kFontScale, kAxisColour);
  HaloText(c->image, "y", io + cv::Point(-4, -46), kFontScale, kAxisColour);
}

void DrawCameras(Canvas* c, const Site& site, const std::vector<CameraFootprint>& footprints) {
  const cv::Scalar colour = Blend(FloorColour(), SourceColour(PoseSource::kCamera), 0.55);
  for (const Camera& camera : site.cameras) {
    const CameraFootprint* footprint = nullptr;
    for (const CameraFootprint& f : footprints) {
      if (f.camera_id == camera.id && f.floor_m.size() >= 3) footprint = &f;
    }
    if (footprint != nullptr) {
      // The floor its image covers: solid when calibrated, thin for the
      // nominal model.
      std::vector<cv::Point> polygon;
      bool finite = true;
      for (const auto& q : footprint->floor_m) {
        const cv::Point2d px = c->map.ToPixel(q[0], q[1]);
        finite = finite && Finite(px.x, px.y) && std::fabs(px.x) < 1e6 && std::fabs(px.y) < 1e6;
        polygon.push_back(Canvas::ToInt(px));
      }
      if (finite) {
        cv::polylines(c->image, polygon, true, colour, footprint->calibrated ? 2 : 1, cv::LINE_AA);
      }
      const cv::Point2d centre = c->map.ToPixel(footprint->lens_m[0], footprint->lens_m[1]);
      if (c->Inside(centre)) {
        const cv::Point ic = Canvas::ToInt(centre);
        cv::rectangle(c->image, ic - cv::Point(5, 4), ic + cv::Point(5, 4), colour, 2, cv::LINE_AA);
        HaloText(c->image, fmt::format("cam {}", camera.id), ic + cv::Point(9, 15), kSmallFontScale,
                 Blend(kTextColour, SourceColour(PoseSource::kCamera), 0.5));
      }
      continue;
    }
    const auto& p = camera.mount_position_m;
    const double half_fov_rad = camera.field_of_view_deg * CV_PI / 360.0;
    if (!Finite(p[0], p[1]) || !std::isfinite(p[2]) || p[2] <= 0 || !std::isfinite(half_fov_rad) ||
        half_fov_rad <= 0 || half_fov_rad >= CV_PI / 2) {
      continue;
    }
    // Where the view cone meets the floor (z = 0): what the camera can see
    // at best (markers stand above the floor, so a little more).
    const double radius_m = p[2] * std::tan(half_fov_rad);
    const cv::Point2d centre = c->map.ToPixel(p[0], p[1]);
    Circle(c, centre, radius_m * c->map.scale_px_per_m, colour, 1, cv::LINE_AA, true);
    if (c->Inside(centre)) {
      const cv::Point ic = Canvas::ToInt(centre);
      cv::rectangle(c->image, ic - cv::Point(5, 4), ic + cv::Point(5, 4), colour, 2, cv::LINE_AA);
      HaloText(c->image, fmt::format("cam {}", camera.id), ic + cv::Point(9, 15), kSmallFontScale,
               Blend(kTextColour, SourceColour(PoseSource::kCamera), 0.5));
    }
  }
}

// Fixed obstacles (site `obstacles`) as filled footprints with their names:
// what hides the robot from a receiver. A moving one (a person on a
// trajectory) has no place in the background and the viewer does not know
// the simulation's time, so it is not drawn.
const cv::Scalar kObstacleColour(150, 160, 170);
const cv::Scalar kObstacleOutlineColour(90, 100, 110);
constexpr int kCylinderPolygonSides = 48;

void DrawObstacles(Canvas* c, const Site& site) {
  for (const Obstacle& o : site.obstacles) {
    if (o.trajectory != nullptr) continue;
    std::vector<std::array<double, 2>> corners_m;
    if (o.shape == Obstacle::Shape::kCylinder) {
      for (int k = 0; k < kCylinderPolygonSides; ++k) {
        const double a = 2.0 * CV_PI * k / kCylinderPolygonSides;
        corners_m.push_back(
            {o.centre_m[0] + o.radius_m * std::cos(a), o.centre_m[1] + o.radius_m * std::sin(a)});
      }
    } else {
      const double cs = std::cos(o.yaw_rad);
      const double sn = std::sin(o.yaw_rad);
      for (const auto& [u, v] : {std::pair{1, 1}, {-1, 1}, {-1, -1}, {1, -1}}) {
        const double du = 0.5 * u * o.size_m[0];
        const double dv = 0.5 * v * o.size_m[1];
        corners_m.push_back({o.centre_m[0] + cs * du - sn * dv, o.centre_m[1] + sn * du + cs * dv});
      }
    }
    std::vector<cv::Point> polygon;
    bool finite = true;
    for (const auto& q : corners_m) {
      const cv::Point2d px = c->map.ToPixel(q[0], q[1]);
      finite = finite && Finite(px.x, px.y) && std::fabs(px.x) < 1e6 && std::fabs(px.y) < 1e6;
      polygon.push_back(Canvas::ToInt(px));
    }
    if (!finite) continue;
    cv::fillPoly(c->image, std::vector<std::vector<cv::Point>>{polygon}, kObstacleColour,
                 cv::LINE_AA);
    cv::polylines(c->image, polygon, true, kObstacleOutlineColour, 1, cv::LINE_AA);
    const cv::Point2d centre = c->map.ToPixel(o.centre_m[0], o.centre_m[1]);
    if (!o.name.empty() && c->Inside(centre)) {
      HaloText(c->image, o.name, Canvas::ToInt(centre) + cv::Point(-12, 4), kSmallFontScale,
               kTextColour);
    }
  }
}

void DrawReceivers(Canvas* c, const Site& site) {
  for (const Receiver& r : site.receivers) {
    const cv::Point2d p = c->map.ToPixel(r.position_m[0], r.position_m[1]);
    if (!c->Inside(p)) continue;
    const cv::Point ip = Canvas::ToInt(p);
    const cv::Point half(kReceiverHalfPx, kReceiverHalfPx);
    cv::rectangle(c->image, ip - half - cv::Point(1, 1), ip + half + cv::Point(1, 1), kWhite,
                  cv::FILLED);
    cv::rectangle(c->image, ip - half, ip + half, ReceiverColour(), cv::FILLED);
    HaloText(c->image, std::to_string(r.id),
             ip + cv::Point(kReceiverHalfPx + 3, -kReceiverHalfPx - 2), kFontScale,
             ReceiverColour());
  }
}

void DrawLegend(cv::Mat& panel, int top) {
  const int x = kPanelPadPx;
  const int column = (panel.cols - 2 * kPanelPadPx) / 4;
  for (int i = 0; i < kNumSources; ++i) {
    const PoseSource s = kSources[i];
    const cv::Point at(x + i * column, top);
    cv::circle(panel, at + cv::Point(6, -4), kDiscRadiusPx - 1, SourceColour(s), cv::FILLED,
               cv::LINE_AA);
    Text(panel, SourceName(s), at + cv::Point(15, 0), kSmallFontScale, kTextColour);
  }
  const int y = top + kLinePx;
  cv::rectangle(panel, {x + 2, y - 8}, {x + 10, y}, ReceiverColour(), cv::FILLED);
  Text(panel, "receiver", {x + 15, y}, kSmallFontScale, kTextColour);
  const int x2 = x + column;
  cv::line(panel, {x2, y - 4}, {x2 + 14, y - 4}, SourceColour(PoseSource::kUltrasound), 2,
           cv::LINE_AA);
  Text(panel, "range", {x2 + 18, y}, kSmallFontScale, kTextColour);
  const int x3 = x + 2 * column;
  cv::line(panel, {x3, y - 4}, {x3 + 5, y - 4}, WarningColour(), 2, cv::LINE_AA);
  cv::line(panel, {x3 + 9, y - 4}, {x3 + 14, y - 4}, WarningColour(), 2, cv::LINE_AA);
  Text(panel, "rejected", {x3 + 18, y}, kSmallFontScale, kTextColour);
  const int x4 = x + 3 * column;
  const cv::Point sc(x4 + 6, y - 4);
  cv::circle(panel, sc, kDiscRadiusPx - 1, StaleColour(), cv::FILLED, cv::LINE_AA);
  cv::line(panel, sc - cv::Point(4, 4), sc + cv::Point(4, 4), kStaleMarkColour, 1, cv::LINE_AA);
  cv::line(panel, sc + cv::Point(-4, 4), sc + cv::Point(4, -4), kStaleMarkColour, 1, cv::LINE_AA);
  Text(panel, "stale", {x4 + 15, y}, kSmallFontScale, kTextColour);
}

// Panel rows above the legend: title and time (drawn per frame).
constexpr int kLegendTopPx = 56;
constexpr int kPanelBodyTopPx = kLegendTopPx + 2 * kLinePx + 8;

// Everything that does not change between frames of one site and one view.
std::vector<double> BackgroundKey(const Site& site, const std::vector<CameraFootprint>& footprints,
                                  const RenderOptions& o) {
  const Room& r = site.room;
  std::vector<double> key = {static_cast<double>(o.width_px),
                             static_cast<double>(o.height_px),
                             static_cast<double>(o.panel_px),
                             o.zoom,
                             o.pan_x_m,
                             o.pan_y_m,
                             r.min_x_m,
                             r.min_y_m,
                             r.size_x_m,
                             r.size_y_m,
                             r.grid_m,
                             static_cast<double>(site.receivers.size()),
                             static_cast<double>(site.cameras.size())};
  for (const Receiver& rx : site.receivers) {
    key.insert(key.end(), {static_cast<double>(rx.id), rx.position_m[0], rx.position_m[1]});
  }
  key.push_back(static_cast<double>(site.obstacles.size()));
  for (const Obstacle& ob : site.obstacles) {
    key.insert(key.end(), {static_cast<double>(ob.shape), ob.trajectory != nullptr ? 1.0 : 0.0,
                           ob.centre_m[0], ob.centre_m[1], ob.size_m[0], ob.size_m[1], ob.yaw_rad,
                           ob.radius_m, static_cast<double>(std::hash<std::string>{}(ob.name))});
  }
  for (const Camera& cam : site.cameras) {
    key.insert(key.end(),
               {static_cast<double>(cam.id), cam.mount_position_m[0], cam.mount_position_m[1],
                cam.mount_position_m[2], cam.field_of_view_deg});
  }
  for (const CameraFootprint& f : footprints) {
    key.insert(key.end(), {static_cast<double>(f.camera_id), f.calibrated ? 1.0 : 0.0, f.lens_m[0],
                           f.lens_m[1], static_cast<double>(f.floor_m.size())});
    for (const auto& q : f.floor_m) key.insert(key.end(), {q[0], q[1]});
  }
  return key;
}

bool SameKey(const std::vector<double>& a, const std::vector<double>& b) {
  // Bitwise, so that a NaN in the site still hits the cache.
  return a.size() == b.size() &&
         (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(double)) == 0);
}

void DrawBackground(const Site& site, const std::vector<CameraFootprint>& footprints,
                    const RenderOptions& o, const FloorMapping& mapping, cv::Mat* background) {
  background->create(o.height_px, o.width_px, CV_8UC3);
  const int floor_w = o.width_px - o.panel_px;
  cv::Mat floor = (*background)(cv::Rect(0, 0, floor_w, o.height_px));
  floor.setTo(kOutsideColour);
  Canvas canvas(floor, mapping);
  DrawRoom(&canvas, site.room);
  DrawCameras(&canvas, site, footprints);
  DrawAxes(&canvas);
  DrawObstacles(&canvas, site);
  DrawReceivers(&canvas, site);
  if (o.panel_px > 0) {
    cv::Mat panel = (*background)(cv::Rect(floor_w, 0, o.panel_px, o.height_px));
    panel.setTo(kPanelColour);
    cv::line(panel, {0, 0}, {0, o.height_px - 1}, kPanelRuleColour, 1);
    DrawLegend(panel, kLegendTopPx);
  }
}

// --- per frame --------------------------------------------------------------

bool IsStale(const ViewState& state, int64_t recv_utime) {
  return AgeS(state.now_utime, recv_utime) > state.stale_after_s;
}

void DrawRangeSet(Canvas* c, const RangeSetView& set, bool stale) {
  for (const RangeView& r : set.ranges) {
    const double dz = r.receiver_m[2] - set.beacon_height_m;
    if (!std::isfinite(r.range_m) || !std::isfinite(dz) || r.range_m < std::fabs(dz)) continue;
    // Where the sphere of this range about the receiver cuts the beacon's
    // height plane.
    const double radius_m = std::sqrt(r.range_m * r.range_m - dz * dz);
    cv::Scalar colour = r.rejected ? WarningColour() : SourceColour(PoseSource::kUltrasound);
    // An old firing stays, faded, so a silent beacon is noticed.
    if (stale) colour = Blend(colour, FloorColour(), 0.6);
    Circle(c, c->map.ToPixel(r.receiver_m[0], r.receiver_m[1]), radius_m * c->map.scale_px_per_m,
           colour, r.rejected ? 2 : 1, cv::LINE_AA, r.rejected);
  }
}

void DrawCovariance(Canvas* c, const TrackView& t, const cv::Scalar& colour) {
  const double a = t.cov_xx_m2;
  const double b = t.cov_xy_m2;
  const double d = t.cov_yy_m2;
  if (!std::isfinite(a) || !std::isfinite(b) || !std::isfinite(d) || a < 0 || d < 0) return;
  // Eigen-decomposition of [[a b] [b d]]; 2-sigma semi-axes.
  const double mean = 0.5 * (a + d);
  const double root = std::hypot(0.5 * (a - d), b);
  const double l1 = mean + root;
  const double l2 = std::max(0.0, mean - root);
  if (!std::isfinite(l1) || l1 <= 0) return;
  const double angle_rad = 0.5 * std::atan2(2 * b, a - d);
  const double s = c->map.scale_px_per_m;
  const cv::Point2d centre = c->map.ToPixel(t.x_m, t.y_m);
  // An ellipse larger than the picture around a point in it is off-picture
  // either way; clamping keeps OpenCV's int arithmetic safe.
  const double limit = 4.0 * (c->image.cols + c->image.rows);
  const double ax1 = std::min(2.0 * std::sqrt(l1) * s, limit);
  const double ax2 = std::min(2.0 * std::sqrt(l2) * s, limit);
  if (!std::isfinite(ax1) || ax1 < 1.0 || !c->Inside(centre, ax1)) return;
  // Screen v points down: the angle flips.
  cv::ellipse(c->image, Canvas::ToInt(centre),
              cv::Size(cvRound(ax1), std::max(1, static_cast<int>(std::lround(ax2)))),
              -angle_rad * 180.0 / CV_PI, 0, 360, colour, 1, cv::LINE_AA);
}

void DrawTrail(Canvas* c, const TrackView& t, const ViewState& state, const cv::Scalar& colour) {
  if (t.trail.empty() || !std::isfinite(state.trail_s) || state.trail_s <= 0) return;
  // Newest first, thinned to kTrailMinStepPx, within trail_s.
  struct P {
    cv::Point2d px;
    double alpha;
  };
  std::vector<P> points;
  size_t looked = 0;
  for (auto it = t.trail.rbegin(); it != t.trail.rend() && looked < kMaxTrailPoints;
       ++it, ++looked) {
    const double age_s = std::max(0.0, AgeS(state.now_utime, it->utime));
    if (!(age_s <= state.trail_s)) break;
    const cv::Point2d px = c->map.ToPixel(it->x_m, it->y_m);
    if (!Finite(px.x, px.y)) continue;
    if (!points.empty()) {
      const cv::Point2d step = px - points.back().px;
      if (step.dot(step) < kTrailMinStepPx * kTrailMinStepPx) continue;
    }
    points.push_back({px, 1.0 - age_s / state.trail_s});
  }
  if (points.size() < 2) return;
  // Fading as a blend towards the floor, in a few shades: true alpha would
  // need a blended copy of the picture per segment.
  std::array<cv::Scalar, kTrailShades> shades;
  for (int i = 0; i < kTrailShades; ++i) {
    const double alpha = kTrailMinAlpha + (1.0 - kTrailMinAlpha) * (i + 1.0) / kTrailShades;
    shades[static_cast<size_t>(i)] = Blend(FloorColour(), colour, alpha);
  }
  PolylineRun run(c, shades[0], 2, cv::LINE_AA);
  for (size_t i = points.size() - 1; i > 0; --i) {
    const int shade =
        std::clamp(static_cast<int>(points[i - 1].alpha * kTrailShades), 0, kTrailShades - 1);
    run.SetColour(shades[static_cast<size_t>(shade)]);
    run.Segment(points[i].px, points[i - 1].px);
  }
}

void DrawPose(Canvas* c, const TrackView& t, bool stale, const cv::Scalar& colour) {
  const cv::Point2d centre = c->map.ToPixel(t.x_m, t.y_m);
  if (!Finite(centre.x, centre.y) || !c->Inside(centre)) return;
  const cv::Point ic = Canvas::ToInt(centre);
  if (std::isfinite(t.heading_rad)) {
    const cv::Point2d dir(std::cos(t.heading_rad), -std::sin(t.heading_rad));
    cv::arrowedLine(c->image, Canvas::ToInt(centre + dir * (kDiscRadiusPx + 1.0)),
                    Canvas::ToInt(centre + dir * (kDiscRadiusPx + 1.0 + kArrowLengthPx)), colour, 2,
                    cv::LINE_AA, 0, 0.35);
  }
  cv::circle(c->image, ic, kDiscRadiusPx + 1, kWhite, cv::FILLED, cv::LINE_AA);
  if (t.lost && !stale) {
    // The last pose before the source lost the robot: a ring, not a disc.
    cv::circle(c->image, ic, kDiscRadiusPx - 1, colour, 2, cv::LINE_AA);
  } else {
    cv::circle(c->image, ic, kDiscRadiusPx, colour, cv::FILLED, cv::LINE_AA);
  }
  if (stale) {
    const cv::Point d(kDiscRadiusPx - 1, kDiscRadiusPx - 1);
    cv::line(c->image, ic - d, ic + d, kStaleMarkColour, 2, cv::LINE_AA);
    cv::line(c->image, ic + cv::Point(-d.x, d.y), ic + cv::Point(d.x, -d.y), kStaleMarkColour, 2,
             cv::LINE_AA);
  }
}

std::string RobotName(const Site& site, int robot_id) {
  const Robot* robot = site.FindRobot(robot_id);
  return robot != nullptr && !robot->name.empty() ? Printable(robot->name, 24)
                                                  : "robot " + std::to_string(robot_id);
}

void DrawTracks(Canvas* c, const ViewState& state) {
  auto visible = [&](PoseSource s) { return Drawn(s) && state.visible[static_cast<size_t>(s)]; };
  // Ground truth at the bottom, the fused estimate on top.
  constexpr std::array<PoseSource, kNumSources> kOrder = {
      PoseSource::kGroundTruth, PoseSource::kCamera, PoseSource::kUltrasound, PoseSource::kFused};
  for (int pass = 0; pass < 2; ++pass) {
    for (PoseSource s : kOrder) {
      if (!visible(s)) continue;
      for (const TrackView& t : state.tracks) {
        if (t.source != s) continue;
        const bool stale = IsStale(state, t.recv_utime);
        const cv::Scalar colour = stale ? StaleColour() : SourceColour(s);
        if (pass == 0) {
          DrawTrail(c, t, state, colour);
          DrawCovariance(c, t, colour);
        } else {
          DrawPose(c, t, stale, colour);
        }
      }
    }
  }
  // Which camera sees which robot: a thin line from each camera whose pose
  // of the robot is fresh to the camera track's position, and the cameras'
  // ids under the robot's name.
  std::map<int, std::string> seen_by;
  if (visible(PoseSource::kCamera)) {
    for (const TrackView& t : state.tracks) {
      if (t.source != PoseSource::kCamera || t.lost) continue;
      const cv::Point2d robot = c->map.ToPixel(t.x_m, t.y_m);
      if (!Finite(robot.x, robot.y) || !c->Inside(robot)) continue;
      for (const auto& [camera_id, recv_utime] : t.camera_seen_recv_utime) {
        if (IsStale(state, recv_utime)) continue;
        for (const CameraFootprint& f : state.footprints) {
          if (f.camera_id != camera_id) continue;
          const cv::Point2d lens = c->map.ToPixel(f.lens_m[0], f.lens_m[1]);
          if (Finite(lens.x, lens.y) && c->Inside(lens)) {
            cv::line(c->image, Canvas::ToInt(lens), Canvas::ToInt(robot),
                     Blend(FloorColour(), SourceColour(PoseSource::kCamera), 0.7), 1, cv::LINE_AA);
          }
        }
        std::string& text = seen_by[t.robot_id];
        if (text.size() < 40) text += (text.empty() ? "cam " : ",") + std::to_string(camera_id);
      }
    }
  }
  // One name per robot, next to the source drawn on top.
  std::map<int, cv::Point2d> label_at;
  for (PoseSource s : kOrder) {
    if (!visible(s)) continue;
    for (const TrackView& t : state.tracks) {
      const cv::Point2d p = c->map.ToPixel(t.x_m, t.y_m);
      if (t.source == s && Finite(p.x, p.y) && c->Inside(p)) label_at[t.robot_id] = p;
      if (label_at.size() > 64) break;  // a garbage state with thousands of robots
    }
  }
  for (const auto& [robot_id, p] : label_at) {
    HaloText(c->image, RobotName(state.site, robot_id),
             Canvas::ToInt(p + cv::Point2d(kDiscRadiusPx + 4, -kDiscRadiusPx - 4)), kFontScale,
             kTextColour);
    auto seen = seen_by.find(robot_id);
    if (seen != seen_by.end()) {
      HaloText(c->image, seen->second,
               Canvas::ToInt(p + cv::Point2d(kDiscRadiusPx + 4, kDiscRadiusPx + 10)),
               kSmallFontScale, Blend(kTextColour, SourceColour(PoseSource::kCamera), 0.5));
    }
  }
}

// --- the panel ----------------------------------------------------------------

std::string TimeText(int64_t utime) {
  // Floor division without overflow, for any int64 (a garbage time too).
  int64_t seconds = utime / 1000000;
  int64_t micros = utime % 1000000;
  if (micros < 0) {
    micros += 1000000;
    seconds -= 1;
  }
  std::tm tm{};
  const auto t = static_cast<std::time_t>(seconds);
  if (utime == 0 || gmtime_r(&t, &tm) == nullptr || tm.tm_year + 1900 > 9999) {
    return fmt::format("t = {:.3f} s", static_cast<double>(utime) * 1e-6);
  }
  return fmt::format("{:04d}-{:02d}-{:02d} {:02d}:{:02d}:{:02d}.{:03d} UTC", tm.tm_year + 1900,
                     tm.tm_mon + 1, tm.tm_mday, tm.tm_hour, tm.tm_min, tm.tm_sec,
                     static_cast<int>(micros / 1000));
}

struct ProcessStateText {
  const char* text;
  cv::Scalar colour;
};

ProcessStateText StateText(int state) {
  switch (state) {
    case 0:
      return {"starting", kMutedTextColour};
    case 1:
      return {"running", kRunningColour};
    case 2:
      return {"DEGRADED", kDegradedColour};
    case 3:
      return {"stopping", kMutedTextColour};
    case 4:
      return {"FAILED", WarningColour()};
    default:
      return {"unknown", kMutedTextColour};
  }
}

const char* ShortSourceName(PoseSource s) {
  switch (s) {
    case PoseSource::kCamera:
      return "camera";
    case PoseSource::kUltrasound:
      return "ultra";
    case PoseSource::kFused:
      return "fused";
    case PoseSource::kGroundTruth:
      return "truth";
    case PoseSource::kUnknown:
      break;
  }
  return "?";
}

// Writes lines top-down and stops (saying how many were left) at `bottom`.
class PanelWriter {
 public:
  PanelWriter(cv::Mat panel, int top, int bottom)
      : panel_(std::move(panel)), y_(top), bottom_(bottom) {}
  // False when the line would not fit; the caller stops.
  bool Next(int height = kLinePx) {
    if (y_ + height > bottom_) return false;
    y_ += height;
    return true;
  }
  int y() const { return y_; }
  cv::Mat& panel() { return panel_; }
  int width() const { return panel_.cols; }
  // "+N more" after the last row that fitted, over the right end of it when
  // no line is left.
  void More(int left) {
    if (left <= 0) return;
    const std::string text = fmt::format("+{} more", left);
    const int x = panel_.cols - kPanelPadPx - TextWidth(text, kSmallFontScale);
    Text(panel_, text, {x, y_ + kLinePx <= bottom_ ? y_ + kLinePx : y_}, kSmallFontScale,
         WarningColour());
  }
  void Heading(const std::string& text) {
    if (!Next(kLinePx + 6)) return;
    Text(panel_, text, {kPanelPadPx, y_}, 0.48, kTextColour, 1);
    cv::line(panel_, {kPanelPadPx, y_ + 4}, {panel_.cols - kPanelPadPx, y_ + 4}, kPanelRuleColour,
             1);
    y_ += 4;
  }

 private:
  cv::Mat panel_;
  int y_;
  int bottom_;
};

void DrawSourceTable(PanelWriter* w, const ViewState& state) {
  // Robots in id order; a (source, robot) listed twice shows its first.
  std::map<int, std::array<const TrackView*, kNumPoseSources>> rows;
  for (const TrackView& t : state.tracks) {
    if (!Drawn(t.source)) continue;
    const auto s = static_cast<size_t>(t.source);
    auto& row = rows[t.robot_id];
    if (row[s] == nullptr) row[s] = &t;
  }
  w->Heading(fmt::format("Sources ({} robot{})", rows.size(), rows.size() == 1 ? "" : "s"));
  // Hidden sources are still listed, and named hidden on the heading line.
  std::string hidden;
  for (PoseSource s : kSources) {
    if (state.visible[static_cast<size_t>(s)]) continue;
    hidden += (hidden.empty() ? "hidden: " : ", ") + std::string(ShortSourceName(s));
  }
  if (!hidden.empty()) {
    Text(w->panel(), hidden,
         {w->width() - kPanelPadPx - TextWidth(hidden, kSmallFontScale), w->y() - 4},
         kSmallFontScale, kDegradedColour);
  }
  const int name_px = 64;
  const int column = (w->width() - 2 * kPanelPadPx - name_px) / kNumSources;
  if (!w->Next()) return;
  for (int i = 0; i < kNumSources; ++i) {
    const PoseSource s = kSources[i];
    const bool shown = state.visible[static_cast<size_t>(s)];
    const int x = kPanelPadPx + name_px + i * column;
    Text(w->panel(), ShortSourceName(s), {x, w->y()}, kSmallFontScale,
         shown ? Blend(SourceColour(s), kTextColour, 0.25) : kMutedTextColour);
    if (!shown) {
      const int width = TextWidth(ShortSourceName(s), kSmallFontScale);
      cv::line(w->panel(), {x, w->y() - 4}, {x + width, w->y() - 4}, kMutedTextColour, 1);
    }
  }
  Text(w->panel(), "Hz / ms", {kPanelPadPx, w->y()}, kSmallFontScale, kMutedTextColour);
  int left = static_cast<int>(rows.size());
  for (const auto& [robot_id, row] : rows) {
    if (!w->Next()) break;
    --left;
    Text(w->panel(), Fit(RobotName(state.site, robot_id), kSmallFontScale, name_px - 4),
         {kPanelPadPx, w->y()}, kSmallFontScale, kTextColour);
    for (int i = 0; i < kNumSources; ++i) {
      const auto s = static_cast<size_t>(kSources[i]);
      const TrackView* t = row[s];
      if (t == nullptr) continue;
      const bool shown = state.visible[s];
      const double age_s = AgeS(state.now_utime, t->recv_utime);
      std::string text;
      cv::Scalar colour = kTextColour;
      if (IsStale(state, t->recv_utime)) {
        text = std::isfinite(age_s) && age_s < 1e5 ? fmt::format("STALE {:.0f}s", age_s) : "STALE";
        colour = kMutedTextColour;
      } else if (t->lost) {
        text = "lost " + Number(t->rate_hz, 0);
        colour = WarningColour();
      } else {
        text = Number(t->rate_hz, 0) + " " + Number(t->latency_ms, 0);
        if (t->degraded) colour = kDegradedColour;
      }
      if (!shown) colour = Blend(colour, kPanelColour, 0.5);
      Text(w->panel(), Fit(text, kSmallFontScale, column - 4),
           {kPanelPadPx + name_px + i * column, w->y()}, kSmallFontScale, colour);
    }
  }
  w->More(left);
}

void DrawProcesses(PanelWriter* w, const ViewState& state) {
  w->Heading(fmt::format("Processes ({})", state.processes.size()));
  int left = static_cast<int>(state.processes.size());
  const int right = w->width() - kPanelPadPx;
  if (!state.site_warning.empty() && w->Next()) {
    Text(w->panel(), Fit(Printable(state.site_warning, 400), kSmallFontScale, right - kPanelPadPx),
         {kPanelPadPx, w->y()}, kSmallFontScale, WarningColour());
  }
  for (const ProcessView& p : state.processes) {
    if (!w->Next(kLinePx + 2)) break;
    --left;
    const bool stale = IsStale(state, p.recv_utime);
    ProcessStateText st = StateText(p.state);
    std::string state_text = st.text;
    if (stale) {
      state_text = fmt::format("STALE ({})", st.text);
      st.colour = kMutedTextColour;
    }
    const int state_px = TextWidth(state_text, kFontScale);
    Text(w->panel(), state_text, {right - state_px, w->y()}, kFontScale, st.colour);
    Text(w->panel(),
         Fit(Printable(p.name, 40) + "@" + Printable(p.host, 40), kFontScale,
             right - state_px - kPanelPadPx - 8),
         {kPanelPadPx, w->y()}, kFontScale, stale ? kMutedTextColour : kTextColour);
    if (!w->Next()) break;
    std::string detail =
        fmt::format("{}/s out, {} dropped", Number(p.output_rate_hz, 1), p.dropped);
    for (size_t i = 0; i < p.losses.size(); ++i) {
      detail += fmt::format("{}{} {}", i == 0 ? " (" : ", ", Printable(p.losses[i].first, 40),
                            p.losses[i].second);
      if (i + 1 == p.losses.size()) detail += ")";
    }
    // The most frequent rejection reasons first.
    std::vector<std::pair<std::string, int64_t>> rejected = p.rejected;
    std::sort(rejected.begin(), rejected.end(),
              [](const auto& a, const auto& b) { return a.second > b.second; });
    for (size_t i = 0; i < rejected.size() && i < 3; ++i) {
      detail += fmt::format("{} {} {}", i == 0 ? "; rej" : ",", Printable(rejected[i].first, 40),
                            rejected[i].second);
    }
    Text(w->panel(), Fit(detail, kSmallFontScale, right - kPanelPadPx - 10),
         {kPanelPadPx + 10, w->y()}, kSmallFontScale,
         p.dropped > 0 && !stale ? kDegradedColour : kMutedTextColour);
    if (!p.last_error.empty() && (p.state == 2 || p.state == 4) && w->Next()) {
      Text(w->panel(), Fit(p.last_error, kSmallFontScale, right - kPanelPadPx - 10),
           {kPanelPadPx + 10, w->y()}, kSmallFontScale, st.colour);
    }
  }
  w->More(left);
}

struct PreviewCache {
  std::vector<uint8_t> encoded;
  cv::Mat decoded;  // empty when undecodable
  cv::Size box;
  cv::Mat scaled;
  // The detector view, decoded (checked) only when its bytes change.
  std::vector<uint8_t> view_encoded;
  cv::Mat view_decoded;
};

// How much of the detector view shows through the preview: enough to read
// its painted masks and labels, little enough to recognise the scene.
constexpr double kDetectorViewOpacity = 0.7;

const cv::Mat& DecodedDetectorView(const DetectorViewView& view, PreviewCache* cache) {
  if (view.encoded != cache->view_encoded) {
    cache->view_encoded = view.encoded;
    std::string error;
    if (view.encoded.size() > kMaxPreviewBytes ||
        !camera::DecodeImageChecked(view.encoded, kMaxPreviewSidePx, kMaxPreviewSidePx,
                                    cv::IMREAD_COLOR, &cache->view_decoded, &error)) {
      cache->view_decoded.release();
    }
  }
  return cache->view_decoded;
}

// The detector view of the preview's camera blended over the preview
// (`target`, which shows the whole frame at `px_per_source_px`).
void OverlayDetectorView(const DetectorViewView& view, double px_per_source_px, cv::Mat target,
                         PreviewCache* cache) {
  const cv::Mat& decoded = DecodedDetectorView(view, cache);
  if (decoded.empty() || !(px_per_source_px > 0.0)) return;
  const cv::Rect where = cv::Rect(cvRound(view.region_u_px * px_per_source_px),
                                  cvRound(view.region_v_px * px_per_source_px),
                                  std::max(1, cvRound(view.region_width_px * px_per_source_px)),
                                  std::max(1, cvRound(view.region_height_px * px_per_source_px))) &
                         cv::Rect(0, 0, target.cols, target.rows);
  if (where.empty()) return;
  cv::Mat resized;
  cv::resize(decoded, resized, where.size(), 0, 0, cv::INTER_AREA);
  cv::Mat roi = target(where);
  cv::addWeighted(resized, kDetectorViewOpacity, roi, 1.0 - kDetectorViewOpacity, 0.0, roi);
  cv::rectangle(target, where, kWhite, 1);
}

// Each robot's line of the detector view above `bottom` (the preview's
// label), the ones not found in the warning colour; the new bottom.
int DrawDetectorViewLines(cv::Mat& panel, const ViewState& state, int bottom) {
  if (!state.has_detector_view) return bottom;
  const DetectorViewView& v = state.detector_view;
  int y = bottom - kLinePx * static_cast<int>(v.robots.size());
  if (y - kLinePx < kPanelBodyTopPx) return bottom;
  Text(panel,
       fmt::format("camera {} detector view, {} s old", v.camera_id,
                   Number(AgeS(state.now_utime, v.utime), 1)),
       {kPanelPadPx, y - kLinePx + 4}, kSmallFontScale, kTextColour);
  for (const DetectorViewView::Robot& r : v.robots) {
    Text(panel, Fit(r.text, kSmallFontScale, panel.cols - 2 * kPanelPadPx), {kPanelPadPx, y + 4},
         kSmallFontScale, r.found ? kTextColour : WarningColour());
    y += kLinePx;
  }
  return bottom - kLinePx * (static_cast<int>(v.robots.size()) + 1);
}

// Decodes (only when the bytes changed) and scales (only when the box did)
// the preview; an empty result when it cannot be decoded.
const cv::Mat& ScaledPreview(const PreviewView& preview, cv::Size box, PreviewCache* cache,
                             double* scale) {
  if (preview.encoded != cache->encoded) {
    cache->encoded = preview.encoded;
    cache->decoded.release();
    cache->scaled.release();
    // The same checked decoder as camera_proc's frames: the size comes from
    // the header (libjpeg's own parser for JPEG) before a pixel is decoded,
    // so a small preview declaring 20000 x 20000 is refused, not decoded.
    std::string error;
    if (preview.encoded.size() > kMaxPreviewBytes ||
        !camera::DecodeImageChecked(preview.encoded, kMaxPreviewSidePx, kMaxPreviewSidePx,
                                    cv::IMREAD_COLOR, &cache->decoded, &error)) {
      cache->decoded.release();
    }
  }
  *scale = 0.0;
  if (cache->decoded.empty() || box.width <= 0 || box.height <= 0) {
    cache->scaled.release();
    return cache->scaled;
  }
  *scale = std::min(static_cast<double>(box.width) / cache->decoded.cols,
                    static_cast<double>(box.height) / cache->decoded.rows);
  const cv::Size size(std::max(1, cvRound(cache->decoded.cols * *scale)),
                      std::max(1, cvRound(cache->decoded.rows * *scale)));
  if (cache->scaled.size() != size || cache->box != box) {
    cv::resize(cache->decoded, cache->scaled, size, 0, 0, cv::INTER_AREA);
    cache->box = box;
  }
  return cache->scaled;
}

cv::Scalar MarkerColour(const std::string& name) {
  if (name == "orange") return {0, 140, 255};
  if (name == "green") return {40, 220, 40};
  if (name == "red") return {40, 40, 255};
  if (name == "blue") return {255, 120, 0};
  if (name == "yellow") return {0, 230, 255};
  return {255, 0, 255};  // magenta: stands out on most camera pictures
}

// The preview box's top edge, or the panel's height when there is none.
int DrawPreview(cv::Mat& panel, const ViewState& state, PreviewCache* cache) {
  const int box_w = panel.cols - 2 * kPanelPadPx;
  // Too narrow a panel for a picture anyone could read.
  if (!state.has_preview || box_w < 48) return panel.rows;
  // At most a quarter of the panel's height: the tables above matter more.
  const int box_h = std::min(box_w * 3 / 4, panel.rows / 4);
  double scale = 0.0;
  const cv::Mat& scaled = ScaledPreview(state.preview, {box_w, box_h}, cache, &scale);
  const int label_y = panel.rows - kPanelPadPx - (scaled.empty() ? kLinePx : scaled.rows) - 6;
  if (label_y < kPanelBodyTopPx) return panel.rows;
  const double age_s = AgeS(state.now_utime, state.preview.utime);
  Text(panel,
       fmt::format("camera {} preview, {} s old{}", state.preview.camera_id, Number(age_s, 1),
                   scaled.empty() ? ": cannot decode" : ""),
       {kPanelPadPx, label_y}, kSmallFontScale, scaled.empty() ? WarningColour() : kTextColour);
  if (scaled.empty()) return label_y - kLinePx;
  const cv::Rect where(kPanelPadPx, panel.rows - kPanelPadPx - scaled.rows, scaled.cols,
                       scaled.rows);
  cv::Mat target = panel(where);
  scaled.copyTo(target);
  if (state.has_detector_view && state.detector_view.camera_id == state.preview.camera_id &&
      state.detector_view.source_width_px > 0) {
    OverlayDetectorView(state.detector_view,
                        scale * cache->decoded.cols / state.detector_view.source_width_px, target,
                        cache);
  }
  for (const PreviewView::Marker& m : state.preview.markers) {
    const cv::Point2d c(m.u_px * scale, m.v_px * scale);
    const double r = m.radius_px * scale;
    if (!Finite(c.x, c.y) || !std::isfinite(r) || c.x < -r || c.y < -r || c.x > where.width + r ||
        c.y > where.height + r || r > 4.0 * (where.width + where.height)) {
      continue;
    }
    // A ring just outside the marker, over a white one, so that it shows on
    // the blob it circles (drawn in the blob's own colour).
    const int ring_px = std::max(2, cvRound(r)) + kMarkerRingGapPx;
    cv::circle(target, Canvas::ToInt(c), ring_px, kWhite, 4, cv::LINE_AA);
    cv::circle(target, Canvas::ToInt(c), ring_px, MarkerColour(m.colour), 2, cv::LINE_AA);
  }
  return label_y - kLinePx;
}

void DrawPanel(cv::Mat panel, const ViewState& state, PreviewCache* cache) {
  Text(panel, Fit("roomfix  " + state.site.name, 0.6, panel.cols - 2 * kPanelPadPx),
       {kPanelPadPx, 24}, 0.6, kTextColour, 2);
  Text(panel, TimeText(state.now_utime), {kPanelPadPx, 44}, kFontScale, kTextColour);
  const int bottom = DrawDetectorViewLines(panel, state, DrawPreview(panel, state, cache));
  PanelWriter w(panel, kPanelBodyTopPx, bottom);
  DrawSourceTable(&w, state);
  w.Next(6);
  DrawProcesses(&w, state);
}

struct RenderCache {
  std::vector<double> key;
  cv::Mat background;
  PreviewCache preview;
};

}  // namespace

const char* SourceName(PoseSource source) {
  // PoseSourceName's identifiers, but "ground truth" in words.
  return source == PoseSource::kGroundTruth ? "ground truth" : PoseSourceName(source);
}

bool RenderOptions::IsValid(std::string* error) const {
  auto fail = [&](const std::string& what) {
    if (error != nullptr) *error = what;
    return false;
  };
  if (width_px < kMinSidePx || width_px > kMaxSidePx || height_px < kMinSidePx ||
      height_px > kMaxSidePx) {
    return fail(fmt::format("picture {} x {} px: each side must be in [{}, {}]", width_px,
                            height_px, kMinSidePx, kMaxSidePx));
  }
  if (panel_px < 0 || panel_px > width_px - kMinFloorPx) {
    return fail(fmt::format("panel_px {}: must be in [0, width_px - {}] ({})", panel_px,
                            kMinFloorPx, width_px - kMinFloorPx));
  }
  if (!std::isfinite(zoom) || zoom < kMinZoom || zoom > kMaxZoom) {
    return fail(fmt::format("zoom {:g}: must be in [{:g}, {:g}]", zoom, kMinZoom, kMaxZoom));
  }
  if (!std::isfinite(pan_x_m) || !std::isfinite(pan_y_m) || std::fabs(pan_x_m) > kMaxPanM ||
      std::fabs(pan_y_m) > kMaxPanM) {
    return fail(fmt::format("pan ({:g}, {:g}) m: must be finite and within {:g} m", pan_x_m,
                            pan_y_m, kMaxPanM));
  }
  return true;
}

cv::Point2d FloorMapping::ToPixel(double x_m, double y_m) const {
  return {u0_px + scale_px_per_m * x_m, v0_px - scale_px_per_m * y_m};
}

void FloorMapping::ToFloor(cv::Point2d px, double* x_m, double* y_m) const {
  *x_m = (px.x - u0_px) / scale_px_per_m;
  *y_m = (v0_px - px.y) / scale_px_per_m;
}

FloorMapping MakeFloorMapping(const Site& site, const RenderOptions& options) {
  const RenderOptions o = Sanitized(options);
  const double floor_w = o.width_px - o.panel_px;
  const double floor_h = o.height_px;
  Room room = site.room;
  if (!SaneRoom(room)) {
    room.min_x_m = 0;
    room.min_y_m = 0;
    room.size_x_m = 1;
    room.size_y_m = 1;
  }
  const double span_x = room.size_x_m + 2 * kMarginM;
  const double span_y = room.size_y_m + 2 * kMarginM;
  const double centre_x = room.min_x_m + 0.5 * room.size_x_m + o.pan_x_m;
  const double centre_y = room.min_y_m + 0.5 * room.size_y_m + o.pan_y_m;
  FloorMapping m;
  m.scale_px_per_m = std::min(floor_w / span_x, floor_h / span_y) * o.zoom;
  m.u0_px = 0.5 * floor_w - m.scale_px_per_m * centre_x;
  m.v0_px = 0.5 * floor_h + m.scale_px_per_m * centre_y;
  return m;
}

cv::Scalar SourceColour(PoseSource source) {
  switch (source) {
    case PoseSource::kCamera:
      return {0, 130, 245};  // orange
    case PoseSource::kUltrasound:
      return {205, 105, 20};  // blue
    case PoseSource::kFused:
      return {50, 165, 30};  // green
    case PoseSource::kGroundTruth:
      return {35, 35, 35};  // near-black
    case PoseSource::kUnknown:
      break;
  }
  return {255, 0, 255};
}

cv::Scalar WarningColour() { return {30, 30, 215}; }
cv::Scalar ReceiverColour() { return {120, 30, 120}; }
cv::Scalar ObstacleColour() { return kObstacleColour; }
cv::Scalar StaleColour() { return {175, 175, 175}; }
cv::Scalar FloorColour() { return {247, 246, 242}; }

void Render(const ViewState& state, const RenderOptions& options, cv::Mat* image) {
  if (image == nullptr) return;
  thread_local RenderCache cache;
  const RenderOptions o = Sanitized(options);
  const FloorMapping mapping = MakeFloorMapping(state.site, o);
  std::vector<double> key = BackgroundKey(state.site, state.footprints, o);
  if (!SameKey(key, cache.key) || cache.background.empty()) {
    DrawBackground(state.site, state.footprints, o, mapping, &cache.background);
    cache.key = std::move(key);
  }
  // copyTo reallocates only when the size or type differs.
  cache.background.copyTo(*image);

  const int floor_w = o.width_px - o.panel_px;
  Canvas canvas((*image)(cv::Rect(0, 0, floor_w, o.height_px)), mapping);
  // Range circles belong to the ultrasound view: hiding ultrasound hides
  // them too, which is the way to see the other sources in a busy room.
  if (state.visible[static_cast<size_t>(PoseSource::kUltrasound)]) {
    for (const RangeSetView& set : state.range_sets) {
      DrawRangeSet(&canvas, set, IsStale(state, set.recv_utime));
    }
  }
  DrawTracks(&canvas, state);
  if (o.panel_px > 0) {
    DrawPanel((*image)(cv::Rect(floor_w, 0, o.panel_px, o.height_px)), state, &cache.preview);
  }
}

}  // namespace roomfix::viewer
