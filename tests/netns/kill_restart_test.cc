// The whole pipeline as processes (roomfix_sim playing the wall devices on a
// pseudo-terminal, zigbee_bridge, trilat_proc, camera_proc on the synthetic
// camera, roomfix_logger) while one process at a time is killed with SIGKILL:
// the others keep running and publishing, the gap shows (no output and no
// STATUS from the dead process), and once it is started again its output
// resumes within 2 s. The log of a SIGKILLed logger stays readable up to the
// kill. Runs inside a private network namespace (scripts/netns_run).
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/stat.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <memory>
#include <set>
#include <thread>

#include "msgio/bus.h"
#include "msgio/log.h"
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
using Clock = std::chrono::steady_clock;

// The requirement: output resumes this soon after a restart.
#ifdef __SANITIZE_ADDRESS__
// AddressSanitizer slows a process's start (shadow memory, interceptors)
// and everything it does two to five times: camera_proc's first pose came
// 2.12 s after its restart in `make test SANITIZE=1` (issue #28). The
// sanitizer build judges that each process recovers; the ordinary build
// holds the 2 s.
constexpr double kRecoveryLimit_s = 5.0;
#else
constexpr double kRecoveryLimit_s = 2.0;
#endif
// How long each killed process stays dead: long enough for several missed
// heartbeats (1 Hz) and a gap no jitter explains.
constexpr double kDead_s = 2.5;

double Since(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}

int64_t LogEventsReadable(const std::string& path, bool* damaged = nullptr) {
  std::string error;
  auto reader = LogReader::Open(path, &error);
  if (!reader) return -1;
  LogEvent event;
  while (reader->Next(&event)) {
  }
  if (damaged) *damaged = reader->damaged();
  return reader->events_read();
}

// What arrives over LCM, with the arrival time on the test's clock.
struct Arrivals {
  std::map<std::string, std::vector<Clock::time_point>> by_channel;
  // STATUS arrivals by process name, with the sender's pid.
  std::map<std::string, std::vector<std::pair<Clock::time_point, process_status_t>>> status;

  size_t Count(const std::string& channel) const {
    const auto it = by_channel.find(channel);
    return it == by_channel.end() ? 0 : it->second.size();
  }
  // Measurement times (the messages' own utime), by channel: what was
  // measured after an instant, whenever the test got round to reading it.
  std::map<std::string, std::vector<int64_t>> measured;
  size_t CountMeasuredAfter(const std::string& channel, int64_t utime) const {
    const auto it = measured.find(channel);
    if (it == measured.end()) return 0;
    return std::count_if(it->second.begin(), it->second.end(),
                         [&](int64_t u) { return u > utime; });
  }
  size_t CountAfter(const std::string& channel, Clock::time_point t) const {
    const auto it = by_channel.find(channel);
    if (it == by_channel.end()) return 0;
    return std::count_if(it->second.begin(), it->second.end(),
                         [&](Clock::time_point a) { return a > t; });
  }
  size_t StatusSentAfter(const std::string& process, int64_t utime) const {
    const auto it = status.find(process);
    if (it == status.end()) return 0;
    return std::count_if(it->second.begin(), it->second.end(),
                         [&](const auto& a) { return a.second.utime > utime; });
  }
  size_t StatusAfter(const std::string& process, Clock::time_point t) const {
    const auto it = status.find(process);
    if (it == status.end()) return 0;
    return std::count_if(it->second.begin(), it->second.end(),
                         [&](const auto& a) { return a.first > t; });
  }
};

class Pipeline {
 public:
  explicit Pipeline(const testing::TempDir& dir)
      : dir_(dir), link_(dir.File("radio")), start_utime_(NowUtime()) {}

  std::vector<std::string> Argv(const std::string& name) const {
    const std::string bin = BinDir() + "/" + name;
    if (name == "roomfix_sim") {
      return {bin,           "--config", DemoSitePath(),  "--radio-pty",
              "--pty-link",  link_,      "--start-utime", std::to_string(start_utime_),
              "--log-level", "warn"};
    }
    if (name == "zigbee_bridge") {
      // A quick reopen, so losing the device (the simulator) costs little.
      return {bin,   "--config",    DemoSitePath(), "--port", link_, "--reopen-max",
              "0.5", "--log-level", "error"};
    }
    if (name == "trilat_proc") {
      return {bin, "--config", DemoSitePath(), "--method", "robust", "--log-level", "warn"};
    }
    if (name == "camera_proc") {
      // The clean synthetic camera the demo site used before its webcam.
      return {bin,
              "--config",
              DemoSitePath(),
              "--device",
              "sim:reference_circle",
              "--start-utime",
              std::to_string(start_utime_),
              "--log-level",
              "warn"};
    }
    // roomfix_logger: a new file per start, as an operator would restart it.
    return {bin, LogPath(), "--log-level", "warn"};
  }

