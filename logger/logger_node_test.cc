#include "logger/logger_node.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <lcm/lcm-cpp.hpp>
#include <sstream>

#include "tests/testing/test_paths.h"

namespace roomfix {
namespace {

using testing::ChildProcess;
using testing::ReadFile;
using testing::TempDir;

std::vector<LogEvent> ReadAll(const std::string& path) {
  std::vector<LogEvent> events;
  std::string error;
  EXPECT_TRUE(ReadLogEvents(path, &events, &error)) << error;
  return events;
}

std::vector<uint8_t> Payload(int k, int size) {
  std::vector<uint8_t> b(size);
  for (int i = 0; i < size; ++i) b[i] = static_cast<uint8_t>(k * 31 + i);
  return b;
}

class LoggerNodeTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string error;
    bus_ = LcmBus::Create("memq://", &error);
    ASSERT_NE(bus_, nullptr) << error;
  }
  void Publish(int n, int size, const std::string& channel = "DATA") {
    for (int k = 0; k < n; ++k) {
      const auto b = Payload(k, size);
      bus_->PublishRaw(channel, b.data(), size);
      while (bus_->Handle(0) > 0) {
      }
    }
  }
  TempDir dir_;
  std::unique_ptr<LcmBus> bus_;
};

TEST_F(LoggerNodeTest, RecordsEveryEventWithItsChannelPayloadAndReceiveTime) {
  LoggerOptions o;
  o.path = dir_.File("a.lcm");
  std::string error;
  auto node = LoggerNode::Create(bus_.get(), o, 0, &error);
  ASSERT_NE(node, nullptr) << error;
  Publish(500, 40, "POSE_A");
  Publish(500, 7, "RANGES");
  node->Stop(1);
  const auto events = ReadAll(o.path);
  ASSERT_EQ(events.size(), 1000u);
  for (size_t i = 0; i < events.size(); ++i) {
    EXPECT_EQ(events[i].eventnum, static_cast<int64_t>(i));
    EXPECT_EQ(events[i].channel, i < 500 ? "POSE_A" : "RANGES");
    EXPECT_EQ(events[i].data, Payload(static_cast<int>(i % 500), i < 500 ? 40 : 7));
    EXPECT_GT(events[i].utime, 1500000000000000);
    if (i > 0) {
      EXPECT_GE(events[i].utime, events[i - 1].utime);
    }
  }
  EXPECT_EQ(node->status().inputs(), 1000);
  EXPECT_EQ(node->status().outputs(), 1000);
  EXPECT_EQ(node->status().dropped(), 0);
}

TEST_F(LoggerNodeTest, RecordsOnlyTheChosenChannels) {
  LoggerOptions o;
  o.path = dir_.File("a.lcm");
  o.channel_regex = "POSE_.*";
  std::string error;
  auto node = LoggerNode::Create(bus_.get(), o, 0, &error);
  ASSERT_NE(node, nullptr) << error;
  Publish(10, 8, "POSE_CAMERA");
  Publish(10, 8, "STATUS");
  Publish(10, 8, "XPOSE_CAMERA");
  node->Stop(1);
  EXPECT_EQ(ReadAll(o.path).size(), 10u);
}

TEST_F(LoggerNodeTest, RefusesToOverwriteAnExistingLogUnlessTold) {
  LoggerOptions o;
  o.path = dir_.File("a.lcm");
  ASSERT_TRUE(testing::WriteFile(o.path, "precious"));
  std::string error;
  EXPECT_EQ(LoggerNode::Create(bus_.get(), o, 0, &error), nullptr);
  EXPECT_EQ(error, o.path + ": already exists (refusing to overwrite)");
  EXPECT_EQ(testing::ReadFile(o.path), "precious");
  o.overwrite = true;
  EXPECT_NE(LoggerNode::Create(bus_.get(), o, 0, &error), nullptr);
}

