// roomfix frames decode: an XBee API byte stream in, one JSON line per frame
// and per error out.
#include <fcntl.h>
#include <fmt/format.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <cctype>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "core/radio/wall_payload.h"
#include "core/radio/xbee_frame.h"
#include "core/world/site.h"
#include "tools/commands.h"

namespace roomfix {
namespace {

using json = nlohmann::ordered_json;

struct FramesOptions {
  std::string input = "-";
  int api_mode = 2;
  bool hex = false;
};

std::string Hex(const uint8_t* data, size_t size) {
  static const char kDigits[] = "0123456789ABCDEF";
  std::string out;
  out.reserve(size * 2);
  for (size_t i = 0; i < size; ++i) {
    out.push_back(kDigits[data[i] >> 4]);
    out.push_back(kDigits[data[i] & 0xF]);
  }
  return out;
}

std::string HexByte(unsigned value, int digits) { return fmt::format("0x{:0{}X}", value, digits); }

const char* FrameTypeName(uint8_t type) {
  switch (type) {
    case radio::kZigbeeRxFrameType:
      return "zigbee_receive_packet";
    case radio::kRx64FrameType:
      return "rx_64bit_address";
    case radio::kRx16FrameType:
      return "rx_16bit_address";
    case 0x88:
      return "at_command_response";
    case 0x8A:
      return "modem_status";
    case 0x8B:
      return "transmit_status";
    default:
      return "other";
  }
}

json DescribePayload(const std::vector<uint8_t>& payload) {
  radio::WallMessage m;
  std::string detail;
  const radio::PayloadError error =
      radio::DecodeWallMessage(payload.data(), payload.size(), &m, &detail);
  if (error != radio::PayloadError::kOk) {
    return {{"error", radio::PayloadErrorName(error)}, {"detail", detail}};
  }
  json out = {{"type", m.type == radio::PayloadType::kFiring ? "firing" : "range_report"},
              {"beacon_id", m.beacon_id},
              {"firing_seq", m.firing_seq}};
  if (m.type == radio::PayloadType::kRangeReport) {
    out["time_of_flight_ns"] = m.time_of_flight_ns;
  }
  out["temperature_c"] = m.has_temperature() ? json(m.temperature_c()) : json(nullptr);
  json flags = json::array();
  if (m.flags & radio::kFlagWeakEcho) flags.push_back("weak_echo");
  if (m.flags & radio::kFlagNoEcho) flags.push_back("no_echo");
  if (m.flags & radio::kFlagLowBattery) flags.push_back("low_battery");
  if (m.flags & radio::kFlagSensorFault) flags.push_back("sensor_fault");
  out["flags"] = flags;
  return out;
}

// Prints each frame and error as it is decoded.
class JsonLines : public radio::FrameSink {
 public:
  void OnFrame(const uint8_t* data, size_t size, uint64_t offset) override {
    ++frames;
    json line = {
        {"offset", offset}, {"type", HexByte(data[0], 2)}, {"type_name", FrameTypeName(data[0])}};
    radio::ReceivePacket p;
    const radio::PacketParse parse = radio::ParseReceivePacket(data, size, &p);
    if (parse == radio::PacketParse::kOk) {
      if (p.has_address64) line["address64"] = FormatRadioAddress(p.address64);
      if (p.has_address16) line["address16"] = HexByte(p.address16, 4);
      line["options"] = HexByte(p.options, 2);
      if (p.has_rssi) line["rssi_dbm"] = p.rssi_dbm;
      line["payload_hex"] = Hex(p.payload.data(), p.payload.size());
      line["roomfix"] = DescribePayload(p.payload);
    } else {
      if (parse == radio::PacketParse::kTooShort) line["error"] = "short_frame";
      line["frame_hex"] = Hex(data, size);
    }
    std::cout << line.dump() << "\n";
  }
  void OnFrameError(const radio::FrameErrorInfo& e) override {
    ++errors;
    json line = {{"offset", e.stream_offset},
                 {"error", radio::FrameErrorName(e.error)},
                 {"bytes", e.size_bytes},
                 {"detail", e.detail}};
    std::cout << line.dump() << "\n";
  }
  int64_t frames = 0;
  int64_t errors = 0;
};

// Hex text to bytes: pairs of hex digits, with any whitespace, commas,
// colons and "0x" prefixes between them. Returns false with the position
// of the first character that is none of these.
bool ParseHexText(const std::string& text, std::vector<uint8_t>* out, std::string* error) {
  int high = -1;
  for (size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (c == '0' && i + 1 < text.size() && (text[i + 1] == 'x' || text[i + 1] == 'X') && high < 0) {
      ++i;
      continue;
    }
    if (std::isspace(static_cast<unsigned char>(c)) || c == ',' || c == ':') {
      if (high >= 0) {
        *error = "hex digit without its pair before character " + std::to_string(i);
        return false;
      }
      continue;
    }
    if (!std::isxdigit(static_cast<unsigned char>(c))) {
      *error = std::string("not a hex digit at character ") + std::to_string(i) + ": '" + c + "'";
      return false;
    }
    const int v = std::isdigit(static_cast<unsigned char>(c))
                      ? c - '0'
                      : std::tolower(static_cast<unsigned char>(c)) - 'a' + 10;
    if (high < 0) {
      high = v;
    } else {
      out->push_back(static_cast<uint8_t>(high << 4 | v));
      high = -1;
    }
  }
  if (high >= 0) {
    *error = "odd number of hex digits";
    return false;
  }
  return true;
}

int RunDecode(const FramesOptions& options) {
  int fd = 0;
  if (options.input != "-") {
    fd = ::open(options.input.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) {
      std::cerr << "roomfix frames decode: cannot read " << options.input << ": "
                << std::strerror(errno) << "\n";
      return 1;
    }
  }
  radio::FrameDecoderOptions decoder_options;
  decoder_options.mode =
      options.api_mode == 1 ? radio::ApiMode::kUnescaped : radio::ApiMode::kEscaped;
  radio::FrameDecoder decoder(decoder_options);
  JsonLines sink;
  std::vector<uint8_t> bytes;
  std::string pending_text;
  int64_t line_number = 0;
  std::vector<char> buffer(1 << 16);
  // read(2), not an istream: on a pipe from a live port it returns what has
  // arrived instead of waiting for a full buffer, so each frame is printed
  // as it comes.
  while (true) {
    const ssize_t n = ::read(fd, buffer.data(), buffer.size());
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) {
      std::cerr << "roomfix frames decode: read failed: " << std::strerror(errno) << "\n";
      break;
    }
    if (n == 0) break;
    if (!options.hex) {
      decoder.Feed(reinterpret_cast<const uint8_t*>(buffer.data()), static_cast<size_t>(n), &sink);
    } else {
      pending_text.append(buffer.data(), static_cast<size_t>(n));
      size_t end;
      while ((end = pending_text.find('\n')) != std::string::npos) {
        ++line_number;
        bytes.clear();
        std::string error;
        if (!ParseHexText(pending_text.substr(0, end), &bytes, &error)) {
          std::cerr << "roomfix frames decode: line " << line_number << ": " << error << "\n";
          if (fd != 0) ::close(fd);
          return 2;
        }
        decoder.Feed(bytes.data(), bytes.size(), &sink);
        pending_text.erase(0, end + 1);
      }
    }
    std::cout.flush();
  }
  if (options.hex && !pending_text.empty()) {
    ++line_number;
    bytes.clear();
    std::string error;
    if (!ParseHexText(pending_text, &bytes, &error)) {
      std::cerr << "roomfix frames decode: line " << line_number << ": " << error << "\n";
      if (fd != 0) ::close(fd);
      return 2;
    }
    decoder.Feed(bytes.data(), bytes.size(), &sink);
  }
  if (fd != 0) ::close(fd);
  // The stream ended: a frame still open was cut short.
  decoder.FlushPartial(&sink);
  std::cout.flush();
  std::cerr << "roomfix frames decode: " << decoder.bytes_fed() << " bytes, " << sink.frames
            << " frames, " << sink.errors << " errors\n";
  return 0;
}

}  // namespace

void AddFramesCommand(CLI::App* app, int* exit_code) {
  auto* frames = app->add_subcommand("frames", "XBee API frames");
  frames->require_subcommand(1);
  auto options = std::make_shared<FramesOptions>();
  auto* decode = frames->add_subcommand(
      "decode",
      "Decode a byte stream from a coordinator: one JSON line per frame (type, addresses, "
      "options, RSSI, payload, the roomfix payload decoded) and per error (offset, reason)");
  decode->add_option("input", options->input, "File to read, or - for stdin")
      ->capture_default_str();
  decode->add_option("--api-mode", options->api_mode, "1 (unescaped) or 2 (escaped)")
      ->capture_default_str()
      ->check(CLI::IsMember({1, 2}));
  decode->add_flag("--hex", options->hex,
                   "The input is hex text (\"7E 00 12 90 ...\"), not binary");
  decode->callback([options, exit_code] { *exit_code = RunDecode(*options); });
}

}  // namespace roomfix
