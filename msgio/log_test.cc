#include "msgio/log.h"

#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <lcm/lcm-cpp.hpp>

#include "msgio/bus.h"
#include "tests/testing/raw_log_event.h"
#include "tests/testing/test_messages.h"
#include "tests/testing/test_paths.h"

namespace roomfix {
namespace {

using testing::MakeTestPose;
using testing::TempDir;

std::vector<uint8_t> Encode(const pose2d_t& p) {
  std::vector<uint8_t> bytes(p.getEncodedSize());
  p.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
  return bytes;
}

// Writes n poses on alternating channels, 0.1 s apart from t0.
void WriteLog(const std::string& path, int n, int64_t t0) {
  std::string error;
  auto writer = LogWriter::Create(path, false, &error);
  ASSERT_NE(writer, nullptr) << error;
  for (int i = 0; i < n; ++i) {
    const auto bytes = Encode(MakeTestPose(t0 + i * 100000, 1, 0.1 * i, 0.2 * i));
    ASSERT_TRUE(writer->Write(t0 + i * 100000 + 50, i % 2 ? "POSE_CAMERA" : "POSE_ULTRASOUND",
                              bytes.data(), static_cast<int>(bytes.size()), &error))
        << error;
  }
  ASSERT_TRUE(writer->Flush(&error));
}

TEST(LogWriter, WritesEventsThatLogReaderReadsBackUnchanged) {
  TempDir dir;
  const std::string path = dir.File("a.lcm");
  WriteLog(path, 10, 1700000000000000);
  std::string error;
  auto reader = LogReader::Open(path, &error);
  ASSERT_NE(reader, nullptr) << error;
  LogEvent e;
  for (int i = 0; i < 10; ++i) {
    ASSERT_TRUE(reader->Next(&e));
    EXPECT_EQ(e.eventnum, i);
    EXPECT_EQ(e.utime, 1700000000000000 + i * 100000 + 50);
    EXPECT_EQ(e.channel, i % 2 ? "POSE_CAMERA" : "POSE_ULTRASOUND");
    EXPECT_EQ(e.data, Encode(MakeTestPose(1700000000000000 + i * 100000, 1, 0.1 * i, 0.2 * i)));
  }
  EXPECT_FALSE(reader->Next(&e));
  EXPECT_FALSE(reader->damaged());
}

TEST(LogWriter, RefusesToOverwriteUnlessTold) {
  TempDir dir;
  const std::string path = dir.File("a.lcm");
  WriteLog(path, 1, 1);
  std::string error;
  EXPECT_EQ(LogWriter::Create(path, false, &error), nullptr);
  EXPECT_EQ(error, path + ": already exists (refusing to overwrite)");
  EXPECT_NE(LogWriter::Create(path, true, &error), nullptr);
}

TEST(LogWriter, ReportsAFolderItCannotWriteTo) {
  std::string error;
  EXPECT_EQ(LogWriter::Create("/nonexistent/dir/a.lcm", false, &error), nullptr);
  EXPECT_EQ(error.rfind("/nonexistent/dir/a.lcm: cannot create", 0), 0u) << error;
}

TEST(LogReader, ReportsATruncatedLogAfterReadingWhatIsWhole) {
  TempDir dir;
  const std::string path = dir.File("a.lcm");
  WriteLog(path, 5, 1000);
  const auto size = std::filesystem::file_size(path);
  std::filesystem::resize_file(path, size - 7);  // Cut into the last event.
  std::string error;
  auto reader = LogReader::Open(path, &error);
  ASSERT_NE(reader, nullptr);
  LogEvent e;
  int n = 0;
  while (reader->Next(&e)) ++n;
  EXPECT_EQ(n, 4);
  EXPECT_TRUE(reader->damaged());

  EXPECT_TRUE(reader->truncated());
  // The cut event starts where the fourth ended and runs to the end.
  const int64_t cut_at = reader->bytes_read();
  EXPECT_EQ(reader->bytes_skipped(), static_cast<int64_t>(size) - 7 - cut_at);
  ASSERT_EQ(reader->damage().size(), 1u);
  EXPECT_EQ(reader->damage()[0].offset, cut_at);
  EXPECT_EQ(reader->damage()[0].reason, "truncated");

  std::vector<LogEvent> events;
  EXPECT_FALSE(ReadLogEvents(path, &events, &error));
  EXPECT_EQ(events.size(), 4u);  // What was whole is kept.
  EXPECT_EQ(error, path + ": skipped " + std::to_string(size - 7 - cut_at) +
                       " bytes in 1 region (truncated 1): at byte " + std::to_string(cut_at) +
                       " (" + std::to_string(size - 7 - cut_at) + " bytes, truncated)");
}

std::string RawEvent(int64_t eventnum, int64_t utime, const std::string& channel,
                     const std::string& data, int32_t channel_bytes, int32_t data_bytes) {
  return testing::RawLogEvent(eventnum, utime, channel, data, channel_bytes, data_bytes);
}

std::string RawEvent(int64_t eventnum, const std::string& channel, const std::string& data) {
  return RawEvent(eventnum, 1000 + eventnum, channel, data, static_cast<int32_t>(channel.size()),
                  static_cast<int32_t>(data.size()));
}

struct ReadResult {
  std::vector<std::string> channels;
  std::vector<std::string> payloads;
  std::vector<LogDamage> damage;
  int64_t bytes_skipped = 0;
  bool truncated = false;
  std::string summary;
};

ReadResult ReadBytes(const std::string& bytes) {
  ReadResult r;
  auto reader = LogReader::FromBytes(std::vector<uint8_t>(bytes.begin(), bytes.end()), "mem");
  LogEvent e;
  while (reader->Next(&e)) {
    r.channels.push_back(e.channel);
    r.payloads.emplace_back(e.data.begin(), e.data.end());
  }
  r.damage = reader->damage();
  r.bytes_skipped = reader->bytes_skipped();
  r.truncated = reader->truncated();
  r.summary = reader->DamageSummary();
  return r;
}

const std::string kGood1 = RawEvent(0, "ONE", "first payload");
const std::string kGood2 = RawEvent(2, "TWO", "second payload");
const std::string kGood3 = RawEvent(3, "THREE", "third");

// The audit's crash: liblcm's reader calloc()s len + 1, which overflows for
// 0x7FFFFFFF, and writes into the failed allocation.
TEST(LogReaderDamage, AnEventClaiming0x7FFFFFFFBytesIsSkippedAndWhatFollowsIsRead) {
  const std::string bad = RawEvent(1, 5, "BAD", "xxxxxxxx", 3, 0x7FFFFFFF);
  const ReadResult r = ReadBytes(kGood1 + bad + kGood2 + kGood3);
  EXPECT_EQ(r.channels, (std::vector<std::string>{"ONE", "TWO", "THREE"}));
  EXPECT_EQ(r.payloads[1], "second payload");
  ASSERT_EQ(r.damage.size(), 1u);
  EXPECT_EQ(r.damage[0].offset, static_cast<int64_t>(kGood1.size()));
  EXPECT_EQ(r.damage[0].bytes, static_cast<int64_t>(bad.size()));
  EXPECT_EQ(r.damage[0].reason, "data_length_over_cap");
  EXPECT_FALSE(r.truncated);
  EXPECT_EQ(r.summary, "skipped " + std::to_string(bad.size()) +
                           " bytes in 1 region (data_length_over_cap 1): at byte " +
                           std::to_string(kGood1.size()) + " (" + std::to_string(bad.size()) +
                           " bytes, data_length_over_cap)");
}

TEST(LogReaderDamage, ALengthWithinTheCapThatRunsPastTheEndIsSkippedWhenEventsFollow) {
  const std::string bad = RawEvent(1, 5, "BAD", "", 3, 1 << 20);
  const ReadResult r = ReadBytes(kGood1 + bad + kGood2);
  EXPECT_EQ(r.channels, (std::vector<std::string>{"ONE", "TWO"}));
  ASSERT_EQ(r.damage.size(), 1u);
  EXPECT_EQ(r.damage[0].reason, "runs_past_end");
  EXPECT_EQ(r.damage[0].bytes, static_cast<int64_t>(bad.size()));
}

// The datagram the logger used to record: LCM's reader refuses a channel
// length of 0 and stops for the rest of the file.
TEST(LogReaderDamage, AnEmptyChannelEventIsSkippedAndWhatFollowsIsRead) {
  const std::string empty = RawEvent(1, "", "payload");
  const std::string huge_channel = RawEvent(1, 5, "", "", 1000, 0);
  const std::string negative = RawEvent(1, 5, "NEG", "", 3, -4);
  const ReadResult r = ReadBytes(kGood1 + empty + kGood2 + huge_channel + kGood3 + negative);
  EXPECT_EQ(r.channels, (std::vector<std::string>{"ONE", "TWO", "THREE"}));
  ASSERT_EQ(r.damage.size(), 3u);
  EXPECT_EQ(r.damage[0].reason, "bad_channel_length");
  EXPECT_EQ(r.damage[0].bytes, static_cast<int64_t>(empty.size()));
  EXPECT_EQ(r.damage[1].reason, "bad_channel_length");
  EXPECT_EQ(r.damage[2].reason, "negative_data_length");
  EXPECT_EQ(r.bytes_skipped,
            static_cast<int64_t>(empty.size() + huge_channel.size() + negative.size()));
}

TEST(LogReaderDamage, GarbageBetweenEventsIsSkippedToTheNextSyncWord) {
  std::string garbage(1000, '\0');
  for (size_t i = 0; i < garbage.size(); ++i) garbage[i] = static_cast<char>(i * 131 + 7);
  const ReadResult r = ReadBytes(kGood1 + garbage + kGood2 + garbage + kGood3);
  EXPECT_EQ(r.channels, (std::vector<std::string>{"ONE", "TWO", "THREE"}));
  ASSERT_EQ(r.damage.size(), 2u);
  EXPECT_EQ(r.damage[0].offset, static_cast<int64_t>(kGood1.size()));
  EXPECT_EQ(r.damage[0].bytes, 1000);
  EXPECT_EQ(r.damage[0].reason, "not_an_event");
  EXPECT_EQ(r.damage[1].offset, static_cast<int64_t>(kGood1.size() + 1000 + kGood2.size()));
}

// A data length made too large by a flipped bit that still ends inside the
// file would swallow the next events; the next sync word inside its payload
// (and none after it) gives it away.
TEST(LogReaderDamage, AnEventWhosePayloadSwallowsTheNextEventIsSkipped) {
  const std::string bad = RawEvent(1, 5, "BAD", "abc", 3, 3 + static_cast<int32_t>(kGood2.size()));
  const ReadResult r = ReadBytes(kGood1 + bad + kGood2 + "zzzzzz" + kGood3);
  EXPECT_EQ(r.channels, (std::vector<std::string>{"ONE", "TWO", "THREE"}));
  ASSERT_EQ(r.damage.size(), 2u);
  EXPECT_EQ(r.damage[0].reason, "overlaps_next_event");
  EXPECT_EQ(r.damage[0].bytes, static_cast<int64_t>(bad.size()));
  EXPECT_EQ(r.damage[1].reason, "not_an_event");
  EXPECT_EQ(r.damage[1].bytes, 6);
}

// Seen after a kill -9 of roomfix_logger: stdio had written the first byte
// of the next event's sync word.
TEST(LogReaderDamage, AFirstByteOfASyncWordAtTheEndIsATruncatedEvent) {
  const ReadResult cut = ReadBytes(kGood1 + kGood2.substr(0, 1));
  EXPECT_EQ(cut.channels, (std::vector<std::string>{"ONE"}));
  EXPECT_TRUE(cut.truncated);
  ASSERT_EQ(cut.damage.size(), 1u);
  EXPECT_EQ(cut.damage[0].reason, "truncated");
  // Other stray bytes at the end are not an event.
  const ReadResult junk = ReadBytes(kGood1 + "\x01\x02");
  EXPECT_FALSE(junk.truncated);
  ASSERT_EQ(junk.damage.size(), 1u);
  EXPECT_EQ(junk.damage[0].reason, "not_an_event");
}

TEST(LogReaderDamage, ATruncatedHeaderAtTheEndIsReportedAsTruncated) {
  const ReadResult r = ReadBytes(kGood1 + kGood2.substr(0, 10));
  EXPECT_EQ(r.channels, (std::vector<std::string>{"ONE"}));
  EXPECT_TRUE(r.truncated);
  ASSERT_EQ(r.damage.size(), 1u);
  EXPECT_EQ(r.damage[0].reason, "truncated");
  EXPECT_EQ(r.damage[0].bytes, 10);
}

// An lcm-logger log of another system may carry the sync word inside a
// payload (images, nested logs): that is not damage, as for liblcm.
TEST(LogReader, ReadsWhatLiblcmReadsWhenAPayloadHoldsTheSyncWord) {
  TempDir dir;
  const std::string path = dir.File("sync_in_payload.lcm");
  const std::string payload = std::string("\xED\xA1\xDA\x01", 4) + kGood2 + "tail";
  std::ofstream(path, std::ios::binary) << kGood1 << RawEvent(1, "NESTED", payload) << kGood3;
  std::vector<std::pair<std::string, std::string>> lcm_read;
  {
    lcm::LogFile file(path, "r");
    while (const lcm::LogEvent* e = file.readNextEvent()) {
      lcm_read.emplace_back(e->channel, std::string(static_cast<const char*>(e->data), e->datalen));
    }
  }
  std::vector<LogEvent> events;
  std::string error;
  ASSERT_TRUE(ReadLogEvents(path, &events, &error)) << error;
  ASSERT_EQ(events.size(), 3u);
  ASSERT_EQ(lcm_read.size(), 3u);
  for (size_t i = 0; i < events.size(); ++i) {
    EXPECT_EQ(events[i].channel, lcm_read[i].first);
    EXPECT_EQ(std::string(events[i].data.begin(), events[i].data.end()), lcm_read[i].second);
  }
}

TEST(LogReaderDamage, ManyRegionsAreCountedAndTheSummaryStaysOneLine) {
  std::string bytes;
  for (int i = 0; i < 100; ++i) bytes += RawEvent(i, "", "x") + kGood1;
  auto reader = LogReader::FromBytes(std::vector<uint8_t>(bytes.begin(), bytes.end()), "mem");
  LogEvent e;
  int n = 0;
  while (reader->Next(&e)) ++n;
  EXPECT_EQ(n, 100);
  EXPECT_EQ(reader->damage_regions(), 100);
  EXPECT_EQ(reader->damage().size(), LogReader::kMaxDamageRegionsKept);
  const std::string summary = reader->DamageSummary();
  EXPECT_EQ(summary.find('\n'), std::string::npos);
  EXPECT_NE(summary.find("and 97 more"), std::string::npos) << summary;
}

TEST(LogWriter, RefusesEventsLcmCannotReadBackAndKeepsTheFileGood) {
  TempDir dir;
  const std::string path = dir.File("a.lcm");
  std::string error;
  auto writer = LogWriter::Create(path, false, &error);
  ASSERT_NE(writer, nullptr) << error;
  const char data[4] = {1, 2, 3, 4};
  EXPECT_TRUE(writer->Write(1, "A", data, 4, &error)) << error;
  EXPECT_FALSE(writer->Write(2, "", data, 4, &error));
  EXPECT_EQ(error, path + ": refused an event: empty channel name (LCM's log reader stops at it)");
  EXPECT_FALSE(writer->Write(3, std::string(64, 'C'), data, 4, &error));
  EXPECT_EQ(error, path + ": refused an event: channel name of 64 bytes (LCM allows 63)");
  EXPECT_FALSE(writer->Write(4, "B", data, -1, &error));
  EXPECT_TRUE(writer->Write(5, "B", data, 4, &error)) << error;
  writer.reset();
  lcm::LogFile file(path, "r");
  std::vector<std::string> channels;
  while (const lcm::LogEvent* e = file.readNextEvent()) channels.push_back(e->channel);
  EXPECT_EQ(channels, (std::vector<std::string>{"A", "B"}));
}

// Processes given --lcm-url file://... read through LogFileBus: LCM's file
// provider SIGSEGVs on this log.
TEST(LogFileBus, PlaysEveryGoodEventOfADamagedLogThenReportsTheEnd) {
  TempDir dir;
  const std::string path = dir.File("damaged.lcm");
  std::ofstream(path, std::ios::binary)
      << kGood1 << RawEvent(1, 5, "BAD", "xxxxxxxx", 3, 0x7FFFFFFF) << kGood2 << kGood3;
  std::string error;
  auto bus = LogFileBus::Create("file://" + path + "?speed=0", &error);
  ASSERT_NE(bus, nullptr) << error;
  std::vector<std::string> channels;
  bus->SubscribeRaw("T.*", [&](const MessageInfo& info, const void*, int) {
    channels.push_back(info.channel);
    EXPECT_GT(info.recv_utime, 1'500'000'000'000'000);  // Wall clock, as LCM's provider.
  });
  int handled = 0;
  int rc = 0;
  while ((rc = bus->Handle(1000)) > 0) handled += rc;
  EXPECT_EQ(rc, -1);
  EXPECT_EQ(handled, 3);
  EXPECT_EQ(channels, (std::vector<std::string>{"TWO", "THREE"}));
  EXPECT_NE(bus->stats().last_error.find("data_length_over_cap"), std::string::npos)
      << bus->stats().last_error;
}

// Like LCM's provider at speed 1, events keep their recorded spacing.
TEST(LogFileBus, KeepsTheRecordedSpacingAtSpeedOne) {
  TempDir dir;
  const std::string path = dir.File("a.lcm");
  WriteLog(path, 3, 1000000);  // 0.1 s apart.
  std::string error;
  auto bus = LogFileBus::Create("file://" + path, &error);
  ASSERT_NE(bus, nullptr) << error;
  const auto start = std::chrono::steady_clock::now();
  int handled = 0;
  while (handled < 3 && std::chrono::steady_clock::now() - start < std::chrono::seconds(5)) {
    handled += std::max(bus->Handle(50), 0);
  }
  EXPECT_EQ(handled, 3);
  // Never early; how late depends on the machine, so no upper bound.
  EXPECT_GE(std::chrono::steady_clock::now() - start, std::chrono::milliseconds(200));
}

TEST(ParseLogUrl, TakesThePathAndSpeedAsLcmsFileProviderDoes) {
  std::string path, error;
  double speed = -1;
  ASSERT_TRUE(ParseLogUrl("file:///tmp/a.lcm?speed=0", &path, &speed, &error)) << error;
  EXPECT_EQ(path, "/tmp/a.lcm");
  EXPECT_EQ(speed, 0.0);
  ASSERT_TRUE(ParseLogUrl("file://rel.lcm", &path, &speed, &error)) << error;
  EXPECT_EQ(path, "rel.lcm");
  EXPECT_EQ(speed, 1.0);
  EXPECT_FALSE(ParseLogUrl("file:///a.lcm?speed=fast", &path, &speed, &error));
  EXPECT_EQ(error, "file:///a.lcm?speed=fast: speed must be a number >= 0");
  EXPECT_FALSE(ParseLogUrl("file:///a.lcm?mode=w", &path, &speed, &error));
  EXPECT_FALSE(ParseLogUrl("udpm://239.255.76.67:7667", &path, &speed, &error));
}

TEST(LogReader, RefusesAFolderAFifoAndADevice) {
  TempDir dir;
  ASSERT_EQ(::mkfifo(dir.File("fifo").c_str(), 0600), 0);
  for (const std::string& path : {dir.path(), dir.File("fifo"), std::string("/dev/zero")}) {
    std::string error;
    EXPECT_EQ(LogReader::Open(path, &error), nullptr) << path;
    EXPECT_EQ(error, path + ": not a regular file");
  }
}

TEST(LogReader, SaysWhenTheFileIsMissing) {
  std::string error;
  EXPECT_EQ(LogReader::Open("/nonexistent.lcm", &error), nullptr);
  EXPECT_EQ(error, "/nonexistent.lcm: No such file or directory");
}

TEST(ReplayLog, DeliversMatchingEventsInOrderWithLogTimeAsTheClock) {
  TempDir dir;
  const std::string path = dir.File("a.lcm");
  WriteLog(path, 6, 5000000);
  LoopbackBus bus;
  std::vector<int64_t> recv;
  std::vector<int64_t> ticks;
  std::vector<double> xs;
  bus.Subscribe<pose2d_t>(".*", [&](const pose2d_t& p, const MessageInfo& info) {
    recv.push_back(info.recv_utime);
    xs.push_back(p.x_m);
    EXPECT_EQ(bus.now_utime(), info.recv_utime);
  });
  ReplayOptions options;
  options.channel_regex = "POSE_ULTRASOUND";
  options.on_time = [&](int64_t t) { ticks.push_back(t); };
  const ReplaySummary s = ReplayLog(path, &bus, options);
  ASSERT_TRUE(s.ok) << s.error;
  EXPECT_EQ(s.events_read, 6);
  EXPECT_EQ(s.events_delivered, 3);
  EXPECT_EQ(s.first_utime, 5000050);
  EXPECT_EQ(s.last_utime, 5500050);
  EXPECT_FALSE(s.damaged);
  EXPECT_EQ(recv, (std::vector<int64_t>{5000050, 5200050, 5400050}));
  EXPECT_EQ(ticks, recv);
  ASSERT_EQ(xs.size(), 3u);
  EXPECT_DOUBLE_EQ(xs[1], 0.2);
}

// LCM's own file provider reads a LogWriter log as if it were the network,
// which is how a process is pointed at a recording with --lcm-url. LCM 1.3.1
// stamps those messages with the wall clock, not the log's times: a replay
// that must be deterministic uses ReplayLog instead.
TEST(LcmBus, ReadsALogWrittenByLogWriterThroughTheFileUrl) {
  TempDir dir;
  const std::string path = dir.File("a.lcm");
  WriteLog(path, 5, 1000000);
  std::string error;
  auto bus = LcmBus::Create("file://" + path + "?speed=0", &error);
  ASSERT_NE(bus, nullptr) << error;
  std::vector<double> xs;
  std::vector<int64_t> times;
  bus->Subscribe<pose2d_t>(".*", [&](const pose2d_t& p, const MessageInfo& info) {
    xs.push_back(p.x_m);
    times.push_back(info.recv_utime);
  });
  while (bus->Handle(1000) > 0) {
  }
  ASSERT_EQ(xs.size(), 5u);
  EXPECT_DOUBLE_EQ(xs[4], 0.4);
  EXPECT_GT(times[2], 1500000000000000);  // Wall clock, not 1200050 from the log.
}

// The same node code runs live and in replay: a node publishing from its
// handler reaches a recorder subscribed on the same bus, stamped with log time.
TEST(ReplayLog, ANodeOutputIsStampedWithTheInputEventTime) {
  TempDir dir;
  const std::string path = dir.File("a.lcm");
  WriteLog(path, 4, 0);
  LoopbackBus bus;
  bus.Subscribe<pose2d_t>("POSE_ULTRASOUND", [&](const pose2d_t& p, const MessageInfo&) {
    pose2d_t out = p;
    out.source = pose2d_t::SOURCE_FUSED;
    bus.Publish("POSE_FUSED", out);
  });
  std::vector<int64_t> fused_times;
  bus.Subscribe<pose2d_t>("POSE_FUSED", [&](const pose2d_t&, const MessageInfo& info) {
    fused_times.push_back(info.recv_utime);
  });
  ASSERT_TRUE(ReplayLog(path, &bus).ok);
  EXPECT_EQ(fused_times, (std::vector<int64_t>{50, 200050}));
}

}  // namespace
}  // namespace roomfix