TEST_F(LoggerNodeTest, ADatedNameLetsARestartedLoggerStartAFreshFile) {
  // 2026-11-22 23:59:58 UTC and two seconds later: two files, nothing
  // refused, nothing overwritten.
  constexpr int64_t kFirstUtime = 1'795'391'998'000'000;
  LoggerOptions o;
  o.path = dir_.File("roomfix-%Y%m%d-%H%M%S.lcm");
  std::string error;
  auto first = LoggerNode::Create(bus_.get(), o, kFirstUtime, &error);
  ASSERT_NE(first, nullptr) << error;
  auto second = LoggerNode::Create(bus_.get(), o, kFirstUtime + 2'000'000, &error);
  ASSERT_NE(second, nullptr) << error;
  EXPECT_EQ(first->files(), std::vector<std::string>{dir_.File("roomfix-20261122-235958.lcm")});
  EXPECT_EQ(second->files(), std::vector<std::string>{dir_.File("roomfix-20261123-000000.lcm")});
}

// Issue #18: bot-procman restarted the demo's logger, which had --force, and
// the restart replaced a whole demo log with 13 KB. With --increment a
// restart writes the next numbered file and the first stays byte for byte.
TEST_F(LoggerNodeTest, IncrementLetsARestartedLoggerKeepTheFirstLogIntact) {
  LoggerOptions o;
  o.path = dir_.File("sim_demo.lcm");
  o.increment = true;
  std::string error;
  auto first = LoggerNode::Create(bus_.get(), o, 0, &error);
  ASSERT_NE(first, nullptr) << error;
  Publish(200, 40, "POSE_A");
  first->Stop(1);
  // A restart is a new process: a new node on a bus of its own.
  first.reset();
  bus_ = LcmBus::Create("memq://", &error);
  ASSERT_NE(bus_, nullptr) << error;
  const std::string first_path = dir_.File("sim_demo-00.lcm");
  ASSERT_EQ(ReadAll(first_path).size(), 200u);
  const std::string first_bytes = ReadFile(first_path);

  auto restarted = LoggerNode::Create(bus_.get(), o, 2, &error);
  ASSERT_NE(restarted, nullptr) << error;
  Publish(7, 40, "POSE_A");
  restarted->Stop(3);
  EXPECT_EQ(restarted->files(), std::vector<std::string>{dir_.File("sim_demo-01.lcm")});
  EXPECT_EQ(ReadAll(dir_.File("sim_demo-01.lcm")).size(), 7u);
  EXPECT_EQ(ReadFile(first_path), first_bytes);
  EXPECT_FALSE(std::filesystem::exists(o.path));
}

// A gap left by a deleted log is taken (the first free number), and a
// rotating run keeps one number for all its files.
TEST_F(LoggerNodeTest, IncrementTakesTheFirstFreeNumberAndARunKeepsIt) {
  ASSERT_TRUE(testing::WriteFile(dir_.File("s-00.0000.lcm"), "older run"));
  ASSERT_TRUE(testing::WriteFile(dir_.File("s-02.0000.lcm"), "older run"));
  LoggerOptions o;
  o.path = dir_.File("s.lcm");
  o.increment = true;
  o.rotate_bytes = 1000;
  std::string error;
  auto node = LoggerNode::Create(bus_.get(), o, 0, &error);
  ASSERT_NE(node, nullptr) << error;
  Publish(40, 100);
  node->Stop(1);
  const auto files = node->files();
  ASSERT_GE(files.size(), 3u);  // 40 x ~133 bytes in files of about 1000.
  for (size_t i = 0; i < files.size(); ++i) {
    EXPECT_EQ(files[i], RotatedLogPath(dir_.File("s-01.lcm"), static_cast<int>(i)));
  }
  EXPECT_EQ(ReadFile(dir_.File("s-00.0000.lcm")), "older run");
  EXPECT_EQ(ReadFile(dir_.File("s-02.0000.lcm")), "older run");
}

TEST_F(LoggerNodeTest, RotatesBySizeIntoNumberedFilesWithoutLosingAnEvent) {
  LoggerOptions o;
  o.path = dir_.File("session.lcm");
  o.rotate_bytes = 4000;
  std::string error;
  auto node = LoggerNode::Create(bus_.get(), o, 0, &error);
  ASSERT_NE(node, nullptr) << error;
  Publish(300, 100);
  node->Stop(1);
  const auto files = node->files();
  ASSERT_GE(files.size(), 7u);  // 300 x ~133 bytes in files of about 4000.
  EXPECT_EQ(files[0], dir_.File("session.0000.lcm"));
  EXPECT_EQ(files[1], dir_.File("session.0001.lcm"));
  size_t total = 0;
  int k = 0;
  for (const auto& f : files) {
    const auto events = ReadAll(f);
    EXPECT_LE(std::filesystem::file_size(f), 4000u + 133u) << f;
    for (const auto& e : events) EXPECT_EQ(e.data, Payload(k++, 100));
    if (!events.empty()) {
      EXPECT_EQ(events[0].eventnum, 0);  // Each file counts from 0.
    }
    total += events.size();
  }
  EXPECT_EQ(total, 300u);
}

