#include "zigbee_bridge/serial_link.h"

#include <gtest/gtest.h>
#include <libserialport.h>
#include <poll.h>

#include <cerrno>
#include <chrono>
#include <cmath>
#include <limits>
#include <memory>
#include <vector>

#include "sim/pseudo_terminal.h"
#include "tests/testing/byte_reads.h"
#include "tests/testing/test_paths.h"

namespace roomfix {
namespace {

constexpr int64_t kT0 = 1'700'000'000'000'000;

SerialLinkOptions OptionsFor(const std::string& port) {
  SerialLinkOptions options;
  options.port = port;
  return options;
}

// Reads through the link until `size` bytes came, the link reports the
// device gone, or timeout_ms passed.
std::vector<uint8_t> ReadFor(SerialLink* link, size_t size, int timeout_ms) {
  return testing::ReadFor([link] { return link->fd(); },
                          [link](uint8_t* buffer, size_t capacity) -> ssize_t {
                            return link->Read(buffer, capacity, kT0);
                          },
                          size, timeout_ms);
}

TEST(SerialLinkOptions, RejectsBadBaudAndBackoff) {
  std::string error;
  EXPECT_TRUE(OptionsFor("/dev/ttyUSB0").IsValid(&error)) << error;

  EXPECT_FALSE(OptionsFor("").IsValid(&error));
  EXPECT_NE(error.find("port"), std::string::npos) << error;

  SerialLinkOptions options = OptionsFor("/dev/ttyUSB0");
  options.baud = 115201;
  EXPECT_FALSE(options.IsValid(&error));
  EXPECT_NE(error.find("115201"), std::string::npos) << error;
  options.baud = 0;
  EXPECT_FALSE(options.IsValid(&error));
  options.baud = 9600;
  EXPECT_TRUE(options.IsValid(&error)) << error;

  for (const auto& [initial, max] :
       std::vector<std::pair<double, double>>{{0.0, 5.0},
                                              {-0.1, 5.0},
                                              {6.0, 5.0},
                                              {std::nan(""), 5.0},
                                              {0.1, std::numeric_limits<double>::infinity()}}) {
    options.reopen_initial_s = initial;
    options.reopen_max_s = max;
    EXPECT_FALSE(options.IsValid(&error)) << initial << " " << max;
    EXPECT_NE(error.find("reopen"), std::string::npos) << error;
  }
  options.reopen_initial_s = 2.0;
  options.reopen_max_s = 2.0;
  EXPECT_TRUE(options.IsValid(&error)) << error;
}

TEST(SerialLink, MissingDeviceGivesAClearError) {
  SerialLink link(OptionsFor("/dev/ttyUSB_roomfix_absent"));
  EXPECT_FALSE(link.MaybeOpen(kT0));
  EXPECT_EQ(link.state(), SerialLink::State::kClosed);
  EXPECT_EQ(link.fd(), -1);
  EXPECT_EQ(link.open_failures(), 1);
  EXPECT_EQ(link.opens(), 0);
  EXPECT_EQ(link.last_error(),
            "/dev/ttyUSB_roomfix_absent: open failed: No such file or directory");
  uint8_t byte;
  EXPECT_EQ(link.Read(&byte, 1, kT0), 0);
}

TEST(SerialLink, RefusesAPathThatIsNotADevice) {
  testing::TempDir dir;
  const std::string path = dir.File("zigbee");
  ASSERT_TRUE(testing::WriteFile(path, "x"));
  SerialLink link(OptionsFor(path));
  EXPECT_FALSE(link.MaybeOpen(kT0));
  EXPECT_NE(link.last_error().find("not a character device"), std::string::npos)
      << link.last_error();
}

TEST(SerialLink, ReadsEveryByteValueWrittenToAPseudoTerminalUnchanged) {
  std::string error;
  auto pty = PseudoTerminal::Open("", &error);
  ASSERT_NE(pty, nullptr) << error;
  SerialLink link(OptionsFor(pty->device_path()));
  ASSERT_TRUE(link.MaybeOpen(kT0)) << link.last_error();
  EXPECT_EQ(link.state(), SerialLink::State::kOpen);
  EXPECT_GE(link.fd(), 0);
  EXPECT_EQ(link.opens(), 1);

  // Every value, including XON/XOFF (0x11/0x13), LF, CR and the ZigBee
  // API frame delimiter 0x7E, twice so that reads span buffer boundaries.
  const std::vector<uint8_t> ascending = testing::AllByteValues();
  std::vector<uint8_t> bytes = ascending;
  bytes.insert(bytes.end(), ascending.rbegin(), ascending.rend());
  ASSERT_TRUE(pty->Write(bytes.data(), bytes.size(), &error)) << error;
  EXPECT_EQ(ReadFor(&link, bytes.size(), 1000), bytes);

  uint8_t byte;
  EXPECT_EQ(link.Read(&byte, 1, kT0), 0) << "nothing is waiting";
  EXPECT_EQ(link.state(), SerialLink::State::kOpen);
  EXPECT_EQ(link.disconnects(), 0);
}

TEST(SerialLink, OpensThroughASymlink) {
  testing::TempDir dir;
  std::string error;
  auto pty = PseudoTerminal::Open(dir.File("zigbee"), &error);
  ASSERT_NE(pty, nullptr) << error;
  SerialLink link(OptionsFor(dir.File("zigbee")));
  ASSERT_TRUE(link.MaybeOpen(kT0)) << link.last_error();
  const uint8_t frame[] = {0x7E, 0x00, 0x02, 0x11, 0x13, 0xD9};
  ASSERT_TRUE(pty->Write(frame, sizeof(frame), &error)) << error;
  EXPECT_EQ(ReadFor(&link, sizeof(frame), 1000), std::vector<uint8_t>(frame, frame + 6));
}

TEST(SerialLink, DiscardsWhatWasQueuedBeforeItOpened) {
  std::string error;
  auto pty = PseudoTerminal::Open("", &error);
  ASSERT_NE(pty, nullptr) << error;
  const uint8_t stale[] = {0x01, 0x02, 0x03};
  const uint8_t fresh[] = {0x7E, 0x04};
  ASSERT_TRUE(pty->Write(stale, sizeof(stale), &error)) << error;
  SerialLink link(OptionsFor(pty->device_path()));
  ASSERT_TRUE(link.MaybeOpen(kT0)) << link.last_error();
  ASSERT_TRUE(pty->Write(fresh, sizeof(fresh), &error)) << error;
  EXPECT_EQ(ReadFor(&link, 3, 200), std::vector<uint8_t>(fresh, fresh + 2));
}

TEST(SerialLink, ReportsTheDeviceGoneWhenTheTerminalCloses) {
  // Through the symlink, which goes with the pty: the /dev/pts number is
  // handed to the next pty opened anywhere on the host at once, so a retry
  // on it could open another test's (or a user's) terminal.
  testing::TempDir dir;
  const std::string device = dir.File("zigbee");
  std::string error;
  auto pty = PseudoTerminal::Open(device, &error);
  ASSERT_NE(pty, nullptr) << error;
  SerialLink link(OptionsFor(device));
  ASSERT_TRUE(link.MaybeOpen(kT0)) << link.last_error();
  const int fd = link.fd();

  pty.reset();
  pollfd p{fd, POLLIN, 0};
  ASSERT_EQ(::poll(&p, 1, 1000), 1) << "a hang-up must wake the poll loop";
  uint8_t buffer[16];
  EXPECT_EQ(link.Read(buffer, sizeof(buffer), kT0 + 5), -1);
  EXPECT_EQ(link.state(), SerialLink::State::kClosed);
  EXPECT_EQ(link.fd(), -1);
  EXPECT_EQ(link.disconnects(), 1);
  EXPECT_EQ(link.open_failures(), 0);
  EXPECT_EQ(link.last_error().rfind(device + ": device gone: ", 0), 0u) << link.last_error();
  EXPECT_EQ(link.next_retry_utime(), kT0 + 5 + 100'000);
  // The pty is gone for good: the retry fails, naming the port.
  EXPECT_FALSE(link.MaybeOpen(link.next_retry_utime()));
  EXPECT_EQ(link.open_failures(), 1);
  EXPECT_EQ(link.last_error(), device + ": open failed: No such file or directory");
}

TEST(SerialLink, ReopensWithExponentialBackoffWhenTheDeviceReturns) {
  testing::TempDir dir;
  const std::string path = dir.File("zigbee");
  SerialLink link(OptionsFor(path));
  int64_t now = kT0;
  ASSERT_FALSE(link.MaybeOpen(now));
  const std::vector<int64_t> delays_us = {100'000,   200'000,   400'000,   800'000,
                                          1'600'000, 3'200'000, 5'000'000, 5'000'000};
  for (size_t k = 0; k < delays_us.size(); ++k) {
    EXPECT_EQ(link.open_failures(), static_cast<int64_t>(k + 1));
    ASSERT_EQ(link.next_retry_utime(), now + delays_us[k]) << "after failure " << k + 1;
    EXPECT_FALSE(link.MaybeOpen(now + delays_us[k] - 1)) << "not due yet";
    EXPECT_EQ(link.open_failures(), static_cast<int64_t>(k + 1)) << "no attempt before it is due";
    now += delays_us[k];
    EXPECT_FALSE(link.MaybeOpen(now));
  }
  EXPECT_NE(link.last_error().find(path + ": open failed: No such file"), std::string::npos)
      << link.last_error();

  std::string error;
  auto pty = PseudoTerminal::Open(path, &error);
  ASSERT_NE(pty, nullptr) << error;
  EXPECT_FALSE(link.MaybeOpen(link.next_retry_utime() - 1));
  now = link.next_retry_utime();
  ASSERT_TRUE(link.MaybeOpen(now)) << link.last_error();
  EXPECT_EQ(link.opens(), 1);
  const uint8_t frame[] = {0x7E, 0x00, 0x01, 0x0D, 0x0A};
  ASSERT_TRUE(pty->Write(frame, sizeof(frame), &error)) << error;
  EXPECT_EQ(ReadFor(&link, sizeof(frame), 1000), std::vector<uint8_t>(frame, frame + 5));

  // Data arrived, so the next disconnect retries at the initial delay.
  pty.reset();
  uint8_t buffer[16];
  now += 1'000'000;
  ASSERT_EQ(link.Read(buffer, sizeof(buffer), now), -1);
  EXPECT_EQ(link.next_retry_utime(), now + 100'000);
}

TEST(SerialLink, KeepsBackingOffWhenAnOpenDropsBeforeAnyData) {
  testing::TempDir dir;
  const std::string path = dir.File("zigbee");
  SerialLink link(OptionsFor(path));
  int64_t now = kT0;
  ASSERT_FALSE(link.MaybeOpen(now));  // retry after 0.1 s
  now = link.next_retry_utime();
  ASSERT_FALSE(link.MaybeOpen(now));  // retry after 0.2 s
  now = link.next_retry_utime();

  std::string error;
  auto pty = PseudoTerminal::Open(path, &error);
  ASSERT_NE(pty, nullptr) << error;
  ASSERT_TRUE(link.MaybeOpen(now)) << link.last_error();
  const int fd = link.fd();
  pty.reset();
  pollfd p{fd, POLLIN, 0};
  ASSERT_EQ(::poll(&p, 1, 1000), 1);
  uint8_t buffer[16];
  ASSERT_EQ(link.Read(buffer, sizeof(buffer), now), -1);
  EXPECT_EQ(link.disconnects(), 1);
  // A device that drops before sending anything does not reset the
  // backoff: the next delay is 0.4 s, not 0.1 s.
  EXPECT_EQ(link.next_retry_utime(), now + 400'000);
}

// SerialLink opens pseudo-terminals with open() and termios because
// libserialport 0.1.1 cannot open them (see serial_link.h). When this test
// fails, libserialport has learnt to, and that special case can go.
TEST(SerialLink, LibserialportStillCannotOpenAPseudoTerminal) {
  testing::TempDir dir;
  std::string error;
  auto pty = PseudoTerminal::Open(dir.File("zigbee"), &error);
  ASSERT_NE(pty, nullptr) << error;

  sp_port* port = nullptr;
  EXPECT_EQ(sp_get_port_by_name(pty->device_path().c_str(), &port), SP_ERR_ARG)
      << "no /sys/class/tty entry for " << pty->device_path();

  // A name that passes its /sys/class/tty check (/dev/ and /sys/class/tty/
  // followed by enough ".." both reach the symlink) still fails in sp_open,
  // on TIOCMGET.
  const std::string disguised = "/dev/../../../.." + dir.File("zigbee");
  ASSERT_EQ(sp_get_port_by_name(disguised.c_str(), &port), SP_OK);
  EXPECT_EQ(sp_open(port, SP_MODE_READ_WRITE), SP_ERR_FAIL);
  EXPECT_EQ(sp_last_error_code(), ENOTTY);
  sp_free_port(port);
}

}  // namespace
}  // namespace roomfix
