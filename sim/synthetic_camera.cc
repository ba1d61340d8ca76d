#include "sim/synthetic_camera.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <limits>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>
#include <sstream>
#include <utility>

#include "core/world/file_io.h"

namespace roomfix::sim {
namespace {

constexpr double kPi = 3.14159265358979323846;
// Wall colour (outside the room rectangle) relative to the floor colour.
constexpr double kWallShade = 0.55;
// Noise is stored as int8 in units of 1/kNoiseUnits of a standard deviation
// (clipped at +-8 sigma; the quantisation adds (1/16)^2/12 of the variance).
// Not a power of two: with one, noise of sigma 2 DN would come in steps of
// 1/8 DN, every eighth value would land on the rounding midpoint and the
// mean would rise by 1/16 DN.
constexpr double kNoiseUnits = 15.7;
// Points on a disc's rim projected to bound its pixels.
constexpr int kRimPoints = 64;
// Safety factor on a pixel's footprint radius (the pixel-to-plane map is
// close to affine over one pixel; 1.5 covers its curvature with room).
constexpr double kFootprintSafety = 1.5;

uint64_t SplitMix64(uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

cv::Vec3f ToVec(const cv::Scalar& s) {
  return cv::Vec3f(static_cast<float>(s[0]), static_cast<float>(s[1]), static_cast<float>(s[2]));
}

// Middle of an HSV range (hue wrapping through 0 when min > max) in BGR.
cv::Vec3f ClassColour(const MarkerClass& c) {
  int h = (c.hsv_min[0] + c.hsv_max[0]) / 2;
  if (c.hsv_min[0] > c.hsv_max[0]) h = ((c.hsv_min[0] + c.hsv_max[0] + 180) / 2) % 180;
  const int s = (c.hsv_min[1] + c.hsv_max[1]) / 2;
  const int v = (c.hsv_min[2] + c.hsv_max[2]) / 2;
  cv::Mat hsv(1, 1, CV_8UC3, cv::Scalar(h, s, v));
  cv::Mat bgr;
  cv::cvtColor(hsv, bgr, cv::COLOR_HSV2BGR);
  const cv::Vec3b p = bgr.at<cv::Vec3b>(0, 0);
  return cv::Vec3f(p[0], p[1], p[2]);
}

struct Disc {
  double cx = 0.0, cy = 0.0, z = 0.0, r = 0.0;
  cv::Vec3f bgr;
  // Index into the truth list, or -1 (robot bodies).
  int truth_index = -1;
};

}  // namespace

struct SyntheticCamera::Impl {
  Room room;
  std::vector<CameraRobot> camera_robots;
  MarkerCode marker_code;
  std::map<std::string, std::pair<double, cv::Vec3f>> classes;  // diameter, colour
  std::vector<SimulatedRobot> sim_robots;
  SimScenario scenario;
  SyntheticCameraOptions options;
  calib::CameraModel model;
  int w = 0, h = 0;
  double px = 0.0, py = 0.0, pz = 0.0;
  // Per pixel centre, for u in [-1, w] and v in [-1, h]: (dx/dz, dy/dz) of
  // the room-frame ray, so that the ray meets the plane z at
  // (px + (z - pz) a, py + (z - pz) b). NaN where the ray does not go down.
  std::vector<float> ab;
  cv::Mat base;                    // CV_8UC3, floor and grid
  std::vector<float> gradient;     // w * h gains, empty when no gradient
  std::vector<int8_t> noise_bank;  // empty when no noise
  size_t frame_values = 0;

