#include "msgio/log.h"

#include <sys/stat.h>

#include <cerrno>
#include <cstring>
#include <lcm/lcm-cpp.hpp>

#include "msgio/bus.h"

namespace roomfix {

std::unique_ptr<LogReader> LogReader::Open(const std::string& path, std::string* error) {
  struct stat st;
  if (::stat(path.c_str(), &st) != 0) {
    if (error != nullptr) *error = path + ": " + std::strerror(errno);
    return nullptr;
  }
  if (!S_ISREG(st.st_mode)) {
    if (error != nullptr) *error = path + ": not a regular file";
    return nullptr;
  }
  auto file = std::make_unique<lcm::LogFile>(path, "r");
  if (!file->good()) {
    if (error != nullptr) *error = path + ": cannot open as an LCM log";
    return nullptr;
  }
  return std::unique_ptr<LogReader>(new LogReader(std::move(file), path, st.st_size));
}

LogReader::LogReader(std::unique_ptr<lcm::LogFile> file, std::string path, int64_t size)
    : file_(std::move(file)), path_(std::move(path)), file_size_(size) {}

LogReader::~LogReader() = default;

bool LogReader::Next(LogEvent* event) {
  if (at_end_) return false;
  const lcm::LogEvent* e = file_->readNextEvent();
  if (e == nullptr) {
    at_end_ = true;
    return false;
  }
  event->eventnum = e->eventnum;
  event->utime = e->timestamp;
  event->channel = e->channel;
  const auto* bytes = static_cast<const uint8_t*>(e->data);
  event->data.assign(bytes, bytes + e->datalen);
  ++events_read_;
  FILE* f = file_->getFilePtr();
  if (f != nullptr) good_bytes_ = static_cast<int64_t>(std::ftell(f));
  return true;
}

bool LogReader::damaged() const { return at_end_ && good_bytes_ < file_size_; }

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

bool LogWriter::Write(int64_t utime, const std::string& channel, const void* data, int size,
                      std::string* error) {
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

bool ReadLogEvents(const std::string& path, std::vector<LogEvent>* events, std::string* error) {
  events->clear();
  auto reader = LogReader::Open(path, error);
  if (reader == nullptr) return false;
  LogEvent e;
  while (reader->Next(&e)) events->push_back(e);
  if (reader->damaged()) {
    *error = path + ": unreadable after byte " + std::to_string(reader->bytes_read());
    return false;
  }
  return true;
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
  if (summary.damaged) {
    summary.error = path + ": unreadable after byte " + std::to_string(reader->bytes_read()) +
                    " of " + std::to_string(reader->file_size());
  }
  return summary;
}

}  // namespace roomfix
