#include "msgio/process.h"

#include <gtest/gtest.h>

#include <map>

namespace roomfix {
namespace {

std::map<std::string, int64_t> AsMap(const std::vector<counter_t>& counters) {
  std::map<std::string, int64_t> m;
  for (const auto& c : counters) m[c.name] = c.count;
  return m;
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
  bus.decode_failures = 4;
  bus.handler_exceptions = 1;
  bus.last_error = "message on POSE does not decode as pose2d_t";
  const process_status_t s = status.Make(1, &bus);
  EXPECT_EQ(AsMap(s.rejected)["undecodable_message"], 4);
  EXPECT_EQ(AsMap(s.counters)["handler_exceptions"], 1);
  EXPECT_EQ(s.last_error, bus.last_error);
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
