#include "core/radio/device_config.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <iterator>
#include <sstream>

#include "core/radio/wall_payload.h"
#include "core/world/air_model.h"
#include "core/world/ultrasound_model.h"

namespace roomfix::radio {
namespace {

void PutU16(uint8_t* out, uint32_t value) {
  out[0] = static_cast<uint8_t>(value >> 8);
  out[1] = static_cast<uint8_t>(value);
}

void PutU32(uint8_t* out, uint32_t value) {
  PutU16(out, value >> 16);
  PutU16(out + 2, value & 0xFFFFu);
}

void PutU64(uint8_t* out, uint64_t value) {
  PutU32(out, static_cast<uint32_t>(value >> 32));
  PutU32(out + 4, static_cast<uint32_t>(value));
}

uint16_t GetU16(const uint8_t* in) { return static_cast<uint16_t>((in[0] << 8) | in[1]); }

uint32_t GetU32(const uint8_t* in) {
  return (static_cast<uint32_t>(GetU16(in)) << 16) | GetU16(in + 2);
}

uint64_t GetU64(const uint8_t* in) {
  return (static_cast<uint64_t>(GetU32(in)) << 32) | GetU32(in + 4);
}

bool Fail(std::string* error, const std::string& text) {
  if (error) *error = text;
  return false;
}

}  // namespace

bool DeviceConfig::IsValid(std::string* error) const {
  if (role != DeviceRole::kBeacon && role != DeviceRole::kReceiver) {
    return Fail(error, "role must be beacon (1) or receiver (2)");
  }
  if (id == 0) return Fail(error, "id must be 1..255");
  if (burst_cycles == 0 || burst_cycles > kMaxBurstCycles) {
    return Fail(error, "burst_cycles must be 1.." + std::to_string(kMaxBurstCycles));
  }
  if (window_close_us <= window_open_us || window_close_us > kMaxWindowUs) {
    return Fail(error, "the window must close after it opens and by " +
                           std::to_string(kMaxWindowUs) + " us");
  }
  if (sound_speed_mm_s == 0) return Fail(error, "sound_speed_mm_s must be positive");
  // Same integer arithmetic as the firmware: cm x 10^4 / (mm/s) = us.
  const uint32_t flight_us = static_cast<uint32_t>(max_range_cm) * 10000u / sound_speed_mm_s;
  if (role == DeviceRole::kReceiver && window_close_us < flight_us) {
    return Fail(error, "the window (" + std::to_string(window_close_us) +
                           " us) is shorter than the longest flight (" + std::to_string(flight_us) +
                           " us)");
  }
  if (role != DeviceRole::kBeacon) return true;
  if (slot_count == 0 || slot_count > kDeviceMaxSlots || slot_index >= slot_count) {
    return Fail(error, "slot_index must be below slot_count, at most " +
                           std::to_string(kDeviceMaxSlots) + " slots");
  }
  if (slot_beacon_ids[slot_index] != id) {
    return Fail(error, "the slot table does not give this beacon its own slot");
  }
  if (fire_delay_us < kMinFireDelayUs || fire_delay_us > kMaxFireDelayUs) {
    return Fail(error, "fire_delay_us must be " + std::to_string(kMinFireDelayUs) + ".." +
                           std::to_string(kMaxFireDelayUs));
  }
  if (slot_us == 0 || frame_us < static_cast<uint64_t>(slot_count) * slot_us) {
    return Fail(error, "frame_us must hold slot_count slots");
  }
  if (frame_us < 10000 || frame_us > 60000000) {
    return Fail(error, "frame_us must be 10 ms .. 60 s");
  }
  return true;
}

std::vector<uint8_t> EncodeDeviceConfig(const DeviceConfig& c) {
  std::vector<uint8_t> out(kDeviceConfigBytes, 0);
  uint8_t* p = out.data();
  p[0] = kDeviceConfigMagic0;
  p[1] = kDeviceConfigMagic1;
  p[2] = kDeviceConfigLayoutVersion;
  p[3] = static_cast<uint8_t>(c.role);
  p[4] = c.id;
  p[5] = c.flags;
  PutU64(p + 6, c.own_address);
  PutU64(p + 14, c.coordinator_address);
  p[22] = c.slot_index;
  p[23] = c.slot_count;
  PutU32(p + 24, c.slot_us);
  PutU32(p + 28, c.frame_us);
  PutU16(p + 32, c.fire_delay_us);
  p[34] = c.burst_cycles;
  PutU16(p + 36, c.radio_latency_us);
  PutU32(p + 38, c.window_open_us);
  PutU32(p + 42, c.window_close_us);
  PutU16(p + 46, c.report_delay_us);
  PutU32(p + 48, static_cast<uint32_t>(c.tof_offset_ns));
  PutU32(p + 52, c.sound_speed_mm_s);
  PutU16(p + 56, c.max_range_cm);
  std::copy(c.slot_beacon_ids.begin(), c.slot_beacon_ids.end(), p + 58);
  PutU16(p + kDeviceConfigBytes - 2, Crc16CcittFalse(p, kDeviceConfigBytes - 2));
  return out;
}

bool DecodeDeviceConfig(const uint8_t* data, size_t size, DeviceConfig* c, std::string* error) {
  if (size < kDeviceConfigBytes) {
    return Fail(error, "image of " + std::to_string(size) + " bytes, expected " +
                           std::to_string(kDeviceConfigBytes));
  }
  if (data[0] != kDeviceConfigMagic0 || data[1] != kDeviceConfigMagic1) {
    return Fail(error, "no configuration (magic bytes are not \"RF\")");
  }
  const uint16_t crc = Crc16CcittFalse(data, kDeviceConfigBytes - 2);
  if (crc != GetU16(data + kDeviceConfigBytes - 2)) {
    return Fail(error, fmt::format("CRC 0x{:04X}, the image says 0x{:04X}", crc,
                                   GetU16(data + kDeviceConfigBytes - 2)));
  }
  if (data[2] != kDeviceConfigLayoutVersion) {
    return Fail(error, "layout version " + std::to_string(data[2]) + ", this reads " +
                           std::to_string(kDeviceConfigLayoutVersion));
  }
  c->role = static_cast<DeviceRole>(data[3]);
  c->id = data[4];
  c->flags = data[5];
  c->own_address = GetU64(data + 6);
  c->coordinator_address = GetU64(data + 14);
  c->slot_index = data[22];
  c->slot_count = data[23];
  c->slot_us = GetU32(data + 24);
  c->frame_us = GetU32(data + 28);
  c->fire_delay_us = GetU16(data + 32);
  c->burst_cycles = data[34];
  c->radio_latency_us = GetU16(data + 36);
  c->window_open_us = GetU32(data + 38);
  c->window_close_us = GetU32(data + 42);
  c->report_delay_us = GetU16(data + 46);
  c->tof_offset_ns = static_cast<int32_t>(GetU32(data + 48));
  c->sound_speed_mm_s = GetU32(data + 52);
  c->max_range_cm = GetU16(data + 56);
  std::copy(data + 58, data + 58 + kDeviceMaxSlots, c->slot_beacon_ids.begin());
  return true;
}

size_t AirFrameBytes(size_t payload_bytes) { return 5 + 1 + 2 + 1 + 2 + 2 + 8 + payload_bytes + 2; }

double NominalRadioLatencyUs(size_t payload_bytes, const RadioTimingModel& m) {
  const double uart_byte_us = 10.0 / m.uart_baud * 1e6;
  return m.tx_processing_us + m.cca_us + m.turnaround_us +
         static_cast<double>(AirFrameBytes(payload_bytes)) * m.air_byte_us + m.rx_processing_us +
         uart_byte_us;
}

bool DeviceConfigOptions::IsValid(std::string* error) const {
  if (fire_delay_us < kMinFireDelayUs || fire_delay_us > kMaxFireDelayUs) {
    return Fail(error, "--fire-delay-us must be " + std::to_string(kMinFireDelayUs) + ".." +
                           std::to_string(kMaxFireDelayUs));
  }
  if (burst_cycles == 0 || burst_cycles > kMaxBurstCycles) {
    return Fail(error, "--burst-cycles must be 1.." + std::to_string(kMaxBurstCycles));
  }
  if (!(detector_delay_us >= 0.0 && detector_delay_us <= 1000.0)) {
    return Fail(error, "--detector-delay-us must be 0..1000");
  }
  if (!(min_temperature_c >= -20.0 && min_temperature_c <= 60.0)) {
    return Fail(error, "--min-temperature must be -20..60 degC");
  }
  if (!(rate_hz > 0.0 && rate_hz <= 100.0)) return Fail(error, "--rate-hz must be in (0, 100]");
  if (report_spacing_us > 20000) return Fail(error, "--report-spacing-us must be at most 20000");
  if (!(radio_latency_us >= 0.0 && radio_latency_us <= 10000.0)) {
    return Fail(error, "--radio-latency-us must be 0 (nominal) .. 10000");
  }
  return true;
}

namespace {

// The timing every device of the site shares.
struct SiteTiming {
  uint32_t slot_us = 0;
  uint32_t frame_us = 0;
  uint16_t latency_us = 0;
  uint32_t window_open_us = 0;
  uint32_t window_close_us = 0;
  int32_t tof_offset_ns = 0;
  uint32_t sound_speed_mm_s = 0;
  uint16_t max_range_cm = 0;
};

SiteTiming ComputeSiteTiming(const Site& site, const DeviceConfigOptions& o) {
  SiteTiming t;
  const RoomDecay decay = ComputeRoomDecay(site, o.min_temperature_c);
  const double c_min = SpeedOfSound(o.min_temperature_c);
  const size_t n = std::max<size_t>(1, site.beacons.size());
  t.slot_us = static_cast<uint32_t>(std::ceil(decay.slot_s * 1e6));
  t.frame_us = std::max(static_cast<uint32_t>(n) * t.slot_us,
                        static_cast<uint32_t>(std::ceil(1e6 / o.rate_hz)));
  const double latency_us = o.radio_latency_us > 0.0
                                ? o.radio_latency_us
                                : NominalRadioLatencyUs(kFiringPayloadBytes, o.radio);
  t.latency_us = static_cast<uint16_t>(std::lround(latency_us));
  // From the receiver's stamp to the pulse leaving the beacon.
  const double pulse_after_stamp_us = static_cast<double>(o.fire_delay_us) - t.latency_us;
  // Open half a millisecond before the pulse can have left (earlier edges are
  // the tail of something else); close after the longest flight at the
  // slowest sound, the detector, and 5 ms (1.7 m) of reflected detours, as
  // the simulator's listening time does.
  t.window_open_us = static_cast<uint32_t>(std::max(0.0, pulse_after_stamp_us - 500.0));
  const double flight_us = decay.max_range_m / c_min * 1e6;
  t.window_close_us = static_cast<uint32_t>(
      std::ceil(std::max(0.0, pulse_after_stamp_us) + flight_us + o.detector_delay_us + 5000.0));
  t.tof_offset_ns =
      static_cast<int32_t>(std::lround((pulse_after_stamp_us + o.detector_delay_us) * 1000.0));
  t.sound_speed_mm_s = static_cast<uint32_t>(std::floor(c_min * 1000.0));
  t.max_range_cm = static_cast<uint16_t>(std::ceil(decay.max_range_m * 100.0));
  return t;
}

}  // namespace

bool DeviceConfigsForSite(const Site& site, const DeviceConfigOptions& o,
                          std::vector<DeviceImage>* images, std::string* error) {
  if (!o.IsValid(error)) return false;
  if (site.beacons.size() > kDeviceMaxSlots) {
    return Fail(error, "the site has " + std::to_string(site.beacons.size()) +
                           " beacons; the firmware's table holds " +
                           std::to_string(kDeviceMaxSlots));
  }
  const SiteTiming t = ComputeSiteTiming(site, o);
  // Every receiver must have reported before the next announcement goes on
  // the air, or that announcement's CCA finds the channel busy and backs off
  // (a random delay the receivers cannot see: a wrong range).
  const uint64_t busy_us = t.latency_us + t.window_close_us +
                           static_cast<uint64_t>(site.receivers.size()) * o.report_spacing_us;
  const uint32_t period_us = site.beacons.size() > 1 ? t.slot_us : t.frame_us;
  if (busy_us > period_us) {
    return Fail(error, "a firing keeps the radio busy for " + std::to_string(busy_us) +
                           " us (latency, window, " + std::to_string(site.receivers.size()) +
                           " reports), longer than the " + std::to_string(period_us) +
                           " us until the next announcement: lower --report-spacing-us or "
                           "--rate-hz, or raise acoustics.clock_uncertainty_s");
  }
  DeviceConfig common;
  common.coordinator_address = o.coordinator_address;
  common.slot_count = static_cast<uint8_t>(std::max<size_t>(1, site.beacons.size()));
  common.slot_us = t.slot_us;
  common.frame_us = t.frame_us;
  common.fire_delay_us = static_cast<uint16_t>(o.fire_delay_us);
  common.burst_cycles = o.burst_cycles;
  common.radio_latency_us = t.latency_us;
  common.window_open_us = t.window_open_us;
  common.window_close_us = t.window_close_us;
  common.tof_offset_ns = t.tof_offset_ns;
  common.sound_speed_mm_s = t.sound_speed_mm_s;
  common.max_range_cm = t.max_range_cm;
  for (size_t i = 0; i < site.beacons.size(); ++i) {
    if (site.beacons[i].id < 1 || site.beacons[i].id > 255) {
      return Fail(error, "beacon id " + std::to_string(site.beacons[i].id) +
                             " does not fit the payload's byte (1..255)");
    }
    common.slot_beacon_ids[i] = static_cast<uint8_t>(site.beacons[i].id);
  }
  images->clear();
  for (size_t i = 0; i < site.beacons.size(); ++i) {
    DeviceImage image{"beacon-" + std::to_string(site.beacons[i].id), common};
    image.config.role = DeviceRole::kBeacon;
    image.config.id = static_cast<uint8_t>(site.beacons[i].id);
    image.config.own_address = site.beacons[i].address;
    image.config.slot_index = static_cast<uint8_t>(i);
    images->push_back(image);
  }
  for (size_t i = 0; i < site.receivers.size(); ++i) {
    const Receiver& r = site.receivers[i];
    if (r.id < 1 || r.id > 255) {
      return Fail(error, "receiver id " + std::to_string(r.id) + " must be 1..255 for its EEPROM");
    }
    DeviceImage image{"receiver-" + std::to_string(r.id), common};
    image.config.role = DeviceRole::kReceiver;
    image.config.id = static_cast<uint8_t>(r.id);
    image.config.own_address = r.address;
    image.config.report_delay_us = static_cast<uint16_t>(i * o.report_spacing_us);
    images->push_back(image);
  }
  for (const DeviceImage& image : *images) {
    std::string why;
    if (!image.config.IsValid(&why)) return Fail(error, image.name + ": " + why);
  }
  return true;
}

std::string EncodeIntelHex(const std::vector<uint8_t>& data, uint16_t address) {
  std::string text;
  auto out = std::back_inserter(text);
  for (size_t at = 0; at < data.size(); at += 16) {
    const size_t n = std::min<size_t>(16, data.size() - at);
    const uint16_t where = static_cast<uint16_t>(address + at);
    unsigned sum = static_cast<unsigned>(n + (where >> 8) + (where & 0xFF));
    fmt::format_to(out, ":{:02X}{:04X}00", n, where);
    for (size_t i = 0; i < n; ++i) {
      fmt::format_to(out, "{:02X}", data[at + i]);
      sum += data[at + i];
    }
    fmt::format_to(out, "{:02X}\n", (0x100 - (sum & 0xFF)) & 0xFF);
  }
  text += ":00000001FF\n";
  return text;
}

namespace {

bool HexByte(const std::string& text, size_t at, uint8_t* value) {
  if (at + 2 > text.size()) return false;
  unsigned v = 0;
  for (size_t i = at; i < at + 2; ++i) {
    const char ch = text[i];
    v <<= 4;
    if (ch >= '0' && ch <= '9') {
      v |= static_cast<unsigned>(ch - '0');
    } else if (ch >= 'A' && ch <= 'F') {
      v |= static_cast<unsigned>(ch - 'A' + 10);
    } else if (ch >= 'a' && ch <= 'f') {
      v |= static_cast<unsigned>(ch - 'a' + 10);
    } else {
      return false;
    }
  }
  *value = static_cast<uint8_t>(v);
  return true;
}

}  // namespace

bool DecodeIntelHex(const std::string& text, std::vector<uint8_t>* data, std::string* error) {
  data->clear();
  std::istringstream in(text);
  std::string line;
  int number = 0;
  bool ended = false;
  while (std::getline(in, line)) {
    ++number;
    while (!line.empty() && (line.back() == '\r' || line.back() == ' ')) line.pop_back();
    if (line.empty()) continue;
    const std::string where = "line " + std::to_string(number) + ": ";
    if (ended) return Fail(error, where + "data after the end-of-file record");
    if (line[0] != ':' || line.size() < 11 || line.size() % 2 == 0) {
      return Fail(error, where + "not an Intel hex record");
    }
    std::vector<uint8_t> bytes((line.size() - 1) / 2);
    for (size_t i = 0; i < bytes.size(); ++i) {
      if (!HexByte(line, 1 + 2 * i, &bytes[i])) return Fail(error, where + "not hexadecimal");
    }
    if (bytes[0] + 5u != bytes.size()) return Fail(error, where + "length does not match");
    unsigned sum = 0;
    for (uint8_t b : bytes) sum += b;
    if ((sum & 0xFF) != 0) return Fail(error, where + "bad checksum");
    const uint8_t type = bytes[3];
    if (type == 0x01) {
      ended = true;
      continue;
    }
    if (type != 0x00)
      return Fail(error, where + "record type " + std::to_string(type) +
                             " (an EEPROM image has data records only)");
    const size_t address = (static_cast<size_t>(bytes[1]) << 8) | bytes[2];
    if (address + bytes[0] > data->size()) data->resize(address + bytes[0], 0xFF);
    std::copy(bytes.begin() + 4, bytes.begin() + 4 + bytes[0], data->begin() + address);
  }
  if (!ended) return Fail(error, "no end-of-file record");
  return true;
}

}  // namespace roomfix::radio
