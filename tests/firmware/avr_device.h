#ifndef ROOMFIX_TESTS_FIRMWARE_AVR_DEVICE_H_
#define ROOMFIX_TESTS_FIRMWARE_AVR_DEVICE_H_

#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "sim/firmware/avr_core.h"

namespace roomfix::testing {

// One simulated ATmega328P at 16 MHz running a firmware ELF in simavr,
// cycle by cycle: bytes in and out of USART0 with the cycle of each, pin
// edges on PB1/PB2 (the beacon's drive), pins PB0/PD2 driven by the test.
// A test-only face on the simulator's firmware::AvrCore for single-device
// tests; the simulator's lockstep world (sim/firmware) is the many-device
// one.
class AvrDevice {
 public:
  static constexpr uint64_t kHz = 16000000;
  static constexpr uint64_t kCyclesPerUs = 16;
  static constexpr uint64_t kCyclesPerUartByte = 640;  // 10 bits at 250 kb/s

  AvrDevice() = default;
  ~AvrDevice();
  AvrDevice(const AvrDevice&) = delete;
  AvrDevice& operator=(const AvrDevice&) = delete;

  // Loads the ELF with `eeprom` at EEPROM address 0 (the rest erased, 0xFF).
  bool Load(const std::string& elf_path, const std::vector<uint8_t>& eeprom, std::string* error);
  // Runs until the cycle count reaches `cycle`; false if the core crashed.
  bool RunUntil(uint64_t cycle);
  bool RunFor(uint64_t cycles) { return RunUntil(cycle() + cycles); }
  uint64_t cycle() const;
  // Queues bytes on the UART's input now: simavr delivers the first one a
  // byte time (640 cycles) later and the others a byte time apart.
  void SendBytes(const std::vector<uint8_t>& bytes);
  void SetPin(char port, int pin, bool high);
  // A reset as the reset pin gives (EEPROM kept).
  void Reset();
  // An I/O register upset (firmware::AvrCore::UpsetRegister).
  bool UpsetRegister(uint16_t address, uint8_t value) {
    return core_->UpsetRegister(address, value);
  }
  // Resets so far, asked for or by the watchdog.
  int64_t resets() const { return core_->counters().resets; }

  struct Byte {
    uint64_t cycle;
    uint8_t value;
  };
  struct Edge {
    uint64_t cycle;
    int pin;  // 1: PB1, 2: PB2
    bool high;
  };
  const std::vector<Byte>& uart_out() const { return uart_out_; }
  const std::vector<Edge>& edges() const { return edges_; }
  void ClearOutput() {
    uart_out_.clear();
    edges_.clear();
  }

 private:
  std::unique_ptr<firmware::AvrCore> core_;
  std::vector<Byte> uart_out_;
  std::vector<Edge> edges_;
  bool pb_level_[8] = {};
};

}  // namespace roomfix::testing

#endif  // ROOMFIX_TESTS_FIRMWARE_AVR_DEVICE_H_
