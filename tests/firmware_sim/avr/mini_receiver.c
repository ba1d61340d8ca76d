/* The tests' own minimal wall receiver (not the project's firmware/): it
 * reads API mode 2 frames from its XBee, and on a firing announcement (an
 * 0x80 or 0x90 receive frame whose payload is type 1) arms: its time zero is
 * the announcement frame's start delimiter. The first rising edge on ICP1
 * (PB0, Timer1 at the full clock, 62.5 ns a tick, extended to 32 bits by its
 * overflows) after that is the echo; it reports
 *   time of flight = (capture - start delimiter) x 62.5 ns + latency_ns,
 * latency_ns (EEPROM bytes 0-3, big-endian, signed) being the radio's
 * constant delay from the burst to the start delimiter, with the weak-echo
 * flag when PD7 (the strong-echo comparator) is low at the capture, or a
 * no-echo report after 30 ms. */
#include <avr/eeprom.h>
#include <avr/interrupt.h>
#include <avr/io.h>
#include <stdint.h>

#include "xbee_api.h"

#define WINDOW_TICKS (30UL * 16000UL)

static volatile uint16_t overflows = 0;
static volatile uint32_t capture = 0;
static volatile uint8_t captured = 0;
static volatile uint8_t strong = 0;
static volatile uint8_t armed = 0;
static volatile uint32_t arm_time = 0;

static uint32_t now_ticks(void) {
  uint8_t s = SREG;
  cli();
  uint16_t lo = TCNT1;
  uint16_t hi = overflows;
  if ((TIFR1 & (1 << TOV1)) && lo < 0x8000) ++hi;
  SREG = s;
  return ((uint32_t)hi << 16) | lo;
}

ISR(TIMER1_OVF_vect) { ++overflows; }

ISR(TIMER1_CAPT_vect) {
  uint16_t lo = ICR1;
  uint16_t hi = overflows;
  if ((TIFR1 & (1 << TOV1)) && lo < 0x8000) ++hi;
  if (armed && !captured) {
    capture = ((uint32_t)hi << 16) | lo;
    strong = (PIND & (1 << PIND7)) != 0;
    captured = 1;
  }
}

/* Receive state: mode 2 unescaping, frame data into buf. */
static uint8_t buf[64];
static uint8_t escape = 0, state = 0;
static uint16_t length = 0, got = 0;
static uint32_t delimiter_time = 0;
static volatile uint8_t announcement[10];
static volatile uint8_t have_announcement = 0;
static volatile uint32_t announcement_time = 0;

static void on_frame(void) {
  uint8_t off;
  if (buf[0] == 0x80) off = 11;
  else if (buf[0] == 0x90) off = 12;
  else return;
  if (length != off + 10u || buf[off] != 1 || buf[off + 1] != 1) return;
  for (uint8_t i = 0; i < 10; ++i) announcement[i] = buf[off + i];
  announcement_time = delimiter_time;
  have_announcement = 1;
}

ISR(USART_RX_vect) {
  uint8_t b = UDR0;
  if (b == 0x7E) {
    delimiter_time = now_ticks();
    state = 1;
    got = 0;
    escape = 0;
    return;
  }
  if (state == 0) return;
  if (b == 0x7D) {
    escape = 1;
    return;
  }
  if (escape) {
    b ^= 0x20;
    escape = 0;
  }
  if (state == 1) {
    length = (uint16_t)b << 8;
    state = 2;
  } else if (state == 2) {
    length |= b;
    state = (length > 0 && length <= sizeof(buf)) ? 3 : 0;
  } else if (got < length) {
    buf[got++] = b;
  } else {
    uint8_t sum = b;
    for (uint16_t i = 0; i < length; ++i) sum += buf[i];
    if (sum == 0xFF) on_frame();
    state = 0;
  }
}

static void report(uint8_t beacon, uint8_t seq_hi, uint8_t seq_lo, uint32_t tof_ns, uint8_t flags) {
  uint8_t p[14] = {1, 2, beacon, seq_hi, seq_lo, (uint8_t)(tof_ns >> 24), (uint8_t)(tof_ns >> 16),
                   (uint8_t)(tof_ns >> 8), (uint8_t)tof_ns, 0x80, 0x00, flags, 0, 0};
  const uint16_t crc = crc16(p, 12);
  p[12] = (uint8_t)(crc >> 8);
  p[13] = (uint8_t)crc;
  send_tx_request(0, 0, p, sizeof(p));
}

int main(void) {
  const int32_t latency_ns = (int32_t)eeprom_read_dword((const uint32_t*)0);
  uart_init();
  UCSR0B |= (1 << RXCIE0);
  DDRB = 0;
  TCCR1A = 0;
  TCCR1B = (1 << ICES1) | (1 << CS10);
  TIMSK1 = (1 << ICIE1) | (1 << TOIE1);
  sei();
  uint8_t beacon = 0, seq_hi = 0, seq_lo = 0;
  for (;;) {
    if (have_announcement) {
      cli();
      beacon = announcement[2];
      seq_hi = announcement[3];
      seq_lo = announcement[4];
      arm_time = announcement_time;
      have_announcement = 0;
      captured = 0;
      armed = 1;
      sei();
    }
    if (!armed) continue;
    if (captured) {
      armed = 0;
      int32_t ticks = (int32_t)(capture - arm_time);
      int32_t ns = ticks * 125 / 2 + (latency_ns == -1 ? 0 : latency_ns);
      report(beacon, seq_hi, seq_lo, ns > 0 ? (uint32_t)ns : 0, strong ? 0 : 0x01);
    } else if (now_ticks() - arm_time > WINDOW_TICKS) {
      armed = 0;
      report(beacon, seq_hi, seq_lo, 0, 0x02);
    }
  }
}