  size_t Index(int i, int j) const {
    return 2 *
           (static_cast<size_t>(j + 1) * static_cast<size_t>(w + 2) + static_cast<size_t>(i + 1));
  }
  // Bilinear interpolation of the ray map at (u, v); false off the map or on
  // an invalid ray.
  bool Sample(double u, double v, double* a, double* b) const {
    if (!(u >= -1.0 && u <= w && v >= -1.0 && v <= h)) return false;
    int i0 = std::min(static_cast<int>(std::floor(u)), w - 1);
    int j0 = std::min(static_cast<int>(std::floor(v)), h - 1);
    const double fu = u - i0, fv = v - j0;
    const float* p00 = &ab[Index(i0, j0)];
    const float* p01 = &ab[Index(i0, j0 + 1)];
    const double w00 = (1 - fu) * (1 - fv), w10 = fu * (1 - fv), w01 = (1 - fu) * fv, w11 = fu * fv;
    *a = w00 * p00[0] + w10 * p00[2] + w01 * p01[0] + w11 * p01[2];
    *b = w00 * p00[1] + w10 * p00[3] + w01 * p01[1] + w11 * p01[3];
    return std::isfinite(*a) && std::isfinite(*b);
  }
  // Radius (in ray-map units) of the circle around pixel (i, j)'s centre that
  // holds the pixel's footprint; NaN when a neighbour is invalid.
  double FootprintAb(int i, int j) const {
    const float* l = &ab[Index(i - 1, j)];
    const float* r = &ab[Index(i + 1, j)];
    const float* t = &ab[Index(i, j - 1)];
    const float* d = &ab[Index(i, j + 1)];
    const double du = 0.5 * std::hypot(r[0] - l[0], r[1] - l[1]);
    const double dv = 0.5 * std::hypot(d[0] - t[0], d[1] - t[1]);
    return kFootprintSafety * 0.5 * (du + dv);
  }

  cv::Vec3f FloorColour(double x, double y) const {
    const double max_x = room.min_x_m + room.size_x_m, max_y = room.min_y_m + room.size_y_m;
    const cv::Vec3f floor = ToVec(options.floor_bgr);
    if (!(x >= room.min_x_m && x <= max_x && y >= room.min_y_m && y <= max_y)) {
      return floor * static_cast<float>(kWallShade);
    }
    const double g = room.grid_m, half = 0.5 * options.grid_line_width_m;
    if (g > 0) {
      const double gx = x - room.min_x_m, gy = y - room.min_y_m;
      if (std::abs(gx - std::round(gx / g) * g) <= half ||
          std::abs(gy - std::round(gy / g) * g) <= half) {
        return ToVec(options.grid_bgr);
      }
    }
    return floor;
  }
  // Distance from (x, y) to the nearest edge where FloorColour changes.
  double FloorEdgeDistance(double x, double y) const {
    const double max_x = room.min_x_m + room.size_x_m, max_y = room.min_y_m + room.size_y_m;
    double d = std::min({std::abs(x - room.min_x_m), std::abs(x - max_x),
                         std::abs(y - room.min_y_m), std::abs(y - max_y)});
    const double g = room.grid_m, half = 0.5 * options.grid_line_width_m;
    if (g > 0) {
      const double gx = x - room.min_x_m, gy = y - room.min_y_m;
      d = std::min(d, std::abs(std::abs(gx - std::round(gx / g) * g) - half));
      d = std::min(d, std::abs(std::abs(gy - std::round(gy / g) * g) - half));
    }
    return d;
  }

