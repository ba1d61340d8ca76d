#include <fmt/format.h>

#include <CLI/CLI.hpp>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <cstdio>
#include <deque>
#include <iostream>
#include <map>
#include <mutex>
#include <nlohmann/json.hpp>
#include <set>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "msgio/bus.h"
#include "msgio/channels.h"
#include "msgio/log.h"
#include "msgio/message_json.h"
#include "msgio/process.h"
#include "msgio/site_message.h"
#include "msgio/wire_check.h"
#include "tools/commands.h"
#include "tools/tool_site.h"

namespace roomfix {
namespace {

struct ListenOptions {
  std::string lcm_url = kDefaultLcmUrl;
  std::string channel = ".*";
  int64_t count = 0;
  double timeout_s = 0.0;
  // Compared with every site heard on SITE (a warning naming the keys).
  std::string config_path;
};

// Live: says on stderr which site each process publishes on SITE (once per
// distinct site), warns when one differs from --config, and when processes
// disagree (SITE or STATUS site_hash), whatever --channel prints.
//
// SITE and STATUS are examined on a thread of their own. Verifying a new
// SITE parses its texts as YAML (up to 1 MiB of site and 16 x 256 KiB of
// calibration, about a quarter of a second each for yaml-cpp at 1 MiB) and
// comparing it with --config parses them again: on the receive thread, a
// stream of forged SITEs (issue #28: each a new site with a valid hash)
// would hold every other message behind them. The receive thread only
// decodes and queues; at most kMaxPending messages wait, and further ones
// are counted and said at exit (the real site's SITE comes again every
// kSitePeriodUs). At exit the waiting ones are examined first: bounded work.
class LiveSiteWatch {
 public:
  static constexpr size_t kMaxPending = 8;

  ~LiveSiteWatch() { Finish(); }

  bool Init(const std::string& config_path, std::string* error) {
    if (!config_path.empty()) {
      if (!LoadSiteWithTexts(config_path, &config_, error)) return false;
      listing_ = SiteListing(&config_);
      std::cerr << "roomfix listen: site from --config " << config_path << ": "
                << DescribeSite(config_) << "\n";
    }
    worker_ = std::thread([this] { Work(); });
    return true;
  }
  // On the receive thread: decode and queue, never parse.
  void Observe(const MessageInfo& info, const void* data, int size) {
    Pending p;
    p.recv_utime = info.recv_utime;
    p.is_site = info.channel == kSiteChannel;
    if (p.is_site) {
      std::string reason;
      if (!DecodeChecked(data, size, &p.site, &reason)) return;  // counted by PrintMessage
    } else if (info.channel == kStatusChannel) {
      if (!DecodeChecked(data, size, &p.status, nullptr)) return;
    } else {
      return;
    }
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (queue_.size() >= kMaxPending) {
        ++not_examined_;
        return;
      }
      queue_.push_back(std::move(p));
    }
    wake_.notify_one();
  }
  // Examines what waits, then stops the thread.
  void Finish() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stop_ = true;
    }
    wake_.notify_one();
    if (worker_.joinable()) worker_.join();
  }
  // At exit, after Finish: the SITE messages refused or not described.
  void Summary() const {
    if (listing_.refused() > 0) {
      std::cerr << "roomfix listen: warning: " << listing_.refused()
                << " SITE messages refused (their texts do not match their hash or are no "
                   "valid site)\n";
    }
    if (listing_.not_listed() > 0) {
      std::cerr << "roomfix listen: warning: " << listing_.not_listed()
                << " SITE messages of sites over the first " << SiteListing::kMaxListed
                << " not described\n";
    }
    if (not_examined_ > 0) {
      std::cerr << "roomfix listen: warning: " << not_examined_
                << " SITE and STATUS messages not examined for the site (more than " << kMaxPending
                << " waited at once)\n";
    }
  }

 private:
  struct Pending {
    bool is_site = false;
    int64_t recv_utime = 0;
    site_t site;
    process_status_t status;
  };

  void Work() {
    for (;;) {
      Pending p;
      {
        std::unique_lock<std::mutex> lock(mutex_);
        wake_.wait(lock, [this] { return stop_ || !queue_.empty(); });
        if (queue_.empty()) return;  // stopped, nothing waits
        p = std::move(queue_.front());
        queue_.pop_front();
      }
      std::vector<std::string> lines;
      if (p.is_site) {
        listing_.ObserveSite(p.site, p.recv_utime, &lines);
      } else {
        listing_.ObserveStatus(p.status, p.recv_utime, &lines);
      }
      for (const std::string& line : lines) std::cerr << "roomfix listen: " << line << "\n";
    }
  }

  LoadedSite config_;
  SiteListing listing_{nullptr};
  std::mutex mutex_;
  std::condition_variable wake_;
  std::deque<Pending> queue_;
  bool stop_ = false;
  int64_t not_examined_ = 0;
  std::thread worker_;
};

