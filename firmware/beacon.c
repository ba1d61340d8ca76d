/* Beacon firmware: fires a 40 kHz ultrasonic burst in its TDMA slot and
 * announces each firing over the XBee (docs/radio_protocol.md, sections 2
 * and 5a; pins and timing: firmware/INTERFACE.md; why: docs/devices.md).
 *
 * Timing: the announcement's last byte leaves the UART at TXC; the burst's
 * first edge is exactly fire_delay_us later (hardware compare, no ISR in
 * the path). Receivers start their timers on the 0x7E of the frame their
 * module delivers, radio_latency_us (nominal) after TXC, so they measure
 * flight + fire_delay - latency, and subtract the constant part. */
#include <avr/interrupt.h>
#include <avr/io.h>
#include <avr/wdt.h>

#include "common/fw_hw.h"

/* Observable state (INTERFACE.md). */
volatile uint16_t fw_firings;

static struct fw_config config;

/* The last announcement heard from another beacon, from the receive ISR. */
static volatile uint8_t heard_valid;
static volatile uint8_t heard_beacon;
static volatile uint32_t heard_ticks;

/* Compare toggles left in the burst (PB1 and PB2). */
static volatile uint8_t toggles_left;

void fw_on_frame(const uint8_t* frame, uint8_t length, uint32_t start_ticks) {
  uint8_t offset;
  const int8_t size = fw_xbee_rf_data(frame, length, &offset);
  uint8_t beacon_id;
  uint16_t seq;
  if (size < 0 || !fw_decode_firing(frame + offset, (uint8_t)size, &beacon_id, &seq)) return;
  if (beacon_id == config.id) return; /* another device with our id: not a clock */
  heard_beacon = beacon_id;
  heard_ticks = start_ticks;
  heard_valid = 1;
}

/* One compare match of the burst has toggled the pins. PB1 toggles at
 * half-periods 0 .. 2N-1 (rising first), PB2 at 1 .. 2N: PB2 is PB1 half a
 * period later, its complement while both run. The next match is 200 ticks
 * on; this ISR runs well inside that (about 40 cycles plus at most one
 * other short ISR ahead of it), and the hardware toggles at the exact tick
 * whatever the ISR's latency. */
ISR(TIMER1_COMPA_vect) {
  --toggles_left;
  if (toggles_left == 1) {
    /* PB1 has made its last toggle: disconnect it (it rests low); PB2 has
     * one more, at the same OCR1B + 200, ended by COMPB. */
    TCCR1A &= (uint8_t)~_BV(COM1A0);
    TIMSK1 &= (uint8_t)~_BV(OCIE1A);
    OCR1B = (uint16_t)(OCR1B + FW_HALF_CARRIER_TICKS);
    TIFR1 = _BV(OCF1B);
    TIMSK1 |= _BV(OCIE1B);
    return;
  }
  OCR1A = (uint16_t)(OCR1A + FW_HALF_CARRIER_TICKS);
  if (toggles_left != 2u * config.burst_cycles) {
    OCR1B = (uint16_t)(OCR1B + FW_HALF_CARRIER_TICKS);
  }
}

ISR(TIMER1_COMPB_vect) {
  TCCR1A &= (uint8_t)~_BV(COM1B0);
  TIMSK1 &= (uint8_t)~_BV(OCIE1B);
  toggles_left = 0;
  UCSR0B |= _BV(RXCIE0); /* listen again (see ArmBurst) */
}

/* Arms the burst's first edge at tick `at` (less than one wrap ahead).
 * Interrupts are off.
 *
 * The compare ISR must run within 200 cycles of each match, or the next
 * half period is lost for a whole Timer1 wrap (4 ms). The receive ISR can
 * take longer than that when a frame completes (its CRC), so the beacon
 * stops taking serial input from here to the burst's end (fire delay +
 * burst, 3.4 ms by default). A frame arriving then overruns the USART and
 * is dropped and counted (fw_frames_bad); by the schedule none should: the
 * other beacons announce in other slots and the receivers report to the
 * coordinator. */
static void ArmBurst(uint32_t at) {
  UCSR0B &= (uint8_t)~_BV(RXCIE0);
  const uint16_t first = (uint16_t)at;
  OCR1A = first;
  OCR1B = (uint16_t)(first + FW_HALF_CARRIER_TICKS);
  toggles_left = (uint8_t)(2u * config.burst_cycles + 1u);
  TIFR1 = _BV(OCF1A) | _BV(OCF1B);
  TCCR1A = _BV(COM1A0) | _BV(COM1B0); /* toggle both on compare match */
  TIMSK1 |= _BV(OCIE1A);
}

/* Sends the announcement for firing `seq` so that the burst starts at
 * `burst_at`; returns when the burst is armed. */
