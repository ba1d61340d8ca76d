#include "zigbee_bridge/bridge_app.h"

#include <spdlog/spdlog.h>

#include <iostream>
#include <vector>

namespace roomfix {

bool BridgeAppOptions::IsValid(std::string* error) const {
  return node.IsValid(error) && link.IsValid(error);
}

namespace {

void PrintCheckLine(const ProcessContext& ctx, const Site& site, const BridgeAppOptions& options) {
  std::cout << "zigbee_bridge: ok: " << options.link.port << " at " << options.link.baud
            << " baud, API mode " << (options.node.api_mode == radio::ApiMode::kUnescaped ? 1 : 2)
            << ", " << site.receivers.size() << " receivers, " << ctx.site.beacons.size()
            << " beacons, deadline " << options.node.assembler.deadline_s * 1e3 << " ms, on "
            << ctx.options.lcm_url << "\n";
}

// One tick: reopens a lost port (each failure told to the node, and logged
// at the 1st and every 10th attempt), then drains what the port holds. Each
// read is stamped with the time it returned, the arrival time of its bytes;
// deadlines are judged at the time of the read that found nothing more, so a
// report that came before a deadline has always been read by then.
class PortReader {
 public:
  PortReader(BridgeNode* node, SerialLink* link, std::string port)
      : node_(node), link_(link), port_(std::move(port)), buffer_(64 * 1024) {}

  void Tick(int64_t now_utime) {
    if (link_->state() != SerialLink::State::kOpen) {
      if (link_->MaybeOpen(now_utime)) {
        node_->OnLinkUp(port_, now_utime);
      } else if (link_->open_failures() != last_failures_) {
        last_failures_ = link_->open_failures();
        node_->OnOpenFailed(link_->last_error(), now_utime);
        if (last_failures_ == 1 || last_failures_ % 10 == 0) {
          spdlog::warn("{} (attempt {}, retrying)", link_->last_error(), last_failures_);
        }
      }
    }
    int64_t tick_utime = NowUtime();
    while (link_->state() == SerialLink::State::kOpen) {
      tick_utime = NowUtime();
      const int n = link_->Read(buffer_.data(), buffer_.size(), tick_utime);
      if (n < 0) {
        spdlog::warn("{}; reopening", link_->last_error());
        node_->OnLinkDown(link_->last_error(), tick_utime);
        break;
      }
      if (n == 0) break;
      node_->OnBytes(buffer_.data(), static_cast<size_t>(n), tick_utime);
    }
    node_->Tick(tick_utime);
  }

 private:
  BridgeNode* node_;
  SerialLink* link_;
  std::string port_;
  std::vector<uint8_t> buffer_;
  int64_t last_failures_ = 0;
};

void LogStopped(const BridgeNode& node) {
  const radio::RangeAssembler& a = node.assembler();
  std::string rejected;
  for (const auto& [reason, count] : a.rejected()) {
    rejected += (rejected.empty() ? "" : ", ") + reason + " " + std::to_string(count);
  }
  spdlog::info("stopped: {} range sets published ({} complete, {} at the deadline); rejected: {}",
               node.sets_published(), a.counter("sets_complete"), a.counter("sets_deadline"),
               rejected.empty() ? "none" : rejected);
}

}  // namespace

int RunBridge(ProcessContext* ctx, const BridgeAppOptions& options, std::string* error) {
  // With --radio, the bridge sees only its coordinator's receivers.
  Site radio_site;
  if (options.radio_id != 0 && !SiteForRadio(ctx->site, options.radio_id, &radio_site, error)) {
    *error = "--radio: " + *error;
    return 1;
  }
  const Site& site = options.radio_id != 0 ? radio_site : ctx->site;
  if (options.radio_id == 0 && ctx->site.radios.size() > 1) {
    spdlog::warn("the site names {} radios; without --radio this bridge expects every receiver",
                 ctx->site.radios.size());
  }
  if (ctx->options.check) {
    PrintCheckLine(*ctx, site, options);
    return 0;
  }
  BridgeNode node(site, ctx->bus.get(), options.node, NowUtime());
  SerialLink link(options.link);
  PortReader reader(&node, &link, options.link.port);
  RunLoopOptions loop;
  // Deadlines are checked at every tick: 2 ms keeps a closed-by-deadline
  // set within 2 ms of its deadline at a negligible cost.
  loop.tick_period_ms = 2;
  loop.duration_s = options.duration_s;
  loop.extra_fd = [&] { return link.fd(); };
  const int rc = RunLoop(
      ctx->bus.get(), [&](int64_t now_utime) { reader.Tick(now_utime); }, loop);
  node.Stop(NowUtime());
  LogStopped(node);
  return rc;
}

}  // namespace roomfix
