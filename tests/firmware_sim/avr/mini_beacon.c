/* The tests' own minimal beacon (not the project's firmware/): every
 * PERIOD_MS it broadcasts a firing announcement through its XBee (API mode 2
 * transmit request) and, as the announcement's last byte is handed to the
 * UART, starts a 40 kHz burst of 16 half-periods on OC1A (PB1) from Timer1.
 * EEPROM byte 0 is its beacon id (0xFF, erased: it sends nothing).
 * Timer0 ticks every 1 ms (CTC, /64, OCR0A = 249). */
#include <avr/eeprom.h>
#include <avr/interrupt.h>
#include <avr/io.h>
#include <stdint.h>

#include "xbee_api.h"

#define PERIOD_MS 100
#define BURST_TOGGLES 16

static volatile uint16_t ms = 0;
static volatile uint8_t toggles = 0;

ISR(TIMER0_COMPA_vect) { ++ms; }

ISR(TIMER1_COMPA_vect) {
  if (++toggles >= BURST_TOGGLES) {
    TCCR1A = 0; /* disconnect OC1A, PB1 falls back to PORTB1 = 0 */
    TCCR1B = 0;
    TIMSK1 = 0;
  }
}

static void start_burst(void) {
  toggles = 0;
  TCNT1 = 0;
  OCR1A = 199; /* toggle every 200 cycles: 12.5 us, 40 kHz */
  TIFR1 = (1 << OCF1A);
  TIMSK1 = (1 << OCIE1A);
  TCCR1A = (1 << COM1A0);
  TCCR1B = (1 << WGM12) | (1 << CS10);
}

int main(void) {
  const uint8_t id = eeprom_read_byte((const uint8_t*)0);
  uart_init();
  DDRB = (1 << DDB1);
  PORTB = 0;
  TCCR0A = (1 << WGM01);
  OCR0A = 249;
  TCCR0B = (1 << CS01) | (1 << CS00);
  TIMSK0 = (1 << OCIE0A);
  sei();
  uint16_t seq = 0;
  uint16_t next = PERIOD_MS;
  for (;;) {
    uint16_t now;
    cli();
    now = ms;
    sei();
    if (id == 0xFF || id == 0 || (int16_t)(now - next) < 0) continue;
    next += PERIOD_MS;
    uint8_t p[10] = {1, 1, id, (uint8_t)(seq >> 8), (uint8_t)seq, 0x80, 0x00, 0, 0, 0};
    const uint16_t crc = crc16(p, 8);
    p[8] = (uint8_t)(crc >> 8);
    p[9] = (uint8_t)crc;
    send_tx_request(0xFF, 0xFF, p, sizeof(p));
    start_burst();
    ++seq;
  }
}
