// The tools that decode a log's messages with no STATUS of their own
// (`roomfix listen`, `analyze`): issue #15's hostile messages are refused and
// reported on stderr with their count per reason, and every good message
// around them is still read.
#include <gtest/gtest.h>

#include <climits>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "msgio/log.h"
#include "roomfix/marker_pixels_t.hpp"
#include "roomfix/pose2d_t.hpp"
#include "roomfix/process_status_t.hpp"
#include "tests/testing/test_paths.h"
#include "tests/testing/wire_test_messages.h"

namespace roomfix {
namespace {

using nlohmann::json;
using testing::BinDir;
using testing::ChildProcess;
using testing::ReadFile;
using testing::TempDir;

// A log of good messages with issue #15's crash inputs between them: a STATUS
// whose string length is INT32_MIN, a 52-byte RANGES claiming 2^24 ranges,
// and a pose cut short.
void WriteHostileLog(const std::string& path) {
  std::string error;
  auto log = LogWriter::Create(path, true, &error);
  ASSERT_NE(log, nullptr) << error;
  auto write = [&](int64_t utime, const std::string& channel, const std::vector<uint8_t>& bytes) {
    ASSERT_TRUE(log->Write(utime, channel, bytes.data(), static_cast<int>(bytes.size()), &error))
        << error;
  };
  std::vector<uint8_t> status = testing::Encode(testing::MakeTestStatus());
  std::vector<uint8_t> hostile_status = status;
  testing::PutInt32(&hostile_status, testing::kStatusProcessLengthOffset, INT32_MIN);
  std::vector<uint8_t> hostile_ranges = testing::Encode(testing::MakeTestRangeSet(0));
  testing::PutInt32(&hostile_ranges, testing::kRangeSetNumRangesOffset, 1 << 24);
  std::vector<uint8_t> pose = testing::Encode(testing::MakeTestPose(1700000000000000, 1, 1.0, 2.0));
  std::vector<uint8_t> cut_pose(pose.begin(), pose.end() - 10);

  write(1700000000000000, "STATUS", status);
  write(1700000000100000, "STATUS", hostile_status);
  write(1700000000200000, "RANGES", hostile_ranges);
  write(1700000000300000, "POSE_GROUND_TRUTH", cut_pose);
  write(1700000000400000, "POSE_GROUND_TRUTH", pose);
  ASSERT_TRUE(log->Flush(&error)) << error;
}

struct ToolRun {
  int exit_code = -1;
  std::string out;
  std::string err;
};

ToolRun RunRoomfix(const TempDir& dir, const std::string& args) {
  ToolRun run;
  ChildProcess p(
      {"sh", "-c", "exec '" + BinDir() + "/roomfix' " + args + " 2>'" + dir.File("err.txt") + "'"},
      dir.File("out.txt"));
  run.exit_code = p.Wait(120);
  run.out = ReadFile(dir.File("out.txt"));
  run.err = ReadFile(dir.File("err.txt"));
  return run;
}

// `roomfix analyze --json` of the log `name` in `dir`, its report beside it.
ToolRun AnalyzeJson(const TempDir& dir, const std::string& name) {
  return RunRoomfix(dir, "analyze --json --no-figures --out '" + dir.File("report") + "' '" +
                             dir.File(name) + "'");
}

TEST(RoomfixListen, RefusesHostileMessagesInALogAndCountsThemByReason) {
  TempDir dir;
  WriteHostileLog(dir.File("hostile.lcm"));
  const ToolRun run =
      RunRoomfix(dir, "listen --lcm-url 'file://" + dir.File("hostile.lcm") + "?speed=0'");
  ASSERT_EQ(run.exit_code, 0) << run.err;
  std::vector<json> lines;
  std::istringstream out(run.out);
  for (std::string line; std::getline(out, line);) lines.push_back(json::parse(line));
  ASSERT_EQ(lines.size(), 5u) << run.out;
  EXPECT_EQ(lines[0]["message"]["process"], "trilat_proc");
  EXPECT_EQ(lines[1]["refused"], "negative_length");
  EXPECT_EQ(lines[2]["refused"], "count_over_cap");
  EXPECT_EQ(lines[3]["refused"], "truncated");
  EXPECT_EQ(lines[4]["message"]["x_m"], 1.0);
  EXPECT_NE(run.err.find("roomfix listen: warning: 3 messages refused (1 count_over_cap, 1 "
                         "negative_length, 1 truncated)\n"),
            std::string::npos)
      << run.err;
}

// A channel name is the publisher's: quotes, backslashes, control bytes
// (not NUL: no log holds it) and bytes that are not UTF-8 still give lines
// of valid JSON that read back to the name (U+FFFD for what is not UTF-8);
// an ordinary line keeps its bytes.
TEST(RoomfixListen, EscapesEveryChannelNameIntoValidJson) {
  TempDir dir;
  const std::string path = dir.File("names.lcm");
  const std::vector<uint8_t> pose =
      testing::Encode(testing::MakeTestPose(1700000000000000, 1, 1.0, 2.0));
  const std::vector<std::string> names = {"POSE_GROUND_TRUTH", "say \"hi\"", "back\\slash",
                                          "bell\a\x1f\x7f tab\t", "bad \xff\xfe utf8"};
  {
    std::string error;
    auto log = LogWriter::Create(path, true, &error);
    ASSERT_NE(log, nullptr) << error;
    for (size_t i = 0; i < names.size(); ++i) {
      ASSERT_TRUE(log->Write(1700000000000000 + static_cast<int64_t>(i), names[i], pose.data(),
                             static_cast<int>(pose.size()), &error))
          << error;
    }
    ASSERT_TRUE(log->Flush(&error)) << error;
  }
  const ToolRun run = RunRoomfix(dir, "listen --lcm-url 'file://" + path + "?speed=0'");
  ASSERT_EQ(run.exit_code, 0) << run.err;
  std::vector<std::string> lines;
  std::istringstream out(run.out);
  for (std::string line; std::getline(out, line);) lines.push_back(line);
  ASSERT_EQ(lines.size(), names.size()) << run.out;
  std::vector<std::string> read_back;
  for (const std::string& line : lines) {
    json parsed;
    ASSERT_NO_THROW(parsed = json::parse(line)) << line;
    EXPECT_EQ(parsed["message"]["x_m"], 1.0) << line;
    read_back.push_back(parsed["channel"]);
  }
  EXPECT_EQ(read_back[0], names[0]);
  EXPECT_EQ(read_back[1], names[1]);
  EXPECT_EQ(read_back[2], names[2]);
  EXPECT_EQ(read_back[3], names[3]);
  EXPECT_EQ(read_back[4], "bad \xef\xbf\xbd\xef\xbf\xbd utf8");
  EXPECT_EQ(lines[0].rfind(R"({"channel":"POSE_GROUND_TRUTH","recv_utime":1700000000000000,)"
                           R"("message":{"type":"roomfix.pose2d_t","utime":1700000000000000,)",
                           0),
            0u)
      << lines[0];
}

TEST(RoomfixAnalyze, ReportsARefusedPoseOnStderrAndReadsTheRest) {
  TempDir dir;
  WriteHostileLog(dir.File("hostile.lcm"));
  const ToolRun run = AnalyzeJson(dir, "hostile.lcm");
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const json summary = json::parse(run.out);
  EXPECT_EQ(summary["logs"][0]["pose_events"], 2);
  EXPECT_EQ(summary["logs"][0]["undecodable"], 1);
  EXPECT_EQ(summary["logs"][0]["refused"], (json{{"truncated", 1}}));
  EXPECT_NE(run.err.find(": 1 POSE_* events refused (1 truncated)\n"), std::string::npos)
      << run.err;
}

// A log whose messages are each well formed but for one enum-valued field
// outside its .lcm constants, one per message type that has enums, between
// good ones: a pose with status 7 ("ok" to a reader that only compares with
// LOST and DEGRADED), a pose with source -1, MARKER_PIXELS with search mode 5
// and with a marker role of 3, STATUS with state 9.
void WriteBadEnumLog(const std::string& path) {
  std::string error;
  auto log = LogWriter::Create(path, true, &error);
  ASSERT_NE(log, nullptr) << error;
  int64_t utime = 1700000000000000;
  auto write = [&](const std::string& channel, const std::vector<uint8_t>& bytes) {
    utime += 100000;
    ASSERT_TRUE(log->Write(utime, channel, bytes.data(), static_cast<int>(bytes.size()), &error))
        << error;
  };
  pose2d_t bad_status = testing::MakeTestPose(1700000000000000, 1, 1.0, 2.0);
  bad_status.source = pose2d_t::SOURCE_CAMERA;
  bad_status.status = 7;
  pose2d_t bad_source = bad_status;
  bad_source.utime += 100000;
  bad_source.status = pose2d_t::STATUS_OK;
  bad_source.source = -1;
  pose2d_t good = bad_source;
  good.utime += 100000;
  good.source = pose2d_t::SOURCE_CAMERA;
  marker_pixels_t bad_mode = testing::MakeTestMarkerPixels();
  bad_mode.search_mode = 5;
  marker_pixels_t bad_role = testing::MakeTestMarkerPixels();
  bad_role.frame_seq += 1;
  bad_role.markers[0].role = 3;
  marker_pixels_t good_pixels = testing::MakeTestMarkerPixels();
  good_pixels.frame_seq += 2;
  process_status_t bad_state = testing::MakeTestStatus();
  bad_state.state = 9;

  write("POSE_CAMERA", testing::Encode(bad_status));
  write("POSE_CAMERA", testing::Encode(bad_source));
  write("POSE_CAMERA", testing::Encode(good));
  write("MARKER_PIXELS", testing::Encode(bad_mode));
  write("MARKER_PIXELS", testing::Encode(bad_role));
  write("MARKER_PIXELS", testing::Encode(good_pixels));
  write("STATUS", testing::Encode(bad_state));
  ASSERT_TRUE(log->Flush(&error)) << error;
}

TEST(RoomfixAnalyze, RefusesPosesWithAStatusOrSourceOutsideTheEnum) {
  TempDir dir;
  WriteBadEnumLog(dir.File("enums.lcm"));
  const ToolRun run = AnalyzeJson(dir, "enums.lcm");
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const json summary = json::parse(run.out);
  EXPECT_EQ(summary["logs"][0]["pose_events"], 3);
  EXPECT_EQ(summary["logs"][0]["undecodable"], 2);
  EXPECT_EQ(summary["logs"][0]["refused"], (json{{"enum_out_of_range", 2}}));
  EXPECT_NE(run.err.find(": 2 POSE_* events refused (2 enum_out_of_range)\n"), std::string::npos)
      << run.err;
}

TEST(RoomfixListen, RefusesEveryMessageTypeWithAnEnumOutsideItsConstants) {
  TempDir dir;
  WriteBadEnumLog(dir.File("enums.lcm"));
  const ToolRun run =
      RunRoomfix(dir, "listen --lcm-url 'file://" + dir.File("enums.lcm") + "?speed=0'");
  ASSERT_EQ(run.exit_code, 0) << run.err;
  std::vector<json> lines;
  std::istringstream out(run.out);
  for (std::string line; std::getline(out, line);) lines.push_back(json::parse(line));
  ASSERT_EQ(lines.size(), 7u) << run.out;
  for (size_t i : {0, 1, 3, 4, 6}) EXPECT_EQ(lines[i]["refused"], "enum_out_of_range") << i;
  EXPECT_EQ(lines[2]["message"]["status"], pose2d_t::STATUS_OK);
  EXPECT_EQ(lines[5]["message"]["frame_seq"], 101);
  EXPECT_NE(run.err.find("roomfix listen: warning: 5 messages refused (5 enum_out_of_range)\n"),
            std::string::npos)
      << run.err;
}

// log-info counts a camera's frames from MARKER_PIXELS: a refused one is not
// a frame, and is said on stderr rather than dropped without a word.
TEST(RoomfixLogInfo, CountsOnlyGoodFramesAndReportsTheRefusedOnes) {
  TempDir dir;
  WriteBadEnumLog(dir.File("enums.lcm"));
  const ToolRun run = RunRoomfix(dir, "log-info '" + dir.File("enums.lcm") + "'");
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_NE(run.out.find("camera 1: 1 frames (seq 101..101)"), std::string::npos) << run.out;
  EXPECT_NE(run.err.find("roomfix log-info: warning: 3 MARKER_PIXELS and STATUS events refused "
                         "(3 enum_out_of_range)\n"),
            std::string::npos)
      << run.err;
}

}  // namespace
}  // namespace roomfix
