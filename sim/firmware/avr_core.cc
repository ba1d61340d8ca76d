#include "sim/firmware/avr_core.h"

extern "C" {
#include <avr_eeprom.h>
#include <avr_ioport.h>
#include <avr_uart.h>
#include <sim_avr.h>
#include <sim_elf.h>
#include <sim_io.h>
}

#include <cstdarg>
#include <cstring>
#include <limits>
#include <mutex>

namespace roomfix::firmware {

namespace {

// ATmega328P USART0 registers (data-space addresses, datasheet section 36
// "Register Summary"), read to know the baud rate and frame the firmware set.
constexpr uint16_t kUcsr0a = 0xC0;
constexpr uint16_t kUcsr0b = 0xC1;
constexpr uint16_t kUcsr0c = 0xC2;
constexpr uint16_t kUbrr0l = 0xC4;
constexpr uint16_t kUbrr0h = 0xC5;

// simavr logs through one process-wide function; its messages about a
// firmware (a stray UDR read, a full FIFO) are the firmware's business and
// are counted, not printed. Installed once.
void QuietLogger(avr_t*, const int, const char*, va_list) {}
void InstallQuietLogger() {
  static std::once_flag once;
  std::call_once(once, [] { avr_global_logger_set(&QuietLogger); });
}

// simavr's raw run loop calls this while the firmware sleeps, to keep pace
// with the wall clock; we pace simulated time ourselves.
void NoSleep(avr_t*, avr_cycle_count_t) {}

// Frees what simavr's elf_read_firmware allocated in *elf once
// avr_load_firmware has copied it (simavr 1.6 has no function for it).
void FreeElf(elf_firmware_t* elf) {
  free(elf->flash);
  free(elf->eeprom);
  free(elf->fuse);
  free(elf->lockbits);
#if ELF_SYMBOLS
  for (uint32_t i = 0; i < elf->symbolcount; ++i) free(elf->symbol[i]);
  free(elf->symbol);
#endif
}

}  // namespace

bool AvrCoreOptions::IsValid(std::string* error) const {
  if (elf_path.empty()) {
    *error = "no firmware ELF given";
    return false;
  }
  if (frequency_hz < 1000000 || frequency_hz > 20000000) {
    *error = "frequency_hz must be in [1, 20] MHz (the ATmega328P's range)";
    return false;
  }
  if (eeprom.size() > 1024) {
    *error = "eeprom image larger than the ATmega328P's 1024 bytes";
    return false;
  }
  return true;
}

// avr_t has no user pointer; the reset hook finds its AvrCore here.
namespace {
std::mutex& CoresMutex() {
  static std::mutex m;
  return m;
}
std::map<avr_t*, AvrCore*>& Cores() {
  static std::map<avr_t*, AvrCore*> cores;
  return cores;
}
}  // namespace

void AvrCore::RegisterCore(avr_t* avr, AvrCore* core) {
  std::lock_guard<std::mutex> lock(CoresMutex());
  Cores()[avr] = core;
}

void AvrCore::UnregisterCore(avr_t* avr) {
  std::lock_guard<std::mutex> lock(CoresMutex());
  Cores().erase(avr);
}

AvrCore::AvrCore(const AvrCoreOptions& options) : options_(options) {}

AvrCore::~AvrCore() {
  if (avr_ == nullptr) return;
  UnregisterCore(avr_);
  avr_terminate(avr_);
  // avr_terminate frees the core's I/O but not the core itself (simavr's
  // examples exit instead); the struct was malloc'ed by the MCU's maker.
  free(avr_);
}

std::unique_ptr<AvrCore> AvrCore::Create(const AvrCoreOptions& options, std::string* error) {
  if (!options.IsValid(error)) return nullptr;
  InstallQuietLogger();
  elf_firmware_t elf;
  std::memset(&elf, 0, sizeof(elf));
  if (elf_read_firmware(options.elf_path.c_str(), &elf) != 0) {
    *error = options.elf_path + ": not an AVR ELF simavr can read";
    return nullptr;
  }
  std::unique_ptr<AvrCore> core(new AvrCore(options));
  core->avr_ = avr_make_mcu_by_name(options.mcu.c_str());
  if (core->avr_ == nullptr) {
    *error = "simavr does not know the MCU " + options.mcu;
    FreeElf(&elf);
    return nullptr;
  }
  avr_t* avr = core->avr_;
  avr_init(avr);
  avr->log = LOG_NONE;
  elf.mmcu[options.mcu.copy(elf.mmcu, sizeof(elf.mmcu) - 1)] = '\0';
  elf.frequency = options.frequency_hz;
  avr_load_firmware(avr, &elf);
  FreeElf(&elf);
  avr->frequency = options.frequency_hz;
  avr->sleep = &NoSleep;
  if (!options.eeprom.empty()) {
    std::vector<uint8_t> image = options.eeprom;
    avr_eeprom_desc_t desc{image.data(), 0, static_cast<uint32_t>(image.size())};
    avr_ioctl(avr, AVR_IOCTL_EEPROM_SET, &desc);
  }
  uint32_t flags = 0;
  avr_ioctl(avr, AVR_IOCTL_UART_GET_FLAGS('0'), &flags);
  flags &= ~(AVR_UART_FLAG_POLL_SLEEP | AVR_UART_FLAG_STDIO);
  avr_ioctl(avr, AVR_IOCTL_UART_SET_FLAGS('0'), &flags);
  avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUTPUT),
                          &AvrCore::OnUartOutput, core.get());
  // The core's own reset hook runs inside avr_reset after the cycle timers
  // were dropped: ours re-arms them. avr->data's spare pointer is not ours,
  // so the core is found through the hook table below.
  core->mcu_reset_ = avr->reset;
  avr->reset = &AvrCore::OnResetHook;
  core->normal_run_ = avr->run;
  RegisterCore(avr, core.get());
  return core;
}

