#ifndef ROOMFIX_LOGGER_LOGGER_NODE_H_
#define ROOMFIX_LOGGER_LOGGER_NODE_H_

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "msgio/bus.h"
#include "msgio/log.h"
#include "msgio/process.h"
#include "msgio/subscriptions.h"

namespace roomfix {

struct LoggerOptions {
  // Where to write. Without rotation exactly this file; with rotation
  // numbered files beside it: session.lcm -> session.0000.lcm, session.0001.lcm, ...
  // strftime conversions (%Y %m %d %H %M %S ...) are expanded in UTC when
  // each file is opened, so a restarted logger starts a new file instead of
  // refusing to overwrite the last one: "roomfix-%Y%m%d-%H%M%S.lcm".
  std::string path;
  // Channels to record (LCM regular expression, whole-name match).
  std::string channel_regex = ".*";
  // Replace existing files instead of refusing to start.
  bool overwrite = false;
  // Never overwrite and never refuse: each run writes under the first free
  // numbered name, session.lcm -> session-00.lcm, session-01.lcm, ... (with
  // rotation session-01.0000.lcm, ...). What lcm-logger --increment does
  // (it writes session.lcm.00, ...), keeping the .lcm extension. For a
  // logger that bot-procman may restart: a restart never touches the last
  // run's log. Excludes overwrite.
  bool increment = false;
  // Written events reach the operating system at least this often, so a
  // kill -9 loses at most this much.
  int flush_interval_ms = 100;
  // Start a new numbered file when the current one reaches this size
  // (0: never) or has been open this long (0: never).
  int64_t rotate_bytes = 0;
  double rotate_seconds = 0.0;
  // Events received but not yet written, in payload bytes; beyond it new
  // events are dropped (and counted) rather than growing memory without end.
  int64_t max_queue_bytes = 64 << 20;

  bool IsValid(std::string* error) const;
  bool rotating() const { return rotate_bytes > 0 || rotate_seconds > 0.0; }
};

// Records LCM traffic into LCM log files that lcm-logplayer plays and
// lcm::LogFile reads: channel, receive timestamp and payload unchanged,
// event numbers from 0 in each file.
//
// Events LCM's log tools could not read back (LogWriter::Loggable: an empty
// or over-long channel name, an oversized payload) are refused, counted in
// STATUS rejected[] as unloggable_channel or unloggable_size, and skipped.
//
// Receiving and writing are split: the bus handler only copies the event
// into a bounded queue (no disk access on the receive thread, so a slow disk
// cannot stall LCM's socket), and a writer thread drains it. When the queue
// is full, or the disk fails, events are dropped and counted; what was
// already written stays readable (a failed write stops the writer and the
// file is flushed up to the last whole event).
class LoggerNode {
 public:
  // Opens the first file. Returns nullptr with a one-line reason when the
  // file exists (and overwrite is off) or cannot be created.
  static std::unique_ptr<LoggerNode> Create(Bus* bus, const LoggerOptions& options,
                                            int64_t start_utime, std::string* error);
  // Unsubscribes (the bus would otherwise call into a freed node), then
  // writes what is queued. Like Stop, on the thread that calls bus->Handle:
  // a Bus is not thread-safe.
  ~LoggerNode();

  // Heartbeat; call from the receive loop.
  void Tick(int64_t now_utime);
  // Stops receiving (later events are neither recorded nor counted), writes
  // everything still queued, flushes and closes the file.
  void Stop(int64_t now_utime);

  const StatusReporter& status() const { return status_; }
  // Files written so far, in order.
  std::vector<std::string> files() const;

 private:
  LoggerNode(Bus* bus, const LoggerOptions& options, int64_t start_utime);
  bool OpenNext(int64_t utime, std::string* error);
  void OnMessage(const MessageInfo& info, const void* data, int size);
  void WriterLoop();

  struct Event {
    int64_t utime;
    std::string channel;
    std::vector<uint8_t> data;
  };

  Bus* bus_;
  // Ended first thing in Stop and in the destructor.
  Subscriptions subscriptions_{bus_};
  LoggerOptions options_;
  StatusReporter status_;

  mutable std::mutex mutex_;
  std::condition_variable wake_;
  std::deque<Event> queue_;
  int64_t queued_bytes_ = 0;
  int64_t peak_queued_bytes_ = 0;
  bool stopping_ = false;
  bool failed_ = false;

  // Writer thread only (and Create before it starts).
  std::unique_ptr<LogWriter> writer_;
  int64_t file_bytes_ = 0;
  int64_t file_opened_utime_ = 0;
  int file_index_ = 0;
  // With increment: the run number chosen for the first file; later files
  // of the run start their search there, so a run's files share a number.
  int run_number_ = 0;
  std::vector<std::string> files_;
  std::thread thread_;
};

// The name of rotated file `index`: "dir/session.lcm" -> "dir/session.0003.lcm".
std::string RotatedLogPath(const std::string& path, int index);
// The name of run `number` with --increment: "dir/session.lcm" ->
// "dir/session-03.lcm" (at least two digits).
std::string IncrementedLogPath(const std::string& path, int number);
// `pattern` with its strftime conversions expanded for `utime` (UTC); the
// pattern itself when it has none.
std::string ExpandLogPath(const std::string& pattern, int64_t utime);

}  // namespace roomfix

#endif  // ROOMFIX_LOGGER_LOGGER_NODE_H_
