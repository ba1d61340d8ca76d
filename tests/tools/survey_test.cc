// `roomfix survey` end to end: a log recorded in-process (RANGES from
// receivers displaced from the site file's values, POSE_GROUND_TRUTH at
// 30 Hz) must give back the true receivers, a better held-out error and a
// fragment that pastes into the site file.
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <cmath>
#include <nlohmann/json.hpp>
#include <random>

#include "core/world/site.h"
#include "msgio/log.h"
#include "roomfix/pose2d_t.hpp"
#include "roomfix/range_set_t.hpp"
#include "tests/testing/demo_site.h"
#include "tests/testing/test_messages.h"
#include "tests/testing/test_paths.h"

namespace roomfix {
namespace {

using nlohmann::json;
using testing::BinDir;
using testing::ChildProcess;
using testing::DemoSitePath;
using testing::ReadFile;
using testing::SourceDir;
using testing::TempDir;

constexpr int64_t kT0 = 1'700'000'000'000'000;
constexpr double kSpeedOfSound = 343.8;

struct TrueReceiver {
  int id;
  Eigen::Vector3d position_m;
  double offset_m;
};

// demo_room's receivers displaced by up to 20 cm, offsets up to 15 cm.
std::vector<TrueReceiver> Truth() {
  // Inside the room: the site file rejects receivers outside it.
  return {{1, {0.20, 0.12, 2.65}, 0.15},
          {2, {3.83, 0.20, 2.40}, -0.08},
          {3, {3.92, 2.80, 2.68}, 0.11},
          {4, {0.20, 2.91, 2.34}, -0.15}};
}

Eigen::Vector2d RobotAt(double t_s) {
  static const std::vector<Eigen::Vector2d> kWaypoints = {
      {0.3, 0.3}, {3.7, 0.3}, {3.7, 1.0}, {0.3, 1.0}, {0.3, 2.0}, {3.7, 2.0}, {3.7, 2.7},
      {0.3, 2.7}, {0.3, 0.3}, {2.0, 0.3}, {2.0, 2.7}, {3.7, 1.5}, {0.3, 1.5}, {0.3, 0.3}};
  double loop_s = 0;
  for (size_t i = 0; i + 1 < kWaypoints.size(); ++i) {
    loop_s += (kWaypoints[i + 1] - kWaypoints[i]).norm() / 0.3;
  }
  double t = std::fmod(t_s, loop_s);
  for (size_t i = 0; i + 1 < kWaypoints.size(); ++i) {
    const double leg = (kWaypoints[i + 1] - kWaypoints[i]).norm() / 0.3;
    if (t < leg) return kWaypoints[i] + (kWaypoints[i + 1] - kWaypoints[i]) * (t / leg);
    t -= leg;
  }
  return kWaypoints.back();
}

template <typename Message>
void Write(LogWriter* w, int64_t utime, const char* channel, const Message& msg) {
  std::vector<uint8_t> buffer(static_cast<size_t>(msg.getEncodedSize()));
  msg.encode(buffer.data(), 0, static_cast<int>(buffer.size()));
  std::string error;
  ASSERT_TRUE(w->Write(utime, channel, buffer.data(), static_cast<int>(buffer.size()), &error))
      << error;
}

// A 10-minute drive: ranges at 10 Hz with 1 cm noise and 3% non-line-of-
// sight ranges 30 cm long; ground truth at 30 Hz with 1 mm noise.
void RecordDrive(const std::string& path, const Site& site,
                 const std::vector<TrueReceiver>& truth = Truth()) {
  std::string error;
  auto w = LogWriter::Create(path, true, &error);
  ASSERT_NE(w, nullptr) << error;
  std::mt19937 rng(5);
  std::normal_distribution<double> noise(0.0, 1.0);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  constexpr double kDuration_s = 600.0;
  constexpr double kHeight_m = 1.3;
  int64_t seq = 0;
  for (int k = 0; k * (1.0 / 30) <= kDuration_s; ++k) {
    const double t = k / 30.0;
    const Eigen::Vector2d p = RobotAt(t);
    pose2d_t pose = testing::MakeTestPose(kT0 + static_cast<int64_t>(std::llround(t * 1e6)), 1,
                                          p.x() + 0.001 * noise(rng), p.y() + 0.001 * noise(rng));
    pose.source = pose2d_t::SOURCE_GROUND_TRUTH;
    Write(w.get(), pose.utime, "POSE_GROUND_TRUTH", pose);
    if (k % 3 != 1) continue;
    range_set_t set{};
    set.utime = pose.utime + 1000;  // between two reference samples
    set.beacon_id = 1;
    set.firing_seq = seq++;
    set.speed_of_sound_mps = kSpeedOfSound;
    set.temperature_c = 21.0;
    set.num_expected = 4;
    const Eigen::Vector2d q2 = RobotAt(t + 0.001);
    const Eigen::Vector3d q(q2.x(), q2.y(), kHeight_m);
    for (const TrueReceiver& r : truth) {
      double raw = (r.position_m - q).norm() + r.offset_m + 0.01 * noise(rng);
      if (uniform(rng) < 0.03) raw += 0.30;
      range_t out{};
      out.receiver_id = r.id;
      const Receiver* rx = site.FindReceiver(r.id);
      for (int i = 0; i < 3; ++i)
        out.receiver_position_m[i] = rx->position_m[static_cast<size_t>(i)];
      out.time_of_flight_us = raw / kSpeedOfSound * 1e6;
      out.range_m = raw - rx->range_offset_m;
      out.arrival_utime = set.utime + 20000;
      set.ranges.push_back(out);
    }
    set.num_ranges = static_cast<int32_t>(set.ranges.size());
    Write(w.get(), set.utime + 20000, "RANGES", set);
  }
}

// Runs `roomfix survey ARGS... --json DIR/out.json`, which must succeed;
// prints its report and returns the JSON (discarded when it does not parse).
json RunSurvey(const testing::TempDir& dir, std::vector<std::string> args) {
  std::vector<std::string> argv = {BinDir() + "/roomfix", "survey"};
  argv.insert(argv.end(), args.begin(), args.end());
  argv.insert(argv.end(), {"--json", dir.File("out.json")});
  ChildProcess p(argv, dir.File("stdout.txt"));
  const int rc = p.Wait(120);
  EXPECT_EQ(rc, 0) << ReadFile(dir.File("stdout.txt"));
  std::printf("%s", ReadFile(dir.File("stdout.txt")).c_str());
  if (rc != 0) return json::value_t::discarded;
  return json::parse(ReadFile(dir.File("out.json")), nullptr, false);
}

TEST(RoomfixSurvey, RecoversDisplacedReceiversFromALogAndWritesAPastableFragment) {
  TempDir dir;
  const std::string site_path = DemoSitePath();
  Site site;
  std::string error;
  ASSERT_TRUE(LoadSite(site_path, &site, &error)) << error;
  RecordDrive(dir.File("drive.lcm"), site);
  const json out = RunSurvey(dir, {dir.File("drive.lcm"), "--site", site_path, "--reference",
                                   "ground_truth", "--out", dir.File("fragment.yaml")});
  ASSERT_FALSE(out.is_discarded());
  // One beacon height and 10 minutes: heights and offsets trade off (see
  // core/survey's tests); 1-sigma about 2-3 mm, so these are 5-sigma bounds.
  constexpr double kPositionTolerance_m = 0.02;
  constexpr double kOffsetTolerance_m = 0.015;
  ASSERT_EQ(out["receivers"].size(), 4u);
  for (const TrueReceiver& t : Truth()) {
    const json* r = nullptr;
    for (const auto& x : out["receivers"]) {
      if (x["id"] == t.id) r = &x;
    }
    ASSERT_NE(r, nullptr);
    const Eigen::Vector3d p_est((*r)["position_m"][0], (*r)["position_m"][1],
                                (*r)["position_m"][2]);
    EXPECT_LT((p_est - t.position_m).norm(), kPositionTolerance_m) << t.id;
    EXPECT_NEAR((*r)["range_offset_m"].get<double>(), t.offset_m, kOffsetTolerance_m) << t.id;
  }
  // The non-line-of-sight ranges are rejected.
  EXPECT_GT(out["ranges_rejected"].get<int>(), 0.02 * 4 * 6000);
  const double before = out["held_out"]["before"]["rmse_m"];
  const double after = out["held_out"]["after"]["rmse_m"];
  EXPECT_LT(after, 0.5 * before);
  // The fragment replaces the site's receivers and the site still loads.
  std::string text = ReadFile(site_path);
  const size_t from = text.find("receivers:\n");
  const size_t to = text.find("\nbeacons:");
  ASSERT_NE(from, std::string::npos);
  ASSERT_NE(to, std::string::npos);
  text = text.substr(0, from) + ReadFile(dir.File("fragment.yaml")) + text.substr(to);
  Site surveyed;
  ASSERT_TRUE(ParseSite(text, "surveyed", SourceDir() + "/config/sites", &surveyed, &error))
      << error;
  ASSERT_EQ(surveyed.receivers.size(), 4u);
  EXPECT_NEAR(surveyed.receivers[0].range_offset_m, 0.15, kOffsetTolerance_m);
}

TEST(RoomfixSurvey, WithoutAReferenceTwoPinnedReceiversFixTheFrame) {
  TempDir dir;
  const std::string site_path = DemoSitePath();
  Site site;
  std::string error;
  ASSERT_TRUE(LoadSite(site_path, &site, &error)) << error;
  // Receivers 1 and 2 are where the site says (surveyed); 3 and 4 moved in
  // x, y only (their heights were measured).
  std::vector<TrueReceiver> truth = {{1, {0.0, 0.0, 2.5}, 0.15},
                                     {2, {4.0, 0.0, 2.5}, -0.08},
                                     {3, {3.88, 2.85, 2.5}, 0.11},
                                     {4, {0.15, 2.82, 2.5}, -0.15}};
  RecordDrive(dir.File("drive.lcm"), site, truth);
  const json out = RunSurvey(dir, {dir.File("drive.lcm"), "--site", site_path, "--no-reference",
                                   "--pin", "1,2", "--fix-heights", "--reference", "ground_truth"});
  ASSERT_FALSE(out.is_discarded());
  // 600 firings, 1 cm noise: about 5 mm 1-sigma.
  constexpr double kSelfCalPosition_m = 0.025;
  constexpr double kSelfCalOffset_m = 0.02;
  for (const auto& r : out["receivers"]) {
    const TrueReceiver& t = truth[r["id"].get<size_t>() - 1];
    const Eigen::Vector3d p_est(r["position_m"][0], r["position_m"][1], r["position_m"][2]);
    EXPECT_LT((p_est - t.position_m).norm(), kSelfCalPosition_m) << t.id;
    EXPECT_NEAR(r["range_offset_m"].get<double>(), t.offset_m, kSelfCalOffset_m) << t.id;
    EXPECT_EQ(r["pinned"].get<bool>(), t.id <= 2);
  }
  // The log has ground truth: the held-out check still runs.
  EXPECT_LT(out["held_out"]["after"]["median_m"].get<double>(),
            0.5 * out["held_out"]["before"]["median_m"].get<double>());
}

TEST(RoomfixSurvey, SaysWhatIsMissingWithoutAReference) {
  TempDir dir;
  const std::string site_path = DemoSitePath();
  Site site;
  std::string error;
  ASSERT_TRUE(LoadSite(site_path, &site, &error)) << error;
  RecordDrive(dir.File("drive.lcm"), site);
  ChildProcess p({BinDir() + "/roomfix", "survey", dir.File("drive.lcm"), "--site", site_path,
                  "--reference", "camera"},
                 dir.File("stdout.txt"));
  EXPECT_EQ(p.Wait(60), 1);
}

}  // namespace
}  // namespace roomfix