static void Fire(uint16_t seq, uint32_t burst_at) {
  uint8_t payload[FW_FIRING_BYTES];
  fw_encode_firing(config.id, seq, FW_NO_TEMPERATURE, 0, payload);
  uint8_t frame[FW_XBEE_MAX_DATA];
  uint8_t wire[2 * FW_XBEE_MAX_DATA + 8];
  const uint8_t length = fw_tx16_request(0xFFFFu, payload, sizeof payload, frame, sizeof frame);
  const uint8_t n = fw_xbee_encode(frame, length, wire, sizeof wire);
  const uint32_t fire_ticks = (uint32_t)config.fire_delay_us * FW_TICKS_PER_US;
  const uint32_t start = burst_at - fire_ticks - (uint32_t)n * FW_TICKS_PER_UART_BYTE;
  while ((int32_t)(fw_now() - start) < 0) {
  }
  fw_uart_write_timed(wire, n);
  cli();
  const uint32_t sent = fw_uart_wait_sent_locked();
  ArmBurst(sent + fire_ticks);
  sei();
}

/* Realigns the next burst on beacon `heard`'s announcement stamped at
 * `stamp`: that beacon burst at stamp - latency + fire delay, in its slot j;
 * ours, in slot k, comes (k - j) slots later when k > j, and a frame less
 * (j - k) slots later when k < j (the frame may be longer than n slots: the
 * rate bounds it too), moved on by whole frames until it is far enough
 * ahead (`lead`) to send our announcement first.
 *
 * Once firing, a beacon follows only beacons in earlier slots: the one in
 * the lowest slot heard keeps its own crystal and the others follow it.
 * Following every beacon fails when two burst together (they booted
 * together, or one was reset): each would move to the other's time plus
 * the same offset, and with n = 2 and a frame of 2 slots they would stay
 * together for ever. A beacon that has not fired yet (`joining`) follows
 * anyone it hears, so joining a running site never collides. */
static uint32_t Resync(uint8_t heard, uint32_t stamp, uint32_t next_burst, uint32_t now,
                       uint32_t lead, uint8_t joining) {
  const int8_t slot = fw_config_slot_of(&config, heard);
  if (slot < 0) return next_burst; /* not in our site's table */
  const uint8_t k = config.slot_index;
  const uint8_t j = (uint8_t)slot;
  if (j == k) return next_burst; /* two beacons own one slot: keep our own time */
  if (j > k && !joining) return next_burst;
  const uint32_t slot_ticks = config.slot_us * FW_TICKS_PER_US;
  const uint32_t frame_ticks = config.frame_us * FW_TICKS_PER_US;
  const uint32_t their_burst =
      stamp + ((uint32_t)config.fire_delay_us - config.radio_latency_us) * FW_TICKS_PER_US;
  const uint32_t offset =
      k > j ? (uint32_t)(k - j) * slot_ticks : frame_ticks - (uint32_t)(j - k) * slot_ticks;
  uint32_t next = their_burst + offset;
  while ((int32_t)(next - (now + lead)) < 0) next += frame_ticks;
  return next;
}

int main(void) {
  fw_hw_init();
  DDRB |= _BV(DDB1) | _BV(DDB2);
  PORTB &= (uint8_t)~(_BV(PORTB1) | _BV(PORTB2));
  wdt_enable(WDTO_250MS);
  if (!fw_self_test()) fw_fault_loop(0, FW_FAULT_SELF_TEST);
  const uint8_t fault = fw_read_config(FW_ROLE_BEACON, &config);
  if (fault != FW_FAULT_NONE) fw_fault_loop(config.id, fault);
  fw_led(1);

  /* Ahead of a burst: the longest announcement frame (every byte escaped)
   * at 640 ticks a byte, the fire delay, and 1 ms for the loop. */
  const uint32_t lead = (2u * 24u) * FW_TICKS_PER_UART_BYTE +
                        ((uint32_t)config.fire_delay_us + 1000u) * FW_TICKS_PER_US;
  const uint32_t frame_ticks = config.frame_us * FW_TICKS_PER_US;
  /* Listen for one frame first: a beacon heard in that time places us.
   * Heard or not, the first burst is in our slot of that frame, so beacons
   * switched on together (one power supply) start apart. */
  uint32_t next_burst = fw_now() + frame_ticks + lead +
                        (uint32_t)config.slot_index * config.slot_us * FW_TICKS_PER_US;
  uint16_t seq = 0;
  uint8_t joining = 1; /* not fired since boot (seq wraps to 0 later) */
  fw_firings = 0;
  for (;;) {
    fw_watchdog_pet();
    const uint32_t now = fw_now();
    if (heard_valid) {
      cli();
      const uint8_t beacon = heard_beacon;
      const uint32_t stamp = heard_ticks;
      heard_valid = 0;
      sei();
      next_burst = Resync(beacon, stamp, next_burst, now, lead, joining);
    }
    if ((int32_t)(next_burst - now) <= (int32_t)lead) {
      Fire(seq, next_burst);
      joining = 0;
      ++seq; /* 65535 wraps to 0, as the protocol says */
      fw_firings = seq;
      next_burst += frame_ticks;
      continue;
    }
    /* Sleep while a wake-up (at most FW_WAKE_TICKS away) still comes
     * before the lead; the last stretch is polled, so the burst keeps its
     * tick. An announcement heard meanwhile wakes the loop (receive ISR). */
    cli();
    if (!heard_valid && (int32_t)(next_burst - fw_now_locked()) > (int32_t)(lead + FW_WAKE_TICKS)) {
      fw_sleep_locked();
    } else {
      sei();
    }
  }
}