TEST_F(LoggerNodeTest, AFullDiskIsReportedAndCountedNotACrash) {
  LoggerOptions o;
  o.path = "/dev/full";  // Every write fails with ENOSPC.
  o.overwrite = true;
  std::string error;
  auto node = LoggerNode::Create(bus_.get(), o, 0, &error);
  ASSERT_NE(node, nullptr) << error;
  Publish(2000, 64);
  node->Stop(1);
  const process_status_t s = node->status().Make(2, nullptr);
  EXPECT_EQ(s.state, process_status_t::STATE_FAILED);
  EXPECT_NE(s.last_error.find("No space left on device"), std::string::npos) << s.last_error;
  EXPECT_GT(s.dropped, 0);
  EXPECT_EQ(s.inputs, 2000);
}

TEST_F(LoggerNodeTest, DropsAndCountsWhatTheQueueCannotHold) {
  LoggerOptions o;
  o.path = dir_.File("a.lcm");
  o.max_queue_bytes = 50;  // A 100-byte message can never be queued.
  std::string error;
  auto node = LoggerNode::Create(bus_.get(), o, 0, &error);
  ASSERT_NE(node, nullptr) << error;
  Publish(3, 100);
  Publish(3, 10);
  node->Stop(1);
  EXPECT_EQ(node->status().dropped(), 3);
  EXPECT_EQ(ReadAll(o.path).size(), 3u);
}

// The bus must not call into a destroyed node: it used to stay subscribed,
// and the next message ran its handler on freed memory. Another subscriber
// on the same bus still receives every message.
TEST_F(LoggerNodeTest, ADestroyedNodeReceivesNothingMore) {
  int other_received = 0;
  bus_->SubscribeRaw("DATA", [&](const MessageInfo&, const void*, int) { ++other_received; });
  LoggerOptions o;
  o.path = dir_.File("a.lcm");
  std::string error;
  auto node = LoggerNode::Create(bus_.get(), o, 0, &error);
  ASSERT_NE(node, nullptr) << error;
  Publish(3, 10);
  EXPECT_EQ(bus_->stats().received, 2 * 3) << "the node and the other subscriber";
  node.reset();
  Publish(5, 10);
  EXPECT_EQ(other_received, 3 + 5);
  EXPECT_EQ(bus_->stats().received, 2 * 3 + 5) << "only the other subscriber after the node";
  EXPECT_EQ(ReadAll(o.path).size(), 3u);
}

// Stop ends the recording: what arrives after it is neither written nor
// counted as an input (it would otherwise wait in a queue no one drains).
TEST_F(LoggerNodeTest, StopEndsReceiving) {
  LoggerOptions o;
  o.path = dir_.File("a.lcm");
  std::string error;
  auto node = LoggerNode::Create(bus_.get(), o, 0, &error);
  ASSERT_NE(node, nullptr) << error;
  Publish(3, 10);
  node->Stop(1);
  Publish(2, 10);  // also delivers the STATUS that Stop published
  EXPECT_EQ(node->status().inputs(), 3);
  EXPECT_EQ(ReadAll(o.path).size(), 3u);
}

TEST(LoggerOptions, RejectsABadChannelExpressionAndNoPath) {
  LoggerOptions o;
  std::string error;
  EXPECT_FALSE(o.IsValid(&error));
  EXPECT_EQ(error, "a log file path is required");
  o.path = "x.lcm";
  o.channel_regex = "(";
  EXPECT_FALSE(o.IsValid(&error));
  EXPECT_EQ(error, "channel expression '(' is not a valid regular expression");
}

