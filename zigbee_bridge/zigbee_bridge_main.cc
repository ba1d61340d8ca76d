// zigbee_bridge: the ZigBee coordinator's serial port to range sets on RANGES.
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <cmath>
#include <iostream>

#include "msgio/process.h"
#include "zigbee_bridge/bridge_node.h"
#include "zigbee_bridge/serial_link.h"

int main(int argc, char** argv) {
  roomfix::ProcessOptions process;
  roomfix::BridgeNodeOptions options;
  roomfix::SerialLinkOptions link_options;
  int api_mode = 2;
  double deadline_ms = options.assembler.deadline_s * 1e3;
  double duration_s = 0.0;
  CLI::App app{
      "zigbee_bridge: reads the ZigBee coordinator (XBee API frames) on a serial port and "
      "publishes one range set per beacon firing on RANGES"};
  roomfix::AddProcessFlags(&app, &process, /*config_required=*/true);
  app.add_option("--port", link_options.port,
                 "Serial device of the coordinator (/dev/ttyUSB0, or a pseudo-terminal)")
      ->required();
  app.add_option("--baud", link_options.baud, "Baud rate")->capture_default_str();
  app.add_option("--api-mode", api_mode, "XBee API mode: 1 (unescaped) or 2 (escaped, AP=2)")
      ->capture_default_str()
      ->check(CLI::IsMember({1, 2}));
  app.add_option("--deadline-ms", deadline_ms,
                 "Publish a firing's set this long after its first packet even if a receiver "
                 "has not answered")
      ->capture_default_str();
  app.add_option("--temperature", options.assembler.default_temperature_c,
                 "Air temperature when no device reports one, degC")
      ->capture_default_str();
  app.add_option("--range-margin", options.assembler.range_margin_m,
                 "Tolerance on the ranges the room allows, m")
      ->capture_default_str();
  app.add_option("--reopen-max", link_options.reopen_max_s,
                 "Longest wait between attempts to reopen a lost device, s")
      ->capture_default_str();
  app.add_option("--duration", duration_s, "Stop after this many seconds (0: until a signal)")
      ->capture_default_str();
  int radio_id = 0;
  app.add_option("--radio", radio_id,
                 "The coordinator this bridge reads (site radios[].id): its range sets hold and "
                 "expect only that radio's receivers, and trilat_proc merges the parts "
                 "(0: the site has one coordinator for every receiver)")
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);

  options.api_mode =
      api_mode == 1 ? roomfix::radio::ApiMode::kUnescaped : roomfix::radio::ApiMode::kEscaped;
  options.assembler.deadline_s = deadline_ms * 1e-3;
  std::string error;
  if (!options.IsValid(&error) || !link_options.IsValid(&error)) {
    std::cerr << "zigbee_bridge: " << error << "\n";
    return 1;
  }
  auto ctx = roomfix::StartProcess("zigbee_bridge", process, &error);
  if (ctx == nullptr) {
    std::cerr << "zigbee_bridge: " << error << "\n";
    return 1;
  }
  // With --radio, the bridge sees only its coordinator's receivers.
  roomfix::Site radio_site;
  if (radio_id != 0 && !roomfix::SiteForRadio(ctx->site, radio_id, &radio_site, &error)) {
    std::cerr << "zigbee_bridge: --radio: " << error << "\n";
    return 1;
  }
  const roomfix::Site& site = radio_id != 0 ? radio_site : ctx->site;
  if (radio_id == 0 && ctx->site.radios.size() > 1) {
    spdlog::warn("the site names {} radios; without --radio this bridge expects every receiver",
                 ctx->site.radios.size());
  }
  if (process.check) {
    std::cout << "zigbee_bridge: ok: " << link_options.port << " at " << link_options.baud
              << " baud, API mode " << api_mode << ", " << site.receivers.size() << " receivers, "
              << ctx->site.beacons.size() << " beacons, deadline " << deadline_ms << " ms, on "
              << process.lcm_url << "\n";
    return 0;
  }

  const int64_t start = roomfix::NowUtime();
  roomfix::BridgeNode node(site, ctx->bus.get(), options, start);
  roomfix::SerialLink link(link_options);
  std::vector<uint8_t> buffer(64 * 1024);
  int64_t last_failures = 0;

  roomfix::RunLoopOptions loop;
  // Deadlines are checked at every tick: 2 ms keeps a closed-by-deadline
  // set within 2 ms of its deadline at a negligible cost.
  loop.tick_period_ms = 2;
  loop.duration_s = duration_s;
  loop.extra_fd = [&] { return link.fd(); };
  const int rc = roomfix::RunLoop(
      ctx->bus.get(),
      [&](int64_t now) {
        if (link.state() != roomfix::SerialLink::State::kOpen) {
          if (link.MaybeOpen(now)) {
            node.OnLinkUp(link_options.port, now);
          } else if (link.open_failures() != last_failures) {
            last_failures = link.open_failures();
            node.OnOpenFailed(link.last_error(), now);
            if (last_failures == 1 || last_failures % 10 == 0) {
              spdlog::warn("{} (attempt {}, retrying)", link.last_error(), last_failures);
            }
          }
        }
        // Drain what the port holds; each read is stamped with the time it
        // returned, the arrival time of its bytes. Deadlines are judged at
        // the time of the read that found nothing more, so a report that
        // came before a deadline has always been read by then.
        int64_t tick_utime = roomfix::NowUtime();
        while (link.state() == roomfix::SerialLink::State::kOpen) {
          tick_utime = roomfix::NowUtime();
          const int n = link.Read(buffer.data(), buffer.size(), tick_utime);
          if (n < 0) {
            spdlog::warn("{}; reopening", link.last_error());
            node.OnLinkDown(link.last_error(), tick_utime);
            break;
          }
          if (n == 0) break;
          node.OnBytes(buffer.data(), static_cast<size_t>(n), tick_utime);
        }
        node.Tick(tick_utime);
      },
      loop);
  node.Stop(roomfix::NowUtime());
  const roomfix::radio::RangeAssembler& a = node.assembler();
  std::string rejected;
  for (const auto& [reason, count] : a.rejected()) {
    rejected += (rejected.empty() ? "" : ", ") + reason + " " + std::to_string(count);
  }
  spdlog::info("stopped: {} range sets published ({} complete, {} at the deadline); rejected: {}",
               node.sets_published(), a.counter("sets_complete"), a.counter("sets_deadline"),
               rejected.empty() ? "none" : rejected);
  return rc;
}
