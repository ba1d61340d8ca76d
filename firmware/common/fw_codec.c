/* See fw_codec.h. Plain C11: compiled by avr-gcc for the devices and by the
 * host's C compiler for tests/firmware. `int` is 16 bits on the AVR, so
 * every product that can pass 32767 is done in an explicit 32-bit type. */
#include "fw_codec.h"

uint16_t fw_crc16(const uint8_t* data, uint8_t size) {
  uint16_t crc = 0xFFFFu;
  for (uint8_t i = 0; i < size; ++i) {
    uint8_t x = (uint8_t)((crc >> 8) ^ data[i]);
    x ^= (uint8_t)(x >> 4);
    crc = (uint16_t)((crc << 8) ^ ((uint16_t)x << 12) ^ ((uint16_t)x << 5) ^ x);
  }
  return crc;
}

static uint8_t NeedsEscape(uint8_t byte) {
  return byte == FW_XBEE_START || byte == FW_XBEE_ESCAPE || byte == FW_XBEE_XON ||
         byte == FW_XBEE_XOFF;
}

/* Appends one byte, escaped; returns the new length or 0 when full. */
static uint8_t PutEscaped(uint8_t byte, uint8_t* out, uint8_t n, uint8_t capacity) {
  if (NeedsEscape(byte)) {
    if (n + 2 > capacity) return 0;
    out[n++] = FW_XBEE_ESCAPE;
    out[n++] = (uint8_t)(byte ^ FW_XBEE_ESCAPE_XOR);
    return n;
  }
  if (n + 1 > capacity) return 0;
  out[n++] = byte;
  return n;
}

uint8_t fw_xbee_encode(const uint8_t* data, uint8_t size, uint8_t* out, uint8_t out_capacity) {
  if (out_capacity < 1) return 0;
  uint8_t n = 0;
  out[n++] = FW_XBEE_START;
  if ((n = PutEscaped(0, out, n, out_capacity)) == 0) return 0;
  if ((n = PutEscaped(size, out, n, out_capacity)) == 0) return 0;
  uint8_t sum = 0;
  for (uint8_t i = 0; i < size; ++i) {
    sum = (uint8_t)(sum + data[i]);
    if ((n = PutEscaped(data[i], out, n, out_capacity)) == 0) return 0;
  }
  return PutEscaped((uint8_t)(0xFF - sum), out, n, out_capacity);
}

enum { kIdle = 0, kLengthHigh, kLengthLow, kData, kChecksum, kSkip };

void fw_xbee_decoder_reset(struct fw_xbee_decoder* decoder) {
  decoder->state = kIdle;
  decoder->escaped = 0;
  decoder->length = 0;
  decoder->index = 0;
  decoder->sum = 0;
}

int8_t fw_xbee_decode_byte(struct fw_xbee_decoder* decoder, uint8_t byte) {
  if (byte == FW_XBEE_START) {
    /* In mode 2 a raw start delimiter is always a new frame. */
    const uint8_t was_inside = decoder->state != kIdle && decoder->state != kSkip;
    fw_xbee_decoder_reset(decoder);
    decoder->state = kLengthHigh;
    return was_inside ? FW_XBEE_TRUNCATED : FW_XBEE_MORE;
  }
  if (decoder->state == kIdle) return FW_XBEE_GARBAGE;
  if (decoder->state == kSkip) return FW_XBEE_MORE;
  if (decoder->escaped) {
    decoder->escaped = 0;
    byte ^= FW_XBEE_ESCAPE_XOR;
    if (!NeedsEscape(byte)) {
      decoder->state = kIdle;
      return FW_XBEE_BAD_ESCAPE;
    }
  } else if (byte == FW_XBEE_ESCAPE) {
    decoder->escaped = 1;
    return FW_XBEE_MORE;
  }
  switch (decoder->state) {
    case kLengthHigh:
      decoder->length = (uint16_t)byte << 8;
      decoder->state = kLengthLow;
      return FW_XBEE_MORE;
    case kLengthLow:
      decoder->length |= byte;
      if (decoder->length == 0 || decoder->length > FW_XBEE_MAX_DATA) {
        decoder->state = kSkip;
        return FW_XBEE_TOO_LONG;
      }
      decoder->state = kData;
      return FW_XBEE_MORE;
    case kData:
      decoder->data[decoder->index++] = byte;
      decoder->sum = (uint8_t)(decoder->sum + byte);
      if (decoder->index == decoder->length) decoder->state = kChecksum;
      return FW_XBEE_MORE;
    default: /* kChecksum */
      decoder->state = kIdle;
      return (uint8_t)(decoder->sum + byte) == 0xFF ? FW_XBEE_FRAME : FW_XBEE_BAD_CHECKSUM;
  }
}

