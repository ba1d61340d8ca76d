#ifndef ROOMFIX_SIM_FIRMWARE_AVR_CORE_H_
#define ROOMFIX_SIM_FIRMWARE_AVR_CORE_H_

// One simulated ATmega328P running a firmware ELF in simavr, cycle by cycle,
// with its pins and its USART0 opened to the outside world at exact cycles.
//
// simavr (libsimavr-dev) is used as its examples use it: avr_make_mcu_by_name,
// avr_init, elf_read_firmware + avr_load_firmware, avr_run once per
// instruction. Three of its defaults would make a lockstep simulation wrong
// or slow and are switched off here:
// - avr->sleep usleep()s so that a sleeping core keeps pace with the wall
//   clock: replaced by a no-op (simulated time is ours to pace);
// - the UART's AVR_UART_FLAG_POLL_SLEEP usleep()s while the firmware polls
//   UCSR0A: cleared; AVR_UART_FLAG_STDIO prints the UART's bytes: cleared;
// - the USART paces a byte at 11 bit times for 8N1 (a parity bit always
//   counted): set to the true 10 (FixUartPacing);
// - avr_reset drops every cycle timer, ours included: the core's reset hook
//   re-arms ours (a watchdog reset goes through avr_reset too).
//
// Events from outside (a pin level, a byte for the UART) are queued with the
// cycle they are due at and delivered by a simavr cycle timer at exactly
// that cycle, also while the core sleeps: simavr wakes a sleeping core at
// its next timer. RunUntil(cycle) never lets a core sleep past `cycle` (a
// timer there bounds the sleep), so a world that advances every core to a
// common cycle before it delivers what one core caused to another keeps
// each delivery exact (FirmwareWorld states the lookahead that makes this
// hold).

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

struct avr_t;
struct avr_irq_t;

namespace roomfix::firmware {

// A pin: port letter 'B', 'C' or 'D' and bit 0..7 (PB0 = {'B', 0}).
struct AvrPin {
  char port = 'B';
  int bit = 0;
  bool operator<(const AvrPin& o) const { return port != o.port ? port < o.port : bit < o.bit; }
  bool operator==(const AvrPin& o) const { return port == o.port && bit == o.bit; }
  std::string Name() const { return std::string("P") + port + std::to_string(bit); }
};

struct AvrCoreOptions {
  std::string elf_path;
  // The MCU and its clock: 16 MHz is a 62.5 ns cycle.
  std::string mcu = "atmega328p";
  uint32_t frequency_hz = 16000000;
  // Written into the EEPROM after the ELF's own .eeprom section (the
  // device's configuration); empty: the ELF's (or erased, 0xFF) EEPROM.
  std::vector<uint8_t> eeprom;

  bool IsValid(std::string* error) const;
};

// What the core counted.
struct AvrCoreCounters {
  int64_t instructions_run = 0;
  int64_t uart_bytes_out = 0;
  int64_t uart_bytes_in = 0;
  // Bytes pushed while simavr's receive FIFO was full (it raised XOFF) or
  // the receiver was disabled: a real USART would have overrun.
  int64_t uart_bytes_refused = 0;
  // Resets: asked for (Reset) and by the firmware itself (watchdog).
  int64_t resets = 0;
  // Events queued for a cycle the core had already passed (delivered at
  // once, late): the lookahead was violated.
  int64_t late_events = 0;
  // The core stopped (sleep with interrupts off, a crash): it runs no more
  // until Reset.
  int64_t stops = 0;
};

class AvrCore {
 public:
  // Loads the ELF and the EEPROM; nullptr with a one-line reason when the
  // MCU is unknown or the file is not an AVR ELF simavr can load.
  static std::unique_ptr<AvrCore> Create(const AvrCoreOptions& options, std::string* error);
  ~AvrCore();
  AvrCore(const AvrCore&) = delete;
  AvrCore& operator=(const AvrCore&) = delete;

  // Runs instructions until the core's cycle count reaches `cycle` (it may
  // end up to one instruction, at most 4 cycles, beyond). A stopped core
  // just has its clock moved on.
  void RunUntil(uint64_t cycle);
  uint64_t cycle() const;
  uint32_t frequency_hz() const { return options_.frequency_hz; }
  bool stopped() const;

