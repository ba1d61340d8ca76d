#include "msgio/log.h"

#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <filesystem>

#include "msgio/bus.h"
#include "msgio/test_messages.h"
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

  std::vector<LogEvent> events;
  EXPECT_FALSE(ReadLogEvents(path, &events, &error));
  EXPECT_EQ(events.size(), 4u);  // What was whole is kept.
  EXPECT_NE(error.find("unreadable after byte"), std::string::npos) << error;
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
