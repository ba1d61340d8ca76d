#include <CLI/CLI.hpp>
#include <cstdint>
#include <cstdio>
#include <iostream>
#include <map>
#include <string>

#include "msgio/bus.h"
#include "msgio/message_json.h"
#include "msgio/process.h"
#include "msgio/wire_check.h"
#include "tools/commands.h"

namespace roomfix {
namespace {

struct ListenOptions {
  std::string lcm_url = kDefaultLcmUrl;
  std::string channel = ".*";
  int64_t count = 0;
  double timeout_s = 0.0;
};

}  // namespace

void AddListenCommand(CLI::App* app, int* exit_code) {
  auto* cmd = app->add_subcommand(
      "listen", "Print every roomfix message received as one JSON line (channel, time, fields)");
  auto o = std::make_shared<ListenOptions>();
  cmd->add_option("--lcm-url", o->lcm_url, "LCM URL")->capture_default_str();
  cmd->add_option("--channel", o->channel, "Channel regular expression")->capture_default_str();
  cmd->add_option("--count", o->count, "Stop after this many messages (0: no limit)");
  cmd->add_option("--timeout", o->timeout_s,
                  "Give up after this many seconds; exit 3 if fewer than --count arrived");
  cmd->callback([o, exit_code] {
    std::string error;
    auto bus = OpenBus(o->lcm_url, &error);
    if (bus == nullptr) {
      std::cerr << "roomfix listen: " << error << "\n";
      *exit_code = 1;
      return;
    }
    InstallShutdownHandlers();
    int64_t received = 0;
    // Refused messages by reason, for the warning line at exit; each is also
    // printed in place as an "error" line.
    std::map<std::string, int64_t> refused;
    bus->SubscribeRaw(o->channel, [&](const MessageInfo& info, const void* data, int size) {
      std::string json;
      std::string why;
      std::string reason;
      if (MessageToJson(data, size, &json, &why, &reason)) {
        std::printf("{\"channel\":\"%s\",\"recv_utime\":%lld,\"message\":%s}\n",
                    info.channel.c_str(), static_cast<long long>(info.recv_utime), json.c_str());
      } else {
        ++refused[reason];
        std::printf(
            "{\"channel\":\"%s\",\"recv_utime\":%lld,\"size\":%d,\"refused\":\"%s\","
            "\"error\":\"%s\"}\n",
            info.channel.c_str(), static_cast<long long>(info.recv_utime), size, reason.c_str(),
            why.c_str());
      }
      std::fflush(stdout);
      if (o->count > 0 && ++received >= o->count) RequestShutdown();
    });
    if (o->lcm_url.rfind("file://", 0) == 0) {
      // A log: LCM's receive fails at its end, which here is the normal end.
      const int64_t give_up =
          o->timeout_s > 0 ? NowUtime() + static_cast<int64_t>(o->timeout_s * 1e6) : INT64_MAX;
      while (!ShutdownRequested() && NowUtime() < give_up && bus->Handle(100) >= 0) {
      }
      *exit_code = 0;
    } else {
      RunLoopOptions loop;
      loop.duration_s = o->timeout_s;
      *exit_code = RunLoop(
          bus.get(), [](int64_t) {}, loop);
    }
    if (!refused.empty()) {
      int64_t total = 0;
      for (const auto& [reason, count] : refused) total += count;
      std::cerr << "roomfix listen: warning: " << total << " messages refused ("
                << RefusalCounts(refused) << ")\n";
    }
    if (*exit_code == 0 && o->count > 0 && received < o->count) {
      std::cerr << "roomfix listen: timed out after " << received << " of " << o->count
                << " messages\n";
      *exit_code = 3;
    }
  });
}

}  // namespace roomfix
