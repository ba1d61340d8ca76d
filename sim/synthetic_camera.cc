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

#include "camera_io/video_file.h"
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

// One disc composited into an image: each touched pixel becomes
// coverage * colour + (1 - coverage) * what was there, and the coverage's
// moments give the disc's true area (its sum) and centroid (the moments over
// the sum), which is what a perfect detector would measure.
struct DiscCoverage {
  double sum = 0.0, sum_u = 0.0, sum_v = 0.0;

  void Blend(int i, int j, double coverage, const cv::Vec3f& bgr, cv::Vec3b* out) {
    sum += coverage;
    sum_u += coverage * i;
    sum_v += coverage * j;
    for (int c = 0; c < 3; ++c) {
      (*out)[c] = cv::saturate_cast<uchar>(coverage * bgr[c] + (1.0 - coverage) * (*out)[c]);
    }
  }
  // Visible only when the whole rim projects inside the image (`inside`):
  // a disc cut by the edge has no true centroid to score against.
  void FillTruth(bool inside, MarkerTruth* truth) const {
    truth->area_px = sum;
    if (sum > 0) {
      truth->centroid_u_px = sum_u / sum;
      truth->centroid_v_px = sum_v / sum;
    }
    truth->visible = inside && sum > 0;
  }
};

// A uniform draw in [0, 1) from a seed and two keys.
double Uniform(uint64_t seed, uint64_t a, uint64_t b) {
  const uint64_t x = SplitMix64(seed ^ SplitMix64(a ^ SplitMix64(b + 0x51ED2701ull)));
  return static_cast<double>(x >> 11) * (1.0 / 9007199254740992.0);
}

// sRGB transfer (IEC 61966-2-1): linear light in [0, 1] to the encoded value
// in [0, 1], and back.
double SrgbEncode(double x) {
  return x <= 0.0031308 ? 12.92 * x : 1.055 * std::pow(x, 1.0 / 2.4) - 0.055;
}
double SrgbDecode(double c) {
  return c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4);
}

// Steps of the linear-light to 8-bit table: at the sRGB toe (slope 12.92 x
// 255 codes per unit) one step is 0.2 of a code, so a noiseless value goes
// through decode, table and rounding unchanged.
constexpr int kEncodeSteps = 16384;
// Where worn paint fades to (BGR): a dusty grey.
constexpr float kWearGrey = 150.0f;
// Rocking while driving: three sinusoids per axis (Hz, weights summing to 1,
// so the peak is the amplitude) at the robot speed that gives the full
// tilt_rocking_deg; faster robots rock more, up to twice.
constexpr double kRockHz[3] = {0.9, 1.7, 2.9};
constexpr double kRockWeight[3] = {0.6, 0.3, 0.1};
constexpr double kRockReferenceSpeed_mps = 0.2;
constexpr double kRockMaxScale = 2.0;
// Motion blur: time samples per exposure so that consecutive samples are at
// most this far apart in the image (the supersampled coverage smooths the
// rest), at most kMaxTimeSamples.
constexpr double kTimeSampleSpacingPx = 0.25;
constexpr int kMaxTimeSamples = 16;
// SimulatedRobots: central-difference step and acceleration cap.
constexpr double kDifferenceStep_s = 0.005;
constexpr double kMaxAcceleration_mps2 = 3.0;

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

  // The webcam scenario (webcam_effects).
  cv::Mat base_blurred;           // base through the point spread; empty when sharp
  std::vector<float> vignetting;  // w * h relative illumination; empty when none
  std::array<float, 256> decode{};
  std::vector<uint8_t> encode;       // kEncodeSteps + 1 entries over [0, 1]
  std::vector<int8_t> sensor_noise;  // standard normal, units 1/kNoiseUnits
  size_t sensor_values = 0;          // noise values one frame reads
  void BuildWebcam();
  // A disc that may move over the frame: on a robot (a point `forward_m`
  // ahead of its centre at `height_m` on the mast, moved by its motion and
  // tilt) or fixed (a distractor at x, y, z).
  struct MovingDisc {
    bool on_robot = false;
    RobotState robot;
    double forward_m = 0.0, height_m = 0.0;
    double x = 0.0, y = 0.0, z = 0.0;
    double r = 0.0;
    cv::Vec3f bgr;
    int truth_index = -1;
    int supersample = 8;
  };
  // The robot's lean (forward, left; radians) at t_s + tau.
  void Tilt(const RobotState& r, double t_s, double tau, double* forward, double* left) const;
  Eigen::Vector3d CentreAt(const MovingDisc& d, double t_s, double tau) const;
  // Draws a disc whose every row r integrates its coverage over
  // [t_read(r) - exposure, t_read(r)], t_read(r) = t_s + r readout / H;
  // returns the pixels touched (empty when none).
  cv::Rect DrawMovingDisc(const MovingDisc& disc, double t_s, cv::Mat* image,
                          MarkerTruth* truth) const;
  void RenderWebcam(double t_s, int64_t frame_seq, const std::vector<RobotState>& robots,
                    cv::Mat* bgr, std::vector<MarkerTruth>* marks) const;
  // Linear light, gains, shot and read noise, the sRGB curve and the Bayer
  // mosaic with its demosaicing: `scene` (8-bit, as an ideal camera would
  // output) into `bgr`.
  void Sensor(const cv::Mat& scene, double t_s, int64_t frame_seq, cv::Mat* bgr) const;
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

