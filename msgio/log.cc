#include "msgio/log.h"

#include <fcntl.h>
#include <poll.h>
#include <sys/stat.h>
#include <sys/timerfd.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <lcm/lcm-cpp.hpp>
#include <map>
#include <sstream>

#include "msgio/bus.h"
#include "msgio/process.h"

namespace roomfix {

namespace {

constexpr uint32_t kLogSync = 0xEDA1DA01u;
constexpr uint8_t kSyncBytes[4] = {0xED, 0xA1, 0xDA, 0x01};
// Read-ahead of LogReader: one pread per this many bytes of small events.
constexpr int64_t kWindowBytes = 1 << 20;

uint32_t BigEndian32(const uint8_t* p) {
  return static_cast<uint32_t>(p[0]) << 24 | static_cast<uint32_t>(p[1]) << 16 |
         static_cast<uint32_t>(p[2]) << 8 | static_cast<uint32_t>(p[3]);
}

uint64_t BigEndian64(const uint8_t* p) {
  return static_cast<uint64_t>(BigEndian32(p)) << 32 | BigEndian32(p + 4);
}

// Reads exactly n bytes at offset; false on an error or the end of the file.
bool PreadAll(int fd, int64_t offset, uint8_t* out, int64_t n) {
  while (n > 0) {
    const ssize_t got = ::pread(fd, out, static_cast<size_t>(n), static_cast<off_t>(offset));
    if (got < 0 && errno == EINTR) continue;
    if (got <= 0) return false;
    out += got;
    offset += got;
    n -= got;
  }
  return true;
}

}  // namespace

std::unique_ptr<LogReader> LogReader::Open(const std::string& path, std::string* error) {
  // O_NONBLOCK: a FIFO given as a log must not block the open; it is then
  // refused as not a regular file.
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) {
    if (error != nullptr) *error = path + ": " + std::strerror(errno);
    return nullptr;
  }
  struct stat st;
  if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
    if (error != nullptr) *error = path + ": not a regular file";
    ::close(fd);
    return nullptr;
  }
  return std::unique_ptr<LogReader>(new LogReader(fd, {}, path, st.st_size));
}

std::unique_ptr<LogReader> LogReader::FromBytes(std::vector<uint8_t> bytes, std::string name) {
  const auto size = static_cast<int64_t>(bytes.size());
  return std::unique_ptr<LogReader>(new LogReader(-1, std::move(bytes), std::move(name), size));
}

LogReader::LogReader(int fd, std::vector<uint8_t> bytes, std::string path, int64_t size)
    : fd_(fd), bytes_(std::move(bytes)), path_(std::move(path)), file_size_(size) {}

LogReader::~LogReader() {
  if (fd_ >= 0) ::close(fd_);
}

bool LogReader::ReadAt(int64_t offset, void* out, int64_t n) {
  if (offset < 0 || n < 0 || offset + n > file_size_) return false;
  // An empty event's payload: nothing to copy, and `out` is then the data()
  // of an empty vector, a null pointer memcpy must not be given even for 0
  // bytes (UBSan in `make test SANITIZE=1`).
  if (n == 0) return true;
  auto* dst = static_cast<uint8_t*>(out);
  if (fd_ < 0) {
    std::memcpy(dst, bytes_.data() + offset, static_cast<size_t>(n));
    return true;
  }
  if (n > kWindowBytes) return PreadAll(fd_, offset, dst, n);
  const auto window_end = window_offset_ + static_cast<int64_t>(window_.size());
  if (offset < window_offset_ || offset + n > window_end) {
    const int64_t want = std::min(kWindowBytes, file_size_ - offset);
    window_.resize(static_cast<size_t>(want));
    window_offset_ = offset;
    if (!PreadAll(fd_, offset, window_.data(), want)) {
      window_.clear();
      return false;
    }
  }
  std::memcpy(dst, window_.data() + (offset - window_offset_), static_cast<size_t>(n));
  return true;
}

