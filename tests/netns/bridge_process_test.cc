// The radio side as processes: roomfix_sim plays the wall devices on a
// pseudo-terminal, zigbee_bridge reads it and publishes RANGES over LCM's UDP
// multicast, trilat_proc turns them into poses. Runs inside a private network
// namespace (scripts/netns_run), so nothing leaves the host.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/stat.h>

#include <chrono>
#include <thread>

#include "msgio/bus.h"
#include "msgio/process.h"
#include "roomfix/pose2d_t.hpp"
#include "roomfix/process_status_t.hpp"
#include "roomfix/range_set_t.hpp"
#include "tests/testing/demo_site.h"
#include "tests/testing/test_paths.h"

namespace roomfix {
namespace {

using testing::BinDir;
using testing::ChildProcess;
using testing::DemoSitePath;
using testing::WaitForPath;

std::vector<std::string> Simulator(const std::string& link) {
  return {BinDir() + "/roomfix_sim",
          "--config",
          DemoSitePath(),
          "--radio-pty",
          "--pty-link",
          link,
          "--faults",
          "all",
          "--log-level",
          "warn"};
}

int64_t Counter(const std::vector<counter_t>& counters, const std::string& name) {
  for (const counter_t& c : counters) {
    if (c.name == name) return c.count;
  }
  return 0;
}

class BridgeProcess : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string error;
    bus_ = LcmBus::Create(kDefaultLcmUrl, &error);
    ASSERT_NE(bus_, nullptr) << error;
    bus_->Subscribe<range_set_t>(
        "RANGES", [this](const range_set_t& s, const MessageInfo&) { sets_.push_back(s); });
    bus_->Subscribe<pose2d_t>(
        "POSE_ULTRASOUND", [this](const pose2d_t& p, const MessageInfo&) { poses_.push_back(p); });
    bus_->Subscribe<process_status_t>("STATUS",
                                      [this](const process_status_t& s, const MessageInfo&) {
                                        if (s.process == "zigbee_bridge")
                                          bridge_status_.push_back(s);
                                      });
  }

  std::unique_ptr<LcmBus> bus_;
  std::vector<range_set_t> sets_;
  std::vector<pose2d_t> poses_;
  std::vector<process_status_t> bridge_status_;
  testing::TempDir dir_;
};

TEST_F(BridgeProcess, RangeSetsFlowFromTheVirtualDevicesToPosesAndSurviveAnUnplug) {
  const std::string link = dir_.File("radio");
  auto sim = std::make_unique<ChildProcess>(Simulator(link), dir_.File("sim.out"));
  ASSERT_TRUE(WaitForPath(link, 10)) << "roomfix_sim made no pseudo-terminal";
  ChildProcess bridge({BinDir() + "/zigbee_bridge", "--config", DemoSitePath(), "--port", link,
                       "--api-mode", "2", "--reopen-max", "0.2", "--log-level", "warn"});
  ChildProcess trilat({BinDir() + "/trilat_proc", "--config", DemoSitePath(), "--method", "robust",
                       "--log-level", "warn"});
  ASSERT_TRUE(HandleUntil(
      bus_.get(), [&] { return sets_.size() >= 20 && poses_.size() >= 10; }, 20))
      << sets_.size() << " range sets, " << poses_.size() << " poses";
  EXPECT_EQ(testing::ReadFile(dir_.File("sim.out")).substr(0, link.size()), link)
      << "roomfix_sim prints the device path first";
  for (const range_set_t& s : sets_) {
    EXPECT_EQ(s.beacon_id, 1);
    EXPECT_EQ(s.num_expected, 4);
    EXPECT_LE(s.num_ranges, 4);
  }

  // Unplug: the device vanishes with the process that made it.
  sim->Signal(SIGKILL);
  sim->Wait(5);
  sim.reset();
  const size_t statuses_before = bridge_status_.size();
  ASSERT_TRUE(HandleUntil(
      bus_.get(),
      [&] {
        return bridge_status_.size() > statuses_before &&
               bridge_status_.back().state == process_status_t::STATE_DEGRADED;
      },
      5))
      << "zigbee_bridge did not report the device gone";
  EXPECT_NE(bridge_status_.back().last_error.find(link), std::string::npos)
      << bridge_status_.back().last_error;

  // Plugged in again: range sets resume, the bridge says it is running.
  const size_t sets_before = sets_.size();
  const auto replug = std::chrono::steady_clock::now();
  sim = std::make_unique<ChildProcess>(Simulator(link));
  ASSERT_TRUE(HandleUntil(
      bus_.get(),
      [&] {
        return sets_.size() >= sets_before + 10 && !bridge_status_.empty() &&
               bridge_status_.back().state == process_status_t::STATE_RUNNING;
      },
      10))
      << "no recovery: " << sets_.size() - sets_before << " new sets";
  const double recovery_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - replug).count();
  EXPECT_LT(recovery_s, 5.0);
  // The fault counters are in STATUS, by reason.
  ASSERT_TRUE(HandleUntil(
      bus_.get(), [&] { return Counter(bridge_status_.back().rejected, "unknown_address") > 0; },
      5));
  EXPECT_GE(Counter(bridge_status_.back().counters, "link_opens"), 2);
  EXPECT_GE(Counter(bridge_status_.back().counters, "link_lost"), 1);

  bridge.Signal(SIGTERM);
  EXPECT_EQ(bridge.Wait(5), 0);
  trilat.Signal(SIGTERM);
  EXPECT_EQ(trilat.Wait(5), 0);
  sim->Signal(SIGTERM);
  EXPECT_EQ(sim->Wait(5), 0);
}

TEST_F(BridgeProcess, WaitsForAMissingDeviceAndSaysSo) {
  const std::string link = dir_.File("not_yet");
  ChildProcess bridge({BinDir() + "/zigbee_bridge", "--config", DemoSitePath(), "--port", link,
                       "--reopen-max", "0.2", "--log-level", "error"});
  ASSERT_TRUE(HandleUntil(
      bus_.get(), [&] { return !bridge_status_.empty(); }, 5));
  EXPECT_EQ(bridge_status_.back().state, process_status_t::STATE_DEGRADED);
  EXPECT_NE(bridge_status_.back().last_error.find("not_yet"), std::string::npos)
      << bridge_status_.back().last_error;
  ChildProcess sim(Simulator(link));
  ASSERT_TRUE(HandleUntil(
      bus_.get(), [&] { return sets_.size() >= 5; }, 10))
      << "the bridge never opened the device once it appeared";
  bridge.Signal(SIGINT);
  EXPECT_EQ(bridge.Wait(5), 0);
}

}  // namespace
}  // namespace roomfix
