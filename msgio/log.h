#ifndef ROOMFIX_MSGIO_LOG_H_
#define ROOMFIX_MSGIO_LOG_H_

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace lcm {
class LogFile;
}

namespace roomfix {

class LoopbackBus;

// One event of an LCM log: what lcm-logger records and lcm-logplayer plays.
struct LogEvent {
  int64_t eventnum = 0;
  // Receive time, microseconds since the Unix epoch.
  int64_t utime = 0;
  std::string channel;
  std::vector<uint8_t> data;
};

// Reads an LCM log file (lcm::LogFile) event by event.
class LogReader {
 public:
  // nullptr with a one-line reason when the file cannot be opened.
  static std::unique_ptr<LogReader> Open(const std::string& path, std::string* error);
  ~LogReader();

  // Reads the next event into *event; false at the end of the log or where
  // it stops being readable (then damaged() tells which).
  bool Next(LogEvent* event);

  // True when reading stopped before the end of the file: a truncated last
  // event or a corrupt region LCM could not resynchronise past.
  bool damaged() const;
  // Bytes of the file up to the end of the last whole event, and its size.
  int64_t bytes_read() const { return good_bytes_; }
  int64_t file_size() const { return file_size_; }
  int64_t events_read() const { return events_read_; }
  const std::string& path() const { return path_; }

 private:
  LogReader(std::unique_ptr<lcm::LogFile> file, std::string path, int64_t size);
  std::unique_ptr<lcm::LogFile> file_;
  std::string path_;
  int64_t file_size_ = 0;
  int64_t events_read_ = 0;
  // File offset just past the last whole event read.
  int64_t good_bytes_ = 0;
  bool at_end_ = false;
};

// Writes an LCM log file that lcm-logplayer and lcm::LogFile read. Event
// numbers are assigned in write order from 0, as lcm-logger does.
class LogWriter {
 public:
  // Refuses to replace an existing file unless overwrite is true.
  static std::unique_ptr<LogWriter> Create(const std::string& path, bool overwrite,
                                           std::string* error);
  ~LogWriter();

  // False (with *error) when the write failed, e.g. a full disk; events
  // already written stay readable.
  bool Write(int64_t utime, const std::string& channel, const void* data, int size,
             std::string* error);
  // Pushes buffered events to the operating system.
  bool Flush(std::string* error);
  int64_t events_written() const { return events_written_; }
  const std::string& path() const { return path_; }

 private:
  LogWriter(std::unique_ptr<lcm::LogFile> file, std::string path);
  std::unique_ptr<lcm::LogFile> file_;
  std::string path_;
  int64_t events_written_ = 0;
};

// Reads a whole log into memory (for tests and small logs). False, with the
// reason, when it cannot be opened or is damaged; the readable events are in
// *events either way.
bool ReadLogEvents(const std::string& path, std::vector<LogEvent>* events, std::string* error);

struct ReplayOptions {
  // Only events on matching channels are delivered (LCM regex rules).
  std::string channel_regex = ".*";
  // Called with each event's timestamp before the event is delivered, so a
  // node's timers (deadlines, heartbeats) run on log time.
  std::function<void(int64_t utime)> on_time;
};

struct ReplaySummary {
  int64_t events_read = 0;
  int64_t events_delivered = 0;
  int64_t first_utime = 0;
  int64_t last_utime = 0;
  // The log ended early (truncated or corrupt); what came before was replayed.
  bool damaged = false;
  // False when the log could not be opened at all.
  bool ok = false;
  std::string error;
};

// Reads the log in order and delivers each event to the bus's subscribers
// with the event's timestamp as the receive time and the bus clock. The same
// node class as live sees the same messages, without a network.
ReplaySummary ReplayLog(const std::string& path, LoopbackBus* bus,
                        const ReplayOptions& options = ReplayOptions());

}  // namespace roomfix

#endif  // ROOMFIX_MSGIO_LOG_H_
