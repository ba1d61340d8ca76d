#include "tests/firmware/avr_device.h"

#include <cstdlib>

#include "avr_eeprom.h"
#include "avr_ioport.h"
#include "avr_uart.h"
#include "sim/firmware/avr_core.h"
#include "sim_avr.h"
#include "sim_elf.h"

namespace roomfix::testing {

AvrDevice::~AvrDevice() {
  if (avr_) {
    avr_terminate(avr_);
    free(avr_);
  }
}

bool AvrDevice::Load(const std::string& elf_path, const std::vector<uint8_t>& eeprom,
                     std::string* error) {
  elf_firmware_t firmware = {};
  if (elf_read_firmware(elf_path.c_str(), &firmware) != 0) {
    *error = "simavr cannot read " + elf_path;
    return false;
  }
  avr_ = avr_make_mcu_by_name("atmega328p");
  if (!avr_) {
    roomfix::firmware::FreeElf(&firmware);
    *error = "simavr has no atmega328p";
    return false;
  }
  avr_init(avr_);
  avr_->log = LOG_NONE;
  firmware.frequency = kHz;
  avr_load_firmware(avr_, &firmware);
  roomfix::firmware::FreeElf(&firmware);
  if (!eeprom.empty()) {
    avr_eeprom_desc_t desc = {};
    desc.ee = const_cast<uint8_t*>(eeprom.data());
    desc.offset = 0;
    desc.size = static_cast<uint16_t>(eeprom.size());
    avr_ioctl(avr_, AVR_IOCTL_EEPROM_SET, &desc);
  }
  // No "UART0: ..." lines on stdout: the bytes go to the test.
  uint32_t flags = 0;
  avr_ioctl(avr_, AVR_IOCTL_UART_GET_FLAGS('0'), &flags);
  flags &= ~AVR_UART_FLAG_STDIO;
  avr_ioctl(avr_, AVR_IOCTL_UART_SET_FLAGS('0'), &flags);
  avr_irq_register_notify(avr_io_getirq(avr_, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUTPUT),
                          &AvrDevice::OnUartOut, this);
  for (int pin = 1; pin <= 2; ++pin) {
    avr_irq_register_notify(avr_io_getirq(avr_, AVR_IOCTL_IOPORT_GETIRQ('B'), pin),
                            &AvrDevice::OnPortB, this);
  }
  return true;
}

void AvrDevice::OnUartOut(avr_irq_t* /*irq*/, uint32_t value, void* param) {
  auto* self = static_cast<AvrDevice*>(param);
  self->uart_out_.push_back({self->avr_->cycle, static_cast<uint8_t>(value)});
}

void AvrDevice::OnPortB(avr_irq_t* irq, uint32_t value, void* param) {
  auto* self = static_cast<AvrDevice*>(param);
  const int pin = static_cast<int>(irq->irq);
  const bool high = (value & 0xFF) != 0;
  if (pin < 0 || pin > 7 || self->pb_level_[pin] == high) return;
  self->pb_level_[pin] = high;
  self->edges_.push_back({self->avr_->cycle, pin, high});
}

bool AvrDevice::RunUntil(uint64_t target) {
  while (avr_->cycle < target) {
    const int state = avr_run(avr_);
    if (state == cpu_Done || state == cpu_Crashed) return false;
  }
  return true;
}

uint64_t AvrDevice::cycle() const { return avr_->cycle; }

void AvrDevice::SendBytes(const std::vector<uint8_t>& bytes) {
  avr_irq_t* in = avr_io_getirq(avr_, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_INPUT);
  for (uint8_t b : bytes) avr_raise_irq(in, b);
}

void AvrDevice::SetPin(char port, int pin, bool high) {
  avr_raise_irq(avr_io_getirq(avr_, AVR_IOCTL_IOPORT_GETIRQ(port), pin), high ? 1 : 0);
}

void AvrDevice::Reset() { avr_reset(avr_); }

}  // namespace roomfix::testing
