// libFuzzer target for the XBee API frame codec (core/radio/xbee_frame.h).
//
// The input is a serial stream. For both API modes, each with the default and
// a small frame size limit, it checks and abort()s on the first violation:
//  - feeding the stream at once, a byte at a time, or in chunks whose sizes
//    come from the input's own bytes gives identical reports;
//  - a reference decoder (below: the documented rules applied to the whole
//    stream with random access, summing each candidate frame byte by byte;
//    no incremental state, no window, no prefix sums) gives the same reports;
//  - reports come in increasing stream order, errors never overlap, and
//    after FlushPartial every byte is in a frame or an error;
//  - every frame re-encodes (EncodeFrame) to bytes that decode to that frame
//    data alone; in mode 1 they are the very bytes of the stream;
//  - ParseReceivePacket classifies every frame consistently, and
//    EncodeReceivePacket gives back the frame data of every accepted one.

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "core/radio/xbee_frame.h"

namespace {

using roomfix::radio::ApiMode;
using roomfix::radio::FrameDecoder;
using roomfix::radio::FrameDecoderOptions;
using roomfix::radio::FrameError;
using roomfix::radio::FrameErrorInfo;
using roomfix::radio::FrameSink;
using Bytes = std::vector<uint8_t>;

[[noreturn]] void Violation(const char* what, ApiMode mode, size_t max_frame) {
  std::fprintf(stderr, "xbee_frame_fuzz: %s (API mode %d, max frame data %zu)\n", what,
               static_cast<int>(mode), max_frame);
  std::abort();
}

struct Report {
  bool is_frame = false;
  FrameError error = FrameError::kGarbage;
  uint64_t offset = 0;
  uint64_t size = 0;     // errors: bytes covered; frames: frame data bytes
  uint64_t raw_end = 0;  // reference decoder only: one past the frame's last byte
  Bytes data;