void SyntheticCamera::Impl::BuildWebcam() {
  const WebcamSimulation& wc = scenario.webcam;
  if (wc.psf_sigma_px > 0) {
    cv::GaussianBlur(base, base_blurred, cv::Size(0, 0), wc.psf_sigma_px, wc.psf_sigma_px,
                     cv::BORDER_REFLECT_101);
  }
  if (wc.vignetting_corner_gain < 1.0) {
    // g(rho) = 1 / (1 + T rho^2)^2: cos^4 of the field angle of a
    // rectilinear lens with tan^2 = T rho^2, T chosen so that g = corner gain
    // at rho = 1 (the farthest image corner from the principal point).
    const double cx = model.intrinsics.cx_px, cy = model.intrinsics.cy_px;
    double r_corner = 0.0;
    for (const double u : {-0.5, w - 0.5}) {
      for (const double v : {-0.5, h - 0.5})
        r_corner = std::max(r_corner, std::hypot(u - cx, v - cy));
    }
    const double T = 1.0 / std::sqrt(wc.vignetting_corner_gain) - 1.0;
    vignetting.resize(static_cast<size_t>(w) * h);
    for (int j = 0; j < h; ++j) {
      for (int i = 0; i < w; ++i) {
        const double rho2 = (std::pow(i - cx, 2) + std::pow(j - cy, 2)) / (r_corner * r_corner);
        const double d = 1.0 + T * rho2;
        vignetting[static_cast<size_t>(j) * w + i] = static_cast<float>(1.0 / (d * d));
      }
    }
  }
  encode.resize(kEncodeSteps + 1);
  for (int k = 0; k <= kEncodeSteps; ++k) {
    const double x = static_cast<double>(k) / kEncodeSteps;
    encode[k] = static_cast<uint8_t>(std::lround(255.0 * (wc.srgb_gamma ? SrgbEncode(x) : x)));
  }
  for (int v = 0; v < 256; ++v) {
    decode[v] = static_cast<float>(wc.srgb_gamma ? SrgbDecode(v / 255.0) : v / 255.0);
  }
  sensor_values = static_cast<size_t>(w) * h * (wc.bayer ? 1 : 3);
  if (wc.shot_noise || wc.read_noise_e > 0) {
    cv::Mat bank(1, static_cast<int>(sensor_values + sensor_values / 2), CV_8S);
    cv::RNG rng(SplitMix64(scenario.seed ^ 0xC0FFEEull));
    rng.fill(bank, cv::RNG::NORMAL, 0.0, kNoiseUnits);
    sensor_noise.assign(bank.ptr<int8_t>(0), bank.ptr<int8_t>(0) + bank.cols);
  }
}

void SyntheticCamera::Impl::Tilt(const RobotState& r, double t_s, double tau, double* forward,
                                 double* left) const {
  const WebcamSimulation& wc = scenario.webcam;
  constexpr double kDeg = kPi / 180.0;
  const uint64_t id = static_cast<uint64_t>(r.robot_id);
  // A static lean in a direction fixed per robot and seed.
  const double phi = 2 * kPi * Uniform(scenario.seed, id, 1);
  double f = wc.tilt_static_deg * kDeg * std::cos(phi);
  double l = wc.tilt_static_deg * kDeg * std::sin(phi);
  // Against the acceleration (body frame): speeding up leans back, a left
  // turn's centripetal acceleration leans right.
  const double heading = r.heading_rad + r.yaw_rate_radps * tau;
  const double c = std::cos(heading), s = std::sin(heading);
  const double a_forward = r.ax_mps2 * c + r.ay_mps2 * s;
  const double a_left = -r.ax_mps2 * s + r.ay_mps2 * c;
  f -= wc.tilt_per_acceleration_deg_per_mps2 * kDeg * a_forward;
  l -= wc.tilt_per_acceleration_deg_per_mps2 * kDeg * a_left;
  // Rocking on the floor's unevenness, growing with speed.
  const double speed = std::hypot(r.vx_mps + r.ax_mps2 * tau, r.vy_mps + r.ay_mps2 * tau);
  const double scale = std::min(speed / kRockReferenceSpeed_mps, kRockMaxScale);
  if (scale > 0 && wc.tilt_rocking_deg > 0) {
    const double t = t_s + tau;
    for (int k = 0; k < 3; ++k) {
      const double a = wc.tilt_rocking_deg * kDeg * scale * kRockWeight[k];
      f += a * std::sin(2 * kPi * (kRockHz[k] * t + Uniform(scenario.seed, id, 10 + k)));
      l += a * std::sin(2 * kPi * (kRockHz[k] * t + Uniform(scenario.seed, id, 20 + k)));
    }
  }
  *forward = f;
  *left = l;
}

