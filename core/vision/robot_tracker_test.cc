#include "core/vision/robot_tracker.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

namespace roomfix::vision {
namespace {

// A 1920 x 1080 camera at 30 frames per second.
constexpr int kWidthPx = 1920;
constexpr int kHeightPx = 1080;
constexpr int64_t kFramePeriodUs = 33333;
constexpr int64_t kStartUs = 1'700'000'000'000'000;
constexpr double kFramePeriodS = kFramePeriodUs * 1e-6;

// Marker classes as the detector numbers them.
constexpr int kOrange = 0;
constexpr int kGreen = 1;
constexpr int kBlue = 2;
constexpr int kPink = 3;

constexpr double kRadiusPx = 15.0;
// The heading marker sits this far from the position marker (well inside
// heading_search_radii * radius = 75 px).
constexpr double kHeadingOffsetPx = 40.0;
// Centroid agreement: the tracker copies blobs, so exact up to rounding.
constexpr double kTolPx = 1e-9;
// A search window is a cv::Rect of whole pixels centred on a predicted
// position: its centre (x + (width - 1) / 2) rounds the prediction by up to
// a pixel.
constexpr double kWholePixelRectPx = 1.0;
// Angles from atan2 of exact offsets.
constexpr double kTolRad = 1e-12;

// Options that search the full frame for robots out of view in every frame,
// for tests of what a full-frame search decides (absent_search_period_frames
// has its own tests).
TrackerOptions EveryFrame(TrackerOptions o = TrackerOptions{}) {
  o.absent_search_period_frames = 1;
  return o;
}

Blob MakeBlob(int class_index, double u, double v, double radius = kRadiusPx) {
  Blob b;
  b.class_index = class_index;
  b.u_px = u;
  b.v_px = v;
  b.radius_px = radius;
  b.area_px = M_PI * radius * radius;
  b.circularity = 0.9;
  return b;
}

// A robot's two markers: position at (u, v), heading `offset` to the right.
std::vector<Blob> Robot(double u, double v, int position_class = kOrange,
                        int heading_class = kGreen, double du = kHeadingOffsetPx, double dv = 0.0) {
  return {MakeBlob(position_class, u, v), MakeBlob(heading_class, u + du, v + dv, 8.0)};
}

std::vector<Blob> Join(std::vector<Blob> a, const std::vector<Blob>& b) {
  a.insert(a.end(), b.begin(), b.end());
  return a;
}

TrackedRobotSpec Spec(int id, int position_class = kOrange, int heading_class = kGreen) {
  TrackedRobotSpec s;
  s.robot_id = id;
  s.position_class = position_class;
  s.heading_class = heading_class;
  s.position_radius_px = kRadiusPx;
  return s;
}

// Plays the node: asks for a plan, "detects" by handing every blob of the
// scene to the searches the plan asked for (a full-frame search sees all;
// a window search gets only the blobs inside its window unless
// `leak_into_windows`, which hands it the whole scene to prove the tracker
// filters by window itself).
struct Frame {
  std::vector<SearchPlan> plans;
  std::vector<RobotObservation> obs;
};

Frame Step(RobotTracker* tracker, int64_t utime, const std::vector<Blob>& scene,
           bool leak_into_windows = false) {
  Frame f;
  f.plans = tracker->Plan(utime);
  bool any_full = false;
  std::vector<std::vector<Blob>> windows;
  for (const SearchPlan& p : f.plans) {
    any_full |= p.full_frame;
    std::vector<Blob> in_window;
    if (!p.full_frame) {
      for (const Blob& b : scene) {
        if (leak_into_windows ||
            p.window.contains(cv::Point(static_cast<int>(b.u_px), static_cast<int>(b.v_px)))) {
          in_window.push_back(b);
        }
      }
    }
    windows.push_back(in_window);
  }
  f.obs = tracker->Update(utime, f.plans, any_full ? scene : std::vector<Blob>{}, windows);
  return f;
}

TEST(TrackStateName, NamesEveryState) {
  EXPECT_STREQ(TrackStateName(TrackState::kSearching), "searching");
  EXPECT_STREQ(TrackStateName(TrackState::kTracking), "tracking");
  EXPECT_STREQ(TrackStateName(TrackState::kAmbiguous), "ambiguous");
  EXPECT_STREQ(TrackStateName(TrackState::kLost), "lost");
}

TEST(RobotTracker, SearchesTheFullFrameBeforeTheFirstFind) {
  RobotTracker tracker({Spec(1)}, TrackerOptions{}, kWidthPx, kHeightPx);
  const auto plans = tracker.Plan(kStartUs);
  ASSERT_EQ(plans.size(), 1u);
  EXPECT_EQ(plans[0].robot_id, 1);
  EXPECT_TRUE(plans[0].full_frame);
}

TEST(RobotTracker, WindowIsSizedFromSpeedAndTimeSinceTheLastFind) {
  TrackerOptions options;
  options.max_speed_px_per_s = 600.0;
  options.window_margin_px = 24.0;
  options.window_radius_factor = 4.0;
  RobotTracker tracker({Spec(1)}, options, kWidthPx, kHeightPx);
  constexpr double kU = 960.0, kV = 540.0;
  const Frame first = Step(&tracker, kStartUs, Robot(kU, kV));
  ASSERT_TRUE(first.obs[0].found);
  EXPECT_EQ(first.obs[0].state, TrackState::kTracking);

  constexpr int64_t kDtUs = 100'000;  // 0.1 s
  const auto plans = tracker.Plan(kStartUs + kDtUs);
  ASSERT_FALSE(plans[0].full_frame);
  // Half-size 24 + 15 * 4 + 600 * 0.1 = 144 px around the last position
  // (no velocity yet after one find).
  constexpr int kHalf = 144;
  EXPECT_EQ(plans[0].window, cv::Rect(960 - kHalf, 540 - kHalf, 2 * kHalf + 1, 2 * kHalf + 1));

  // Twice the time: the speed term doubles.
  const auto later = tracker.Plan(kStartUs + 2 * kDtUs);
  constexpr int kHalf2 = 24 + 60 + 120;
  EXPECT_EQ(later[0].window, cv::Rect(960 - kHalf2, 540 - kHalf2, 2 * kHalf2 + 1, 2 * kHalf2 + 1));
}

TEST(RobotTracker, WindowIsClippedAtTheImageBorders) {
  RobotTracker tracker({Spec(1)}, TrackerOptions{}, kWidthPx, kHeightPx);
  constexpr double kU = 20.0, kV = kHeightPx - 30.0;  // near the bottom-left corner
  ASSERT_TRUE(Step(&tracker, kStartUs, Robot(kU, kV)).obs[0].found);
  const auto plans = tracker.Plan(kStartUs + 100'000);
  ASSERT_FALSE(plans[0].full_frame);
  const cv::Rect& w = plans[0].window;
  EXPECT_EQ(w.x, 0);
  EXPECT_EQ(w.y + w.height, kHeightPx);
  EXPECT_EQ(w.y, static_cast<int>(kV) - 144);
  EXPECT_EQ(w.x + w.width, static_cast<int>(kU) + 144 + 1);
}

TEST(RobotTracker, WindowNeverExceedsTheImageAfterALongGap) {
  TrackerOptions options;
  options.lost_after_s = 100.0;  // keep tracking through the gap
  RobotTracker tracker({Spec(1)}, options, kWidthPx, kHeightPx);
  ASSERT_TRUE(Step(&tracker, kStartUs, Robot(960, 540)).obs[0].found);
  const auto plans = tracker.Plan(kStartUs + 50'000'000);  // 50 s: 30000 px of travel
  ASSERT_FALSE(plans[0].full_frame);
  EXPECT_EQ(plans[0].window, cv::Rect(0, 0, kWidthPx, kHeightPx));
}

TEST(RobotTracker, ConstantVelocityMarkerStaysTrackedWithWindowsCentredOnThePrediction) {
  RobotTracker tracker({Spec(1)}, TrackerOptions{}, kWidthPx, kHeightPx);
  constexpr double kU0 = 300.0, kV0 = 200.0;
  constexpr double kVu = 240.0, kVv = 120.0;  // px/s
  for (int k = 0; k < 40; ++k) {
    const int64_t t = kStartUs + k * kFramePeriodUs;
    const double dt = (t - kStartUs) * 1e-6;
    const double u = kU0 + kVu * dt;
    const double v = kV0 + kVv * dt;
    const Frame f = Step(&tracker, t, Robot(u, v));
    ASSERT_TRUE(f.obs[0].found) << "frame " << k << ": " << f.obs[0].note;
    EXPECT_EQ(f.obs[0].state, TrackState::kTracking);
    EXPECT_NEAR(f.obs[0].position.u_px, u, kTolPx);
    EXPECT_EQ(f.plans[0].full_frame, k == 0) << "frame " << k;
    if (k >= 2) {
      // Two consecutive finds give the velocity: the window's centre is the
      // predicted (here: true) position, to the pixel rounding of the rect.
      const cv::Rect& w = f.plans[0].window;
      EXPECT_NEAR(w.x + (w.width - 1) / 2.0, u, kWholePixelRectPx) << "frame " << k;
      EXPECT_NEAR(w.y + (w.height - 1) / 2.0, v, kWholePixelRectPx) << "frame " << k;
    }
  }
}

TEST(RobotTracker, MarkerJumpingOutOfTheWindowIsMissedThenReacquiredFromTheFullFrame) {
  RobotTracker tracker({Spec(1)}, TrackerOptions{}, kWidthPx, kHeightPx);
  int64_t t = kStartUs;
  ASSERT_TRUE(Step(&tracker, t, Robot(400, 400)).obs[0].found);
  t += kFramePeriodUs;
  ASSERT_TRUE(Step(&tracker, t, Robot(400, 400)).obs[0].found);

  constexpr double kJumpU = 1400.0, kJumpV = 800.0;  // far beyond any window
  t += kFramePeriodUs;
  const Frame missed = Step(&tracker, t, Robot(kJumpU, kJumpV));
  EXPECT_FALSE(missed.plans[0].full_frame);
  EXPECT_FALSE(missed.obs[0].found);
  EXPECT_EQ(missed.obs[0].state, TrackState::kTracking);  // not lost yet
  EXPECT_NE(missed.obs[0].note.find("full-frame search next frame"), std::string::npos)
      << missed.obs[0].note;

  t += kFramePeriodUs;
  const Frame again = Step(&tracker, t, Robot(kJumpU, kJumpV));
  EXPECT_TRUE(again.plans[0].full_frame);
  ASSERT_TRUE(again.obs[0].found) << again.obs[0].note;
  EXPECT_EQ(again.obs[0].state, TrackState::kTracking);
  EXPECT_NEAR(again.obs[0].position.u_px, kJumpU, kTolPx);

  // Back to windows, centred on the new place: the old velocity was reset.
  const auto plans = tracker.Plan(t + kFramePeriodUs);
  ASSERT_FALSE(plans[0].full_frame);
  const cv::Rect& w = plans[0].window;
  EXPECT_NEAR(w.x + (w.width - 1) / 2.0, kJumpU, kWholePixelRectPx);
  EXPECT_NEAR(w.y + (w.height - 1) / 2.0, kJumpV, kWholePixelRectPx);
}

TEST(RobotTracker, SameClassDistractorOutsideTheWindowIsIgnoredWhileTracking) {
  RobotTracker tracker({Spec(1)}, TrackerOptions{}, kWidthPx, kHeightPx);
  int64_t t = kStartUs;
  ASSERT_TRUE(Step(&tracker, t, Robot(500, 500)).obs[0].found);
  // An orange object (with something green beside it) appears far away;
  // the window search is even handed it directly.
  const auto distractor = Robot(1500, 300);
  for (int k = 1; k < 10; ++k) {
    t += kFramePeriodUs;
    const Frame f = Step(&tracker, t, Join(Robot(500, 500), distractor), true);
    ASSERT_TRUE(f.obs[0].found);
    EXPECT_FALSE(f.plans[0].full_frame);
    EXPECT_NEAR(f.obs[0].position.u_px, 500.0, kTolPx);
    EXPECT_EQ(f.obs[0].num_candidates, 1);
  }
  // The robot vanishes: the distractor, alone in the image, is still not
  // taken from the window.
  t += kFramePeriodUs;
  const Frame gone = Step(&tracker, t, distractor, true);
  EXPECT_FALSE(gone.plans[0].full_frame);
  EXPECT_FALSE(gone.obs[0].found);
}

TEST(RobotTracker, StartUpWithALookalikeIsAmbiguousUntilItLeaves) {
  RobotTracker tracker({Spec(1)}, TrackerOptions{}, kWidthPx, kHeightPx);
  int64_t t = kStartUs;
  const auto robot = Robot(600, 500);
  const auto lookalike = Robot(1300, 700);  // orange with green beside it
  for (int k = 0; k < 3; ++k) {
    const Frame f = Step(&tracker, t, Join(robot, lookalike));
    EXPECT_TRUE(f.plans[0].full_frame);
    EXPECT_FALSE(f.obs[0].found);
    EXPECT_EQ(f.obs[0].state, TrackState::kAmbiguous);
    EXPECT_EQ(f.obs[0].num_candidates, 2);
    EXPECT_NE(f.obs[0].note.find("(600.0, 500.0)"), std::string::npos) << f.obs[0].note;
    EXPECT_NE(f.obs[0].note.find("(1300.0, 700.0)"), std::string::npos) << f.obs[0].note;
    t += kFramePeriodUs;
  }
  const Frame f = Step(&tracker, t, robot);
  ASSERT_TRUE(f.obs[0].found);
  EXPECT_EQ(f.obs[0].state, TrackState::kTracking);
  EXPECT_NEAR(f.obs[0].position.u_px, 600.0, kTolPx);
  EXPECT_EQ(f.obs[0].num_candidates, 1);
}

TEST(RobotTracker, APositionHintFromAnotherSensorResolvesALookalike) {
  // The ultrasound puts the robot within 40 px of (610, 490): of the two
  // look-alike pairs only the one at (600, 500) is inside, so it is taken.
  constexpr double kHintRadiusPx = 40.0;
  RobotTracker tracker({Spec(1)}, TrackerOptions{}, kWidthPx, kHeightPx);
  int64_t t = kStartUs;
  const auto scene = Join(Robot(600, 500), Robot(1300, 700));
  EXPECT_EQ(Step(&tracker, t, scene).obs[0].state, TrackState::kAmbiguous);
  tracker.SetHint(1, 610, 490, kHintRadiusPx, t);
  t += kFramePeriodUs;
  const Frame f = Step(&tracker, t, scene);
  ASSERT_TRUE(f.obs[0].found) << f.obs[0].note;
  EXPECT_NEAR(f.obs[0].position.u_px, 600.0, kTolPx);
  EXPECT_NE(f.obs[0].note.find("position hint"), std::string::npos) << f.obs[0].note;
  // From then on the window keeps the look-alike out.
  t += kFramePeriodUs;
  const Frame next = Step(&tracker, t, scene);
  EXPECT_FALSE(next.plans[0].full_frame);
  EXPECT_TRUE(next.obs[0].found);
}

TEST(RobotTracker, AStaleOrVagueHintDecidesNothing) {
  TrackerOptions options;
  options.hint_max_age_s = 1.0;
  RobotTracker tracker({Spec(1)}, options, kWidthPx, kHeightPx);
  const auto scene = Join(Robot(600, 500), Robot(700, 520));
  int64_t t = kStartUs;
  // Both candidates inside a wide hint: still ambiguous.
  tracker.SetHint(1, 650, 510, 200.0, t);
  EXPECT_EQ(Step(&tracker, t, scene).obs[0].state, TrackState::kAmbiguous);
  // A sharp hint, but two seconds old.
  tracker.SetHint(1, 600, 500, 20.0, t - 2'000'000);
  EXPECT_EQ(Step(&tracker, t, scene).obs[0].state, TrackState::kAmbiguous);
}

TEST(RobotTracker, LookalikeAfterABriefOcclusionDoesNotBlockReacquisitionNearby) {
  RobotTracker tracker({Spec(1)}, TrackerOptions{}, kWidthPx, kHeightPx);
  int64_t t = kStartUs;
  ASSERT_TRUE(Step(&tracker, t, Robot(600, 500)).obs[0].found);
  t += kFramePeriodUs;
  EXPECT_FALSE(Step(&tracker, t, {}).obs[0].found);  // occluded: window misses
  t += kFramePeriodUs;
  const Frame f = Step(&tracker, t, Join(Robot(605, 502), Robot(1300, 700)));
  EXPECT_TRUE(f.plans[0].full_frame);
  ASSERT_TRUE(f.obs[0].found) << f.obs[0].note;
  EXPECT_NEAR(f.obs[0].position.u_px, 605.0, kTolPx);
  EXPECT_EQ(f.obs[0].num_candidates, 2);
}

TEST(RobotTracker, MarkerLeavingTheImageIsLostAfterLostAfterS) {
  TrackerOptions options;
  options.lost_after_s = 0.5;
  RobotTracker tracker({Spec(1)}, EveryFrame(options), kWidthPx, kHeightPx);
  int64_t t = kStartUs;
  // Heading marker on the image's side: a marker beyond the edge is clipped.
  ASSERT_TRUE(Step(&tracker, t, Robot(1900, 500, kOrange, kGreen, -kHeadingOffsetPx)).obs[0].found);
  const int64_t last_seen = t;
  const int frames_until_lost = static_cast<int>(std::ceil(options.lost_after_s / kFramePeriodS));
  for (int k = 1; k < frames_until_lost; ++k) {
    t += kFramePeriodUs;
    const Frame f = Step(&tracker, t, {});
    EXPECT_FALSE(f.obs[0].found);
    ASSERT_EQ(f.obs[0].state, TrackState::kTracking) << "frame " << k;
    // After the first miss every search is full frame.
    EXPECT_EQ(f.plans[0].full_frame, k > 1) << "frame " << k;
  }
  t += kFramePeriodUs;
  ASSERT_GE((t - last_seen) * 1e-6, options.lost_after_s);
  const Frame lost = Step(&tracker, t, {});
  EXPECT_EQ(lost.obs[0].state, TrackState::kLost);
  EXPECT_STREQ(TrackStateName(lost.obs[0].state), "lost");
  EXPECT_TRUE(tracker.Plan(t + kFramePeriodUs)[0].full_frame);

  // It comes back: found from the full frame, tracking again.
  t += kFramePeriodUs;
  const Frame back = Step(&tracker, t, Robot(1800, 520));
  ASSERT_TRUE(back.obs[0].found);
  EXPECT_STREQ(TrackStateName(back.obs[0].state), "tracking");
}

TEST(RobotTracker, NeverFoundRobotStaysSearching) {
  RobotTracker tracker({Spec(1)}, TrackerOptions{}, kWidthPx, kHeightPx);
  const Frame f = Step(&tracker, kStartUs + 10'000'000, {});
  EXPECT_EQ(f.obs[0].state, TrackState::kSearching);
  EXPECT_STREQ(TrackStateName(f.obs[0].state), "searching");
  EXPECT_FALSE(f.obs[0].note.empty());
}

TEST(RobotTracker, PositionMarkerWithoutHeadingIsTrackedButNotAcceptedAtStartUp) {
  const std::vector<Blob> bare = {MakeBlob(kOrange, 700, 400)};
  {
    RobotTracker tracker({Spec(1)}, TrackerOptions{}, kWidthPx, kHeightPx);
    const Frame f = Step(&tracker, kStartUs, bare);
    EXPECT_FALSE(f.obs[0].found);
    EXPECT_EQ(f.obs[0].state, TrackState::kSearching);
    EXPECT_EQ(f.obs[0].num_candidates, 0);
    EXPECT_NE(f.obs[0].note.find("(700.0, 400.0)"), std::string::npos) << f.obs[0].note;
    EXPECT_NE(f.obs[0].note.find("not a robot"), std::string::npos) << f.obs[0].note;
  }
  {
    RobotTracker tracker({Spec(1)}, TrackerOptions{}, kWidthPx, kHeightPx);
    ASSERT_TRUE(Step(&tracker, kStartUs, Robot(700, 400)).obs[0].found);
    // The heading marker is covered: the position alone is still confirmed.
    const Frame f = Step(&tracker, kStartUs + kFramePeriodUs, bare);
    EXPECT_FALSE(f.plans[0].full_frame);
    ASSERT_TRUE(f.obs[0].found);
    EXPECT_FALSE(f.obs[0].has_heading);
    EXPECT_EQ(f.obs[0].state, TrackState::kTracking);
  }
}

TEST(RobotTracker, RobotsWithDifferentClassPairsAreTrackedIndependently) {
  RobotTracker tracker({Spec(1, kOrange, kGreen), Spec(2, kBlue, kPink)}, TrackerOptions{},
                       kWidthPx, kHeightPx);
  int64_t t = kStartUs;
  for (int k = 0; k < 20; ++k) {
    const double s = k * kFramePeriodS;
    const double u1 = 300 + 200 * s, v1 = 300;
    const double u2 = 1500 - 150 * s, v2 = 800 - 100 * s;
    // Robot 2 is covered for a few frames; robot 1 is unaffected.
    const bool hide2 = k >= 8 && k < 11;
    auto scene = Robot(u1, v1, kOrange, kGreen);
    if (!hide2) scene = Join(scene, Robot(u2, v2, kBlue, kPink, 0.0, -kHeadingOffsetPx));
    const Frame f = Step(&tracker, t, scene);
    ASSERT_EQ(f.obs.size(), 2u);
    EXPECT_EQ(f.obs[0].robot_id, 1);
    EXPECT_EQ(f.obs[1].robot_id, 2);
    ASSERT_TRUE(f.obs[0].found) << "frame " << k;
    EXPECT_NEAR(f.obs[0].position.u_px, u1, kTolPx);
    EXPECT_EQ(f.plans[0].full_frame, k == 0) << "frame " << k;
    EXPECT_EQ(f.obs[1].found, !hide2) << "frame " << k;
    if (!hide2) {
      EXPECT_NEAR(f.obs[1].position.u_px, u2, kTolPx);
      EXPECT_EQ(f.obs[1].position.class_index, kBlue);
      EXPECT_NEAR(f.obs[1].image_angle_rad, -M_PI / 2, kTolRad);
    }
    EXPECT_NEAR(f.obs[0].image_angle_rad, 0.0, kTolRad);
    t += kFramePeriodUs;
  }
}

TEST(RobotTracker, TwoLookalikeRobotsWithTwoCandidatesAreAmbiguousAtStartUp) {
  RobotTracker tracker({Spec(1), Spec(2)}, TrackerOptions{}, kWidthPx, kHeightPx);
  const Frame f = Step(&tracker, kStartUs, Join(Robot(400, 400), Robot(1400, 600)));
  for (const auto& o : f.obs) {
    EXPECT_FALSE(o.found);
    EXPECT_EQ(o.state, TrackState::kAmbiguous);
    EXPECT_EQ(o.num_candidates, 2);
    EXPECT_NE(o.note.find("share marker classes"), std::string::npos) << o.note;
  }
}

TEST(RobotTracker, LookalikeRobotsNeverTakeTheSameBlob) {
  RobotTracker tracker({Spec(1), Spec(2)}, EveryFrame(), kWidthPx, kHeightPx);
  // Robot 1 alone at first (look-alikes enter in spec order), then robot 2
  // drives in.
  int64_t t = kStartUs;
  const Frame first = Step(&tracker, t, Robot(400, 400));
  ASSERT_TRUE(first.obs[0].found);
  EXPECT_FALSE(first.obs[1].found);
  EXPECT_EQ(first.obs[1].state, TrackState::kSearching);
  t += kFramePeriodUs;
  const Frame f = Step(&tracker, t, Join(Robot(405, 400), Robot(1400, 600)));
  ASSERT_TRUE(f.obs[0].found);
  ASSERT_TRUE(f.obs[1].found) << f.obs[1].note;
  EXPECT_NEAR(f.obs[0].position.u_px, 405.0, kTolPx);
  EXPECT_NEAR(f.obs[1].position.u_px, 1400.0, kTolPx);
  // Both now tracked in windows; they pass close: each keeps the blob
  // nearest its own prediction, never both the same one.
  t += kFramePeriodUs;
  const Frame g = Step(&tracker, t, Join(Robot(410, 400), Robot(1395, 600)));
  ASSERT_TRUE(g.obs[0].found && g.obs[1].found);
  EXPECT_NE(g.obs[0].position.u_px, g.obs[1].position.u_px);
}

TEST(RobotTracker, SharedBlobGoesToTheRobotWhosePredictionIsNearest) {
  RobotTracker tracker({Spec(1), Spec(2)}, EveryFrame(), kWidthPx, kHeightPx);
  constexpr double kU1 = 400.0, kU2 = 470.0, kV = 400.0;  // windows overlap
  int64_t t = kStartUs;
  ASSERT_TRUE(
      Step(&tracker, t, Robot(kU1, kV, kOrange, kGreen, 0.0, kHeadingOffsetPx)).obs[0].found);
  t += kFramePeriodUs;
  const Frame both = Step(&tracker, t,
                          Join(Robot(kU1, kV, kOrange, kGreen, 0.0, kHeadingOffsetPx),
                               Robot(kU2, kV, kOrange, kGreen, 0.0, kHeadingOffsetPx)));
  ASSERT_TRUE(both.obs[0].found && both.obs[1].found) << both.obs[1].note;
  EXPECT_NEAR(both.obs[1].position.u_px, kU2, kTolPx);

  // Robot 1 is covered; the one blob left lies in both windows, nearer
  // robot 2's prediction: robot 2 takes it and robot 1 misses.
  t += kFramePeriodUs;
  const Frame one = Step(&tracker, t, Robot(kU2 - 5.0, kV, kOrange, kGreen, 0.0, kHeadingOffsetPx));
  ASSERT_FALSE(one.plans[0].full_frame);
  ASSERT_FALSE(one.plans[1].full_frame);
  EXPECT_EQ(one.obs[0].num_candidates, 1);
  EXPECT_FALSE(one.obs[0].found);
  ASSERT_TRUE(one.obs[1].found);
  EXPECT_NEAR(one.obs[1].position.u_px, kU2 - 5.0, kTolPx);
}

TEST(RobotTracker, HeadingAngleInAllFourQuadrants) {
  constexpr double kD = 30.0;
  struct Case {
    double du, dv, expected_rad;
  };
  // v points down the image, so atan2(dv, du) turns clockwise on screen.
  const Case cases[] = {
      {kD, kD, M_PI / 4},   {-kD, kD, 3 * M_PI / 4}, {-kD, -kD, -3 * M_PI / 4},
      {kD, -kD, -M_PI / 4}, {kD, 0.0, 0.0},          {0.0, kD, M_PI / 2},
  };
  for (const Case& c : cases) {
    RobotTracker tracker({Spec(1)}, TrackerOptions{}, kWidthPx, kHeightPx);
    const Frame f = Step(&tracker, kStartUs, Robot(900, 500, kOrange, kGreen, c.du, c.dv));
    ASSERT_TRUE(f.obs[0].found);
    ASSERT_TRUE(f.obs[0].has_heading);
    EXPECT_NEAR(f.obs[0].image_angle_rad, c.expected_rad, kTolRad) << c.du << ", " << c.dv;
  }
}

TEST(RobotTracker, HeadingMarkerFartherThanTheSearchRadiusIsNotPaired) {
  TrackerOptions options;
  RobotTracker tracker({Spec(1)}, options, kWidthPx, kHeightPx);
  const double far = options.heading_search_radii * kRadiusPx + 5.0;
  const Frame f = Step(&tracker, kStartUs, Robot(900, 500, kOrange, kGreen, far, 0.0));
  EXPECT_FALSE(f.obs[0].found);
  EXPECT_EQ(f.obs[0].num_candidates, 0);
}

// --- Identification by marker code (ordered colour pairs, roles by size) ---
// absent_search_period_frames: a robot out of view costs a full-frame search
// only every N frames; one that enters whole is found within N frames
// whatever the phase; one tracked and missed is searched in full at once.
TEST(AbsentSearch, ARobotEnteringTheViewIsAcquiredWithinThePeriod) {
  constexpr int kPeriod = 4;
  for (int enter = 0; enter < 3 * kPeriod; ++enter) {
    TrackerOptions options;
    options.absent_search_period_frames = kPeriod;
    RobotTracker tracker({Spec(1)}, options, kWidthPx, kHeightPx);
    int full_searches = 0, found_at = -1;
    for (int k = 0; k < enter + 2 * kPeriod && found_at < 0; ++k) {
      const Frame f = Step(&tracker, kStartUs + k * kFramePeriodUs,
                           k >= enter ? Robot(900, 500) : std::vector<Blob>{});
      full_searches += f.plans[0].full_frame ? 1 : 0;
      if (f.obs[0].found) found_at = k;
    }
    ASSERT_GE(found_at, enter);
    EXPECT_LE(found_at - enter, kPeriod - 1) << "entered at frame " << enter;
    // Out of view, one frame in kPeriod was searched in full.
    EXPECT_LE(full_searches, enter / kPeriod + 2) << "entered at frame " << enter;
  }
}

TEST(AbsentSearch, ATrackedRobotThatMissesItsWindowGetsAFullSearchAtOnce) {
  TrackerOptions options;
  options.absent_search_period_frames = 8;
  RobotTracker tracker({Spec(1)}, options, kWidthPx, kHeightPx);
  int64_t t = kStartUs;
  ASSERT_TRUE(Step(&tracker, t, Robot(900, 500)).obs[0].found);
  t += kFramePeriodUs;
  // Hidden for a frame: the window misses...
  const Frame miss = Step(&tracker, t, {});
  EXPECT_FALSE(miss.plans[0].full_frame);
  EXPECT_FALSE(miss.obs[0].found);
  t += kFramePeriodUs;
  // ... and the next frame is searched in full, where it is found far away.
  const Frame back = Step(&tracker, t, Robot(1500, 300));
  EXPECT_TRUE(back.plans[0].full_frame);
  EXPECT_TRUE(back.obs[0].found);
}

TEST(AbsentSearch, OneRobotsFullSearchServesTheRobotsOutOfView) {
  TrackerOptions options;
  options.absent_search_period_frames = 100;
  RobotTracker tracker({Spec(1), Spec(2, kBlue, kPink)}, options, kWidthPx, kHeightPx);
  int64_t t = kStartUs;
  ASSERT_TRUE(Step(&tracker, t, Robot(900, 500)).obs[0].found);
  t += kFramePeriodUs;
  ASSERT_FALSE(Step(&tracker, t, {}).obs[0].found);  // robot 1's window misses
  t += kFramePeriodUs;
  // Robot 1's full-frame search finds robot 2, which entered meanwhile.
  const Frame f = Step(&tracker, t, Join(Robot(900, 505), Robot(300, 300, kBlue, kPink)));
  EXPECT_TRUE(f.plans[1].full_frame);
  EXPECT_TRUE(f.obs[1].found) << f.obs[1].note;
}

TEST(AbsentSearch, AnOutOfViewRobotIsNeverIdentifiedFromWindowsAlone) {
  // Marker code: robot 2 has never been seen; robot 1's window shows a pair
  // with robot 2's code. Unique in the window is not unique in the frame:
  // robot 2 is taken only at the full-frame search this asks for.
  TrackerOptions options;
  options.identify_by_code = true;
  options.heading_offset_radii = 2.0;
  options.heading_size_ratio = 0.5;
  options.absent_search_period_frames = 100;
  RobotTracker tracker({Spec(1, kOrange, kGreen), Spec(2, kBlue, kPink)}, options, kWidthPx,
                       kHeightPx);
  auto robot = [](int p, int h, double u, double v) {
    return std::vector<Blob>{MakeBlob(p, u, v, 15.0), MakeBlob(h, u + 30.0, v, 7.5)};
  };
  int64_t t = kStartUs;
  ASSERT_TRUE(Step(&tracker, t, robot(kOrange, kGreen, 900, 500)).obs[0].found);
  t += kFramePeriodUs;
  const std::vector<Blob> both =
      Join(robot(kOrange, kGreen, 902, 500), robot(kBlue, kPink, 900, 560));
  const Frame f = Step(&tracker, t, both);
  ASSERT_FALSE(f.plans[0].full_frame);
  EXPECT_TRUE(f.obs[0].found);
  EXPECT_FALSE(f.obs[1].found) << "identified from a window";
  t += kFramePeriodUs;
  const Frame g = Step(&tracker, t, both);
  EXPECT_TRUE(g.plans[1].full_frame);
  EXPECT_TRUE(g.obs[1].found) << g.obs[1].note;
}

TEST(TooManyBlobs, AFrameOfFiveThousandSpecksIdentifiesNoRobotAndDoesNoPairing) {
  TrackerOptions options;
  options.identify_by_code = true;
  options.heading_offset_radii = 2.0;
  options.heading_size_ratio = 0.5;
  RobotTracker tracker({Spec(1, kOrange, kGreen), Spec(2, kBlue, kPink)}, options, kWidthPx,
                       kHeightPx);
  // 5000 coloured dots on a grid, radius 3 px, every class, plus robot 1.
  std::vector<Blob> scene = {MakeBlob(kOrange, 900, 500, 15.0), MakeBlob(kGreen, 930, 500, 7.5)};
  for (int k = 0; k < 5000; ++k) {
    scene.push_back(MakeBlob(k % 4, 10 + 19 * (k % 100), 20 + 19 * (k / 100), 3.0));
  }
  const Frame f = Step(&tracker, kStartUs, scene);
  EXPECT_FALSE(f.obs[0].found);
  EXPECT_EQ(f.obs[0].identity_problem, "too_many_blobs");
  EXPECT_EQ(tracker.last_pairing_checks(), 0);
}

TEST(TooManyBlobs, PairingWorkGrowsLinearlyWithTheSpecksUnderTheCap) {
  TrackerOptions options;
  options.identify_by_code = true;
  options.heading_offset_radii = 2.0;
  options.heading_size_ratio = 0.5;
  // Specks of one size spread over the frame: with 500 of them a sweep
  // compares each with the few in its band of u, where all against all
  // would be 500 x 499.
  for (const int specks : {100, 500}) {
    RobotTracker tracker({Spec(1, kOrange, kGreen)}, options, kWidthPx, kHeightPx);
    std::vector<Blob> scene = {MakeBlob(kOrange, 900, 500, 15.0), MakeBlob(kGreen, 930, 500, 7.5)};
    for (int k = 0; k < specks; ++k) {
      scene.push_back(MakeBlob(kBlue + k % 2, 10 + (1900.0 * k) / specks, 20 + 37 * (k % 28), 3.0));
    }
    const Frame f = Step(&tracker, kStartUs, scene);
    EXPECT_TRUE(f.obs[0].found) << f.obs[0].note;
    // Each speck's band is 2.9 x 3 px either side: a handful of specks.
    EXPECT_LE(tracker.last_pairing_checks(), 10 * static_cast<int64_t>(scene.size()))
        << specks << " specks";
  }
}

namespace code {

// Four colours; every class may be either marker.
constexpr int kRed = 0;
constexpr int kYellow = 1;
constexpr int kGreen = 2;
constexpr int kBlue = 3;
// Position markers 15 px in radius, heading markers half that, 30 px apart
// (the site's 12 cm / 6 cm / 12 cm at 250 px per metre).
constexpr double kPosRadiusPx = 15.0;
constexpr double kHeadRadiusPx = 7.5;
constexpr double kOffsetPx = 30.0;
// Two robots' centres 0.35 m apart at 250 px/m: the closest the 0.30 m
// bodies pass in the eight-robot site.
constexpr double kCloseBodiesPx = 87.5;

TrackerOptions CodeOptions() {
  TrackerOptions o;
  o.identify_by_code = true;
  o.heading_offset_radii = kOffsetPx / kPosRadiusPx;
  o.heading_size_ratio = kHeadRadiusPx / kPosRadiusPx;
  return o;
}

// Robot `id`'s markers at (u, v) heading `angle_rad` in the image.
std::vector<Blob> Coded(int position_class, int heading_class, double u, double v,
                        double angle_rad) {
  return {MakeBlob(position_class, u, v, kPosRadiusPx),
          MakeBlob(heading_class, u + kOffsetPx * std::cos(angle_rad),
                   v + kOffsetPx * std::sin(angle_rad), kHeadRadiusPx)};
}

std::vector<TrackedRobotSpec> SwappedPairRobots() {
  return {Spec(1, kRed, kGreen), Spec(2, kGreen, kRed), Spec(3, kYellow, kBlue),
          Spec(4, kBlue, kYellow)};
}

TEST(RobotTrackerCode, TellsSwappedColourPairsApartByTheMarkersSizes) {
  RobotTracker tracker(SwappedPairRobots(), CodeOptions(), kWidthPx, kHeightPx);
  // Robot 1 (red big, green small) and robot 2 (green big, red small) side
  // by side 0.35 m apart, headings towards each other: each one's small
  // marker is nearest the other's big marker of the same colour.
  const std::vector<Blob> scene = Join(Coded(kRed, kGreen, 800, 500, 0.0),
                                       Coded(kGreen, kRed, 800 + kCloseBodiesPx, 500, M_PI));
  const Frame f = Step(&tracker, kStartUs, scene);
  ASSERT_TRUE(f.obs[0].found);
  ASSERT_TRUE(f.obs[1].found);
  EXPECT_NEAR(f.obs[0].position.u_px, 800.0, kTolPx);
  EXPECT_NEAR(f.obs[1].position.u_px, 800.0 + kCloseBodiesPx, kTolPx);
  EXPECT_TRUE(f.obs[0].has_heading);
  EXPECT_NEAR(f.obs[0].image_angle_rad, 0.0, kTolRad);
  EXPECT_NEAR(std::abs(f.obs[1].image_angle_rad), M_PI, kTolRad);
  EXPECT_TRUE(f.obs[0].identity_problem.empty()) << f.obs[0].identity_problem;
  EXPECT_FALSE(f.obs[2].found);  // not in view
  EXPECT_EQ(f.obs[2].state, TrackState::kSearching);
}

TEST(RobotTrackerCode, TracksEightRobotsInARingCloseTogetherFrameAfterFrame) {
  std::vector<TrackedRobotSpec> specs;
  const int colours[4] = {kRed, kYellow, kGreen, kBlue};
  for (int k = 0; k < 8; ++k) {
    specs.push_back(Spec(k + 1, colours[k % 4], colours[(k + 1 + k / 4) % 4]));
  }
  RobotTracker tracker(specs, CodeOptions(), kWidthPx, kHeightPx);
  // Eight robots on a ring whose neighbours are 0.35 m apart, turning at
  // 0.5 rad/s, headings tangential.
  const double ring_px = kCloseBodiesPx / (2.0 * std::sin(M_PI / 8.0));
  int wrong = 0, found = 0;
  for (int f = 0; f < 60; ++f) {
    const double t = f * kFramePeriodS;
    std::vector<Blob> scene;
    for (int k = 0; k < 8; ++k) {
      const double a = 0.5 * t + k * M_PI / 4.0;
      scene = Join(
          scene, Coded(specs[k].position_class, specs[k].heading_class, 960 + ring_px * std::cos(a),
                       540 + ring_px * std::sin(a), a + M_PI / 2.0));
    }
    const Frame fr = Step(&tracker, kStartUs + f * kFramePeriodUs, scene);
    for (int k = 0; k < 8; ++k) {
      if (!fr.obs[k].found) continue;
      ++found;
      const double a = 0.5 * t + k * M_PI / 4.0;
      if (std::hypot(fr.obs[k].position.u_px - (960 + ring_px * std::cos(a)),
                     fr.obs[k].position.v_px - (540 + ring_px * std::sin(a))) > 1.0) {
        ++wrong;
      }
    }
  }
  EXPECT_EQ(found, 8 * 60);
  EXPECT_EQ(wrong, 0);
}

TEST(RobotTrackerCode, ACodeSeenTwiceIsNotPublishedBeforeTheFirstFind) {
  RobotTracker tracker(SwappedPairRobots(), CodeOptions(), kWidthPx, kHeightPx);
  // Robot 3's code twice (a look-alike on the floor): neither is taken.
  const std::vector<Blob> scene =
      Join(Coded(kYellow, kBlue, 400, 300, 0.0), Coded(kYellow, kBlue, 1400, 700, 1.0));
  const Frame f = Step(&tracker, kStartUs, scene);
  EXPECT_FALSE(f.obs[2].found);
  EXPECT_EQ(f.obs[2].state, TrackState::kAmbiguous);
  EXPECT_EQ(f.obs[2].identity_problem, "code_seen_twice");
  EXPECT_EQ(f.obs[2].num_candidates, 2);
}

TEST(RobotTrackerCode, ALookAlikeOutsideTheGateLeavesTheTrackedRobotDegraded) {
  RobotTracker tracker(SwappedPairRobots(), CodeOptions(), kWidthPx, kHeightPx);
  ASSERT_TRUE(Step(&tracker, kStartUs, Coded(kYellow, kBlue, 400, 300, 0.0)).obs[2].found);
  // Next frame a second copy of robot 3's code far away, handed in with
  // the window's blobs: the one inside the gate is taken, without its
  // heading (status degraded), and the doubt is counted.
  const std::vector<Blob> scene =
      Join(Coded(kYellow, kBlue, 402, 300, 0.0), Coded(kYellow, kBlue, 1400, 700, 1.0));
  const Frame f = Step(&tracker, kStartUs + kFramePeriodUs, scene, /*leak_into_windows=*/true);
  ASSERT_TRUE(f.obs[2].found);
  EXPECT_NEAR(f.obs[2].position.u_px, 402.0, kTolPx);
  EXPECT_FALSE(f.obs[2].has_heading);
  EXPECT_EQ(f.obs[2].identity_problem, "code_seen_twice");
}

TEST(RobotTrackerCode, AnIdentitySwapThatWouldBeAnImpossibleJumpIsNotPublished) {
  RobotTracker tracker(SwappedPairRobots(), CodeOptions(), kWidthPx, kHeightPx);
  ASSERT_TRUE(Step(&tracker, kStartUs, Coded(kRed, kGreen, 400, 300, 0.0)).obs[0].found);
  // One frame later robot 1's code shows 800 px away (its markers misread
  // elsewhere) and not where it was: at 600 px/s it cannot have gone there.
  const Frame f = Step(&tracker, kStartUs + kFramePeriodUs, Coded(kRed, kGreen, 1200, 300, 0.0),
                       /*leak_into_windows=*/true);
  EXPECT_FALSE(f.obs[0].found);
  EXPECT_EQ(f.obs[0].identity_problem, "impossible_jump");
  EXPECT_EQ(f.obs[0].state, TrackState::kTracking);  // not lost yet
  // Once the track is lost (0.5 s), the code is taken where it is.
  Frame later;
  for (int k = 2; k <= 20; ++k) {
    later = Step(&tracker, kStartUs + k * kFramePeriodUs, Coded(kRed, kGreen, 1200, 300, 0.0));
  }
  EXPECT_TRUE(later.obs[0].found);
  EXPECT_NEAR(later.obs[0].position.u_px, 1200.0, kTolPx);
}

TEST(RobotTrackerCode, InterleavedMarkersOfTwoRobotsAreNotPublished) {
  RobotTracker tracker(SwappedPairRobots(), CodeOptions(), kWidthPx, kHeightPx);
  // Robot 1's big red marker with a small green blob on either side at the
  // code's distance: two pairs with its code share the red blob.
  std::vector<Blob> scene = Coded(kRed, kGreen, 800, 500, 0.0);
  scene.push_back(MakeBlob(kGreen, 800 - kOffsetPx, 500, kHeadRadiusPx));
  const Frame f = Step(&tracker, kStartUs, scene);
  EXPECT_FALSE(f.obs[0].found);
  EXPECT_EQ(f.obs[0].state, TrackState::kAmbiguous);
  EXPECT_EQ(f.obs[0].identity_problem, "interleaved_markers");

  // Robot 1's small green marker also lies at the code's distance from a
  // big blue one, and blue/green is robot 7's code: the green blob would
  // serve two robots, so neither is published.
  RobotTracker seven({Spec(1, kRed, kGreen), Spec(7, kBlue, kGreen)}, CodeOptions(), kWidthPx,
                     kHeightPx);
  std::vector<Blob> shared = Coded(kRed, kGreen, 800, 500, 0.0);
  shared.push_back(MakeBlob(kBlue, 800 + 2 * kOffsetPx, 500, kPosRadiusPx));
  const Frame g = Step(&seven, kStartUs, shared);
  EXPECT_FALSE(g.obs[0].found);
  EXPECT_FALSE(g.obs[1].found);
  EXPECT_EQ(g.obs[0].identity_problem, "interleaved_markers");
  EXPECT_EQ(g.obs[1].identity_problem, "interleaved_markers");
}

TEST(RobotTrackerCode, ALonePositionMarkerInsideTheGateIsTakenWithoutHeading) {
  RobotTracker tracker(SwappedPairRobots(), CodeOptions(), kWidthPx, kHeightPx);
  ASSERT_TRUE(Step(&tracker, kStartUs, Coded(kBlue, kYellow, 600, 600, 0.0)).obs[3].found);
  // The heading marker is hidden: the big blue blob near where robot 4 was
  // is taken, status degraded. A small blue blob (another robot's heading
  // marker size) would not be.
  const Frame f =
      Step(&tracker, kStartUs + kFramePeriodUs, {MakeBlob(kBlue, 603, 600, kPosRadiusPx)});
  ASSERT_TRUE(f.obs[3].found);
  EXPECT_FALSE(f.obs[3].has_heading);
  EXPECT_TRUE(f.obs[3].identity_problem.empty());
  const Frame g =
      Step(&tracker, kStartUs + 2 * kFramePeriodUs, {MakeBlob(kBlue, 606, 600, kHeadRadiusPx)});
  EXPECT_FALSE(g.obs[3].found);
}

TEST(RobotTrackerCode, AMarkerCutByAWindowEdgeIsOneMarkerNotTwo) {
  RobotTracker tracker(SwappedPairRobots(), CodeOptions(), kWidthPx, kHeightPx);
  // Robot 3's heading marker measured whole (full frame) and, cut by a
  // neighbour's window edge, as a smaller blob 3 px off: were they two
  // blobs, two pairs would share robot 3's position marker.
  std::vector<Blob> scene = Coded(kYellow, kBlue, 700, 350, 0.0);
  scene.push_back(MakeBlob(kBlue, 700 + kOffsetPx - 3.0, 350, 5.5));
  const Frame f = Step(&tracker, kStartUs, scene);
  ASSERT_TRUE(f.obs[2].found);
  EXPECT_TRUE(f.obs[2].has_heading);
  EXPECT_NEAR(f.obs[2].heading.u_px, 700 + kOffsetPx, kTolPx);  // the whole one
  EXPECT_TRUE(f.obs[2].identity_problem.empty()) << f.obs[2].identity_problem;
}

// The hall's incident: robot 3 (yellow big, blue small) enters at the image's
// left edge with its yellow marker cut to a sliver. The sliver measures
// smaller than the blue marker and two blue radii from it: as blobs, the
// pair reads blue-big, yellow-small, robot 4's code.
std::vector<Blob> CutAtTheLeftEdge() {
  const double sliver_u = 3.0, sliver_radius = 0.6 * kHeadRadiusPx;
  return {MakeBlob(kYellow, sliver_u, 400, sliver_radius),
          MakeBlob(kBlue, sliver_u + 2.0 * kHeadRadiusPx, 400, kHeadRadiusPx)};
}

TEST(RobotTrackerCode, AMarkerCutByTheImageEdgeNeverNamesItsSwapPartner) {
  RobotTracker tracker(SwappedPairRobots(), CodeOptions(), kWidthPx, kHeightPx);
  const Frame f = Step(&tracker, kStartUs, CutAtTheLeftEdge());
  EXPECT_FALSE(f.obs[3].found) << "robot 4 read from robot 3's cut marker";
  EXPECT_EQ(f.obs[3].identity_problem, "marker_clipped");
  EXPECT_FALSE(f.obs[2].found);
  // Without the clip rule the same blobs are robot 4 with a heading: the
  // scene is the failure it guards against, not a harmless one.
  TrackerOptions unguarded = CodeOptions();
  unguarded.refuse_clipped = false;
  RobotTracker old_rule(SwappedPairRobots(), unguarded, kWidthPx, kHeightPx);
  const Frame g = Step(&old_rule, kStartUs, CutAtTheLeftEdge());
  EXPECT_TRUE(g.obs[3].found && g.obs[3].has_heading) << g.obs[3].note;
}

TEST(RobotTrackerCode, ARobotLeavingTheImageIsNotPublishedOnceAMarkerTouchesTheEdge) {
  RobotTracker tracker(SwappedPairRobots(), CodeOptions(), kWidthPx, kHeightPx);
  // Robot 3 drives left, heading marker trailing on the image's side; from
  // the frame its position marker's disc (1.1 radii and 2 px) reaches the
  // edge it is not published, neither as itself nor as robot 4.
  int published = 0, withheld = 0;
  for (int k = 0; k < 40; ++k) {
    const double u = 60.0 - 2.0 * k;
    const Frame f =
        Step(&tracker, kStartUs + k * kFramePeriodUs, Coded(kYellow, kBlue, u, 400, 0.0));
    EXPECT_FALSE(f.obs[3].found) << "frame " << k;
    const bool reaches = u - 1.1 * kPosRadiusPx - 2.0 < -0.5;
    if (f.obs[2].found) {
      ++published;
      EXPECT_FALSE(reaches) << "frame " << k << " u " << u;
    } else {
      ++withheld;
      EXPECT_TRUE(reaches) << "frame " << k << " u " << u << ": " << f.obs[2].note;
    }
  }
  EXPECT_GT(published, 0);
  EXPECT_GT(withheld, 0);
}

}  // namespace code

TEST(RobotTrackerClasses, AClippedPositionMarkerIsNotFoundAndSaysWhy) {
  RobotTracker tracker({Spec(1)}, EveryFrame(), kWidthPx, kHeightPx);
  // Position marker cut by the top edge, heading marker inside.
  const Frame f = Step(&tracker, kStartUs, Robot(600, 5, kOrange, kGreen, 0.0, kHeadingOffsetPx));
  EXPECT_FALSE(f.obs[0].found);
  EXPECT_EQ(f.obs[0].identity_problem, "marker_clipped");
  // Whole, a frame later: found.
  const Frame g = Step(&tracker, kStartUs + kFramePeriodUs,
                       Robot(600, 30, kOrange, kGreen, 0.0, kHeadingOffsetPx));
  EXPECT_TRUE(g.obs[0].found) << g.obs[0].note;
  EXPECT_TRUE(g.obs[0].identity_problem.empty());
}

TEST(TrackerOptions, IsValidNamesTheBadField) {
  std::string error;
  EXPECT_TRUE(TrackerOptions{}.IsValid(&error)) << error;
  TrackerOptions o;
  o.clip_radius_factor = 0.9;
  EXPECT_FALSE(o.IsValid(&error));
  EXPECT_NE(error.find("clip_radius_factor"), std::string::npos) << error;
  o = TrackerOptions{};
  o.lost_after_s = 0.0;
  EXPECT_FALSE(o.IsValid(&error));
  EXPECT_NE(error.find("lost_after_s"), std::string::npos) << error;
}

TEST(TrackerOptions, RefusesNonPositiveSizesAndTimesAndATolerancePastOne) {
  std::string error;
  EXPECT_TRUE(TrackerOptions{}.IsValid(&error)) << error;
  TrackerOptions o;
  o.lost_after_s = 0.0;
  EXPECT_FALSE(o.IsValid(&error));
  EXPECT_NE(error.find("lost_after_s"), std::string::npos) << error;
  o = TrackerOptions{};
  o.max_speed_px_per_s = std::numeric_limits<double>::infinity();
  EXPECT_FALSE(o.IsValid(&error));
  o = TrackerOptions{};
  o.window_margin_px = -1.0;
  EXPECT_FALSE(o.IsValid(&error));
  o = TrackerOptions{};
  o.heading_offset_tolerance = 1.0;
  EXPECT_FALSE(o.IsValid(&error));
}

}  // namespace
}  // namespace roomfix::vision
