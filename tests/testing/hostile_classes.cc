#include "tests/testing/hostile_classes.h"

#include <chrono>
#include <thread>

namespace roomfix::hostile {

namespace {

std::map<std::string, TrafficClass> MakeClasses() {
  return {
      {"conflicting-total",
       {"two LC03 fragments of one RANGES message whose totals disagree",
        [](Sender& s, int) {
          return s.SendAll(ConflictingTotalFragments(s.NextSeqno(), "RANGES"));
        }}},
      {"huge-fragment",
       {"an LC03 first fragment declaring a 64 MiB RANGES message",
        [](Sender& s, int) { return s.Send(HugeFirstFragment(s.NextSeqno(), "RANGES")); }}},
      {"negative-string",
       {"INT32_MIN string lengths on STATUS, MARKER_PIXELS and CAMERA_PREVIEW",
        [](Sender& s, int) {
          return s.Publish("STATUS", StatusWithNegativeStringLength()) &&
                 s.Publish("MARKER_PIXELS", MarkerPixelsWithNegativeStringLength()) &&
                 s.Publish("CAMERA_PREVIEW", CameraPreviewWithNegativeStringLength());
        }}},
      {"huge-count",
       {"a 52-byte RANGES message claiming 2^24 ranges",
        [](Sender& s, int) { return s.Publish("RANGES", RangesClaimingCount(kHugeRangeCount)); }}},
      {"inconsistent-ranges",
       {"RANGES with 400 and with 800 mutually inconsistent ranges",
        [](Sender& s, int k) {
          const int64_t now = NowUtime();
          return s.Publish("RANGES", Encode(InconsistentRanges(400, 2 * k, now, 2 * k + 1))) &&
                 s.Publish("RANGES", Encode(InconsistentRanges(800, 2 * k + 1, now, 2 * k + 2)));
        }}},
      {"empty-channel",
       {"an LC02 datagram with an empty channel name",
        [](Sender& s, int) { return s.Send(EmptyChannelDatagram(s.NextSeqno())); }}},
      {"new-robots",
       {"poses on POSE_CAMERA and POSE_ULTRASOUND, each for a new robot id",
        [](Sender& s, int k) {
          const bool camera = k % 2 == 0;
          return s.Publish(
              camera ? "POSE_CAMERA" : "POSE_ULTRASOUND",
              Encode(PoseForNewRobot(camera ? pose2d_t::SOURCE_CAMERA : pose2d_t::SOURCE_ULTRASOUND,
                                     1000 + k, NowUtime())));
        }}},
      {"non-finite",
       {"NaN and infinite fields in RANGES, POSE_CAMERA and POSE_ULTRASOUND",
        [](Sender& s, int k) {
          const int64_t now = NowUtime();
          bool ok = s.Publish("RANGES", Encode(NonFiniteRanges(k, now)));
          for (const auto& p : NonFinitePoses(pose2d_t::SOURCE_CAMERA, now)) {
            ok = s.Publish("POSE_CAMERA", Encode(p)) && ok;
          }
          for (const auto& p : NonFinitePoses(pose2d_t::SOURCE_ULTRASOUND, now)) {
            ok = s.Publish("POSE_ULTRASOUND", Encode(p)) && ok;
          }
          return ok;
        }}},
      {"absurd-utime",
       {"RANGES and poses timed 100 years away and at the int64 limits",
        [](Sender& s, int k) {
          bool ok = true;
          for (int64_t t : AbsurdUtimes(NowUtime())) {
            ok = s.Publish("RANGES", Encode(GoodRanges(k, t))) && ok;
            ok = s.Publish("POSE_CAMERA", Encode(GoodPose(pose2d_t::SOURCE_CAMERA, k, t))) && ok;
            ok =
                s.Publish("POSE_ULTRASOUND", Encode(GoodPose(pose2d_t::SOURCE_ULTRASOUND, k, t))) &&
                ok;
          }
          return ok;
        }}},
  };
}

}  // namespace

const std::map<std::string, TrafficClass>& TrafficClasses() {
  static const std::map<std::string, TrafficClass> classes = MakeClasses();
  return classes;
}

bool PublisherOptions::IsValid(std::string* error) const {
  if (TrafficClasses().count(class_name) == 0) {
    *error = "unknown class '" + class_name + "'";
    return false;
  }
  return true;
}

int SendTraffic(const PublisherOptions& options, std::string* error) {
  const TrafficClass& traffic = TrafficClasses().at(options.class_name);
  Sender sender(options.lcm_url);
  if (!sender.ok()) {
    *error = sender.error();
    return 1;
  }
  const auto start = std::chrono::steady_clock::now();
  for (int k = 0; k < options.count; ++k) {
    if (options.rate_hz > 0.0) {
      std::this_thread::sleep_until(start + std::chrono::duration<double>(k / options.rate_hz));
    }
    if (!traffic.send(sender, k)) {
      *error = sender.error();
      return 1;
    }
  }
  return 0;
}

}  // namespace roomfix::hostile