Eigen::Vector3d SyntheticCamera::Impl::CentreAt(const MovingDisc& d, double t_s, double tau) const {
  if (!d.on_robot) return Eigen::Vector3d(d.x, d.y, d.z);
  const RobotState& r = d.robot;
  double f = 0, l = 0;
  Tilt(r, t_s, tau, &f, &l);
  // The mast point (forward, 0, height) in the body frame (x ahead, y left,
  // z up), leaned by Ry(f) Rx(-l) about the floor point under the centre
  // (f tips z towards +x, l towards +y), then turned by the heading.
  const double y1 = d.height_m * std::sin(l), z1 = d.height_m * std::cos(l);
  const double x2 = d.forward_m * std::cos(f) + z1 * std::sin(f);
  const double z2 = -d.forward_m * std::sin(f) + z1 * std::cos(f);
  const double heading = r.heading_rad + r.yaw_rate_radps * tau;
  const double c = std::cos(heading), s = std::sin(heading);
  const double x = r.x_m + r.vx_mps * tau + 0.5 * r.ax_mps2 * tau * tau;
  const double y = r.y_m + r.vy_mps * tau + 0.5 * r.ay_mps2 * tau * tau;
  return Eigen::Vector3d(x + c * x2 - s * y1, y + s * x2 + c * y1, z2);
}

cv::Rect SyntheticCamera::Impl::DrawMovingDisc(const MovingDisc& disc, double t_s, cv::Mat* image,
                                               MarkerTruth* truth) const {
  const double exposure = scenario.webcam.exposure_s, readout = scenario.webcam.readout_s;
  const double row_s = readout / h;
  // Bound the disc over the frame's whole window (row 0's exposure start to
  // the last row's read) by its rim at both ends and in the middle.
  double u_min = 1e300, u_max = -1e300, v_min = 1e300, v_max = -1e300;
  bool inside = true;
  for (const double tau : {-exposure, 0.5 * (readout - exposure), readout}) {
    const Eigen::Vector3d c = CentreAt(disc, t_s, tau);
    for (int k = 0; k < kRimPoints; ++k) {
      const double phi = 2 * kPi * k / kRimPoints;
      double u, v;
      if (!model.ProjectToPixel(Eigen::Vector3d(c.x() + disc.r * std::cos(phi),
                                                c.y() + disc.r * std::sin(phi), c.z()),
                                &u, &v)) {
        if (truth) truth->visible = false;
        return cv::Rect();
      }
      u_min = std::min(u_min, u), u_max = std::max(u_max, u);
      v_min = std::min(v_min, v), v_max = std::max(v_max, v);
      if (u < -0.5 || u > w - 0.5 || v < -0.5 || v > h - 0.5) inside = false;
    }
  }
  const int i0 = std::max(0, static_cast<int>(std::floor(u_min)) - 2);
  const int i1 = std::min(w - 1, static_cast<int>(std::ceil(u_max)) + 2);
  const int j0 = std::max(0, static_cast<int>(std::floor(v_min)) - 2);
  const int j1 = std::min(h - 1, static_cast<int>(std::ceil(v_max)) + 2);
  if (i0 > i1 || j0 > j1) {
    if (truth) truth->visible = false;
    return cv::Rect();
  }
  // Time samples: enough that the disc moves at most kTimeSampleSpacingPx
  // between two; fewer subsamples per pixel side when there are more.
  int samples = 1;
  if (exposure > 0) {
    double u0, v0, u1, v1;
    if (model.ProjectToPixel(CentreAt(disc, t_s, -exposure), &u0, &v0) &&
        model.ProjectToPixel(CentreAt(disc, t_s, 0.0), &u1, &v1)) {
      const double streak = std::hypot(u1 - u0, v1 - v0);
      samples = std::clamp(static_cast<int>(std::ceil(streak / kTimeSampleSpacingPx)), 1,
                           kMaxTimeSamples);
    }
  }
  const int s = std::max(
      3, static_cast<int>(std::lround(disc.supersample / std::sqrt(static_cast<double>(samples)))));
  const double r2 = disc.r * disc.r;
  std::vector<Eigen::Vector3d> centres(static_cast<size_t>(samples));
  DiscCoverage cover;
  for (int j = j0; j <= j1; ++j) {
    const double t_read = j * row_s;
    for (int k = 0; k < samples; ++k) {
      const double tau = exposure > 0 ? t_read - exposure + (k + 0.5) * exposure / samples : t_read;
      centres[static_cast<size_t>(k)] = CentreAt(disc, t_s, tau);
    }
    cv::Vec3b* row = image->ptr<cv::Vec3b>(j);
    for (int i = i0; i <= i1; ++i) {
      const float* p = &ab[Index(i, j)];
      if (!std::isfinite(p[0])) continue;
      const double foot = FootprintAb(i, j);
      int full = 0;
      int hits = 0;
      for (const Eigen::Vector3d& c : centres) {
        const double depth = c.z() - pz;
        const double dist = std::hypot(px + depth * p[0] - c.x(), py + depth * p[1] - c.y());
        const double rho = std::abs(depth) * foot;
        if (std::isfinite(rho) && dist + rho <= disc.r) {
          ++full;
        } else if (std::isfinite(rho) && dist - rho >= disc.r) {
          continue;
        } else {
          for (int sj = 0; sj < s; ++sj) {
            for (int si = 0; si < s; ++si) {
              double a, b;
              if (!Sample(i - 0.5 + (si + 0.5) / s, j - 0.5 + (sj + 0.5) / s, &a, &b)) continue;
              const double ex = px + depth * a - c.x(), ey = py + depth * b - c.y();
              if (ex * ex + ey * ey <= r2) ++hits;
            }
          }
        }
      }
      if (full == 0 && hits == 0) continue;
      const double coverage = (full + static_cast<double>(hits) / (s * s)) / samples;
      cover.Blend(i, j, coverage, disc.bgr, &row[i]);
    }
  }
  if (truth) {
    cover.FillTruth(inside, truth);
    const double row = std::isfinite(truth->centroid_v_px) ? truth->centroid_v_px : truth->v_px;
    const double tau = (std::isfinite(row) ? row * row_s : 0.0) - 0.5 * exposure;
    truth->exposure_mid_t_s = t_s + tau;
    const Eigen::Vector3d c = CentreAt(disc, t_s, tau);
    truth->exposure_mid_x_m = c.x();
    truth->exposure_mid_y_m = c.y();
    truth->exposure_mid_z_m = c.z();
    if (disc.on_robot) {
      const RobotState& r = disc.robot;
      truth->robot_x_m = r.x_m + r.vx_mps * tau + 0.5 * r.ax_mps2 * tau * tau;
      truth->robot_y_m = r.y_m + r.vy_mps * tau + 0.5 * r.ay_mps2 * tau * tau;
      truth->robot_heading_rad = r.heading_rad + r.yaw_rate_radps * tau;
      Tilt(r, t_s, tau, &truth->robot_tilt_forward_rad, &truth->robot_tilt_left_rad);
    }
  }
  return cv::Rect(i0, j0, i1 - i0 + 1, j1 - j0 + 1);
}