  void BuildRayMap();
  void RenderFloor();
  void BuildLighting();
  double GainAt(double t_s) const;
  // Composites a disc into `image` (CV_8UC3) by supersampled coverage and
  // fills the truth's centroid, area and visibility.
  void DrawDisc(const Disc& disc, cv::Mat* image, MarkerTruth* truth) const;
};

void SyntheticCamera::Impl::BuildRayMap() {
  ab.assign(2 * static_cast<size_t>(w + 2) * static_cast<size_t>(h + 2),
            std::numeric_limits<float>::quiet_NaN());
  const Eigen::Matrix3d& R = model.pose.R_room_from_camera;
  const calib::FisheyeIntrinsics& in = model.intrinsics;
  // The undistortion depends on the distorted radius theta_d alone: tabulate
  // sin(theta) / theta_d and cos(theta) against theta_d with PixelToRay, at
  // steps of kRadialStep (0.1 px at f = 1000 px; linear interpolation errs by
  // step^2 / 8 ~ 1e-9 rad), instead of 2 M Newton solves.
  constexpr double kRadialStep = 1e-4;
  double r_max = 0.0;
  for (const double u : {-1.0, static_cast<double>(w)}) {
    for (const double v : {-1.0, static_cast<double>(h)}) {
      r_max = std::max(r_max, std::hypot((u - in.cx_px) / in.fx_px, (v - in.cy_px) / in.fy_px));
    }
  }
  const size_t n = static_cast<size_t>(std::ceil(r_max / kRadialStep)) + 2;
  std::vector<double> sin_over_r(n, std::numeric_limits<double>::quiet_NaN());
  std::vector<double> cos_theta(n, std::numeric_limits<double>::quiet_NaN());
  for (size_t k = 0; k < n; ++k) {
    const double r = static_cast<double>(k) * kRadialStep;
    Eigen::Vector3d ray;
    if (!model.PixelToRay(in.cx_px + r * in.fx_px, in.cy_px, &ray)) continue;
    const double xd = (in.cx_px + r * in.fx_px - in.cx_px) / in.fx_px;
    sin_over_r[k] = k == 0 ? 1.0 : ray.x() / xd;
    cos_theta[k] = ray.z();
  }
  for (int j = -1; j <= h; ++j) {
    for (int i = -1; i <= w; ++i) {
      const double xd = (i - in.cx_px) / in.fx_px, yd = (j - in.cy_px) / in.fy_px;
      const double f = std::hypot(xd, yd) / kRadialStep;
      const size_t k = static_cast<size_t>(f);
      Eigen::Vector3d ray;
      if (k + 1 < n && std::isfinite(sin_over_r[k]) && std::isfinite(sin_over_r[k + 1])) {
        const double t = f - static_cast<double>(k);
        const double s = sin_over_r[k] + t * (sin_over_r[k + 1] - sin_over_r[k]);
        ray = Eigen::Vector3d(s * xd, s * yd, cos_theta[k] + t * (cos_theta[k + 1] - cos_theta[k]));
      } else if (!model.PixelToRay(i, j, &ray)) {
        continue;
      }
      const Eigen::Vector3d d = R * ray;
      if (!(d.z() < -1e-9)) continue;
      float* p = &ab[Index(i, j)];
      p[0] = static_cast<float>(d.x() / d.z());
      p[1] = static_cast<float>(d.y() / d.z());
    }
  }
}

void SyntheticCamera::Impl::RenderFloor() {
  base.create(h, w, CV_8UC3);
  const int s = std::max(1, options.supersample);
  const cv::Vec3f wall = ToVec(options.floor_bgr) * static_cast<float>(kWallShade);
  for (int j = 0; j < h; ++j) {
    cv::Vec3b* row = base.ptr<cv::Vec3b>(j);
    for (int i = 0; i < w; ++i) {
      const float* p = &ab[Index(i, j)];
      cv::Vec3f colour = wall;
      if (std::isfinite(p[0])) {
        const double x = px - pz * p[0], y = py - pz * p[1];
        const double rho = pz * FootprintAb(i, j);
        if (std::isfinite(rho) && FloorEdgeDistance(x, y) > rho) {
          colour = FloorColour(x, y);
        } else {
          cv::Vec3f sum(0, 0, 0);
          for (int sj = 0; sj < s; ++sj) {
            for (int si = 0; si < s; ++si) {
              double a, b;
              if (Sample(i - 0.5 + (si + 0.5) / s, j - 0.5 + (sj + 0.5) / s, &a, &b)) {
                sum += FloorColour(px - pz * a, py - pz * b);
              } else {
                sum += wall;
              }
            }
          }
          colour = sum * (1.0f / static_cast<float>(s * s));
        }
      }
      row[i] = cv::Vec3b(cv::saturate_cast<uchar>(colour[0]), cv::saturate_cast<uchar>(colour[1]),
                         cv::saturate_cast<uchar>(colour[2]));
    }
  }
}

void SyntheticCamera::Impl::BuildLighting() {
  if (scenario.gradient != 0.0 && room.size_x_m > 0) {
    gradient.assign(static_cast<size_t>(w) * h, 1.0f);
    for (int j = 0; j < h; ++j) {
      for (int i = 0; i < w; ++i) {
        const float* p = &ab[Index(i, j)];
        if (!std::isfinite(p[0])) continue;
        const double f = std::clamp((px - pz * p[0] - room.min_x_m) / room.size_x_m, 0.0, 1.0);
        gradient[static_cast<size_t>(j) * w + i] =
            static_cast<float>(1.0 + scenario.gradient * (2.0 * f - 1.0));
      }
    }
  }
  frame_values = static_cast<size_t>(w) * h * 3;
  if (scenario.noise_sigma_dn > 0) {
    // One frame and a half of standard normal values; a frame reads a window
    // starting at a pseudo-random offset.
    cv::Mat bank(1, static_cast<int>(frame_values + frame_values / 2), CV_8S);
    cv::RNG rng(SplitMix64(scenario.seed));
    rng.fill(bank, cv::RNG::NORMAL, 0.0, kNoiseUnits);
    noise_bank.assign(bank.ptr<int8_t>(0), bank.ptr<int8_t>(0) + bank.cols);
  }
}

double SyntheticCamera::Impl::GainAt(double t_s) const {
  const auto& steps = scenario.gain_steps;
  if (steps.empty()) return 1.0;
  if (!(t_s > 0) || scenario.gain_step_period_s <= 0) return steps[0];
  const double period = scenario.gain_step_period_s;
  const int64_t n = static_cast<int64_t>(std::floor(t_s / period));
  const double tau = t_s - n * period;
  const size_t count = steps.size();
  const double current = steps[static_cast<size_t>(n % static_cast<int64_t>(count))];
  if (n == 0 || tau >= scenario.gain_ramp_s) return current;
  const double previous = steps[static_cast<size_t>((n - 1) % static_cast<int64_t>(count))];
  return previous + (current - previous) * tau / scenario.gain_ramp_s;
}

void SyntheticCamera::Impl::DrawDisc(const Disc& disc, cv::Mat* image, MarkerTruth* truth) const {
  // Bound the disc's pixels by projecting its rim.
  double u_min = 1e300, u_max = -1e300, v_min = 1e300, v_max = -1e300;
  bool inside = true;
  for (int k = 0; k < kRimPoints; ++k) {
    const double phi = 2 * kPi * k / kRimPoints;
    double u, v;
    if (!model.ProjectToPixel(Eigen::Vector3d(disc.cx + disc.r * std::cos(phi),
                                              disc.cy + disc.r * std::sin(phi), disc.z),
                              &u, &v)) {
      if (truth) truth->visible = false;
      return;
    }
    u_min = std::min(u_min, u), u_max = std::max(u_max, u);
    v_min = std::min(v_min, v), v_max = std::max(v_max, v);
    if (u < -0.5 || u > w - 0.5 || v < -0.5 || v > h - 0.5) inside = false;
  }
  // The rim polygon's chords lie inside the circle: a margin of two pixels.
  const int i0 = std::max(0, static_cast<int>(std::floor(u_min)) - 2);
  const int i1 = std::min(w - 1, static_cast<int>(std::ceil(u_max)) + 2);
  const int j0 = std::max(0, static_cast<int>(std::floor(v_min)) - 2);
  const int j1 = std::min(h - 1, static_cast<int>(std::ceil(v_max)) + 2);
  const int s = std::max(1, options.supersample);
  const double depth = disc.z - pz;  // plane point = camera + depth * (a, b)
  const double r2 = disc.r * disc.r;
  double sum = 0, sum_u = 0, sum_v = 0;
  for (int j = j0; j <= j1; ++j) {
    cv::Vec3b* row = image->ptr<cv::Vec3b>(j);
    for (int i = i0; i <= i1; ++i) {
      const float* p = &ab[Index(i, j)];
      if (!std::isfinite(p[0])) continue;
      const double dx = px + depth * p[0] - disc.cx, dy = py + depth * p[1] - disc.cy;
      const double dist = std::hypot(dx, dy);
      const double rho = std::abs(depth) * FootprintAb(i, j);
      double coverage;
      if (std::isfinite(rho) && dist + rho <= disc.r) {
        coverage = 1.0;
      } else if (std::isfinite(rho) && dist - rho >= disc.r) {
        continue;
      } else {
        int hits = 0;
        for (int sj = 0; sj < s; ++sj) {
          for (int si = 0; si < s; ++si) {
            double a, b;
            if (!Sample(i - 0.5 + (si + 0.5) / s, j - 0.5 + (sj + 0.5) / s, &a, &b)) continue;
            const double ex = px + depth * a - disc.cx, ey = py + depth * b - disc.cy;
            if (ex * ex + ey * ey <= r2) ++hits;
          }
        }
        if (hits == 0) continue;
        coverage = static_cast<double>(hits) / (s * s);
      }
      sum += coverage;
      sum_u += coverage * i;
      sum_v += coverage * j;
      cv::Vec3b& out = row[i];
      for (int c = 0; c < 3; ++c) {
        out[c] = cv::saturate_cast<uchar>(coverage * disc.bgr[c] + (1.0 - coverage) * out[c]);
      }
    }
  }
  if (truth) {
    truth->area_px = sum;
    if (sum > 0) {
      truth->centroid_u_px = sum_u / sum;
      truth->centroid_v_px = sum_v / sum;
    }
    truth->visible = inside && sum > 0;
  }
}

bool ParseSimScenario(const std::string& text, SimScenario* scenario, std::string* error) {
  std::string name = text;
  if (name.rfind("sim:", 0) == 0) name = name.substr(4);
  SimScenario s;
  s.name = name;
  const bool lighting = name == "lighting" || name == "harsh";
  const bool distractors = name == "distractors" || name == "harsh";
  if (!(name == "clean" || name == "reference_circle" || lighting || distractors)) {
    if (error) {
      *error = "unknown simulation scenario '" + text +
               "': known scenarios are clean, reference_circle, lighting, distractors, harsh "
               "(optionally prefixed sim:)";
    }
    return false;
  }
  if (lighting) {
    s.gain_steps = {1.0, 1.4, 0.6};
    s.gradient = 0.3;
    s.flicker_amplitude = 0.1;
    s.flicker_hz = 100.0;
  }
  if (lighting || distractors) s.noise_sigma_dn = 2.0;
  if (distractors) {
    // In the demo room's frame (origin at a floor corner, 4 x 3 m): a fake
    // robot (orange with a green beside it) 0.5 m from the walls in the
    // corner at the origin, and a lone orange disc in the opposite corner;
    // both far from the reference circle (x 1.5..2.3 m, y 1.1..1.9 m).
    s.distractors = {
        {"orange", 0.50, 0.50, 0.10}, {"green", 0.62, 0.50, 0.05}, {"orange", 3.50, 2.50, 0.10}};
  }
  *scenario = s;
  return true;
}

SyntheticCamera::SyntheticCamera(const Site& site, const Camera& camera,
                                 const calib::CameraModel& model, SimScenario scenario,
                                 SyntheticCameraOptions options)
    : model_(model) {
  auto impl = std::make_shared<Impl>();
  impl->room = site.room;
  impl->camera_robots = camera.robots;
  impl->marker_code = camera.marker_code;
  for (const auto& c : camera.marker_classes) {
    impl->classes[c.name] = {c.diameter_m, ClassColour(c)};
  }
  impl->sim_robots = site.simulation.robots;
  impl->scenario = std::move(scenario);
  impl->options = options;
  impl->model = model;
  impl->w = camera.width_px > 0 ? camera.width_px : model.intrinsics.width_px;
  impl->h = camera.height_px > 0 ? camera.height_px : model.intrinsics.height_px;
  impl->px = model.pose.position_m.x();
  impl->py = model.pose.position_m.y();
  impl->pz = model.pose.position_m.z();
  impl->BuildRayMap();
  impl->RenderFloor();
  impl->BuildLighting();
  impl_ = std::move(impl);
}

int SyntheticCamera::width_px() const { return impl_->w; }
int SyntheticCamera::height_px() const { return impl_->h; }

std::vector<RobotState> SyntheticCamera::SimulatedRobots(double t_s) const {
  std::vector<RobotState> out;
  for (const auto& r : impl_->sim_robots) {
    if (!r.trajectory) continue;
    const bool known = std::any_of(impl_->camera_robots.begin(), impl_->camera_robots.end(),
                                   [&](const CameraRobot& c) { return c.robot_id == r.robot_id; });
    if (!known) continue;
    const GroundTruthPose pose = r.trajectory->PoseAt(t_s);
    out.push_back({r.robot_id, pose.x_m, pose.y_m, pose.heading_rad});
  }
  return out;
}

void SyntheticCamera::Render(double t_s, int64_t frame_seq, const std::vector<RobotState>& robots,
                             cv::Mat* bgr, std::vector<MarkerTruth>* truth) const {
  const Impl& m = *impl_;
  impl_->base.copyTo(*bgr);
  std::vector<MarkerTruth> local_truth;
  std::vector<MarkerTruth>& marks = truth ? *truth : local_truth;
  marks.clear();
  std::vector<Disc> discs;
  // diameter_m <= 0: the class's diameter.
  auto add_marker = [&](const std::string& cls, int robot_id, bool heading, double x, double y,
                        double z, double diameter_m) {
    const auto it = m.classes.find(cls);
    if (it == m.classes.end()) return;
    MarkerTruth t;
    t.robot_id = robot_id;
    t.colour_class = cls;
    t.is_heading_marker = heading;
    t.x_m = x;
    t.y_m = y;
    t.z_m = z;
    t.u_px = t.v_px = t.centroid_u_px = t.centroid_v_px = std::numeric_limits<double>::quiet_NaN();
    m.model.ProjectToPixel(Eigen::Vector3d(x, y, z), &t.u_px, &t.v_px);
    marks.push_back(t);
    discs.push_back({x, y, z, 0.5 * (diameter_m > 0 ? diameter_m : it->second.first),
                     it->second.second, static_cast<int>(marks.size()) - 1});
  };
  // Painter's order: floor objects, then each robot's body, then markers.
  for (const auto& d : m.scenario.distractors) {
    add_marker(d.colour_class, -1, false, d.x_m, d.y_m, 0.0, d.diameter_m);
  }
  for (const auto& r : robots) {
    const auto cam = std::find_if(m.camera_robots.begin(), m.camera_robots.end(),
                                  [&](const CameraRobot& c) { return c.robot_id == r.robot_id; });
    if (cam == m.camera_robots.end()) continue;
    const double z = cam->marker_height_m;
    if (m.options.body_diameter_m > 0) {
      discs.push_back({r.x_m, r.y_m, z - m.options.body_height_m, 0.5 * m.options.body_diameter_m,
                       ToVec(m.options.body_bgr), -1});
    }
    // A site's marker code sizes and spaces the markers by role (0: the
    // class's diameter and the options' offset).
    const MarkerCode& code = m.marker_code;
    add_marker(cam->position_marker, r.robot_id, false, r.x_m, r.y_m, z, code.position_diameter_m);
    const double off = code.enabled() ? code.heading_offset_m : m.options.heading_marker_offset_m;
    add_marker(cam->heading_marker, r.robot_id, true, r.x_m + off * std::cos(r.heading_rad),
               r.y_m + off * std::sin(r.heading_rad), z, code.heading_diameter_m);
  }
  for (const auto& d : discs) {
    m.DrawDisc(d, bgr, d.truth_index >= 0 ? &marks[static_cast<size_t>(d.truth_index)] : nullptr);
  }
  // One pass for lighting and noise.
  const double global = m.GainAt(t_s);
  const bool flicker = m.scenario.flicker_amplitude != 0.0;
  const bool noise = !m.noise_bank.empty();
  if (global == 1.0 && !flicker && m.gradient.empty() && !noise) return;
  const int8_t* nz = nullptr;
  if (noise) {
    const uint64_t key = SplitMix64(m.scenario.seed ^ SplitMix64(static_cast<uint64_t>(frame_seq)));
    nz = m.noise_bank.data() + key % (m.noise_bank.size() - m.frame_values + 1);
  }
  const float noise_scale = static_cast<float>(m.scenario.noise_sigma_dn / kNoiseUnits);
  const int n3 = 3 * m.w;
  // Per-value gain and noise of one row, so that the inner loop is a plain
  // (vectorisable) multiply-add over the row's bytes.
  std::vector<float> gains(static_cast<size_t>(n3));
  std::vector<float> offsets(static_cast<size_t>(n3), 0.5f);  // 0.5: rounding
  for (int j = 0; j < m.h; ++j) {
    float row_gain = static_cast<float>(global);
    if (flicker) {
      row_gain *= static_cast<float>(
          1.0 + m.scenario.flicker_amplitude *
                    std::sin(2 * kPi * m.scenario.flicker_hz * (t_s + j * m.scenario.row_time_s)));
    }
    if (m.gradient.empty()) {
      std::fill(gains.begin(), gains.end(), row_gain);
    } else {
      const float* g = &m.gradient[static_cast<size_t>(j) * m.w];
      for (int i = 0; i < m.w; ++i) {
        gains[3 * i] = gains[3 * i + 1] = gains[3 * i + 2] = row_gain * g[i];
      }
    }
    if (noise) {
      const int8_t* n = nz + static_cast<size_t>(j) * n3;
      for (int k = 0; k < n3; ++k) offsets[k] = 0.5f + n[k] * noise_scale;
    }
    uchar* p = bgr->ptr<uchar>(j);
    const float* gk = gains.data();
    const float* ok = offsets.data();
    for (int k = 0; k < n3; ++k) {
      const float v = std::min(std::max(p[k] * gk[k] + ok[k], 0.0f), 255.0f);
      p[k] = static_cast<uchar>(v);
    }
  }
}

bool WriteSequence(const SyntheticCamera& camera, const SequenceOptions& options,
                   const std::string& out_path, std::string* error) {
  auto fail = [&](const std::string& what) {
    if (error) *error = out_path + ": " + what;
    return false;
  };
  if (!(options.fps > 0) || !(options.duration_s >= 0)) {
    return fail("fps must be positive and duration non-negative");
  }
  namespace fs = std::filesystem;
  const fs::path path(out_path);
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  std::error_code ec;
  const bool folder = fs::is_directory(path, ec) || ext.empty();
  cv::VideoWriter video;
  std::string truth_path;
  if (folder) {
    fs::create_directories(path, ec);
    if (ec || !fs::is_directory(path)) return fail("cannot create folder: " + ec.message());
    truth_path = (path / "truth.csv").string();
  } else {
    int fourcc;
    if (ext == ".avi") {
      fourcc = cv::VideoWriter::fourcc('M', 'J', 'P', 'G');
    } else if (ext == ".mp4") {
      fourcc = cv::VideoWriter::fourcc('m', 'p', '4', 'v');
    } else {
      return fail("unknown extension '" + ext + "': write to a folder, .avi or .mp4");
    }
    if (!video.open(out_path, fourcc, options.fps, cv::Size(camera.width_px(), camera.height_px()),
                    true) ||
        !video.isOpened()) {
      return fail("cannot open the video for writing");
    }
    truth_path = (path.parent_path() / path.stem()).string() + "_truth.csv";
  }
  std::ofstream csv(truth_path);
  if (!csv) return fail("cannot write " + truth_path);
  csv << "frame,t_s,utime,robot_id,colour_class,role,x_m,y_m,z_m,u_px,v_px,centroid_u_px,"
         "centroid_v_px,visible,heading_rad\n";
  csv << std::setprecision(10);
  const int64_t frames = static_cast<int64_t>(std::llround(options.duration_s * options.fps));
  const std::vector<int> jpeg = {cv::IMWRITE_JPEG_QUALITY, options.jpeg_quality};
  cv::Mat image;
  std::vector<MarkerTruth> truth;
  for (int64_t f = 0; f < frames; ++f) {
    const double t = static_cast<double>(f) / options.fps;
    const int64_t utime = options.start_utime + static_cast<int64_t>(std::llround(t * 1e6));
    const std::vector<RobotState> robots = camera.SimulatedRobots(t);
    camera.Render(t, f, robots, &image, &truth);
    if (folder) {
      std::ostringstream name;
      name << "frame_" << std::setw(6) << std::setfill('0') << f << ".jpg";
      const std::string file = (path / name.str()).string();
      // Encoded here, written with every step checked: imwrite does not
      // report every failed write (a full disk).
      std::vector<uint8_t> bytes;
      bool encoded = false;
      try {
        encoded = cv::imencode(".jpg", image, bytes, jpeg);
      } catch (const cv::Exception&) {
        encoded = false;
      }
      if (!encoded) return fail("cannot encode frame " + std::to_string(f));
      std::string write_error;
      if (!WriteOutputFile(file, std::string(bytes.begin(), bytes.end()), &write_error)) {
        return fail(write_error);
      }
    } else {
      video.write(image);
    }
    for (const auto& m : truth) {
      double heading = std::numeric_limits<double>::quiet_NaN();
      for (const auto& r : robots) {
        if (r.robot_id == m.robot_id) heading = r.heading_rad;
      }
      const char* role = m.robot_id < 0        ? "distractor"
                         : m.is_heading_marker ? "heading"
                                               : "position";
      csv << f << ',' << t << ',' << utime << ',' << m.robot_id << ',' << m.colour_class << ','
          << role << ',' << m.x_m << ',' << m.y_m << ',' << m.z_m << ',' << m.u_px << ',' << m.v_px
          << ',' << m.centroid_u_px << ',' << m.centroid_v_px << ',' << (m.visible ? 1 : 0) << ','
          << heading << '\n';
    }
  }
  // close() flushes: a full disk shows here if not before.
  csv.close();
  if (!csv) return fail("cannot write " + truth_path + ": " + std::strerror(errno));
  return true;
}

}  // namespace roomfix::sim
