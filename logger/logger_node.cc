#include "logger/logger_node.h"

#include <fmt/format.h>
#include <sys/stat.h>

#include <chrono>
#include <ctime>
#include <string>
#include <utility>

namespace roomfix {

bool LoggerOptions::IsValid(std::string* error) const {
  if (path.empty()) {
    *error = "a log file path is required";
    return false;
  }
  if (!ChannelPattern(channel_regex).valid()) {
    *error = "channel expression '" + channel_regex + "' is not a valid regular expression";
    return false;
  }
  if (flush_interval_ms <= 0) {
    *error = "flush interval must be positive";
    return false;
  }
  if (rotate_bytes < 0 || rotate_seconds < 0.0) {
    *error = "rotation size and time must not be negative";
    return false;
  }
  if (increment && overwrite) {
    *error = "--increment and --force exclude each other (one never overwrites, the other does)";
    return false;
  }
  if (max_queue_bytes <= 0) {
    *error = "queue size must be positive";
    return false;
  }
  return true;
}

std::string RotatedLogPath(const std::string& path, int index) {
  const std::string number = fmt::format(".{:04d}", index);
  const size_t slash = path.find_last_of('/');
  const size_t dot = path.find_last_of('.');
  if (dot == std::string::npos || (slash != std::string::npos && dot < slash)) {
    return path + number;
  }
  return path.substr(0, dot) + number + path.substr(dot);
}

namespace {
// "dir/session.lcm" -> ("dir/session", ".lcm"); no extension -> (path, "").
std::pair<std::string, std::string> SplitExtension(const std::string& path) {
  const size_t slash = path.find_last_of('/');
  const size_t dot = path.find_last_of('.');
  const bool has_extension =
      dot != std::string::npos && dot > 0 && (slash == std::string::npos || dot > slash + 1);
  if (!has_extension) return {path, ""};
  return {path.substr(0, dot), path.substr(dot)};
}

bool PathExists(const std::string& path) {
  struct stat st;
  return ::lstat(path.c_str(), &st) == 0;
}

// Far beyond any real number of restarts; bounds the search on a folder
// that somehow holds them all.
constexpr int kMaxRunNumber = 100000;
}  // namespace

std::string IncrementedLogPath(const std::string& path, int number) {
  const auto [stem, extension] = SplitExtension(path);
  return fmt::format("{}-{:02d}{}", stem, number, extension);
}

std::string ExpandLogPath(const std::string& pattern, int64_t utime) {
  if (pattern.find('%') == std::string::npos) return pattern;
  const std::time_t seconds = static_cast<std::time_t>(utime / 1'000'000);
  std::tm tm{};
  gmtime_r(&seconds, &tm);
  std::vector<char> out(pattern.size() + 256);
  const size_t n = std::strftime(out.data(), out.size(), pattern.c_str(), &tm);
  return n > 0 ? std::string(out.data(), n) : pattern;
}

std::unique_ptr<LoggerNode> LoggerNode::Create(Bus* bus, const LoggerOptions& options,
                                               int64_t start_utime, std::string* error) {
  if (!options.IsValid(error)) return nullptr;
  std::unique_ptr<LoggerNode> node(new LoggerNode(bus, options, start_utime));
  if (!node->OpenNext(start_utime, error)) return nullptr;
  node->thread_ = std::thread(&LoggerNode::WriterLoop, node.get());
  node->subscriptions_.Add(bus->SubscribeRaw(
      options.channel_regex, [n = node.get()](const MessageInfo& info, const void* data, int size) {
        n->OnMessage(info, data, size);
      }));
  node->status_.SetState(process_status_t::STATE_RUNNING);
  return node;
}

LoggerNode::LoggerNode(Bus* bus, const LoggerOptions& options, int64_t start_utime)
    : bus_(bus), options_(options), status_("roomfix_logger", start_utime) {}

LoggerNode::~LoggerNode() {
  subscriptions_.Clear();
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  if (thread_.joinable()) thread_.join();
}

bool LoggerNode::OpenNext(int64_t utime, std::string* error) {
  const std::string expanded = ExpandLogPath(options_.path, utime);
  const auto name_of = [&](const std::string& base) {
    return options_.rotating() ? RotatedLogPath(base, file_index_) : base;
  };
  std::string path = name_of(expanded);
  if (options_.increment) {
    // The first number whose file is not there yet. A run's first file
    // checks index 0 of each number, so a restarted rotating logger does not
    // slip its files in among an earlier run's.
    int number = run_number_;
    while (number < kMaxRunNumber && PathExists(name_of(IncrementedLogPath(expanded, number)))) {
      ++number;
    }
    if (number == kMaxRunNumber) {
      *error = IncrementedLogPath(expanded, 0) + ": no free numbered name up to " +
               std::to_string(kMaxRunNumber);
      return false;
    }
    run_number_ = number;
    path = name_of(IncrementedLogPath(expanded, number));
  }
  if (writer_ != nullptr && !writer_->Flush(error)) return false;
  auto writer = LogWriter::Create(path, options_.overwrite, error);
  if (writer == nullptr) return false;
  writer_ = std::move(writer);
  file_bytes_ = 0;
  file_opened_utime_ = -1;
  ++file_index_;
  std::lock_guard<std::mutex> lock(mutex_);
  files_.push_back(path);
  return true;
}

std::vector<std::string> LoggerNode::files() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return files_;
}