void SyntheticCamera::Impl::Sensor(const cv::Mat& scene, double t_s, int64_t frame_seq,
                                   cv::Mat* bgr) const {
  const WebcamSimulation& wc = scenario.webcam;
  // Slow drifts, at the middle of the frame's readout.
  const double t = t_s + 0.5 * wc.readout_s;
  const uint64_t seed = scenario.seed;
  const double ae =
      1.0 + wc.auto_exposure_drift *
                std::sin(2 * kPi * (t / wc.auto_exposure_period_s + Uniform(seed, 0xAE, 0)));
  const double wb_r =
      1.0 + wc.white_balance_drift *
                std::sin(2 * kPi * (t / wc.white_balance_period_s + Uniform(seed, 0xBA, 1)));
  const double wb_b =
      1.0 + wc.white_balance_drift *
                std::sin(2 * kPi * (t / wc.white_balance_period_s + Uniform(seed, 0xBA, 2)));
  const double global = GainAt(t_s) * ae;
  const float full_well = static_cast<float>(wc.full_well_e);
  // BGR gains, times the full well: linear light to electrons.
  const float gain[3] = {static_cast<float>(global * wb_b) * full_well,
                         static_cast<float>(global) * full_well,
                         static_cast<float>(global * wb_r) * full_well};
  const float to_index = static_cast<float>(kEncodeSteps) / full_well;
  const float read_var = static_cast<float>(wc.read_noise_e * wc.read_noise_e);
  const float shot = wc.shot_noise ? 1.0f : 0.0f;
  const int8_t* nz = nullptr;
  if (!sensor_noise.empty()) {
    const uint64_t key = SplitMix64(seed ^ SplitMix64(static_cast<uint64_t>(frame_seq) + 77));
    nz = sensor_noise.data() + key % (sensor_noise.size() - sensor_values + 1);
  }
  const float noise_scale = 1.0f / static_cast<float>(kNoiseUnits);
  const float* vig = vignetting.empty() ? nullptr : vignetting.data();
  // One value: 8-bit scene value -> electrons -> noise -> 8-bit output.
  auto expose = [&](uint8_t value, int c, size_t pixel, size_t noise_index) -> uint8_t {
    float e = decode[value] * gain[c];
    if (vig != nullptr) e *= vig[pixel];
    if (nz != nullptr) {
      e += std::sqrt(shot * std::max(e, 0.0f) + read_var) * (nz[noise_index] * noise_scale);
    }
    const float index =
        std::min(std::max(e * to_index + 0.5f, 0.0f), static_cast<float>(kEncodeSteps));
    return encode[static_cast<size_t>(index)];
  };
  if (wc.bayer) {
    // RGGB: R at even rows and columns, B at odd rows and columns. Row by
    // row in passes the compiler and OpenCV vectorise (the square root by
    // cv::sqrt); only the two table look-ups are gathers.
    cv::Mat mosaic(h, w, CV_8UC1);
    cv::Mat e_row(1, w, CV_32F), sd_row(1, w, CV_32F);
    float* e = e_row.ptr<float>(0);
    float* sd = sd_row.ptr<float>(0);
    const float top = static_cast<float>(kEncodeSteps);
    for (int j = 0; j < h; ++j) {
      const uchar* in = scene.ptr<uchar>(j);
      uchar* out = mosaic.ptr<uchar>(j);
      const size_t row = static_cast<size_t>(j) * w;
      const int even = (j & 1) == 0 ? 2 : 1;  // channel at even columns
      const int odd = (j & 1) == 0 ? 1 : 0;   // at odd columns
      for (int i = 0; i < w; i += 2) {
        e[i] = decode[in[3 * i + even]] * gain[even];
        if (i + 1 < w) e[i + 1] = decode[in[3 * i + 3 + odd]] * gain[odd];
      }
      if (vig != nullptr) {
        const float* v = vig + row;
        for (int i = 0; i < w; ++i) e[i] *= v[i];
      }
      if (nz != nullptr) {
        for (int i = 0; i < w; ++i) sd[i] = shot * std::max(e[i], 0.0f) + read_var;
        cv::sqrt(sd_row, sd_row);
        const int8_t* n = nz + row;
        for (int i = 0; i < w; ++i) e[i] += sd[i] * (static_cast<float>(n[i]) * noise_scale);
      }
      for (int i = 0; i < w; ++i) {
        const float index = std::min(std::max(e[i] * to_index + 0.5f, 0.0f), top);
        out[i] = encode[static_cast<size_t>(index)];
      }
    }
    cv::cvtColor(mosaic, *bgr, cv::COLOR_BayerBG2BGR);
  } else {
    bgr->create(h, w, CV_8UC3);
    for (int j = 0; j < h; ++j) {
      const uchar* in = scene.ptr<uchar>(j);
      uchar* out = bgr->ptr<uchar>(j);
      const size_t row = static_cast<size_t>(j) * w;
      for (int i = 0; i < w; ++i) {
        for (int c = 0; c < 3; ++c) {
          out[3 * i + c] = expose(in[3 * i + c], c, row + i, 3 * (row + i) + c);
        }
      }
    }
  }
}