int64_t LogReader::FindSync(int64_t from) {
  constexpr int64_t kChunk = 64 << 10;
  std::vector<uint8_t> chunk;
  for (int64_t off = std::max<int64_t>(from, 0); off + 4 <= file_size_; off += kChunk) {
    // Chunks overlap by 3 bytes so a sync word across a boundary is found.
    const int64_t n = std::min(kChunk + 3, file_size_ - off);
    chunk.resize(static_cast<size_t>(n));
    if (!ReadAt(off, chunk.data(), n)) return -1;
    const void* hit = ::memmem(chunk.data(), chunk.size(), kSyncBytes, sizeof(kSyncBytes));
    if (hit != nullptr) return off + (static_cast<const uint8_t*>(hit) - chunk.data());
  }
  return -1;
}

void LogReader::Skip(int64_t from, int64_t to, const char* reason) {
  if (to <= from) return;
  bytes_skipped_ += to - from;
  const bool is_truncation = std::strcmp(reason, "truncated") == 0;
  // A refusal whose resynchronisation lands on another refused event is one
  // region, named for its first cause; a truncated end is always its own.
  if (!damage_.empty() && damage_.back().offset + damage_.back().bytes == from &&
      damage_.back().reason != "truncated" && !is_truncation) {
    damage_.back().bytes += to - from;
    return;
  }
  ++damage_regions_;
  if (damage_.size() < kMaxDamageRegionsKept) damage_.push_back({from, to - from, reason});
}

bool LogReader::Next(LogEvent* event) {
  // A file still being written (a live logger's) is read up to where it is
  // now, not where it was when opened.
  if (fd_ >= 0 && pos_ >= file_size_) {
    struct stat st;
    if (::fstat(fd_, &st) == 0 && st.st_size > file_size_) file_size_ = st.st_size;
  }
  while (pos_ < file_size_) {
    const int64_t start = pos_;
    uint8_t header[kLogEventHeaderBytes];
    if (!ReadAt(start, header, 4) || BigEndian32(header) != kLogSync) {
      const int64_t tail = file_size_ - start;
      if (tail < 4 && ReadAt(start, header, tail) &&
          std::memcmp(header, kSyncBytes, static_cast<size_t>(tail)) == 0) {
        // The first bytes of a sync word: a writer stopped as it began an event.
        truncated_ = true;
        pos_ = file_size_;
        Skip(start, pos_, "truncated");
        break;
      }
      const int64_t next = FindSync(start + 1);
      pos_ = next < 0 ? file_size_ : next;
      Skip(start, pos_, "not_an_event");
      continue;
    }
    if (!ReadAt(start, header, kLogEventHeaderBytes)) {
      truncated_ = true;
      pos_ = file_size_;
      Skip(start, pos_, "truncated");
      break;
    }
    const auto channel_bytes = static_cast<int32_t>(BigEndian32(header + 20));
    const auto data_bytes = static_cast<int32_t>(BigEndian32(header + 24));
    // The same limits as LCM 1.3.1's lcm_eventlog_read_next_event, checked
    // before anything is allocated, plus the payload cap.
    const char* refusal = nullptr;
    if (channel_bytes <= 0 || channel_bytes > kMaxLogChannelBytesLcmReads) {
      refusal = "bad_channel_length";
    } else if (data_bytes < 0) {
      refusal = "negative_data_length";
    } else if (data_bytes > kMaxLogEventDataBytes) {
      refusal = "data_length_over_cap";
    }
    const int64_t end = start + kLogEventHeaderBytes + int64_t{channel_bytes} + data_bytes;
    int64_t next_sync = -2;  // Not searched yet.
    if (refusal == nullptr && end > file_size_) {
      next_sync = FindSync(start + 4);
      if (next_sync < 0) {
        // Nothing follows: the writer stopped in the middle of this event.
        truncated_ = true;
        pos_ = file_size_;
        Skip(start, pos_, "truncated");
        break;
      }
      refusal = "runs_past_end";
    }
    if (refusal == nullptr && end < file_size_) {
      // LCM refuses an event not followed by a sync word (or the end). This
      // reader refuses it only when its claimed payload holds the next
      // sync word, i.e. its length is what is wrong; otherwise the event is
      // whole and the bytes after it are the damage (skipped next call).
      uint8_t after[4];
      if (!ReadAt(end, after, 4) || BigEndian32(after) != kLogSync) {
        next_sync = FindSync(start + 4);
        if (next_sync >= 0 && next_sync < end) refusal = "overlaps_next_event";
      }
    }
    if (refusal != nullptr) {
      if (next_sync == -2) next_sync = FindSync(start + 4);
      pos_ = next_sync < 0 ? file_size_ : next_sync;
      Skip(start, pos_, refusal);
      continue;
    }
    event->eventnum = static_cast<int64_t>(BigEndian64(header + 4));
    event->utime = static_cast<int64_t>(BigEndian64(header + 12));
    event->channel.resize(static_cast<size_t>(channel_bytes));
    event->data.resize(static_cast<size_t>(data_bytes));
    if (!ReadAt(start + kLogEventHeaderBytes, event->channel.data(), channel_bytes) ||
        !ReadAt(start + kLogEventHeaderBytes + channel_bytes, event->data.data(), data_bytes)) {
      // An I/O error, or the file shrank under us: nothing more is readable.
      truncated_ = true;
      pos_ = file_size_;
      Skip(start, pos_, "truncated");
      break;
    }
    pos_ = end;
    good_bytes_ = end;
    ++events_read_;
    return true;
  }
  return false;
}

