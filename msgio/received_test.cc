#include "msgio/received.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "msgio/message_conversions.h"
#include "msgio/time_limits.h"
#include "msgio/wire_check.h"
#include "tests/testing/demo_site.h"

namespace roomfix {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
// The receive time of every message below; each is measured 20 ms before.
constexpr int64_t kRecvUtime = 1'714'564'800'000'000;
constexpr int64_t kUtime = kRecvUtime - 20'000;

Site DemoSite() {
  Site site;
  std::string error;
  EXPECT_TRUE(LoadSite(testing::DemoSitePath(), &site, &error)) << error;
  return site;
}

// The message as a node's handler gets it: encoded, then decoded by the
// bus's DecodeChecked.
template <typename Message>
Message Delivered(const Message& msg) {
  std::vector<uint8_t> bytes(static_cast<size_t>(msg.getEncodedSize()));
  msg.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
  Message out;
  std::string reason;
  EXPECT_TRUE(DecodeChecked(bytes.data(), static_cast<int>(bytes.size()), &out, &reason)) << reason;
  return out;
}

// A camera pose of the demo's robot as camera_proc builds it: heading
// known, every covariance finite.
pose2d_t CameraPose(const Site& site) {
  Pose2d p;
  p.utime = kUtime;
  p.source = PoseSource::kCamera;
  p.camera_id = site.cameras.front().id;
  p.robot_id = site.robots.front().id;
  p.measurement_seq = 12;
  p.x_m = 1.5;
  p.y_m = 2.0;
  p.z_m = 0.2;
  p.heading_rad = 0.3;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) p.covariance[r][c] = r == c ? 1e-6 : 0.0;
  }
  p.num_measurements = 2;
  p.status = PoseStatus::kOk;
  p.latency_us = 20'000;
  return ToMessage(p);
}

// One firing of the demo's beacon heard by every receiver of the site, as
// zigbee_bridge publishes it.
range_set_t Firing(const Site& site) {
  range_set_t set{};
  set.utime = kUtime;
  set.beacon_id = site.beacons.front().id;
  set.firing_seq = 7;
  set.speed_of_sound_mps = 343.2;
  set.temperature_c = 20.0;
  set.num_expected = static_cast<int32_t>(site.receivers.size());
  for (const Receiver& receiver : site.receivers) {
    range_t r{};
    r.receiver_id = receiver.id;
    for (int k = 0; k < 3; ++k) r.receiver_position_m[k] = receiver.position_m[k];
    r.range_m = 2.0;
    r.time_of_flight_us = 2.0 / 343.2 * 1e6;
    r.arrival_utime = kUtime + 6000;
    set.ranges.push_back(r);
  }
  set.num_ranges = static_cast<int32_t>(set.ranges.size());
  return set;
}

// What ReceivePose says of `msg`: the problem, with *error its text.
InputProblem PoseProblem(const pose2d_t& msg, const Site& site, std::string* error = nullptr) {
  Pose2d pose;
  std::string why;
  InputProblem problem = InputProblem::kNone;
  const bool ok = ReceivePose(Delivered(msg), site, kRecvUtime, &pose, &why, &problem);
  EXPECT_EQ(ok, problem == InputProblem::kNone);
  EXPECT_EQ(ok, why.empty()) << why;
  if (error != nullptr) *error = why;
  return problem;
}

InputProblem RangeSetProblem(const range_set_t& set, const Site& site,
                             std::string* error = nullptr) {
  std::string why;
  InputProblem problem = InputProblem::kNone;
  const bool ok = CheckRangeSet(Delivered(set), site, kRecvUtime, &why, &problem);
  EXPECT_EQ(ok, problem == InputProblem::kNone);
  if (error != nullptr) *error = why;
  return problem;
}

TEST(InputProblemCounter, NamesEachProblemAsTheNodesCountIt) {
  EXPECT_STREQ(InputProblemCounter(InputProblem::kNone), "");
  EXPECT_STREQ(InputProblemCounter(InputProblem::kUtimeOutOfRange), "utime_out_of_range");
  EXPECT_STREQ(InputProblemCounter(InputProblem::kUnknownRobot), "unknown_robot");
  EXPECT_STREQ(InputProblemCounter(InputProblem::kNonFinite), "non_finite");
  EXPECT_STREQ(InputProblemCounter(InputProblem::kTooManyRanges), "too_many_ranges");
  EXPECT_STREQ(InputProblemCounter(InputProblem::kNegativeExpected), "negative_expected");
  EXPECT_STREQ(InputProblemCounter(InputProblem::kUnknownReceiver), "unknown_receiver");
}

