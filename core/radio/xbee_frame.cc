#include "core/radio/xbee_frame.h"

#include <fmt/format.h>

#include <algorithm>
#include <cstring>
#include <utility>

namespace roomfix::radio {
namespace {

// Longest length field a frame can carry.
constexpr size_t kMaxLengthField = 0xFFFF;
// Start delimiter, two length bytes, checksum.
constexpr size_t kFrameOverhead = 4;
// Mode 1 takes at most this many fed bytes into its window at a time, which
// bounds the window (and its one allocation) whatever the caller feeds.
constexpr size_t kWindowSlice = 4096;

// A failure's detail, formatted into the caller's fixed buffer (cut to
// fit): a stream of bad frames costs no allocation per frame.
template <size_t N, typename... Args>
const char* FormatDetail(char (&buffer)[N], fmt::format_string<Args...> format, Args&&... args) {
  *fmt::format_to_n(buffer, N - 1, format, std::forward<Args>(args)...).out = '\0';
  return buffer;
}

bool NeedsEscape(uint8_t byte) {
  return byte == kStartDelimiter || byte == kEscape || byte == kXon || byte == kXoff;
}

uint8_t Checksum(const uint8_t* data, size_t size) {
  uint32_t sum = 0;
  for (size_t i = 0; i < size; ++i) sum += data[i];
  return static_cast<uint8_t>(0xFF - (sum & 0xFF));
}

void AppendByte(uint8_t byte, bool escaped, std::vector<uint8_t>* out) {
  if (escaped && NeedsEscape(byte)) {
    out->push_back(kEscape);
    out->push_back(byte ^ kEscapeXor);
  } else {
    out->push_back(byte);
  }
}

uint64_t ReadBigEndian(const uint8_t* data, size_t size) {
  uint64_t value = 0;
  for (size_t i = 0; i < size; ++i) value = (value << 8) | data[i];
  return value;
}

void AppendBigEndian(uint64_t value, size_t size, std::vector<uint8_t>* out) {
  for (size_t i = size; i-- > 0;) out->push_back(static_cast<uint8_t>(value >> (8 * i)));
}

// Fixed header sizes of the receive frames, frame type included; 0 for any
// other type.
size_t ReceiveHeaderSize(uint8_t frame_type) {
  switch (frame_type) {
    case kZigbeeRxFrameType:
      return 1 + 8 + 2 + 1;
    case kRx64FrameType:
      return 1 + 8 + 1 + 1;
    case kRx16FrameType:
      return 1 + 2 + 1 + 1;
    default:
      return 0;
  }
}

}  // namespace

const char* FrameErrorName(FrameError error) {
  switch (error) {
    case FrameError::kGarbage:
      return "garbage";
    case FrameError::kBadChecksum:
      return "bad_checksum";
    case FrameError::kTruncated:
      return "truncated_frame";
    case FrameError::kBadLength:
      return "bad_length";
    case FrameError::kBadEscape:
      return "bad_escape";
  }
  return "unknown";
}

FrameDecoder::FrameDecoder(const FrameDecoderOptions& options)
    : options_(options),
      escaped_(options.mode == ApiMode::kEscaped),
      max_length_(std::min(options.max_frame_data_bytes, kMaxLengthField)) {
  if (escaped_) {
    frame_.resize(max_length_);
  } else {
    window_.reserve(kWindowSlice + max_length_ + kFrameOverhead);
    prefix_.reserve(kWindowSlice + max_length_ + kFrameOverhead + 1);
    prefix_.push_back(0);
  }
}

bool FrameDecoder::InFrame() const { return phase_ != Phase::kIdle; }
uint64_t FrameDecoder::bytes_fed() const { return bytes_fed_; }
const FrameDecoderOptions& FrameDecoder::options() const { return options_; }

void FrameDecoder::Feed(const uint8_t* data, size_t size, FrameSink* sink) {
  const uint64_t offset = bytes_fed_;
  bytes_fed_ += size;
  if (escaped_) {
    FeedEscaped(data, size, offset, sink);
    return;
  }
  while (size > 0) {
    const size_t take = std::min(size, kWindowSlice);
    const size_t from = window_.size();
    window_.insert(window_.end(), data, data + take);
    prefix_.resize(from + take + 1);
    uint8_t running = prefix_[from];
    for (size_t i = 0; i < take; ++i) {
      running = static_cast<uint8_t>(running + data[i]);
      prefix_[from + i + 1] = running;
    }
    ScanWindow(from, sink);
    data += take;
    size -= take;
  }
}

void FrameDecoder::FlushPartial(FrameSink* sink) {
  char detail[96];
  // In mode 1 the rescan of a truncated candidate may start another one that
  // is just as incomplete; each starts later in the stream, so this ends.
  while (phase_ != Phase::kIdle) {
    FailFrame(FrameError::kTruncated, bytes_fed_,
              FormatDetail(detail, "stream paused or ended {} bytes into the frame",
                           bytes_fed_ - frame_offset_),
              sink);
    if (!escaped_) ScanWindow(1, sink);
  }
  FlushGarbage(sink);
}

void FrameDecoder::StartFrame(uint64_t offset, FrameSink* sink) {
  FlushGarbage(sink);
  frame_offset_ = offset;
  phase_ = escaped_ ? Phase::kLengthMsb : Phase::kCandidate;
  frame_size_ = 0;
  length_ = 0;
  sum_ = 0;
  escape_next_ = false;
}

void FrameDecoder::FailFrame(FrameError error, uint64_t end_offset, const char* detail,
                             FrameSink* sink) {
  phase_ = Phase::kIdle;
  escape_next_ = false;
  if (frame_offset_ < covered_until_) return;
  FrameErrorInfo info;
  info.error = error;
  info.stream_offset = frame_offset_;
  info.size_bytes = end_offset - frame_offset_;
  info.detail = detail;
  covered_until_ = end_offset;
  sink->OnFrameError(info);
}

void FrameDecoder::FailChecksum(uint8_t checksum, uint32_t sum, uint64_t end_offset,
                                FrameSink* sink) {
  char detail[64] = "";
  // Mode 1 suppresses most failures in adversarial input; formatting their
  // detail would then be most of the cost.
  if (frame_offset_ >= covered_until_) {
    FormatDetail(detail, "checksum 0x{:02X}, expected 0x{:02X}", checksum, 0xFF - (sum & 0xFF));
  }
  FailFrame(FrameError::kBadChecksum, end_offset, detail, sink);
}

void FrameDecoder::AddGarbage(uint64_t offset, uint64_t size) {
  const uint64_t end = offset + size;
  if (end <= covered_until_) return;
  offset = std::max(offset, covered_until_);
  // A run only grows at its end: it is flushed before any frame starts, and
  // a rescan only revisits bytes after a frame's start.
  if (garbage_bytes_ == 0) garbage_start_ = offset;
  garbage_bytes_ += end - offset;
}

void FrameDecoder::FlushGarbage(FrameSink* sink) {
  if (garbage_bytes_ == 0) return;
  FrameErrorInfo info;
  info.error = FrameError::kGarbage;
  info.stream_offset = garbage_start_;
  info.size_bytes = garbage_bytes_;
  info.detail = fmt::format("{} bytes outside any frame", garbage_bytes_);
  garbage_bytes_ = 0;
  sink->OnFrameError(info);
}

void FrameDecoder::ScanWindow(size_t from, FrameSink* sink) {
  const uint8_t* const w = window_.data();
  const uint8_t* const sums = prefix_.data();
  const size_t n = window_.size();
  size_t candidate = 0;  // where the frame in progress starts, if any
  size_t i = from;       // next byte to look at outside a frame
  char detail[96];
  for (;;) {
    if (phase_ == Phase::kIdle) {
      const void* found = i < n ? std::memchr(w + i, kStartDelimiter, n - i) : nullptr;
      const size_t at = found != nullptr ? static_cast<const uint8_t*>(found) - w : n;
      if (at > i) AddGarbage(window_offset_ + i, at - i);
      if (at == n) break;
      candidate = at;
      StartFrame(window_offset_ + at, sink);
    }
    const size_t available = n - candidate;
    if (available < 3) break;
    const size_t length = static_cast<size_t>(w[candidate + 1]) << 8 | w[candidate + 2];
    if (length == 0 || length > max_length_) {
      detail[0] = '\0';
      if (frame_offset_ >= covered_until_) {
        FormatDetail(detail, "length {}, accepted 1 to {}", length, max_length_);
      }
      FailFrame(FrameError::kBadLength, frame_offset_ + 3, detail, sink);
      i = candidate + 1;
      continue;
    }
    if (available < length + kFrameOverhead) break;
    const size_t data_at = candidate + 3;
    const uint8_t sum = static_cast<uint8_t>(sums[data_at + length] - sums[data_at]);
    const uint8_t checksum = w[data_at + length];
    if (static_cast<uint8_t>(sum + checksum) == 0xFF) {
      phase_ = Phase::kIdle;
      sink->OnFrame(w + data_at, length, frame_offset_);
      i = candidate + length + kFrameOverhead;
    } else {
      FailChecksum(checksum, sum, frame_offset_ + length + kFrameOverhead, sink);
      i = candidate + 1;
    }
  }
  // Keep only the frame in progress; prefix sums stay valid shifted, since
  // only their differences count.
  const size_t keep_from = phase_ == Phase::kIdle ? n : candidate;
  window_.erase(window_.begin(), window_.begin() + keep_from);
  prefix_.erase(prefix_.begin(), prefix_.begin() + keep_from);
  window_offset_ += keep_from;
}

void FrameDecoder::FeedEscaped(const uint8_t* data, size_t size, uint64_t offset, FrameSink* sink) {
  const uint8_t* p = data;
  const uint8_t* const end = data + size;
  char detail[96];
  while (p < end) {
    if (phase_ == Phase::kIdle) {
      const void* found = std::memchr(p, kStartDelimiter, end - p);
      const uint8_t* start = found != nullptr ? static_cast<const uint8_t*>(found) : end;
      if (start != p) AddGarbage(offset + (p - data), start - p);
      if (start == end) return;
      StartFrame(offset + (start - data), sink);
      p = start + 1;
      continue;
    }
    // Frame data runs to the next byte that needs a look without the
    // per-byte state machine.
    if (phase_ == Phase::kData && !escape_next_) {
      const uint8_t* run = p;
      const uint8_t* const run_end = p + std::min<size_t>(length_ - frame_size_, end - p);
      uint8_t* out = frame_.data() + frame_size_;
      uint32_t sum = 0;
      while (run < run_end && *run != kStartDelimiter && *run != kEscape) {
        sum += *run;
        *out++ = *run++;
      }
      sum_ += sum;
      frame_size_ += run - p;
      p = run;
      if (frame_size_ == length_) {
        phase_ = Phase::kChecksum;
        continue;
      }
      if (p == end) return;
    }

    uint8_t byte = *p;
    if (byte == kStartDelimiter) {
      // Not consumed: it starts the next frame on the next round.
      const uint64_t at = offset + (p - data);
      if (escape_next_) {
        FailFrame(FrameError::kBadEscape, at, "escape byte followed by a start delimiter", sink);
      } else {
        FailFrame(
            FrameError::kTruncated, at,
            FormatDetail(detail, "start delimiter {} bytes into the frame", at - frame_offset_),
            sink);
      }
      continue;
    }
    ++p;
    if (escape_next_) {
      escape_next_ = false;
      byte ^= kEscapeXor;
      if (!NeedsEscape(byte)) {
        FailFrame(FrameError::kBadEscape, offset + (p - data),
                  FormatDetail(detail, "escape byte followed by 0x{:02X}", byte ^ kEscapeXor),
                  sink);
        continue;
      }
    } else if (byte == kEscape) {
      escape_next_ = true;
      continue;
    }

    // One unescaped length, data or checksum byte.
    switch (phase_) {
      case Phase::kLengthMsb:
        length_ = static_cast<size_t>(byte) << 8;
        phase_ = Phase::kLengthLsb;
        break;
      case Phase::kLengthLsb:
        length_ |= byte;
        if (length_ == 0 || length_ > max_length_) {
          FailFrame(FrameError::kBadLength, offset + (p - data),
                    FormatDetail(detail, "length {}, accepted 1 to {}", length_, max_length_),
                    sink);
        } else {
          phase_ = Phase::kData;
        }
        break;
      case Phase::kData:
        frame_[frame_size_++] = byte;
        sum_ += byte;
        if (frame_size_ == length_) phase_ = Phase::kChecksum;
        break;
      case Phase::kChecksum:
        if (((sum_ + byte) & 0xFF) == 0xFF) {
          phase_ = Phase::kIdle;
          sink->OnFrame(frame_.data(), length_, frame_offset_);
        } else {
          FailChecksum(byte, sum_, offset + (p - data), sink);
        }
        break;
      case Phase::kIdle:
      case Phase::kCandidate:
        break;
    }
  }
}

std::vector<uint8_t> EncodeFrame(const uint8_t* frame_data, size_t size, ApiMode mode) {
  std::vector<uint8_t> out;
  AppendFrame(frame_data, size, mode, &out);
  return out;
}

void AppendFrame(const uint8_t* frame_data, size_t size, ApiMode mode, std::vector<uint8_t>* out) {
  // A length field cannot say more; appending nothing beats a frame whose
  // length lies. Size 0 is encoded as is (decoders report kBadLength), which
  // the tests use.
  if (size > kMaxLengthField) return;
  const bool escaped = mode == ApiMode::kEscaped;
  out->reserve(out->size() + (escaped ? 2 : 1) * (size + kFrameOverhead));
  out->push_back(kStartDelimiter);
  AppendByte(static_cast<uint8_t>(size >> 8), escaped, out);
  AppendByte(static_cast<uint8_t>(size & 0xFF), escaped, out);
  if (escaped) {
    for (size_t i = 0; i < size; ++i) AppendByte(frame_data[i], true, out);
  } else {
    out->insert(out->end(), frame_data, frame_data + size);
  }
  AppendByte(Checksum(frame_data, size), escaped, out);
}

PacketParse ParseReceivePacket(const uint8_t* frame_data, size_t size, ReceivePacket* packet) {
  if (size == 0) return PacketParse::kTooShort;
  const uint8_t type = frame_data[0];
  const size_t header = ReceiveHeaderSize(type);
  if (header == 0) return PacketParse::kOtherFrameType;
  if (size < header) return PacketParse::kTooShort;

  *packet = ReceivePacket();
  packet->frame_type = type;
  const uint8_t* p = frame_data + 1;
  if (type == kZigbeeRxFrameType || type == kRx64FrameType) {
    packet->has_address64 = true;
    packet->address64 = ReadBigEndian(p, 8);
    p += 8;
  }
  if (type == kZigbeeRxFrameType || type == kRx16FrameType) {
    packet->has_address16 = true;
    packet->address16 = static_cast<uint16_t>(ReadBigEndian(p, 2));
    p += 2;
  }
  if (type != kZigbeeRxFrameType) {
    // The module reports -dBm: 0x28 is -40 dBm.
    packet->has_rssi = true;
    packet->rssi_dbm = -static_cast<int>(*p++);
  }
  packet->options = *p++;
  packet->payload.assign(p, frame_data + size);
  return PacketParse::kOk;
}

std::vector<uint8_t> EncodeReceivePacket(const ReceivePacket& packet) {
  // Fields follow frame_type; the has_* flags are what a parse sets, not
  // switches. Another frame type has no receive layout: empty result.
  std::vector<uint8_t> out;
  const uint8_t type = packet.frame_type;
  const size_t header = ReceiveHeaderSize(type);
  if (header == 0) return out;
  out.reserve(header + packet.payload.size());
  out.push_back(type);
  if (type == kZigbeeRxFrameType || type == kRx64FrameType) {
    AppendBigEndian(packet.address64, 8, &out);
  }
  if (type == kZigbeeRxFrameType || type == kRx16FrameType) {
    AppendBigEndian(packet.address16, 2, &out);
  }
  if (type != kZigbeeRxFrameType) {
    // Outside what a byte of -dBm can say: clamped to 0 dBm or -255 dBm.
    out.push_back(static_cast<uint8_t>(std::clamp(-packet.rssi_dbm, 0, 255)));
  }
  out.push_back(packet.options);
  out.insert(out.end(), packet.payload.begin(), packet.payload.end());
  return out;
}

}  // namespace roomfix::radio
