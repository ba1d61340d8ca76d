/* The tests' AVR programs' shared bits: USART0 at 115200 baud (U2X0,
 * UBRR0 = 16), XBee API mode 2 transmit requests, CRC-16/CCITT-FALSE and
 * the roomfix payload (docs/radio_protocol.md). Header-only, static. */
#ifndef ROOMFIX_TESTS_FIRMWARE_SIM_AVR_XBEE_API_H_
#define ROOMFIX_TESTS_FIRMWARE_SIM_AVR_XBEE_API_H_

#include <avr/io.h>
#include <stdint.h>

static void uart_init(void) {
  UBRR0H = 0;
  UBRR0L = 16;
  UCSR0A = (1 << U2X0);
  UCSR0C = (1 << UCSZ01) | (1 << UCSZ00);
  UCSR0B = (1 << RXEN0) | (1 << TXEN0);
}

static void uart_put(uint8_t b) {
  while (!(UCSR0A & (1 << UDRE0))) {
  }
  UDR0 = b;
}

/* Mode 2: 0x7E, 0x7D, 0x11, 0x13 go out as 0x7D, byte ^ 0x20. */
static void put_escaped(uint8_t b) {
  if (b == 0x7E || b == 0x7D || b == 0x11 || b == 0x13) {
    uart_put(0x7D);
    uart_put(b ^ 0x20);
  } else {
    uart_put(b);
  }
}

static uint16_t crc16(const uint8_t* p, uint8_t n) {
  uint16_t crc = 0xFFFF;
  while (n--) {
    crc ^= (uint16_t)(*p++) << 8;
    for (uint8_t i = 0; i < 8; ++i)
      crc = (crc & 0x8000) ? (uint16_t)((crc << 1) ^ 0x1021) : (uint16_t)(crc << 1);
  }
  return crc;
}

/* A ZigBee Transmit Request (0x10), frame id 0 (no status), to a 64-bit
 * address: 0x000000000000FFFF broadcasts, 0 is the coordinator. */
static void send_tx_request(uint8_t dest_low16_hi, uint8_t dest_low16_lo, const uint8_t* data,
                            uint8_t n) {
  uint8_t header[14] = {0x10, 0, 0, 0, 0, 0, 0, 0, dest_low16_hi, dest_low16_lo, 0xFF, 0xFE, 0, 0};
  uint16_t len = 14 + n;
  uint8_t sum = 0;
  uart_put(0x7E);
  put_escaped((uint8_t)(len >> 8));
  put_escaped((uint8_t)len);
  for (uint8_t i = 0; i < 14; ++i) {
    sum += header[i];
    put_escaped(header[i]);
  }
  for (uint8_t i = 0; i < n; ++i) {
    sum += data[i];
    put_escaped(data[i]);
  }
  put_escaped((uint8_t)(0xFF - sum));
}

#endif
