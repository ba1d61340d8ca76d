#ifndef ROOMFIX_MSGIO_PROCESS_H_
#define ROOMFIX_MSGIO_PROCESS_H_

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>

#include "core/world/site.h"
#include "msgio/bus.h"
#include "msgio/channels.h"
#include "roomfix/process_status_t.hpp"

namespace CLI {
class App;
}

namespace roomfix {

// LCM's default group and port with ttl=0: packets never leave this host.
// Several hosts need ttl=1 (docs/operations.md).
inline constexpr char kDefaultLcmUrl[] = "udpm://239.255.76.67:7667?ttl=0";

// Host wall clock, microseconds since the Unix epoch. Only processes and
// msgio read the clock; core/ takes time as an argument.
int64_t NowUtime();

// The flags every roomfix process has.
struct ProcessOptions {
  std::string lcm_url = kDefaultLcmUrl;
  std::string config_path;
  std::string log_level = "info";
  // auto: colour only when stderr is a terminal and NO_COLOR is unset or
  // empty (https://no-color.org); always; never. bot-procman runs every
  // command on a pseudo-terminal, so its .pmd files pass never.
  std::string log_color = "auto";
  // Validate flags and configuration, print what would run, and exit.
  bool check = false;
  // For udpm:// URLs, speak LCM's wire format on our own socket (UdpmBus)
  // instead of going through liblcm, whose 1.3.1 fragment reassembly one
  // datagram crashes and whose queue losses cannot be counted
  // (msgio/udpm_bus.h). false only to measure liblcm (`roomfix_bench logger`).
  bool direct_udpm = true;
};

// Adds --lcm-url, --config, --log-level, --log-color and --check to a CLI11
// app.
void AddProcessFlags(CLI::App* app, ProcessOptions* options, bool config_required);

// Counters and state for a process's STATUS heartbeat. Thread-safe: a
// process may count from its receive thread and a worker.
class StatusReporter {
 public:
  StatusReporter(std::string process_name, int64_t start_utime);

  void AddInputs(int64_t n = 1);
  void AddOutputs(int64_t n = 1);
  void AddDropped(int64_t n = 1);
  // An input refused for `reason` (lower_case_with_underscores).
  void Reject(const std::string& reason, int64_t n = 1);
  // Any other counter, by name.
  void Count(const std::string& name, int64_t n = 1);
  // A gauge: a named value that is set rather than added to (queue depth).
  void SetCounter(const std::string& name, int64_t value);
  void SetState(int8_t state);
  void SetError(const std::string& text, int64_t utime);

  int64_t inputs() const;
  int64_t outputs() const;
  int64_t dropped() const;
  int64_t rejected(const std::string& reason) const;
  int64_t counter(const std::string& name) const;

  // The heartbeat message as of utime; the bus's own failures (undecodable
  // messages, throwing handlers) are folded in when a bus is given, and its
  // transport losses are added into `dropped` and reported by cause as
  // counters (dropped_kernel_overflow, dropped_queue_overflow,
  // fragments_expired, fragments_over_budget, fragments_malformed,
  // fragments_duplicate).
  process_status_t Make(int64_t utime, const BusStats* bus_stats) const;

  // Publishes on STATUS when a second has passed since the last heartbeat
  // (or at once, the first time). Returns true when it published.
  bool MaybePublish(Bus* bus, int64_t now_utime);
  // Publishes now, whatever the time since the last one (state changes,
  // the last heartbeat before exit).
  bool Publish(Bus* bus, int64_t now_utime);

