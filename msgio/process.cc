#include "msgio/process.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <poll.h>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <utility>

#include "msgio/log.h"
#include "msgio/site_message.h"
#include "msgio/udpm_bus.h"
#include "msgio/wire_check.h"

namespace roomfix {

int64_t NowUtime() {
  using namespace std::chrono;
  return duration_cast<microseconds>(system_clock::now().time_since_epoch()).count();
}

void AddProcessFlags(CLI::App* app, ProcessOptions* options, bool config_required) {
  app->add_option("--lcm-url", options->lcm_url,
                  "LCM URL: udpm://GROUP:PORT?ttl=N (ttl=0 stays on this host), memq://, "
                  "file://LOG?speed=1")
      ->capture_default_str();
  auto* config = app->add_option("--config", options->config_path, "Site file (YAML)")
                     ->check(CLI::ExistingFile);
  if (config_required) config->required();
  app->add_option("--log-level", options->log_level, "trace, debug, info, warn or error")
      ->capture_default_str()
      ->check(CLI::IsMember({"trace", "debug", "info", "warn", "error"}));
  app->add_option("--log-color", options->log_color,
                  "Colour log lines: auto (only on a terminal, and not when NO_COLOR is set), "
                  "always or never")
      ->capture_default_str()
      ->check(CLI::IsMember({"auto", "always", "never"}));
  app->add_flag("--check", options->check,
                "Validate the flags and the site file, print what would run, and exit");
}

bool LogColorWanted(const std::string& mode, bool stderr_is_tty, const char* no_color) {
  if (mode == "always") return true;
  if (mode == "never") return false;
  return stderr_is_tty && (no_color == nullptr || no_color[0] == '\0');
}

bool SetUpLogging(const std::string& process_name, const std::string& level,
                  const std::string& color) {
  const auto parsed = spdlog::level::from_str(level);
  if (parsed == spdlog::level::off && level != "off") return false;
  if (color != "auto" && color != "always" && color != "never") return false;
  // Decided here rather than by spdlog's own automatic mode, which looks at
  // TERM but not at NO_COLOR.
  const bool colour = LogColorWanted(color, ::isatty(STDERR_FILENO) == 1, std::getenv("NO_COLOR"));
  auto logger = spdlog::stderr_color_mt(
      process_name, colour ? spdlog::color_mode::always : spdlog::color_mode::never);
  logger->set_level(parsed);
  logger->set_pattern("%Y-%m-%d %H:%M:%S.%e %n %^%l%$: %v");
  spdlog::set_default_logger(logger);
  return true;
}

// ---------------------------------------------------------------------------

StatusReporter::StatusReporter(std::string process_name, int64_t start_utime)
    : process_(std::move(process_name)),
      pid_(static_cast<int32_t>(::getpid())),
      start_utime_(start_utime) {
  char host[256] = {0};
  if (::gethostname(host, sizeof(host) - 1) == 0) host_ = host;
}

void StatusReporter::AddInputs(int64_t n) {
  std::lock_guard<std::mutex> lock(mutex_);
  inputs_ += n;
}
void StatusReporter::AddOutputs(int64_t n) {
  std::lock_guard<std::mutex> lock(mutex_);
  outputs_ += n;
}
void StatusReporter::AddDropped(int64_t n) {
  std::lock_guard<std::mutex> lock(mutex_);
  dropped_ += n;
}
void StatusReporter::Reject(const std::string& reason, int64_t n) {
  std::lock_guard<std::mutex> lock(mutex_);
  rejected_[reason] += n;
}
void StatusReporter::Count(const std::string& name, int64_t n) {
  std::lock_guard<std::mutex> lock(mutex_);
  counters_[name] += n;
}
void StatusReporter::SetCounter(const std::string& name, int64_t value) {
  std::lock_guard<std::mutex> lock(mutex_);
  counters_[name] = value;
}
void StatusReporter::SetState(int8_t state) {
  std::lock_guard<std::mutex> lock(mutex_);
  state_ = state;
}
void StatusReporter::SetError(const std::string& text, int64_t utime) {
  std::lock_guard<std::mutex> lock(mutex_);
  last_error_ = text;
  last_error_utime_ = utime;
}

int64_t StatusReporter::inputs() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return inputs_;
}
int64_t StatusReporter::outputs() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return outputs_;
}
int64_t StatusReporter::dropped() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return dropped_;
}
int64_t StatusReporter::rejected(const std::string& reason) const {
  std::lock_guard<std::mutex> lock(mutex_);
  auto it = rejected_.find(reason);
  return it == rejected_.end() ? 0 : it->second;
}
int64_t StatusReporter::counter(const std::string& name) const {
  std::lock_guard<std::mutex> lock(mutex_);
  auto it = counters_.find(name);
  return it == counters_.end() ? 0 : it->second;
}

