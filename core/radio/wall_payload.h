#ifndef ROOMFIX_CORE_RADIO_WALL_PAYLOAD_H_
#define ROOMFIX_CORE_RADIO_WALL_PAYLOAD_H_

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace roomfix::radio {

// The payload the beacon and the wall receivers put inside XBee receive
// frames (docs/radio_protocol.md has the byte tables). All multi-byte fields
// are big-endian, like the XBee frame around them.
//
// Firing announcement (beacon -> everyone), 10 bytes:
//   0     version (1)
//   1     type 0x01
//   2     beacon id (1..255)
//   3-4   firing sequence number, uint16, +1 per firing, wraps 65535 -> 0
//   5-6   beacon temperature, int16, 0.01 degC (0x8000: not measured)
//   7     status flags
//   8-9   CRC-16/CCITT-FALSE of bytes 0-7
//
// Range report (receiver -> coordinator), 14 bytes:
//   0     version (1)
//   1     type 0x02
//   2     beacon id the report answers
//   3-4   firing sequence number the report answers
//   5-8   time of flight, uint32, nanoseconds (1 ns resolution; 0 with
//         kFlagNoEcho when nothing was heard)
//   9-10  receiver temperature, int16, 0.01 degC (0x8000: not measured)
//   11    status flags
//   12-13 CRC-16/CCITT-FALSE of bytes 0-11
//
// The receiver is identified by the frame's source address, not by the
// payload, so a report can only claim to be from the module that sent it.
//
// Why a CRC when the XBee frame has a checksum: the frame checksum is an
// 8-bit sum, which passes 1 in 256 random corruptions of the serial line and
// misses any pair of errors that cancel. A corrupted firing number that slips
// through would put a range into another firing's set, the exact failure that
// sank the reference; the 16-bit CRC makes that about 1 in 65536 of the
// frames that already passed the checksum.

inline constexpr uint8_t kPayloadVersion = 1;

enum class PayloadType : uint8_t {
  kFiring = 0x01,
  kRangeReport = 0x02,
};

inline constexpr size_t kFiringPayloadBytes = 10;
inline constexpr size_t kRangeReportPayloadBytes = 14;

// Status flags (bit field). Unknown bits are ignored, so a newer firmware
// can add flags without breaking an older bridge.
inline constexpr uint8_t kFlagWeakEcho = 0x01;  // echo amplitude below the detector's margin
inline constexpr uint8_t kFlagNoEcho = 0x02;    // the timer ran out: no time of flight
inline constexpr uint8_t kFlagLowBattery = 0x04;
inline constexpr uint8_t kFlagSensorFault = 0x08;  // temperature sensor failed its self-test

// Sentinel for "no temperature reading".
inline constexpr int16_t kNoTemperature = INT16_MIN;

struct WallMessage {
  PayloadType type = PayloadType::kRangeReport;
  uint8_t beacon_id = 0;
  uint16_t firing_seq = 0;
  // Range reports only.
  uint32_t time_of_flight_ns = 0;
  int16_t temperature_centi_c = kNoTemperature;
  uint8_t flags = 0;

  bool has_temperature() const { return temperature_centi_c != kNoTemperature; }
  double temperature_c() const { return temperature_centi_c * 0.01; }
};

enum class PayloadError {
  kOk,
  kEmpty,
  kUnsupportedVersion,
  kUnknownType,
  // Length does not match the type's fixed size.
  kBadLength,
  kBadCrc,
  // A beacon id of 0 (reserved).
  kBadBeaconId,
};

// Lower-case reason for counters ("bad_crc", ...).
const char* PayloadErrorName(PayloadError error);

// Decodes a payload. On any error *message is left unspecified and *detail
// (when given) gets one line saying what was wrong.
PayloadError DecodeWallMessage(const uint8_t* data, size_t size, WallMessage* message,
                               std::string* detail = nullptr);

// Encodes a message (the virtual devices and tests use it; a real
// receiver's firmware would do the same).
std::vector<uint8_t> EncodeWallMessage(const WallMessage& message);

// CRC-16/CCITT-FALSE: polynomial 0x1021, initial value 0xFFFF, no
// reflection, no final XOR; check value 0x29B1 for "123456789".
uint16_t Crc16CcittFalse(const uint8_t* data, size_t size);

// Rounds a time of flight in seconds to the wire's nanoseconds, saturating
// at the field's range.
uint32_t TimeOfFlightToNs(double time_of_flight_s);
// Rounds a temperature to the wire's 0.01 degC, saturating short of the
// "no reading" sentinel; NaN becomes the sentinel.
int16_t TemperatureToCentiC(double temperature_c);

}  // namespace roomfix::radio

#endif  // ROOMFIX_CORE_RADIO_WALL_PAYLOAD_H_