std::string LogReader::DamageSummary() const {
  if (bytes_skipped_ == 0) return "";
  std::map<std::string, int64_t> reasons;
  for (const LogDamage& d : damage_) ++reasons[d.reason];
  std::ostringstream out;
  out << "skipped " << bytes_skipped_ << " bytes in " << damage_regions_
      << (damage_regions_ == 1 ? " region" : " regions") << " (";
  const char* separator = "";
  for (const auto& [reason, count] : reasons) {
    out << separator << reason << " " << count;
    separator = ", ";
  }
  out << "):";
  constexpr size_t kListed = 3;
  for (size_t i = 0; i < damage_.size() && i < kListed; ++i) {
    out << (i == 0 ? " " : ", ") << "at byte " << damage_[i].offset << " (" << damage_[i].bytes
        << " bytes, " << damage_[i].reason << ")";
  }
  if (damage_regions_ > static_cast<int64_t>(kListed)) {
    out << " and " << damage_regions_ - static_cast<int64_t>(kListed) << " more";
  }
  return out.str();
}

std::unique_ptr<LogWriter> LogWriter::Create(const std::string& path, bool overwrite,
                                             std::string* error) {
  struct stat st;
  if (!overwrite && ::stat(path.c_str(), &st) == 0) {
    if (error != nullptr) *error = path + ": already exists (refusing to overwrite)";
    return nullptr;
  }
  errno = 0;
  auto file = std::make_unique<lcm::LogFile>(path, "w");
  if (!file->good()) {
    if (error != nullptr) {
      *error = path + ": cannot create: " + (errno != 0 ? std::strerror(errno) : "unknown error");
    }
    return nullptr;
  }
  return std::unique_ptr<LogWriter>(new LogWriter(std::move(file), path));
}

LogWriter::LogWriter(std::unique_ptr<lcm::LogFile> file, std::string path)
    : file_(std::move(file)), path_(std::move(path)) {}

LogWriter::~LogWriter() = default;

bool LogWriter::Loggable(const std::string& channel, int64_t size, std::string* why) {
  if (channel.empty()) {
    *why = "empty channel name (LCM's log reader stops at it)";
    return false;
  }
  if (channel.size() > LCM_MAX_CHANNEL_NAME_LENGTH) {
    *why = "channel name of " + std::to_string(channel.size()) + " bytes (LCM allows " +
           std::to_string(LCM_MAX_CHANNEL_NAME_LENGTH) + ")";
    return false;
  }
  if (channel.find('\0') != std::string::npos) {
    *why = "channel name holds a NUL byte";
    return false;
  }
  if (size < 0 || size > kMaxLogEventDataBytes) {
    *why = "payload of " + std::to_string(size) + " bytes (at most " +
           std::to_string(kMaxLogEventDataBytes) + ")";
    return false;
  }
  return true;
}

