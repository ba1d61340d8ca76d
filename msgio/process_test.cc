#include "msgio/process.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <map>

namespace roomfix {
namespace {

std::map<std::string, int64_t> AsMap(const std::vector<counter_t>& counters) {
  std::map<std::string, int64_t> m;
  for (const auto& c : counters) m[c.name] = c.count;
  return m;
}

// https://no-color.org: a non-empty NO_COLOR turns colour off; a
// command-line mode overrides it either way.
TEST(LogColorWanted, AutoColoursOnlyATerminalWithoutNoColor) {
  EXPECT_TRUE(LogColorWanted("auto", true, nullptr));
  EXPECT_TRUE(LogColorWanted("auto", true, ""));
  EXPECT_FALSE(LogColorWanted("auto", true, "1"));
  EXPECT_FALSE(LogColorWanted("auto", false, nullptr));
  EXPECT_TRUE(LogColorWanted("always", false, "1"));
  EXPECT_FALSE(LogColorWanted("never", true, nullptr));
}

TEST(SetUpLogging, RefusesAnUnknownColourMode) {
  EXPECT_FALSE(SetUpLogging("set_up_logging_test", "info", "sometimes"));
}

TEST(StatusReporter, FillsTheHeartbeatWithCountersByReason) {
  StatusReporter status("trilat_proc", 1000000);
  status.SetState(process_status_t::STATE_RUNNING);
  status.AddInputs(10);
  status.AddOutputs(7);
  status.Reject("negative_range");
  status.Reject("negative_range");
  status.Reject("too_few_ranges");
  status.Count("warm_starts", 5);
  status.SetError("range 3 is negative", 2500000);

  const process_status_t s = status.Make(4000000, nullptr);
  EXPECT_EQ(s.utime, 4000000);
  EXPECT_EQ(s.process, "trilat_proc");
  EXPECT_GT(s.pid, 0);
  EXPECT_FALSE(s.host.empty());
  EXPECT_EQ(s.uptime_us, 3000000);
  EXPECT_EQ(s.state, process_status_t::STATE_RUNNING);
  EXPECT_EQ(s.inputs, 10);
  EXPECT_EQ(s.outputs, 7);
  EXPECT_EQ(s.num_rejected, 2);
  EXPECT_EQ(AsMap(s.rejected),
            (std::map<std::string, int64_t>{{"negative_range", 2}, {"too_few_ranges", 1}}));
  EXPECT_EQ(AsMap(s.counters), (std::map<std::string, int64_t>{{"warm_starts", 5}}));
  EXPECT_EQ(s.last_error, "range 3 is negative");
  EXPECT_EQ(s.last_error_utime, 2500000);
}

TEST(StatusReporter, FoldsInTheBusFailures) {
  StatusReporter status("x", 0);
  BusStats bus;
  status.Reject("unknown_robot");
  bus.decode_failures = 4;
  bus.refused = {{"POSE_CAMERA.wrong_type", 3}, {"STATUS.negative_length", 1}};
  bus.handler_exceptions = 1;
  bus.last_error = "message on POSE_CAMERA refused (wrong_type): not a pose2d_t (fingerprint)";
  const process_status_t s = status.Make(1, &bus);
  EXPECT_EQ(AsMap(s.rejected), (std::map<std::string, int64_t>{{"POSE_CAMERA.wrong_type", 3},
                                                               {"STATUS.negative_length", 1},
                                                               {"unknown_robot", 1}}));
  EXPECT_EQ(AsMap(s.counters)["handler_exceptions"], 1);
  EXPECT_EQ(s.last_error, bus.last_error);
}

// The heartbeat must pass every receiver's wire check (wire_check.h), however
// long the texts and lists the process fed it.
TEST(StatusReporter, KeepsTheHeartbeatWithinTheWireCaps) {
  StatusReporter status(std::string(1000, 'p'), 0);
  for (int i = 0; i < 2 * wire_cap::kStatusCounters; ++i) {
    status.Reject(std::string(300, 'r') + std::to_string(i));
  }
  status.SetError(std::string(10000, 'e'), 1);
  const process_status_t s = status.Make(2, nullptr);
  EXPECT_EQ(s.process.size(), static_cast<size_t>(wire_cap::kNameBytes - 1));
  EXPECT_EQ(s.last_error.size(), static_cast<size_t>(wire_cap::kLastErrorBytes - 1));
  EXPECT_EQ(s.num_rejected, wire_cap::kStatusCounters);
  std::vector<uint8_t> bytes(static_cast<size_t>(s.getEncodedSize()));
  ASSERT_EQ(s.encode(bytes.data(), 0, static_cast<int>(bytes.size())),
            static_cast<int>(bytes.size()));
  EXPECT_EQ(CheckEncoded<process_status_t>(bytes.data(), static_cast<int>(bytes.size())), nullptr);
}

// Contract of issue #15: transport losses add into `dropped` (with the
// process's own drops) and appear as counters by cause; malformed datagrams
// are counted but are not losses.
TEST(StatusReporter, AddsTheTransportLossesIntoDroppedByCause) {
  StatusReporter status("x", 0);
  status.AddDropped(2);  // The process's own queue.
  BusStats bus;
  bus.dropped_kernel_overflow = 100;
  bus.dropped_queue_overflow = 20;
  bus.fragments_expired = 3;
  bus.fragments_over_budget = 4;
  bus.fragments_malformed = 5;
  bus.fragments_duplicate = 6;
  bus.datagrams_malformed = 7;
  const process_status_t s = status.Make(1, &bus);
  EXPECT_EQ(s.dropped, 2 + 100 + 20 + 3 + 4 + 5 + 6);
  EXPECT_EQ(AsMap(s.counters), (std::map<std::string, int64_t>{{"dropped_kernel_overflow", 100},
                                                               {"dropped_queue_overflow", 20},
                                                               {"fragments_expired", 3},
                                                               {"fragments_over_budget", 4},
                                                               {"fragments_malformed", 5},
                                                               {"fragments_duplicate", 6},
                                                               {"datagrams_malformed", 7}}));
  EXPECT_EQ(status.Make(1, nullptr).dropped, 2);
}

TEST(StatusReporter, PublishesOncePerSecondOfItsClock) {
  std::string error;
  auto bus = LcmBus::Create("memq://", &error);
  ASSERT_NE(bus, nullptr);
  std::vector<int64_t> times;
  bus->Subscribe<process_status_t>(
      kStatusChannel,
      [&](const process_status_t& s, const MessageInfo&) { times.push_back(s.utime); });
  StatusReporter status("x", 0);
  for (int64_t t = 0; t <= 3000000; t += 100000) status.MaybePublish(bus.get(), t);
  while (bus->Handle(0) > 0) {
  }
  EXPECT_EQ(times, (std::vector<int64_t>{0, 1000000, 2000000, 3000000}));
}

}  // namespace
}  // namespace roomfix