TEST(ReceivePose, GivesEveryFieldOfAGoodPose) {
  const Site site = DemoSite();
  const pose2d_t msg = CameraPose(site);
  Pose2d pose;
  std::string why;
  InputProblem problem = InputProblem::kUnknownRobot;
  ASSERT_TRUE(ReceivePose(Delivered(msg), site, kRecvUtime, &pose, &why, &problem)) << why;
  EXPECT_EQ(problem, InputProblem::kNone);
  // Field for field what FromMessage gives (its own test covers each).
  const Pose2d expected = FromMessage(msg);
  EXPECT_EQ(pose.utime, expected.utime);
  EXPECT_EQ(pose.source, PoseSource::kCamera);
  EXPECT_EQ(pose.camera_id, expected.camera_id);
  EXPECT_EQ(pose.robot_id, expected.robot_id);
  EXPECT_EQ(pose.x_m, expected.x_m);
  EXPECT_EQ(pose.y_m, expected.y_m);
  EXPECT_EQ(pose.heading_rad, expected.heading_rad);
  EXPECT_EQ(pose.covariance, expected.covariance);
  EXPECT_EQ(pose.status, PoseStatus::kOk);
}

TEST(ReceivePose, TakesNaNWhereThePoseMeansUnknown) {
  const Site site = DemoSite();
  // An ultrasonic pose: no heading, its covariances NaN.
  pose2d_t no_heading = CameraPose(site);
  no_heading.source = pose2d_t::SOURCE_ULTRASOUND;
  no_heading.heading_rad = kNaN;
  for (int k = 0; k < 3; ++k) no_heading.covariance[2][k] = no_heading.covariance[k][2] = kNaN;
  no_heading.z_m = kNaN;
  EXPECT_EQ(PoseProblem(no_heading, site), InputProblem::kNone);
  // A lost pose: nothing but its header.
  Pose2d lost;
  lost.utime = kUtime;
  lost.source = PoseSource::kFused;
  lost.robot_id = site.robots.front().id;
  EXPECT_EQ(PoseProblem(ToMessage(lost), site), InputProblem::kNone);
}

TEST(ReceivePose, RefusesATimeFarFromItsReceiveTime) {
  const Site site = DemoSite();
  pose2d_t msg = CameraPose(site);
  for (int64_t utime : {std::numeric_limits<int64_t>::min(), int64_t{0},
                        kRecvUtime - kMaxUtimeSkewUs - 1, kRecvUtime + kMaxUtimeAheadUs + 1}) {
    msg.utime = utime;
    std::string why;
    EXPECT_EQ(PoseProblem(msg, site, &why), InputProblem::kUtimeOutOfRange) << utime;
    EXPECT_EQ(why, "measurement time " + std::to_string(utime) +
                       " us is more than an hour before or 0.1 s after its receive time");
  }
  // Another host's clock a little ahead is no reason.
  msg.utime = kRecvUtime + kMaxUtimeAheadUs;
  EXPECT_EQ(PoseProblem(msg, site), InputProblem::kNone);
}

TEST(ReceivePose, RefusesARobotTheSiteDoesNotList) {
  const Site site = DemoSite();
  pose2d_t msg = CameraPose(site);
  msg.robot_id = 1000;
  std::string why;
  EXPECT_EQ(PoseProblem(msg, site, &why), InputProblem::kUnknownRobot);
  EXPECT_EQ(why, "the site file does not list this robot");
}

TEST(ReceivePose, RefusesAnInfinityAnywhereAndNaNWhereANumberIsRequired) {
  const Site site = DemoSite();
  const pose2d_t good = CameraPose(site);
  std::vector<pose2d_t> bad(8, good);
  bad[0].x_m = kInf;
  bad[1].y_m = -kInf;
  bad[2].z_m = kInf;
  bad[3].heading_rad = kInf;
  bad[4].covariance[2][2] = kInf;
  bad[5].x_m = kNaN;  // Not lost: a position is required.
  bad[6].covariance[1][0] = kNaN;
  bad[7].status = pose2d_t::STATUS_LOST;  // Lost, but an infinity is never "unknown".
  bad[7].covariance[0][0] = kInf;
  for (size_t i = 0; i < bad.size(); ++i) {
    std::string why;
    EXPECT_EQ(PoseProblem(bad[i], site, &why), InputProblem::kNonFinite) << i;
    EXPECT_EQ(why, "a position, covariance or heading that is not a finite number");
  }
}

TEST(CheckRangeSet, AcceptsAFiringOfTheSite) {
  const Site site = DemoSite();
  EXPECT_EQ(RangeSetProblem(Firing(site), site), InputProblem::kNone);
}

