#include "viewer/render.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <opencv2/imgcodecs.hpp>
#include <random>
#include <string>
#include <vector>

#include "core/world/site.h"
#include "tests/testing/demo_site.h"
#include "tests/testing/test_paths.h"

namespace roomfix::viewer {
namespace {

constexpr int64_t kNowUtime = 1'714'564'800'000'000;  // 2024-05-01 12:00:00 UTC
constexpr double kInf = std::numeric_limits<double>::infinity();

// Discs and receivers are filled shapes: the pixels inside them are the
// colour itself, exactly.
constexpr int kExact = 0;
// Anti-aliased lines blend their colour with what is under them. A pixel
// shows a line when it is that blend: the reference picture (the same state
// without the line) moved towards the colour by a coverage t, give or take
// OpenCV's 8-bit rounding.
constexpr int kBlendResidual = 6;
// A 1 px anti-aliased line puts its ink into at most two pixels across it,
// so the nearer one has at least half; allowing for rounding, 0.45.
constexpr double kMinLineCoverage = 0.45;
// A pixel a few levels off its reference (an anti-aliased fringe of another
// colour) is a faint blend towards any colour: below this, no line there.
constexpr double kNoLine = 0.1;
// How far from the ideal curve a line's nearest pixel may be: rounding of
// the chord ends to whole pixels, the chords' sagitta (<= 0.25 px) and the
// line's half width.
constexpr double kLineSearchPx = 2.0;
// Trails and discs, compared by colour: 24 levels for the blending of a 2 px
// anti-aliased line's core pixel (the trail test).
constexpr int kLineCoreTolerance = 24;
// The floor mapping is an affine map computed in doubles; its pixels (up to
// ~1e3 px) and metres (up to ~1e3 m in the round trip) match the closed form
// to round-off, ~1e-13, so these fail only on a wrong formula, not on noise.
constexpr double kAffineRoundOffPx = 1e-9;
constexpr double kRoundTripM = 1e-9;
constexpr double kScaleRoundOffPxPerM = 1e-9;
// Panning shifts the mapping's origin and leaves its scale (~196 px/m)
// computed by the same operations: equal to within a few ulps.
constexpr double kPanKeepsScalePxPerM = 1e-12;

Site DemoSite() {
  Site site;
  std::string error;
  const bool ok = LoadSite(testing::DemoSitePath(), &site, &error);
  EXPECT_TRUE(ok) << error;
  return site;
}

ViewState DemoState() {
  ViewState state;
  state.site = DemoSite();
  state.now_utime = kNowUtime;
  return state;
}

int Distance(const cv::Vec3b& pixel, const cv::Scalar& colour) {
  int d = 0;
  for (int i = 0; i < 3; ++i) d = std::max(d, std::abs(pixel[i] - static_cast<int>(colour[i])));
  return d;
}

cv::Vec3b At(const cv::Mat& image, cv::Point2d px) {
  return image.at<cv::Vec3b>(cvRound(px.y), cvRound(px.x));
}

// The share of `colour` that `pixel` shows over `reference` (see
// kBlendResidual); 0 when it is not such a blend.
double Coverage(const cv::Vec3b& pixel, const cv::Vec3b& reference, const cv::Scalar& colour) {
  double dot = 0;
  double norm = 0;
  for (int i = 0; i < 3; ++i) {
    dot += (pixel[i] - reference[i]) * (colour[i] - reference[i]);
    norm += (colour[i] - reference[i]) * (colour[i] - reference[i]);
  }
  if (norm < 1) return 0;
  const double t = std::clamp(dot / norm, 0.0, 1.0);
  for (int i = 0; i < 3; ++i) {
    if (std::abs(pixel[i] - (reference[i] + t * (colour[i] - reference[i]))) > kBlendResidual) {
      return 0;
    }
  }
  return t;
}

// The most of `colour` shown by a pixel within kLineSearchPx of `px` (a
// square), over the reference picture.
double LineNear(const cv::Mat& image, const cv::Mat& reference, cv::Point2d px,
                const cv::Scalar& colour) {
  const int r = static_cast<int>(std::ceil(kLineSearchPx));
  double best = 0;
  for (int dv = -r; dv <= r; ++dv) {
    for (int du = -r; du <= r; ++du) {
      const int u = cvRound(px.x) + du;
      const int v = cvRound(px.y) + dv;
      if (u < 0 || v < 0 || u >= image.cols || v >= image.rows) continue;
      best = std::max(best,
                      Coverage(image.at<cv::Vec3b>(v, u), reference.at<cv::Vec3b>(v, u), colour));
    }
  }
  return best;
}

// As LineNear, on the radial line at `angle_rad` (room frame) through the
// circle about `centre_px` of `radius_px`: radial only, so that a dash's end
// is not found from the middle of a gap.
double OnCircle(const cv::Mat& image, const cv::Mat& reference, cv::Point2d centre_px,
                double radius_px, double angle_rad, const cv::Scalar& colour) {
  const cv::Point2d dir(std::cos(angle_rad), -std::sin(angle_rad));
  double best = 0;
  for (double d = -kLineSearchPx; d <= kLineSearchPx; d += 0.5) {
    const cv::Point2d p = centre_px + dir * (radius_px + d);
    const int u = cvRound(p.x);
    const int v = cvRound(p.y);
    if (u < 0 || v < 0 || u >= image.cols || v >= image.rows) continue;
    best =
        std::max(best, Coverage(image.at<cv::Vec3b>(v, u), reference.at<cv::Vec3b>(v, u), colour));
  }
  return best;
}

TrackView Track(PoseSource source, int robot_id, double x_m, double y_m) {
  TrackView t;
  t.source = source;
  t.robot_id = robot_id;
  t.x_m = x_m;
  t.y_m = y_m;
  t.utime = kNowUtime - 20'000;
  t.recv_utime = kNowUtime - 10'000;
  t.rate_hz = 30;
  t.latency_ms = 12;
  return t;
}

RangeSetView OneRange(const Site& site, int receiver_id, double range_m, bool rejected) {
  RangeSetView set;
  set.beacon_id = 1;
  set.beacon_height_m = site.beacons.at(0).height_m;
  set.utime = kNowUtime - 50'000;
  set.recv_utime = kNowUtime - 40'000;
  RangeView r;
  r.receiver_id = receiver_id;
  r.receiver_m = site.FindReceiver(receiver_id)->position_m;
  r.range_m = range_m;
  r.rejected = rejected;
  set.ranges.push_back(r);
  return set;
}

TEST(SourceName, NamesEverySource) {
  EXPECT_STREQ(SourceName(PoseSource::kCamera), "camera");
  EXPECT_STREQ(SourceName(PoseSource::kUltrasound), "ultrasound");
  EXPECT_STREQ(SourceName(PoseSource::kFused), "fused");
  EXPECT_STREQ(SourceName(PoseSource::kGroundTruth), "ground truth");
  EXPECT_STREQ(SourceName(PoseSource::kUnknown), "unknown");
  EXPECT_STREQ(SourceName(static_cast<PoseSource>(17)), "unknown");
}

TEST(SourceColour, TellsSourcesWarningsReceiversAndStaleApart) {
  std::vector<cv::Scalar> colours = {WarningColour(), ReceiverColour(), StaleColour(),
                                     FloorColour()};
  for (PoseSource s : kSources) colours.push_back(SourceColour(s));
  for (size_t i = 0; i < colours.size(); ++i) {
    for (size_t j = i + 1; j < colours.size(); ++j) {
      // 60 levels in some channel: apart at a glance, and far beyond the
      // line tolerance, so no pixel test can mistake one for another.
      EXPECT_GE(Distance(cv::Vec3b(static_cast<uint8_t>(colours[i][0]),
                                   static_cast<uint8_t>(colours[i][1]),
                                   static_cast<uint8_t>(colours[i][2])),
                         colours[j]),
                60)
          << i << " vs " << j;
    }
  }
}

TEST(RenderOptions, AcceptsTheDefaultsAndRejectsNonsense) {
  std::string error;
  EXPECT_TRUE(RenderOptions{}.IsValid(&error)) << error;
  auto rejects = [](RenderOptions o) {
    std::string e;
    const bool valid = o.IsValid(&e);
    return !valid && !e.empty();
  };
  RenderOptions o;
  o.width_px = 0;
  EXPECT_TRUE(rejects(o));
  o = {};
  o.height_px = 100000;
  EXPECT_TRUE(rejects(o));
  o = {};
  o.panel_px = -1;
  EXPECT_TRUE(rejects(o));
  o = {};
  o.panel_px = o.width_px;  // no floor left
  EXPECT_TRUE(rejects(o));
  o = {};
  o.zoom = 0;
  EXPECT_TRUE(rejects(o));
  o = {};
  o.zoom = std::nan("");
  EXPECT_TRUE(rejects(o));
  o = {};
  o.pan_y_m = kInf;
  EXPECT_TRUE(rejects(o));
  o = {};
  o.panel_px = 0;
  EXPECT_TRUE(o.IsValid(&error)) << error;
}

TEST(FloorMapping, RoundTripsBetweenMetresAndPixels) {
  const FloorMapping m = MakeFloorMapping(DemoSite(), RenderOptions{});
  for (const auto& [x, y] :
       std::vector<std::pair<double, double>>{{0, 0}, {4, 3}, {-1.5, 7.25}, {1e3, -1e3}}) {
    double bx = 0;
    double by = 0;
    m.ToFloor(m.ToPixel(x, y), &bx, &by);
    EXPECT_NEAR(bx, x, kRoundTripM);
    EXPECT_NEAR(by, y, kRoundTripM);
  }
}

TEST(FloorMapping, FitsTheRoomAndItsMarginCentredKeepingAspectWithYUp) {
  const Site site = DemoSite();  // 4 x 3 m from the origin
  RenderOptions o;               // 1280 x 800, panel 380: floor 900 x 800
  const FloorMapping m = MakeFloorMapping(site, o);
  // (4 + 0.6) m across 900 px limits: 900 / 4.6; (3 + 0.6) m would allow 800 / 3.6.
  EXPECT_NEAR(m.scale_px_per_m, 900.0 / 4.6, kScaleRoundOffPxPerM);
  const cv::Point2d centre = m.ToPixel(2.0, 1.5);
  EXPECT_NEAR(centre.x, 450.0, kAffineRoundOffPx);
  EXPECT_NEAR(centre.y, 400.0, kAffineRoundOffPx);
  // The margin exactly reaches the floor's left and right edges.
  EXPECT_NEAR(m.ToPixel(-0.3, 0).x, 0.0, kAffineRoundOffPx);
  EXPECT_NEAR(m.ToPixel(4.3, 0).x, 900.0, kAffineRoundOffPx);
  // One scale both ways (aspect kept), y up.
  EXPECT_NEAR(m.ToPixel(0, 0).y - m.ToPixel(0, 1).y, m.scale_px_per_m, kAffineRoundOffPx);
  EXPECT_LT(m.ToPixel(0, 3).y, m.ToPixel(0, 0).y);
  // A tall floor area: the height limits instead.
  o.width_px = 1000;
  o.panel_px = 0;
  o.height_px = 2000;
  EXPECT_NEAR(MakeFloorMapping(site, o).scale_px_per_m, 1000.0 / 4.6, kScaleRoundOffPxPerM);
  o.width_px = 3000;
  EXPECT_NEAR(MakeFloorMapping(site, o).scale_px_per_m, 2000.0 / 3.6, kScaleRoundOffPxPerM);
}

TEST(FloorMapping, PanMovesTheCentreAndZoomScalesAboutIt) {
  const Site site = DemoSite();
  RenderOptions o;
  const FloorMapping base = MakeFloorMapping(site, o);
  o.pan_x_m = 1.0;
  o.pan_y_m = -0.5;
  const FloorMapping panned = MakeFloorMapping(site, o);
  // The room point (3, 1) is now in the middle of the floor area.
  EXPECT_NEAR(panned.ToPixel(3.0, 1.0).x, 450.0, kAffineRoundOffPx);
  EXPECT_NEAR(panned.ToPixel(3.0, 1.0).y, 400.0, kAffineRoundOffPx);
  EXPECT_NEAR(panned.scale_px_per_m, base.scale_px_per_m, kPanKeepsScalePxPerM);
  o.zoom = 2.0;
  const FloorMapping zoomed = MakeFloorMapping(site, o);
  EXPECT_NEAR(zoomed.scale_px_per_m, 2 * base.scale_px_per_m, kScaleRoundOffPxPerM);
  EXPECT_NEAR(zoomed.ToPixel(3.0, 1.0).x, 450.0, kAffineRoundOffPx);
  EXPECT_NEAR(zoomed.ToPixel(3.5, 1.0).x - 450.0, 0.5 * 2 * base.scale_px_per_m, kAffineRoundOffPx);
}

TEST(FloorMapping, IsFiniteForARoomOrOptionsThatMakeNoSense) {
  Site site;
  for (double v : {0.0, std::nan(""), kInf, -5.0, 1e300}) {
    site.room.size_x_m = v;
    site.room.size_y_m = v;
    site.room.min_x_m = v;
    RenderOptions o;
    o.zoom = v;
    o.pan_x_m = v;
    o.width_px = static_cast<int>(std::isfinite(v) ? v : -1);
    const FloorMapping m = MakeFloorMapping(site, o);
    EXPECT_TRUE(std::isfinite(m.scale_px_per_m) && m.scale_px_per_m > 0) << v;
    EXPECT_TRUE(std::isfinite(m.u0_px) && std::isfinite(m.v0_px)) << v;
  }
}

TEST(Render, FillsAPictureOfTheOptionsSizeAndReusesItsMemory) {
  const ViewState state = DemoState();
  RenderOptions o;
  o.width_px = 640;
  o.height_px = 400;
  o.panel_px = 200;
  cv::Mat image;
  Render(state, o, &image);
  ASSERT_EQ(image.type(), CV_8UC3);
  EXPECT_EQ(image.cols, 640);
  EXPECT_EQ(image.rows, 400);
  const uint8_t* data = image.data;
  Render(state, o, &image);
  EXPECT_EQ(image.data, data) << "a second frame of the same size must not allocate";
  o.width_px = 700;
  Render(state, o, &image);
  EXPECT_EQ(image.cols, 700);
}

TEST(Render, DrawsEachReceiverWhereTheSiteGeometryPutsIt) {
  const ViewState state = DemoState();
  const RenderOptions o;
  const FloorMapping m = MakeFloorMapping(state.site, o);
  cv::Mat image;
  Render(state, o, &image);
  ASSERT_EQ(state.site.receivers.size(), 4u);
  for (const Receiver& r : state.site.receivers) {
    const cv::Point2d px = m.ToPixel(r.position_m[0], r.position_m[1]);
    EXPECT_LE(Distance(At(image, px), ReceiverColour()), kExact) << "receiver " << r.id;
  }
  // And nowhere else: the middle of the room is floor.
  EXPECT_LE(Distance(At(image, m.ToPixel(1.75, 1.25)), FloorColour()), kExact);
}

TEST(Render, DrawsEachFixedObstacleAsItsFootprint) {
  ViewState state = DemoState();
  Obstacle pillar;
  pillar.shape = Obstacle::Shape::kCylinder;
  pillar.centre_m = {2.5, 2.0};
  pillar.radius_m = 0.25;
  pillar.top_m = 3.0;
  Obstacle cupboard;
  cupboard.shape = Obstacle::Shape::kBox;
  cupboard.centre_m = {1.0, 0.6};
  cupboard.size_m = {0.8, 0.4};
  cupboard.yaw_rad = M_PI / 2;  // now 0.4 m along x, 0.8 m along y
  cupboard.top_m = 2.0;
  state.site.obstacles = {pillar, cupboard};
  const RenderOptions o;
  const FloorMapping m = MakeFloorMapping(state.site, o);
  cv::Mat image;
  Render(state, o, &image);
  // Inside each footprint (clear of the outline's antialiasing), and just
  // outside the turned box where the unturned one would have been.
  EXPECT_LE(Distance(At(image, m.ToPixel(2.5, 2.1)), ObstacleColour()), kExact);
  EXPECT_LE(Distance(At(image, m.ToPixel(1.0, 0.9)), ObstacleColour()), kExact);
  EXPECT_LE(Distance(At(image, m.ToPixel(1.3, 0.6)), FloorColour()), kExact);
}

TEST(Render, DrawsEachVisibleSourceAsADiscInItsColourAtThePose) {
  ViewState state = DemoState();
  const double xs[kNumSources] = {1.0, 2.0, 3.0, 1.0};
  const double ys[kNumSources] = {1.0, 1.0, 1.0, 2.2};
  for (int i = 0; i < kNumSources; ++i) {
    state.tracks.push_back(Track(kSources[i], 1, xs[i], ys[i]));
    state.tracks.back().heading_rad = 0.5;
  }
  const RenderOptions o;
  const FloorMapping m = MakeFloorMapping(state.site, o);
  cv::Mat image;
  Render(state, o, &image);
  for (int i = 0; i < kNumSources; ++i) {
    const PoseSource s = kSources[i];
    EXPECT_LE(Distance(At(image, m.ToPixel(xs[i], ys[i])), SourceColour(s)), kExact)
        << SourceName(s);
  }
}

TEST(Render, LeavesAHiddenSourceOutOfTheFloor) {
  ViewState with = DemoState();
  with.tracks.push_back(Track(PoseSource::kFused, 1, 2.0, 1.5));
  TrackView camera = Track(PoseSource::kCamera, 1, 1.0, 1.0);
  camera.heading_rad = 1.0;
  camera.cov_xx_m2 = 0.01;
  camera.cov_yy_m2 = 0.02;
  camera.cov_xy_m2 = 0.0;
  for (int k = 0; k < 100; ++k) {
    camera.trail.push_back({kNowUtime - (100 - k) * 50'000, 0.5 + 0.01 * k, 1.0});
  }
  with.tracks.push_back(camera);
  with.visible[static_cast<size_t>(PoseSource::kCamera)] = false;
  ViewState without = with;
  without.tracks.pop_back();

  const RenderOptions o;
  const FloorMapping m = MakeFloorMapping(with.site, o);
  cv::Mat a;
  cv::Mat b;
  Render(with, o, &a);
  Render(without, o, &b);
  EXPECT_GT(Distance(At(a, m.ToPixel(1.0, 1.0)), SourceColour(PoseSource::kCamera)), 60);
  // The floor area is exactly as if the track were not there (the panel
  // still lists it, marked hidden).
  const cv::Rect floor(0, 0, o.width_px - o.panel_px, o.height_px);
  EXPECT_EQ(cv::norm(a(floor), b(floor), cv::NORM_INF), 0.0);
  EXPECT_GT(cv::norm(a, b, cv::NORM_INF), 0.0);
}

TEST(Render, DrawsARangeAsItsCircleInTheBeaconsHeightPlane) {
  ViewState state = DemoState();
  const RenderOptions o;
  const FloorMapping m = MakeFloorMapping(state.site, o);
  cv::Mat reference;
  Render(state, o, &reference);
  const double range_m = 2.0;
  state.range_sets.push_back(OneRange(state.site, 1, range_m, false));
  cv::Mat image;
  Render(state, o, &image);
  // Receiver 1 at (0, 0, 2.5), beacon at 1.3 m: the circle's radius is
  // sqrt(2.0^2 - 1.2^2) = 1.6 m, not 2.0 m.
  const double radius_m = std::sqrt(range_m * range_m - 1.2 * 1.2);
  const cv::Point2d centre = m.ToPixel(0, 0);
  const cv::Scalar colour = SourceColour(PoseSource::kUltrasound);
  double worst = 1.0;
  for (double deg = 1; deg < 90; deg += 1) {
    const double a = deg * M_PI / 180.0;
    const double t = LineNear(image, reference,
                              m.ToPixel(radius_m * std::cos(a), radius_m * std::sin(a)), colour);
    EXPECT_GE(t, kMinLineCoverage) << deg << " deg";
    worst = std::min(worst, t);
    // Not at the slant range.
    EXPECT_LT(OnCircle(image, reference, centre, range_m * m.scale_px_per_m, a, colour), kNoLine)
        << deg << " deg";
  }
  RecordProperty("worst_coverage", std::to_string(worst));
  // A circle, not a disc: nothing at the centre or half way out.
  EXPECT_LT(LineNear(image, reference, centre, colour), kNoLine);
  EXPECT_LT(LineNear(image, reference, m.ToPixel(0.5 * radius_m, 0.5 * radius_m), colour), kNoLine);
  // Hiding ultrasound hides its range circles.
  state.visible[static_cast<size_t>(PoseSource::kUltrasound)] = false;
  Render(state, o, &image);
  const double a = 45 * M_PI / 180.0;
  EXPECT_LT(
      LineNear(image, reference, m.ToPixel(radius_m * std::cos(a), radius_m * std::sin(a)), colour),
      kNoLine);
}

TEST(Render, DrawsARejectedRangeDashedInTheWarningColour) {
  ViewState state = DemoState();
  const RenderOptions o;
  const FloorMapping m = MakeFloorMapping(state.site, o);
  cv::Mat reference;
  Render(state, o, &reference);
  state.range_sets.push_back(OneRange(state.site, 3, 2.0, true));
  cv::Mat image;
  Render(state, o, &image);
  const double radius_px = 1.6 * m.scale_px_per_m;
  // Receiver 3 is the corner (4, 3): the quarter towards the room, sampled
  // every degree (~5.5 px apart; dashes and gaps are ~6 px).
  const cv::Point2d centre = m.ToPixel(4.0, 3.0);
  int warning = 0;
  int samples = 0;
  for (double deg = 181; deg < 270; deg += 1, ++samples) {
    const double a = deg * M_PI / 180.0;
    warning +=
        OnCircle(image, reference, centre, radius_px, a, WarningColour()) >= kMinLineCoverage;
    EXPECT_LT(
        OnCircle(image, reference, centre, radius_px, a, SourceColour(PoseSource::kUltrasound)),
        kNoLine);
  }
  // Dashed: there at about half the samples, not everywhere.
  EXPECT_GT(warning, samples / 4);
  EXPECT_LT(warning, samples * 3 / 4);
}

TEST(Render, SkipsARangeShorterThanTheHeightDifference) {
  ViewState state = DemoState();
  state.range_sets.push_back(OneRange(state.site, 1, 1.0, false));  // |dz| = 1.2 m
  state.range_sets.push_back(OneRange(state.site, 2, std::nan(""), false));
  state.range_sets.push_back(OneRange(state.site, 3, -3.0, false));
  ViewState empty = DemoState();
  const RenderOptions o;
  cv::Mat a;
  cv::Mat b;
  Render(state, o, &a);
  Render(empty, o, &b);
  EXPECT_EQ(cv::norm(a, b, cv::NORM_INF), 0.0);
}

TEST(Render, GreysAndMarksAStaleTrack) {
  ViewState state = DemoState();
  state.stale_after_s = 2.0;
  TrackView t = Track(PoseSource::kFused, 1, 2.0, 1.5);
  t.recv_utime = kNowUtime - 3'000'000;
  state.tracks.push_back(t);
  const RenderOptions o;
  const FloorMapping m = MakeFloorMapping(state.site, o);
  cv::Mat image;
  Render(state, o, &image);
  const cv::Point2d centre = m.ToPixel(2.0, 1.5);
  // The 'X' crosses the centre; the disc around it is grey.
  EXPECT_GT(Distance(At(image, centre), SourceColour(PoseSource::kFused)), 60);
  EXPECT_LE(Distance(At(image, centre + cv::Point2d(4, 0)), StaleColour()), kExact);
  EXPECT_GT(Distance(At(image, centre), StaleColour()), 60) << "the X mark";
  // A second later than the limit it is not stale.
  state.tracks[0].recv_utime = kNowUtime - 1'000'000;
  Render(state, o, &image);
  EXPECT_LE(Distance(At(image, centre), SourceColour(PoseSource::kFused)), kExact);
}

TEST(Render, FadesATrailTowardsTheFloorWithAge) {
  ViewState state = DemoState();
  TrackView t = Track(PoseSource::kUltrasound, 1, 3.6, 1.1);
  // 10 s from x = 0.4 (oldest) to x = 3.4 (newest), at 10 Hz.
  for (int k = 0; k <= 100; ++k) {
    t.trail.push_back({kNowUtime - (100 - k) * 100'000, 0.4 + 0.03 * k, 1.1});
  }
  state.tracks.push_back(t);
  const RenderOptions o;
  const FloorMapping m = MakeFloorMapping(state.site, o);
  cv::Mat image;
  Render(state, o, &image);
  const cv::Scalar colour = SourceColour(PoseSource::kUltrasound);
  const int newest = Distance(At(image, m.ToPixel(3.3, 1.1)), colour);
  const int middle = Distance(At(image, m.ToPixel(1.9, 1.1)), colour);
  // (Not x = 0.5: a grid line.)
  const int oldest = Distance(At(image, m.ToPixel(0.6, 1.1)), colour);
  EXPECT_LE(newest, kLineCoreTolerance);
  EXPECT_GT(middle, newest + 30);
  EXPECT_GT(oldest, middle + 30);
  // Yet still there: not the floor.
  EXPECT_GT(Distance(At(image, m.ToPixel(0.6, 1.1)), FloorColour()), 10);
  // Points older than trail_s are not drawn.
  state.trail_s = 5.0;
  Render(state, o, &image);
  EXPECT_LE(Distance(At(image, m.ToPixel(0.6, 1.1)), FloorColour()), kExact);
}

TEST(Render, ZoomAndPanMoveTheDrawing) {
  ViewState state = DemoState();
  state.tracks.push_back(Track(PoseSource::kFused, 1, 3.0, 2.0));
  RenderOptions o;
  o.zoom = 2.0;
  o.pan_x_m = 1.0;
  o.pan_y_m = 0.5;  // centre (3, 2): the robot
  const FloorMapping m = MakeFloorMapping(state.site, o);
  cv::Mat image;
  Render(state, o, &image);
  EXPECT_LE(Distance(At(image, {450, 400}), SourceColour(PoseSource::kFused)), kExact);
  // Receiver 3 at (4, 3) is 1 m right and 1 m up of the centre.
  const cv::Point2d r3 = m.ToPixel(4.0, 3.0);
  EXPECT_NEAR(r3.x, 450 + 1.0 * m.scale_px_per_m, kAffineRoundOffPx);
  EXPECT_NEAR(r3.y, 400 - 1.0 * m.scale_px_per_m, kAffineRoundOffPx);
  EXPECT_LE(Distance(At(image, r3), ReceiverColour()), kExact);
  // Where the robot was at zoom 1 it is not.
  const FloorMapping before = MakeFloorMapping(state.site, RenderOptions{});
  EXPECT_GT(Distance(At(image, before.ToPixel(3.0, 2.0)), SourceColour(PoseSource::kFused)), 60);
}

TEST(Render, ShowsTheSameBackgroundWhenTheSiteChangesAndComesBack) {
  ViewState a = DemoState();
  ViewState b = DemoState();
  b.site.receivers[0].position_m = {1.0, 1.0, 2.5};
  b.site.room.size_x_m = 6.0;
  const RenderOptions o;
  cv::Mat first;
  cv::Mat other;
  cv::Mat again;
  Render(a, o, &first);
  Render(b, o, &other);
  Render(a, o, &again);
  EXPECT_GT(cv::norm(first, other, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(first, again, cv::NORM_INF), 0.0);
}

TEST(Render, SurvivesAnEmptyState) {
  cv::Mat image;
  Render(ViewState{}, RenderOptions{}, &image);
  EXPECT_EQ(image.cols, 1280);
  Render(ViewState{}, RenderOptions{}, nullptr);
}

TEST(Render, SurvivesInvalidOptionsByClampingThem) {
  const ViewState state = DemoState();
  cv::Mat image;
  RenderOptions o;
  o.width_px = -5;
  o.height_px = 1 << 30;
  o.panel_px = 100000;
  o.zoom = -kInf;
  o.pan_x_m = std::nan("");
  Render(state, o, &image);
  std::string error;
  EXPECT_FALSE(o.IsValid(&error));
  EXPECT_EQ(image.cols, 64);
  EXPECT_EQ(image.rows, 8192);
}

// Random garbage through every field: NaN, infinities, huge and tiny values,
// extreme times, random bytes as a preview. Anything goes but a crash (the
// sanitizer build also checks for undefined behaviour).
TEST(Render, SurvivesNaNsHugeValuesAndGarbage) {
  std::mt19937_64 rng(12345);
  const double specials[] = {std::nan(""), kInf, -kInf, 1e300, -1e300, 1e-300,
                             0.0,          -0.0, 1e9,   -1e9,  3.0,    0.5};
  auto value = [&]() {
    std::uniform_int_distribution<int> pick(0, 15);
    const int k = pick(rng);
    if (k < 12) return specials[k];
    return std::uniform_real_distribution<double>(-10, 10)(rng);
  };
  auto time = [&]() -> int64_t {
    std::uniform_int_distribution<int> pick(0, 4);
    switch (pick(rng)) {
      case 0:
        return std::numeric_limits<int64_t>::min();
      case 1:
        return std::numeric_limits<int64_t>::max();
      case 2:
        return 0;
      default:
        return kNowUtime - std::uniform_int_distribution<int64_t>(-5'000'000, 30'000'000)(rng);
    }
  };
  const Site demo = DemoSite();
  cv::Mat image;
  for (int iteration = 0; iteration < 150; ++iteration) {
    ViewState s;
    s.site = demo;
    s.site.room = {value(), value(), value(), value(), value(), value(), "garbage"};
    for (Receiver& r : s.site.receivers) r.position_m = {value(), value(), value()};
    for (Camera& c : s.site.cameras) {
      c.mount_position_m = {value(), value(), value()};
      c.field_of_view_deg = value() * 40;
    }
    s.now_utime = iteration % 3 == 0 ? time() : kNowUtime;
    s.trail_s = value();
    s.stale_after_s = value();
    for (int i = 0; i < 6; ++i) {
      TrackView t;
      t.source = static_cast<PoseSource>(i);  // 0 (unknown) and 5 are no drawn source
      t.robot_id = static_cast<int>(rng() % 4) - 1;
      t.x_m = value();
      t.y_m = value();
      t.heading_rad = value();
      t.cov_xx_m2 = value();
      t.cov_xy_m2 = value();
      t.cov_yy_m2 = value();
      t.lost = rng() % 2 == 0;
      t.degraded = rng() % 2 == 0;
      t.utime = time();
      t.recv_utime = time();
      t.rate_hz = value();
      t.latency_ms = value();
      for (int k = 0; k < 50; ++k) t.trail.push_back({time(), value(), value()});
      s.tracks.push_back(t);
    }
    for (int i = 0; i < 3; ++i) {
      RangeSetView set;
      set.beacon_height_m = value();
      set.recv_utime = time();
      for (int k = 0; k < 4; ++k) {
        set.ranges.push_back({k, {value(), value(), value()}, value(), rng() % 2 == 0});
      }
      s.range_sets.push_back(set);
    }
    ProcessView p;
    p.name = std::string("n\xff\x01\tame") + std::string(static_cast<size_t>(rng() % 300), 'x');
    p.host = "h";
    p.state = static_cast<int>(rng() % 7) - 1;
    p.dropped = static_cast<int64_t>(rng());
    p.output_rate_hz = value();
    p.rejected = {{"a", static_cast<int64_t>(rng())}, {"b\n", -1}, {"", 0}, {"d", 5}};
    p.last_error = std::string(500, 'e');
    p.recv_utime = time();
    s.processes.assign(static_cast<size_t>(rng() % 40), p);
    s.has_preview = rng() % 2 == 0;
    s.preview.encoded.resize(rng() % 200);
    for (uint8_t& byte : s.preview.encoded) byte = static_cast<uint8_t>(rng());
    if (iteration % 4 == 0 && s.preview.encoded.size() > 4) {
      s.preview.encoded[0] = 0xFF;  // a JPEG start, then garbage
      s.preview.encoded[1] = 0xD8;
    }
    s.preview.utime = time();
    s.preview.markers = {{value(), value(), value(), "green"}, {value(), value(), value(), ""}};
    s.visible = {rng() % 2 == 0, rng() % 2 == 0, true, rng() % 2 == 0};
    RenderOptions o;
    o.width_px = 320 + static_cast<int>(rng() % 400);
    o.height_px = 200 + static_cast<int>(rng() % 300);
    o.panel_px = static_cast<int>(rng() % 400) - 20;
    o.zoom = iteration % 5 == 0 ? value() : 1.0;
    o.pan_x_m = iteration % 7 == 0 ? value() : 0.0;
    Render(s, o, &image);
    ASSERT_FALSE(image.empty());
  }
}

TEST(Render, SurvivesAnUndecodablePreview) {
  ViewState state = DemoState();
  state.has_preview = true;
  const RenderOptions o;
  cv::Mat image;
  // Empty, random, a truncated PNG and a PNG header that claims a 100000 x
  // 100000 picture (imdecode would try to allocate 30 GB).
  std::vector<std::vector<uint8_t>> previews = {
      {}, {1, 2, 3, 4, 5}, {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'}};
  std::vector<uint8_t> huge = {0x89, 'P',  'N', 'G', '\r', '\n', 0x1a, '\n', 0,    0, 0,
                               13,   'I',  'H', 'D', 'R',  0,    1,    0x86, 0xA0, 0, 1,
                               0x86, 0xA0, 8,   2,   0,    0,    0,    0,    0,    0, 0};
  previews.push_back(huge);
  std::vector<uint8_t> png;
  cv::imencode(".png", cv::Mat(48, 64, CV_8UC3, cv::Scalar(0, 0, 255)), png);
  png.resize(png.size() / 2);
  previews.push_back(png);
  for (const auto& bytes : previews) {
    state.preview.encoded = bytes;
    state.preview.markers = {{10, 10, 5, "orange"}};
    Render(state, o, &image);
    ASSERT_EQ(image.cols, o.width_px);
  }
}

TEST(Render, ShowsTheCameraPreviewAndItsMarkersAtTheBottomOfThePanel) {
  ViewState state = DemoState();
  state.has_preview = true;
  std::vector<uint8_t> png;
  ASSERT_TRUE(cv::imencode(".png", cv::Mat(120, 160, CV_8UC3, cv::Scalar(0, 0, 200)), png));
  state.preview.encoded = png;
  state.preview.utime = kNowUtime - 300'000;
  // A marker in the preview's own pixels, in its top-left quarter.
  state.preview.markers = {{40, 30, 10, "green"}};
  const RenderOptions o;
  cv::Mat image;
  Render(state, o, &image);
  // The preview box is the panel's width less 10 px each side (360 px) by a
  // quarter of its height (200 px), at its bottom, 10 px above the
  // picture's: the 160 x 120 preview scales by 200 / 120 to 267 x 200.
  const int left = o.width_px - o.panel_px + 10;
  const int bottom = o.height_px - 10;
  const cv::Scalar red(0, 0, 200);
  EXPECT_LE(Distance(image.at<cv::Vec3b>(bottom - 5, left + 260), red), kExact);
  EXPECT_LE(Distance(image.at<cv::Vec3b>(bottom - 195, left + 5), red), kExact);
  EXPECT_GT(Distance(image.at<cv::Vec3b>(bottom - 100, left + 275), red), 60) << "right of it";
  // The marker's ring: centre (40, 30) * 5/3, radius 10 * 5/3 px and a
  // 3 px gap (so it shows on a blob of its own colour); its rightmost point.
  const cv::Point2d marker(left + (40 + 10) * 5.0 / 3.0 + 3, bottom - 200 + 30 * 5.0 / 3.0);
  cv::Mat reference(image.size(), CV_8UC3, red);
  EXPECT_GE(LineNear(image, reference, marker, cv::Scalar(40, 220, 40)), kMinLineCoverage);
}

// The detector view (CAMERA_DETECTOR_VIEW) of the preview's camera is
// blended over the part of the preview it shows, and each robot's line is
// listed above the preview.
TEST(Render, BlendsTheDetectorViewOverItsRegionOfThePreviewAndListsTheRobots) {
  ViewState state = DemoState();
  state.has_preview = true;
  std::vector<uint8_t> png;
  ASSERT_TRUE(cv::imencode(".png", cv::Mat(120, 160, CV_8UC3, cv::Scalar(0, 0, 200)), png));
  state.preview.encoded = png;
  state.preview.utime = kNowUtime - 300'000;
  const RenderOptions o;
  cv::Mat without;
  Render(state, o, &without);
  // The left half of a 640 x 480 frame, shown as a green image.
  state.has_detector_view = true;
  DetectorViewView& v = state.detector_view;
  v.camera_id = state.preview.camera_id;
  v.utime = kNowUtime - 200'000;
  ASSERT_TRUE(cv::imencode(".png", cv::Mat(240, 160, CV_8UC3, cv::Scalar(0, 200, 0)), v.encoded));
  v.region_width_px = 320;
  v.region_height_px = 480;
  v.source_width_px = 640;
  v.source_height_px = 480;
  v.robots = {{1, false, "robot 1: no pixels of class green"}};
  cv::Mat image;
  Render(state, o, &image);
  // The preview box (ShowsTheCameraPreview...): 267 x 200 px, the view's
  // half 133 px wide; 0.7 of the view over 0.3 of the preview.
  const int left = o.width_px - o.panel_px + 10;
  const int bottom = o.height_px - 10;
  const cv::Scalar blended(0, 0.7 * 200, 0.3 * 200);
  constexpr double kRoundingDn = 2.0;
  EXPECT_LE(Distance(image.at<cv::Vec3b>(bottom - 100, left + 60), blended), kRoundingDn);
  EXPECT_LE(Distance(image.at<cv::Vec3b>(bottom - 100, left + 200), cv::Scalar(0, 0, 200)), kExact);
  // The robot's line (and the view's title) sit above the preview's label.
  const cv::Rect lines(o.width_px - o.panel_px, bottom - 200 - 3 * 17 - 10, o.panel_px, 2 * 17);
  EXPECT_GT(cv::norm(image(lines), without(lines), cv::NORM_L1), 0.0);
}

}  // namespace
}  // namespace roomfix::viewer
