// roomfix_logger as a process, over real multicast inside a private network
// namespace: what it records plays back through lcm-logplayer into
// lcm-logger unchanged, and a kill -9 loses at most the flush interval.
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <cstring>
#include <fstream>
#include <map>
#include <thread>

#include "msgio/bus.h"
#include "msgio/log.h"
#include "msgio/process.h"
#include "msgio/udpm_bus.h"
#include "roomfix/process_status_t.hpp"
#include "tests/testing/demo_site.h"
#include "tests/testing/hostile_traffic.h"
#include "tests/testing/test_paths.h"

namespace roomfix {
namespace {

using testing::BinDir;
using testing::ChildProcess;
using testing::DemoSitePath;
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
    ChildProcess sim({BinDir() + "/roomfix_sim", "--config", DemoSitePath(), "--ranges",
                      "--duration", "1.5", "--log-level", "warn"});
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

// A logger stopped (SIGSTOP) while a publisher sends loses what its kernel
// receive buffer cannot hold, and says so: once it runs again, its STATUS
// `dropped` equals what was sent minus what it wrote, exactly (tolerance 0:
// nothing else is sent on this namespace's bus while it is stopped, and the
// kernel counts each datagram it drops on the logger's socket), and the
// cause is the counter dropped_kernel_overflow. With its own receiver the
// kernel's count comes from the socket (SO_RXQ_OVFL, SO_MEMINFO); through
// liblcm (--via-liblcm) from /proc/net/udp.
class StoppedLogger : public ::testing::TestWithParam<std::string> {};

TEST_P(StoppedLogger, LosesWhatItsStatusReportsDropped) {
  constexpr int kSent = 3000;
  // A small buffer (the kernel grants twice this) holds a few hundred small
  // datagrams, so the burst overflows it.
  const std::string url = std::string(kDefaultLcmUrl) + "&recv_buf_size=65536";
  TempDir dir;
  const std::string path = dir.File("stopped.lcm");
  std::string error;
  auto bus = UdpmBus::Create(kDefaultLcmUrl, &error);
  ASSERT_NE(bus, nullptr) << error;
  std::vector<process_status_t> statuses;
  bus->Subscribe<process_status_t>(kStatusChannel,
                                   [&](const process_status_t& s, const MessageInfo&) {
                                     if (s.process == "roomfix_logger") statuses.push_back(s);
                                   });
  std::vector<std::string> command = {BinDir() + "/roomfix_logger",
                                      path,
                                      "--channel",
                                      "STOP",
                                      "--lcm-url",
                                      url,
                                      "--log-level",
                                      "warn"};
  if (!GetParam().empty()) command.push_back(GetParam());
  ChildProcess logger(command);
  ASSERT_TRUE(HandleUntil(
      bus.get(), [&] { return !statuses.empty(); }, 5.0));
  logger.Signal(SIGSTOP);
  SleepS(0.1);
  uint8_t payload[32] = {0};
  for (int k = 0; k < kSent; ++k) {
    std::memcpy(payload, &k, sizeof(k));
    ASSERT_TRUE(bus->PublishRaw("STOP", payload, sizeof(payload)));
  }
  logger.Signal(SIGCONT);
  // Heartbeats come every second; the second one after SIGCONT was made
  // after the logger had drained its socket.
  const size_t seen = statuses.size();
  ASSERT_TRUE(HandleUntil(
      bus.get(), [&] { return statuses.size() >= seen + 2; }, 5.0));
  const process_status_t status = statuses.back();
  logger.Signal(SIGINT);
  ASSERT_EQ(logger.Wait(10), 0);

  const int64_t written = static_cast<int64_t>(ReadAll(path).size());
  EXPECT_GT(kSent - written, kSent / 2) << "the burst was meant to overflow the buffer";
  EXPECT_EQ(status.dropped, kSent - written);
  int64_t kernel_overflow = -1;
  for (const auto& c : status.counters) {
    if (c.name == "dropped_kernel_overflow") kernel_overflow = c.count;
  }
  EXPECT_EQ(kernel_overflow, kSent - written);
}

INSTANTIATE_TEST_SUITE_P(RoomfixLogger, StoppedLogger,
                         ::testing::Values(std::string(), std::string("--via-liblcm")));

// An LC03 fragment from a socket of its own (one sender), fragment 0 with
// the channel before its data.
void SendFragment(int fd, uint32_t seqno, uint32_t total, uint32_t offset, uint16_t number,
                  uint16_t count, const std::string& channel, size_t data_bytes) {
  const std::vector<uint8_t> d = hostile::FragmentDatagram(
      seqno, total, offset, number, count, channel, hostile::Bytes(data_bytes, 0x5A));
  sockaddr_in to{};
  to.sin_family = AF_INET;
  to.sin_port = htons(7667);
  inet_pton(AF_INET, "239.255.76.67", &to.sin_addr);
  ASSERT_EQ(::sendto(fd, d.data(), d.size(), 0, reinterpret_cast<sockaddr*>(&to), sizeof(to)),
            static_cast<ssize_t>(d.size()));
}

int64_t PeakResidentKb(int pid) {
  std::ifstream status("/proc/" + std::to_string(pid) + "/status");
  std::string line;
  while (std::getline(status, line)) {
    if (line.rfind("VmHWM:", 0) == 0) return std::atoll(line.c_str() + 6);
  }
  return -1;
}

// Issue #15's rows: LC03 fragments whose totals disagree crashed the logger
// (heap overflow), and first fragments each declaring 64 MiB made it hold
// 1 GB and lose 703 of 800 good messages with STATUS saying dropped 0. Now it
// stays up, records every good message, keeps its peak memory within 50 MB,
// and counts each refused fragment by cause in STATUS.
TEST(RoomfixLogger, HostileFragmentsNeitherCrashNorBloatNorCostGoodMessages) {
  constexpr int kHostile = 200;
  constexpr int kGood = 800;
  constexpr int64_t kMaxPeakKb = 50 << 10;  // The bound for growth.
  TempDir dir;
  const std::string path = dir.File("hostile.lcm");
  std::string error;
  auto bus = UdpmBus::Create(kDefaultLcmUrl, &error);
  ASSERT_NE(bus, nullptr) << error;
  std::vector<process_status_t> statuses;
  bus->Subscribe<process_status_t>(kStatusChannel,
                                   [&](const process_status_t& s, const MessageInfo&) {
                                     if (s.process == "roomfix_logger") statuses.push_back(s);
                                   });
  ChildProcess logger(
      {BinDir() + "/roomfix_logger", path, "--channel", "GOOD|BIG|MM", "--log-level", "warn"});
  ASSERT_TRUE(HandleUntil(
      bus.get(), [&] { return !statuses.empty(); }, 5.0));
  const int64_t peak_before_kb = PeakResidentKb(logger.pid());
  const int fd = ::socket(AF_INET, SOCK_DGRAM, 0);
  const unsigned char ttl = 0;
  ::setsockopt(fd, IPPROTO_IP, IP_MULTICAST_TTL, &ttl, sizeof(ttl));
  // Disagreeing totals: 100 bytes declared, then 60 000 at offset 50 of a
  // message declaring 70 000; and liblcm's crasher, an offset that wraps.
  SendFragment(fd, 1, 100, 0, 0, 2, "MM", 50);
  SendFragment(fd, 1, 70000, 50, 1, 2, "", 60000);
  SendFragment(fd, 2, 1000, 0xFFFFFF00u, 0, 2, "MM", 0x200);
  int good = 0;
  for (int k = 0; k < kHostile; ++k) {
    SendFragment(fd, uint32_t(100 + k), 64u << 20, 0, 0, 1100, "BIG", 1000);
    for (int g = 0; g < kGood / kHostile; ++g, ++good) {
      ASSERT_TRUE(bus->PublishRaw("GOOD", &good, sizeof(good)));
    }
    std::this_thread::sleep_for(std::chrono::microseconds(200));
  }
  ::close(fd);
  // The 100-byte message's fragment 0 waits for a fragment 1 that never
  // comes: it expires 1 s after it arrived, at the logger's next receive (its
  // own heartbeat at the latest), and the heartbeat after that reports it.
  const size_t seen = statuses.size();
  ASSERT_TRUE(HandleUntil(
      bus.get(), [&] { return statuses.size() >= seen + 3; }, 6.0));
  const process_status_t status = statuses.back();
  const int64_t peak_after_kb = PeakResidentKb(logger.pid());
  logger.Signal(SIGINT);
  ASSERT_EQ(logger.Wait(10), 0);

  int64_t good_written = 0;
  for (const auto& e : ReadAll(path)) good_written += e.channel == "GOOD";
  EXPECT_EQ(good_written, kGood);
  std::map<std::string, int64_t> counters;
  for (const auto& c : status.counters) counters[c.name] = c.count;
  EXPECT_EQ(counters["fragments_over_budget"], kHostile);
  EXPECT_EQ(counters["fragments_malformed"], 2);
  EXPECT_EQ(counters["fragments_expired"], 1);
  EXPECT_EQ(status.dropped, kHostile + 2 + 1);
  EXPECT_LT(peak_after_kb - peak_before_kb, kMaxPeakKb);
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
