#include "core/world/acoustic_paths.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>

#include "core/world/ultrasound_model.h"
#include "tests/testing/test_paths.h"

namespace roomfix {
namespace {

// Lengths are sums of a few square roots of metre-sized numbers: double
// rounding leaves ~1e-15 m; a nanometre bounds it with room to spare.
constexpr double kLengthTolerance_m = 1e-9;
// dB figures are logarithms of those lengths plus products: the same.
constexpr double kLevelTolerance_db = 1e-9;

// A 4 x 3 x 3.3 m room with three receivers, as text, followed by `extra`.
Site RoomWith(const std::string& extra) {
  const std::string text =
      "name: t\n"
      "room: {size_m: [4, 3], height_m: 3.3}\n"
      "receivers:\n"
      "  - {id: 1, address: '0x0000000000000001', position_m: [4, 1.5, 1.3]}\n"
      "  - {id: 2, address: '0x0000000000000002', position_m: [0, 0, 2.5]}\n"
      "  - {id: 3, address: '0x0000000000000003', position_m: [0, 3, 2.5]}\n" +
      extra;
  Site site;
  std::string error;
  EXPECT_TRUE(ParseSite(text, "t.yaml", ".", &site, &error)) << error;
  return site;
}

TEST(AcousticPaths, AnOpenRoomGivesTheDirectPathWithSpreadingAndAirLoss) {
  const Site site = RoomWith("");
  const AcousticScene scene(site, 20.0);
  const AudiblePath p = scene.ShortestAudiblePath(0.0, {1.0, 1.5, 1.3}, {4.0, 1.5, 1.3});
  EXPECT_EQ(p.kind, AudiblePath::Kind::kDirect);
  EXPECT_NEAR(p.length_m, 3.0, kLengthTolerance_m);
  EXPECT_NEAR(p.direct_m, 3.0, kLengthTolerance_m);
  const double alpha = scene.decay().air_absorption_db_per_m;
  EXPECT_NEAR(p.loss_db, 20.0 * std::log10(3.0) + 3.0 * alpha, kLevelTolerance_db);
  // The threshold sits the site's margin (10 dB) below the weakest direct
  // arrival in the room, so a 3 m direct path is well above it.
  EXPECT_GT(p.level_db, 10.0);
  EXPECT_NEAR(p.level_db, scene.decay().level_at_1m_db - p.loss_db, kLevelTolerance_db);
}

// Beacon (1, 1.5, 1.3), receiver on the far wall at (4, 1.5, 1.3), a
// floor-to-ceiling pillar of radius 0.25 m at (2.5, 1.5) in between. The
// floor, the ceiling and the wall behind the beacon reflect along the same
// plan line, through the pillar; the wall behind the receiver holds the
// receiver. The side walls y = 0 and y = 3 reflect round it: image source
// (1, -1.5, 1.3), length sqrt(3^2 + 3^2).
TEST(AcousticPaths, APillarOnTheLineLeavesTheShortestWallEchoRoundIt) {
  const Site site = RoomWith(
      "obstacles:\n  - {type: cylinder, centre_m: [2.5, 1.5], radius_m: 0.25, top_m: 3.3}\n");
  const AudiblePath p = ShortestAudiblePath(site, {1.0, 1.5, 1.3}, {4.0, 1.5, 1.3});
  EXPECT_EQ(p.kind, AudiblePath::Kind::kReflected);
  EXPECT_EQ(p.mirror, AudiblePath::Mirror::kWall);
  EXPECT_EQ(p.obstacle_index, -1);
  EXPECT_NEAR(p.length_m, std::sqrt(18.0), kLengthTolerance_m);
  EXPECT_NEAR(p.length_m - p.direct_m, std::sqrt(18.0) - 3.0, kLengthTolerance_m);
  EXPECT_NEAR(p.reflection_point_m[0], 2.5, kLengthTolerance_m);
  EXPECT_NEAR(std::abs(p.reflection_point_m[1] - 1.5), 1.5, kLengthTolerance_m);
  EXPECT_NEAR(p.reflection_point_m[2], 1.3, kLengthTolerance_m);
  // One reflection costs -10 log10(1 - 0.1) dB on top of the longer path.
  const AcousticScene scene(site, 20.0);
  const double expected_loss = 20.0 * std::log10(p.length_m) +
                               scene.decay().air_absorption_db_per_m * p.length_m -
                               10.0 * std::log10(0.9);
  EXPECT_NEAR(p.loss_db, expected_loss, kLevelTolerance_db);
  EXPECT_GT(p.level_db, 0.0);
}

TEST(AcousticPaths, APillarLowerThanThePathDoesNotBlockIt) {
  const Site low = RoomWith(
      "obstacles:\n  - {type: cylinder, centre_m: [2.5, 1.5], radius_m: 0.25, top_m: 1.2}\n");
  EXPECT_EQ(ShortestAudiblePath(low, {1.0, 1.5, 1.3}, {4.0, 1.5, 1.3}).kind,
            AudiblePath::Kind::kDirect);
  // A table top (bottom 0.7 m) above a path at 0.5 m leaves it open too.
  const Site table = RoomWith(
      "obstacles:\n  - {type: box, centre_m: [2.5, 1.5], size_m: [1.2, 0.8], bottom_m: 0.7,"
      " top_m: 0.75}\n");
  EXPECT_EQ(ShortestAudiblePath(table, {1.0, 1.5, 0.5}, {3.5, 1.5, 0.5}).kind,
            AudiblePath::Kind::kDirect);
}

// A cupboard's front (the face y = 1.6 of a box centred at (2, 1.8), 2 m wide
// and 0.4 m deep) behind a thin pillar: the face is the nearest mirror.
// Image source (1, 2.2, 1.3), length sqrt(2^2 + 1.2^2); the wall y = 0 would
// give sqrt(2^2 + 2^2).
TEST(AcousticPaths, ABoxFaceIsAMirror) {
  const Site site = RoomWith(
      "obstacles:\n"
      "  - {type: cylinder, centre_m: [2.0, 1.0], radius_m: 0.2, top_m: 3.3}\n"
      "  - {type: box, name: cupboard, centre_m: [2.0, 1.8], size_m: [2.0, 0.4], top_m: 2.0}\n");
  const AudiblePath p = ShortestAudiblePath(site, {1.0, 1.0, 1.3}, {3.0, 1.0, 1.3});
  EXPECT_EQ(p.kind, AudiblePath::Kind::kReflected);
  EXPECT_EQ(p.mirror, AudiblePath::Mirror::kObstacleFace);
  EXPECT_EQ(p.obstacle_index, 1);
  EXPECT_NEAR(p.length_m, std::sqrt(4.0 + 1.44), kLengthTolerance_m);
  EXPECT_NEAR(p.reflection_point_m[1], 1.6, kLengthTolerance_m);
}

TEST(AcousticPaths, AWallAcrossTheRoomLeavesNothingToHear) {
  // A partition from wall to wall and floor to ceiling: every path crosses
  // it, and its own faces face one side each.
  const Site site = RoomWith(
      "obstacles:\n  - {type: box, centre_m: [2.0, 1.5], size_m: [0.1, 3.2], top_m: 3.3}\n");
  const AudiblePath p = ShortestAudiblePath(site, {1.0, 1.5, 1.3}, {4.0, 1.5, 1.3});
  EXPECT_EQ(p.kind, AudiblePath::Kind::kNone);
  EXPECT_TRUE(std::isinf(p.loss_db));
}

TEST(AcousticPaths, AnEchoBelowTheThresholdIsNotHeard) {
  // With no margin the threshold is the weakest direct arrival in the room:
  // the 4.24 m echo of the pillar case is then still above it, but the
  // surfaces absorbing 99 % (20 dB per reflection) put it below.
  const Site site = RoomWith(
      "acoustics: {wall_absorption: 0.99, detection_margin_db: 0}\n"
      "obstacles:\n  - {type: cylinder, centre_m: [2.5, 1.5], radius_m: 0.25, top_m: 3.3}\n");
  EXPECT_EQ(ShortestAudiblePath(site, {1.0, 1.5, 1.3}, {4.0, 1.5, 1.3}).kind,
            AudiblePath::Kind::kNone);
}

TEST(AcousticPaths, ALegEndingOnAFaceOrGrazingAnEdgeIsNotBlocked) {
  const Site site = RoomWith(
      "obstacles:\n  - {type: box, centre_m: [2.0, 1.5], size_m: [1.0, 1.0], top_m: 1.0}\n");
  const AcousticScene scene(site, 20.0);
  EXPECT_FALSE(scene.Blocked(0.0, {0.5, 1.5, 0.5}, {1.5, 1.5, 0.5}));  // ends on the face
  EXPECT_FALSE(scene.Blocked(0.0, {0.5, 1.0, 0.5}, {3.5, 1.0, 0.5}));  // along a face
  EXPECT_FALSE(scene.Blocked(0.0, {0.5, 1.5, 1.0}, {3.5, 1.5, 1.0}));  // along the top
  EXPECT_TRUE(scene.Blocked(0.0, {0.5, 1.5, 0.99}, {3.5, 1.5, 0.99}));
  // A box turned by 45 degrees reaches sqrt(0.5) m from its centre along x.
  const Site turned = RoomWith(
      "obstacles:\n  - {type: box, centre_m: [2.0, 1.5], size_m: [1.0, 1.0], yaw_deg: 45,"
      " top_m: 1.0}\n");
  const AcousticScene t(turned, 20.0);
  EXPECT_TRUE(t.Blocked(0.0, {0.5, 1.5, 0.5}, {1.32, 1.5, 0.5}));
  EXPECT_FALSE(t.Blocked(0.0, {0.5, 1.5, 0.5}, {1.28, 1.5, 0.5}));
}

TEST(AcousticPaths, AWalkingPersonBlocksOnlyWhileInTheWay) {
  // A person (radius 0.2 m, 1.8 m tall) walking along x = 2.5 from y = 0.5
  // to y = 2.5 at 0.5 m/s crosses the line y = 1.5 at t = 2 s.
  const Site site = RoomWith(
      "obstacles:\n"
      "  - type: cylinder\n    name: person\n    radius_m: 0.2\n    top_m: 1.8\n"
      "    trajectory: {type: waypoints, points_m: [[2.5, 0.5], [2.5, 2.5]], speed_mps: 0.5,"
      " loop: false}\n");
  const AcousticScene scene(site, 20.0);
  const std::array<double, 3> beacon = {1.0, 1.5, 1.3};
  const std::array<double, 3> receiver = {4.0, 1.5, 1.3};
  EXPECT_EQ(scene.ShortestAudiblePath(0.0, beacon, receiver).kind, AudiblePath::Kind::kDirect);
  EXPECT_EQ(scene.ShortestAudiblePath(2.0, beacon, receiver).kind, AudiblePath::Kind::kReflected);
  EXPECT_EQ(scene.ShortestAudiblePath(3.5, beacon, receiver).kind, AudiblePath::Kind::kDirect);
}

// The simulator's ranges: a blocked receiver reads the echo's length, the
// others read exactly what they read without the obstacle (the generator's
// draws do not depend on the geometry).
TEST(AcousticPaths, SimulatedRangesReadTheEchoOnlyWhereTheGeometryBlocks) {
  const Site open = RoomWith("");
  const Site pillar = RoomWith(
      "obstacles:\n  - {type: cylinder, centre_m: [2.5, 1.5], radius_m: 0.25, top_m: 3.3}\n");
  UltrasoundNoise noise;
  noise.sigma_m = 0.01;
  std::mt19937_64 rng_open(7);
  std::mt19937_64 rng_pillar(7);
  const std::array<double, 3> beacon = {1.0, 1.5, 1.3};
  const auto a = SimulateRanges(open, beacon, 20.0, noise, &rng_open);
  const auto b = SimulateRanges(pillar, beacon, 20.0, noise, &rng_pillar);
  ASSERT_EQ(a.size(), 3u);
  ASSERT_EQ(b.size(), 3u);
  EXPECT_EQ(b[0].path, AudiblePath::Kind::kReflected);
  EXPECT_NEAR(b[0].detour_m, std::sqrt(18.0) - 3.0, kLengthTolerance_m);
  EXPECT_NEAR(b[0].measured_m - a[0].measured_m, std::sqrt(18.0) - 3.0, kLengthTolerance_m);
  for (size_t i = 1; i < 3; ++i) {
    EXPECT_EQ(b[i].path, AudiblePath::Kind::kDirect);
    EXPECT_EQ(b[i].measured_m, a[i].measured_m);
  }
  // Switched off, the geometry is ignored: the old behavioural model.
  noise.geometric_nlos = false;
  std::mt19937_64 rng_off(7);
  const auto c = SimulateRanges(pillar, beacon, 20.0, noise, &rng_off);
  EXPECT_EQ(c[0].measured_m, a[0].measured_m);
}

TEST(AcousticPaths, ThePillarDemoHidesTheRobotFromReceiverThreeForMuchOfALap) {
  Site site;
  std::string error;
  ASSERT_TRUE(LoadSite(testing::SourceDir() + "/config/sites/demo_room_pillar.yaml", &site, &error))
      << error;
  ASSERT_EQ(site.obstacles.size(), 1u);
  const AcousticScene scene(site, site.simulation.temperature_c);
  const Trajectory& t = *site.simulation.robots[0].trajectory;
  // One lap of the reference circle (2 pi / 0.439 = 14.3 s) at 10 Hz.
  constexpr int kSamples = 143;
  std::array<int, 4> blocked = {};
  for (int k = 0; k < kSamples; ++k) {
    const GroundTruthPose p = t.PoseAt(0.1 * k);
    for (size_t i = 0; i < site.receivers.size(); ++i) {
      const AudiblePath path =
          scene.ShortestAudiblePath(0.1 * k, {p.x_m, p.y_m, 1.3}, site.receivers[i].position_m);
      blocked[i] += path.kind != AudiblePath::Kind::kDirect;
    }
  }
  // The site file's comment: receiver 3 hidden about two thirds of a lap,
  // the others never (the pillar is behind the robot for them).
  EXPECT_EQ(blocked[0], 0);
  EXPECT_EQ(blocked[1], 0);
  EXPECT_EQ(blocked[3], 0);
  EXPECT_GT(blocked[2], kSamples / 2);
  EXPECT_LT(blocked[2], kSamples * 4 / 5);
}

}  // namespace
}  // namespace roomfix