namespace {
counter_t MakeCounter(const std::string& name, int64_t count) {
  counter_t c{};
  c.name = name;
  c.count = count;
  return c;
}
}  // namespace

process_status_t StatusReporter::Make(int64_t utime, const BusStats* bus_stats) const {
  std::lock_guard<std::mutex> lock(mutex_);
  process_status_t s{};
  s.utime = utime;
  s.process = process_;
  s.host = host_;
  s.pid = pid_;
  s.uptime_us = utime - start_utime_;
  s.state = state_;
  s.inputs = inputs_;
  s.outputs = outputs_;
  s.dropped = dropped_;
  auto rejected = rejected_;
  auto counters = counters_;
  // Which site the process runs with (site_message.h): equal values mean
  // equal site and calibration texts.
  if (const auto site = ProcessSite()) {
    const int64_t hash = SiteHashCounterValue(site->content_hash);
    if (hash >= 0) counters[kSiteHashCounter] = hash;
  }
  s.last_error = last_error_;
  s.last_error_utime = last_error_utime_;
  if (bus_stats != nullptr) {
    // A message refused before decoding is input refused at the door, named
    // `<CHANNEL>.<reason>`; a throwing handler is a bug, surfaced rather
    // than hidden.
    for (const auto& [key, count] : bus_stats->refused) rejected[key] += count;
    if (bus_stats->handler_exceptions > 0) {
      counters["handler_exceptions"] += bus_stats->handler_exceptions;
    }
    if (bus_stats->publish_failures > 0) {
      counters["publish_failures"] += bus_stats->publish_failures;
    }
    // Transport losses: messages that never reached a handler.
    const std::pair<const char*, int64_t> losses[] = {
        {"dropped_kernel_overflow", bus_stats->dropped_kernel_overflow},
        {"dropped_queue_overflow", bus_stats->dropped_queue_overflow},
        {"fragments_expired", bus_stats->fragments_expired},
        {"fragments_over_budget", bus_stats->fragments_over_budget},
        {"fragments_malformed", bus_stats->fragments_malformed},
        {"fragments_duplicate", bus_stats->fragments_duplicate}};
    for (const auto& [name, count] : losses) {
      if (count <= 0) continue;
      s.dropped += count;
      counters[name] += count;
    }
    if (bus_stats->datagrams_malformed > 0) {
      counters["datagrams_malformed"] += bus_stats->datagrams_malformed;
    }
    if (s.last_error.empty() && !bus_stats->last_error.empty()) {
      s.last_error = bus_stats->last_error;
    }
  }
  // Within the caps every receiver checks (wire_check.h), or the heartbeat
  // itself would be refused: strings are clipped, the counter lists cut.
  const auto clip = [](std::string* text, int32_t cap_bytes) {
    if (text->size() >= static_cast<size_t>(cap_bytes)) text->resize(cap_bytes - 1);
  };
  clip(&s.process, wire_cap::kNameBytes);
  clip(&s.host, wire_cap::kNameBytes);
  clip(&s.last_error, wire_cap::kLastErrorBytes);
  for (const auto& [name, count] : rejected) {
    if (s.rejected.size() >= static_cast<size_t>(wire_cap::kStatusCounters)) break;
    s.rejected.push_back(MakeCounter(name, count));
    clip(&s.rejected.back().name, wire_cap::kNameBytes);
  }
  for (const auto& [name, count] : counters) {
    if (s.counters.size() >= static_cast<size_t>(wire_cap::kStatusCounters)) break;
    s.counters.push_back(MakeCounter(name, count));
    clip(&s.counters.back().name, wire_cap::kNameBytes);
  }
  s.num_rejected = static_cast<int32_t>(s.rejected.size());
  s.num_counters = static_cast<int32_t>(s.counters.size());
  return s;
}