TEST(CheckRangeSet, RefusesATimeFarFromItsReceiveTime) {
  const Site site = DemoSite();
  range_set_t set = Firing(site);
  set.utime = kRecvUtime + kMaxUtimeAheadUs + 1;
  std::string why;
  EXPECT_EQ(RangeSetProblem(set, site, &why), InputProblem::kUtimeOutOfRange);
  EXPECT_EQ(why, "firing time " + std::to_string(set.utime) +
                     " us is more than an hour before or 0.1 s after its receive time " +
                     std::to_string(kRecvUtime) + " us");
}

TEST(CheckRangeSet, RefusesANonFiniteSpeedOfSoundOrTemperature) {
  const Site site = DemoSite();
  range_set_t set = Firing(site);
  set.speed_of_sound_mps = kNaN;
  std::string why;
  EXPECT_EQ(RangeSetProblem(set, site, &why), InputProblem::kNonFinite);
  EXPECT_EQ(why, "speed of sound or temperature is not a finite number");
  set = Firing(site);
  set.temperature_c = -kInf;
  EXPECT_EQ(RangeSetProblem(set, site), InputProblem::kNonFinite);
}

TEST(CheckRangeSet, RefusesMoreRangesThanTheSiteHasReceivers) {
  const Site site = DemoSite();
  range_set_t set = Firing(site);
  set.ranges.push_back(set.ranges.front());
  set.num_ranges = static_cast<int32_t>(set.ranges.size());
  std::string why;
  EXPECT_EQ(RangeSetProblem(set, site, &why), InputProblem::kTooManyRanges);
  EXPECT_EQ(why, std::to_string(set.ranges.size()) + " ranges, but the site has " +
                     std::to_string(site.receivers.size()) + " receivers");
}

TEST(CheckRangeSet, RefusesANegativeExpectedCount) {
  const Site site = DemoSite();
  range_set_t set = Firing(site);
  set.num_expected = -1;
  std::string why;
  EXPECT_EQ(RangeSetProblem(set, site, &why), InputProblem::kNegativeExpected);
  EXPECT_EQ(why, "num_expected -1 is negative");
}

TEST(CheckRangeSet, ChecksTimeFirst) {
  const Site site = DemoSite();
  range_set_t set = Firing(site);
  set.utime = 0;
  set.speed_of_sound_mps = kNaN;
  set.num_expected = -1;
  EXPECT_EQ(RangeSetProblem(set, site), InputProblem::kUtimeOutOfRange);
}

TEST(CheckRange, GivesTheSiteReceiverOfAGoodRange) {
  const Site site = DemoSite();
  const range_set_t set = Delivered(Firing(site));
  for (const range_t& r : set.ranges) {
    std::string why;
    InputProblem problem = InputProblem::kUnknownReceiver;
    const Receiver* receiver = CheckRange(r, site, &why, &problem);
    ASSERT_NE(receiver, nullptr) << why;
    EXPECT_EQ(receiver->id, r.receiver_id);
    EXPECT_EQ(problem, InputProblem::kNone);
  }
}

TEST(CheckRange, RefusesANonFiniteRangeTimeOrPosition) {
  const Site site = DemoSite();
  range_set_t set = Firing(site);
  set.ranges[0].range_m = kNaN;
  set.ranges[1].time_of_flight_us = kInf;
  set.ranges[2].receiver_position_m[2] = -kInf;
  // Non-finite is said before an unknown receiver.
  set.ranges[3].receiver_position_m[0] = kNaN;
  set.ranges[3].receiver_id = 99;
  set = Delivered(set);
  for (const range_t& r : set.ranges) {
    std::string why;
    InputProblem problem = InputProblem::kNone;
    EXPECT_EQ(CheckRange(r, site, &why, &problem), nullptr) << r.receiver_id;
    EXPECT_EQ(problem, InputProblem::kNonFinite) << r.receiver_id;
    EXPECT_EQ(why, "receiver " + std::to_string(r.receiver_id) +
                       ": a range, time of flight or position that is not a finite number");
  }
}

TEST(CheckRange, RefusesAReceiverTheSiteDoesNotList) {
  const Site site = DemoSite();
  range_set_t set = Firing(site);
  set.ranges[0].receiver_id = 99;
  set = Delivered(set);
  std::string why;
  InputProblem problem = InputProblem::kNone;
  EXPECT_EQ(CheckRange(set.ranges[0], site, &why, &problem), nullptr);
  EXPECT_EQ(problem, InputProblem::kUnknownReceiver);
  EXPECT_EQ(why, "receiver 99, which the site file does not list");
}

}  // namespace
}  // namespace roomfix