int8_t fw_xbee_rf_data(const uint8_t* frame, uint8_t length, uint8_t* offset) {
  uint8_t header;
  if (length < 1) return -1;
  switch (frame[0]) {
    case FW_XBEE_RX64:
      header = FW_XBEE_RX64_HEADER;
      break;
    case FW_XBEE_RX16:
      header = FW_XBEE_RX16_HEADER;
      break;
    case FW_XBEE_ZB_RX:
      header = FW_XBEE_ZB_RX_HEADER;
      break;
    default:
      return -1;
  }
  if (length < header) return -1;
  *offset = header;
  return (int8_t)(length - header);
}

static uint8_t TxRequest(const uint8_t* header, uint8_t header_size, const uint8_t* payload,
                         uint8_t size, uint8_t* out, uint8_t out_capacity) {
  if ((uint16_t)header_size + size > out_capacity) return 0;
  for (uint8_t i = 0; i < header_size; ++i) out[i] = header[i];
  for (uint8_t i = 0; i < size; ++i) out[header_size + i] = payload[i];
  return (uint8_t)(header_size + size);
}

uint8_t fw_tx16_request(uint16_t destination, const uint8_t* payload, uint8_t size, uint8_t* out,
                        uint8_t out_capacity) {
  /* type, frame id 0 (no TX status), destination (2), options 0. */
  const uint8_t header[5] = {FW_XBEE_TX16, 0, (uint8_t)(destination >> 8), (uint8_t)destination,
                             0};
  return TxRequest(header, sizeof header, payload, size, out, out_capacity);
}

uint8_t fw_tx64_request(const uint8_t destination[8], const uint8_t* payload, uint8_t size,
                        uint8_t* out, uint8_t out_capacity) {
  uint8_t header[11] = {FW_XBEE_TX64, 0};
  for (uint8_t i = 0; i < 8; ++i) header[2 + i] = destination[i];
  header[10] = 0; /* options: MAC ACK and retries on */
  return TxRequest(header, sizeof header, payload, size, out, out_capacity);
}

static void PutU16(uint8_t* out, uint16_t value) {
  out[0] = (uint8_t)(value >> 8);
  out[1] = (uint8_t)value;
}

static void PutCrc(uint8_t* out, uint8_t size) {
  PutU16(out + size, fw_crc16(out, size));
}

void fw_encode_firing(uint8_t beacon_id, uint16_t firing_seq, uint16_t temperature_centi_c,
                      uint8_t flags, uint8_t out[FW_FIRING_BYTES]) {
  out[0] = FW_PAYLOAD_VERSION;
  out[1] = FW_TYPE_FIRING;
  out[2] = beacon_id;
  PutU16(out + 3, firing_seq);
  PutU16(out + 5, temperature_centi_c);
  out[7] = flags;
  PutCrc(out, FW_FIRING_BYTES - 2);
}

void fw_encode_report(uint8_t beacon_id, uint16_t firing_seq, uint32_t time_of_flight_ns,
                      uint16_t temperature_centi_c, uint8_t flags, uint8_t out[FW_REPORT_BYTES]) {
  out[0] = FW_PAYLOAD_VERSION;
  out[1] = FW_TYPE_RANGE_REPORT;
  out[2] = beacon_id;
  PutU16(out + 3, firing_seq);
  PutU16(out + 5, (uint16_t)(time_of_flight_ns >> 16));
  PutU16(out + 7, (uint16_t)time_of_flight_ns);
  PutU16(out + 9, temperature_centi_c);
  out[11] = flags;
  PutCrc(out, FW_REPORT_BYTES - 2);
}

void fw_encode_status(uint8_t device_id, uint8_t fault, uint8_t reset_cause,
                      uint8_t out[FW_STATUS_BYTES]) {
  out[0] = FW_PAYLOAD_VERSION;
  out[1] = FW_TYPE_DEVICE_STATUS;
  out[2] = device_id;
  out[3] = fault;
  out[4] = reset_cause;
  out[5] = FW_VERSION;
  PutCrc(out, FW_STATUS_BYTES - 2);
}

static uint16_t GetU16(const uint8_t* in) { return (uint16_t)(((uint16_t)in[0] << 8) | in[1]); }

static uint32_t GetU32(const uint8_t* in) {
  return ((uint32_t)GetU16(in) << 16) | GetU16(in + 2);
}

uint8_t fw_decode_firing(const uint8_t* payload, uint8_t size, uint8_t* beacon_id,
                         uint16_t* firing_seq) {
  if (size != FW_FIRING_BYTES || payload[0] != FW_PAYLOAD_VERSION ||
      payload[1] != FW_TYPE_FIRING || payload[2] == 0) {
    return 0;
  }
  if (fw_crc16(payload, FW_FIRING_BYTES - 2) != GetU16(payload + FW_FIRING_BYTES - 2)) return 0;
  *beacon_id = payload[2];
  *firing_seq = GetU16(payload + 3);
  return 1;
}