// One message as one JSON line; a message refused before decoding is a line
// with its reason, counted in *refused for the warning at exit. A channel
// name is whatever a publisher chose (quotes, control bytes, bytes that are
// not UTF-8): dump() escapes it like every other string, the bytes that are
// not UTF-8 as U+FFFD (error_handler_t::replace; the default would throw),
// so each line stays valid JSON. Doubles are nlohmann's shortest form that
// reads back to the same bits; NaN and infinities are null.
void PrintMessage(const std::string& channel, int64_t recv_utime, const void* data, int size,
                  std::map<std::string, int64_t>* refused) {
  nlohmann::ordered_json message;
  std::string why;
  std::string reason;
  nlohmann::ordered_json line = {{"channel", channel}, {"recv_utime", recv_utime}};
  if (MessageToJsonValue(data, size, &message, &why, &reason)) {
    line["message"] = std::move(message);
  } else {
    ++(*refused)[reason];
    line["size"] = size;
    line["refused"] = reason;
    line["error"] = why;
  }
  fmt::print("{}\n", line.dump(-1, ' ', false, nlohmann::ordered_json::error_handler_t::replace));
  std::fflush(stdout);
}

void WarnRefused(const std::map<std::string, int64_t>& refused) {
  if (refused.empty()) return;
  int64_t total = 0;
  for (const auto& [reason, count] : refused) total += count;
  std::cerr << "roomfix listen: warning: " << total << " messages refused ("
            << RefusalCounts(refused) << ")\n";
}

