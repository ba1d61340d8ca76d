#ifndef ROOMFIX_MSGIO_LOG_H_
#define ROOMFIX_MSGIO_LOG_H_

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "msgio/bus.h"

namespace lcm {
class LogFile;
}

namespace roomfix {

// One event of an LCM log: what lcm-logger records and lcm-logplayer plays.
struct LogEvent {
  int64_t eventnum = 0;
  // Receive time, microseconds since the Unix epoch.
  int64_t utime = 0;
  std::string channel;
  std::vector<uint8_t> data;
};

// The largest payload a log event may claim: LCM_MAX_MESSAGE_SIZE, the
// largest message LCM itself transports (lcm.h, 256 MiB). No LCM bus can
// have delivered a bigger one, so a bigger length is damage, and LogWriter
// refuses to write one (LCM's reader would try to allocate it).
constexpr int64_t kMaxLogEventDataBytes = int64_t{1} << 28;
// LCM 1.3.1's reader (lcm_eventlog_read_next_event) refuses an event whose
// channel length is <= 0 or >= 1000 and stops reading the file there.
constexpr int kMaxLogChannelBytesLcmReads = 999;
// Bytes of an event besides its channel and payload: sync word, event
// number, timestamp, channel length, data length.
constexpr int64_t kLogEventHeaderBytes = 4 + 8 + 8 + 4 + 4;

// A stretch of a log that held no readable event and was skipped.
struct LogDamage {
  // File offset of the first skipped byte, and how many were skipped.
  int64_t offset = 0;
  int64_t bytes = 0;
  // Why reading stopped at `offset`: bad_channel_length,
  // negative_data_length, data_length_over_cap, runs_past_end (a length that
  // reaches past the end of the file while more events follow),
  // overlaps_next_event (the claimed payload holds the next event's sync word
  // and is not followed by one), not_an_event (bytes without a sync word) or
  // truncated (the last event is cut short by the end of the file).
  std::string reason;
};

// Reads an LCM log file event by event, and reads past damage.
//
// Not lcm::LogFile: liblcm 1.3.1's reader (lcm_eventlog_read_next_event)
// stops for good at the first event it refuses (an empty channel name), and
// for a data length of 0x7FFFFFFF calls calloc(1, len + 1), which overflows
// to a huge size, fails, and is then written into: SIGSEGV (measured, also
// through the file:// provider). It never says what it skipped. This reader
// accepts exactly the events LCM's accepts (same format, big-endian: sync
// word 0xEDA1DA01, int64 event number, int64 timestamp, int32 channel
// length, int32 data length, channel, data), refuses an event whose lengths
// are out of range or run past the end of the file before allocating
// anything, resynchronises at the next sync word, and records every skipped
// region. Memory per event is bounded by the bytes actually in the file.
class LogReader {
 public:
  // nullptr with a one-line reason when the file cannot be opened.
  static std::unique_ptr<LogReader> Open(const std::string& path, std::string* error);
  // Reads a log held in memory (fuzzing, tests); `name` stands for the path.
  static std::unique_ptr<LogReader> FromBytes(std::vector<uint8_t> bytes, std::string name);
  ~LogReader();

  // Reads the next good event into *event, skipping (and recording) damage;
  // false at the end of the file.
  bool Next(LogEvent* event);

  // True when anything was skipped: a corrupt region or a truncated end.
  bool damaged() const { return bytes_skipped_ > 0; }
  // True when the last event is cut short by the end of the file (what a
  // kill -9 of a writer leaves); those bytes count as skipped.
  bool truncated() const { return truncated_; }
  int64_t bytes_skipped() const { return bytes_skipped_; }
  // The skipped regions in file order; at most kMaxDamageRegionsKept are
  // kept, damage_regions() counts them all.
  const std::vector<LogDamage>& damage() const { return damage_; }
  int64_t damage_regions() const { return damage_regions_; }
  static constexpr size_t kMaxDamageRegionsKept = 64;
  // One line for a warning, "" when nothing was skipped: "skipped 2147 bytes
  // in 2 regions (data_length_over_cap 1, truncated 1): at byte 62 (2085
  // bytes, data_length_over_cap), at byte 2170 (62 bytes, truncated)".
  std::string DamageSummary() const;

  // File offset just past the last good event read, and the file's size.
  int64_t bytes_read() const { return good_bytes_; }
  int64_t file_size() const { return file_size_; }
  int64_t events_read() const { return events_read_; }
  const std::string& path() const { return path_; }

 private:
  LogReader(int fd, std::vector<uint8_t> bytes, std::string path, int64_t size);
  bool ReadAt(int64_t offset, void* out, int64_t n);
  // The offset of the next sync word at or after `from`, or -1.
  int64_t FindSync(int64_t from);
  void Skip(int64_t from, int64_t to, const char* reason);

