// AvrCore on a real AVR program (avr/probe.c, built with avr-gcc): bytes,
// output edges and input captures cross between the simulated ATmega328P
// and the world at the cycles they should.
#include "sim/firmware/avr_core.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <vector>

namespace roomfix::firmware {
namespace {

std::string ProbeElf() { return std::string(ROOMFIX_AVR_TEST_PROGRAMS) + "/probe.elf"; }

// The probe's USART: UBRR0 = 16 with U2X0, 8N1: 8 x 17 = 136 cycles a bit,
// ten bits a byte.
constexpr uint64_t kProbeByteCycles = 1360;
constexpr double kProbeBaud = 16e6 / (8.0 * 17.0);
constexpr double kBaudTolerance = 1e-9;  // the same double division twice
// The probe's instructions between its answer's cause and the write (a
// loop polling a flag: up to two passes of ld/sbrs/rjmp, then the store).
constexpr uint64_t kPollSlackCycles = 16;
// From a byte becoming readable to the answer's write: the main loop's poll,
// the read, the counter, two comparisons and put()'s poll, about 30 cycles
// at -Os.
constexpr uint64_t kAnswerSlackCycles = 40;
// The world runs a core in quanta of 100 us (firmware_world.h); simavr's
// UART pacing is corrected at each (AvrCore::FixUartPacing).
constexpr uint64_t kQuantumCycles = 1600;
// From `TCNT1 = 0` to the `sbi PORTB` that raises PB1: the 16-bit store is
// two sts (2 cycles each), then the sbi (2): the timer counts from the first
// store, so the capture exceeds the edge-to-edge distance by 2 to 6 ticks.
constexpr uint64_t kStoreToEdgeMin = 1;
constexpr uint64_t kStoreToEdgeMax = 8;

struct Probe {
  std::unique_ptr<AvrCore> core;
  std::vector<std::pair<uint64_t, uint8_t>> out;
  std::vector<std::pair<uint64_t, bool>> pb1;
};

void RunInQuanta(AvrCore* core, uint64_t until) {
  while (core->cycle() < until) core->RunUntil(std::min(until, core->cycle() + kQuantumCycles));
}

// The first rising edge of PB1 (simavr also reports the level 0 when the
// firmware sets the pin's direction).
const std::pair<uint64_t, bool>* FirstRise(const std::vector<std::pair<uint64_t, bool>>& edges) {
  for (const auto& e : edges) {
    if (e.second) return &e;
  }
  return nullptr;
}

Probe StartProbe() {
  Probe p;
  AvrCoreOptions o;
  o.elf_path = ProbeElf();
  std::string error;
  p.core = AvrCore::Create(o, &error);
  EXPECT_NE(p.core, nullptr) << error;
  if (p.core == nullptr) return p;
  p.core->WatchUart([&out = p.out](uint64_t c, uint8_t b) { out.emplace_back(c, b); });
  p.core->WatchPin({'B', 1},
                   [&pb1 = p.pb1](uint64_t c, bool level) { pb1.emplace_back(c, level); });
  return p;
}

TEST(AvrCore, RefusesAFileThatIsNotAnAvrElf) {
  AvrCoreOptions o;
  o.elf_path = std::string(ROOMFIX_AVR_TEST_PROGRAMS) + "/no_such.elf";
  std::string error;
  EXPECT_EQ(AvrCore::Create(o, &error), nullptr);
  EXPECT_NE(error.find("not an AVR ELF"), std::string::npos) << error;
}

TEST(AvrCore, BootsAndSendsItsBytesAtTheBaudRateTheFirmwareSet) {
  Probe p = StartProbe();
  ASSERT_NE(p.core, nullptr);
  RunInQuanta(p.core.get(), 16000);  // 1 ms
  ASSERT_GE(p.out.size(), 2u);
  EXPECT_EQ(p.out[0].second, 'R');
  EXPECT_EQ(p.core->uart_byte_cycles(), kProbeByteCycles);
  EXPECT_NEAR(p.core->uart_baud(), kProbeBaud, kBaudTolerance);
  // The firmware waits for UDRE0 between bytes: the two bytes of an answer
  // go one frame apart (paced at 10 bits, not simavr's 11; the boot bytes
  // were paced before the firmware's U2X0 write, which simavr overlooks).
  p.out.clear();
  p.core->SendUart('E', 20000);
  RunInQuanta(p.core.get(), 20000 + 4 * kProbeByteCycles);
  ASSERT_EQ(p.out.size(), 2u);
  const uint64_t gap = p.out[1].first - p.out[0].first;
  EXPECT_GE(gap, kProbeByteCycles);
  EXPECT_LE(gap, kProbeByteCycles + kPollSlackCycles);
}

TEST(AvrCore, DeliversUartBytesAndTheFirmwareAnswersThem) {
  Probe p = StartProbe();
  ASSERT_NE(p.core, nullptr);
  RunInQuanta(p.core.get(), 16000);
  p.out.clear();
  const uint64_t start = 20000;
  p.core->SendUart('a', start);
  p.core->SendUart('E', start + kProbeByteCycles);
  RunInQuanta(p.core.get(), start + 10 * kProbeByteCycles);
  ASSERT_EQ(p.out.size(), 3u);
  EXPECT_EQ(p.out[0].second, 'b');
  EXPECT_EQ(p.out[1].second, 'e');
  EXPECT_EQ(p.out[2].second, 2);
  // A byte handed in at its start bit is readable one frame later.
  EXPECT_GE(p.out[0].first, start + kProbeByteCycles);
  EXPECT_LE(p.out[0].first, start + kProbeByteCycles + kAnswerSlackCycles);
  EXPECT_EQ(p.core->counters().late_events, 0);
}

TEST(AvrCore, InputCaptureTimesAnEdgeDrivenAtAnExactCycleFromTheOutputEdge) {
  Probe p = StartProbe();
  ASSERT_NE(p.core, nullptr);
  RunInQuanta(p.core.get(), 16000);
  p.core->SendUart('S', 20000);
  RunInQuanta(p.core.get(), 20000 + 2 * kProbeByteCycles);
  const auto* rise = FirstRise(p.pb1);
  ASSERT_NE(rise, nullptr);
  const uint64_t edge = rise->first;
  // An "echo" 3 ms after the "burst" (TCNT1's 16 bits hold 4.1 ms).
  constexpr uint64_t kDelay = 48000;
  p.out.clear();
  p.core->DrivePin({'B', 0}, true, edge + kDelay);
  RunInQuanta(p.core.get(), edge + kDelay + 5 * kProbeByteCycles);
  ASSERT_EQ(p.out.size(), 3u);
  EXPECT_EQ(p.out[0].second, 'C');
  const uint64_t icr = (static_cast<uint64_t>(p.out[1].second) << 8) | p.out[2].second;
  EXPECT_GE(icr, kDelay + kStoreToEdgeMin);
  EXPECT_LE(icr, kDelay + kStoreToEdgeMax);
  EXPECT_EQ(p.core->counters().late_events, 0);
}

TEST(AvrCore, ASleepingOrIdleCoreNeverRunsPastTheCycleAsked) {
  Probe p = StartProbe();
  ASSERT_NE(p.core, nullptr);
  // At most one instruction (4 cycles) past the bound, however far.
  constexpr uint64_t kLongestInstructionCycles = 4;
  for (uint64_t c : {1000ull, 1601ull, 50000ull, 1000000ull}) {
    p.core->RunUntil(c);
    EXPECT_GE(p.core->cycle(), c);
    EXPECT_LE(p.core->cycle(), c + kLongestInstructionCycles);
  }
}

TEST(AvrCore, AResetRestartsTheFirmwareAndKeepsTheClock) {
  Probe p = StartProbe();
  ASSERT_NE(p.core, nullptr);
  p.core->RunUntil(16000);
  p.out.clear();
  p.core->Reset();
  EXPECT_GE(p.core->cycle(), 16000u);
  p.core->RunUntil(32000);
  ASSERT_GE(p.out.size(), 1u);
  EXPECT_EQ(p.out[0].second, 'R');
  EXPECT_EQ(p.core->counters().resets, 1);
  // And its timers are armed again: a byte still gets through.
  p.out.clear();
  p.core->SendUart('a', 40000);
  p.core->RunUntil(40000 + 3 * kProbeByteCycles);
  ASSERT_EQ(p.out.size(), 1u);
  EXPECT_EQ(p.out[0].second, 'b');
}

}  // namespace
}  // namespace roomfix::firmware