void SyntheticCamera::Impl::RenderWebcam(double t_s, int64_t frame_seq,
                                         const std::vector<RobotState>& robots, cv::Mat* bgr,
                                         std::vector<MarkerTruth>* marks) const {
  const WebcamSimulation& wc = scenario.webcam;
  std::vector<MovingDisc> discs;
  // Paint: worn towards grey by a fraction fixed per marker, whitened by a
  // sheen growing with the viewing angle (full at 60 degrees off vertical).
  auto paint = [&](cv::Vec3f colour, uint64_t key, const Eigen::Vector3d& at) {
    const float wear = static_cast<float>(wc.marker_wear * Uniform(scenario.seed, key, 3));
    colour = (1.0f - wear) * colour + wear * cv::Vec3f(kWearGrey, kWearGrey, kWearGrey);
    const Eigen::Vector3d to_camera = Eigen::Vector3d(px, py, pz) - at;
    const double cos_view = to_camera.z() / to_camera.norm();
    const float sheen = static_cast<float>(wc.marker_sheen * std::min(1.0, (1.0 - cos_view) / 0.5));
    return (1.0f - sheen) * colour + sheen * cv::Vec3f(255, 255, 255);
  };
  auto add_truth = [&](const std::string& cls, int robot_id, bool heading,
                       const Eigen::Vector3d& at) {
    MarkerTruth t;
    t.robot_id = robot_id;
    t.colour_class = cls;
    t.is_heading_marker = heading;
    t.x_m = at.x();
    t.y_m = at.y();
    t.z_m = at.z();
    const double nan = std::numeric_limits<double>::quiet_NaN();
    t.u_px = t.v_px = t.centroid_u_px = t.centroid_v_px = nan;
    t.robot_x_m = t.robot_y_m = t.robot_heading_rad = nan;
    t.robot_tilt_forward_rad = t.robot_tilt_left_rad = nan;
    model.ProjectToPixel(at, &t.u_px, &t.v_px);
    marks->push_back(t);
    return static_cast<int>(marks->size()) - 1;
  };
  uint64_t key = 0;
  for (const auto& d : scenario.distractors) {
    const auto it = classes.find(d.colour_class);
    ++key;
    if (it == classes.end()) continue;
    MovingDisc m;
    m.x = d.x_m;
    m.y = d.y_m;
    m.r = 0.5 * d.diameter_m;
    const Eigen::Vector3d at(m.x, m.y, 0.0);
    m.bgr = paint(it->second.second, 1000 + key, at);
    m.truth_index = add_truth(d.colour_class, -1, false, at);
    discs.push_back(m);
  }
  for (const auto& r : robots) {
    const auto cam = std::find_if(camera_robots.begin(), camera_robots.end(),
                                  [&](const CameraRobot& c) { return c.robot_id == r.robot_id; });
    if (cam == camera_robots.end()) continue;
    MovingDisc base_disc;
    base_disc.on_robot = true;
    base_disc.robot = r;
    if (options.body_diameter_m > 0) {
      MovingDisc body = base_disc;
      body.height_m = cam->marker_height_m - options.body_height_m;
      body.r = 0.5 * options.body_diameter_m;
      body.bgr = ToVec(options.body_bgr);
      discs.push_back(body);
    }
    for (const bool heading : {false, true}) {
      const std::string& cls = heading ? cam->heading_marker : cam->position_marker;
      const auto it = classes.find(cls);
      if (it == classes.end()) continue;
      MovingDisc m = base_disc;
      m.height_m = cam->marker_height_m;
      // A site's marker code sizes and spaces the markers by role.
      const double offset_m =
          marker_code.enabled() ? marker_code.heading_offset_m : options.heading_marker_offset_m;
      const double code_diameter_m =
          heading ? marker_code.heading_diameter_m : marker_code.position_diameter_m;
      m.forward_m = heading ? offset_m : 0.0;
      m.r = 0.5 * (marker_code.enabled() ? code_diameter_m : it->second.first);
      const Eigen::Vector3d at = CentreAt(m, t_s, 0.0);
      m.bgr =
          paint(it->second.second, 2 * static_cast<uint64_t>(r.robot_id) + (heading ? 1 : 0), at);
      m.truth_index = add_truth(cls, r.robot_id, heading, at);
      discs.push_back(m);
    }
  }
  cv::Mat work = base.clone();
  std::vector<cv::Rect> touched;
  for (const auto& d : discs) {
    const cv::Rect rect = DrawMovingDisc(
        d, t_s, &work,
        d.truth_index >= 0 ? &(*marks)[static_cast<size_t>(d.truth_index)] : nullptr);
    if (!rect.empty()) touched.push_back(rect);
  }
  cv::Mat scene;
  if (base_blurred.empty()) {
    scene = work;
  } else {
    // Blurring is linear and local: the static floor was blurred once; only
    // the discs' surroundings (plus the kernel's reach) are blurred again,
    // reading the sharp frame around them (OpenCV's filters read outside an
    // ROI from its parent, so the seams match the pre-blurred floor).
    scene = base_blurred.clone();
    const int reach = static_cast<int>(std::ceil(4 * wc.psf_sigma_px)) + 1;
    const cv::Rect all(0, 0, w, h);
    for (const cv::Rect& r : touched) {
      const cv::Rect roi =
          cv::Rect(r.x - reach, r.y - reach, r.width + 2 * reach, r.height + 2 * reach) & all;
      cv::Mat blurred;
      cv::GaussianBlur(work(roi), blurred, cv::Size(0, 0), wc.psf_sigma_px, wc.psf_sigma_px,
                       cv::BORDER_REFLECT_101);
      blurred.copyTo(scene(roi));
    }
  }
  Sensor(scene, t_s, frame_seq, bgr);
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
  DiscCoverage cover;
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
      cover.Blend(i, j, coverage, disc.bgr, &row[i]);
    }
  }
  if (truth) {
    cover.FillTruth(inside, truth);
  }
}

