// roomfix_bench logger: how many small messages per second roomfix_logger
// writes with none lost, and its peak memory, for each receiver in the same
// run: roomfix's own (UdpmBus, what every process uses), liblcm tuned as
// LcmBus tunes it (queue capacity kLcmQueueCapacity, recv_buf_size) through
// roomfix_logger --via-liblcm, and stock lcm-logger (liblcm's default queue
// of 30). Runs the loggers as child processes on the default multicast URL,
// so run it inside a private network namespace:
//   scripts/netns_run build/bin/roomfix_bench logger
#include <fmt/format.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>
#include <thread>

#include "bench/commands.h"
#include "msgio/bus.h"
#include "msgio/log.h"
#include "msgio/process.h"

extern char** environ;

namespace roomfix {
namespace {

struct BenchLoggerOptions {
  std::vector<int> rates = {50000, 100000, 150000, 200000};
  double seconds_per_rate = 2.0;
  int payload_bytes = 32;
  // Kernel receive buffer the loggers ask for (LCM's recv_buf_size); the
  // kernel caps it at net.core.rmem_max. 0 keeps the system default.
  int recv_buf_bytes = 4 << 20;
  bool json = false;
};

// Peak resident memory of a process, kB (VmHWM in /proc/PID/status).
int64_t PeakMemoryKb(pid_t pid) {
  std::ifstream status("/proc/" + std::to_string(pid) + "/status");
  std::string line;
  while (std::getline(status, line)) {
    if (line.rfind("VmHWM:", 0) == 0) return std::atoll(line.c_str() + 6);
  }
  return -1;
}

std::string SelfDir() {
  char buffer[4096];
  const ssize_t n = ::readlink("/proc/self/exe", buffer, sizeof(buffer) - 1);
  if (n <= 0) return ".";
  std::string path(buffer, static_cast<size_t>(n));
  return path.substr(0, path.find_last_of('/'));
}

struct LadderResult {
  nlohmann::json steps = nlohmann::json::array();
  int max_rate_without_loss = 0;
  int64_t peak_rss_kb = -1;
};

// Starts `command` (a logger recording BENCH_.* into log_path), publishes the
// rate ladder, stops it with SIGINT and counts what it wrote per step.
bool RunLadder(const BenchLoggerOptions& o, Bus* bus, std::vector<std::string> command,
               const std::string& log_path, LadderResult* result, std::string* error) {
  std::vector<char*> argv;
  for (auto& a : command) argv.push_back(a.data());
  argv.push_back(nullptr);
  pid_t pid = -1;
  if (posix_spawnp(&pid, command[0].c_str(), nullptr, nullptr, argv.data(), environ) != 0) {
    *error = "cannot start " + command[0];
    return false;
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  std::vector<uint8_t> payload(static_cast<size_t>(o.payload_bytes), 0xAB);
  std::map<std::string, int64_t> sent;
  std::map<std::string, double> achieved;
  for (int rate : o.rates) {
    const std::string channel = "BENCH_" + std::to_string(rate);
    const auto start = std::chrono::steady_clock::now();
    int64_t n = 0;
    // Paced in 1 ms slices: rate / 1000 messages, then wait for the slice.
    for (int slice = 0; slice < static_cast<int>(o.seconds_per_rate * 1000); ++slice) {
      for (int k = 0; k < rate / 1000; ++k) {
        bus->PublishRaw(channel, payload.data(), static_cast<int>(payload.size()));
        ++n;
      }
      std::this_thread::sleep_until(start + std::chrono::milliseconds(slice + 1));
    }
    const double s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    sent[channel] = n;
    achieved[channel] = n / s;
    std::this_thread::sleep_for(std::chrono::milliseconds(300));  // Let it drain.
  }
  result->peak_rss_kb = PeakMemoryKb(pid);
  ::kill(pid, SIGINT);
  int status = 0;
  ::waitpid(pid, &status, 0);

  std::map<std::string, int64_t> written;
  auto reader = LogReader::Open(log_path, error);
  if (reader == nullptr) return false;
  LogEvent e;
  while (reader->Next(&e)) ++written[e.channel];
  ::unlink(log_path.c_str());
  for (int rate : o.rates) {
    const std::string channel = "BENCH_" + std::to_string(rate);
    const int64_t w = written[channel];
    result->steps.push_back(
        {{"target_per_s", rate},
         {"published_per_s", achieved[channel]},
         {"published", sent[channel]},
         {"written", w},
         {"lost", sent[channel] - w},
         {"delivered_ratio", sent[channel] > 0 ? double(w) / sent[channel] : 0.0}});
    if (w == sent[channel]) {
      result->max_rate_without_loss =
          std::max(result->max_rate_without_loss, static_cast<int>(achieved[channel]));
    }
  }
  return true;
}

void PrintLadder(const char* name, const LadderResult& r, int payload_bytes) {
  fmt::print("\n{}\n{:>12} {:>14} {:>12} {:>12} {:>8} {:>10}\n", name, "target/s", "published/s",
             "published", "written", "lost", "delivered");
  for (const auto& s : r.steps) {
    fmt::print("{:12} {:14.0f} {:12} {:12} {:8} {:9.2f}%\n", s["target_per_s"].get<int>(),
               s["published_per_s"].get<double>(), s["published"].get<long long>(),
               s["written"].get<long long>(), s["lost"].get<long long>(),
               100.0 * s["delivered_ratio"].get<double>());
  }
  fmt::print(
      "highest rate written with no loss: {} messages/s of {} bytes; peak memory {:.1f} MiB\n",
      r.max_rate_without_loss, payload_bytes, r.peak_rss_kb / 1024.0);
}

int Run(const BenchLoggerOptions& o) {
  if (std::getenv("ROOMFIX_IN_NETNS") == nullptr) {
    std::cerr << "roomfix_bench logger: run it in a private network namespace: "
                 "scripts/netns_run build/bin/roomfix_bench logger\n";
    return 1;
  }
  char dir_template[] = "/tmp/roomfix_bench_logger_XXXXXX";
  const char* dir = ::mkdtemp(dir_template);
  if (dir == nullptr) return 1;
  const std::string log_path = std::string(dir) + "/bench.lcm";
  std::string error;
  auto bus = LcmBus::Create(kDefaultLcmUrl, &error);
  if (bus == nullptr) {
    std::cerr << "roomfix_bench logger: " << error << "\n";
    return 1;
  }
  std::string url = kDefaultLcmUrl;
  if (o.recv_buf_bytes > 0) url += "&recv_buf_size=" + std::to_string(o.recv_buf_bytes);
  LadderResult ours, tuned, stock;
  const std::vector<std::string> logger = {SelfDir() + "/roomfix_logger",
                                           log_path,
                                           "--channel",
                                           "BENCH_.*",
                                           "--lcm-url",
                                           url,
                                           "--log-level",
                                           "warn"};
  std::vector<std::string> via_liblcm = logger;
  via_liblcm.push_back("--via-liblcm");
  const bool ok =
      RunLadder(o, bus.get(), logger, log_path, &ours, &error) &&
      RunLadder(o, bus.get(), via_liblcm, log_path, &tuned, &error) &&
      RunLadder(o, bus.get(), {"lcm-logger", "-c", "BENCH_.*", "--lcm-url=" + url, log_path},
                log_path, &stock, &error);
  ::rmdir(dir);
  if (!ok) {
    std::cerr << "roomfix_bench logger: " << error << "\n";
    return 1;
  }
  const std::pair<const char*, LadderResult*> ladders[] = {
      {"udpm_bus", &ours}, {"liblcm_tuned", &tuned}, {"lcm_logger", &stock}};
  nlohmann::json out;
  for (const auto& [name, r] : ladders) {
    out[name] = {{"steps", r->steps},
                 {"max_rate_without_loss_per_s", r->max_rate_without_loss},
                 {"peak_rss_kb", r->peak_rss_kb}};
  }
  out["payload_bytes"] = o.payload_bytes;
  out["lcm_url"] = url;
  out["liblcm_queue_capacity"] = kLcmQueueCapacity;
  if (o.json) {
    std::cout << out.dump() << "\n";
    return 0;
  }
  fmt::print("on {}, {}-byte payloads\n", url.c_str(), o.payload_bytes);
  PrintLadder("roomfix_logger, own receiver (UdpmBus)", ours, o.payload_bytes);
  PrintLadder(("roomfix_logger --via-liblcm (liblcm 1.3.1, queue capacity " +
               std::to_string(kLcmQueueCapacity) + ")")
                  .c_str(),
              tuned, o.payload_bytes);
  PrintLadder("lcm-logger (liblcm 1.3.1, default queue of 30)", stock, o.payload_bytes);
  fmt::print("\ndelivered, same run:\n{:>12} {:>12} {:>14} {:>12}\n", "target/s", "UdpmBus",
             "liblcm tuned", "lcm-logger");
  for (size_t k = 0; k < ours.steps.size(); ++k) {
    fmt::print("{:12} {:11.2f}% {:13.2f}% {:11.2f}%\n", ours.steps[k]["target_per_s"].get<int>(),
               100.0 * ours.steps[k]["delivered_ratio"].get<double>(),
               100.0 * tuned.steps[k]["delivered_ratio"].get<double>(),
               100.0 * stock.steps[k]["delivered_ratio"].get<double>());
  }
  return 0;
}

}  // namespace

void AddBenchLoggerCommand(CLI::App* bench, int* exit_code) {
  auto* cmd = bench->add_subcommand(
      "logger",
      "roomfix_logger's loss-free write rate and peak memory with its own receiver, with tuned "
      "liblcm and lcm-logger, in one run (inside scripts/netns_run)");
  auto o = std::make_shared<BenchLoggerOptions>();
  cmd->add_option("--rates", o->rates, "Publish rates to try, messages per second")
      ->capture_default_str();
  cmd->add_option("--seconds", o->seconds_per_rate, "Seconds at each rate")->capture_default_str();
  cmd->add_option("--payload", o->payload_bytes, "Message payload bytes")->capture_default_str();
  cmd->add_option("--recv-buf", o->recv_buf_bytes,
                  "Kernel receive buffer the loggers request, bytes (0: system default; capped "
                  "by net.core.rmem_max)")
      ->capture_default_str();
  cmd->add_flag("--json", o->json, "Print one JSON object");
  cmd->callback([o, exit_code] { *exit_code = Run(*o); });
}

}  // namespace roomfix
