#ifndef ROOMFIX_ZIGBEE_BRIDGE_BRIDGE_NODE_H_
#define ROOMFIX_ZIGBEE_BRIDGE_BRIDGE_NODE_H_

#include <cstdint>
#include <string>
#include <vector>

#include "core/radio/range_assembler.h"
#include "core/radio/xbee_frame.h"
#include "core/world/site.h"
#include "msgio/bus.h"
#include "msgio/channels.h"
#include "msgio/process.h"

namespace roomfix {

struct BridgeNodeOptions {
  radio::ApiMode api_mode = radio::ApiMode::kEscaped;
  radio::AssemblerOptions assembler;
  // A frame still incomplete after the line has been quiet this long is
  // declared truncated, so that its bytes are rescanned and a frame stuck
  // behind a lost byte does not wait for the next burst. At 9600 baud a
  // 30-byte frame takes 31 ms to arrive.
  double quiet_line_s = 0.1;

  bool IsValid(std::string* error) const;
};

// The bridge's logic, with no serial port and no clock of its own: bytes
// from the coordinator come in with the time they were read, range sets go
// out on RANGES as soon as they close, and STATUS reports every drop by
// reason:
//   frame level: garbage, bad_checksum, truncated_frame, bad_length,
//                bad_escape, short_frame (a receive frame shorter than its
//                header)
//   packet level: everything RangeAssembler refuses (unknown_address,
//                late_report, duplicate_report, ...).
// Other API frames (modem status, AT responses) are counted, not refused.
// The main feeds it from a SerialLink; tests feed it bytes directly.
class BridgeNode : public radio::FrameSink {
 public:
  BridgeNode(const Site& site, Bus* bus, const BridgeNodeOptions& options, int64_t start_utime);

  // Bytes read from the coordinator, all stamped with the read's time.
  void OnBytes(const uint8_t* data, size_t size, int64_t now_utime);
  // Closes sets whose deadline passed, declares a stalled frame truncated,
  // publishes the heartbeat when due.
  void Tick(int64_t now_utime);
  // The serial link came up or went down; the state (RUNNING / DEGRADED)
  // and STATUS follow at once.
  void OnLinkUp(const std::string& port, int64_t now_utime);
  void OnLinkDown(const std::string& error, int64_t now_utime);
  // An attempt to (re)open the port failed; the heartbeat carries it.
  void OnOpenFailed(const std::string& error, int64_t now_utime);
  // Publishes what is still open and a last heartbeat (STOPPING).
  void Stop(int64_t now_utime);

  // When Tick next has something to do (a deadline), for the main's wait.
  int64_t NextDeadlineUtime() const { return assembler_.NextDeadlineUtime(); }
  const StatusReporter& status() const { return status_; }
  const radio::RangeAssembler& assembler() const { return assembler_; }
  int64_t sets_published() const { return sets_published_; }

  void OnFrame(const uint8_t* frame_data, size_t size, uint64_t stream_offset) override;
  void OnFrameError(const radio::FrameErrorInfo& error) override;

 private:
  void PublishClosed(int64_t now_utime);
  void SyncCounters();

  Bus* bus_;
  BridgeNodeOptions options_;
  StatusReporter status_;
  // A coordinator that stays open but sends nothing (its radio down, the
  // beacon off) is reported, not only one that disappears: two seconds is
  // twenty firings at the nominal rate, and longer than a beacon restart.
  InputWatch coordinator_watch_{"bytes from the coordinator", 2.0};
  bool link_up_ = false;
  radio::FrameDecoder decoder_;
  radio::RangeAssembler assembler_;
  radio::ReceivePacket packet_;
  std::vector<radio::AssembledSet> closed_;
  int64_t now_utime_ = 0;
  int64_t last_bytes_utime_ = 0;
  int64_t bytes_ = 0;
  int64_t frames_ = 0;
  int64_t sets_published_ = 0;
};

}  // namespace roomfix

#endif  // ROOMFIX_ZIGBEE_BRIDGE_BRIDGE_NODE_H_
