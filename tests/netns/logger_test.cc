// roomfix_logger as a process, over real multicast inside a private network
// namespace: what it records plays back through lcm-logplayer into
// lcm-logger unchanged, and a kill -9 loses at most the flush interval.
#include <gtest/gtest.h>
#include <signal.h>

#include <chrono>
#include <cstring>
#include <thread>

#include "msgio/bus.h"
#include "msgio/log.h"
#include "msgio/process.h"
#include "tests/testing/test_paths.h"

namespace roomfix {
namespace {

using testing::BinDir;
using testing::ChildProcess;
using testing::SourceDir;
using testing::TempDir;

std::vector<LogEvent> ReadAll(const std::string& path) {
  std::vector<LogEvent> events;
  std::string error;
  EXPECT_TRUE(ReadLogEvents(path, &events, &error)) << error;
  return events;
}

void SleepS(double s) { std::this_thread::sleep_for(std::chrono::duration<double>(s)); }

TEST(RoomfixLogger, WhatItRecordsLcmLogplayerPlaysAndLcmLoggerRecordsIdentically) {
  TempDir dir;
  const std::string ours = dir.File("ours.lcm");
  const std::string theirs = dir.File("theirs.lcm");
  {
    ChildProcess logger(
        {BinDir() + "/roomfix_logger", ours, "--channel", "POSE_.*|RANGES", "--log-level", "warn"});
    SleepS(0.5);
    ChildProcess sim({BinDir() + "/roomfix_sim", "--config",
                      SourceDir() + "/config/sites/demo_room.yaml", "--ranges", "--duration", "1.5",
                      "--log-level", "warn"});
    ASSERT_EQ(sim.Wait(20), 0);
    SleepS(0.3);
    logger.Signal(SIGINT);
    ASSERT_EQ(logger.Wait(10), 0);
  }
  const auto recorded = ReadAll(ours);
  ASSERT_GE(recorded.size(), 50u);  // 1.5 s of 30 Hz truth and 10 Hz ranges.
  {
    ChildProcess lcm_logger({"lcm-logger", "-c", "POSE_.*|RANGES", theirs});
    SleepS(0.5);
    ChildProcess player({"lcm-logplayer", "--speed=4", ours});
    ASSERT_EQ(player.Wait(30), 0);
    SleepS(0.5);
    lcm_logger.Signal(SIGINT);
    ASSERT_EQ(lcm_logger.Wait(10), 0);
  }
  const auto replayed = ReadAll(theirs);
  ASSERT_EQ(replayed.size(), recorded.size());
  for (size_t i = 0; i < recorded.size(); ++i) {
    EXPECT_EQ(replayed[i].channel, recorded[i].channel) << i;
    EXPECT_EQ(replayed[i].data, recorded[i].data) << i;
    EXPECT_EQ(recorded[i].eventnum, static_cast<int64_t>(i));
  }
}

// The logger flushes every 100 ms: after SIGKILL every message published
// more than that (plus scheduling slack) before the kill is in the file.
TEST(RoomfixLogger, AKillNineLosesAtMostTheFlushInterval) {
  constexpr double kFlushInterval_s = 0.1;
  constexpr double kSlack_s = 0.1;  // Receive, queue and scheduling delays.
  TempDir dir;
  const std::string path = dir.File("killed.lcm");
  std::string error;
  auto bus = LcmBus::Create(kDefaultLcmUrl, &error);
  ASSERT_NE(bus, nullptr) << error;
  ChildProcess logger(
      {BinDir() + "/roomfix_logger", path, "--channel", "SEQ", "--log-level", "warn"});
  SleepS(0.5);
  std::vector<int64_t> sent_utime;
  const auto start = std::chrono::steady_clock::now();
  int64_t seq = 0;
  while (std::chrono::steady_clock::now() - start < std::chrono::milliseconds(1500)) {
    uint8_t payload[8];
    std::memcpy(payload, &seq, sizeof(seq));
    bus->PublishRaw("SEQ", payload, sizeof(payload));
    sent_utime.push_back(NowUtime());
    ++seq;
    std::this_thread::sleep_for(std::chrono::microseconds(500));
  }
  const int64_t kill_utime = NowUtime();
  logger.Signal(SIGKILL);
  logger.Wait(10);

  // A kill -9 may land while stdio writes out a buffer that ends inside an
  // event: a truncated last event is what it may leave, nothing else.
  auto reader = LogReader::Open(path, &error);
  ASSERT_NE(reader, nullptr) << error;
  std::vector<LogEvent> events;
  LogEvent event;
  while (reader->Next(&event)) events.push_back(event);
  if (reader->damaged()) {
    ASSERT_TRUE(reader->truncated()) << reader->DamageSummary();
    EXPECT_EQ(reader->damage_regions(), 1) << reader->DamageSummary();
    EXPECT_EQ(reader->bytes_read() + reader->bytes_skipped(), reader->file_size());
  }
  std::vector<bool> seen(static_cast<size_t>(seq), false);
  for (const auto& e : events) {
    int64_t s = 0;
    ASSERT_EQ(e.data.size(), sizeof(s));
    std::memcpy(&s, e.data.data(), sizeof(s));
    seen.at(static_cast<size_t>(s)) = true;
  }
  const int64_t safe_utime = kill_utime - static_cast<int64_t>((kFlushInterval_s + kSlack_s) * 1e6);
  int64_t must_have = 0, missing = 0;
  for (size_t k = 0; k < sent_utime.size(); ++k) {
    if (sent_utime[k] > safe_utime) break;
    ++must_have;
    if (!seen[k]) ++missing;
  }
  EXPECT_GT(must_have, 1000);
  EXPECT_EQ(missing, 0) << "of " << must_have << " messages sent before the last flush";
}

TEST(RoomfixLogger, RefusesToOverwriteAndSaysSoInOneLine) {
  TempDir dir;
  const std::string path = dir.File("exists.lcm");
  ASSERT_TRUE(testing::WriteFile(path, "keep me"));
  ChildProcess logger({BinDir() + "/roomfix_logger", path}, dir.File("out.txt"));
  EXPECT_EQ(logger.Wait(10), 1);
  EXPECT_EQ(testing::ReadFile(path), "keep me");
}

}  // namespace
}  // namespace roomfix