  int fd_ = -1;
  std::vector<uint8_t> bytes_;  // FromBytes only.
  // A read-ahead window of the file (fd_ only).
  std::vector<uint8_t> window_;
  int64_t window_offset_ = 0;
  std::string path_;
  int64_t file_size_ = 0;
  int64_t pos_ = 0;
  int64_t events_read_ = 0;
  int64_t good_bytes_ = 0;
  int64_t bytes_skipped_ = 0;
  int64_t damage_regions_ = 0;
  bool truncated_ = false;
  std::vector<LogDamage> damage_;
};

// Writes an LCM log file that lcm-logplayer and lcm::LogFile read. Event
// numbers are assigned in write order from 0, as lcm-logger does.
class LogWriter {
 public:
  // Refuses to replace an existing file unless overwrite is true.
  static std::unique_ptr<LogWriter> Create(const std::string& path, bool overwrite,
                                           std::string* error);
  ~LogWriter();

  // Whether LCM's tools could read and replay the event; if not, false with
  // the reason in *why. Refused: an empty channel (LCM's reader stops the
  // whole file there), one longer than LCM_MAX_CHANNEL_NAME_LENGTH (63
  // bytes: lcm_publish, and so lcm-logplayer, refuses it; LCM's reader stops
  // at 1000), one holding a NUL byte (LCM's C API would see a shorter name),
  // and a payload over kMaxLogEventDataBytes or negative.
  static bool Loggable(const std::string& channel, int64_t size, std::string* why);

  // False (with *error) when the event is not Loggable (nothing is written
  // and the file stays good) or the write failed, e.g. a full disk; events
  // already written stay readable.
  bool Write(int64_t utime, const std::string& channel, const void* data, int size,
             std::string* error);
  // Pushes buffered events to the operating system.
  bool Flush(std::string* error);
  // Flush, then fsync: with delayed allocation a full disk shows only when
  // the data is written back. For a log that is finished (roomfix replay's
  // new log is renamed into place only after this succeeds).
  bool Sync(std::string* error);
  int64_t events_written() const { return events_written_; }
  const std::string& path() const { return path_; }

 private:
  LogWriter(std::unique_ptr<lcm::LogFile> file, std::string path);
  std::unique_ptr<lcm::LogFile> file_;
  std::string path_;
  int64_t events_written_ = 0;
};

// Reads a whole log into memory (for tests and small logs). False, with the
// reason, when it cannot be opened or is damaged; the good events are in
// *events either way.
bool ReadLogEvents(const std::string& path, std::vector<LogEvent>* events, std::string* error);

// A file:// URL as LCM's file provider takes it ("file:///tmp/a.lcm?speed=0"):
// the log's path and the playback speed (1: as recorded, 0: as fast as
// possible). False with the reason for another scheme or an option LCM's
// provider would not accept for reading.
bool ParseLogUrl(const std::string& url, std::string* path, double* speed, std::string* error);

// A bus that plays a log given as a file:// URL, in place of LCM's file
// provider (which runs liblcm's log reader: SIGSEGV on an event claiming
// 0x7FFFFFFF bytes, and the rest of the file lost after an empty channel).
// Like LCM's provider it keeps the recorded spacing scaled by ?speed= (0: as
// fast as possible), stamps messages with the wall clock, drops what is
// published, and Handle() returns -1 at the end of the log, with the
// damage skipped, if any, in stats().last_error. Fileno() is a timer that
// becomes readable when the next event is due, so RunLoop works unchanged.
class LogFileBus final : public Bus {
 public:
  static std::unique_ptr<LogFileBus> Create(const std::string& url, std::string* error);
  ~LogFileBus() override;

  bool PublishRaw(const std::string& channel, const void* data, int size) override;
  SubscriptionId SubscribeRaw(const std::string& channel_regex, RawHandler handler) override;
  void Unsubscribe(SubscriptionId id) override;
  int Handle(int timeout_ms) override;
  int Fileno() const override { return timer_fd_; }
  const LogReader& reader() const { return *reader_; }

 private:
  LogFileBus(std::unique_ptr<LogReader> reader, double speed, int timer_fd);
  // Reads the next event and arms the timer for when it is due.
  void Advance();
  std::unique_ptr<LogReader> reader_;
  double speed_;
  int timer_fd_;
  LogEvent next_;
  bool have_next_ = false;
  // Monotonic time of the first event and its log time, for the pacing.
  int64_t start_mono_us_ = -1;
  int64_t first_utime_ = 0;
};

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
  // Bytes were skipped (corrupt regions or a truncated end); every good
  // event around them was replayed. `damage` is LogReader::DamageSummary().
  bool damaged = false;
  int64_t bytes_skipped = 0;
  std::string damage;
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
