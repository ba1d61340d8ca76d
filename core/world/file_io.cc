#include "core/world/file_io.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstdlib>
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

namespace {

bool WriteAll(int fd, const std::string& bytes) {
  size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::write(fd, bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      if (n == 0) errno = EIO;
      return false;
    }
    done += static_cast<size_t>(n);
  }
  return true;
}

}  // namespace

std::string PartialPathFor(const std::string& target) {
  const size_t slash = target.rfind('/');
  const std::string folder = slash == std::string::npos ? "" : target.substr(0, slash + 1);
  const std::string name = slash == std::string::npos ? target : target.substr(slash + 1);
  return folder + "." + name + ".partial";
}

namespace {

bool CreatePartialFile(const std::string& target, std::string* partial, int* fd) {
  // O_EXCL on a name of our own: the mode is 0666 less the umask, as for a
  // file opened in place, and two writers never share a partial file.
  static std::atomic<unsigned> counter{0};
  for (int attempt = 0; attempt < 100; ++attempt) {
    *partial =
        PartialPathFor(target) + "-" + std::to_string(::getpid()) + "-" + std::to_string(counter++);
    *fd = ::open(partial->c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC | O_NOCTTY, 0666);
    if (*fd >= 0 || errno != EEXIST) return *fd >= 0;
  }
  return false;
}

}  // namespace

bool WriteOutputFile(const std::string& path, const std::string& bytes, std::string* error) {
  auto fail = [&](int err) {
    SetError(error, path + ": cannot write: " + std::strerror(err));
    return false;
  };
  struct stat st {};
  if (::stat(path.c_str(), &st) == 0 && !S_ISREG(st.st_mode)) {
    // A device, FIFO or terminal (/dev/stdout, /dev/full) cannot be
    // replaced: written in place, every step checked.
    const int fd = ::open(path.c_str(), O_WRONLY | O_TRUNC | O_CLOEXEC | O_NOCTTY);
    if (fd < 0) return fail(errno);
    if (!WriteAll(fd, bytes)) {
      const int err = errno;
      ::close(fd);
      return fail(err);
    }
    // close can report a deferred write error (NFS, quota).
    return ::close(fd) == 0 || fail(errno);
  }
  // A link is replaced at the file it names, not turned into a file.
  std::string target = path;
  if (char* real = ::realpath(path.c_str(), nullptr)) {
    target = real;
    std::free(real);
  }
  std::string partial;
  int fd = -1;
  if (!CreatePartialFile(target, &partial, &fd)) return fail(errno);
  // fsync: with delayed allocation a full disk shows only when the data is
  // written back, after every write() has succeeded.
  if (!WriteAll(fd, bytes) || ::fsync(fd) != 0) {
    const int err = errno;
    ::close(fd);
    ::unlink(partial.c_str());
    return fail(err);
  }
  if (::close(fd) != 0 || ::rename(partial.c_str(), target.c_str()) != 0) {
    const int err = errno;
    ::unlink(partial.c_str());
    return fail(err);
  }
  return true;
}

}  // namespace roomfix