void AvrCore::OnResetHook(avr_t* avr) {
  AvrCore* core = nullptr;
  {
    std::lock_guard<std::mutex> lock(CoresMutex());
    auto it = Cores().find(avr);
    if (it != Cores().end()) core = it->second;
  }
  if (core == nullptr) return;
  if (core->mcu_reset_ != nullptr) core->mcu_reset_(avr);
  ++core->counters_.resets;
  // Pending bytes for the UART were on a wire into a chip that was just
  // reset; pin levels too are the world's, re-driven when they change.
  for (auto it = core->events_.begin(); it != core->events_.end();) {
    it = it->second.kind == Event::Kind::kUartByte ? core->events_.erase(it) : std::next(it);
  }
  core->event_timer_cycle_ = 0;
  core->ArmEventTimer();
}

uint64_t AvrCore::cycle() const { return avr_->cycle; }

bool AvrCore::stopped() const {
  return avr_->state == cpu_Done || avr_->state == cpu_Crashed || avr_->state == cpu_Stopped;
}

int AvrCore::state() const { return avr_->state; }

uint64_t AvrCore::OnBoundTimer(avr_t*, uint64_t, void*) { return 0; }

// simavr 1.6 (and its master branch) paces USART bytes at start + data +
// parity + stop bits, a parity bit counted whether or not parity is on:
// 11 bit times for 8N1 instead of 10, so a firmware's frames would leave
// 10 % slower than on the chip. The UART's own struct (the io port of kind
// "uart" named '0') is set to the true frame length whenever the frame's
// registers (UBRR0, UCSR0A's U2X0, UCSR0B, UCSR0C) change: RunUntil looks
// at them after every instruction (four loads; checking once per RunUntil
// left a firmware that sets its baud rate and sends within one long
// RunUntil with 11-bit bytes until the call returned).
uint32_t AvrCore::UartFrameRegisters() const {
  const uint8_t* d = avr_->data;
  return static_cast<uint32_t>(d[kUbrr0l]) | (static_cast<uint32_t>(d[kUbrr0h]) << 8) |
         (static_cast<uint32_t>(d[kUcsr0c]) << 16) |
         (static_cast<uint32_t>((d[kUcsr0a] & 0x02) | (d[kUcsr0b] & 0x1C)) << 24);
}

void AvrCore::FixUartPacing() {
  uart_frame_registers_ = UartFrameRegisters();
  const uint64_t real = uart_byte_cycles();
  if (real == 0) return;
  for (avr_io_t* io = avr_->io_port; io != nullptr; io = io->next) {
    if (io->kind == nullptr || std::strcmp(io->kind, "uart") != 0) continue;
    auto* uart = reinterpret_cast<avr_uart_t*>(io);
    if (uart->name == '0' && uart->cycles_per_byte != real) uart->cycles_per_byte = real;
  }
}

