#ifndef ROOMFIX_CORE_RADIO_XBEE_FRAME_H_
#define ROOMFIX_CORE_RADIO_XBEE_FRAME_H_

#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace roomfix::radio {

// Digi XBee API frames, as a coordinator in API mode writes them to its
// serial port (docs/radio_protocol.md):
//
//   0x7E | length (2 bytes, big-endian) | frame data (length bytes) | checksum
//
// where frame data starts with the frame type and the checksum is
// 0xFF - (sum of the frame data bytes mod 256), so that the frame data plus the
// checksum sum to 0xFF. In API mode 2 ("escaped", AP=2) every byte after the
// start delimiter that equals 0x7E, 0x7D, 0x11 or 0x13 is sent as 0x7D
// followed by the byte XOR 0x20; the length counts unescaped bytes. In API
// mode 1 nothing is escaped, so 0x7E may appear inside a frame and only the
// checksum tells a real frame start from a data byte.

enum class ApiMode : int { kUnescaped = 1, kEscaped = 2 };

inline constexpr uint8_t kStartDelimiter = 0x7E;
inline constexpr uint8_t kEscape = 0x7D;
inline constexpr uint8_t kXon = 0x11;
inline constexpr uint8_t kXoff = 0x13;
inline constexpr uint8_t kEscapeXor = 0x20;

// Frame types roomfix reads.
inline constexpr uint8_t kRx64FrameType = 0x80;      // 802.15.4 receive, 64-bit source
inline constexpr uint8_t kRx16FrameType = 0x81;      // 802.15.4 receive, 16-bit source
inline constexpr uint8_t kZigbeeRxFrameType = 0x90;  // ZigBee receive packet

// What went wrong in the byte stream. Every error is reported once, at the
// stream offset where the bad frame (or the run of garbage) started.
enum class FrameError {
  // Bytes outside any frame (before a start delimiter).
  kGarbage,
  // A complete frame whose checksum does not match.
  kBadChecksum,
  // A frame cut short: a start delimiter arrived inside it (mode 2), the
  // stream ended, or FlushPartial() was called while it was incomplete.
  kTruncated,
  // A length of 0 or above the decoder's maximum.
  kBadLength,
  // Mode 2: an escape byte followed by a byte that cannot have been escaped.
  kBadEscape,
};

// The reason's name as counted in STATUS and printed by `roomfix frames`:
// garbage, bad_checksum, truncated_frame, bad_length, bad_escape.
const char* FrameErrorName(FrameError error);

struct FrameErrorInfo {
  FrameError error = FrameError::kGarbage;
  // Offset in the whole stream fed so far of the first byte concerned.
  uint64_t stream_offset = 0;
  // How many bytes the error covers (garbage run, bad frame).
  uint64_t size_bytes = 0;
  // One human-readable line, e.g. "checksum 0x12, expected 0x34".
  std::string detail;
};

// Receives decoded frames and errors, in stream order. `frame_data` (frame
// type first, no length, no checksum, unescaped) is only valid during the
// call.
class FrameSink {
 public:
  virtual ~FrameSink() = default;
  virtual void OnFrame(const uint8_t* frame_data, size_t size, uint64_t stream_offset) = 0;
  virtual void OnFrameError(const FrameErrorInfo& error) = 0;
};

struct FrameDecoderOptions {
  ApiMode mode = ApiMode::kEscaped;
  // Longest frame data accepted; a longer length field is kBadLength. XBee
  // receive frames carry at most 255 payload bytes plus a 12-byte header.
  size_t max_frame_data_bytes = 300;
};

// Incremental decoder: feed it whatever the serial port returned, in any
// chunking; frames come out exactly as if the stream had been fed at once.
//
// Resynchronisation: after a bad checksum, a bad length or a truncated frame
// the decoder rescans the bytes it had taken for that frame, starting one
// byte after its start delimiter, so a good frame that began inside the bad
// one (a truncated frame followed by a complete one) is not lost.
//
// Cost: O(1) per byte amortised, no allocation after the first frames.
class FrameDecoder {
 public:
  explicit FrameDecoder(const FrameDecoderOptions& options = {});

  void Feed(const uint8_t* data, size_t size, FrameSink* sink);
  // Declares the frame in progress (if any) truncated, reports it, and
  // rescans its bytes. Call at end of stream, after the device was reopened,
  // or when the line has been quiet longer than a frame takes to send.
  void FlushPartial(FrameSink* sink);
  // True while a frame has started but not completed.
  bool InFrame() const;
  uint64_t bytes_fed() const;
  const FrameDecoderOptions& options() const;