 private:
  mutable std::mutex mutex_;
  std::string process_;
  std::string host_;
  int32_t pid_ = 0;
  int64_t start_utime_ = 0;
  int64_t last_publish_utime_ = -1;
  int8_t state_ = process_status_t::STATE_STARTING;
  int64_t inputs_ = 0;
  int64_t outputs_ = 0;
  int64_t dropped_ = 0;
  std::map<std::string, int64_t> rejected_;
  std::map<std::string, int64_t> counters_;
  std::string last_error_;
  int64_t last_error_utime_ = 0;
};

// Watches a process's input for silence: once input has been seen, a gap
// longer than max_gap_s turns the process DEGRADED with "no <what> for N s"
// in STATUS and counts `input_gaps`; the next input makes it RUNNING again.
// So a process whose upstream died says so, not only by its own silence.
class InputWatch {
 public:
  InputWatch(std::string what, double max_gap_s);
  void Seen(int64_t utime, StatusReporter* status);
  // Returns true when this call declared a new gap.
  bool Check(int64_t now_utime, StatusReporter* status);
  bool in_gap() const { return in_gap_; }

 private:
  std::string what_;
  int64_t max_gap_us_;
  int64_t last_utime_ = -1;
  bool in_gap_ = false;
};

// SIGINT and SIGTERM set a flag and wake the run loop through a pipe.
void InstallShutdownHandlers();
bool ShutdownRequested();
// Asks the run loop to stop as a signal would (for tests and --duration).
void RequestShutdown();

// Dispatches what is waiting on the bus without blocking, until it runs dry
// or budget_us has passed (a sustained flood never runs dry, so the budget
// keeps the caller's own work going). A transport reads one batch per
// Handle(0), so a single call would leave a backlog that a busy loop clears
// only slowly. Returns the number handled, or -1 when the transport failed.
int DrainBus(Bus* bus, int64_t budget_us);

struct RunLoopOptions {
  // The tick is called at least this often, and after every batch of
  // messages.
  int tick_period_ms = 10;
  // Stop after this long; <= 0 runs until a signal.
  double duration_s = 0.0;
  // A further descriptor to wait on besides the bus (a serial port), or -1.
  // Asked for before every wait, because a reopened device has a new one.
  // Its readiness only wakes the loop early; the tick does the reading.
  std::function<int()> extra_fd;
};

// Dispatches messages from the bus and calls tick(now_utime) until SIGINT,
// SIGTERM or the duration ends. Returns 0 on a clean stop and 1 (with the
// reason logged) when LCM fails.
int RunLoop(Bus* bus, const std::function<void(int64_t now_utime)>& tick,
            const RunLoopOptions& options);

// Opens the bus for an LCM URL as processes do: udpm:// through UdpmBus (or
// liblcm when direct_udpm is false), memq:// through LcmBus and file://
// through LogFileBus.
// Tools that receive without StartProcess (`roomfix listen`) use it too.
std::unique_ptr<Bus> OpenBus(const std::string& url, std::string* error, bool direct_udpm = true);

// What a process's main needs after its flags are parsed: logging set up,
// signals handled, the site file loaded and the bus opened.
struct ProcessContext {
  std::string name;
  ProcessOptions options;
  Site site;
  std::unique_ptr<Bus> bus;
};

// Returns nullptr with a one-line reason when the process cannot start (bad
// site file, LCM unavailable). With --check the bus is not opened.
std::unique_ptr<ProcessContext> StartProcess(const std::string& name, const ProcessOptions& options,
                                             std::string* error);

// Whether log lines get ANSI colour: `mode` "always" or "never" decides;
// "auto" colours only a terminal (stderr_is_tty) and only when no_color (the
// NO_COLOR variable, nullptr when unset) is unset or empty. A command-line
// "always" overrides NO_COLOR, as no-color.org asks of per-run arguments.
bool LogColorWanted(const std::string& mode, bool stderr_is_tty, const char* no_color);

// Sets spdlog's default logger to stderr with the process name, level
// ("trace", "debug", "info", "warn", "error") and colour mode ("auto",
// "always", "never"; see LogColorWanted); false for an unknown level or
// mode.
bool SetUpLogging(const std::string& process_name, const std::string& level,
                  const std::string& color = "auto");

// The one clear line of a process that cannot start or run on:
// "PROCESS: ERROR" on stderr. Returns 1, the exit code a main returns then.
int PrintFailure(const std::string& process_name, const std::string& error);

}  // namespace roomfix

#endif  // ROOMFIX_MSGIO_PROCESS_H_