bool LogWriter::Write(int64_t utime, const std::string& channel, const void* data, int size,
                      std::string* error) {
  std::string why;
  if (!Loggable(channel, size, &why)) {
    if (error != nullptr) *error = path_ + ": refused an event: " + why;
    return false;
  }
  lcm::LogEvent e;
  e.eventnum = events_written_;
  e.timestamp = utime;
  e.channel = channel;
  e.datalen = size;
  e.data = const_cast<void*>(data);  // lcm::LogFile's API is not const-correct.
  errno = 0;
  if (file_->writeEvent(&e) != 0) {
    if (error != nullptr) {
      *error = path_ + ": write failed: " + (errno != 0 ? std::strerror(errno) : "unknown error");
    }
    return false;
  }
  ++events_written_;
  return true;
}

bool LogWriter::Flush(std::string* error) {
  if (std::fflush(file_->getFilePtr()) != 0) {
    if (error != nullptr) *error = path_ + ": flush failed: " + std::strerror(errno);
    return false;
  }
  return true;
}

bool LogWriter::Sync(std::string* error) {
  if (!Flush(error)) return false;
  if (::fsync(::fileno(file_->getFilePtr())) != 0) {
    if (error != nullptr) *error = path_ + ": write failed: " + std::strerror(errno);
    return false;
  }
  return true;
}

bool ReadLogEvents(const std::string& path, std::vector<LogEvent>* events, std::string* error) {
  events->clear();
  auto reader = LogReader::Open(path, error);
  if (reader == nullptr) return false;
  LogEvent e;
  while (reader->Next(&e)) events->push_back(e);
  if (reader->damaged()) {
    *error = path + ": " + reader->DamageSummary();
    return false;
  }
  return true;
}

bool ParseLogUrl(const std::string& url, std::string* path, double* speed, std::string* error) {
  const std::string scheme = "file://";
  if (url.rfind(scheme, 0) != 0) {
    *error = url + ": not a file:// URL";
    return false;
  }
  const size_t question = url.find('?');
  *path = url.substr(scheme.size(),
                     question == std::string::npos ? std::string::npos : question - scheme.size());
  *speed = 1.0;  // LCM's file provider plays in real time unless told.
  if (path->empty()) {
    *error = url + ": no file name";
    return false;
  }
  if (question == std::string::npos) return true;
  std::istringstream options(url.substr(question + 1));
  std::string option;
  while (std::getline(options, option, '&')) {
    const size_t eq = option.find('=');
    const std::string key = option.substr(0, eq);
    const std::string value = eq == std::string::npos ? "" : option.substr(eq + 1);
    if (key == "speed") {
      char* end = nullptr;
      *speed = std::strtod(value.c_str(), &end);
      if (value.empty() || *end != '\0' || !(*speed >= 0.0) || !std::isfinite(*speed)) {
        *error = url + ": speed must be a number >= 0";
        return false;
      }
    } else if (key == "mode" && value == "r") {
    } else {
      *error = url + ": option '" + option + "' is not supported for reading a log";
      return false;
    }
  }
  return true;
}

namespace {

int64_t MonotonicUs() {
  timespec ts{};
  ::clock_gettime(CLOCK_MONOTONIC, &ts);
  return int64_t{ts.tv_sec} * 1'000'000 + ts.tv_nsec / 1000;
}

}  // namespace