  // Power-on reset at the current cycle: registers, I/O and timers as after
  // power-up, RAM left as it was (the C runtime clears what it uses), the
  // EEPROM kept; queued pin levels are dropped, the UART's input too.
  void Reset();

  // Drives an input pin to `level` at `cycle` (at once when already
  // passed, counted late). Input capture (ICP1 on PB0), pin-change and
  // external interrupts see it as on the real part.
  void DrivePin(AvrPin pin, bool level, uint64_t cycle);
  // Called with the cycle whenever an output pin changes level (the
  // firmware wrote PORTx, or a timer's compare output toggled it).
  using PinWatcher = std::function<void(uint64_t cycle, bool level)>;
  void WatchPin(AvrPin pin, PinWatcher watcher);

  // USART0, output: every byte the firmware writes to UDR0, with the cycle
  // of the write. The byte is on the wire for uart_byte_cycles() from then.
  using UartWatcher = std::function<void(uint64_t cycle, uint8_t byte)>;
  void WatchUart(UartWatcher watcher);
  // USART0, input: the byte's start bit at `cycle`; simavr makes it
  // readable from UDR0 one byte time (uart_byte_cycles) later. Bytes must
  // come one byte time apart or more, as on a wire (the caller serialises
  // them).
  void SendUart(uint8_t byte, uint64_t cycle);
  // One 8N1 frame at the baud rate the firmware set (UBRR0, U2X0): the
  // bits of a byte times the cycles per bit. 0 before the firmware set the
  // baud rate.
  uint64_t uart_byte_cycles() const;
  double uart_baud() const;

  // A fault: the I/O register at data address `address` (0x20..0xFF) takes
  // `value` now, as an upset would leave it, with the I/O module's side
  // effects (writing TCCR1B = 0 stops Timer1). For tests of what the
  // firmware does about it (its watchdog); false for an address outside
  // the I/O space.
  bool UpsetRegister(uint16_t address, uint8_t value);
  const AvrCoreCounters& counters() const { return counters_; }
  // simavr's state (cpu_Running, cpu_Sleeping, ...), for messages.
  int state() const;

 private:
  explicit AvrCore(const AvrCoreOptions& options);
  struct Event {
    enum class Kind { kPin, kUartByte } kind = Kind::kPin;
    AvrPin pin;
    bool level = false;
    uint8_t byte = 0;
  };
  void Queue(uint64_t cycle, const Event& event);
  void FixUartPacing();
  uint32_t UartFrameRegisters() const;
  void ArmEventTimer();
  void Deliver(const Event& event);
  avr_irq_t* PinIrq(AvrPin pin) const;
  static uint64_t OnEventTimer(avr_t* avr, uint64_t when, void* param);
  static uint64_t OnBoundTimer(avr_t* avr, uint64_t when, void* param);
  static void OnResetHook(avr_t* avr);
  static void RegisterCore(avr_t* avr, AvrCore* core);
  static void UnregisterCore(avr_t* avr);
  static void OnUartOutput(avr_irq_t* irq, uint32_t value, void* param);
  static void OnPinChange(avr_irq_t* irq, uint32_t value, void* param);

  AvrCoreOptions options_;
  avr_t* avr_ = nullptr;
  void (*mcu_reset_)(avr_t*) = nullptr;
  // simavr's run callback as avr_init set it (see RunUntil).
  void (*normal_run_)(avr_t*) = nullptr;
  std::multimap<uint64_t, Event> events_;
  uint64_t event_timer_cycle_ = 0;
  // UartFrameRegisters() when FixUartPacing last ran.
  uint32_t uart_frame_registers_ = 0;
  std::vector<UartWatcher> uart_watchers_;
  struct PinTap {
    AvrCore* core;
    PinWatcher watcher;
  };
  std::vector<std::unique_ptr<PinTap>> pin_taps_;
  AvrCoreCounters counters_;
};

}  // namespace roomfix::firmware

#endif  // ROOMFIX_SIM_FIRMWARE_AVR_CORE_H_