 private:
  // Choices the public comments leave open:
  //  - Bytes of a bad frame are covered by that frame's error only. While
  //    rescanning them (mode 1), a candidate frame that starts inside an already
  //    reported range and also fails is not reported (its bytes are already
  //    covered), and skipped bytes inside the range are not garbage. Errors
  //    therefore never overlap each other; a good frame found by the rescan
  //    may lie inside the range of the error reported before it.
  //  - Reports come out with strictly increasing stream offsets.
  //  - FlushPartial() also ends (and reports) a run of garbage in progress,
  //    so after it every byte fed is in a frame or in an error.
  //  - Mode 2 accepts raw 0x11/0x13 inside a frame (a module never sends
  //    them, but nothing is ambiguous about them).
  //  - Cost, mode 1: each candidate frame (each 0x7E) is checked in O(1)
  //    with prefix sums, so even a stream of 0x7E 0x01 0x2C ... that starts
  //    a 300-byte candidate every 3 bytes costs O(1) per byte.

  // kLengthMsb..kChecksum: where a mode-2 frame is. kCandidate: mode 1, a
  // frame starts at window_[0] and is not resolved yet.
  enum class Phase : uint8_t { kIdle, kLengthMsb, kLengthLsb, kData, kChecksum, kCandidate };

  // Mode 2: a streaming state machine. A raw 0x7E ends every frame, so a
  // bad frame never contains the start of another and needs no rescan.
  void FeedEscaped(const uint8_t* data, size_t size, uint64_t offset, FrameSink* sink);
  // Mode 1: new bytes are appended to window_ (at most kWindowSlice at a
  // time) and ScanWindow resolves candidates in it, rescanning from one
  // after a failed candidate's 0x7E. Afterwards window_ holds only the
  // unresolved candidate, if any.
  void ScanWindow(size_t from, FrameSink* sink);
  void StartFrame(uint64_t offset, FrameSink* sink);
  void FailFrame(FrameError error, uint64_t end_offset, const char* detail, FrameSink* sink);
  void FailChecksum(uint8_t checksum, uint32_t sum, uint64_t end_offset, FrameSink* sink);
  void AddGarbage(uint64_t offset, uint64_t size);
  void FlushGarbage(FrameSink* sink);

  FrameDecoderOptions options_;
  bool escaped_ = true;
  size_t max_length_ = 0;  // min(options_.max_frame_data_bytes, 0xFFFF)
  Phase phase_ = Phase::kIdle;
  uint64_t frame_offset_ = 0;  // stream offset of the frame's 0x7E
  uint64_t bytes_fed_ = 0;
  // Bytes before this offset are inside a reported error.
  uint64_t covered_until_ = 0;
  uint64_t garbage_start_ = 0;
  uint64_t garbage_bytes_ = 0;

  // Mode 2: frame data so far, unescaped; sized once, never reallocated.
  std::vector<uint8_t> frame_;
  size_t frame_size_ = 0;
  size_t length_ = 0;
  uint32_t sum_ = 0;
  bool escape_next_ = false;

  // Mode 1: raw bytes not yet resolved, window_[0] at window_offset_, and
  // prefix_[i] = sum of window_[0..i) mod 256 (one entry more). Capacity is
  // reserved once for a slice plus the longest frame.
  std::vector<uint8_t> window_;
  std::vector<uint8_t> prefix_;
  uint64_t window_offset_ = 0;
};

// Wraps frame data (frame type first) into a complete frame: start
// delimiter, length, data and checksum, escaped in mode 2.
std::vector<uint8_t> EncodeFrame(const uint8_t* frame_data, size_t size, ApiMode mode);
void AppendFrame(const uint8_t* frame_data, size_t size, ApiMode mode, std::vector<uint8_t>* out);

// A received RF packet from frame 0x90, 0x80 or 0x81.
struct ReceivePacket {
  uint8_t frame_type = kZigbeeRxFrameType;
  // 0x90 and 0x80 carry the sender's 64-bit address (0xFFFFFFFFFFFFFFFF when
  // the module does not know it), 0x90 and 0x81 its 16-bit network address.
  bool has_address64 = false;
  uint64_t address64 = 0;
  bool has_address16 = false;
  uint16_t address16 = 0;
  // Receive options bit field as the module reports it.
  uint8_t options = 0;
  // 802.15.4 frames only: received signal strength, dBm (negative).
  bool has_rssi = false;
  int rssi_dbm = 0;
  // The RF data.
  std::vector<uint8_t> payload;
};

enum class PacketParse {
  kOk,
  // Any other frame type (AT response, modem status, transmit status, ...):
  // not an error, not for us.
  kOtherFrameType,
  // A receive frame shorter than its fixed header.
  kTooShort,
};

// Parses frame data (frame type first) as a receive packet.
PacketParse ParseReceivePacket(const uint8_t* frame_data, size_t size, ReceivePacket* packet);

// The frame data of a receive packet (inverse of ParseReceivePacket); the
// virtual devices and the tests build frames with it.
std::vector<uint8_t> EncodeReceivePacket(const ReceivePacket& packet);

}  // namespace roomfix::radio

#endif  // ROOMFIX_CORE_RADIO_XBEE_FRAME_H_