std::unique_ptr<LogFileBus> LogFileBus::Create(const std::string& url, std::string* error) {
  std::string path;
  double speed = 1.0;
  if (!ParseLogUrl(url, &path, &speed, error)) return nullptr;
  auto reader = LogReader::Open(path, error);
  if (reader == nullptr) return nullptr;
  const int fd = ::timerfd_create(CLOCK_MONOTONIC, TFD_NONBLOCK | TFD_CLOEXEC);
  if (fd < 0) {
    *error = std::string("timerfd_create: ") + std::strerror(errno);
    return nullptr;
  }
  std::unique_ptr<LogFileBus> bus(new LogFileBus(std::move(reader), speed, fd));
  bus->Advance();
  return bus;
}

LogFileBus::LogFileBus(std::unique_ptr<LogReader> reader, double speed, int timer_fd)
    : reader_(std::move(reader)), speed_(speed), timer_fd_(timer_fd) {}

LogFileBus::~LogFileBus() { ::close(timer_fd_); }

bool LogFileBus::PublishRaw(const std::string& channel, const void*, int) {
  // A log opened for reading takes nothing; what a node publishes is dropped.
  CountPublished(true, channel);
  return true;
}

SubscriptionId LogFileBus::SubscribeRaw(const std::string& channel_regex, RawHandler handler) {
  return AddSubscription(channel_regex, std::move(handler));
}

void LogFileBus::Unsubscribe(SubscriptionId id) { RemoveSubscription(id); }

void LogFileBus::Advance() {
  have_next_ = reader_->Next(&next_);
  itimerspec due{};
  if (have_next_) {
    if (start_mono_us_ < 0) {
      start_mono_us_ = MonotonicUs();
      first_utime_ = next_.utime;
    }
    int64_t at_us = start_mono_us_;
    if (speed_ > 0) at_us += static_cast<int64_t>((next_.utime - first_utime_) / speed_);
    // An absolute time already past fires at once; 0 would disarm.
    at_us = std::max<int64_t>(at_us, 1);
    due.it_value.tv_sec = at_us / 1'000'000;
    due.it_value.tv_nsec = (at_us % 1'000'000) * 1000;
  } else {
    // The end: stay readable so the caller's next Handle() reports it.
    due.it_value.tv_nsec = 1;
  }
  ::timerfd_settime(timer_fd_, have_next_ ? TFD_TIMER_ABSTIME : 0, &due, nullptr);
}

int LogFileBus::Handle(int timeout_ms) {
  if (!have_next_) {
    RecordError(reader_->damaged()
                    ? "end of log " + reader_->path() + "; " + reader_->DamageSummary()
                    : "end of log " + reader_->path());
    return -1;
  }
  pollfd pfd{timer_fd_, POLLIN, 0};
  if (::poll(&pfd, 1, std::max(timeout_ms, 0)) <= 0) return 0;
  uint64_t expirations = 0;
  if (::read(timer_fd_, &expirations, sizeof(expirations)) < 0 && errno != EAGAIN) return 0;
  DeliverToSubscribers(MessageInfo{next_.channel, NowUtime()}, next_.data.data(),
                       static_cast<int>(next_.data.size()));
  Advance();
  return 1;
}

ReplaySummary ReplayLog(const std::string& path, LoopbackBus* bus, const ReplayOptions& options) {
  ReplaySummary summary;
  auto reader = LogReader::Open(path, &summary.error);
  if (reader == nullptr) return summary;
  summary.ok = true;
  const ChannelPattern pattern(options.channel_regex);
  LogEvent event;
  while (reader->Next(&event)) {
    if (summary.events_read == 0) summary.first_utime = event.utime;
    summary.last_utime = event.utime;
    ++summary.events_read;
    if (!pattern.Matches(event.channel)) continue;
    bus->set_now_utime(event.utime);
    if (options.on_time) options.on_time(event.utime);
    bus->Inject(event.channel, event.data.data(), static_cast<int>(event.data.size()), event.utime);
    ++summary.events_delivered;
  }
  summary.damaged = reader->damaged();
  summary.bytes_skipped = reader->bytes_skipped();
  summary.damage = reader->DamageSummary();
  return summary;
}

}  // namespace roomfix
