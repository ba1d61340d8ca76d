#include "core/world/file_io.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

namespace roomfix {
namespace {

std::string KindOf(mode_t mode) {
  if (S_ISDIR(mode)) return "a folder";
  if (S_ISFIFO(mode)) return "a FIFO";
  if (S_ISCHR(mode)) return "a character device";
  if (S_ISBLK(mode)) return "a block device";
  if (S_ISSOCK(mode)) return "a socket";
  return "not a file";
}

void SetError(std::string* error, const std::string& text) {
  if (error != nullptr) *error = text;
}

}  // namespace

std::string ByteSizeText(size_t bytes) {
  if (bytes >= (size_t{1} << 20) && bytes % (size_t{1} << 20) == 0) {
    return std::to_string(bytes >> 20) + " MiB";
  }
  if (bytes >= 1024 && bytes % 1024 == 0) return std::to_string(bytes >> 10) + " KiB";
  return std::to_string(bytes) + " bytes";
}

bool ReadConfigFile(const std::string& path, std::string* text, std::string* error,
                    size_t cap_bytes) {
  // O_NONBLOCK: opening a FIFO for reading would otherwise wait for a
  // writer. It has no effect on regular files, the only kind read here.
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC | O_NOCTTY);
  if (fd < 0) {
    SetError(error, path + ": cannot open: " + std::strerror(errno));
    return false;
  }
  struct stat st {};
  if (::fstat(fd, &st) != 0) {
    SetError(error, path + ": cannot open: " + std::strerror(errno));
    ::close(fd);
    return false;
  }
  if (!S_ISREG(st.st_mode)) {
    SetError(error, path + ": not a regular file (" + KindOf(st.st_mode) + ")");
    ::close(fd);
    return false;
  }
  const std::string over_cap =
      path + ": over the " + ByteSizeText(cap_bytes) + " cap for configuration files";
  if (st.st_size < 0 || static_cast<unsigned long long>(st.st_size) > cap_bytes) {
    SetError(error, path + ": " + std::to_string(st.st_size) + " bytes, over the " +
                        ByteSizeText(cap_bytes) + " cap for configuration files");
    ::close(fd);
    return false;
  }
  std::string out;
  out.reserve(static_cast<size_t>(st.st_size));
  char buffer[65536];
  for (;;) {
    const ssize_t n = ::read(fd, buffer, sizeof(buffer));
    if (n == 0) break;
    if (n < 0) {
      if (errno == EINTR) continue;
      SetError(error, path + ": cannot read: " + std::strerror(errno));
      ::close(fd);
      return false;
    }
    // The file may have grown since fstat.
    if (out.size() + static_cast<size_t>(n) > cap_bytes) {
      SetError(error, over_cap);
      ::close(fd);
      return false;
    }
    out.append(buffer, static_cast<size_t>(n));
  }
  ::close(fd);
  *text = std::move(out);
  return true;
}

LineRead ReadBoundedLine(std::istream& in, std::string* line, size_t max_bytes) {
  line->clear();
  std::streambuf* buffer = in.rdbuf();
  if (buffer == nullptr || !in.good()) return LineRead::kEnd;
  for (;;) {
    const int c = buffer->sbumpc();
    if (c == std::char_traits<char>::eof()) {
      in.setstate(std::ios::eofbit);
      return line->empty() ? LineRead::kEnd : LineRead::kLine;
    }
    if (c == '\n') return LineRead::kLine;
    if (line->size() >= max_bytes) return LineRead::kTooLong;
    line->push_back(static_cast<char>(c));
  }
}

bool WriteOutputFile(const std::string& path, const std::string& bytes, std::string* error) {
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC | O_NOCTTY, 0666);
  if (fd < 0) {
    SetError(error, path + ": cannot write: " + std::strerror(errno));
    return false;
  }
  size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::write(fd, bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      SetError(error, path + ": cannot write: " + std::strerror(n < 0 ? errno : EIO));
      ::close(fd);
      return false;
    }
    done += static_cast<size_t>(n);
  }
  // close can report a deferred write error (NFS, quota).
  if (::close(fd) != 0) {
    SetError(error, path + ": cannot write: " + std::strerror(errno));
    return false;
  }
  return true;
}

}  // namespace roomfix
