// A recorded log in tests/data is read back with the log utilities, and
// played by the real lcm-logplayer over multicast into a subscriber: every
// event arrives intact and in order. Runs inside a private network namespace.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>

#include "core/world/site.h"
#include "msgio/bus.h"
#include "msgio/log.h"
#include "msgio/message_json.h"
#include "msgio/process.h"
#include "roomfix/pose2d_t.hpp"
#include "tests/testing/demo_site.h"
#include "tests/testing/test_paths.h"

namespace roomfix {
namespace {

using testing::ChildProcess;
using testing::DemoSitePath;
using testing::SourceDir;

// Recorded by lcm-logger from `roomfix_sim --config config/sites/demo_room.yaml
// --rate-hz 30` (see tests/data/README.md).
std::string SampleLog() { return SourceDir() + "/tests/data/ground_truth_sample.lcm"; }

std::vector<LogEvent> ReadAll(const std::string& path) {
  std::vector<LogEvent> events;
  std::string error;
  EXPECT_TRUE(ReadLogEvents(path, &events, &error)) << error;
  return events;
}

TEST(SampleLog, ReadsBackAsGroundTruthOnTheReferenceCircle) {
  const auto events = ReadAll(SampleLog());
  ASSERT_GE(events.size(), 30u);
  Site site;
  std::string error;
  ASSERT_TRUE(LoadSite(DemoSitePath(), &site, &error)) << error;
  int poses = 0;
  int beats = 0;
  int64_t start_utime = -1;
  for (const auto& e : events) {
    // LCM's UDP multicast provider announces itself once when it starts; a
    // real recording carries that event and must still read back.
    if (e.channel == "LCM_SELF_TEST") continue;
    const char* type = RoomfixTypeName(e.data.data(), static_cast<int>(e.data.size()));
    ASSERT_NE(type, nullptr) << "event " << e.eventnum << " on " << e.channel;
    if (e.channel == "STATUS") {
      ++beats;
      continue;
    }
    // roomfix_sim states its site (docs/messages.md, "The site on SITE"); a
    // recording made since then carries it.
    if (e.channel == "SITE") continue;
    ASSERT_EQ(e.channel, "POSE_GROUND_TRUTH");
    pose2d_t p{};
    ASSERT_EQ(p.decode(e.data.data(), 0, static_cast<int>(e.data.size())),
              static_cast<int>(e.data.size()));
    // Samples sit on a 30 Hz grid from the simulator's start.
    if (start_utime < 0) start_utime = p.utime - std::llround(p.measurement_seq * 1e6 / 30.0);
    const double t_s = (p.utime - start_utime) * 1e-6;
    const GroundTruthPose truth = site.simulation.robots[0].trajectory->PoseAt(t_s);
    // The sample's time is a whole microsecond: at the circle's 0.18 m/s the
    // truth moves 0.2 um in one, so 1 um is exact to the stamp.
    constexpr double kWholeMicrosecondM = 1e-6;
    EXPECT_NEAR(p.x_m, truth.x_m, kWholeMicrosecondM);
    EXPECT_NEAR(p.y_m, truth.y_m, kWholeMicrosecondM);
    // The logger stamps receipt, which comes after the sample's time.
    EXPECT_GE(e.utime, p.utime);
    ++poses;
  }
  EXPECT_GE(poses, 30);
  EXPECT_GE(beats, 1);
}

// Plays `path` with the real lcm-logplayer and checks that a subscriber on
// the default multicast URL receives every event, byte for byte, in order.
void ExpectLogplayerDeliversEveryEvent(const std::string& path) {
  const auto expected = ReadAll(path);
  ASSERT_FALSE(expected.empty());
  std::string error;
  auto bus = LcmBus::Create(kDefaultLcmUrl, &error);
  ASSERT_NE(bus, nullptr) << error;
  std::vector<std::pair<std::string, std::vector<uint8_t>>> received;
  bus->SubscribeRaw(".*", [&](const MessageInfo& info, const void* data, int size) {
    const auto* b = static_cast<const uint8_t*>(data);
    received.emplace_back(info.channel, std::vector<uint8_t>(b, b + size));
  });

  ChildProcess player({"lcm-logplayer", "--speed=4", path});
  ASSERT_TRUE(player.started()) << "lcm-logplayer not found (liblcm-bin)";
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  while (received.size() < expected.size() && std::chrono::steady_clock::now() < deadline) {
    bus->Handle(50);
  }
  EXPECT_EQ(player.Wait(10), 0);
  ASSERT_EQ(received.size(), expected.size());
  for (size_t i = 0; i < expected.size(); ++i) {
    EXPECT_EQ(received[i].first, expected[i].channel) << "event " << i;
    EXPECT_EQ(received[i].second, expected[i].data) << "event " << i;
  }
}

TEST(LcmLogplayer, PlaysEveryEventOfTheSampleLogIntactAndInOrder) {
  ExpectLogplayerDeliversEveryEvent(SampleLog());
}

// Logs written by roomfix's LogWriter are ordinary LCM logs.
TEST(LcmLogplayer, PlaysALogWrittenByLogWriter) {
  testing::TempDir dir;
  const std::string path = dir.File("written.lcm");
  std::string error;
  auto writer = LogWriter::Create(path, false, &error);
  ASSERT_NE(writer, nullptr) << error;
  for (int i = 0; i < 50; ++i) {
    pose2d_t p{};
    p.utime = 1700000000000000 + i * 20000;
    p.source = pose2d_t::SOURCE_CAMERA;
    p.robot_id = i % 3;
    p.x_m = 0.01 * i;
    p.y_m = -0.02 * i;
    p.heading_rad = 0.1 * i;
    std::vector<uint8_t> bytes(p.getEncodedSize());
    p.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
    ASSERT_TRUE(writer->Write(p.utime, i % 2 ? "POSE_CAMERA" : "POSE_FUSED", bytes.data(),
                              static_cast<int>(bytes.size()), &error))
        << error;
  }
  writer.reset();  // Closes the file.
  ExpectLogplayerDeliversEveryEvent(path);
}

}  // namespace
}  // namespace roomfix