void LoggerNode::OnMessage(const MessageInfo& info, const void* data, int size) {
  status_.AddInputs();
  // An event LCM's log tools cannot read (an empty channel name stops LCM's
  // reader for the rest of the file) is refused here, so one hostile
  // datagram cannot spoil a recording; counted, and recording goes on.
  std::string why;
  if (!LogWriter::Loggable(info.channel, size, &why)) {
    status_.Reject(size < 0 || size > kMaxLogEventDataBytes ? "unloggable_size"
                                                            : "unloggable_channel");
    return;
  }
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!failed_ && queued_bytes_ + size <= options_.max_queue_bytes) {
      const auto* bytes = static_cast<const uint8_t*>(data);
      queue_.push_back({info.recv_utime, info.channel, std::vector<uint8_t>(bytes, bytes + size)});
      queued_bytes_ += size;
      peak_queued_bytes_ = std::max(peak_queued_bytes_, queued_bytes_);
      if (queue_.size() == 1) wake_.notify_one();
      return;
    }
  }
  // Queue full (the disk is slower than the network) or writing has failed.
  status_.AddDropped();
}

void LoggerNode::WriterLoop() {
  using Clock = std::chrono::steady_clock;
  const auto flush_every = std::chrono::milliseconds(options_.flush_interval_ms);
  auto last_flush = Clock::now();
  std::deque<Event> batch;
  while (true) {
    bool stopping = false;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      wake_.wait_for(lock, flush_every, [this] { return stopping_ || !queue_.empty(); });
      batch.swap(queue_);
      queued_bytes_ = 0;
      stopping = stopping_;
    }
    for (Event& e : batch) {
      bool failed;
      {
        std::lock_guard<std::mutex> lock(mutex_);
        failed = failed_;
      }
      if (failed) {
        status_.AddDropped();
        continue;
      }
      std::string error;
      if (file_opened_utime_ < 0) file_opened_utime_ = e.utime;
      const bool rotate = (options_.rotate_bytes > 0 && file_bytes_ >= options_.rotate_bytes) ||
                          (options_.rotate_seconds > 0.0 &&
                           (e.utime - file_opened_utime_) * 1e-6 >= options_.rotate_seconds);
      if (rotate) {
        if (!OpenNext(e.utime, &error)) {
          std::lock_guard<std::mutex> lock(mutex_);
          failed_ = true;
        } else {
          file_opened_utime_ = e.utime;
          status_.Count("files_opened");
        }
      }
      if (!failed_ && writer_->Write(e.utime, e.channel, e.data.data(),
                                     static_cast<int>(e.data.size()), &error)) {
        file_bytes_ +=
            kLogEventHeaderBytes + static_cast<int64_t>(e.channel.size() + e.data.size());
        status_.AddOutputs();
        continue;
      }
      // A failed write (full or vanished disk): stop writing, keep what is
      // there, and say so. Events from here on are dropped and counted.
      {
        std::lock_guard<std::mutex> lock(mutex_);
        failed_ = true;
      }
      status_.AddDropped();
      status_.SetState(process_status_t::STATE_FAILED);
      status_.SetError(error, e.utime);
      std::string ignored;
      writer_->Flush(&ignored);
    }
    batch.clear();
    if (stopping || Clock::now() - last_flush >= flush_every) {
      std::string error;
      bool failed;
      {
        std::lock_guard<std::mutex> lock(mutex_);
        failed = failed_;
      }
      if (!failed && !writer_->Flush(&error)) {
        std::lock_guard<std::mutex> lock(mutex_);
        failed_ = true;
        status_.SetState(process_status_t::STATE_FAILED);
        status_.SetError(error, 0);
      }
      last_flush = Clock::now();
    }
    if (stopping) {
      std::lock_guard<std::mutex> lock(mutex_);
      if (queue_.empty()) break;
    }
  }
  writer_.reset();
}

void LoggerNode::Tick(int64_t now_utime) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    status_.SetCounter("queue_bytes", queued_bytes_);
    status_.SetCounter("queue_peak_bytes", peak_queued_bytes_);
  }
  status_.MaybePublish(bus_, now_utime);
}

void LoggerNode::Stop(int64_t now_utime) {
  subscriptions_.Clear();
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  if (thread_.joinable()) thread_.join();
  if (status_.Make(now_utime, nullptr).state != process_status_t::STATE_FAILED) {
    status_.SetState(process_status_t::STATE_STOPPING);
  }
  status_.Publish(bus_, now_utime);
}

}  // namespace roomfix
