#ifndef ROOMFIX_CORE_RADIO_DEVICE_CONFIG_H_
#define ROOMFIX_CORE_RADIO_DEVICE_CONFIG_H_

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "core/world/site.h"

namespace roomfix::radio {

// The configuration a beacon or wall receiver reads from its EEPROM at boot
// (firmware/INTERFACE.md has the byte table; docs/devices.md the why).
// `roomfix devices` writes one image per device from the site file, which
// stays the one source of truth; the simulator loads the same images into
// its simulated ATmegas.

inline constexpr size_t kDeviceConfigBytes = 72;
inline constexpr uint8_t kDeviceConfigLayoutVersion = 1;
inline constexpr uint8_t kDeviceConfigMagic0 = 0x52;  // 'R'
inline constexpr uint8_t kDeviceConfigMagic1 = 0x46;  // 'F'
inline constexpr size_t kDeviceMaxSlots = 12;
// One Timer1 wrap at 16 MHz is 4096 us: the burst's first edge is one
// compare match after the announcement's last byte.
inline constexpr uint32_t kMaxFireDelayUs = 4000;
inline constexpr uint32_t kMinFireDelayUs = 100;
inline constexpr uint32_t kMaxWindowUs = 200000;
inline constexpr uint32_t kMaxBurstCycles = 64;

// The device status payload (type 0x03) a device in fault broadcasts once a
// second, and its fault codes.
inline constexpr uint8_t kDeviceStatusType = 0x03;
inline constexpr size_t kDeviceStatusBytes = 8;
enum class DeviceFault : uint8_t {
  kNone = 0,
  kConfigMissing = 1,
  kConfigCrc = 2,
  kConfigVersion = 3,
  kConfigInvalid = 4,
  kSelfTest = 5,
};

enum class DeviceRole : uint8_t { kBeacon = 1, kReceiver = 2 };

struct DeviceConfig {
  DeviceRole role = DeviceRole::kReceiver;
  // The beacon id, or the receiver's site id; 1..255.
  uint8_t id = 0;
  uint8_t flags = 0;
  uint64_t own_address = 0;
  // Where a receiver sends its reports; 0x000000000000FFFF broadcasts.
  uint64_t coordinator_address = 0xFFFF;
  // The beacon's slot in the site's TDMA table (docs/radio_protocol.md 5a).
  uint8_t slot_index = 0;
  uint8_t slot_count = 1;
  uint32_t slot_us = 0;
  uint32_t frame_us = 0;
  // From the announcement's last byte leaving the UART to the burst.
  uint16_t fire_delay_us = 3000;
  uint8_t burst_cycles = 16;
  // Nominal time from the beacon's last byte to the receivers' stamp of the
  // start delimiter (NominalRadioLatencyUs).
  uint16_t radio_latency_us = 0;
  // The receiver's listening window, from its stamp.
  uint32_t window_open_us = 0;
  uint32_t window_close_us = 0;
  uint16_t report_delay_us = 0;
  // Subtracted from the measured time (fire delay - latency + detector).
  int32_t tof_offset_ns = 0;
  // The slowest speed of sound and the longest path the window was sized for.
  uint32_t sound_speed_mm_s = 0;
  uint16_t max_range_cm = 0;
  // Beacon id of each slot (0: unused).
  std::array<uint8_t, kDeviceMaxSlots> slot_beacon_ids{};

  // The firmware's own checks (firmware/common/fw_codec.c), so that an image
  // this accepts is one the firmware runs.
  bool IsValid(std::string* error) const;
};

// The 72-byte image, CRC-16/CCITT-FALSE at the end.
std::vector<uint8_t> EncodeDeviceConfig(const DeviceConfig& config);
// Reads an image back; false with *error on a bad magic, CRC, version or
// size (field ranges are IsValid's).
bool DecodeDeviceConfig(const uint8_t* data, size_t size, DeviceConfig* config, std::string* error);

// The radio's timing (docs/devices.md, "Timing budget"): XBee 802.15.4
// modules at 250 kb/s on the air, with MM=2, RN=0, RR=0, the devices' UART at
// 250 000 b/s.
struct RadioTimingModel {
  // IEEE 802.15.4-2006 at 2.4 GHz (O-QPSK): 16 us a symbol, 32 us a byte.
  double air_byte_us = 32.0;
  // CCA: 8 symbols; RX-to-TX turnaround (aTurnaroundTime): 12 symbols.
  double cca_us = 128.0;
  double turnaround_us = 192.0;
  // The modules' own processing, serial frame to the radio and radio to
  // serial frame. Digi publishes no figure: these are assumptions, which
  // docs/devices.md's bring-up step 6 measures on the real parts.
  double tx_processing_us = 100.0;
  double rx_processing_us = 100.0;
  // The devices' UART.
  double uart_baud = 250000.0;
};

// The over-air bytes of a broadcast data frame with a 16-bit destination and
// a 64-bit source (MM=2, no Digi header): SHR 5 + PHR 1 + FCF 2 + sequence
// 1 + PAN 2 + destination 2 + source 8 + payload + FCS 2.
size_t AirFrameBytes(size_t payload_bytes);
// From the beacon's last UART byte (TXC) to the receiver's stamp of the 0x7E
// of the frame its module delivers: beacon module processing, CCA,
// turnaround, the PPDU on the air, receiving module processing, one UART
// byte. 1616 us for the 10-byte announcement with the defaults.
double NominalRadioLatencyUs(size_t payload_bytes = 10, const RadioTimingModel& model = {});

// What `roomfix devices` needs beyond the site file.
struct DeviceConfigOptions {
  uint32_t fire_delay_us = 3000;
  uint8_t burst_cycles = 16;
  // The detector's threshold crossing after the pulse's arrival: a few
  // carrier cycles for the envelope to rise (2 at 40 kHz). Its distance-
  // dependent part is what the survey's range offsets cannot absorb.
  double detector_delay_us = 50.0;
  // The coldest air the window must cover (slower sound, longer flights).
  double min_temperature_c = 0.0;
  // Firing rate upper bound: the frame is max(n slot, 1 / rate).
  double rate_hz = 10.0;
  // Space between two receivers' reports: a 14-byte report's PPDU (46
  // bytes, 1.5 ms), its ACK and turnaround.
  uint32_t report_spacing_us = 2000;
  // Where receivers send reports.
  uint64_t coordinator_address = 0xFFFF;
  RadioTimingModel radio;
  // The radio latency measured on the real parts (docs/devices.md,
  // bring-up step 6), us; 0: NominalRadioLatencyUs of `radio`.
  double radio_latency_us = 0.0;

  bool IsValid(std::string* error) const;
};

struct DeviceImage {
  std::string name;  // "beacon-1", "receiver-3"
  DeviceConfig config;
};

// One configuration per beacon and receiver of the site. False with *error
// when the site cannot be served (an id above 255, more beacons than
// slots, a window and reports that do not fit in a slot).
bool DeviceConfigsForSite(const Site& site, const DeviceConfigOptions& options,
                          std::vector<DeviceImage>* images, std::string* error);

// Intel hex (avrdude -U eeprom:w:FILE:i): 16-byte data records from
// `address`, then the end-of-file record.
std::string EncodeIntelHex(const std::vector<uint8_t>& data, uint16_t address = 0);
// Reads data records back into an image starting at address 0 (gaps
// filled with 0xFF, an erased EEPROM); false with *error on a bad record.
bool DecodeIntelHex(const std::string& text, std::vector<uint8_t>* data, std::string* error);

}  // namespace roomfix::radio

#endif  // ROOMFIX_CORE_RADIO_DEVICE_CONFIG_H_