void AvrCore::RunUntil(uint64_t cycle) {
  if (avr_->cycle >= cycle) return;
  // A sleeping core jumps to its next timer: this one bounds the jump.
  avr_cycle_timer_register(avr_, cycle - avr_->cycle, &AvrCore::OnBoundTimer, this);
  while (avr_->cycle < cycle) {
    if (stopped()) {
      ++counters_.stops;
      avr_->cycle = cycle;
      break;
    }
    if (UartFrameRegisters() != uart_frame_registers_) FixUartPacing();
    avr_run(avr_);
    ++counters_.instructions_run;
  }
  // simavr resets for its watchdog through the run callback (it swaps
  // avr->run for one that calls avr_reset), which takes effect at the next
  // avr_run; a sleeping core has meanwhile jumped on to its next timer,
  // here the bound of this call. Run it now, so a watchdog reset due in
  // this call happens in it (at its end: up to the call's length late, as
  // an asleep core jumps; FirmwareWorld's short quanta keep that small).
  if (avr_->run != normal_run_ && !stopped()) {
    avr_run(avr_);
    ++counters_.instructions_run;
  }
}

void AvrCore::Reset() {
  events_.clear();
  event_timer_cycle_ = 0;
  // avr_reset calls OnResetHook, which re-arms the timers. It clears the
  // I/O registers, MCUSR too: a power cycle leaves PORF set.
  avr_reset(avr_);
  constexpr uint16_t kMcusr = 0x54;
  avr_->data[kMcusr] |= 0x01;
}

void AvrCore::Queue(uint64_t cycle, const Event& event) {
  if (cycle <= avr_->cycle) {
    ++counters_.late_events;
    Deliver(event);
    return;
  }
  events_.emplace(cycle, event);
  ArmEventTimer();
}

void AvrCore::ArmEventTimer() {
  if (events_.empty()) return;
  const uint64_t next = events_.begin()->first;
  if (event_timer_cycle_ != 0 && event_timer_cycle_ <= next) return;
  event_timer_cycle_ = next;
  avr_cycle_timer_register(avr_, next > avr_->cycle ? next - avr_->cycle : 1,
                           &AvrCore::OnEventTimer, this);
}

uint64_t AvrCore::OnEventTimer(avr_t* avr, uint64_t when, void* param) {
  auto* core = static_cast<AvrCore*>(param);
  while (!core->events_.empty() && core->events_.begin()->first <= avr->cycle) {
    const Event e = core->events_.begin()->second;
    core->events_.erase(core->events_.begin());
    core->Deliver(e);
  }
  if (core->events_.empty()) {
    core->event_timer_cycle_ = 0;
    return 0;
  }
  // Returning an absolute cycle re-registers this timer.
  core->event_timer_cycle_ = std::max<uint64_t>(core->events_.begin()->first, when + 1);
  return core->event_timer_cycle_;
}

avr_irq_t* AvrCore::PinIrq(AvrPin pin) const {
  return avr_io_getirq(avr_, AVR_IOCTL_IOPORT_GETIRQ(pin.port), pin.bit);
}

void AvrCore::Deliver(const Event& event) {
  if (event.kind == Event::Kind::kPin) {
    avr_irq_t* irq = PinIrq(event.pin);
    if (irq != nullptr) avr_raise_irq(irq, event.level ? 1 : 0);
    return;
  }
  // The receiver must be on (RXEN0) and simavr's FIFO not full; otherwise
  // the byte is lost as a real USART would lose it.
  const bool rx_enabled = (avr_->data[kUcsr0b] & (1 << 4)) != 0;
  if (!rx_enabled) {
    ++counters_.uart_bytes_refused;
    return;
  }
  ++counters_.uart_bytes_in;
  avr_raise_irq(avr_io_getirq(avr_, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_INPUT), event.byte);
}

