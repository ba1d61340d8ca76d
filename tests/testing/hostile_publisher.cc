// roomfix_hostile: sends one class of hostile or broken LCM traffic
// (tests/testing/hostile_traffic.h) to the bus, to reproduce by hand what
// tests/netns/hostile_traffic_test.cc does to the real processes. Run it only
// inside a private network namespace (scripts/netns_run) or on an isolated
// lab network: it is an attack on every process listening.
#include <CLI/CLI.hpp>
#include <chrono>
#include <functional>
#include <iostream>
#include <map>
#include <thread>

#include "msgio/process.h"
#include "tests/testing/hostile_traffic.h"

namespace {

using roomfix::pose2d_t;
using roomfix::hostile::Bytes;
using roomfix::hostile::Encode;
using roomfix::hostile::Sender;

}  // namespace

int main(int argc, char** argv) {
  std::string url = roomfix::kDefaultLcmUrl;
  std::string name;
  int count = 1;
  double rate_hz = 0.0;
  CLI::App app{"roomfix_hostile: sends one class of hostile LCM traffic (issue #15) to the bus"};
  app.add_option("--lcm-url", url, "LCM URL (udpm:// only)")->capture_default_str();
  app.add_option("--count", count, "How many times to send the class")->capture_default_str();
  app.add_option("--rate", rate_hz, "Sends per second (0: as fast as possible)");
  std::map<std::string, std::pair<std::string, std::function<bool(Sender&, int)>>> classes = {
      {"conflicting-total",
       {"two LC03 fragments of one RANGES message whose totals disagree",
        [](Sender& s, int) {
          return s.SendAll(roomfix::hostile::ConflictingTotalFragments(s.NextSeqno(), "RANGES"));
        }}},
      {"huge-fragment",
       {"an LC03 first fragment declaring a 64 MiB RANGES message",
        [](Sender& s, int) {
          return s.Send(roomfix::hostile::HugeFirstFragment(s.NextSeqno(), "RANGES"));
        }}},
      {"negative-string",
       {"INT32_MIN string lengths on STATUS, MARKER_PIXELS and CAMERA_PREVIEW",
        [](Sender& s, int) {
          return s.Publish("STATUS", roomfix::hostile::StatusWithNegativeStringLength()) &&
                 s.Publish("MARKER_PIXELS",
                           roomfix::hostile::MarkerPixelsWithNegativeStringLength()) &&
                 s.Publish("CAMERA_PREVIEW",
                           roomfix::hostile::CameraPreviewWithNegativeStringLength());
        }}},
      {"huge-count",
       {"a 52-byte RANGES message claiming 2^24 ranges",
        [](Sender& s, int) {
          return s.Publish(
              "RANGES", roomfix::hostile::RangesClaimingCount(roomfix::hostile::kHugeRangeCount));
        }}},
      {"inconsistent-ranges",
       {"RANGES with 400 and with 800 mutually inconsistent ranges",
        [](Sender& s, int k) {
          const int64_t now = roomfix::NowUtime();
          return s.Publish("RANGES", Encode(roomfix::hostile::InconsistentRanges(400, 2 * k, now,
                                                                                 2 * k + 1))) &&
                 s.Publish("RANGES", Encode(roomfix::hostile::InconsistentRanges(800, 2 * k + 1,
                                                                                 now, 2 * k + 2)));
        }}},
      {"empty-channel",
       {"an LC02 datagram with an empty channel name",
        [](Sender& s, int) {
          return s.Send(roomfix::hostile::EmptyChannelDatagram(s.NextSeqno()));
        }}},
      {"new-robots",
       {"poses on POSE_CAMERA and POSE_ULTRASOUND, each for a new robot id",
        [](Sender& s, int k) {
          const bool camera = k % 2 == 0;
          return s.Publish(camera ? "POSE_CAMERA" : "POSE_ULTRASOUND",
                           Encode(roomfix::hostile::PoseForNewRobot(
                               camera ? pose2d_t::SOURCE_CAMERA : pose2d_t::SOURCE_ULTRASOUND,
                               1000 + k, roomfix::NowUtime())));
        }}},
      {"non-finite",
       {"NaN and infinite fields in RANGES, POSE_CAMERA and POSE_ULTRASOUND",
        [](Sender& s, int k) {
          const int64_t now = roomfix::NowUtime();
          bool ok = s.Publish("RANGES", Encode(roomfix::hostile::NonFiniteRanges(k, now)));
          for (const auto& p : roomfix::hostile::NonFinitePoses(pose2d_t::SOURCE_CAMERA, now)) {
            ok = s.Publish("POSE_CAMERA", Encode(p)) && ok;
          }
          for (const auto& p : roomfix::hostile::NonFinitePoses(pose2d_t::SOURCE_ULTRASOUND, now)) {
            ok = s.Publish("POSE_ULTRASOUND", Encode(p)) && ok;
          }
          return ok;
        }}},
      {"absurd-utime",
       {"RANGES and poses timed 100 years away and at the int64 limits",
        [](Sender& s, int k) {
          bool ok = true;
          for (int64_t t : roomfix::hostile::AbsurdUtimes(roomfix::NowUtime())) {
            ok = s.Publish("RANGES", Encode(roomfix::hostile::GoodRanges(k, t))) && ok;
            ok = s.Publish("POSE_CAMERA",
                           Encode(roomfix::hostile::GoodPose(pose2d_t::SOURCE_CAMERA, k, t))) &&
                 ok;
            ok = s.Publish("POSE_ULTRASOUND",
                           Encode(roomfix::hostile::GoodPose(pose2d_t::SOURCE_ULTRASOUND, k, t))) &&
                 ok;
          }
          return ok;
        }}},
  };
  std::string help = "Class to send:";
  for (const auto& [key, value] : classes) help += "\n  " + key + ": " + value.first;
  app.add_option("CLASS", name, help)->required();
  CLI11_PARSE(app, argc, argv);

  auto it = classes.find(name);
  if (it == classes.end()) {
    std::cerr << "roomfix_hostile: unknown class '" << name << "'\n";
    return 1;
  }
  Sender sender(url);
  if (!sender.ok()) {
    std::cerr << "roomfix_hostile: " << sender.error() << "\n";
    return 1;
  }
  const auto start = std::chrono::steady_clock::now();
  for (int k = 0; k < count; ++k) {
    if (rate_hz > 0.0)
      std::this_thread::sleep_until(start + std::chrono::duration<double>(k / rate_hz));
    if (!it->second.second(sender, k)) {
      std::cerr << "roomfix_hostile: " << sender.error() << "\n";
      return 1;
    }
  }
  return 0;
}
