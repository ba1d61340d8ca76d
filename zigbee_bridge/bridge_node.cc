#include "zigbee_bridge/bridge_node.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "msgio/radio_conversions.h"
#include "roomfix/range_set_t.hpp"

namespace roomfix {
namespace {

// Longest frame data the bridge accepts. A ZigBee receive frame without
// fragmentation carries at most 84 payload bytes after its 12-byte header;
// roomfix's own frames are 22 and 26 bytes. A tight limit turns a corrupted
// length into an immediate bad_length instead of a wait for bytes that
// belong to the next frames (which in API mode 1 delays them).
constexpr size_t kMaxFrameDataBytes = 128;

}  // namespace

bool BridgeNodeOptions::IsValid(std::string* error) const {
  if (api_mode != radio::ApiMode::kUnescaped && api_mode != radio::ApiMode::kEscaped) {
    *error = "API mode must be 1 or 2";
    return false;
  }
  if (!(quiet_line_s > 0.0 && quiet_line_s <= 10.0)) {
    *error = "quiet-line time must be in (0, 10] s";
    return false;
  }
  return assembler.IsValid(error);
}

BridgeNode::BridgeNode(const Site& site, Bus* bus, const BridgeNodeOptions& options,
                       int64_t start_utime)
    : bus_(bus),
      options_(options),
      status_("zigbee_bridge", start_utime),
      decoder_(radio::FrameDecoderOptions{options.api_mode, kMaxFrameDataBytes}),
      assembler_(site, options.assembler),
      now_utime_(start_utime) {
  // Until a serial link reports in, the bridge has no input.
  status_.SetState(process_status_t::STATE_DEGRADED);
}

void BridgeNode::OnBytes(const uint8_t* data, size_t size, int64_t now_utime) {
  now_utime_ = now_utime;
  last_bytes_utime_ = now_utime;
  coordinator_watch_.Seen(now_utime, &status_);
  bytes_ += static_cast<int64_t>(size);
  decoder_.Feed(data, size, this);
  // Publish before returning to the read loop: a set that the last report
  // completed leaves within the same call, which keeps the latency from its
  // bytes to RANGES at the cost of one encode and one send.
  PublishClosed(now_utime);
}

void BridgeNode::OnFrame(const uint8_t* frame_data, size_t size, uint64_t stream_offset) {
  ++frames_;
  const radio::PacketParse parse = radio::ParseReceivePacket(frame_data, size, &packet_);
  if (parse == radio::PacketParse::kOtherFrameType) {
    status_.Count("other_frames");
    return;
  }
  if (parse == radio::PacketParse::kTooShort) {
    status_.Reject("short_frame");
    status_.SetError(fmt::format("frame type 0x{:02X} at byte {}: {} bytes is too short",
                                 frame_data[0], stream_offset, size),
                     now_utime_);
    return;
  }
  status_.AddInputs();
  radio::RadioPacket p;
  p.has_address64 = packet_.has_address64;
  p.address64 = packet_.address64;
  p.has_address16 = packet_.has_address16;
  p.address16 = packet_.address16;
  p.payload = packet_.payload.data();
  p.payload_size = packet_.payload.size();
  p.arrival_utime = now_utime_;
  const char* reason = assembler_.OnPacket(p, &closed_);
  if (reason != nullptr) {
    status_.Reject(reason);
    // no_echo is a normal answer from a receiver that heard nothing; keep
    // the error line for real faults.
    if (std::string(reason) != "no_echo") {
      status_.SetError(assembler_.last_rejection(), now_utime_);
      spdlog::debug("{}", assembler_.last_rejection());
    }
  }
}

void BridgeNode::OnFrameError(const radio::FrameErrorInfo& error) {
  const char* reason = radio::FrameErrorName(error.error);
  status_.Reject(reason);
  if (error.error == radio::FrameError::kGarbage) {
    status_.Count("garbage_bytes", static_cast<int64_t>(error.size_bytes));
  }
  const std::string text =
      fmt::format("{} at byte {}: {}", reason, error.stream_offset, error.detail);
  status_.SetError(text, now_utime_);
  spdlog::debug("{}", text);
}

void BridgeNode::PublishClosed(int64_t now_utime) {
  for (const radio::AssembledSet& set : closed_) {
    const range_set_t msg = RangeSetFromAssembled(set);
    if (bus_->Publish(kRangesChannel, msg)) {
      status_.AddOutputs();
      ++sets_published_;
    } else {
      status_.AddDropped();
      status_.SetError("publishing RANGES failed", now_utime);
    }
  }
  closed_.clear();
}

void BridgeNode::SyncCounters() {
  for (const auto& [name, count] : assembler_.counters()) status_.SetCounter(name, count);
  status_.SetCounter("bytes", bytes_);
  status_.SetCounter("frames", frames_);
  status_.SetCounter("open_firings", assembler_.open_firings());
}

void BridgeNode::Tick(int64_t now_utime) {
  now_utime_ = now_utime;
  if (decoder_.InFrame() &&
      now_utime - last_bytes_utime_ > static_cast<int64_t>(options_.quiet_line_s * 1e6)) {
    decoder_.FlushPartial(this);
  }
  assembler_.Advance(now_utime, &closed_);
  PublishClosed(now_utime);
  if (link_up_ && coordinator_watch_.Check(now_utime, &status_)) {
    SyncCounters();
    status_.Publish(bus_, now_utime);
  }
  SyncCounters();
  status_.MaybePublish(bus_, now_utime);
}

void BridgeNode::OnLinkUp(const std::string& port, int64_t now_utime) {
  // Bytes of a frame cut by the disconnect must not join the new stream.
  if (decoder_.InFrame()) decoder_.FlushPartial(this);
  status_.Count("link_opens");
  status_.SetState(process_status_t::STATE_RUNNING);
  link_up_ = true;
  // The silence is timed from the opening: a coordinator that never says
  // anything is reported too.
  coordinator_watch_.Seen(now_utime, &status_);
  spdlog::info("reading {}", port);
  SyncCounters();
  status_.Publish(bus_, now_utime);
}

void BridgeNode::OnOpenFailed(const std::string& error, int64_t now_utime) {
  status_.Count("open_failures");
  status_.SetState(process_status_t::STATE_DEGRADED);
  status_.SetError(error, now_utime);
}

void BridgeNode::OnLinkDown(const std::string& error, int64_t now_utime) {
  status_.Count("link_lost");
  link_up_ = false;
  if (decoder_.InFrame()) decoder_.FlushPartial(this);
  PublishClosed(now_utime);
  status_.SetState(process_status_t::STATE_DEGRADED);
  status_.SetError(error, now_utime);
  SyncCounters();
  status_.Publish(bus_, now_utime);
}

void BridgeNode::Stop(int64_t now_utime) {
  if (decoder_.InFrame()) decoder_.FlushPartial(this);
  assembler_.Flush(now_utime, &closed_);
  PublishClosed(now_utime);
  SyncCounters();
  status_.SetState(process_status_t::STATE_STOPPING);
  status_.Publish(bus_, now_utime);
}

}  // namespace roomfix