  std::string LogPath() const { return dir_.File("log" + std::to_string(logger_starts_) + ".lcm"); }

  void Start(const std::string& name) {
    if (name == "roomfix_logger") ++logger_starts_;
    procs_[name] = std::make_unique<ChildProcess>(
        Argv(name), name == "roomfix_sim" ? dir_.File("sim.out") : "");
  }
  ChildProcess* Get(const std::string& name) { return procs_.at(name).get(); }
  void Kill(const std::string& name) {
    procs_.at(name)->Signal(SIGKILL);
    procs_.at(name)->Wait(5);
    procs_.erase(name);
  }
  bool Alive(const std::string& name) {
    const auto it = procs_.find(name);
    if (it == procs_.end()) return false;
    return it->second->Wait(0) == -1;
  }
  const std::string& link() const { return link_; }

 private:
  const testing::TempDir& dir_;
  std::string link_;
  int64_t start_utime_;
  int logger_starts_ = 0;
  std::map<std::string, std::unique_ptr<ChildProcess>> procs_;
};

const std::vector<std::string> kProcesses = {"roomfix_logger", "trilat_proc", "roomfix_sim",
                                             "zigbee_bridge", "camera_proc"};

// The channel whose resumption shows a restarted process is back.
std::string OutputOf(const std::string& process) {
  if (process == "camera_proc") return "POSE_CAMERA";
  if (process == "trilat_proc") return "POSE_ULTRASOUND";
  if (process == "zigbee_bridge" || process == "roomfix_sim") return "RANGES";
  return "";
}