bool ParseSimScenario(const std::string& text, SimScenario* scenario, std::string* error) {
  std::string name = text;
  if (name.rfind("sim:", 0) == 0) name = name.substr(4);
  SimScenario s;
  s.name = name;
  const bool lighting = name == "lighting" || name == "harsh";
  const bool distractors = name == "distractors" || name == "harsh";
  const bool webcam = name == "webcam";
  if (!(name == "clean" || name == "reference_circle" || lighting || distractors || webcam)) {
    if (error) {
      *error = "unknown simulation scenario '" + text +
               "': known scenarios are clean, reference_circle, lighting, distractors, harsh, "
               "webcam (optionally prefixed sim:)";
    }
    return false;
  }
  s.webcam_effects = webcam;
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

bool ParseSimScenario(const std::string& text, const Site& site, SimScenario* scenario,
                      std::string* error) {
  if (!ParseSimScenario(text, scenario, error)) return false;
  if (scenario->webcam_effects) scenario->webcam = site.simulation.webcam;
  return true;
}

WebcamSimulation WithoutWebcamEffects(WebcamSimulation w) {
  w.psf_sigma_px = 0.0;
  w.vignetting_corner_gain = 1.0;
  w.lens_k = {0.0, 0.0, 0.0, 0.0};
  w.lens_principal_offset_px = {0.0, 0.0};
  w.exposure_s = 0.0;
  w.readout_s = 0.0;
  w.auto_exposure_drift = 0.0;
  w.white_balance_drift = 0.0;
  w.shot_noise = false;
  w.read_noise_e = 0.0;
  w.bayer = false;
  w.tilt_static_deg = 0.0;
  w.tilt_per_acceleration_deg_per_mps2 = 0.0;
  w.tilt_rocking_deg = 0.0;
  w.marker_wear = 0.0;
  w.marker_sheen = 0.0;
  w.timestamp_latency_s = 0.0;
  w.timestamp_jitter_s = 0.0;
  return w;
}

calib::CameraModel TruthLens(const calib::CameraModel& model, const SimScenario& scenario) {
  calib::CameraModel truth = model;
  if (scenario.webcam_effects) {
    for (size_t k = 0; k < 4; ++k) truth.intrinsics.k[k] += scenario.webcam.lens_k[k];
    truth.intrinsics.cx_px += scenario.webcam.lens_principal_offset_px[0];
    truth.intrinsics.cy_px += scenario.webcam.lens_principal_offset_px[1];
  }
  return truth;
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
  impl->model = TruthLens(model, impl->scenario);
  model_ = impl->model;
  impl->w = camera.width_px > 0 ? camera.width_px : model.intrinsics.width_px;
  impl->h = camera.height_px > 0 ? camera.height_px : model.intrinsics.height_px;
  impl->px = model.pose.position_m.x();
  impl->py = model.pose.position_m.y();
  impl->pz = model.pose.position_m.z();
  impl->BuildRayMap();
  impl->RenderFloor();
  impl->BuildLighting();
  if (impl->scenario.webcam_effects) impl->BuildWebcam();
  impl_ = std::move(impl);
}

int SyntheticCamera::width_px() const { return impl_->w; }
int SyntheticCamera::height_px() const { return impl_->h; }
const SimScenario& SyntheticCamera::scenario() const { return impl_->scenario; }

double SyntheticCamera::TimestampDelayS(int64_t frame_seq) const {
  const SimScenario& s = impl_->scenario;
  if (!s.webcam_effects) return 0.0;
  const WebcamSimulation& wc = s.webcam;
  const double u = Uniform(s.seed, static_cast<uint64_t>(frame_seq), 0x7135);
  return wc.readout_s * (impl_->h - 1) / impl_->h + wc.timestamp_latency_s +
         wc.timestamp_jitter_s * (2.0 * u - 1.0);
}

int SyntheticCamera::JpegQuality(int quality) const {
  return impl_->scenario.webcam_effects ? impl_->scenario.webcam.jpeg_quality : quality;
}

bool SyntheticCamera::Encode(const cv::Mat& bgr, int quality, std::vector<uint8_t>* bytes) const {
  bytes->clear();
  const int q = JpegQuality(quality);
  if (q <= 0) return true;
  try {
    return cv::imencode(".jpg", bgr, *bytes, {cv::IMWRITE_JPEG_QUALITY, q});
  } catch (const cv::Exception&) {
    return false;
  }
}

std::vector<RobotState> SyntheticCamera::SimulatedRobots(double t_s) const {
  std::vector<RobotState> out;
  for (const auto& r : impl_->sim_robots) {
    if (!r.trajectory) continue;
    const bool known = std::any_of(impl_->camera_robots.begin(), impl_->camera_robots.end(),
                                   [&](const CameraRobot& c) { return c.robot_id == r.robot_id; });
    if (!known) continue;
    const GroundTruthPose pose = r.trajectory->PoseAt(t_s);
    const GroundTruthPose before = r.trajectory->PoseAt(t_s - kDifferenceStep_s);
    const GroundTruthPose after = r.trajectory->PoseAt(t_s + kDifferenceStep_s);
    RobotState state{r.robot_id, pose.x_m, pose.y_m, pose.heading_rad};
    const double h = kDifferenceStep_s;
    state.vx_mps = (after.x_m - before.x_m) / (2 * h);
    state.vy_mps = (after.y_m - before.y_m) / (2 * h);
    state.ax_mps2 = (after.x_m - 2 * pose.x_m + before.x_m) / (h * h);
    state.ay_mps2 = (after.y_m - 2 * pose.y_m + before.y_m) / (h * h);
    const double a = std::hypot(state.ax_mps2, state.ay_mps2);
    if (a > kMaxAcceleration_mps2) {
      state.ax_mps2 *= kMaxAcceleration_mps2 / a;
      state.ay_mps2 *= kMaxAcceleration_mps2 / a;
    }
    state.yaw_rate_radps =
        std::remainder(after.heading_rad - before.heading_rad, 2 * kPi) / (2 * h);
    out.push_back(state);
  }
  return out;
}

void SyntheticCamera::Render(double t_s, int64_t frame_seq, const std::vector<RobotState>& robots,
                             cv::Mat* bgr, std::vector<MarkerTruth>* truth) const {
  const Impl& m = *impl_;
  std::vector<MarkerTruth> local_truth;
  std::vector<MarkerTruth>& marks = truth ? *truth : local_truth;
  marks.clear();
  if (m.scenario.webcam_effects) {
    m.RenderWebcam(t_s, frame_seq, robots, bgr, &marks);
    return;
  }
  impl_->base.copyTo(*bgr);
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
    // Every row at once, no exposure: the instant rendered.
    t.exposure_mid_t_s = t_s;
    t.exposure_mid_x_m = x;
    t.exposure_mid_y_m = y;
    t.exposure_mid_z_m = z;
    t.robot_x_m = t.robot_y_m = t.robot_heading_rad = std::numeric_limits<double>::quiet_NaN();
    t.robot_tilt_forward_rad = t.robot_tilt_left_rad = std::numeric_limits<double>::quiet_NaN();
    for (const auto& r : robots) {
      if (r.robot_id != robot_id) continue;
      t.robot_x_m = r.x_m;
      t.robot_y_m = r.y_m;
      t.robot_heading_rad = r.heading_rad;
      t.robot_tilt_forward_rad = t.robot_tilt_left_rad = 0.0;
    }
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
  // Whole or absent: checked and renamed into place at the end.
  camera::CheckedVideoWriter video;
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
    std::string open_error;
    if (!video.Open(out_path, fourcc, options.fps, cv::Size(camera.width_px(), camera.height_px()),
                    &open_error)) {
      if (error) *error = open_error;
      return false;
    }
    truth_path = (path.parent_path() / path.stem()).string() + "_truth.csv";
  }
  // Collected, and written with every step checked at the end: a truth file
  // that stops short would look like a shorter run.
  std::ostringstream csv;
  csv << "frame,t_s,utime,robot_id,colour_class,role,x_m,y_m,z_m,u_px,v_px,centroid_u_px,"
         "centroid_v_px,visible,heading_rad,capture_utime,exposure_mid_t_s,exposure_mid_x_m,"
         "exposure_mid_y_m,exposure_mid_z_m,robot_x_m,robot_y_m,robot_heading_rad,"
         "robot_tilt_forward_rad,robot_tilt_left_rad\n";
  csv << std::setprecision(10);
  const int64_t frames = static_cast<int64_t>(std::llround(options.duration_s * options.fps));
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
      // A webcam scenario handing raw frames over (quality 0) still gets
      // JPEG files, at the best quality.
      if (!camera.Encode(image, options.jpeg_quality, &bytes) ||
          (bytes.empty() && !cv::imencode(".jpg", image, bytes, {cv::IMWRITE_JPEG_QUALITY, 100}))) {
        return fail("cannot encode frame " + std::to_string(f));
      }
      std::string write_error;
      if (!WriteOutputFile(file, std::string(bytes.begin(), bytes.end()), &write_error)) {
        return fail(write_error);
      }
    } else {
      video.Write(image);
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
          << heading << ',' << utime + std::llround(camera.TimestampDelayS(f) * 1e6) << ','
          << m.exposure_mid_t_s << ',' << m.exposure_mid_x_m << ',' << m.exposure_mid_y_m << ','
          << m.exposure_mid_z_m << ',' << m.robot_x_m << ',' << m.robot_y_m << ','
          << m.robot_heading_rad << ',' << m.robot_tilt_forward_rad << ',' << m.robot_tilt_left_rad
          << '\n';
    }
  }
  std::string write_error;
  if (!folder && !video.Close(&write_error)) {
    if (error) *error = write_error;
    return false;
  }
  if (!WriteOutputFile(truth_path, csv.str(), &write_error)) {
    return fail("cannot write " + truth_path + ": " +
                write_error.substr(write_error.rfind(": ") + 2));
  }
  return true;
}

}  // namespace roomfix::sim