  bool operator==(const Report& other) const {
    return is_frame == other.is_frame && offset == other.offset && size == other.size &&
           (is_frame ? data == other.data : error == other.error);
  }
};

class RecordingSink : public FrameSink {
 public:
  void OnFrame(const uint8_t* frame_data, size_t size, uint64_t stream_offset) override {
    Report report;
    report.is_frame = true;
    report.offset = stream_offset;
    report.size = size;
    report.data.assign(frame_data, frame_data + size);
    reports.push_back(std::move(report));
  }
  void OnFrameError(const FrameErrorInfo& error) override {
    Report report;
    report.error = error.error;
    report.offset = error.stream_offset;
    report.size = error.size_bytes;
    reports.push_back(std::move(report));
    details.push_back(error.detail);
  }
  std::vector<Report> reports;
  std::vector<std::string> details;
};

FrameDecoderOptions Options(ApiMode mode, size_t max_frame) {
  FrameDecoderOptions options;
  options.mode = mode;
  options.max_frame_data_bytes = max_frame;
  return options;
}

// Feeds [data, data+size) in chunks of chunk(k) bytes for the k-th chunk.
template <typename ChunkFn>
RecordingSink DecodeInChunks(const uint8_t* data, size_t size, const FrameDecoderOptions& options,
                             ChunkFn chunk) {
  FrameDecoder decoder(options);
  RecordingSink sink;
  size_t at = 0;
  for (size_t k = 0; at < size; ++k) {
    const size_t n = std::min(chunk(k), size - at);
    decoder.Feed(data + at, n, &sink);
    at += n;
  }
  decoder.FlushPartial(&sink);
  if (decoder.InFrame())
    Violation("in a frame after FlushPartial", options.mode, options.max_frame_data_bytes);
  if (decoder.bytes_fed() != size)
    Violation("bytes_fed() wrong", options.mode, options.max_frame_data_bytes);
  return sink;
}

// --- Reference decoder --------------------------------------------------------

bool NeedsEscape(uint8_t byte) {
  return byte == 0x7E || byte == 0x7D || byte == 0x11 || byte == 0x13;
}

enum class Attempt { kGood, kBad, kIncomplete };

struct AttemptResult {
  Attempt attempt = Attempt::kIncomplete;
  FrameError error = FrameError::kTruncated;
  size_t end = 0;  // one past the frame's last byte (kGood, kBad)
  Bytes data;
};

// Tries to read one frame whose start delimiter is at s[start].
AttemptResult TryFrame(const uint8_t* s, size_t n, size_t start, bool escaped, size_t max_frame) {
  enum Read { kOk, kEnd, kDelimiter, kEscapedDelimiter, kBadEscape };
  size_t i = start + 1;
  auto next = [&](uint8_t* out) -> Read {
    if (i >= n) return kEnd;
    const uint8_t b = s[i];
    if (!escaped) {
      ++i;
      *out = b;
      return kOk;
    }
    if (b == 0x7E) return kDelimiter;  // i stays at the delimiter
    ++i;
    if (b != 0x7D) {
      *out = b;
      return kOk;
    }
    if (i >= n) return kEnd;
    if (s[i] == 0x7E) return kEscapedDelimiter;
    const uint8_t u = s[i++] ^ 0x20;
    if (!NeedsEscape(u)) return kBadEscape;
    *out = u;
    return kOk;
  };
  AttemptResult result;
  auto fail = [&](Read read) -> AttemptResult& {
    if (read == kEnd) {
      result.attempt = Attempt::kIncomplete;
      return result;
    }
    result.attempt = Attempt::kBad;
    result.error = read == kDelimiter ? FrameError::kTruncated : FrameError::kBadEscape;
    result.end = i;
    return result;
  };
  uint8_t msb = 0, lsb = 0, byte = 0;
  Read read = next(&msb);
  if (read != kOk) return fail(read);
  read = next(&lsb);
  if (read != kOk) return fail(read);
  const size_t length = static_cast<size_t>(msb) << 8 | lsb;
  if (length == 0 || length > std::min<size_t>(max_frame, 0xFFFF)) {
    result.attempt = Attempt::kBad;
    result.error = FrameError::kBadLength;
    result.end = i;
    return result;
  }
  unsigned sum = 0;
  for (size_t k = 0; k < length; ++k) {
    read = next(&byte);
    if (read != kOk) return fail(read);
    result.data.push_back(byte);
    sum += byte;
  }
  read = next(&byte);
  if (read != kOk) return fail(read);
  result.end = i;
  if (((sum + byte) & 0xFF) == 0xFF) {
    result.attempt = Attempt::kGood;
  } else {
    result.attempt = Attempt::kBad;
    result.error = FrameError::kBadChecksum;
  }
  return result;
}

std::vector<Report> ReferenceDecode(const uint8_t* s, size_t n, ApiMode mode, size_t max_frame) {
  const bool escaped = mode == ApiMode::kEscaped;
  std::vector<Report> reports;
  size_t covered = 0;  // bytes before this are inside a reported error
  size_t garbage_start = 0, garbage_size = 0;
  auto flush_garbage = [&] {
    if (garbage_size == 0) return;
    Report report;
    report.offset = garbage_start;
    report.size = garbage_size;
    report.raw_end = garbage_start + garbage_size;
    reports.push_back(report);
    garbage_size = 0;
  };
  auto error = [&](FrameError kind, size_t start, size_t end) {
    if (start < covered) return;  // inside an error already reported
    Report report;
    report.error = kind;
    report.offset = start;
    report.size = end - start;
    report.raw_end = end;
    reports.push_back(report);
    covered = end;
  };
  size_t pos = 0;
  while (pos < n) {
    if (s[pos] != 0x7E) {
      if (pos >= covered) {
        if (garbage_size == 0) garbage_start = pos;
        ++garbage_size;
      }
      ++pos;
      continue;
    }
    flush_garbage();
    const size_t start = pos;
    AttemptResult attempt = TryFrame(s, n, start, escaped, max_frame);
    switch (attempt.attempt) {
      case Attempt::kGood: {
        Report report;
        report.is_frame = true;
        report.offset = start;
        report.size = attempt.data.size();
        report.raw_end = attempt.end;
        report.data = std::move(attempt.data);
        reports.push_back(std::move(report));
        pos = attempt.end;
        break;
      }
      case Attempt::kBad:
        error(attempt.error, start, attempt.end);
        // Mode 2 frames cannot contain a delimiter: nothing to rescan.
        pos = escaped ? attempt.end : start + 1;
        break;
      case Attempt::kIncomplete:
        error(FrameError::kTruncated, start, n);
        pos = escaped ? n : start + 1;
        break;
    }
  }
  flush_garbage();
  return reports;
}

// --- Checks -------------------------------------------------------------------

void CheckFrame(const Report& frame, const uint8_t* stream, size_t n, ApiMode mode,
                size_t max_frame) {
  if (frame.size == 0 || frame.size > max_frame)
    Violation("frame size out of range", mode, max_frame);
  const Bytes encoded = roomfix::radio::EncodeFrame(frame.data.data(), frame.data.size(), mode);
  if (mode == ApiMode::kUnescaped &&
      (frame.offset + encoded.size() > n ||
       std::memcmp(stream + frame.offset, encoded.data(), encoded.size()) != 0)) {
    Violation("mode-1 frame differs from its encoding", mode, max_frame);
  }
  FrameDecoder decoder(Options(mode, max_frame));
  RecordingSink sink;
  decoder.Feed(encoded.data(), encoded.size(), &sink);
  decoder.FlushPartial(&sink);
  if (sink.reports.size() != 1 || !sink.reports[0].is_frame || sink.reports[0].offset != 0 ||
      sink.reports[0].data != frame.data) {
    Violation("re-encoded frame does not decode to the same frame data", mode, max_frame);
  }

  roomfix::radio::ReceivePacket packet;
  const roomfix::radio::PacketParse parse =
      roomfix::radio::ParseReceivePacket(frame.data.data(), frame.data.size(), &packet);
  const uint8_t type = frame.data[0];
  const bool receive = type == 0x80 || type == 0x81 || type == 0x90;
  switch (parse) {
    case roomfix::radio::PacketParse::kOk:
      if (!receive) Violation("parsed a non-receive frame", mode, max_frame);
      if (roomfix::radio::EncodeReceivePacket(packet) != frame.data) {
        Violation("EncodeReceivePacket is not the inverse of ParseReceivePacket", mode, max_frame);
      }
      break;
    case roomfix::radio::PacketParse::kOtherFrameType:
      if (receive) Violation("receive frame called another type", mode, max_frame);
      break;
    case roomfix::radio::PacketParse::kTooShort:
      if (!receive) Violation("non-receive frame called too short", mode, max_frame);
      break;
  }
}

void CheckConfiguration(const uint8_t* data, size_t size, ApiMode mode, size_t max_frame) {
  const FrameDecoderOptions options = Options(mode, max_frame);
  const RecordingSink whole = DecodeInChunks(data, size, options, [size](size_t) { return size; });
  const RecordingSink bytewise =
      DecodeInChunks(data, size, options, [](size_t) { return size_t{1}; });
  // Chunk k takes its size from the stream read backwards: mostly short
  // chunks, now and then up to 128 bytes.
  const RecordingSink chunked = DecodeInChunks(data, size, options, [data, size](size_t k) {
    const uint8_t b = data[size - 1 - k % size];
    return static_cast<size_t>((b & 0x80) != 0 ? (b & 0x7F) + 1 : (b & 0x07) + 1);
  });
  if (bytewise.reports != whole.reports || bytewise.details != whole.details) {
    Violation("byte-at-a-time feeding changed the reports", mode, max_frame);
  }
  if (chunked.reports != whole.reports || chunked.details != whole.details) {
    Violation("chunked feeding changed the reports", mode, max_frame);
  }

  const std::vector<Report> reference = ReferenceDecode(data, size, mode, max_frame);
  if (reference != whole.reports) Violation("differs from the reference decoder", mode, max_frame);

  // Order, overlap and coverage, on the reference's raw extents (equal
  // reports, and it knows where mode-2 frames end).
  uint64_t next_uncovered = 0;  // every byte before it is in a frame or an error
  uint64_t error_end = 0;
  for (size_t i = 0; i < reference.size(); ++i) {
    const Report& r = reference[i];
    if (i > 0 && r.offset <= reference[i - 1].offset)
      Violation("reports out of order", mode, max_frame);
    if (r.offset > next_uncovered) Violation("bytes in no frame and no error", mode, max_frame);
    if (!r.is_frame) {
      if (r.size == 0) Violation("empty error", mode, max_frame);
      if (r.offset < error_end) Violation("errors overlap", mode, max_frame);
      error_end = r.raw_end;
    }
    next_uncovered = std::max<uint64_t>(next_uncovered, r.raw_end);
  }
  if (next_uncovered != size) Violation("stream end not covered", mode, max_frame);

  for (const Report& r : whole.reports) {
    if (r.is_frame) CheckFrame(r, data, size, mode, max_frame);
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  const size_t small_max = 1 + data[0] % 32;
  for (ApiMode mode : {ApiMode::kUnescaped, ApiMode::kEscaped}) {
    CheckConfiguration(data, size, mode, 300);
    CheckConfiguration(data, size, mode, small_max);
  }
  return 0;
}
