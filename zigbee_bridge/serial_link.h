#ifndef ROOMFIX_ZIGBEE_BRIDGE_SERIAL_LINK_H_
#define ROOMFIX_ZIGBEE_BRIDGE_SERIAL_LINK_H_

#include <cstddef>
#include <cstdint>
#include <string>

struct sp_port;

namespace roomfix {

struct SerialLinkOptions {
  // "/dev/ttyUSB0", a /dev/pts/N, or a symlink to either (a udev
  // /dev/serial/by-id name, the simulator's stable link). Prefer the
  // simulator's symlink to its /dev/pts/N: the kernel hands a pty number to
  // the next pty opened on the host as soon as it is free, so retries on a
  // dead simulator's /dev/pts/N can open an unrelated terminal.
  std::string port;
  int baud = 115200;
  // Delay before the first retry after a failed open or a disconnect; each
  // further failure doubles it, up to reopen_max_s.
  double reopen_initial_s = 0.1;
  double reopen_max_s = 5.0;

  // Port non-empty, baud a standard UART rate (1200 .. 921600),
  // 0 < reopen_initial_s <= reopen_max_s.
  bool IsValid(std::string* error) const;
};

// Owns the ZigBee coordinator's serial port: opens it 8N1, raw, without flow
// control, reads it without blocking, notices when the device goes away and
// reopens it with exponential backoff. Time is an argument; the class never
// reads a clock. Not thread-safe.
//
// How the port is opened:
// - The path is resolved first (realpath): libserialport 0.1.1 only accepts
//   a name under /dev/ with its own /sys/class/tty entry, so it refuses
//   symlinks such as /dev/serial/by-id/... ("Device not found").
// - Real serial devices are opened and configured through libserialport.
// - Unix98 pseudo-terminal slaves (the simulator's) are opened with open()
//   and configured with termios instead. libserialport 0.1.1 cannot open
//   them at all: sp_get_port_by_name rejects /dev/pts/N (no /sys/class/tty
//   entry), and sp_open itself fails because its internal get_config issues
//   TIOCMGET, which the pty driver does not implement (ENOTTY), and then
//   closes the descriptor; no later call can tolerate that failure, and
//   every other configuration call goes through the same get_config. The
//   test LibserialportStillCannotOpenAPseudoTerminal checks this still
//   holds. Everything after the open (reading, hang-up detection, backoff)
//   is one code path for both kinds of device.
// - Input queued before the open is discarded: it was sent while nobody
//   listened (the simulator queues up to ~14 KiB with no reader; a USB
//   adapter may hold some too), so its ranges would be stale.
class SerialLink {
 public:
  enum class State { kClosed, kOpen };

  explicit SerialLink(SerialLinkOptions options);
  ~SerialLink();
  SerialLink(const SerialLink&) = delete;
  SerialLink& operator=(const SerialLink&) = delete;

  // Opens the port if it is closed and a retry is due at now_utime (the
  // first attempt is due at once). Returns true when the port is open after
  // the call. A failure counts in open_failures(), sets last_error() and
  // schedules the next attempt.
  bool MaybeOpen(int64_t now_utime);

  // Descriptor to poll() for POLLIN (a hang-up shows as POLLHUP/POLLERR and
  // must also lead to a Read call); -1 while closed.
  int fd() const { return fd_; }

  // Reads what is waiting without blocking. Returns the number of bytes, 0
  // when there are none (or the port is closed), or -1 when the device is
  // gone (unplugged, simulator exited, I/O error): the port is then closed,
  // disconnects() counts it, last_error() says why and a reopen is
  // scheduled with backoff. Bytes still queued when the device went away
  // are lost (the kernel discards them on hang-up).
  int Read(uint8_t* buffer, size_t capacity, int64_t now_utime);

  State state() const { return fd_ >= 0 ? State::kOpen : State::kClosed; }
  // When MaybeOpen will next try; meaningless while open.
  int64_t next_retry_utime() const { return next_retry_utime_; }
  int64_t opens() const { return opens_; }
  int64_t open_failures() const { return open_failures_; }
  int64_t disconnects() const { return disconnects_; }
  // One line naming the port, e.g. "/dev/ttyUSB0: open failed: No such file
  // or directory"; kept after a later successful open, "" until a failure.
  const std::string& last_error() const { return last_error_; }

 private:
  bool Open(std::string* error);
  bool OpenWithLibserialport(const std::string& device, std::string* error);
  bool OpenPseudoTerminal(const std::string& device, std::string* error);
  void Close();
  // Closes the port after a failure and schedules the next attempt.
  void Fail(const std::string& error, int64_t now_utime);

  SerialLinkOptions options_;
  // Set for devices opened through libserialport, which then owns fd_.
  sp_port* port_ = nullptr;
  int fd_ = -1;
  double backoff_s_;
  // The backoff goes back to reopen_initial_s only once an open has
  // delivered data: a device that opens and drops again at once (a flapping
  // cable, a simulator crashing on start) must not be hammered at the
  // initial rate, while a link that worked recovers quickly after its next
  // unplug.
  bool received_since_open_ = false;
  int64_t next_retry_utime_ = 0;
  int64_t opens_ = 0;
  int64_t open_failures_ = 0;
  int64_t disconnects_ = 0;
  std::string last_error_;
};

}  // namespace roomfix

#endif  // ROOMFIX_ZIGBEE_BRIDGE_SERIAL_LINK_H_
