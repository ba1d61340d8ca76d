// End to end through a real pseudo-terminal: the virtual wall devices write
// XBee frames to the master side in real time, the bridge reads the device
// side through libserialport (SerialLink), and its range sets are checked
// against what the devices really sent.
#include <gtest/gtest.h>
#include <poll.h>

#include <atomic>
#include <memory>
#include <mutex>
#include <thread>

#include "msgio/process.h"
#include "roomfix/process_status_t.hpp"
#include "roomfix/range_set_t.hpp"
#include "sim/pseudo_terminal.h"
#include "sim/wall_devices.h"
#include "tests/testing/ledger_check.h"
#include "tests/testing/test_paths.h"
#include "zigbee_bridge/bridge_node.h"
#include "zigbee_bridge/serial_link.h"

namespace roomfix {
namespace {

// Plays the wall devices onto a pseudo-terminal from a thread, 1 ms ticks.
// The terminal can be taken away and replaced (the coordinator unplugged and
// plugged in again) while the devices go on firing.
class DeviceWriter {
 public:
  DeviceWriter(const Site& site, const WallDevicesOptions& options, PseudoTerminal* pty)
      : devices_(site, options), pty_(pty), thread_([this] { Loop(); }) {}
  ~DeviceWriter() { Stop(); }
  void Stop() {
    stop_ = true;
    if (thread_.joinable()) thread_.join();
  }
  void SetTerminal(PseudoTerminal* pty) {
    std::lock_guard<std::mutex> lock(mutex_);
    pty_ = pty;
  }
  const VirtualWallDevices& devices() const { return devices_; }
  int64_t write_failures() const { return write_failures_; }
  // Only after Stop().
  const std::vector<std::pair<int64_t, int64_t>>& late_writes() const { return late_writes_; }

 private:
  void Loop() {
    std::vector<VirtualWallDevices::Chunk> chunks;
    std::vector<uint8_t> bytes;
    std::string error;
    while (!stop_) {
      chunks.clear();
      bytes.clear();
      std::lock_guard<std::mutex> lock(mutex_);
      devices_.AdvanceChunks(NowUtime(), &chunks);
      for (const auto& c : chunks) bytes.insert(bytes.end(), c.bytes.begin(), c.bytes.end());
      // While unplugged the frames are lost, as on a real radio.
      if (pty_ != nullptr && !bytes.empty() && !pty_->Write(bytes.data(), bytes.size(), &error)) {
        ++write_failures_;
      }
      // A writer the machine starved delivers late: say so, so that the
      // check does not hold the bridge to the ledger's times there.
      const int64_t written = NowUtime();
      if (!chunks.empty() && written - chunks.front().utime > kLateWriteUs) {
        late_writes_.push_back({chunks.front().utime, written});
      }
      ::poll(nullptr, 0, 1);
    }
  }
  static constexpr int64_t kLateWriteUs = 3000;
  std::vector<std::pair<int64_t, int64_t>> late_writes_;
  VirtualWallDevices devices_;
  std::mutex mutex_;
  PseudoTerminal* pty_;
  std::atomic<bool> stop_{false};
  std::atomic<int64_t> write_failures_{0};
  std::thread thread_;
};

// The bridge's loop as zigbee_bridge runs it: poll the port, read, feed,
// tick.
class BridgeLoop {
 public:
  BridgeLoop(const Site& site, const std::string& port)
      : link_(SerialLinkOptions{port, 115200, 0.05, 0.2}), node_(site, &bus_, {}, NowUtime()) {
    bus_.Subscribe<range_set_t>(
        "RANGES", [this](const range_set_t& s, const MessageInfo&) { sets.push_back(s); });
    bus_.Subscribe<process_status_t>(
        "STATUS", [this](const process_status_t& s, const MessageInfo&) { statuses.push_back(s); });
  }

  void RunFor(double seconds) {
    const int64_t end = NowUtime() + static_cast<int64_t>(seconds * 1e6);
    std::vector<uint8_t> buffer(4096);
    while (NowUtime() < end) {
      const int64_t now = NowUtime();
      if (link_.state() != SerialLink::State::kOpen) {
        if (link_.MaybeOpen(now)) node_.OnLinkUp("pty", now);
      }
      pollfd fd{link_.fd(), POLLIN, 0};
      ::poll(&fd, 1, 2);
      // Deadlines are judged at the time of the read that found nothing
      // more, as zigbee_bridge does: every byte written before it was read.
      int64_t tick_utime = NowUtime();
      while (link_.state() == SerialLink::State::kOpen) {
        tick_utime = NowUtime();
        const int n = link_.Read(buffer.data(), buffer.size(), tick_utime);
        if (n < 0) node_.OnLinkDown(link_.last_error(), tick_utime);
        if (n <= 0) break;
        node_.OnBytes(buffer.data(), static_cast<size_t>(n), tick_utime);
      }
      bus_.set_now_utime(tick_utime);
      node_.Tick(tick_utime);
    }
  }

