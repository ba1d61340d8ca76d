// roomfix_logger: records LCM traffic into LCM log files.
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <iostream>

#include "logger/logger_node.h"
#include "msgio/process.h"

int main(int argc, char** argv) {
  roomfix::ProcessOptions process;
  roomfix::LoggerOptions options;
  double rotate_mb = 0.0;
  double queue_mb = static_cast<double>(options.max_queue_bytes) / (1 << 20);
  bool via_liblcm = false;
  CLI::App app{
      "roomfix_logger: records LCM channels into LCM log files (lcm-logplayer plays them)"};
  roomfix::AddProcessFlags(&app, &process, /*config_required=*/false);
  app.add_option("FILE", options.path, "Log file to write")->required();
  app.add_option("--channel", options.channel_regex, "Channels to record (regular expression)")
      ->capture_default_str();
  app.add_flag("--force", options.overwrite, "Overwrite existing files");
  app.add_flag("--increment", options.increment,
               "Write under the first free numbered name (FILE-00.lcm, FILE-01.lcm, ...), so a "
               "restarted logger never overwrites nor refuses; as lcm-logger --increment");
  app.add_option("--flush-interval", options.flush_interval_ms,
                 "Flush to the operating system every this many milliseconds")
      ->capture_default_str();
  app.add_option("--rotate-mb", rotate_mb,
                 "Start a new numbered file after this many MiB (0: never)");
  app.add_option("--rotate-seconds", options.rotate_seconds,
                 "Start a new numbered file after this many seconds (0: never)");
  app.add_option("--queue-mb", queue_mb, "Most MiB of received, unwritten messages to hold")
      ->capture_default_str();
  app.add_flag("--via-liblcm", via_liblcm,
               "Receive udpm:// through liblcm (queue capacity raised) instead of roomfix's own "
               "receiver, to measure it: liblcm 1.3.1 is crashed by one malformed fragment and "
               "cannot count what its queues drop (docs/logger.md)");
  CLI11_PARSE(app, argc, argv);
  process.direct_udpm = !via_liblcm;
  options.rotate_bytes = static_cast<int64_t>(rotate_mb * (1 << 20));
  options.max_queue_bytes = static_cast<int64_t>(queue_mb * (1 << 20));

  std::string error;
  if (!options.IsValid(&error)) return roomfix::PrintFailure("roomfix_logger", error);
  auto ctx = roomfix::StartProcess("roomfix_logger", process, &error);
  if (ctx == nullptr) return roomfix::PrintFailure("roomfix_logger", error);
  if (process.check) {
    const std::string now_name = roomfix::ExpandLogPath(options.path, roomfix::NowUtime());
    std::cout << "roomfix_logger: ok: channels '" << options.channel_regex << "' into "
              << options.path << (now_name != options.path ? " (now: " + now_name + ")" : "")
              << " on " << process.lcm_url << "\n";
    return 0;
  }
  auto node = roomfix::LoggerNode::Create(ctx->bus.get(), options, roomfix::NowUtime(), &error);
  if (node == nullptr) return roomfix::PrintFailure("roomfix_logger", error);
  spdlog::info("recording '{}' into {}", options.channel_regex, node->files().front());
  const int rc = roomfix::RunLoop(ctx->bus.get(), [&](int64_t now) { node->Tick(now); }, {});
  node->Stop(roomfix::NowUtime());
  const auto& s = node->status();
  spdlog::info("{} received, {} written, {} dropped, {} file(s)", s.inputs(), s.outputs(),
               s.dropped(), node->files().size());
  if (s.Make(0, nullptr).state == roomfix::process_status_t::STATE_FAILED) {
    std::cerr << "roomfix_logger: " << s.Make(0, nullptr).last_error << "\n";
    return 2;
  }
  return rc;
}
