// Every tool that reads a log, run as a process on a log damaged four ways
// (the audit's 0x7FFFFFFF event, garbage in the middle, an empty-channel
// event, a truncated end): none crashes, each reads every good event after
// the damage and prints one line naming the bytes skipped.
#include <gtest/gtest.h>

#include <algorithm>
#include <nlohmann/json.hpp>
#include <sstream>

#include "roomfix/pose2d_t.hpp"
#include "roomfix/range_set_t.hpp"
#include "tests/testing/demo_site.h"
#include "tests/testing/raw_log_event.h"
#include "tests/testing/test_messages.h"
#include "tests/testing/test_paths.h"

namespace roomfix {
namespace {

using nlohmann::json;
using testing::BinDir;
using testing::ChildProcess;
using testing::MakeTestPose;
using testing::ReadFile;
using testing::TempDir;

constexpr int64_t kT0 = 1'700'000'000'000'000;
// Poses per source on each side of the damage.
constexpr int kPosesPerHalf = 10;

std::string RawEvent(int64_t eventnum, int64_t utime, const std::string& channel,
                     const std::string& data, int32_t channel_bytes, int32_t data_bytes) {
  return testing::RawLogEvent(eventnum, utime, channel, data, channel_bytes, data_bytes);
}

std::string PoseEvent(int k, int8_t source, const std::string& channel) {
  pose2d_t p = MakeTestPose(kT0 + k * 100'000, 1, 1.0 + 0.01 * k, 2.0);
  p.source = source;
  std::string bytes(static_cast<size_t>(p.getEncodedSize()), '\0');
  p.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
  return RawEvent(k, kT0 + k * 100'000 + 500, channel, bytes, static_cast<int32_t>(channel.size()),
                  static_cast<int32_t>(bytes.size()));
}

// kPosesPerHalf ground-truth and ultrasound poses of robot 1, starting at k.
std::string Poses(int k0) {
  std::string out;
  for (int k = k0; k < k0 + kPosesPerHalf; ++k) {
    out += PoseEvent(k, pose2d_t::SOURCE_GROUND_TRUTH, "POSE_GROUND_TRUTH");
    out += PoseEvent(k, pose2d_t::SOURCE_ULTRASOUND, "POSE_ULTRASOUND");
  }
  return out;
}

struct DamagedLog {
  std::string name;
  std::string bytes;
  // Good events in it, bytes the reader must skip, and the reason it names.
  int good_events;
  int64_t skipped;
  std::string reason;
};

std::vector<DamagedLog> DamagedLogs() {
  std::vector<DamagedLog> logs;
  const std::string before = Poses(0);
  const std::string after = Poses(kPosesPerHalf);
  const std::string huge = RawEvent(99, kT0, "POSE_ULTRASOUND", "12345678", 15, 0x7FFFFFFF);
  logs.push_back({"huge_event", before + huge + after, 4 * kPosesPerHalf,
                  static_cast<int64_t>(huge.size()), "data_length_over_cap"});
  std::string garbage(700, '\0');
  for (size_t i = 0; i < garbage.size(); ++i) garbage[i] = static_cast<char>(i * 131 + 7);
  logs.push_back({"garbage", before + garbage + after, 4 * kPosesPerHalf,
                  static_cast<int64_t>(garbage.size()), "not_an_event"});
  const std::string empty = RawEvent(99, kT0, "", "abcdef", 0, 6);
  logs.push_back({"empty_channel", before + empty + after, 4 * kPosesPerHalf,
                  static_cast<int64_t>(empty.size()), "bad_channel_length"});
  const std::string last = PoseEvent(999, pose2d_t::SOURCE_ULTRASOUND, "POSE_ULTRASOUND");
  logs.push_back({"truncated", before + after + last.substr(0, last.size() - 9), 4 * kPosesPerHalf,
                  static_cast<int64_t>(last.size() - 9), "truncated"});
  return logs;
}

struct ToolRun {
  int exit_code = -1;
  std::string out;
  std::string err;
};

// Runs a program; stdout and stderr are captured separately.
ToolRun RunTool(const TempDir& dir, const std::vector<std::string>& argv) {
  std::string command = "exec";
  for (const std::string& a : argv) command += " '" + a + "'";
  command += " 2>'" + dir.File("err.txt") + "'";
  ChildProcess p({"/bin/sh", "-c", command}, dir.File("out.txt"));
  ToolRun r;
  r.exit_code = p.Wait(120);
  r.out = ReadFile(dir.File("out.txt"));
  r.err = ReadFile(dir.File("err.txt"));
  return r;
}

// The one warning line: the tool's name, the file, the bytes and the reason.
void ExpectOneDamageLine(const ToolRun& r, const std::string& tool, const DamagedLog& log) {
  const std::string needle = "skipped " + std::to_string(log.skipped) + " bytes in 1 region (" +
                             log.reason + " 1): at byte ";
  size_t lines = 0;
  std::istringstream err(r.err);
  std::string line;
  while (std::getline(err, line)) {
    if (line.find(needle) == std::string::npos) continue;
    ++lines;
    EXPECT_NE(line.find(tool), std::string::npos) << line;
    EXPECT_NE(line.find(log.name + ".lcm"), std::string::npos) << line;
  }
  EXPECT_EQ(lines, 1u) << "stderr of " << tool << " on " << log.name << ":\n" << r.err;
}

class DamagedLogTest : public ::testing::TestWithParam<DamagedLog> {
 protected:
  void SetUp() override {
    path_ = dir_.File(GetParam().name + ".lcm");
    ASSERT_TRUE(testing::WriteFile(path_, GetParam().bytes));
  }
  TempDir dir_;
  std::string path_;
};

TEST_P(DamagedLogTest, LogInfoCountsEveryGoodEventAndSaysWhatItSkipped) {
  const ToolRun r = RunTool(dir_, {BinDir() + "/roomfix", "log-info", path_});
  EXPECT_EQ(r.exit_code, 2) << r.err;  // Damaged, not failed.
  EXPECT_NE(r.out.find(": " + std::to_string(GetParam().good_events) + " events"),
            std::string::npos)
      << r.out;
  ExpectOneDamageLine(r, "roomfix log-info", GetParam());
}

TEST_P(DamagedLogTest, AnalyzeUsesThePosesOnBothSidesOfTheDamage) {
  const ToolRun r = RunTool(dir_, {BinDir() + "/roomfix", "analyze", path_, "--json",
                                   "--no-figures", "--out", dir_.File("analysis")});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const json out = json::parse(r.out, nullptr, false);
  ASSERT_FALSE(out.is_discarded()) << r.out;
  EXPECT_EQ(out["logs"][0]["events"], GetParam().good_events);
  EXPECT_EQ(out["logs"][0]["bytes_skipped"], GetParam().skipped);
  EXPECT_EQ(out["robots"]["1"]["ultrasound"]["fixes"], 2 * kPosesPerHalf);
  ExpectOneDamageLine(r, "roomfix analyze", GetParam());
}

TEST_P(DamagedLogTest, CompareComparesThePosesOnBothSidesOfTheDamage) {
  const ToolRun r =
      RunTool(dir_, {BinDir() + "/roomfix", "compare", path_, "--json", dir_.File("c.json")});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const json out = json::parse(ReadFile(dir_.File("c.json")), nullptr, false);
  ASSERT_FALSE(out.is_discarded());
  EXPECT_EQ(out["sources"]["ultrasound"]["fixes"], 2 * kPosesPerHalf);
  ExpectOneDamageLine(r, "roomfix compare", GetParam());
}

// LCM's file:// provider SIGSEGVs on the 0x7FFFFFFF event; listen reads
// file:// URLs with LogReader.
TEST_P(DamagedLogTest, ListenOnAFileUrlPrintsEveryGoodEvent) {
  const ToolRun r = RunTool(dir_, {BinDir() + "/roomfix", "listen", "--lcm-url",
                                   "file://" + path_ + "?speed=0", "--channel", "POSE_ULTRASOUND"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  std::istringstream lines(r.out);
  std::string line;
  int poses = 0;
  while (std::getline(lines, line)) {
    const json j = json::parse(line, nullptr, false);
    ASSERT_FALSE(j.is_discarded()) << line;
    EXPECT_EQ(j["channel"], "POSE_ULTRASOUND");
    EXPECT_TRUE(j.contains("message")) << line;
    ++poses;
  }
  EXPECT_EQ(poses, 2 * kPosesPerHalf);
  ExpectOneDamageLine(r, "roomfix listen", GetParam());
}

TEST_P(DamagedLogTest, TheViewerReplaysItHeadless) {
  const ToolRun r =
      RunTool(dir_, {BinDir() + "/roomfix_viewer", "--config", testing::DemoSitePath(), "--log",
                     path_, "--headless", "--png", dir_.File("end.png")});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("replayed every good event"), std::string::npos) << r.err;
  ExpectOneDamageLine(r, "roomfix_viewer", GetParam());
  EXPECT_GT(ReadFile(dir_.File("end.png")).size(), 1000u);
}

// Survey needs minutes of ranges to fit; here only that it reads the RANGES
// around the damage and reports it instead of dying.
TEST_P(DamagedLogTest, SurveyReadsAroundTheDamageAndSaysSo) {
  std::string bytes = GetParam().bytes;
  range_set_t set{};
  set.utime = kT0;
  set.beacon_id = 1;
  set.speed_of_sound_mps = 343.0;
  set.num_ranges = 0;
  std::string encoded(static_cast<size_t>(set.getEncodedSize()), '\0');
  set.encode(encoded.data(), 0, static_cast<int>(encoded.size()));
  const std::string ranges =
      RawEvent(0, kT0, "RANGES", encoded, 6, static_cast<int32_t>(encoded.size()));
  ASSERT_TRUE(testing::WriteFile(path_, ranges + bytes));
  const ToolRun r = RunTool(dir_, {BinDir() + "/roomfix", "survey", path_, "--site",
                                   testing::DemoSitePath(), "--reference", "ground_truth"});
  EXPECT_LT(r.exit_code, 128) << "killed by a signal: " << r.err;
  ExpectOneDamageLine(r, "roomfix survey", GetParam());
}

// roomfix replay re-solves every range set on both sides of the damage.
TEST_P(DamagedLogTest, ReplayRunsAroundTheDamageAndSaysSo) {
  const ToolRun r =
      RunTool(dir_, {BinDir() + "/roomfix", "replay", path_, "--out", dir_.File("replayed.lcm"),
                     "--config", testing::DemoSitePath(), "--json"});
  ASSERT_EQ(r.exit_code, 0) << r.err;  // Damaged, and replayed.
  const json out = json::parse(r.out, nullptr, false);
  ASSERT_FALSE(out.is_discarded()) << r.out;
  EXPECT_EQ(out["events_read"], GetParam().good_events);
  EXPECT_EQ(out["bytes_skipped"], GetParam().skipped);
  EXPECT_EQ(out["damage_regions"], 1);
  ExpectOneDamageLine(r, "roomfix replay", GetParam());
}

// Any process can be pointed at a log with --lcm-url file://...; it reads
// through LogFileBus (LCM's file provider SIGSEGVs on the 0x7FFFFFFF event)
// and, as with LCM's provider, stops with exit 1 at the end of the log.
TEST_P(DamagedLogTest, AProcessReadingItAsItsLcmUrlReachesTheEnd) {
  const ToolRun r = RunTool(dir_, {BinDir() + "/trilat_proc", "--config", testing::DemoSitePath(),
                                   "--lcm-url", "file://" + path_ + "?speed=0"});
  EXPECT_EQ(r.exit_code, 1) << r.err;
  EXPECT_NE(r.err.find("end of log " + path_), std::string::npos) << r.err;
  ExpectOneDamageLine(r, "trilat_proc", GetParam());
}

// roomfix export writes a row for every good event on both sides of the
// damage, lists the damage in _damage.csv and exits 2 (damaged, exported).
TEST_P(DamagedLogTest, ExportWritesEveryGoodEventAndListsTheDamage) {
  const ToolRun r =
      RunTool(dir_, {BinDir() + "/roomfix", "export", path_, "--csv", dir_.File("csv")});
  EXPECT_EQ(r.exit_code, 2) << r.err;
  for (const char* channel : {"POSE_GROUND_TRUTH", "POSE_ULTRASOUND"}) {
    const std::string csv = ReadFile(dir_.File("csv") + "/" + channel + ".csv");
    // A header line, then one line per pose.
    EXPECT_EQ(std::count(csv.begin(), csv.end(), '\n'), 1 + 2 * kPosesPerHalf) << channel;
  }
  const std::string damage = ReadFile(dir_.File("csv/_damage.csv"));
  EXPECT_EQ(std::count(damage.begin(), damage.end(), '\n'), 2) << damage;
  EXPECT_NE(damage.find("," + std::to_string(GetParam().skipped) + "," + GetParam().reason + ","),
            std::string::npos)
      << damage;
  ExpectOneDamageLine(r, "roomfix export", GetParam());
}

INSTANTIATE_TEST_SUITE_P(Damage, DamagedLogTest, ::testing::ValuesIn(DamagedLogs()),
                         [](const auto& param_info) { return param_info.param.name; });

}  // namespace
}  // namespace roomfix
