#include "zigbee_bridge/serial_link.h"

#include <fcntl.h>
#include <libserialport.h>
#include <poll.h>
#include <stdlib.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <termios.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <memory>
#include <utility>

namespace roomfix {
namespace {

struct BaudRate {
  int baud;
  speed_t speed;
};
constexpr BaudRate kBaudRates[] = {
    {1200, B1200},     {2400, B2400},     {4800, B4800},     {9600, B9600},
    {19200, B19200},   {38400, B38400},   {57600, B57600},   {115200, B115200},
    {230400, B230400}, {460800, B460800}, {921600, B921600},
};

const BaudRate* FindBaud(int baud) {
  for (const BaudRate& b : kBaudRates) {
    if (b.baud == baud) return &b;
  }
  return nullptr;
}

// Linux gives Unix98 pty slaves majors 136-143 (UNIX98_PTY_SLAVE_MAJOR and
// the 7 that follow; Documentation/admin-guide/devices.txt).
bool IsPseudoTerminalSlave(const struct stat& st) {
  return S_ISCHR(st.st_mode) && major(st.st_rdev) >= 136 && major(st.st_rdev) <= 143;
}

// libserialport keeps errno's text only for SP_ERR_FAIL.
std::string SpError(sp_return code) {
  switch (code) {
    case SP_ERR_FAIL: {
      char* message = sp_last_error_message();
      std::string text = message != nullptr ? message : "unknown error";
      sp_free_error_message(message);
      return text;
    }
    case SP_ERR_ARG:
      return "libserialport does not recognise it as a serial port";
    case SP_ERR_MEM:
      return "out of memory";
    case SP_ERR_SUPP:
      return "not supported by libserialport";
    default:
      return "libserialport error " + std::to_string(static_cast<int>(code));
  }
}

int64_t SecondsToUtime(double s) { return static_cast<int64_t>(std::llround(s * 1e6)); }

}  // namespace

bool SerialLinkOptions::IsValid(std::string* error) const {
  if (port.empty()) {
    *error = "serial port is empty";
    return false;
  }
  if (FindBaud(baud) == nullptr) {
    *error = "baud " + std::to_string(baud) + " is not a standard rate (1200 .. 921600)";
    return false;
  }
  if (!(reopen_initial_s > 0.0) || !(reopen_initial_s <= reopen_max_s) ||
      !std::isfinite(reopen_max_s)) {
    *error = "reopen backoff must satisfy 0 < reopen_initial_s <= reopen_max_s (got " +
             std::to_string(reopen_initial_s) + ", " + std::to_string(reopen_max_s) + ")";
    return false;
  }
  return true;
}

SerialLink::SerialLink(SerialLinkOptions options)
    : options_(std::move(options)), backoff_s_(options_.reopen_initial_s) {}

SerialLink::~SerialLink() { Close(); }

bool SerialLink::MaybeOpen(int64_t now_utime) {
  if (fd_ >= 0) return true;
  if (now_utime < next_retry_utime_) return false;
  std::string error;
  if (!Open(&error)) {
    ++open_failures_;
    Fail(options_.port + ": open failed: " + error, now_utime);
    return false;
  }
  ++opens_;
  received_since_open_ = false;
  return true;
}

bool SerialLink::Open(std::string* error) {
  std::unique_ptr<char, decltype(&::free)> resolved(::realpath(options_.port.c_str(), nullptr),
                                                    &::free);
  if (resolved == nullptr) {
    *error = std::strerror(errno);
    return false;
  }
  const std::string device = resolved.get();
  struct stat st {};
  if (::stat(device.c_str(), &st) != 0) {
    *error = std::strerror(errno);
    return false;
  }
  if (!S_ISCHR(st.st_mode)) {
    *error = device + " is not a character device";
    return false;
  }
  const bool opened = IsPseudoTerminalSlave(st) ? OpenPseudoTerminal(device, error)
                                                : OpenWithLibserialport(device, error);
  if (!opened) return false;
  // Both paths leave VMIN = VTIME = 0, so read() never waits; O_NONBLOCK
  // also keeps a driver that ignores them from blocking the bridge.
  const int flags = ::fcntl(fd_, F_GETFL);
  if (flags < 0 || ::fcntl(fd_, F_SETFL, flags | O_NONBLOCK) < 0 ||
      ::fcntl(fd_, F_SETFD, FD_CLOEXEC) < 0 || ::tcflush(fd_, TCIFLUSH) != 0) {
    *error = std::string("configuring the descriptor: ") + std::strerror(errno);
    Close();
    return false;
  }
  return true;
}

bool SerialLink::OpenWithLibserialport(const std::string& device, std::string* error) {
  sp_port* port = nullptr;
  sp_return r = sp_get_port_by_name(device.c_str(), &port);
  if (r != SP_OK) {
    *error = device + ": " + SpError(r);
    return false;
  }
  r = sp_open(port, SP_MODE_READ_WRITE);
  if (r != SP_OK) {
    *error = SpError(r);
    sp_free_port(port);
    return false;
  }
  port_ = port;
  // sp_open has made the line raw (no echo, no CR/LF translation, VMIN =
  // VTIME = 0) but leaves the framing and XON/XOFF as it found them: an
  // inherited IXON would swallow 0x11/0x13 from the radio.
  // Fields left unset in a new config (RTS, DTR) keep their current state.
  sp_port_config* config = nullptr;
  r = sp_new_config(&config);
  if (r == SP_OK) {
    sp_set_config_baudrate(config, options_.baud);
    sp_set_config_bits(config, 8);
    sp_set_config_parity(config, SP_PARITY_NONE);
    sp_set_config_stopbits(config, 1);
    sp_set_config_flowcontrol(config, SP_FLOWCONTROL_NONE);
    r = sp_set_config(port, config);
  }
  if (r == SP_OK) r = sp_get_port_handle(port, &fd_);
  if (r != SP_OK)
    *error = "configuring 8N1 at " + std::to_string(options_.baud) + " baud: " + SpError(r);
  if (config != nullptr) sp_free_config(config);
  if (r != SP_OK) {
    fd_ = -1;
    Close();
    return false;
  }
  return true;
}

bool SerialLink::OpenPseudoTerminal(const std::string& device, std::string* error) {
  const BaudRate* baud = FindBaud(options_.baud);
  if (baud == nullptr) {
    *error = "baud " + std::to_string(options_.baud) + " is not a standard rate";
    return false;
  }
  fd_ = ::open(device.c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
  if (fd_ < 0) {
    *error = std::strerror(errno);
    return false;
  }
  // The same settings sp_open and sp_set_config give a real port. The speed
  // means nothing to a pty but is kept so tools show the configured rate.
  termios t{};
  bool ok = ::tcgetattr(fd_, &t) == 0;
  if (ok) {
    ::cfmakeraw(&t);
    t.c_cflag |= CLOCAL | CREAD;
    t.c_cflag &= ~(CSTOPB | PARENB | CRTSCTS);
    t.c_cc[VMIN] = 0;
    t.c_cc[VTIME] = 0;
    ok = ::cfsetispeed(&t, baud->speed) == 0 && ::cfsetospeed(&t, baud->speed) == 0 &&
         ::tcsetattr(fd_, TCSANOW, &t) == 0;
  }
  if (!ok) {
    *error = std::string("configuring the terminal: ") + std::strerror(errno);
    Close();
    return false;
  }
  return true;
}

void SerialLink::Close() {
  if (port_ != nullptr) {
    // A hung-up descriptor still closes; there is nothing to do if not.
    sp_close(port_);
    sp_free_port(port_);
    port_ = nullptr;
  } else if (fd_ >= 0) {
    ::close(fd_);
  }
  fd_ = -1;
}

void SerialLink::Fail(const std::string& error, int64_t now_utime) {
  Close();
  last_error_ = error;
  if (received_since_open_) backoff_s_ = options_.reopen_initial_s;
  received_since_open_ = false;
  next_retry_utime_ = now_utime + SecondsToUtime(backoff_s_);
  backoff_s_ = std::min(2.0 * backoff_s_, options_.reopen_max_s);
}

int SerialLink::Read(uint8_t* buffer, size_t capacity, int64_t now_utime) {
  if (fd_ < 0 || capacity == 0) return 0;
  const ssize_t n = ::read(fd_, buffer, capacity);
  if (n > 0) {
    received_since_open_ = true;
    return static_cast<int>(n);
  }
  if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR)) return 0;
  std::string reason;
  if (n < 0) {
    // EIO: a pty whose master is gone, or a USB adapter mid-removal.
    reason = std::strerror(errno);
  } else {
    // With VMIN = VTIME = 0, read() returns 0 both when nothing is waiting
    // and on a hung-up terminal (USB adapter unplugged, pty master closed);
    // only poll() tells them apart.
    pollfd p{fd_, POLLIN, 0};
    if (::poll(&p, 1, 0) <= 0 || (p.revents & (POLLHUP | POLLERR | POLLNVAL)) == 0) return 0;
    reason = "hung up";
  }
  ++disconnects_;
  Fail(options_.port + ": device gone: " + reason, now_utime);
  return -1;
}

}  // namespace roomfix