bool StatusReporter::MaybePublish(Bus* bus, int64_t now_utime) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (last_publish_utime_ >= 0 && now_utime - last_publish_utime_ < 1000000) return false;
  }
  return Publish(bus, now_utime);
}

bool StatusReporter::Publish(Bus* bus, int64_t now_utime) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    last_publish_utime_ = now_utime;
  }
  // The site travels beside the heartbeat, when the process's
  // SitePublishSchedule says (start, period when elected, a newcomer),
  // whichever node of the process beats.
  MaybePublishProcessSite(bus, now_utime);
  bus->RefreshStats();
  const BusStats stats = bus->stats();
  return bus->Publish(kStatusChannel, Make(now_utime, &stats));
}

// ---------------------------------------------------------------------------

namespace {
std::atomic<bool> g_shutdown{false};
int g_wake_pipe[2] = {-1, -1};

void OnSignal(int) {
  g_shutdown.store(true);
  if (g_wake_pipe[1] >= 0) {
    const char byte = 1;
    // Best effort: a full pipe already wakes the loop.
    [[maybe_unused]] ssize_t n = ::write(g_wake_pipe[1], &byte, 1);
  }
}
}  // namespace

InputWatch::InputWatch(std::string what, double max_gap_s)
    : what_(std::move(what)), max_gap_us_(static_cast<int64_t>(max_gap_s * 1e6)) {}

void InputWatch::Seen(int64_t utime, StatusReporter* status) {
  last_utime_ = std::max(last_utime_, utime);
  if (in_gap_) {
    in_gap_ = false;
    status->SetState(process_status_t::STATE_RUNNING);
  }
}

bool InputWatch::Check(int64_t now_utime, StatusReporter* status) {
  if (last_utime_ < 0 || in_gap_ || now_utime - last_utime_ <= max_gap_us_) return false;
  in_gap_ = true;
  status->SetState(process_status_t::STATE_DEGRADED);
  status->Count("input_gaps");
  status->SetError(fmt::format("no {} for {:.1f} s", what_, (now_utime - last_utime_) * 1e-6),
                   now_utime);
  return true;
}

void InstallShutdownHandlers() {
  if (g_wake_pipe[0] < 0 && ::pipe(g_wake_pipe) == 0) {
    for (int fd : g_wake_pipe) ::fcntl(fd, F_SETFL, ::fcntl(fd, F_GETFL) | O_NONBLOCK);
  }
  struct sigaction sa {};
  sa.sa_handler = OnSignal;
  sigemptyset(&sa.sa_mask);
  ::sigaction(SIGINT, &sa, nullptr);
  ::sigaction(SIGTERM, &sa, nullptr);
  // A reader that went away must not kill a publisher.
  std::signal(SIGPIPE, SIG_IGN);
}

bool ShutdownRequested() { return g_shutdown.load(); }

void RequestShutdown() { OnSignal(0); }