/* The range checks of a layout-valid image; 1 when every field is usable. */
static uint8_t ConfigFieldsValid(const struct fw_config* c, uint8_t role) {
  if (c->role != role || c->id == 0) return 0;
  if (c->burst_cycles == 0 || c->burst_cycles > FW_MAX_BURST_CYCLES) return 0;
  if (c->window_close_us <= c->window_open_us || c->window_close_us > FW_MAX_WINDOW_US) return 0;
  if (c->sound_speed_mm_s == 0) return 0;
  /* The window must hold the longest path at the slowest sound: range (cm)
   * x 10^4 / speed (mm/s) is the flight in us. */
  const uint32_t flight_us = (uint32_t)c->max_range_cm * 10000ul / c->sound_speed_mm_s;
  if (role == FW_ROLE_RECEIVER && c->window_close_us < flight_us) return 0;
  if (role != FW_ROLE_BEACON) return 1;
  if (c->slot_count == 0 || c->slot_count > FW_MAX_SLOTS || c->slot_index >= c->slot_count) {
    return 0;
  }
  if (c->slot_beacon_ids[c->slot_index] != c->id) return 0;
  if (c->fire_delay_us < FW_MIN_FIRE_DELAY_US || c->fire_delay_us > FW_MAX_FIRE_DELAY_US) return 0;
  if (c->slot_us == 0 || c->frame_us < (uint32_t)c->slot_count * c->slot_us) return 0;
  /* A frame must leave room to send the announcement and wait the fire
   * delay (under 10 ms); 268 s is where the 32-bit tick count wraps. */
  if (c->frame_us < 10000ul || c->frame_us > 60000000ul) return 0;
  return 1;
}

uint8_t fw_config_parse(const uint8_t image[FW_CONFIG_BYTES], uint8_t role,
                        struct fw_config* config) {
  if (image[0] != FW_CONFIG_MAGIC0 || image[1] != FW_CONFIG_MAGIC1) return FW_FAULT_CONFIG_MISSING;
  if (fw_crc16(image, FW_CONFIG_BYTES - 2) != GetU16(image + FW_CONFIG_BYTES - 2)) {
    return FW_FAULT_CONFIG_CRC;
  }
  if (image[2] != FW_CONFIG_LAYOUT_VERSION) return FW_FAULT_CONFIG_VERSION;
  config->role = image[3];
  config->id = image[4];
  config->flags = image[5];
  for (uint8_t i = 0; i < 8; ++i) {
    config->own_address[i] = image[6 + i];
    config->coordinator_address[i] = image[14 + i];
  }
  config->slot_index = image[22];
  config->slot_count = image[23];
  config->slot_us = GetU32(image + 24);
  config->frame_us = GetU32(image + 28);
  config->fire_delay_us = GetU16(image + 32);
  config->burst_cycles = image[34];
  config->radio_latency_us = GetU16(image + 36);
  config->window_open_us = GetU32(image + 38);
  config->window_close_us = GetU32(image + 42);
  config->report_delay_us = GetU16(image + 46);
  config->tof_offset_ns = (int32_t)GetU32(image + 48);
  config->sound_speed_mm_s = GetU32(image + 52);
  config->max_range_cm = GetU16(image + 56);
  for (uint8_t i = 0; i < FW_MAX_SLOTS; ++i) config->slot_beacon_ids[i] = image[58 + i];
  return ConfigFieldsValid(config, role) ? FW_FAULT_NONE : FW_FAULT_CONFIG_INVALID;
}

int8_t fw_config_slot_of(const struct fw_config* config, uint8_t beacon_id) {
  for (uint8_t i = 0; i < config->slot_count && i < FW_MAX_SLOTS; ++i) {
    if (config->slot_beacon_ids[i] == beacon_id) return (int8_t)i;
  }
  return -1;
}

uint32_t fw_time_of_flight_ns(uint32_t ticks, int32_t tof_offset_ns) {
  /* 62.5 ns a tick: 62 ticks + ticks / 2 (half a nanosecond truncated on
   * odd counts), in 32 bits (the AVR has no cheap 64-bit multiply). A
   * receiver's window is at most 200 ms = 3.2e6 ticks; a count above 2^25
   * (2.1 s) would overflow the product and is saturated. */
  const uint32_t kMaxTicks = 1ul << 25;
  if (ticks > kMaxTicks) ticks = kMaxTicks;
  const int32_t ns = (int32_t)(ticks * 62u + (ticks >> 1)) - tof_offset_ns;
  return ns < 0 ? 0u : (uint32_t)ns;
}
