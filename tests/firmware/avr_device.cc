#include "tests/firmware/avr_device.h"

#include "sim_avr.h"

namespace roomfix::testing {

// A thin test face on firmware::AvrCore, the simulator's own core, so one
// piece of code loads an ELF and corrects simavr's defaults for both. (This
// harness once drove simavr itself with those defaults: bytes paced at 11
// bits (704 cycles at 250 kb/s, not 640), TXC0 set after every byte, and a
// usleep whenever the firmware slept, which made a test of a device in its
// fault loop take 18 s.)
AvrDevice::~AvrDevice() = default;

bool AvrDevice::Load(const std::string& elf_path, const std::vector<uint8_t>& eeprom,
                     std::string* error) {
  firmware::AvrCoreOptions options;
  options.elf_path = elf_path;
  options.frequency_hz = kHz;
  options.eeprom = eeprom;
  core_ = firmware::AvrCore::Create(options, error);
  if (core_ == nullptr) return false;
  core_->WatchUart([this](uint64_t cycle, uint8_t byte) { uart_out_.push_back({cycle, byte}); });
  for (int pin = 1; pin <= 2; ++pin) {
    // simavr notifies every write to the port (and every compare toggle's
    // update), changed or not: keep the edges.
    core_->WatchPin({'B', pin}, [this, pin](uint64_t cycle, bool level) {
      if (pb_level_[pin] == level) return;
      pb_level_[pin] = level;
      edges_.push_back({cycle, pin, level});
    });
  }
  return true;
}

bool AvrDevice::RunUntil(uint64_t target) {
  core_->RunUntil(target);
  return core_->state() != cpu_Crashed && core_->state() != cpu_Done;
}

uint64_t AvrDevice::cycle() const { return core_->cycle(); }

void AvrDevice::SendBytes(const std::vector<uint8_t>& bytes) {
  // As on a wire, back to back from now: AvrCore takes each byte at its
  // start bit and makes it readable a byte time later.
  const uint64_t byte_cycles =
      core_->uart_byte_cycles() > 0 ? core_->uart_byte_cycles() : kCyclesPerUartByte;
  uint64_t start = cycle();
  for (uint8_t b : bytes) {
    core_->SendUart(b, start);
    start += byte_cycles;
  }
}

void AvrDevice::SetPin(char port, int pin, bool high) {
  core_->DrivePin({port, pin}, high, cycle());
}

void AvrDevice::Reset() { core_->Reset(); }

}  // namespace roomfix::testing