class KillRestart : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string error;
    bus_ = LcmBus::Create(kDefaultLcmUrl, &error);
    ASSERT_NE(bus_, nullptr) << error;
    // A message counts as fresh when its measurement time is less than a
    // second old: stale ones (a backlog replayed after a restart) are not a
    // recovery.
    auto note = [this](const std::string& channel, int64_t utime) {
      const auto now = Clock::now();
      seen_.by_channel[channel].push_back(now);
      seen_.measured[channel].push_back(utime);
      if (std::llabs(NowUtime() - utime) < 1000000)
        seen_.by_channel[channel + "/fresh"].push_back(now);
    };
    bus_->Subscribe<range_set_t>(
        "RANGES", [note](const range_set_t& m, const MessageInfo& i) { note(i.channel, m.utime); });
    bus_->Subscribe<pose2d_t>(
        "POSE_ULTRASOUND|POSE_CAMERA|POSE_GROUND_TRUTH",
        [note](const pose2d_t& m, const MessageInfo& i) { note(i.channel, m.utime); });
    bus_->Subscribe<process_status_t>("STATUS",
                                      [this](const process_status_t& s, const MessageInfo&) {
                                        seen_.status[s.process].emplace_back(Clock::now(), s);
                                      });
  }

  void Pump(double seconds) {
    HandleUntil(
        bus_.get(), [] { return false; }, seconds);
  }

  // Starts the pipeline and waits until every process has sent a heartbeat
  // and the outputs flow.
  void StartAll(Pipeline* p) {
    p->Start("roomfix_logger");
    p->Start("trilat_proc");
    p->Start("roomfix_sim");
    ASSERT_TRUE(WaitForPath(p->link(), 10)) << "roomfix_sim made no pseudo-terminal";
    p->Start("zigbee_bridge");
    p->Start("camera_proc");
    ASSERT_TRUE(HandleUntil(
        bus_.get(),
        [&] {
          for (const auto& name : kProcesses)
            if (seen_.status[name].empty()) return false;
          return seen_.Count("RANGES") >= 10 && seen_.Count("POSE_ULTRASOUND") >= 5 &&
                 seen_.Count("POSE_CAMERA") >= 10;
        },
        20))
        << seen_.Count("RANGES") << " RANGES, " << seen_.Count("POSE_ULTRASOUND")
        << " POSE_ULTRASOUND, " << seen_.Count("POSE_CAMERA") << " POSE_CAMERA";
  }

  // With `victim` dead since `killed`: the others are alive and still
  // publishing; the victim is silent.
  void ExpectOthersCarryOn(Pipeline* p, const std::string& victim, Clock::time_point killed,
                           int64_t killed_utime) {
    for (const std::string& other : kProcesses) {
      if (other == victim) continue;
      EXPECT_TRUE(p->Alive(other)) << other << " died while " << victim << " was dead";
      EXPECT_GE(seen_.StatusAfter(other, killed), 2u) << other << "'s heartbeat stopped";
    }
    for (const std::string& other : kProcesses) {
      const auto it = seen_.status.find(other);
      if (other == victim || it == seen_.status.end() || it->second.empty()) continue;
      const process_status_t& last = it->second.back().second;
      std::printf("[ figures  ] %s dead: %s state %d%s%s\n", victim.c_str(), other.c_str(),
                  last.state,
                  last.last_error.empty() ? "" : ", last error: ", last.last_error.c_str());
    }
    // Heartbeats already in flight at the kill may still arrive just after.
    EXPECT_EQ(seen_.StatusSentAfter(victim, killed_utime + 200'000), 0u);
    if (victim != "roomfix_sim") {
      EXPECT_GE(seen_.CountAfter("POSE_GROUND_TRUTH", killed), 30u) << "roomfix_sim stopped";
    }
    if (victim != "camera_proc") {
      EXPECT_GE(seen_.CountAfter("POSE_CAMERA", killed), 10u) << "camera_proc stopped";
    }
    const std::string output = OutputOf(victim);
    if (!output.empty()) {
      // By measurement time: on a loaded machine the test may read a backlog
      // of messages sent before the kill only after it.
      EXPECT_EQ(seen_.CountMeasuredAfter(output, killed_utime + 200'000), 0u)
          << output << " went on with " << victim << " dead";
    }
    if (victim == "trilat_proc") {
      EXPECT_GE(seen_.CountAfter("RANGES", killed), 10u) << "RANGES stopped with trilat_proc";
    }
    if (victim == "zigbee_bridge" || victim == "roomfix_sim") {
      EXPECT_EQ(seen_.CountMeasuredAfter("POSE_ULTRASOUND", killed_utime + 200'000), 0u);
    }
    if (victim == "roomfix_sim") {
      // Its pseudo-terminal went with it: the bridge says so.
      const auto& bridge = seen_.status["zigbee_bridge"];
      ASSERT_FALSE(bridge.empty());
      ASSERT_GT(bridge.back().second.utime, killed_utime) << "no bridge heartbeat since the kill";
      EXPECT_EQ(bridge.back().second.state, process_status_t::STATE_DEGRADED)
          << "zigbee_bridge did not report its device gone";
    }
  }

  // The file of a logger killed at `killed` is readable up to (about) the
  // kill.
  void ExpectKilledLogReadable(const std::string& old_log, Clock::time_point killed) {
    bool damaged = false;
    const int64_t n = LogEventsReadable(old_log, &damaged);
    EXPECT_GT(n, 100) << old_log;
    std::vector<LogEvent> events;
    std::string error;
    ReadLogEvents(old_log, &events, &error);
    ASSERT_FALSE(events.empty());
    const double last_event_before_kill_s =
        (NowUtime() - events.back().utime) * 1e-6 - Since(killed);
    EXPECT_LT(last_event_before_kill_s, 0.5) << "events lost before the kill";
    // roomfix log-info reads it too: exit 0 when whole, 2 when it reports
    // damage (a cut last event), never a crash.
    ChildProcess info({BinDir() + "/roomfix", "log-info", old_log}, dir_.File("info.txt"));
    EXPECT_EQ(info.Wait(20), damaged ? 2 : 0) << testing::ReadFile(dir_.File("info.txt"));
    std::printf("[ figures  ] killed logger's file: %lld events readable, %s\n",
                static_cast<long long>(n), damaged ? "truncated last event" : "intact");
  }

  // Starts `victim` again (killed at `killed`, as pid `old_pid`) and times
  // the recovery: fresh output within kRecoveryLimit_s, then a heartbeat
  // with a new pid.
  void RestartAndTime(Pipeline* p, const std::string& victim, Clock::time_point killed,
                      int old_pid) {
    const std::string output = OutputOf(victim);
    const size_t statuses_before = seen_.StatusAfter(victim, killed);
    const auto restarted = Clock::now();
    p->Start(victim);
    bool recovered = false;
    if (victim == "roomfix_logger") {
      const std::string new_log = p->LogPath();
      const auto deadline = restarted + std::chrono::seconds(10);
      while (Clock::now() < deadline) {
        bus_->Handle(20);
        if (LogEventsReadable(new_log) > 0) {
          recovered = true;
          break;
        }
      }
    } else {
      recovered = HandleUntil(
          bus_.get(), [&] { return seen_.CountAfter(output, restarted) > 0; }, 10);
      const double first_any_s = Since(restarted);
      recovered =
          recovered &&
          HandleUntil(
              bus_.get(), [&] { return seen_.CountAfter(output + "/fresh", restarted) > 0; }, 10);
      std::printf(
          "[ figures  ] %s: first %s %.3f s after the restart (%zu messages before the "
          "first fresh one)\n",
          victim.c_str(), output.c_str(), first_any_s, seen_.CountAfter(output, restarted) - 1);
    }
    const double recovery_s = Since(restarted);
    EXPECT_TRUE(recovered) << victim << ": no output within 10 s of the restart";
    EXPECT_LT(recovery_s, kRecoveryLimit_s) << victim;
    // The new process's heartbeat, with its new pid.
    ASSERT_TRUE(HandleUntil(
        bus_.get(), [&] { return seen_.StatusAfter(victim, killed) > statuses_before; }, 5));
    EXPECT_NE(seen_.status[victim].back().second.pid, old_pid);
    if (victim == "roomfix_sim") {
      // The bridge reopened the device and says it is running again.
      ASSERT_TRUE(HandleUntil(
          bus_.get(),
          [&] {
            return seen_.status["zigbee_bridge"].back().second.state ==
                   process_status_t::STATE_RUNNING;
          },
          5));
    }
    std::printf("[ figures  ] %s: fresh output resumed %.3f s after the restart\n", victim.c_str(),
                recovery_s);
  }

  std::unique_ptr<LcmBus> bus_;
  Arrivals seen_;
  testing::TempDir dir_;
};

TEST_F(KillRestart, EachProcessKilledTheOthersCarryOnAndItRecoversWithinTwoSeconds) {
  Pipeline p(dir_);
  ASSERT_NO_FATAL_FAILURE(StartAll(&p));
  Pump(1.0);

  for (const std::string& victim : std::vector<std::string>{
           "camera_proc", "trilat_proc", "zigbee_bridge", "roomfix_logger", "roomfix_sim"}) {
    SCOPED_TRACE(victim);
    const std::string old_log = p.LogPath();
    const int old_pid = p.Get(victim)->pid();
    p.Kill(victim);
    const auto killed = Clock::now();
    const int64_t killed_utime = NowUtime();
    Pump(kDead_s);
    // Two heartbeats of each survivor (1 Hz) fit in kDead_s with only 0.5 s
    // to spare, and arrivals are stamped when this test reads them: on a
    // loaded machine a heartbeat sent in time is read late. Keep reading
    // (the victim stays dead) until they are in, or as long again.
    HandleUntil(
        bus_.get(),
        [&] {
          for (const std::string& other : kProcesses) {
            if (other != victim && seen_.StatusAfter(other, killed) < 2) return false;
          }
          return true;
        },
        kDead_s);
    ASSERT_NO_FATAL_FAILURE(ExpectOthersCarryOn(&p, victim, killed, killed_utime));
    if (victim == "roomfix_logger") {
      ASSERT_NO_FATAL_FAILURE(ExpectKilledLogReadable(old_log, killed));
    }
    ASSERT_NO_FATAL_FAILURE(RestartAndTime(&p, victim, killed, old_pid));
    Pump(1.0);
  }

  // The first log (its logger was killed after camera_proc, trilat_proc and
  // zigbee_bridge) shows each of their gaps: two pids in STATUS and a hole in
  // their output.
  {
    std::vector<LogEvent> events;
    std::string error;
    ReadLogEvents(dir_.File("log1.lcm"), &events, &error);
    std::map<std::string, std::vector<int64_t>> times;
    for (const LogEvent& e : events) times[e.channel].push_back(e.utime);
    for (const std::string& channel :
         std::vector<std::string>{"POSE_CAMERA", "POSE_ULTRASOUND", "RANGES"}) {
      const auto& t = times[channel];
      ASSERT_GE(t.size(), 2u) << channel;
      int64_t widest = 0;
      for (size_t i = 1; i < t.size(); ++i) widest = std::max(widest, t[i] - t[i - 1]);
      EXPECT_GT(widest * 1e-6, kDead_s) << channel << ": no gap in the killed logger's file";
      std::printf("[ figures  ] log1.lcm: widest gap in %s %.2f s\n", channel.c_str(),
                  widest * 1e-6);
    }
  }

  // Everything stops cleanly; the last logger's file is whole.
  for (const std::string& name : std::vector<std::string>{
           "camera_proc", "zigbee_bridge", "roomfix_sim", "trilat_proc", "roomfix_logger"}) {
    p.Get(name)->Signal(SIGINT);
    EXPECT_EQ(p.Get(name)->Wait(10), 0) << name;
  }
  bool damaged = true;
  EXPECT_GT(LogEventsReadable(p.LogPath(), &damaged), 50);
  EXPECT_FALSE(damaged);
}

}  // namespace
}  // namespace roomfix