TEST(ExpandLogPath, ExpandsStrftimeInUtcAndLeavesPlainNamesAlone) {
  EXPECT_EQ(ExpandLogPath("/logs/%Y-%m-%d/run-%H%M.lcm", 1'795'391'998'000'000),
            "/logs/2026-11-22/run-2359.lcm");
  EXPECT_EQ(ExpandLogPath("/logs/session.lcm", 0), "/logs/session.lcm");
}

TEST(IncrementedLogPath, NumbersTheRunBeforeTheExtension) {
  EXPECT_EQ(IncrementedLogPath("/logs/sim_demo.lcm", 0), "/logs/sim_demo-00.lcm");
  EXPECT_EQ(IncrementedLogPath("/logs/sim_demo.lcm", 123), "/logs/sim_demo-123.lcm");
  EXPECT_EQ(IncrementedLogPath("/logs.d/session", 4), "/logs.d/session-04");
  EXPECT_EQ(IncrementedLogPath("/logs/.hidden", 1), "/logs/.hidden-01");
}

TEST(LoggerOptions, IncrementAndForceExcludeEachOther) {
  LoggerOptions o;
  o.path = "a.lcm";
  o.increment = true;
  o.overwrite = true;
  std::string error;
  EXPECT_FALSE(o.IsValid(&error));
  EXPECT_NE(error.find("exclude each other"), std::string::npos) << error;
}

TEST(RotatedLogPath, NumbersBeforeTheExtension) {
  EXPECT_EQ(RotatedLogPath("/logs/session.lcm", 3), "/logs/session.0003.lcm");
  EXPECT_EQ(RotatedLogPath("/logs.d/session", 12), "/logs.d/session.0012");
}

// One datagram with an empty channel name used to be recorded, and LCM's
// log reader stops at it: everything after it in the file was lost to
// lcm-logplayer. The logger now refuses what LCM's tools cannot read back,
// counts it, and keeps recording.
TEST(LoggerNodeRefusals, SkipsEventsLcmCannotReadBackAndTheFileStaysWhole) {
  TempDir dir;
  LoopbackBus bus;
  LoggerOptions o;
  o.path = dir.File("a.lcm");
  std::string error;
  auto node = LoggerNode::Create(&bus, o, 0, &error);
  ASSERT_NE(node, nullptr) << error;
  const auto payload = Payload(1, 12);
  const int size = static_cast<int>(payload.size());
  const int64_t t0 = 1'700'000'000'000'000;
  bus.Inject("BEFORE", payload.data(), size, t0);
  bus.Inject("", payload.data(), size, t0 + 1000);
  bus.Inject(std::string(64, 'L'), payload.data(), size, t0 + 2000);  // LCM allows 63.
  bus.Inject(std::string("NUL\0NAME", 8), payload.data(), size, t0 + 3000);
  bus.Inject(std::string(63, 'M'), payload.data(), size, t0 + 4000);  // The longest allowed.
  bus.Inject("AFTER", payload.data(), size, t0 + 5000);
  node->Stop(t0 + 6000);
  EXPECT_EQ(node->status().rejected("unloggable_channel"), 3);
  EXPECT_EQ(node->status().outputs(), 3);
  EXPECT_EQ(node->status().dropped(), 0);

  // liblcm's own reader (what lcm-logplayer uses) reads every event.
  lcm::LogFile file(o.path, "r");
  ASSERT_TRUE(file.good());
  std::vector<std::string> channels;
  while (const lcm::LogEvent* e = file.readNextEvent()) channels.push_back(e->channel);
  EXPECT_EQ(channels, (std::vector<std::string>{"BEFORE", std::string(63, 'M'), "AFTER"}));

  // And the real lcm-logplayer plays all three (into memq://: no network).
  ChildProcess player({"lcm-logplayer", "-v", "-s", "1000", "--lcm-url=memq://", o.path},
                      dir.File("played.txt"));
  ASSERT_EQ(player.Wait(30), 0);
  std::istringstream played(ReadFile(dir.File("played.txt")));
  std::vector<std::string> played_channels;
  std::string line;
  while (std::getline(played, line)) {
    std::istringstream words(line);
    std::string time, word, channel;
    if (words >> time >> word >> channel && word == "Channel") played_channels.push_back(channel);
  }
  EXPECT_EQ(played_channels, channels);
}

}  // namespace
}  // namespace roomfix
