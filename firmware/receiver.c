/* Wall receiver firmware: times the beacon's pulse from its announcement
 * and reports the time of flight to the coordinator
 * (docs/radio_protocol.md section 2; pins and timing:
 * firmware/INTERFACE.md; why: docs/devices.md).
 *
 * The receive ISR arms the listening window the moment an announcement's
 * frame has decoded, with the tick count of that frame's start delimiter;
 * the input capture ISR keeps the first echo edge inside the window; INT0
 * (the higher-threshold comparator) marks the echo strong. The main loop
 * only sends the report once the window (and this receiver's report delay)
 * has passed. */
#include <avr/interrupt.h>
#include <avr/io.h>
#include <avr/wdt.h>

#include "common/fw_hw.h"

/* Observable state (INTERFACE.md). */
volatile uint16_t fw_reports;
/* Announcements that came while a window was open (ignored). */
volatile uint16_t fw_overlaps;

static struct fw_config config;
static uint32_t open_ticks;
static uint32_t close_ticks;

enum { kIdle = 0, kListening = 1 };
static volatile uint8_t state;
static volatile uint8_t window_beacon;
static volatile uint16_t window_seq;
static volatile uint32_t window_stamp;
static volatile uint8_t echo_captured;
static volatile uint32_t echo_ticks;
static volatile uint8_t echo_strong;

void fw_on_frame(const uint8_t* frame, uint8_t length, uint32_t start_ticks) {
  uint8_t offset;
  const int8_t size = fw_xbee_rf_data(frame, length, &offset);
  uint8_t beacon_id;
  uint16_t seq;
  if (size < 0 || !fw_decode_firing(frame + offset, (uint8_t)size, &beacon_id, &seq)) return;
  if (state != kIdle) {
    ++fw_overlaps;
    return;
  }
  window_beacon = beacon_id;
  window_seq = seq;
  window_stamp = start_ticks;
  echo_captured = 0;
  echo_strong = 0;
  state = kListening;
}

/* Ticks from the window's stamp to `at` if inside the window, else 0. */
static uint32_t InWindow(uint32_t at) {
  const uint32_t since = at - window_stamp;
  return (since >= open_ticks && since <= close_ticks) ? since : 0;
}

ISR(TIMER1_CAPT_vect) {
  const uint32_t at = fw_extend_locked(ICR1);
  if (state != kListening || echo_captured) return;
  if (InWindow(at)) {
    echo_ticks = at - window_stamp;
    echo_captured = 1;
  }
}

ISR(INT0_vect) {
  const uint32_t at = fw_now_locked();
  if (state == kListening && InWindow(at)) echo_strong = 1;
}

static void SendReport(uint8_t beacon, uint16_t seq, uint8_t captured, uint32_t ticks,
                       uint8_t strong) {
  uint8_t flags = 0;
  uint32_t tof_ns = 0;
  if (!captured) {
    flags = FW_FLAG_NO_ECHO;
  } else {
    tof_ns = fw_time_of_flight_ns(ticks, config.tof_offset_ns);
    if (!strong) flags = FW_FLAG_WEAK_ECHO;
  }
  uint8_t payload[FW_REPORT_BYTES];
  fw_encode_report(beacon, seq, tof_ns, FW_NO_TEMPERATURE, flags, payload);
  uint8_t frame[FW_XBEE_MAX_DATA];
  uint8_t wire[2 * FW_XBEE_MAX_DATA + 8];
  const uint8_t length =
      fw_tx64_request(config.coordinator_address, payload, sizeof payload, frame, sizeof frame);
  const uint8_t n = fw_xbee_encode(frame, length, wire, sizeof wire);
  fw_uart_write(wire, n);
  ++fw_reports;
}

int main(void) {
  fw_hw_init();
  DDRB &= (uint8_t)~_BV(DDB0); /* ICP1 */
  DDRD &= (uint8_t)~_BV(DDD2); /* INT0 */
  wdt_enable(WDTO_250MS);
  if (!fw_self_test()) fw_fault_loop(0, FW_FAULT_SELF_TEST);
  const uint8_t fault = fw_read_config(FW_ROLE_RECEIVER, &config);
  if (fault != FW_FAULT_NONE) fw_fault_loop(config.id, fault);
  open_ticks = config.window_open_us * FW_TICKS_PER_US;
  close_ticks = config.window_close_us * FW_TICKS_PER_US;
  const uint32_t report_ticks =
      close_ticks + (uint32_t)config.report_delay_us * FW_TICKS_PER_US;
  /* Input capture on the rising edge, noise canceller on (4 cycles, part
   * of the detector's constant); INT0 on the rising edge. */
  TCCR1B |= _BV(ICNC1) | _BV(ICES1);
  TIFR1 = _BV(ICF1);
  TIMSK1 |= _BV(ICIE1);
  EICRA = _BV(ISC01) | _BV(ISC00);
  EIFR = _BV(INTF0);
  EIMSK = _BV(INT0);
  fw_led(1);
  for (;;) {
    fw_watchdog_pet();
    cli();
    if (state != kListening) {
      /* Nothing until an announcement: its receive ISR wakes us. */
      fw_sleep_locked();
      continue;
    }
    const uint32_t since = fw_now_locked() - window_stamp;
    if (since < report_ticks) {
      /* Sleep while a wake-up still comes before the report is due; poll
       * the last stretch, so the report leaves at its own delay. */
      if (report_ticks - since > FW_WAKE_TICKS) {
        fw_sleep_locked();
      } else {
        sei();
      }
      continue;
    }
    const uint8_t beacon = window_beacon;
    const uint16_t seq = window_seq;
    const uint8_t captured = echo_captured;
    const uint32_t ticks = echo_ticks;
    const uint8_t strong = echo_strong;
    state = kIdle;
    sei();
    SendReport(beacon, seq, captured, ticks, strong);
  }
}