int DrainBus(Bus* bus, int64_t budget_us) {
  const int64_t until = NowUtime() + budget_us;
  int total = 0;
  do {
    const int handled = bus->Handle(0);
    if (handled < 0) return -1;
    if (handled == 0) break;
    total += handled;
  } while (NowUtime() < until);
  return total;
}

int RunLoop(Bus* bus, const std::function<void(int64_t)>& tick, const RunLoopOptions& options) {
  const int64_t start = NowUtime();
  const int64_t end =
      options.duration_s > 0 ? start + static_cast<int64_t>(options.duration_s * 1e6) : INT64_MAX;
  const int lcm_fd = bus->Fileno();
  while (!ShutdownRequested()) {
    int64_t now = NowUtime();
    if (now >= end) break;
    const int64_t remaining_ms = (end - now) / 1000;
    const int timeout_ms = static_cast<int>(
        std::min<int64_t>(options.tick_period_ms, std::max<int64_t>(remaining_ms, 0)));
    // A negative descriptor is ignored by poll(), so absent ones need no
    // special case.
    const int extra = options.extra_fd ? options.extra_fd() : -1;
    pollfd fds[3] = {{lcm_fd, POLLIN, 0}, {g_wake_pipe[0], POLLIN, 0}, {extra, POLLIN, 0}};
    const int n = ::poll(fds, 3, timeout_ms);
    if (n < 0 && errno != EINTR) {
      spdlog::error("poll failed: {}", std::strerror(errno));
      return 1;
    }
    if (n > 0 && (fds[0].revents & POLLIN) &&
        DrainBus(bus, int64_t{options.tick_period_ms} * 1000) < 0) {
      spdlog::error("receiving failed: {}", bus->stats().last_error);
      return 1;
    }
    tick(NowUtime());
  }
  return 0;
}

std::unique_ptr<Bus> OpenBus(const std::string& url, std::string* error, bool direct_udpm) {
  if (direct_udpm && url.rfind("udpm://", 0) == 0) return UdpmBus::Create(url, error);
  // Not LCM's file provider: its log reader crashes on a damaged log.
  if (url.rfind("file://", 0) == 0) return LogFileBus::Create(url, error);
  return LcmBus::Create(url, error);
}

std::unique_ptr<ProcessContext> StartProcess(const std::string& name, const ProcessOptions& options,
                                             std::string* error) {
  auto ctx = std::make_unique<ProcessContext>();
  ctx->name = name;
  ctx->options = options;
  if (!SetUpLogging(name, options.log_level, options.log_color)) {
    *error =
        "unknown log level '" + options.log_level + "' or colour mode '" + options.log_color + "'";
    return nullptr;
  }
  if (!options.config_path.empty()) {
    LoadedSite loaded;
    if (!LoadSiteWithTexts(options.config_path, &loaded, error)) return nullptr;
    ctx->site = loaded.site;
    for (const auto& missing : loaded.texts.missing) {
      spdlog::warn("site {}: calibration file {} not carried on {}", options.config_path, missing,
                   kSiteChannel);
    }
    // A site too big for a site_t still runs; it just cannot travel.
    auto msg = std::make_shared<site_t>();
    std::string why;
    if (MakeSiteMessage(loaded, name, NowUtime(), msg.get(), &why)) {
      SetProcessSite(std::move(msg));
    } else {
      spdlog::warn("site not published on {}: {}", kSiteChannel, why);
    }
  }
  InstallShutdownHandlers();
  if (options.check) return ctx;
  ctx->bus = OpenBus(options.lcm_url, error, options.direct_udpm);
  if (ctx->bus == nullptr) return nullptr;
  // Heard on the receiving thread of each node's loop: the other publishers
  // of this site and newcomers decide when the site is sent again.
  if (ProcessSite() != nullptr) FollowSitePeers(ctx->bus.get());
  return ctx;
}

int PrintFailure(const std::string& process_name, const std::string& error) {
  std::cerr << process_name << ": " << error << "\n";
  return 1;
}

}  // namespace roomfix
