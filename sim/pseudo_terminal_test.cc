#include "sim/pseudo_terminal.h"

#include <fcntl.h>
#include <gtest/gtest.h>
#include <poll.h>
#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <vector>

#include "tests/testing/byte_reads.h"
#include "tests/testing/test_paths.h"

namespace roomfix {
namespace {

using Clock = std::chrono::steady_clock;

std::string ReadLink(const std::string& path) {
  char target[256];
  const ssize_t n = ::readlink(path.c_str(), target, sizeof(target) - 1);
  return n > 0 ? std::string(target, static_cast<size_t>(n)) : "";
}

bool Exists(const std::string& path) {
  struct stat st {};
  return ::lstat(path.c_str(), &st) == 0;
}

// Opens the slave as a bridge would, without touching its settings: the
// pseudo-terminal must already be raw.
int OpenSlave(const PseudoTerminal& pty) {
  return ::open(pty.device_path().c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
}

TEST(PseudoTerminal, CreatesTheSymlinkAndRemovesItWhenDestroyed) {
  testing::TempDir dir;
  const std::string link = dir.File("zigbee");
  std::string error;
  auto pty = PseudoTerminal::Open(link, &error);
  ASSERT_NE(pty, nullptr) << error;
  EXPECT_EQ(pty->symlink_path(), link);
  EXPECT_EQ(pty->device_path().rfind("/dev/pts/", 0), 0u) << pty->device_path();
  EXPECT_EQ(ReadLink(link), pty->device_path());
  pty.reset();
  EXPECT_FALSE(Exists(link));
}

TEST(PseudoTerminal, WorksWithoutASymlink) {
  std::string error;
  auto pty = PseudoTerminal::Open("", &error);
  ASSERT_NE(pty, nullptr) << error;
  EXPECT_EQ(pty->symlink_path(), "");
  EXPECT_GE(pty->master_fd(), 0);
}

TEST(PseudoTerminal, ReplacesAStaleSymlinkLeftByACrashedSimulator) {
  testing::TempDir dir;
  const std::string link = dir.File("zigbee");
  ASSERT_EQ(::symlink("/dev/pts/9999", link.c_str()), 0);
  std::string error;
  auto pty = PseudoTerminal::Open(link, &error);
  ASSERT_NE(pty, nullptr) << error;
  EXPECT_EQ(ReadLink(link), pty->device_path());
}

TEST(PseudoTerminal, RefusesToReplaceAFileThatIsNotASymlink) {
  testing::TempDir dir;
  const std::string path = dir.File("zigbee");
  ASSERT_TRUE(testing::WriteFile(path, "not a link\n"));
  std::string error;
  EXPECT_EQ(PseudoTerminal::Open(path, &error), nullptr);
  EXPECT_NE(error.find(path), std::string::npos) << error;
  EXPECT_EQ(testing::ReadFile(path), "not a link\n");
}

TEST(PseudoTerminal, LeavesTheSymlinkOfTheInstanceThatTookItOver) {
  testing::TempDir dir;
  const std::string link = dir.File("zigbee");
  std::string error;
  auto old_pty = PseudoTerminal::Open(link, &error);
  ASSERT_NE(old_pty, nullptr) << error;
  auto new_pty = PseudoTerminal::Open(link, &error);
  ASSERT_NE(new_pty, nullptr) << error;
  old_pty.reset();
  EXPECT_EQ(ReadLink(link), new_pty->device_path());
  new_pty.reset();
  EXPECT_FALSE(Exists(link));
}

TEST(PseudoTerminal, PassesEveryByteValueUntouchedInBothDirections) {
  std::string error;
  auto pty = PseudoTerminal::Open("", &error);
  ASSERT_NE(pty, nullptr) << error;
  const int slave = OpenSlave(*pty);
  ASSERT_GE(slave, 0);
  // Includes XON/XOFF (0x11/0x13), CR/LF, ^C and ^D, which a cooked
  // terminal would act on or translate.
  const std::vector<uint8_t> bytes = testing::AllByteValues();
  ASSERT_TRUE(pty->Write(bytes.data(), bytes.size(), &error)) << error;
  EXPECT_EQ(testing::ReadFdFor(slave, bytes.size(), 1000), bytes);
  // Nothing echoed back to the writer.
  EXPECT_TRUE(testing::ReadFdFor(pty->master_fd(), 1, 20).empty());

  ASSERT_EQ(::write(slave, bytes.data(), bytes.size()), 256);
  EXPECT_EQ(testing::ReadFdFor(pty->master_fd(), bytes.size(), 1000), bytes);
  ::close(slave);
}

TEST(PseudoTerminal, ReaderCanCloseAndReopenTheSlaveWithoutTheMasterHangingUp) {
  std::string error;
  auto pty = PseudoTerminal::Open("", &error);
  ASSERT_NE(pty, nullptr) << error;
  const uint8_t first[] = {0x7E, 0x01};
  const uint8_t second[] = {0x7E, 0x02};
  int slave = OpenSlave(*pty);
  ASSERT_GE(slave, 0);
  ASSERT_TRUE(pty->Write(first, sizeof(first), &error)) << error;
  EXPECT_EQ(testing::ReadFdFor(slave, 2, 1000), std::vector<uint8_t>(first, first + 2));
  ::close(slave);

  // No reader: the master must not report a hang-up (a poll loop on it
  // would spin), and a write is queued rather than refused.
  pollfd p{pty->master_fd(), POLLIN, 0};
  ASSERT_GE(::poll(&p, 1, 0), 0);
  EXPECT_EQ(p.revents & (POLLHUP | POLLERR), 0);
  ASSERT_TRUE(pty->Write(second, sizeof(second), &error)) << error;

  slave = OpenSlave(*pty);
  ASSERT_GE(slave, 0);
  EXPECT_EQ(testing::ReadFdFor(slave, 2, 1000), std::vector<uint8_t>(second, second + 2));
  ::close(slave);
}

TEST(PseudoTerminal, DestroyingItHangsUpTheReader) {
  std::string error;
  auto pty = PseudoTerminal::Open("", &error);
  ASSERT_NE(pty, nullptr) << error;
  const int slave = OpenSlave(*pty);
  ASSERT_GE(slave, 0);
  pty.reset();
  pollfd p{slave, POLLIN, 0};
  ASSERT_EQ(::poll(&p, 1, 1000), 1);
  EXPECT_NE(p.revents & POLLHUP, 0);
  uint8_t byte;
  EXPECT_EQ(::read(slave, &byte, 1), 0);
  ::close(slave);
}

TEST(PseudoTerminal, WritingToATerminalNobodyReadsGivesUpWithinTheBound) {
  std::string error;
  auto pty = PseudoTerminal::Open("", &error);
  ASSERT_NE(pty, nullptr) << error;
  const std::vector<uint8_t> chunk(4096, 0x55);
  const Clock::time_point start = Clock::now();
  int accepted = 0;
  while (pty->Write(chunk.data(), chunk.size(), &error)) {
    ASSERT_LT(++accepted, 1000) << "the pty never filled up";
  }
  const auto first_failure = Clock::now() - start;
  EXPECT_NE(error.find("reader not keeping up"), std::string::npos) << error;
  EXPECT_LT(first_failure, std::chrono::milliseconds(PseudoTerminal::kWriteTimeoutMs + 400));

  // Still stalled: later writes fail without waiting again.
  const Clock::time_point again = Clock::now();
  EXPECT_FALSE(pty->Write(chunk.data(), chunk.size(), &error));
  EXPECT_LT(Clock::now() - again, std::chrono::milliseconds(PseudoTerminal::kWriteTimeoutMs / 2));

  // A reader arriving drains the queue and writes go through again.
  const int slave = OpenSlave(*pty);
  ASSERT_GE(slave, 0);
  testing::ReadFdFor(slave, 1 << 20, 100);
  const uint8_t frame[] = {0x7E, 0x00, 0x01};
  EXPECT_TRUE(pty->Write(frame, sizeof(frame), &error)) << error;
  ::close(slave);
}

}  // namespace
}  // namespace roomfix
