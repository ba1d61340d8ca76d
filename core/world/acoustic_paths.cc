#include "core/world/acoustic_paths.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace roomfix {
namespace {

using Vec3 = std::array<double, 3>;

Vec3 Sub(const Vec3& a, const Vec3& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
double Dot(const Vec3& a, const Vec3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
double Norm(const Vec3& a) { return std::sqrt(Dot(a, a)); }

// A segment shorter than this fraction of its length inside an obstacle only
// touches it: a leg that ends on the face it reflects from, or grazes an
// edge. 1e-9 of a few metres is nanometres, far below any survey.
constexpr double kTouchFraction = 1e-9;

// Clips the parameter interval [*lo, *hi] of p(s) = a + s d to the slab
// lo_bound <= p_k <= hi_bound of one axis; false when nothing is left. A
// segment parallel to the slab and on its boundary only slides along a face:
// outside, as touching is.
bool ClipSlab(double a, double d, double lo_bound, double hi_bound, double* lo, double* hi) {
  if (std::abs(d) < 1e-15) return a > lo_bound && a < hi_bound;
  double s0 = (lo_bound - a) / d;
  double s1 = (hi_bound - a) / d;
  if (s0 > s1) std::swap(s0, s1);
  *lo = std::max(*lo, s0);
  *hi = std::min(*hi, s1);
  return *lo <= *hi;
}

// The part of segment a -> b (s in [0, 1]) inside the obstacle centred at c:
// true when it has a length above kTouchFraction.
bool SegmentEnters(const Obstacle& o, const std::array<double, 2>& c, const Vec3& a,
                   const Vec3& b) {
  double lo = 0.0;
  double hi = 1.0;
  const Vec3 d = Sub(b, a);
  if (!ClipSlab(a[2], d[2], o.bottom_m, o.top_m, &lo, &hi)) return false;
  const double ax = a[0] - c[0];
  const double ay = a[1] - c[1];
  if (o.shape == Obstacle::Shape::kCylinder) {
    // |(ax, ay) + s (dx, dy)|^2 <= r^2: a quadratic in s.
    const double qa = d[0] * d[0] + d[1] * d[1];
    const double qb = 2.0 * (ax * d[0] + ay * d[1]);
    const double qc = ax * ax + ay * ay - o.radius_m * o.radius_m;
    if (qa < 1e-30) {
      if (qc > 0.0) return false;
    } else {
      const double disc = qb * qb - 4.0 * qa * qc;
      if (disc <= 0.0) return false;
      const double root = std::sqrt(disc);
      lo = std::max(lo, (-qb - root) / (2.0 * qa));
      hi = std::min(hi, (-qb + root) / (2.0 * qa));
    }
  } else {
    // Into the box's own frame: turn by -yaw about its centre.
    const double cs = std::cos(o.yaw_rad);
    const double sn = std::sin(o.yaw_rad);
    const double u = cs * ax + sn * ay;
    const double v = -sn * ax + cs * ay;
    const double du = cs * d[0] + sn * d[1];
    const double dv = -sn * d[0] + cs * d[1];
    if (!ClipSlab(u, du, -0.5 * o.size_m[0], 0.5 * o.size_m[0], &lo, &hi)) return false;
    if (!ClipSlab(v, dv, -0.5 * o.size_m[1], 0.5 * o.size_m[1], &lo, &hi)) return false;
  }
  return hi - lo > kTouchFraction;
}

// A bounded plane mirror: points q with n.(q - origin) = 0, |u.(q - origin)|
// <= half_u and |w.(q - origin)| <= half_w, reflecting on its n side.
struct Mirror {
  Vec3 origin;
  Vec3 n;
  Vec3 u;
  Vec3 w;
  double half_u;
  double half_w;
  AudiblePath::Mirror kind;
  int obstacle_index;
};

// A reflection closer than this to its mirror is not a distinct path: a
// receiver on a wall hears the wall's "reflection" at its own position,
// the direct path again.
constexpr double kMinMirrorDistanceM = 1e-3;

void AddRoomMirrors(const Room& room, std::vector<Mirror>* out) {
  const double x0 = room.min_x_m, x1 = room.min_x_m + room.size_x_m;
  const double y0 = room.min_y_m, y1 = room.min_y_m + room.size_y_m;
  const double h = room.height_m;
  const double cx = 0.5 * (x0 + x1), cy = 0.5 * (y0 + y1), cz = 0.5 * h;
  const double hx = 0.5 * room.size_x_m, hy = 0.5 * room.size_y_m, hz = 0.5 * h;
  using M = AudiblePath::Mirror;
  out->push_back({{x0, cy, cz}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, hy, hz, M::kWall, -1});
  out->push_back({{x1, cy, cz}, {-1, 0, 0}, {0, 1, 0}, {0, 0, 1}, hy, hz, M::kWall, -1});
  out->push_back({{cx, y0, cz}, {0, 1, 0}, {1, 0, 0}, {0, 0, 1}, hx, hz, M::kWall, -1});
  out->push_back({{cx, y1, cz}, {0, -1, 0}, {1, 0, 0}, {0, 0, 1}, hx, hz, M::kWall, -1});
  out->push_back({{cx, cy, 0.0}, {0, 0, 1}, {1, 0, 0}, {0, 1, 0}, hx, hy, M::kFloor, -1});
  out->push_back({{cx, cy, h}, {0, 0, -1}, {1, 0, 0}, {0, 1, 0}, hx, hy, M::kCeiling, -1});
}

// A box's four sides, its top and (when it stands off the floor) its bottom,
// each facing outwards.
void AddBoxMirrors(const Obstacle& o, const std::array<double, 2>& c, int index,
                   std::vector<Mirror>* out) {
  const double cs = std::cos(o.yaw_rad);
  const double sn = std::sin(o.yaw_rad);
  const Vec3 ex = {cs, sn, 0.0};
  const Vec3 ey = {-sn, cs, 0.0};
  const Vec3 ez = {0.0, 0.0, 1.0};
  const double hx = 0.5 * o.size_m[0];
  const double hy = 0.5 * o.size_m[1];
  const double hz = 0.5 * (o.top_m - o.bottom_m);
  const double zc = 0.5 * (o.top_m + o.bottom_m);
  using M = AudiblePath::Mirror;
  for (const double side : {1.0, -1.0}) {
    out->push_back({{c[0] + side * hx * ex[0], c[1] + side * hx * ex[1], zc},
                    {side * ex[0], side * ex[1], 0.0},
                    ey,
                    ez,
                    hy,
                    hz,
                    M::kObstacleFace,
                    index});
    out->push_back({{c[0] + side * hy * ey[0], c[1] + side * hy * ey[1], zc},
                    {side * ey[0], side * ey[1], 0.0},
                    ex,
                    ez,
                    hx,
                    hz,
                    M::kObstacleFace,
                    index});
  }
  out->push_back({{c[0], c[1], o.top_m}, ez, ex, ey, hx, hy, M::kObstacleFace, index});
  if (o.bottom_m > 0.0) {
    out->push_back({{c[0], c[1], o.bottom_m}, {0, 0, -1}, ex, ey, hx, hy, M::kObstacleFace, index});
  }
}

}  // namespace

const char* AudiblePathKindName(AudiblePath::Kind kind) {
  switch (kind) {
    case AudiblePath::Kind::kDirect:
      return "direct";
    case AudiblePath::Kind::kReflected:
      return "reflected";
    case AudiblePath::Kind::kNone:
      return "none";
  }
  return "?";
}

AcousticScene::AcousticScene(const Site& site, double temperature_c)
    : room_(site.room),
      obstacles_(site.obstacles),
      decay_(ComputeRoomDecay(site, temperature_c)),
      reflection_loss_db_(
          -10.0 * std::log10(1.0 - std::min(site.acoustics.wall_absorption, 1.0 - 1e-12))) {}

std::vector<AcousticScene::Placed> AcousticScene::PlaceAt(double t_s) const {
  std::vector<Placed> placed;
  placed.reserve(obstacles_.size());
  for (const Obstacle& o : obstacles_) placed.push_back({o, o.CentreAt(t_s)});
  return placed;
}

bool AcousticScene::BlockedBy(const std::vector<Placed>& placed, const Vec3& a, const Vec3& b) {
  for (const Placed& p : placed) {
    if (SegmentEnters(p.obstacle, p.centre_m, a, b)) return true;
  }
  return false;
}

bool AcousticScene::Blocked(double t_s, const Vec3& a, const Vec3& b) const {
  return BlockedBy(PlaceAt(t_s), a, b);
}

AudiblePath AcousticScene::ShortestAudiblePath(double t_s, const Vec3& beacon_m,
                                               const Vec3& receiver_m) const {
  const std::vector<Placed> placed = PlaceAt(t_s);
  AudiblePath best;
  best.direct_m = Norm(Sub(receiver_m, beacon_m));
  const double alpha = decay_.air_absorption_db_per_m;
  // Spreading from 1 m, the air, and the reflections.
  auto loss = [&](double length_m, int reflections) {
    return 20.0 * std::log10(std::max(length_m, 1e-3)) + alpha * length_m +
           reflections * reflection_loss_db_;
  };
  if (!BlockedBy(placed, beacon_m, receiver_m)) {
    best.kind = AudiblePath::Kind::kDirect;
    best.length_m = best.direct_m;
    best.loss_db = loss(best.length_m, 0);
    best.level_db = decay_.level_at_1m_db - best.loss_db;
    return best;
  }
  std::vector<Mirror> mirrors;
  AddRoomMirrors(room_, &mirrors);
  for (size_t i = 0; i < placed.size(); ++i) {
    if (placed[i].obstacle.shape == Obstacle::Shape::kBox) {
      AddBoxMirrors(placed[i].obstacle, placed[i].centre_m, static_cast<int>(i), &mirrors);
    }
  }
  // A path arriving after the receiver stops listening is never timed.
  const double max_length_m = decay_.listen_s * decay_.max_range_m / decay_.max_time_of_flight_s;
  best.length_m = std::numeric_limits<double>::quiet_NaN();
  for (const Mirror& m : mirrors) {
    const double ds = Dot(m.n, Sub(beacon_m, m.origin));
    const double dr = Dot(m.n, Sub(receiver_m, m.origin));
    if (ds < kMinMirrorDistanceM || dr < kMinMirrorDistanceM) continue;
    // Image source S' = S - 2 ds n; the path S' -> R crosses the plane at
    // the fraction ds / (ds + dr) of its length, and |S' - R| is the length
    // of the reflected path.
    const Vec3 image = {beacon_m[0] - 2 * ds * m.n[0], beacon_m[1] - 2 * ds * m.n[1],
                        beacon_m[2] - 2 * ds * m.n[2]};
    const double length_m = Norm(Sub(receiver_m, image));
    if (length_m > max_length_m) continue;
    if (best.kind == AudiblePath::Kind::kReflected && length_m >= best.length_m) continue;
    const double f = ds / (ds + dr);
    const Vec3 p = {image[0] + f * (receiver_m[0] - image[0]),
                    image[1] + f * (receiver_m[1] - image[1]),
                    image[2] + f * (receiver_m[2] - image[2])};
    const Vec3 rel = Sub(p, m.origin);
    if (std::abs(Dot(rel, m.u)) > m.half_u || std::abs(Dot(rel, m.w)) > m.half_w) continue;
    const double level_db = decay_.level_at_1m_db - loss(length_m, 1);
    if (level_db < 0.0) continue;
    if (BlockedBy(placed, beacon_m, p) || BlockedBy(placed, p, receiver_m)) continue;
    best.kind = AudiblePath::Kind::kReflected;
    best.length_m = length_m;
    best.loss_db = loss(length_m, 1);
    best.level_db = level_db;
    best.mirror = m.kind;
    best.obstacle_index = m.obstacle_index;
    best.reflection_point_m = p;
  }
  if (best.kind == AudiblePath::Kind::kNone) {
    best.loss_db = std::numeric_limits<double>::infinity();
    best.level_db = -std::numeric_limits<double>::infinity();
  }
  return best;
}

AudiblePath ShortestAudiblePath(const Site& site, const Vec3& beacon_m, const Vec3& receiver_m,
                                double t_s, double temperature_c) {
  return AcousticScene(site, temperature_c).ShortestAudiblePath(t_s, beacon_m, receiver_m);
}

}  // namespace roomfix