bool AvrCore::UpsetRegister(uint16_t address, uint8_t value) {
  constexpr uint16_t kFirstIo = 0x20;
  constexpr uint16_t kLastIo = 0xFF;  // the ATmega328P's extended I/O ends here
  if (address < kFirstIo || address > kLastIo) return false;
  // As simavr's own store does: the module's write handler when it has one
  // (it updates the register and its state), else the register alone.
  const auto& io = avr_->io[AVR_DATA_TO_IO(address)];
  if (io.w.c != nullptr) {
    io.w.c(avr_, address, value, io.w.param);
  } else {
    avr_->data[address] = value;
  }
  return true;
}

void AvrCore::DrivePin(AvrPin pin, bool level, uint64_t cycle) {
  Event e;
  e.kind = Event::Kind::kPin;
  e.pin = pin;
  e.level = level;
  Queue(cycle, e);
}

void AvrCore::SendUart(uint8_t byte, uint64_t cycle) {
  Event e;
  e.kind = Event::Kind::kUartByte;
  e.byte = byte;
  Queue(cycle, e);
}

void AvrCore::WatchUart(UartWatcher watcher) { uart_watchers_.push_back(std::move(watcher)); }

void AvrCore::OnUartOutput(avr_irq_t*, uint32_t value, void* param) {
  auto* core = static_cast<AvrCore*>(param);
  // simavr's USART has no transmit double buffer: UDRE0 rises only when a
  // byte has gone out, so a firmware writing a frame byte by byte on UDRE0
  // sees TXC0 set after every byte, where the chip (the next byte already
  // waiting in UDR0 when the shift register empties) sets it after the
  // last one only. A firmware that clears TXC0 before a frame and waits for
  // it after the last byte would then return at once, one byte early. A
  // write means the transmitter has more to send: TXC0 is cleared here.
  constexpr uint8_t kTxc0 = 1 << 6;
  core->avr_->data[kUcsr0a] &= static_cast<uint8_t>(~kTxc0);
  ++core->counters_.uart_bytes_out;
  for (auto& w : core->uart_watchers_) w(core->avr_->cycle, static_cast<uint8_t>(value));
}

void AvrCore::WatchPin(AvrPin pin, PinWatcher watcher) {
  pin_taps_.push_back(std::make_unique<PinTap>(PinTap{this, std::move(watcher)}));
  avr_irq_t* irq = PinIrq(pin);
  if (irq != nullptr) avr_irq_register_notify(irq, &AvrCore::OnPinChange, pin_taps_.back().get());
}

void AvrCore::OnPinChange(avr_irq_t*, uint32_t value, void* param) {
  auto* tap = static_cast<PinTap*>(param);
  tap->watcher(tap->core->avr_->cycle, (value & 0xFF) != 0);
}

uint64_t AvrCore::uart_byte_cycles() const {
  const uint32_t ubrr = avr_->data[kUbrr0l] | ((avr_->data[kUbrr0h] & 0x0F) << 8);
  const bool u2x = (avr_->data[kUcsr0a] & (1 << 1)) != 0;
  const uint8_t c = avr_->data[kUcsr0c];
  const int ucsz = ((c >> 1) & 0x3) | ((avr_->data[kUcsr0b] & (1 << 2)) ? 4 : 0);
  static constexpr int kDataBits[8] = {5, 6, 7, 8, 8, 8, 8, 9};
  const int parity = ((c >> 4) & 0x3) != 0 ? 1 : 0;
  const int stop = (c & (1 << 3)) ? 2 : 1;
  const int bits = 1 + kDataBits[ucsz] + parity + stop;
  // Datasheet table 20-1: baud = f / (16 (UBRR + 1)), or / 8 with U2X.
  const uint64_t cycles_per_bit = static_cast<uint64_t>(ubrr + 1) * (u2x ? 8 : 16);
  const bool configured = (avr_->data[kUcsr0b] & ((1 << 3) | (1 << 4))) != 0;
  return configured ? cycles_per_bit * bits : 0;
}

double AvrCore::uart_baud() const {
  const uint32_t ubrr = avr_->data[kUbrr0l] | ((avr_->data[kUbrr0h] & 0x0F) << 8);
  const bool u2x = (avr_->data[kUcsr0a] & (1 << 1)) != 0;
  return static_cast<double>(options_.frequency_hz) / ((ubrr + 1.0) * (u2x ? 8 : 16));
}

}  // namespace roomfix::firmware
