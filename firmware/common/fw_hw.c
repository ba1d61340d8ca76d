/* See fw_hw.h. */
#include "fw_hw.h"

#include <avr/eeprom.h>
#include <avr/interrupt.h>
#include <avr/sleep.h>
#include <avr/io.h>
#include <avr/wdt.h>

volatile uint8_t fw_fault;
volatile uint16_t fw_frames_rx;
volatile uint16_t fw_frames_bad;
uint8_t fw_reset_cause __attribute__((section(".noinit")));

/* High word of the tick count, counted by the overflow ISR. */
static volatile uint16_t t1_high;
static struct fw_xbee_decoder decoder;
static uint32_t frame_start_ticks;

/* avr-libc's recommendation for a watchdog reset: read and clear MCUSR and
 * stop the watchdog before anything else runs (it stays armed, at its
 * shortest period, after a watchdog reset). */
void fw_early_init(void) __attribute__((naked, used, section(".init3")));
void fw_early_init(void) {
  fw_reset_cause = MCUSR;
  MCUSR = 0;
  wdt_disable();
}

ISR(TIMER1_OVF_vect) { ++t1_high; }

uint32_t fw_extend_locked(uint16_t low) {
  uint16_t high = t1_high;
  /* A pending overflow that the ISR has not counted yet: a low value was
   * taken after the wrap (count it), a high one before. */
  if ((TIFR1 & _BV(TOV1)) && low < 0x8000u) ++high;
  return ((uint32_t)high << 16) | low;
}

uint32_t fw_now_locked(void) { return fw_extend_locked(TCNT1); }

uint32_t fw_now(void) {
  const uint8_t sreg = SREG;
  cli();
  const uint32_t now = fw_now_locked();
  SREG = sreg;
  return now;
}

ISR(USART_RX_vect) {
  /* The stamp first: its delay from the stop bit is this ISR's fixed entry
   * plus the instruction or ISR the CPU was in (the jitter term). */
  const uint16_t low = TCNT1;
  const uint8_t status = UCSR0A;
  const uint8_t byte = UDR0;
  if (status & (_BV(FE0) | _BV(DOR0))) {
    ++fw_frames_bad;
    fw_xbee_decoder_reset(&decoder);
    return;
  }
  if (byte == FW_XBEE_START) frame_start_ticks = fw_extend_locked(low);
  const int8_t result = fw_xbee_decode_byte(&decoder, byte);
  if (result == FW_XBEE_FRAME) {
    ++fw_frames_rx;
    fw_on_frame(decoder.data, (uint8_t)decoder.length, frame_start_ticks);
  } else if (result < 0 && result != FW_XBEE_GARBAGE && result != FW_XBEE_TOO_LONG) {
    ++fw_frames_bad;
  }
}

void fw_hw_init(void) {
  DDRB |= _BV(DDB5); /* LED */
  PORTB &= (uint8_t)~_BV(PORTB5);
  /* Timer1: normal mode, clk/1, overflow interrupt. */
  TCCR1A = 0;
  TCCR1B = _BV(CS10);
  TIMSK1 = _BV(TOIE1);
  /* USART0: 250 kb/s = 16 MHz / (16 x (3 + 1)), exact; 8N1. */
  UBRR0 = (uint16_t)(FW_CPU_HZ / (16ul * FW_UART_BAUD) - 1u);
  UCSR0A = 0;
  UCSR0C = _BV(UCSZ01) | _BV(UCSZ00);
  UCSR0B = _BV(RXEN0) | _BV(TXEN0) | _BV(RXCIE0);
  fw_xbee_decoder_reset(&decoder);
  sei();
}

void fw_uart_write(const uint8_t* data, uint8_t size) {
  for (uint8_t i = 0; i < size; ++i) {
    while (!(UCSR0A & _BV(UDRE0))) {
    }
    UDR0 = data[i];
  }
}

void fw_uart_write_timed(const uint8_t* data, uint8_t size) {
  if (size == 0) return;
  fw_uart_write(data, (uint8_t)(size - 1));
  while (!(UCSR0A & _BV(UDRE0))) {
  }
  UCSR0A |= _BV(TXC0); /* a flag bit: writing one clears it */
  UDR0 = data[size - 1];
}

uint32_t fw_uart_wait_sent_locked(void) {
  while (!(UCSR0A & _BV(TXC0))) {
  }
  return fw_now_locked();
}

void fw_send_tx16(uint16_t destination, const uint8_t* payload, uint8_t size) {
  uint8_t frame[FW_XBEE_MAX_DATA];
  uint8_t wire[2 * FW_XBEE_MAX_DATA + 8];
  const uint8_t length = fw_tx16_request(destination, payload, size, frame, sizeof frame);
  const uint8_t n = fw_xbee_encode(frame, length, wire, sizeof wire);
  fw_uart_write(wire, n);
}

void fw_led(uint8_t on) {
  if (on) {
    PORTB |= _BV(PORTB5);
  } else {
    PORTB &= (uint8_t)~_BV(PORTB5);
  }
}

uint8_t fw_self_test(void) {
  static const uint8_t kCheck[9] = {'1', '2', '3', '4', '5', '6', '7', '8', '9'};
  if (fw_crc16(kCheck, sizeof kCheck) != 0x29B1u) return 0;
  /* Timer1 must advance: 100 loop passes are several hundred cycles. */
  const uint16_t before = TCNT1;
  for (volatile uint8_t i = 0; i < 100; ++i) {
  }
  if (TCNT1 == before) return 0;
  /* Walking ones and zeros through a RAM buffer: a stuck or shorted data
   * line shows in any byte. */
  static volatile uint8_t ram[16];
  for (uint8_t bit = 0; bit < 8; ++bit) {
    for (uint8_t i = 0; i < sizeof ram; ++i) ram[i] = (uint8_t)((i & 1) ? _BV(bit) : ~_BV(bit));
    for (uint8_t i = 0; i < sizeof ram; ++i) {
      if (ram[i] != (uint8_t)((i & 1) ? _BV(bit) : ~_BV(bit))) return 0;
    }
  }
  return 1;
}

uint8_t fw_read_config(uint8_t role, struct fw_config* config) {
  uint8_t image[FW_CONFIG_BYTES];
  eeprom_read_block(image, (const void*)0, sizeof image);
  return fw_config_parse(image, role, config);
}

void fw_fault_loop(uint8_t device_id, uint8_t fault) {
  fw_fault = fault;
  uint8_t payload[FW_STATUS_BYTES];
  fw_encode_status(device_id, fault, fw_reset_cause, payload);
  uint32_t next_status = fw_now();
  uint32_t next_blink = next_status;
  uint8_t led = 0;
  for (;;) {
    wdt_reset();
    const uint32_t now = fw_now();
    if ((int32_t)(now - next_status) >= 0) {
      fw_send_tx16(0xFFFFu, payload, sizeof payload);
      next_status += 1000000ul * FW_TICKS_PER_US;
    }
    if ((int32_t)(now - next_blink) >= 0) {
      led ^= 1;
      fw_led(led);
      next_blink += 250000ul * FW_TICKS_PER_US;
    }
  }
}

void fw_watchdog_pet(void) {
  static uint32_t last_pet;
  const uint32_t now = fw_now();
  if (now != last_pet) {
    wdt_reset();
    last_pet = now;
  }
}

void fw_sleep_locked(void) {
  set_sleep_mode(SLEEP_MODE_IDLE);
  sleep_enable();
  sei();
  sleep_cpu();
  sleep_disable();
}
