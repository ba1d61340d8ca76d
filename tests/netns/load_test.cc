// The radio side at ten times its nominal rate: roomfix_sim fires the beacon
// 100 times a second (nominal 10) for 60 s with no radio faults, zigbee_bridge
// reads the pseudo-terminal and publishes RANGES over LCM's UDP multicast, and
// roomfix_logger records them. Every range set the bridge published must be
// in the logger's file, and every firing must have made a set. Runs inside a
// private network namespace (scripts/netns_run).
//
// A pseudo-terminal ignores the baud rate, so the bytes move at memory speed:
// this checks the processes and LCM, not a real serial line (at 115200 baud
// the XBee frames of 100 firings a second do not fit: docs/operations.md).
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/stat.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <thread>

#include "msgio/bus.h"
#include "msgio/log.h"
#include "msgio/process.h"
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

constexpr double kNominalRate_hz = 10.0;
constexpr double kLoadFactor = 10.0;
// The 60 s; ROOMFIX_LOAD_SECONDS shortens it for a quick look.
double LoadSeconds() {
  const char* s = std::getenv("ROOMFIX_LOAD_SECONDS");
  return s ? std::atof(s) : 60.0;
}

TEST(RadioLoad, TenTimesTheNominalRateForAMinuteLosesNoRangeSetBetweenBridgeAndLogger) {
  const double seconds = LoadSeconds();
  const double rate_hz = kNominalRate_hz * kLoadFactor;
  testing::TempDir dir;
  const std::string log = dir.File("load.lcm");
  const std::string link = dir.File("radio");

  ChildProcess logger({BinDir() + "/roomfix_logger", log, "--log-level", "warn"});
  std::this_thread::sleep_for(std::chrono::milliseconds(500));  // joins before anything publishes
  // The load, not the air: --no-collisions, or the demo room's echo decay
  // (a 61.5 ms slot, docs/trilateration.md) would cap the beacon at 16 Hz.
  ChildProcess sim({BinDir() + "/roomfix_sim", "--config", DemoSitePath(), "--radio-pty",
                    "--pty-link", link, "--radio-rate-hz", std::to_string(rate_hz), "--faults",
                    "none", "--no-collisions", "--log-level", "warn"},
                   dir.File("sim.out"));
  ASSERT_TRUE(WaitForPath(link, 10)) << "roomfix_sim made no pseudo-terminal";
  ChildProcess bridge({BinDir() + "/zigbee_bridge", "--config", DemoSitePath(), "--port", link,
                       "--log-level", "info"});
  const auto start = std::chrono::steady_clock::now();
  std::this_thread::sleep_for(std::chrono::duration<double>(seconds));
  ASSERT_EQ(bridge.Wait(0), -1) << "zigbee_bridge died under load";
  ASSERT_EQ(sim.Wait(0), -1) << "roomfix_sim died under load";
  // The bridge stops first (its last STATUS carries its final count), then
  // the device, then the logger once the last messages have arrived.
  bridge.Signal(SIGINT);
  EXPECT_EQ(bridge.Wait(10), 0);
  const double run_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  sim.Signal(SIGINT);
  EXPECT_EQ(sim.Wait(10), 0);
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  logger.Signal(SIGINT);
  ASSERT_EQ(logger.Wait(20), 0);

  std::vector<LogEvent> events;
  std::string error;
  ASSERT_TRUE(ReadLogEvents(log, &events, &error)) << error;
  int64_t logged_sets = 0;
  int64_t first_seq = -1, last_seq = -1, ranges = 0;
  std::map<int64_t, int> seq_seen;
  std::vector<int64_t> incomplete_seqs;
  process_status_t bridge_last, logger_last;
  bool have_bridge = false, have_logger = false;
  for (const LogEvent& e : events) {
    if (e.channel == "RANGES") {
      range_set_t s;
      ASSERT_EQ(s.decode(e.data.data(), 0, static_cast<int>(e.data.size())),
                static_cast<int>(e.data.size()));
      ++logged_sets;
      ++seq_seen[s.firing_seq];
      first_seq = first_seq < 0 ? s.firing_seq : std::min(first_seq, s.firing_seq);
      last_seq = std::max(last_seq, s.firing_seq);
      ranges += s.num_ranges;
      if (s.num_ranges < s.num_expected) incomplete_seqs.push_back(s.firing_seq);
    } else if (e.channel == "STATUS") {
      process_status_t s;
      if (s.decode(e.data.data(), 0, static_cast<int>(e.data.size())) < 0) continue;
      if (s.process == "zigbee_bridge") {
        bridge_last = s;
        have_bridge = true;
      } else if (s.process == "roomfix_logger") {
        logger_last = s;
        have_logger = true;
      }
    }
  }
  ASSERT_TRUE(have_bridge) << "no STATUS from zigbee_bridge in the log";
  ASSERT_EQ(bridge_last.state, process_status_t::STATE_STOPPING)
      << "the bridge's last heartbeat (with its final count) is not in the log";
  const int64_t published = bridge_last.outputs;
  std::printf(
      "[ figures  ] %.0f Hz for %.1f s: bridge published %lld range sets, logger recorded %lld "
      "(%lld ranges, %lld incomplete sets), firings %lld..%lld, %zu distinct; bridge rejected "
      "%d reasons, logger dropped %lld\n",
      rate_hz, run_s, static_cast<long long>(published), static_cast<long long>(logged_sets),
      static_cast<long long>(ranges), static_cast<long long>(incomplete_seqs.size()),
      static_cast<long long>(first_seq), static_cast<long long>(last_seq), seq_seen.size(),
      bridge_last.num_rejected, have_logger ? static_cast<long long>(logger_last.dropped) : -1LL);
  for (const counter_t& c : bridge_last.counters) {
    if (c.name == "bytes" || c.name == "frames") {
      std::printf("[ figures  ]   bridge %s: %lld (%.1f per range set, %.0f per second)\n",
                  c.name.c_str(), static_cast<long long>(c.count),
                  published > 0 ? static_cast<double>(c.count) / published : 0.0, c.count / run_s);
    }
  }
  for (const counter_t& c : bridge_last.rejected) {
    std::printf("[ figures  ]   bridge rejected %s: %lld\n", c.name.c_str(),
                static_cast<long long>(c.count));
  }

  // No loss between the bridge and the logger.
  EXPECT_EQ(logged_sets, published);
  // The load really was ten times nominal (the simulator's clock, allowing
  // for start-up).
  EXPECT_GE(logged_sets, static_cast<int64_t>(0.9 * rate_hz * seconds));
  // Between the simulator and the bridge (not the target, which is
  // bridge to logger): one set per firing and none twice. On a loaded CI
  // machine a starved simulator or bridge can miss a few firings or close a
  // few sets at the deadline, so those are bounded, not forbidden; on an idle
  // machine they are 0 (docs/operations.md).
  constexpr double kMinFiringShare = 0.98;
  constexpr double kMaxIncompleteShare = 0.10;
  EXPECT_EQ(static_cast<int64_t>(seq_seen.size()), logged_sets) << "a firing published twice";
  EXPECT_GE(logged_sets, static_cast<int64_t>(kMinFiringShare * (last_seq - first_seq + 1)))
      << "firings missing";
  EXPECT_LE(static_cast<double>(incomplete_seqs.size()), kMaxIncompleteShare * logged_sets);
  if (have_logger) {
    EXPECT_EQ(logger_last.dropped, 0);
  }
}

}  // namespace
}  // namespace roomfix