  const SerialLink& link() const { return link_; }
  const BridgeNode& node() const { return node_; }
  std::vector<range_set_t> sets;
  std::vector<process_status_t> statuses;

 private:
  LoopbackBus bus_;
  SerialLink link_;
  BridgeNode node_;
};

TEST(BridgeThroughAPseudoTerminal, NeverMixesFiringsWithEveryFaultSwitchedOn) {
  const Site site = LoadDemoSite();
  testing::TempDir dir;
  std::string error;
  auto pty = PseudoTerminal::Open(dir.File("radio"), &error);
  ASSERT_NE(pty, nullptr) << error;
  BridgeLoop bridge(site, dir.File("radio"));
  WallDevicesOptions wall;
  wall.rate_hz = 25.0;  // 2.5 times the nominal rate: more firings per second of test
  // The bridge is under test, not the air: without the collision model the
  // demo room's slot (about 60 ms) does not cap the beacon at 16 Hz.
  wall.collisions = false;
  wall.faults = RadioFaults::All();
  wall.seed = 5;
  wall.start_utime = NowUtime() + 200'000;  // the bridge has opened the port by then
  DeviceWriter writer(site, wall, pty.get());
  bridge.RunFor(8.0);
  writer.Stop();

  LedgerCheckOptions options;
  // Real time: the reader may run a few ms behind the writer.
  options.margin_s = 0.01;
  options.late_writes = writer.late_writes();
  options.judge_until_utime = NowUtime() - 300'000;
  const LedgerCheck check = CheckAgainstLedger(bridge.sets, writer.devices(), options);
  for (const std::string& f : check.failures) ADD_FAILURE() << f;
  EXPECT_EQ(check.mixed_sets, 0);
  EXPECT_EQ(check.repeated_sets, 0);
  EXPECT_EQ(check.incomplete, 0);
  // Enough firings judged for the checks above to mean something. Firings
  // the writer put out late are not judged, and on a loaded machine (the
  // sanitizer suite on 2 cores) that is many: 31 were judged there.
  EXPECT_GT(check.expected_complete, 20);
  EXPECT_GT(check.sets, 150);
  EXPECT_EQ(writer.write_failures(), 0);
  EXPECT_GT(bridge.node().status().rejected("unknown_address"), 0);
  EXPECT_EQ(bridge.link().opens(), 1);
}

TEST(BridgeThroughAPseudoTerminal, SurvivesTheDeviceVanishingAndComingBack) {
  const Site site = LoadDemoSite();
  testing::TempDir dir;
  const std::string port = dir.File("radio");
  std::string error;
  BridgeLoop bridge(site, port);
  WallDevicesOptions wall;
  wall.start_utime = NowUtime();

  auto pty = PseudoTerminal::Open(port, &error);
  ASSERT_NE(pty, nullptr) << error;
  DeviceWriter writer(site, wall, pty.get());
  bridge.RunFor(1.0);
  const size_t before = bridge.sets.size();
  EXPECT_GE(before, 8u);

  // Unplugged: the device and its path disappear.
  writer.SetTerminal(nullptr);
  pty.reset();
  bridge.RunFor(0.5);
  EXPECT_EQ(bridge.link().state(), SerialLink::State::kClosed);
  EXPECT_EQ(bridge.link().disconnects(), 1);
  ASSERT_FALSE(bridge.statuses.empty());
  EXPECT_EQ(bridge.statuses.back().state, process_status_t::STATE_DEGRADED);
  EXPECT_NE(bridge.statuses.back().last_error.find(port), std::string::npos)
      << bridge.statuses.back().last_error;

  // Plugged in again: a new pseudo-terminal behind the same path.
  pty = PseudoTerminal::Open(port, &error);
  ASSERT_NE(pty, nullptr) << error;
  writer.SetTerminal(pty.get());
  bridge.RunFor(1.5);
  writer.Stop();
  EXPECT_EQ(bridge.link().opens(), 2);
  EXPECT_EQ(bridge.statuses.back().state, process_status_t::STATE_RUNNING);
  EXPECT_GE(bridge.sets.size(), before + 10) << "range sets resumed after the reopen";
  // Firing numbers went on increasing across the gap.
  for (size_t k = 1; k < bridge.sets.size(); ++k) {
    EXPECT_GT(bridge.sets[k].firing_seq, bridge.sets[k - 1].firing_seq);
  }
}

}  // namespace
}  // namespace roomfix