namespace roomfix {
namespace {

// A transport that never runs dry: its descriptor is always readable and
// every Handle() finds another message.
class FloodedBus final : public Bus {
 public:
  FloodedBus() {
    if (::pipe(fds_) == 0) {
      const char byte = 1;
      [[maybe_unused]] ssize_t n = ::write(fds_[1], &byte, 1);
    }
  }
  ~FloodedBus() override {
    ::close(fds_[0]);
    ::close(fds_[1]);
  }
  bool PublishRaw(const std::string&, const void*, int) override { return true; }
  SubscriptionId SubscribeRaw(const std::string&, RawHandler) override { return 0; }
  void Unsubscribe(SubscriptionId) override {}
  int Handle(int) override {
    ++handled;
    return 1;
  }
  int Fileno() const override { return fds_[0]; }
  int64_t handled = 0;

 private:
  int fds_[2] = {-1, -1};
};

TEST(RunLoop, KeepsTickingWhileTheTransportIsFlooded) {
  FloodedBus bus;
  int ticks = 0;
  RunLoopOptions options;
  options.tick_period_ms = 10;
  options.duration_s = 0.3;
  EXPECT_EQ(RunLoop(
                &bus, [&](int64_t) { ++ticks; }, options),
            0);
  // About 30 tick periods; a loop that drained forever would tick never.
  EXPECT_GE(ticks, 10);
  EXPECT_GT(bus.handled, 1000);
}

}  // namespace
}  // namespace roomfix

namespace roomfix {
namespace {

// A loop that calls Handle(0) once per frame reads one batch per call; after
// a flood DrainBus must clear the whole backlog in one call when the budget
// allows, and stop at the budget when it does not.
TEST(DrainBus, ClearsTheBacklogWithinItsBudget) {
  std::string error;
  auto bus = LcmBus::Create("memq://", &error);
  ASSERT_NE(bus, nullptr) << error;
  int delivered = 0;
  bus->SubscribeRaw(".*", [&](const MessageInfo&, const void*, int) { ++delivered; });
  constexpr int kBacklog = 500;
  const uint8_t byte = 0;
  for (int i = 0; i < kBacklog; ++i) ASSERT_TRUE(bus->PublishRaw("X", &byte, 1));
  EXPECT_EQ(DrainBus(bus.get(), 10'000'000), kBacklog);
  EXPECT_EQ(delivered, kBacklog);
  EXPECT_EQ(DrainBus(bus.get(), 10'000'000), 0) << "nothing left";
  for (int i = 0; i < kBacklog; ++i) ASSERT_TRUE(bus->PublishRaw("X", &byte, 1));
  // A spent budget still reads what one Handle(0) returns, never blocks.
  const int handled = DrainBus(bus.get(), 0);
  EXPECT_GE(handled, 1);
  EXPECT_LT(handled, kBacklog);
}

}  // namespace
}  // namespace roomfix
