/* The firmware's portable code: CRC, XBee API mode 2 framing, the roomfix
 * payloads and the EEPROM configuration. Plain C11 with no AVR header, so
 * that tests/firmware compiles the very same file on the host and checks it
 * against core/radio (the bridge's decoder). No dynamic memory: every
 * buffer is the caller's. */
#ifndef ROOMFIX_FIRMWARE_COMMON_FW_CODEC_H_
#define ROOMFIX_FIRMWARE_COMMON_FW_CODEC_H_

#include <stdint.h>

#include "fw_protocol.h"

#ifdef __cplusplus
extern "C" {
#endif

/* CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF, not reflected, no final
 * XOR), byte-wise without a table: x = high byte ^ data, x ^= x >> 4, then
 * crc = (crc << 8) ^ (x << 12) ^ (x << 5) ^ x, which is the polynomial
 * division of 8 bits at once (0x1021 = x^12 + x^5 + 1). About 30 AVR
 * cycles a byte, so it can run inside the receive ISR. */
uint16_t fw_crc16(const uint8_t* data, uint8_t size);

/* Builds an escaped API mode 2 frame around `data` (frame data: type byte
 * first) into `out`. Returns the number of bytes, or 0 when `out_capacity`
 * is too small. */
uint8_t fw_xbee_encode(const uint8_t* data, uint8_t size, uint8_t* out, uint8_t out_capacity);

/* Incremental API mode 2 decoder. A raw 0x7E always starts a frame (mode 2
 * escapes every data 0x7E), so any damage costs at most the frame it hits. */
enum fw_xbee_result {
  FW_XBEE_MORE = 0,  /* byte taken, frame not complete */
  FW_XBEE_FRAME = 1, /* a complete, checksummed frame is in data[0..length) */
  FW_XBEE_BAD_CHECKSUM = -1,
  FW_XBEE_BAD_ESCAPE = -2,
  FW_XBEE_TRUNCATED = -3, /* a start delimiter inside a frame */
  FW_XBEE_TOO_LONG = -4,  /* length 0 or above FW_XBEE_MAX_DATA: skipped */
  FW_XBEE_GARBAGE = -5    /* a byte outside any frame */
};
struct fw_xbee_decoder {
  uint8_t state;
  uint8_t escaped;
  uint16_t length;
  uint16_t index;
  uint8_t sum;
  uint8_t data[FW_XBEE_MAX_DATA];
};
void fw_xbee_decoder_reset(struct fw_xbee_decoder* decoder);
int8_t fw_xbee_decode_byte(struct fw_xbee_decoder* decoder, uint8_t byte);

/* The RF data of a receive frame (0x80, 0x81, 0x90): sets *offset and
 * returns its length, or returns -1 for any other frame or a short one. */
int8_t fw_xbee_rf_data(const uint8_t* frame, uint8_t length, uint8_t* offset);

/* Frame data of a TX request carrying `payload`: 0x01 to a 16-bit address
 * (the beacon's broadcast to 0xFFFF) or 0x00 to a 64-bit address (a
 * receiver's report to the coordinator). Frame id 0 (no TX status), options
 * 0. Return the frame data length, 0 when `out_capacity` is too small. */
uint8_t fw_tx16_request(uint16_t destination, const uint8_t* payload, uint8_t size, uint8_t* out,
                        uint8_t out_capacity);
uint8_t fw_tx64_request(const uint8_t destination[8], const uint8_t* payload, uint8_t size,
                        uint8_t* out, uint8_t out_capacity);

/* Payloads (docs/radio_protocol.md section 2); each writes its fixed size. */
void fw_encode_firing(uint8_t beacon_id, uint16_t firing_seq, uint16_t temperature_centi_c,
                      uint8_t flags, uint8_t out[FW_FIRING_BYTES]);
void fw_encode_report(uint8_t beacon_id, uint16_t firing_seq, uint32_t time_of_flight_ns,
                      uint16_t temperature_centi_c, uint8_t flags, uint8_t out[FW_REPORT_BYTES]);
void fw_encode_status(uint8_t device_id, uint8_t fault, uint8_t reset_cause,
                      uint8_t out[FW_STATUS_BYTES]);
/* A firing announcement: returns 1 and fills *beacon_id and *firing_seq
 * when `payload` is one (length, version, type, CRC, id != 0), else 0. */
uint8_t fw_decode_firing(const uint8_t* payload, uint8_t size, uint8_t* beacon_id,
                         uint16_t* firing_seq);

/* The EEPROM configuration (firmware/INTERFACE.md has the byte table). */
struct fw_config {
  uint8_t role;
  uint8_t id;
  uint8_t flags;
  uint8_t own_address[8];
  uint8_t coordinator_address[8];
  uint8_t slot_index;
  uint8_t slot_count;
  uint32_t slot_us;
  uint32_t frame_us;
  uint16_t fire_delay_us;
  uint8_t burst_cycles;
  uint16_t radio_latency_us;
  uint32_t window_open_us;
  uint32_t window_close_us;
  uint16_t report_delay_us;
  int32_t tof_offset_ns;
  uint32_t sound_speed_mm_s;
  uint16_t max_range_cm;
  uint8_t slot_beacon_ids[FW_MAX_SLOTS];
};
/* Checks and reads an image for a device of `role`: returns FW_FAULT_NONE,
 * or the fault (missing, CRC, version, invalid) that keeps the device from
 * firing or reporting. Invalid covers every field out of its range, a role
 * other than `role`, and a window too short for max_range_cm at
 * sound_speed_mm_s. */
uint8_t fw_config_parse(const uint8_t image[FW_CONFIG_BYTES], uint8_t role,
                        struct fw_config* config);
/* The slot of `beacon_id` in the configuration's table, -1 if absent. */
int8_t fw_config_slot_of(const struct fw_config* config, uint8_t beacon_id);

/* Time of flight of a receiver: `ticks` of 62.5 ns from the announcement's
 * stamp to the echo's capture, less the configured constant; clamped to 0
 * below (an echo earlier than the constant says is not a negative
 * distance); counts above 2^25 ticks (2.1 s) are saturated there. */
uint32_t fw_time_of_flight_ns(uint32_t ticks, int32_t tof_offset_ns);

#ifdef __cplusplus
}
#endif

#endif /* ROOMFIX_FIRMWARE_COMMON_FW_CODEC_H_ */
