/* The ATmega328P's peripherals as both devices use them (pins and timing:
 * firmware/INTERFACE.md). AVR only. */
#ifndef ROOMFIX_FIRMWARE_COMMON_FW_HW_H_
#define ROOMFIX_FIRMWARE_COMMON_FW_HW_H_

#include <stdint.h>

#include "fw_codec.h"

/* Observable state (INTERFACE.md, "Observable state for tests"). */
extern volatile uint8_t fw_fault;
extern volatile uint16_t fw_frames_rx;
extern volatile uint16_t fw_frames_bad;
/* MCUSR as it was at reset (read and cleared before main). */
extern uint8_t fw_reset_cause;

/* Sets up the pins, Timer1 (free-running, clk/1, overflow counted), the
 * USART at FW_UART_BAUD with its receive interrupt, and enables interrupts. */
void fw_hw_init(void);

/* The 32-bit tick count (62.5 ns; wraps after 268 s). Outside an ISR. */
uint32_t fw_now(void);
/* The same with interrupts already off (in an ISR, or under cli). The
 * overflow race: if TOV1 is pending, the low word wrapped after the last
 * counted overflow; it is counted here when the low word is small, i.e.
 * was read after the wrap. */
uint32_t fw_now_locked(void);
/* Extends a 16-bit capture or compare value taken at most half a wrap
 * (2 ms) ago to the 32-bit count, with the same race rule. Interrupts off. */
uint32_t fw_extend_locked(uint16_t low);

/* Sends bytes on the USART, waiting for room (interrupts stay on, so
 * reception continues; 40 us a byte). */
void fw_uart_write(const uint8_t* data, uint8_t size);
/* Sends a frame whose end is to be timed: all but the last byte as
 * fw_uart_write, then, once UDR0 has room, clears TXC0 and writes the last
 * byte, so that TXC0 next rises when that byte's stop bit has left. (With
 * the double-buffered UDR0 kept full TXC0 only rises at the end anyway;
 * clearing it just before the last byte also makes that true of a USART,
 * or a simulator such as simavr 1.6, that raises TXC0 after every byte.) */
void fw_uart_write_timed(const uint8_t* data, uint8_t size);
/* With interrupts off, after fw_uart_write_timed: waits until the last
 * byte has left the
 * shift register (TXC0) and returns the tick count at that moment, to one
 * polling loop (3-5 cycles). Interrupts stay off on return. */
uint32_t fw_uart_wait_sent_locked(void);

/* Sends `payload` in a TX request: 16-bit destination (0xFFFF broadcasts). */
void fw_send_tx16(uint16_t destination, const uint8_t* payload, uint8_t size);

/* Called from the USART receive ISR with a frame that decoded (frame data
 * in `frame`) and the tick count at its start delimiter. The device
 * program defines it; it runs with interrupts off, so it must be short. */
void fw_on_frame(const uint8_t* frame, uint8_t length, uint32_t start_ticks);

void fw_led(uint8_t on);

/* Timer1 overflows every 65536 ticks (4.096 ms): the longest an idle sleep
 * lasts, since its interrupt wakes the CPU. */
#define FW_WAKE_TICKS 65536UL

/* Called with interrupts off (cli) after the caller found nothing to do:
 * sleeps in IDLE mode until the next interrupt, then returns with
 * interrupts on. Timer1, the UART and the comparator run on in IDLE, so
 * the hardware time stamps (input capture, the receive ISR's TCNT1 read)
 * are as awake; waking adds 4 cycles to an ISR's entry, a constant. sei()
 * then sleep back to back: the AVR runs the instruction after sei before
 * any interrupt, so one that arrives after the caller's check still wakes
 * the sleep rather than being missed until the next overflow. Why sleep at
 * all: a busy loop spends every cycle polling (a beacon on a battery), and
 * the firmware-in-the-loop simulator must execute every one of those
 * cycles, where a sleeping core jumps to its next interrupt. */
void fw_sleep_locked(void);
/* The main loops' watchdog petting: wdt_reset only when Timer1 has moved
 * since the last pet. A loop that spins or sleeps with its clock stopped
 * (an upset of TCCR1B, a dead overflow interrupt) is the one hang it cannot
 * see for itself; petting unconditionally kept such a beacon spinning for
 * ever in the polled stretch before a burst (found by the watchdog test in
 * tests/firmware/firmware_sim_test.cc). */
void fw_watchdog_pet(void);

/* Power-on self test: the CRC against its published check value, Timer1
 * counting, and a walking-bit test of a RAM buffer. Returns 1 on success. */
uint8_t fw_self_test(void);

/* Reads and checks the EEPROM configuration for `role`; returns the fault. */
uint8_t fw_read_config(uint8_t role, struct fw_config* config);

/* The device's life with a fault: never fires nor reports; sends the device
 * status once a second and blinks the LED at 2 Hz, under the watchdog. */
void fw_fault_loop(uint8_t device_id, uint8_t fault) __attribute__((noreturn));

#endif /* ROOMFIX_FIRMWARE_COMMON_FW_HW_H_ */
