#include "sim/pseudo_terminal.h"

#include <fcntl.h>
#include <poll.h>
#include <stdlib.h>
#include <sys/stat.h>
#include <termios.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>

namespace roomfix {
namespace {

std::string Errno(const std::string& what) { return what + ": " + std::strerror(errno); }

bool SetFdFlags(int fd, std::string* error) {
  const int flags = ::fcntl(fd, F_GETFL);
  if (flags < 0 || ::fcntl(fd, F_SETFL, flags | O_NONBLOCK) < 0 ||
      ::fcntl(fd, F_SETFD, FD_CLOEXEC) < 0) {
    *error = Errno("fcntl");
    return false;
  }
  return true;
}

bool MakeRaw(int fd, const char* side, std::string* error) {
  termios t{};
  if (::tcgetattr(fd, &t) != 0) {
    *error = Errno(std::string("tcgetattr on the ") + side);
    return false;
  }
  ::cfmakeraw(&t);
  t.c_cflag |= CLOCAL | CREAD;
  t.c_cc[VMIN] = 1;
  t.c_cc[VTIME] = 0;
  if (::tcsetattr(fd, TCSANOW, &t) != 0) {
    *error = Errno(std::string("tcsetattr on the ") + side);
    return false;
  }
  return true;
}

// Points path at target, replacing a symlink already there in one rename so
// that a bridge retrying its open never finds the path missing. Whether an
// old symlink is stale cannot be told from its target (pty numbers are
// reused), so any symlink is replaced; anything else is left alone.
bool ReplaceSymlink(const std::string& target, const std::string& path, std::string* error) {
  struct stat st {};
  if (::lstat(path.c_str(), &st) == 0 && !S_ISLNK(st.st_mode)) {
    *error = path + ": exists and is not a symlink; not replacing it";
    return false;
  }
  const std::string temporary = path + ".tmp." + std::to_string(::getpid());
  ::unlink(temporary.c_str());
  if (::symlink(target.c_str(), temporary.c_str()) != 0) {
    *error = Errno(path + ": cannot create symlink");
    return false;
  }
  if (::rename(temporary.c_str(), path.c_str()) != 0) {
    *error = Errno(path + ": cannot create symlink");
    ::unlink(temporary.c_str());
    return false;
  }
  return true;
}

}  // namespace

std::unique_ptr<PseudoTerminal> PseudoTerminal::Open(const std::string& symlink_path,
                                                     std::string* error) {
  std::unique_ptr<PseudoTerminal> pty(new PseudoTerminal());
  pty->master_fd_ = ::posix_openpt(O_RDWR | O_NOCTTY);
  if (pty->master_fd_ < 0) {
    *error = Errno("posix_openpt");
    return nullptr;
  }
  if (!SetFdFlags(pty->master_fd_, error)) return nullptr;
  if (::grantpt(pty->master_fd_) != 0 || ::unlockpt(pty->master_fd_) != 0) {
    *error = Errno("grantpt/unlockpt");
    return nullptr;
  }
  char name[128];
  if (::ptsname_r(pty->master_fd_, name, sizeof(name)) != 0) {
    *error = Errno("ptsname_r");
    return nullptr;
  }
  pty->device_path_ = name;
  pty->slave_fd_ = ::open(name, O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
  if (pty->slave_fd_ < 0) {
    *error = Errno(pty->device_path_ + ": open");
    return nullptr;
  }
  // The slave's settings translate what the master writes; the master's
  // (already raw by default on Linux) translate what the bridge writes back.
  if (!MakeRaw(pty->slave_fd_, "slave", error) || !MakeRaw(pty->master_fd_, "master", error)) {
    return nullptr;
  }
  if (!symlink_path.empty()) {
    if (!ReplaceSymlink(pty->device_path_, symlink_path, error)) return nullptr;
    pty->symlink_path_ = symlink_path;
  }
  return pty;
}

PseudoTerminal::~PseudoTerminal() {
  if (!symlink_path_.empty()) {
    char target[256];
    const ssize_t n = ::readlink(symlink_path_.c_str(), target, sizeof(target) - 1);
    if (n > 0 && std::string(target, static_cast<size_t>(n)) == device_path_) {
      ::unlink(symlink_path_.c_str());
    }
  }
  if (slave_fd_ >= 0) ::close(slave_fd_);
  if (master_fd_ >= 0) ::close(master_fd_);
}

bool PseudoTerminal::Write(const uint8_t* data, size_t size, std::string* error) {
  using Clock = std::chrono::steady_clock;
  const Clock::time_point deadline =
      Clock::now() + std::chrono::milliseconds(stalled_ ? 0 : kWriteTimeoutMs);
  size_t written = 0;
  while (written < size) {
    const ssize_t n = ::write(master_fd_, data + written, size - written);
    if (n > 0) {
      written += static_cast<size_t>(n);
      continue;
    }
    if (n < 0 && errno == EINTR) continue;
    if (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK) {
      *error = Errno(device_path_ + ": write");
      return false;
    }
    const auto left = std::chrono::ceil<std::chrono::milliseconds>(deadline - Clock::now());
    pollfd p{master_fd_, POLLOUT, 0};
    if (left.count() <= 0 || ::poll(&p, 1, static_cast<int>(left.count())) == 0) {
      stalled_ = true;
      *error = device_path_ + ": reader not keeping up; wrote " + std::to_string(written) + " of " +
               std::to_string(size) + " bytes and dropped the rest";
      return false;
    }
  }
  stalled_ = false;
  return true;
}

}  // namespace roomfix
