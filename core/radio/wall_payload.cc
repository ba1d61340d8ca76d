#include "core/radio/wall_payload.h"

#include <fmt/format.h>

#include <array>
#include <climits>
#include <cmath>

namespace roomfix::radio {
namespace {

// Table-driven CRC: one lookup per byte instead of eight shifts.
constexpr std::array<uint16_t, 256> MakeCrcTable() {
  std::array<uint16_t, 256> table{};
  for (int i = 0; i < 256; ++i) {
    uint16_t crc = static_cast<uint16_t>(i << 8);
    for (int bit = 0; bit < 8; ++bit) {
      crc = (crc & 0x8000) ? static_cast<uint16_t>((crc << 1) ^ 0x1021)
                           : static_cast<uint16_t>(crc << 1);
    }
    table[i] = crc;
  }
  return table;
}
constexpr std::array<uint16_t, 256> kCrcTable = MakeCrcTable();

uint16_t Get16(const uint8_t* p) { return static_cast<uint16_t>((p[0] << 8) | p[1]); }
uint32_t Get32(const uint8_t* p) {
  return (static_cast<uint32_t>(p[0]) << 24) | (static_cast<uint32_t>(p[1]) << 16) |
         (static_cast<uint32_t>(p[2]) << 8) | p[3];
}
void Put16(uint16_t v, std::vector<uint8_t>* out) {
  out->push_back(static_cast<uint8_t>(v >> 8));
  out->push_back(static_cast<uint8_t>(v));
}
void Put32(uint32_t v, std::vector<uint8_t>* out) {
  Put16(static_cast<uint16_t>(v >> 16), out);
  Put16(static_cast<uint16_t>(v), out);
}

PayloadError Fail(PayloadError error, std::string* detail, const std::string& text) {
  if (detail != nullptr) *detail = text;
  return error;
}

}  // namespace

const char* PayloadErrorName(PayloadError error) {
  switch (error) {
    case PayloadError::kOk:
      return "ok";
    case PayloadError::kEmpty:
      return "empty_payload";
    case PayloadError::kUnsupportedVersion:
      return "unsupported_version";
    case PayloadError::kUnknownType:
      return "unknown_message_type";
    case PayloadError::kBadLength:
      return "bad_payload_length";
    case PayloadError::kBadCrc:
      return "bad_crc";
    case PayloadError::kBadBeaconId:
      return "bad_beacon_id";
  }
  return "unknown";
}

uint16_t Crc16CcittFalse(const uint8_t* data, size_t size) {
  uint16_t crc = 0xFFFF;
  for (size_t i = 0; i < size; ++i) {
    crc = static_cast<uint16_t>((crc << 8) ^ kCrcTable[((crc >> 8) ^ data[i]) & 0xFF]);
  }
  return crc;
}

PayloadError DecodeWallMessage(const uint8_t* data, size_t size, WallMessage* message,
                               std::string* detail) {
  if (size == 0) return Fail(PayloadError::kEmpty, detail, "empty payload");
  if (data[0] != kPayloadVersion) {
    return Fail(PayloadError::kUnsupportedVersion, detail,
                "payload version " + std::to_string(data[0]) + ", this bridge reads version " +
                    std::to_string(kPayloadVersion));
  }
  if (size < 2) return Fail(PayloadError::kBadLength, detail, "payload of 1 byte has no type");
  size_t expected = 0;
  if (data[1] == static_cast<uint8_t>(PayloadType::kFiring)) {
    expected = kFiringPayloadBytes;
  } else if (data[1] == static_cast<uint8_t>(PayloadType::kRangeReport)) {
    expected = kRangeReportPayloadBytes;
  } else {
    return Fail(PayloadError::kUnknownType, detail,
                fmt::format("unknown message type 0x{:02X}", data[1]));
  }
  if (size != expected) {
    return Fail(PayloadError::kBadLength, detail,
                fmt::format("message type 0x{:02X} is {} bytes, got {}", data[1], expected, size));
  }
  const uint16_t crc = Crc16CcittFalse(data, size - 2);
  const uint16_t sent = Get16(data + size - 2);
  if (crc != sent) {
    return Fail(PayloadError::kBadCrc, detail,
                fmt::format("CRC 0x{:04X}, computed 0x{:04X}", sent, crc));
  }
  if (data[2] == 0) return Fail(PayloadError::kBadBeaconId, detail, "beacon id 0 is reserved");

  WallMessage m;
  m.type = static_cast<PayloadType>(data[1]);
  m.beacon_id = data[2];
  m.firing_seq = Get16(data + 3);
  if (m.type == PayloadType::kFiring) {
    m.temperature_centi_c = static_cast<int16_t>(Get16(data + 5));
    m.flags = data[7];
  } else {
    m.time_of_flight_ns = Get32(data + 5);
    m.temperature_centi_c = static_cast<int16_t>(Get16(data + 9));
    m.flags = data[11];
  }
  *message = m;
  return PayloadError::kOk;
}

std::vector<uint8_t> EncodeWallMessage(const WallMessage& message) {
  std::vector<uint8_t> out;
  out.reserve(kRangeReportPayloadBytes);
  out.push_back(kPayloadVersion);
  out.push_back(static_cast<uint8_t>(message.type));
  out.push_back(message.beacon_id);
  Put16(message.firing_seq, &out);
  if (message.type == PayloadType::kRangeReport) Put32(message.time_of_flight_ns, &out);
  Put16(static_cast<uint16_t>(message.temperature_centi_c), &out);
  out.push_back(message.flags);
  Put16(Crc16CcittFalse(out.data(), out.size()), &out);
  return out;
}

uint32_t TimeOfFlightToNs(double time_of_flight_s) {
  const double ns = std::round(time_of_flight_s * 1e9);
  if (!(ns > 0.0)) return 0;
  if (ns >= static_cast<double>(UINT32_MAX)) return UINT32_MAX;
  return static_cast<uint32_t>(ns);
}

int16_t TemperatureToCentiC(double temperature_c) {
  if (std::isnan(temperature_c)) return kNoTemperature;
  const double centi = std::round(temperature_c * 100.0);
  if (centi <= INT16_MIN) return INT16_MIN + 1;
  if (centi > INT16_MAX) return INT16_MAX;
  return static_cast<int16_t>(centi);
}

}  // namespace roomfix::radio