// A file:// URL is read with LogReader, not LCM's file provider: liblcm
// 1.3.1's log reader dies (SIGSEGV) on an event claiming 0x7FFFFFFF bytes
// and stops for good at an empty channel name. recv_utime is the event's
// time in the log (LCM's provider would stamp the wall clock). Returns the
// exit code.
int ListenToLog(const ListenOptions& o) {
  std::string path;
  double speed = 1.0;
  std::string error;
  if (!ParseLogUrl(o.lcm_url, &path, &speed, &error)) {
    std::cerr << "roomfix listen: " << error << "\n";
    return 1;
  }
  auto reader = LogReader::Open(path, &error);
  if (reader == nullptr) {
    std::cerr << "roomfix listen: " << error << "\n";
    return 1;
  }
  const ChannelPattern pattern(o.channel);
  if (!pattern.valid()) {
    std::cerr << "roomfix listen: channel expression '" << o.channel << "' is not valid\n";
    return 1;
  }
  // Which site the log was recorded in, before its messages.
  if (!ReportToolSite("roomfix listen", ResolveToolSite(o.config_path, path),
                      /*required=*/false)) {
    return 1;
  }
  InstallShutdownHandlers();
  const int64_t give_up =
      o.timeout_s > 0 ? NowUtime() + static_cast<int64_t>(o.timeout_s * 1e6) : INT64_MAX;
  const int64_t start_wall = NowUtime();
  int64_t first_utime = -1;
  int64_t received = 0;
  std::map<std::string, int64_t> refused;
  LogEvent event;
  while (!ShutdownRequested() && NowUtime() < give_up && reader->Next(&event)) {
    if (first_utime < 0) first_utime = event.utime;
    if (speed > 0) {
      // As LCM's provider: events keep their recorded spacing, scaled.
      const auto due = start_wall + static_cast<int64_t>((event.utime - first_utime) / speed);
      while (!ShutdownRequested() && NowUtime() < std::min(due, give_up)) {
        std::this_thread::sleep_for(std::chrono::microseconds(
            std::min<int64_t>(std::min(due, give_up) - NowUtime(), 100'000)));
      }
      if (NowUtime() >= give_up) break;
    }
    if (!pattern.Matches(event.channel)) continue;
    PrintMessage(event.channel, event.utime, event.data.data(), static_cast<int>(event.data.size()),
                 &refused);
    if (o.count > 0 && ++received >= o.count) break;
  }
  WarnRefused(refused);
  if (reader->damaged()) {
    std::cerr << "roomfix listen: warning: " << path << ": " << reader->DamageSummary() << "\n";
  }
  if (o.count > 0 && received < o.count) {
    std::cerr << "roomfix listen: timed out after " << received << " of " << o.count
              << " messages\n";
    return 3;
  }
  return 0;
}

}  // namespace

void AddListenCommand(CLI::App* app, int* exit_code) {
  auto* cmd = app->add_subcommand(
      "listen", "Print every roomfix message received as one JSON line (channel, time, fields)");
  auto o = std::make_shared<ListenOptions>();
  cmd->add_option("--lcm-url", o->lcm_url, "LCM URL")->capture_default_str();
  cmd->add_option("--channel", o->channel, "Channel regular expression")->capture_default_str();
  cmd->add_option("--config", o->config_path,
                  "Site file to compare with the sites heard on SITE (or the log's); a "
                  "difference is a warning naming the keys");
  cmd->add_option("--count", o->count, "Stop after this many messages (0: no limit)");
  cmd->add_option("--timeout", o->timeout_s,
                  "Give up after this many seconds; exit 3 if fewer than --count arrived");
  cmd->callback([o, exit_code] {
    if (o->lcm_url.rfind("file://", 0) == 0) {
      *exit_code = ListenToLog(*o);
      return;
    }
    std::string error;
    auto bus = OpenBus(o->lcm_url, &error);
    if (bus == nullptr) {
      std::cerr << "roomfix listen: " << error << "\n";
      *exit_code = 1;
      return;
    }
    InstallShutdownHandlers();
    LiveSiteWatch sites;
    if (!sites.Init(o->config_path, &error)) {
      std::cerr << "roomfix listen: " << error << "\n";
      *exit_code = 1;
      return;
    }
    bus->SubscribeRaw(std::string(kSiteChannel) + "|" + kStatusChannel,
                      [&](const MessageInfo& info, const void* data, int size) {
                        sites.Observe(info, data, size);
                      });
    int64_t received = 0;
    std::map<std::string, int64_t> refused;
    bus->SubscribeRaw(o->channel, [&](const MessageInfo& info, const void* data, int size) {
      PrintMessage(info.channel, info.recv_utime, data, size, &refused);
      if (o->count > 0 && ++received >= o->count) RequestShutdown();
    });
    RunLoopOptions loop;
    loop.duration_s = o->timeout_s;
    *exit_code = RunLoop(
        bus.get(), [](int64_t) {}, loop);
    sites.Finish();
    WarnRefused(refused);
    sites.Summary();
    if (*exit_code == 0 && o->count > 0 && received < o->count) {
      std::cerr << "roomfix listen: timed out after " << received << " of " << o->count
                << " messages\n";
      *exit_code = 3;
    }
  });
}

}  // namespace roomfix
