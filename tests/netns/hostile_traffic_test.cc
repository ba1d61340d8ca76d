// Issue #15, item 7: every class of hostile or broken input from the issue's
// table, sent by a generator in this test (tests/testing/hostile_traffic.h)
// as raw LCM datagrams to the real processes over multicast in a private
// network namespace. For each process: it stays alive, it answers good
// traffic within 100 ms after each class, it counts each refusal in STATUS
// under the names of the shared contract (docs/security.md), and its memory
// grows by less than 50 MB. Two rows freeze a process with SIGSTOP behind a
// small receive buffer and check that STATUS `dropped` accounts for what it
// missed.
//
// The STATUS names asserted (docs/security.md, "Limits and counters"):
//   bus refusals       rejected "<CHANNEL>.<reason>" (RANGES.count_over_cap, ...)
//   transport losses   counters fragments_malformed, fragments_over_budget,
//                      fragments_expired, dropped_kernel_overflow,
//                      dropped_queue_overflow; their sum also in `dropped`
//   node refusals      rejected unknown_robot, too_many_ranges, non_finite*,
//                      utime_out_of_range, unknown_receiver
//   logger             rejected unloggable_channel
//   roomfix listen     one warning line per reason on stderr
#include "tests/testing/hostile_traffic.h"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <functional>
#include <lcm/lcm-cpp.hpp>
#include <limits>
#include <map>
#include <mutex>
#include <set>
#include <sstream>
#include <thread>

#include "core/world/site.h"
#include "msgio/bus.h"
#include "msgio/process.h"
#include "roomfix/pose2d_t.hpp"
#include "roomfix/process_status_t.hpp"
#include "roomfix/range_set_t.hpp"
#include "tests/testing/demo_site.h"
#include "tests/testing/forged_site.h"
#include "tests/testing/test_paths.h"

namespace roomfix {
namespace {

using hostile::Bytes;
using hostile::Encode;
using testing::BinDir;
using testing::ChildProcess;
using testing::DemoSitePath;
using testing::TempDir;
using Clock = std::chrono::steady_clock;

// The issue's targets.
#ifdef __SANITIZE_ADDRESS__
// AddressSanitizer and UBSan slow the processes two to five times: the
// sanitizer build judges that good traffic is answered, not the issue's
// 100 ms, which the ordinary build holds to.
constexpr double kAnswerWithinS = 0.500;
#else
constexpr double kAnswerWithinS = 0.100;
#endif
constexpr double kMemoryGrowthMaxMiB = 50.0;
// How long an unanswered probe is waited for before it counts as lost; only
// the time to the answer is judged against kAnswerWithinS.
constexpr double kProbeTimeoutS = 1.0;
// STATUS comes at 1 Hz from a loop ticking every 10-33 ms; a gap longer than
// this means the loop was blocked (the issue's 400 ranges held trilat_proc
// 4.7 s). The slack is for a loaded 2-core machine, not for the process.
constexpr double kHeartbeatGapMaxS = 1.5;
// After the 20 000 new robots stop, the viewer must go back to its idle CPU
// use (it drew every row forever and burnt 90 % of a core).
constexpr double kViewerCpuOverIdleMax = 0.25;

// How much of each class is sent.
constexpr int kConflictingMessages = 4;  // one on each subscribed channel
constexpr int kHugeFragments = 200;      // 200 x 64 MiB declared = 12.5 GiB
constexpr int kGoodAmidHuge = 50;        // good messages between them
constexpr int kNewRobots = 20'000;       // the issue's count
constexpr double kNewRobotRateHz = 20'000;

// Room of the demo site, metres, for "no pose outside the room".
constexpr double kRoomX_m = 4.0;
constexpr double kRoomY_m = 3.0;
// A fix this close outside the walls is measurement noise, not the issue's
// pose "outside the room from 800 ranges" (which was metres out).
constexpr double kRoomMargin_m = 0.2;

double Seconds(Clock::duration d) { return std::chrono::duration<double>(d).count(); }
void SleepS(double s) { std::this_thread::sleep_for(std::chrono::duration<double>(s)); }

int64_t Rejected(const process_status_t& s, const std::string& name) {
  for (const counter_t& c : s.rejected) {
    if (c.name == name) return c.count;
  }
  return 0;
}
// Sum of rejected entries whose name starts with prefix ("RANGES." is every
// bus refusal on RANGES, whatever reason the validator named).
int64_t RejectedWithPrefix(const process_status_t& s, const std::string& prefix) {
  int64_t n = 0;
  for (const counter_t& c : s.rejected) {
    if (c.name.rfind(prefix, 0) == 0) n += c.count;
  }
  return n;
}
int64_t Counter(const process_status_t& s, const std::string& name) {
  for (const counter_t& c : s.counters) {
    if (c.name == name) return c.count;
  }
  return 0;
}
std::string Describe(const process_status_t& s) {
  std::ostringstream out;
  out << s.process << ": inputs " << s.inputs << ", outputs " << s.outputs << ", dropped "
      << s.dropped << "; rejected {";
  for (const counter_t& c : s.rejected) out << " " << c.name << "=" << c.count;
  out << " }; counters {";
  for (const counter_t& c : s.counters) out << " " << c.name << "=" << c.count;
  out << " }; last_error '" << s.last_error << "'";
  return out.str();
}

// /proc/PID/status fields in MiB (VmRSS now, VmHWM the peak); -1 when gone.
double ProcMiB(int pid, const std::string& field) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/status");
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind(field + ":", 0) == 0) return std::stod(line.substr(field.size() + 1)) / 1024.0;
  }
  return -1.0;
}

// CPU seconds (user + system) a process has used.
double CpuSeconds(int pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/stat");
  std::string all;
  std::getline(in, all);
  const size_t close = all.rfind(')');
  if (close == std::string::npos) return -1.0;
  std::istringstream fields(all.substr(close + 2));
  std::string f;
  double ticks = 0;
  // Fields from the state (3rd): utime is the 14th, stime the 15th.
  for (int i = 3; i <= 15 && fields >> f; ++i) {
    if (i >= 14) ticks += std::stod(f);
  }
  return ticks / static_cast<double>(::sysconf(_SC_CLK_TCK));
}

bool Alive(ChildProcess* p) { return p->Wait(0.0) == -1; }

// Ids appended to a file (a log being written, a process's stdout) after a
// prefix ("probe-0000000042", "\"channel\":\"PROBE_42\","), found as the file
// grows; an id split across two reads is found on the next.
class FileTail {
 public:
  // digits: how many digits an id has, or 0 for "until a non-digit".
  FileTail(std::string path, std::string prefix, size_t digits = 0)
      : path_(std::move(path)), prefix_(std::move(prefix)), digits_(digits) {}
  bool Contains(int64_t id) {
    if (found_.count(id) != 0) return true;
    std::string fresh;
    if (FILE* f = std::fopen(path_.c_str(), "rb")) {
      if (std::fseek(f, static_cast<long>(offset_), SEEK_SET) == 0) {
        char buffer[1 << 16];
        size_t n = 0;
        while ((n = std::fread(buffer, 1, sizeof(buffer), f)) > 0) fresh.append(buffer, n);
      }
      std::fclose(f);
    }
    offset_ += fresh.size();
    window_ += fresh;
    size_t keep_from = window_.size() > kKeep ? window_.size() - kKeep : 0;
    for (size_t at = window_.find(prefix_); at != std::string::npos;
         at = window_.find(prefix_, at + 1)) {
      size_t end = at + prefix_.size();
      while (end < window_.size() && std::isdigit(static_cast<unsigned char>(window_[end])) &&
             (digits_ == 0 || end < at + prefix_.size() + digits_)) {
        ++end;
      }
      const bool complete =
          digits_ > 0 ? end == at + prefix_.size() + digits_ : end < window_.size();
      if (!complete && end == window_.size()) {  // the digits may go on in the next read
        keep_from = std::min(keep_from, at);
        break;
      }
      if (end > at + prefix_.size()) {
        found_.insert(std::stoll(window_.substr(at + prefix_.size(), end - at - prefix_.size())));
      }
    }
    window_.erase(0, keep_from);
    return found_.count(id) != 0;
  }

 private:
  static constexpr size_t kKeep = 64;
  std::string path_;
  std::string prefix_;
  size_t digits_ = 0;
  size_t offset_ = 0;
  std::string window_;
  std::set<int64_t> found_;
};

// Receives STATUS and the outputs the probes wait for, on a thread of its
// own so that liblcm's 30-message subscription queue never fills while the
// test is busy sending.
class Listener {
 public:
  explicit Listener(const std::string& pose_channels) {
    std::string error;
    bus_ = LcmBus::Create(kDefaultLcmUrl, &error);
    if (bus_ == nullptr) {
      ADD_FAILURE() << error;
      return;
    }
    // STATUS raw: the hostile STATUS has a string length of INT32_MIN, which
    // LCM 1.3.1's generated decoder turns into a wild read. The first
    // string's length must be within the payload before anything decodes.
    bus_->SubscribeRaw("STATUS", [this](const MessageInfo&, const void* data, int size) {
      const auto* b = static_cast<const uint8_t*>(data);
      if (size < 20) return;
      const int32_t len = static_cast<int32_t>((uint32_t{b[16]} << 24) | (uint32_t{b[17]} << 16) |
                                               (uint32_t{b[18]} << 8) | b[19]);
      if (len < 1 || len > size - 20) return;
      process_status_t s{};
      if (s.decode(data, 0, size) != size) return;
      std::lock_guard<std::mutex> lock(mutex_);
      status_[s.process].push_back({Clock::now(), s});
    });
    if (!pose_channels.empty()) {
      bus_->Subscribe<pose2d_t>(pose_channels, [this](const pose2d_t& p, const MessageInfo& info) {
        std::lock_guard<std::mutex> lock(mutex_);
        poses_.push_back({Clock::now(), info.channel, p});
      });
    }
    thread_ = std::thread([this] {
      while (!stop_) bus_->Handle(10);
    });
  }
  ~Listener() {
    stop_ = true;
    if (thread_.joinable()) thread_.join();
  }

  struct Status {
    Clock::time_point at;
    process_status_t s;
  };
  struct Pose {
    Clock::time_point at;
    std::string channel;
    pose2d_t p;
  };

  // The first STATUS of `process` received after `after`, waiting up to
  // timeout_s; false on time-out.
  bool StatusAfter(const std::string& process, Clock::time_point after, double timeout_s,
                   process_status_t* out) {
    const auto until = Clock::now() + std::chrono::duration<double>(timeout_s);
    while (Clock::now() < until) {
      {
        std::lock_guard<std::mutex> lock(mutex_);
        for (const Status& s : status_[process]) {
          if (s.at > after) {
            *out = s.s;
            return true;
          }
        }
      }
      SleepS(0.005);
    }
    return false;
  }
  // Longest gap between two heartbeats of `process`, seconds.
  double LongestHeartbeatGapS(const std::string& process) {
    std::lock_guard<std::mutex> lock(mutex_);
    double gap = 0;
    const auto& v = status_[process];
    for (size_t i = 1; i < v.size(); ++i) gap = std::max(gap, Seconds(v[i].at - v[i - 1].at));
    return gap;
  }
  // When the first pose on `channel` with this measurement_seq arrived.
  bool PoseArrived(const std::string& channel, int64_t seq, Clock::time_point* at) {
    std::lock_guard<std::mutex> lock(mutex_);
    for (const Pose& p : poses_) {
      if (p.channel == channel && p.p.measurement_seq == seq) {
        *at = p.at;
        return true;
      }
    }
    return false;
  }
  std::vector<Pose> Poses() {
    std::lock_guard<std::mutex> lock(mutex_);
    return poses_;
  }

 private:
  std::unique_ptr<LcmBus> bus_;
  std::thread thread_;
  std::atomic<bool> stop_{false};
  std::mutex mutex_;
  std::map<std::string, std::vector<Status>> status_;
  std::vector<Pose> poses_;
};

// How a process under attack shows that it still works: send one good
// message, and tell whether its answer has appeared.
struct Probe {
  std::function<void(int64_t id)> send;
  std::function<bool(int64_t id)> answered;
};

class HostileTraffic : public ::testing::Test {
 protected:
  // Good messages sent among the 64 MiB fragments that got no answer.
  int64_t good_missed_amid_huge_ = 0;
  // What SendEveryClass judges against, and how long a probe is waited for.
  double answer_within_s_ = kAnswerWithinS;
  double probe_timeout_s_ = kProbeTimeoutS;
  // 0: a probe is sent once. Otherwise it is sent again this often until
  // answered (a receiver still draining a flood may find its kernel buffer
  // full when the first one comes: a counted loss, not a wrong answer).
  double probe_resend_s_ = 0;

  void SetUp() override { ASSERT_TRUE(sender_.ok()) << sender_.error(); }

  // Seconds from sending a good message to its answer; +inf when none came
  // within kProbeTimeoutS.
  double AnswerTimeS(const Probe& probe) {
    const int64_t id = next_probe_id_++;
    const auto start = Clock::now();
    probe.send(id);
    auto last_sent = start;
    while (Seconds(Clock::now() - start) < probe_timeout_s_) {
      if (probe.answered(id)) return Seconds(Clock::now() - start);
      if (probe_resend_s_ > 0 && Seconds(Clock::now() - last_sent) >= probe_resend_s_) {
        probe.send(id);
        last_sent = Clock::now();
      }
      std::this_thread::sleep_for(std::chrono::microseconds(500));
    }
    return std::numeric_limits<double>::infinity();
  }

  // The issue's classes, one after the other, each followed by a good
  // message that must be answered within kAnswerWithinS (when the process
  // has a per-message answer; else by the heartbeat check of the caller).
  // Returns the time the last hostile datagram left.
  Clock::time_point SendEveryClass(const Probe* probe, ChildProcess* process) {
    bool alive = true;
    auto check = [&](const std::string& what) {
      if (!alive) return;  // said once; the rest is still sent
      if (!Alive(process)) {
        ADD_FAILURE() << "died after " << what << " (exit status " << process->Wait(0.0)
                      << ", 128 + signal when killed)";
        alive = false;
        return;
      }
      if (probe == nullptr) return;
      const double t = AnswerTimeS(*probe);
      EXPECT_LE(t, answer_within_s_)
          << "good traffic after " << what << " answered in " << t << " s";
    };
    if (probe != nullptr) {
      // Warm: the first answer may pay for start-up work (allocations,
      // the solver's first call), which is not what is judged.
      AnswerTimeS(*probe);
    }
    check("nothing (baseline)");

    for (const char* channel : {"RANGES", "POSE_CAMERA", "POSE_ULTRASOUND", "STATUS"}) {
      sender_.SendAll(hostile::ConflictingTotalFragments(sender_.NextSeqno(), channel));
    }
    check("two LC03 fragments whose totals disagree");

    // 64 MiB first fragments with good traffic between them: every good
    // message must still get through (the issue lost 703 of 800).
    std::vector<int64_t> amid;
    for (int k = 0; k < kHugeFragments; ++k) {
      const char* channels[] = {"RANGES", "POSE_CAMERA", "POSE_ULTRASOUND", "MARKER_PIXELS"};
      sender_.Send(hostile::HugeFirstFragment(sender_.NextSeqno(), channels[k % 4]));
      if (probe != nullptr && k % (kHugeFragments / kGoodAmidHuge) == 0) {
        amid.push_back(next_probe_id_++);
        probe->send(amid.back());
      }
      if (k % 20 == 19) SleepS(0.002);
    }
    if (probe != nullptr) {
      // A slowed receiver (a sanitizer build) answers the last of them late;
      // late is not lost, so wait up to 3 s before counting what is missing.
      int answered = 0;
      for (const auto give_up = Clock::now() + std::chrono::seconds(3);;) {
        answered = 0;
        for (int64_t id : amid) answered += probe->answered(id) ? 1 : 0;
        if (answered == static_cast<int>(amid.size()) || Clock::now() > give_up) break;
        SleepS(0.05);
      }
      // 200 datagrams of 64 KiB are three times the 4 MiB receive buffer:
      // a receiver that keeps up (every build on an idle machine) answers
      // all 50, one slowed down (a sanitizer build, a loaded host) may lose
      // some in the kernel. Either way none may be lost silently (the issue
      // lost 703 of 800 with `dropped` 0): ExpectTransportRefusalsCounted
      // checks the missed ones against dropped_kernel_overflow.
      good_missed_amid_huge_ = static_cast<int64_t>(amid.size()) - answered;
      std::printf("good messages answered among %d 64 MiB first fragments: %d of %zu\n",
                  kHugeFragments, answered, amid.size());
    }
    check("LC03 first fragments declaring 64 MiB");

    sender_.Publish("STATUS", hostile::StatusWithNegativeStringLength());
    sender_.Publish("MARKER_PIXELS", hostile::MarkerPixelsWithNegativeStringLength());
    sender_.Publish("CAMERA_PREVIEW", hostile::CameraPreviewWithNegativeStringLength());
    sender_.Publish("CAMERA_DETECTOR_VIEW", hostile::DetectorViewWithNegativeStringLength());
    check("string lengths of INT32_MIN");

    sender_.Publish("RANGES", hostile::RangesClaimingCount(hostile::kHugeRangeCount));
    check("a 52-byte RANGES claiming 2^24 ranges");

    const int64_t now = NowUtime();
    sender_.Publish("RANGES", Encode(hostile::InconsistentRanges(400, kInconsistentSeq, now, 400)));
    check("400 mutually inconsistent ranges");
    sender_.Publish("RANGES",
                    Encode(hostile::InconsistentRanges(800, kInconsistentSeq + 1, now, 800)));
    check("800 mutually inconsistent ranges");

    sender_.Send(hostile::EmptyChannelDatagram(sender_.NextSeqno()));
    check("an empty channel name");

    const auto flood_start = Clock::now();
    for (int k = 0; k < kNewRobots; ++k) {
      const bool camera = k % 2 == 0;
      sender_.Publish(camera ? "POSE_CAMERA" : "POSE_ULTRASOUND",
                      Encode(hostile::PoseForNewRobot(
                          camera ? pose2d_t::SOURCE_CAMERA : pose2d_t::SOURCE_ULTRASOUND,
                          kFirstNewRobot + k, NowUtime())));
      if (k % 100 == 99) {
        std::this_thread::sleep_until(flood_start +
                                      std::chrono::duration<double>((k + 1) / kNewRobotRateHz));
      }
    }
    check("20 000 poses, each for a new robot");

    sender_.Publish("RANGES", Encode(hostile::NonFiniteRanges(kNonFiniteSeq, NowUtime())));
    for (const char* channel : {"POSE_CAMERA", "POSE_ULTRASOUND"}) {
      const int8_t source = std::strcmp(channel, "POSE_CAMERA") == 0 ? pose2d_t::SOURCE_CAMERA
                                                                     : pose2d_t::SOURCE_ULTRASOUND;
      for (const pose2d_t& p : hostile::NonFinitePoses(source, NowUtime())) {
        sender_.Publish(channel, Encode(p));
      }
    }
    check("NaN and infinite fields");

    int64_t seq = kAbsurdUtimeSeq;
    for (int64_t t : hostile::AbsurdUtimes(NowUtime())) {
      sender_.Publish("RANGES", Encode(hostile::GoodRanges(seq, t)));
      const int64_t pose_seq = seq - kAbsurdUtimeSeq;  // below kFirstRangeSeq
      sender_.Publish("POSE_CAMERA",
                      Encode(hostile::GoodPose(pose2d_t::SOURCE_CAMERA, pose_seq, t)));
      sender_.Publish("POSE_ULTRASOUND",
                      Encode(hostile::GoodPose(pose2d_t::SOURCE_ULTRASOUND, pose_seq, t)));
      ++seq;
    }
    const auto last_hostile = Clock::now();
    check("times 100 years away and at the int64 limits");
    return last_hostile;
  }

  // The checks every process with STATUS shares, on a STATUS made after the
  // attack: transport refusals counted by cause.
  void ExpectTransportRefusalsCounted(const process_status_t& s) const {
    EXPECT_GE(Counter(s, "dropped_kernel_overflow"), good_missed_amid_huge_)
        << good_missed_amid_huge_ << " good messages among the 64 MiB fragments unanswered\n"
        << Describe(s);
    EXPECT_GE(Counter(s, "fragments_malformed"), 1) << "fragments whose totals disagree\n"
                                                    << Describe(s);
    // Each 64 MiB message never completes: refused for the budget, or as
    // malformed (over the largest message), or expired. Half of them by the
    // time of this STATUS; the rest may still be waiting to expire.
    EXPECT_GE(Counter(s, "fragments_over_budget") + Counter(s, "fragments_expired") +
                  Counter(s, "fragments_malformed") - kConflictingMessages,
              kHugeFragments / 2)
        << "64 MiB first fragments\n"
        << Describe(s);
  }

  void ExpectMemoryBounded(int pid, double baseline_rss_mib) {
    const double peak = ProcMiB(pid, "VmHWM");
    if (peak < 0) return;  // gone: its death is already a failure
#ifdef __SANITIZE_ADDRESS__
    // AddressSanitizer keeps freed memory in a quarantine (256 MiB by
    // default) and adds shadow memory, so resident memory is not the
    // program's; the release build judges it.
    std::printf("memory growth not judged under AddressSanitizer\n");
    return;
#endif
    std::printf("pid %d: VmRSS %.1f MiB at start, VmHWM %.1f MiB after the attack\n", pid,
                baseline_rss_mib, peak);
    EXPECT_LT(peak - baseline_rss_mib, kMemoryGrowthMaxMiB);
  }

  // Firing and measurement numbers of what is sent: range sets and probes
  // from kFirstRangeSeq up, so a process's answers are told from the hostile
  // poses (numbered below it).
  static constexpr int64_t kFirstRangeSeq = 1'000'000;
  static constexpr int64_t kInconsistentSeq = 7'000'000;
  static constexpr int64_t kNonFiniteSeq = 7'100'000;
  static constexpr int64_t kAbsurdUtimeSeq = 7'200'000;
  static constexpr int32_t kFirstNewRobot = 1'000;

  hostile::Sender sender_{kDefaultLcmUrl};
  int64_t next_probe_id_ = kFirstRangeSeq;
};

uint32_t BigEndian32(const Bytes& b, size_t offset) {
  uint32_t v = 0;
  for (size_t i = 0; i < 4; ++i) v = (v << 8) | b.at(offset + i);
  return v;
}

// The generator itself: each class is the input the issue describes, so a
// process that passes the suite passed that input and not a near miss.
TEST(HostileGenerator, EachClassIsTheInputTheIssueDescribes) {
  const Bytes ranges = hostile::RangesClaimingCount(hostile::kHugeRangeCount);
  EXPECT_EQ(ranges.size(), 52u);
  EXPECT_EQ(BigEndian32(ranges, 48), 1u << 24);
  EXPECT_EQ(BigEndian32(ranges, 0), static_cast<uint32_t>(range_set_t::getHash() >> 32));

  for (const Bytes& b :
       {hostile::StatusWithNegativeStringLength(), hostile::MarkerPixelsWithNegativeStringLength(),
        hostile::CameraPreviewWithNegativeStringLength()}) {
    size_t int32_min_at = 0;
    for (size_t i = 8; i + 4 <= b.size(); ++i) {
      if (BigEndian32(b, i) == 0x80000000u) int32_min_at = i;
    }
    EXPECT_NE(int32_min_at, 0u) << "no INT32_MIN length in a " << b.size() << "-byte payload";
  }

  const auto pair = hostile::ConflictingTotalFragments(7, "RANGES");
  ASSERT_EQ(pair.size(), 2u);
  for (const Bytes& d : pair) {
    EXPECT_EQ(BigEndian32(d, 0), 0x4c433033u) << "LC03";
    EXPECT_EQ(BigEndian32(d, 4), 7u) << "one message";
  }
  const uint32_t first_total = BigEndian32(pair[0], 8);
  const uint32_t second_offset = BigEndian32(pair[1], 12);
  EXPECT_NE(first_total, BigEndian32(pair[1], 8));
  EXPECT_GT(second_offset, first_total) << "the second's data lies past the first's buffer";
  EXPECT_LE(second_offset + (pair[1].size() - 20), BigEndian32(pair[1], 8))
      << "and within its own total, so only a check against the first fragment finds it";

  const Bytes huge = hostile::HugeFirstFragment(9, "RANGES");
  EXPECT_EQ(BigEndian32(huge, 8), 64u << 20);
  EXPECT_EQ(huge[16] << 8 | huge[17], 0) << "fragment 0";
  const size_t data = huge.size() - 20 - std::strlen("RANGES") - 1;
  EXPECT_GE(static_cast<size_t>(huge[18] << 8 | huge[19]) * data, size_t{64} << 20)
      << "a fragment count that could complete it";

  const Bytes empty = hostile::EmptyChannelDatagram(3);
  EXPECT_EQ(BigEndian32(empty, 0), 0x4c433032u) << "LC02";
  EXPECT_EQ(empty.at(8), 0) << "the channel is empty";

  // The good range set is consistent: every range is the distance from the
  // robot's beacon to its receiver.
  const range_set_t good = hostile::GoodRanges(1, NowUtime());
  ASSERT_EQ(good.num_ranges, 4);
  for (const range_t& r : good.ranges) {
    const double d =
        std::hypot(r.receiver_position_m[0] - hostile::kGoodX_m,
                   r.receiver_position_m[1] - hostile::kGoodY_m, r.receiver_position_m[2] - 1.3);
    constexpr double kSameHypotM = 1e-12;  // the same distance computed again: rounding only
    EXPECT_NEAR(r.range_m, d, kSameHypotM);
  }
  const range_set_t bad = hostile::InconsistentRanges(400, 1, NowUtime(), 1);
  EXPECT_EQ(bad.num_ranges, 400);
  EXPECT_EQ(Encode(bad).size(), 52u + 400 * 52) << "52 bytes of header, 52 per range";
}

// Starts a process and waits for its first heartbeat.
bool WaitReady(Listener* listener, const std::string& name, ChildProcess* p, double* rss_mib) {
  process_status_t s;
  const bool ok = listener->StatusAfter(name, Clock::time_point{}, 10.0, &s) && Alive(p);
  SleepS(0.3);
  *rss_mib = ProcMiB(p->pid(), "VmRSS");
  return ok;
}

TEST_F(HostileTraffic, TrilatProcSurvivesEveryClassAndCountsEachRefusal) {
  Listener listener("POSE_ULTRASOUND");
  ChildProcess trilat({BinDir() + "/trilat_proc", "--config", DemoSitePath(), "--method", "robust",
                       "--log-level", "error"});
  double rss = 0;
  ASSERT_TRUE(WaitReady(&listener, "trilat_proc", &trilat, &rss));
  Probe probe{
      [&](int64_t id) { sender_.Publish("RANGES", Encode(hostile::GoodRanges(id, NowUtime()))); },
      [&](int64_t id) {
        Clock::time_point at;
        return listener.PoseArrived("POSE_ULTRASOUND", id, &at);
      }};
  const auto last = SendEveryClass(&probe, &trilat);
  process_status_t s;
  ASSERT_TRUE(listener.StatusAfter("trilat_proc", last, 3.0, &s)) << "no STATUS after the attack";
  ExpectTransportRefusalsCounted(s);
  EXPECT_GE(RejectedWithPrefix(s, "RANGES."), 1) << "2^24 ranges in 52 bytes\n" << Describe(s);
  EXPECT_GE(Rejected(s, "too_many_ranges") + Rejected(s, "RANGES.count_over_cap") +
                Rejected(s, "unknown_receiver"),
            2)
      << "400 and 800 inconsistent ranges\n"
      << Describe(s);
  EXPECT_GE(RejectedWithPrefix(s, "non_finite"), 1) << Describe(s);
  EXPECT_GE(Rejected(s, "utime_out_of_range"), 1) << Describe(s);
  for (const auto& p : listener.Poses()) {
    // trilat_proc's answers to the range sets sent here, not the hostile
    // poses this test itself sent on POSE_ULTRASOUND.
    if (p.p.robot_id != 1 || p.p.measurement_seq < kFirstRangeSeq) continue;
    if (p.p.status == pose2d_t::STATUS_LOST) continue;
    EXPECT_TRUE(std::isfinite(p.p.x_m) && std::isfinite(p.p.y_m)) << p.p.measurement_seq;
    EXPECT_TRUE(p.p.x_m >= -kRoomMargin_m && p.p.x_m <= kRoomX_m + kRoomMargin_m &&
                p.p.y_m >= -kRoomMargin_m && p.p.y_m <= kRoomY_m + kRoomMargin_m)
        << "pose (" << p.p.x_m << ", " << p.p.y_m << ") outside the room from firing "
        << p.p.measurement_seq << " of " << p.p.num_measurements << " ranges";
  }
  EXPECT_LE(listener.LongestHeartbeatGapS("trilat_proc"), kHeartbeatGapMaxS);
  ExpectMemoryBounded(trilat.pid(), rss);
  trilat.Signal(SIGINT);
  EXPECT_EQ(trilat.Wait(5), 0);
}

TEST_F(HostileTraffic, FusionProcKeepsOnlyTheSitesRobotsAndCountsTheRest) {
  Listener listener("POSE_FUSED");
  ChildProcess fusion(
      {BinDir() + "/fusion_proc", "--config", DemoSitePath(), "--log-level", "error"});
  double rss = 0;
  ASSERT_TRUE(WaitReady(&listener, "fusion_proc", &fusion, &rss));
  Probe probe{[&](int64_t id) {
                sender_.Publish("POSE_CAMERA",
                                Encode(hostile::GoodPose(pose2d_t::SOURCE_CAMERA, id, NowUtime())));
              },
              [&](int64_t id) {
                Clock::time_point at;
                return listener.PoseArrived("POSE_FUSED", id, &at);
              }};
  const auto last = SendEveryClass(&probe, &fusion);
  process_status_t s;
  ASSERT_TRUE(listener.StatusAfter("fusion_proc", last, 3.0, &s)) << "no STATUS after the attack";
  ExpectTransportRefusalsCounted(s);
  // Every new robot is refused, or lost in transport and counted there.
  EXPECT_GE(Rejected(s, "unknown_robot") + s.dropped, kNewRobots) << Describe(s);
  EXPECT_GE(Rejected(s, "unknown_robot"), kNewRobots / 2) << Describe(s);
  EXPECT_GE(RejectedWithPrefix(s, "non_finite"), 1) << Describe(s);
  EXPECT_GE(Rejected(s, "utime_out_of_range"), 1) << Describe(s);
  std::set<int32_t> fused_robots;
  for (const auto& p : listener.Poses()) {
    fused_robots.insert(p.p.robot_id);
    if (p.p.status != pose2d_t::STATUS_LOST) {
      EXPECT_TRUE(std::isfinite(p.p.x_m) && std::isfinite(p.p.y_m)) << p.p.measurement_seq;
    }
  }
  EXPECT_EQ(fused_robots, std::set<int32_t>{1}) << "POSE_FUSED only for the site's robot 1";
  EXPECT_LE(listener.LongestHeartbeatGapS("fusion_proc"), kHeartbeatGapMaxS);
  ExpectMemoryBounded(fusion.pid(), rss);
  fusion.Signal(SIGINT);
  EXPECT_EQ(fusion.Wait(5), 0);
}

// Issue #28, items 6 and 7: times from the future. On the two-radio site a
// RANGES part dated +30 min sent between the two real parts of each firing
// split every firing into three poses; a whole set dated +3 590 s (inside
// the old symmetric hour) gave an ok pose an hour ahead with latency_us
// -3.59e9. Each firing must get one pose from all eight ranges, and no pose
// may be dated ahead or carry a negative latency.
range_set_t TwoRadiosPart(const Site& site, int radio_id, int64_t firing_seq, int64_t utime) {
  constexpr double kBeaconX_m = 6.0, kBeaconY_m = 4.0, kBeaconZ_m = 1.0;  // two_radios.yaml
  constexpr double kSpeedOfSound_mps = 343.4;
  range_set_t s{};
  s.utime = utime;
  s.beacon_id = 1;
  s.firing_seq = firing_seq;
  s.speed_of_sound_mps = kSpeedOfSound_mps;
  s.temperature_c = 20.0;
  for (const RadioNetwork& radio : site.radios) {
    if (radio.id != radio_id) continue;
    for (int id : radio.receiver_ids) {
      const Receiver* receiver = site.FindReceiver(id);
      range_t r{};
      r.receiver_id = id;
      for (int k = 0; k < 3; ++k) r.receiver_position_m[k] = receiver->position_m[k];
      r.range_m =
          std::hypot(receiver->position_m[0] - kBeaconX_m, receiver->position_m[1] - kBeaconY_m,
                     receiver->position_m[2] - kBeaconZ_m);
      r.time_of_flight_us = r.range_m / kSpeedOfSound_mps * 1e6;
      r.arrival_utime = utime + 20'000;
      s.ranges.push_back(r);
    }
  }
  s.num_ranges = static_cast<int32_t>(s.ranges.size());
  s.num_expected = s.num_ranges;
  return s;
}

TEST_F(HostileTraffic, FarDatedPartsNeitherSplitAFiringNorGiveAPoseFromTheFuture) {
  constexpr int64_t kThirtyMinutesUs = int64_t{30} * 60 * 1'000'000;
  constexpr int64_t kAlmostAnHourUs = int64_t{3'590} * 1'000'000;
  constexpr int kFirings = 10;
  constexpr int64_t kFutureSeq = 900;
  const std::string site_path = testing::SourceDir() + "/config/sites/two_radios.yaml";
  Site site;
  std::string error;
  ASSERT_TRUE(LoadSite(site_path, &site, &error)) << error;
  Listener listener("POSE_ULTRASOUND");
  ChildProcess trilat({BinDir() + "/trilat_proc", "--config", site_path, "--method", "robust",
                       "--log-level", "error"});
  double rss = 0;
  ASSERT_TRUE(WaitReady(&listener, "trilat_proc", &trilat, &rss));
  for (int k = 0; k < kFirings; ++k) {
    const int64_t t = NowUtime();
    sender_.Publish("RANGES", Encode(TwoRadiosPart(site, 1, k, t)));
    sender_.Publish("RANGES", Encode(TwoRadiosPart(site, 2, k, t + kThirtyMinutesUs)));
    sender_.Publish("RANGES", Encode(TwoRadiosPart(site, 2, k, t + 1'000)));
    SleepS(0.2);
  }
  range_set_t whole = TwoRadiosPart(site, 1, kFutureSeq, NowUtime() + kAlmostAnHourUs);
  const range_set_t east = TwoRadiosPart(site, 2, kFutureSeq, whole.utime);
  whole.ranges.insert(whole.ranges.end(), east.ranges.begin(), east.ranges.end());
  whole.num_ranges = whole.num_expected = static_cast<int32_t>(whole.ranges.size());
  const auto last = Clock::now();
  sender_.Publish("RANGES", Encode(whole));
  process_status_t s;
  ASSERT_TRUE(listener.StatusAfter("trilat_proc", last, 3.0, &s)) << "no STATUS after the attack";
  std::map<int64_t, std::vector<int32_t>> ranges_per_firing;
  for (const auto& p : listener.Poses()) {
    if (p.channel != "POSE_ULTRASOUND") continue;
    ranges_per_firing[p.p.measurement_seq].push_back(p.p.num_measurements);
    EXPECT_GE(p.p.latency_us, 0) << "firing " << p.p.measurement_seq;
    EXPECT_LE(p.p.utime, NowUtime()) << "firing " << p.p.measurement_seq << " dated ahead";
  }
  for (int k = 0; k < kFirings; ++k) {
    EXPECT_EQ(ranges_per_firing[k], std::vector<int32_t>{8}) << "firing " << k << "\n"
                                                             << Describe(s);
  }
  EXPECT_EQ(ranges_per_firing.count(kFutureSeq), 0u) << "the set dated +3 590 s was solved";
  EXPECT_GE(Rejected(s, "utime_out_of_range"), kFirings + 1) << Describe(s);
  trilat.Signal(SIGINT);
  EXPECT_EQ(trilat.Wait(5), 0);
}

// Issue #28, item 7: one POSE_CAMERA dated +0.5 s gave a degraded POSE_FUSED
// with a negative latency. It is refused; no fused pose is ever dated ahead
// of its publication or carries a negative latency.
TEST_F(HostileTraffic, FusionProcRefusesAPoseFromTheFutureAndNeverPublishesANegativeLatency) {
  constexpr int64_t kHalfASecondUs = 500'000;
  Listener listener("POSE_FUSED");
  ChildProcess fusion(
      {BinDir() + "/fusion_proc", "--config", DemoSitePath(), "--log-level", "error"});
  double rss = 0;
  ASSERT_TRUE(WaitReady(&listener, "fusion_proc", &fusion, &rss));
  for (int64_t seq = 1; seq <= 20; ++seq) {
    const int64_t ahead_us = seq % 2 == 0 ? kHalfASecondUs : 0;
    sender_.Publish("POSE_CAMERA",
                    Encode(hostile::GoodPose(pose2d_t::SOURCE_CAMERA, seq, NowUtime() + ahead_us)));
    SleepS(0.05);
  }
  const auto last = Clock::now();
  process_status_t s;
  ASSERT_TRUE(listener.StatusAfter("fusion_proc", last, 3.0, &s)) << "no STATUS after the attack";
  EXPECT_GE(Rejected(s, "utime_out_of_range"), 1) << Describe(s);
  int fused = 0;
  for (const auto& p : listener.Poses()) {
    if (p.channel != "POSE_FUSED") continue;
    ++fused;
    EXPECT_GE(p.p.latency_us, 0) << "measurement " << p.p.measurement_seq;
  }
  EXPECT_GT(fused, 0) << "the poses on time were fused";
  fusion.Signal(SIGINT);
  EXPECT_EQ(fusion.Wait(5), 0);
}

// The viewer has no per-message output: its heartbeat must keep its pace,
// the good poses after the attack must be counted as inputs, and its CPU
// use must fall back to idle once the traffic stops.
TEST_F(HostileTraffic, HeadlessViewerSurvivesEveryClassAndForgetsUnknownRobots) {
  TempDir dir;
  Listener listener("");
  ChildProcess viewer({BinDir() + "/roomfix_viewer", "--config", DemoSitePath(), "--headless",
                       "--png", dir.File("view.png"), "--log-level", "error"});
  double rss = 0;
  ASSERT_TRUE(WaitReady(&listener, "roomfix_viewer", &viewer, &rss));
  const double idle_cpu0 = CpuSeconds(viewer.pid());
  SleepS(1.0);
  const double idle_cpu = CpuSeconds(viewer.pid()) - idle_cpu0;

  const auto last = SendEveryClass(nullptr, &viewer);
  const double busy_cpu0 = CpuSeconds(viewer.pid());
  SleepS(1.0);
  const double after_cpu = CpuSeconds(viewer.pid()) - busy_cpu0;
  std::printf("roomfix_viewer CPU: %.0f %% idle, %.0f %% in the second after the attack\n",
              idle_cpu * 100, after_cpu * 100);
  EXPECT_LE(after_cpu, idle_cpu + kViewerCpuOverIdleMax);

  process_status_t s;
  ASSERT_TRUE(listener.StatusAfter("roomfix_viewer", last, 3.0, &s));
  ExpectTransportRefusalsCounted(s);
  for (const char* channel :
       {"STATUS.", "MARKER_PIXELS.", "CAMERA_PREVIEW.", "CAMERA_DETECTOR_VIEW.", "RANGES."}) {
    EXPECT_GE(RejectedWithPrefix(s, channel), 1) << channel << "\n" << Describe(s);
  }
  EXPECT_GE(Rejected(s, "unknown_robot") + s.dropped, kNewRobots) << Describe(s);
  EXPECT_GE(Rejected(s, "unknown_robot"), kNewRobots / 2) << Describe(s);
  EXPECT_GE(Rejected(s, "utime_out_of_range"), 1) << Describe(s);
  // Robot 1 at most once per pose source (camera, ultrasound, fused, truth).
  EXPECT_LE(Counter(s, "tracks"), 4) << Describe(s);

  // Good poses after the attack are taken in.
  const auto quiet = Clock::now();
  process_status_t before;
  ASSERT_TRUE(listener.StatusAfter("roomfix_viewer", quiet, 3.0, &before));
  constexpr int kGood = 10;
  for (int k = 0; k < kGood; ++k) {
    sender_.Publish("POSE_CAMERA",
                    Encode(hostile::GoodPose(pose2d_t::SOURCE_CAMERA, k, NowUtime())));
  }
  process_status_t after;
  ASSERT_TRUE(listener.StatusAfter("roomfix_viewer", Clock::now(), 3.0, &after));
  // At least: the viewer also takes in STATUS heartbeats, its own included.
  EXPECT_GE(after.inputs - before.inputs, kGood) << Describe(after);

  EXPECT_LE(listener.LongestHeartbeatGapS("roomfix_viewer"), kHeartbeatGapMaxS);
  ExpectMemoryBounded(viewer.pid(), rss);
  viewer.Signal(SIGINT);
  EXPECT_EQ(viewer.Wait(10), 0);
}

// camera_proc on the demo site's synthetic camera, whose calibration makes
// it subscribe to POSE_ULTRASOUND for search hints.
TEST_F(HostileTraffic, CameraProcsHintSubscriptionSurvivesEveryClass) {
  Listener listener("");
  ChildProcess camera({BinDir() + "/camera_proc", "--config", DemoSitePath(), "--device",
                       "sim:reference_circle", "--log-level", "error"});
  double rss = 0;
  ASSERT_TRUE(WaitReady(&listener, "camera_proc", &camera, &rss));
  const auto last = SendEveryClass(nullptr, &camera);
  process_status_t s;
  ASSERT_TRUE(listener.StatusAfter("camera_proc", last, 3.0, &s));
  ExpectTransportRefusalsCounted(s);

  // Requests for the detector's view (issue #31) that must be refused, a
  // thousand times each: every one refused and counted, none turns the view
  // on, the heartbeat keeps its period.
  const std::vector<hostile::Bytes> requests = hostile::HostileDetectorViewRequests(NowUtime());
  constexpr int kRounds = 1000;
  for (int k = 0; k < kRounds; ++k) {
    for (const hostile::Bytes& r : requests) sender_.Publish("CAMERA_DETECTOR_VIEW_REQUEST", r);
    if (k % 50 == 49) SleepS(0.01);
  }
  process_status_t refused;
  ASSERT_TRUE(listener.StatusAfter("camera_proc", Clock::now(), 3.0, &refused));
  const int64_t refusals = RejectedWithPrefix(refused, "detector_view_bad_") +
                           RejectedWithPrefix(refused, "CAMERA_DETECTOR_VIEW_REQUEST.");
  std::printf("camera_proc refused %lld of %zu hostile detector-view requests (dropped %lld)\n",
              static_cast<long long>(refusals), requests.size() * kRounds,
              static_cast<long long>(refused.dropped));
  EXPECT_GE(refusals + refused.dropped, static_cast<int64_t>(requests.size()) * kRounds)
      << Describe(refused);
  EXPECT_GE(refusals, static_cast<int64_t>(requests.size())) << Describe(refused);
  EXPECT_EQ(Counter(refused, "detector_view_requests"), 0) << Describe(refused);
  EXPECT_TRUE(Alive(&camera));

  // Good hints after the attack are taken.
  process_status_t before;
  ASSERT_TRUE(listener.StatusAfter("camera_proc", Clock::now(), 3.0, &before));
  constexpr int kGood = 10;
  for (int k = 0; k < kGood; ++k) {
    sender_.Publish("POSE_ULTRASOUND",
                    Encode(hostile::GoodPose(pose2d_t::SOURCE_ULTRASOUND, k, NowUtime())));
  }
  process_status_t after;
  ASSERT_TRUE(listener.StatusAfter("camera_proc", Clock::now(), 3.0, &after));
  EXPECT_EQ(Counter(after, "hints") - Counter(before, "hints"), kGood) << Describe(after);

  EXPECT_LE(listener.LongestHeartbeatGapS("camera_proc"), kHeartbeatGapMaxS);
  ExpectMemoryBounded(camera.pid(), rss);
  camera.Signal(SIGINT);
  EXPECT_EQ(camera.Wait(10), 0);
}

TEST_F(HostileTraffic, LoggerRecordsGoodTrafficAndItsFileStaysReadable) {
  TempDir dir;
  const std::string path = dir.File("hostile.lcm");
  Listener listener("");
  ChildProcess logger(
      {BinDir() + "/roomfix_logger", path, "--flush-interval", "10", "--log-level", "error"});
  double rss = 0;
  ASSERT_TRUE(WaitReady(&listener, "roomfix_logger", &logger, &rss));
  FileTail tail(path, "probe-", 10);
  auto token = [](int64_t id) { return fmt::format("probe-{:010d}", id); };
  std::vector<int64_t> probes;
  Probe probe{[&](int64_t id) {
                probes.push_back(id);
                const std::string t = token(id);
                sender_.Publish("PROBE", Bytes(t.begin(), t.end()));
              },
              [&](int64_t id) { return tail.Contains(id); }};
  const auto last = SendEveryClass(&probe, &logger);
  // One more after everything, so the file's end is a good event.
  EXPECT_LE(AnswerTimeS(probe), kAnswerWithinS);

  process_status_t s;
  ASSERT_TRUE(listener.StatusAfter("roomfix_logger", last, 3.0, &s));
  ExpectTransportRefusalsCounted(s);
  EXPECT_GE(Rejected(s, "unloggable_channel"), 1) << Describe(s);
  EXPECT_LE(listener.LongestHeartbeatGapS("roomfix_logger"), kHeartbeatGapMaxS);
  ExpectMemoryBounded(logger.pid(), rss);
  logger.Signal(SIGINT);
  EXPECT_EQ(logger.Wait(10), 0);

  // LCM's own reader (the one lcm-logplayer uses) reads to the end: every
  // probe, the last one included, nothing with an empty channel.
  lcm::LogFile log(path, "r");
  ASSERT_TRUE(log.good());
  std::vector<int64_t> read_probes;
  int64_t events = 0;
  while (const lcm::LogEvent* e = log.readNextEvent()) {
    ++events;
    EXPECT_FALSE(e->channel.empty()) << "event " << e->eventnum;
    if (e->channel != "PROBE") continue;
    const std::string text(static_cast<const char*>(e->data), static_cast<size_t>(e->datalen));
    read_probes.push_back(std::stoll(text.substr(6)));
  }
  EXPECT_EQ(read_probes, probes) << "of " << events << " events read by lcm::LogFile";
}

TEST_F(HostileTraffic, ListenPrintsGoodTrafficAndWarnsOfRefusals) {
#ifdef __SANITIZE_ADDRESS__
  // `listen --channel '.*'` prints every message, in order, the 20 000
  // forged poses too: under AddressSanitizer each costs several times more,
  // and that backlog alone held the next good message 0.8 s and more (issue
  // #28), and on a loaded machine listen was still draining the flood when
  // the good message came, its kernel buffer full: the datagram was
  // dropped (and counted), never answered. Not a defect of listen (the
  // ordinary build answers within kAnswerWithinS after every class); here
  // good traffic must come out once the backlog has drained: a probe sent
  // again each second, answered within 10 s.
  answer_within_s_ = 10.0;
  probe_timeout_s_ = 12.0;
  probe_resend_s_ = 1.0;
#endif
  TempDir dir;
  const std::string out = dir.File("listen.out");
  const std::string err = dir.File("listen.err");
  ChildProcess listen(
      {"/bin/sh", "-c", "exec \"$0\" listen --channel '.*' 2>\"$1\"", BinDir() + "/roomfix", err},
      out);
  SleepS(0.5);
  ASSERT_TRUE(Alive(&listen));
  FileTail tail(out, "\"channel\":\"PROBE_");
  Probe probe{[&](int64_t id) {
                sender_.Publish("PROBE_" + std::to_string(id),
                                Encode(hostile::GoodPose(pose2d_t::SOURCE_CAMERA, id, NowUtime())));
              },
              [&](int64_t id) { return tail.Contains(id); }};
  SendEveryClass(&probe, &listen);
  SleepS(0.2);
  listen.Signal(SIGINT);
  EXPECT_EQ(listen.Wait(10), 0);
  // One warning line with the count per reason (the contract for tools
  // without STATUS): the three INT32_MIN strings, and the 2^24 count in 52
  // bytes refused for its cap or for the bytes it lacks.
  const std::string warnings = testing::ReadFile(err);
  EXPECT_NE(warnings.find("negative_length"), std::string::npos) << warnings;
  EXPECT_TRUE(warnings.find("count_over_cap") != std::string::npos ||
              warnings.find("truncated") != std::string::npos)
      << warnings;
}

// A process frozen (SIGSTOP) behind a small receive buffer while range sets
// keep coming: after SIGCONT, what it never received is in STATUS `dropped`
// and in the kernel or queue overflow counters (the issue: 33 of 50 lost,
// dropped 0).
constexpr char kSmallBufferUrl[] = "udpm://239.255.76.67:7667?ttl=0&recv_buf_size=16384";
constexpr int kSentWhileStopped = 300;
constexpr double kStoppedRateHz = 100;

int64_t TransportDropped(const process_status_t& s) {
  return Counter(s, "dropped_kernel_overflow") + Counter(s, "dropped_queue_overflow");
}

// Freezes `process` (SIGSTOP) while kSentWhileStopped range sets go out on
// `channel` at kStoppedRateHz, then thaws it; its STATUS from before the
// freeze and from after it.
void SendWhileStopped(hostile::Sender* sender, Listener* listener, ChildProcess* process,
                      const std::string& name, const std::string& channel, process_status_t* before,
                      process_status_t* after) {
  ASSERT_TRUE(listener->StatusAfter(name, Clock::now(), 3.0, before));
  process->Signal(SIGSTOP);
  const auto start = Clock::now();
  for (int k = 0; k < kSentWhileStopped; ++k) {
    std::this_thread::sleep_until(start + std::chrono::duration<double>(k / kStoppedRateHz));
    sender->Publish(channel, Encode(hostile::GoodRanges(k, NowUtime())));
  }
  process->Signal(SIGCONT);
  ASSERT_TRUE(
      listener->StatusAfter(name, Clock::now() + std::chrono::milliseconds(200), 3.0, after));
}

// What a stopped process `missed` is in its STATUS `dropped` and in the
// kernel or queue overflow counters.
void ExpectMissedCounted(int64_t missed, const process_status_t& before,
                         const process_status_t& after) {
  ASSERT_GT(missed, 0) << "the small receive buffer did not overflow: the test proves nothing";
  EXPECT_GE(after.dropped - before.dropped, missed) << Describe(after);
  EXPECT_GE(TransportDropped(after) - TransportDropped(before), missed) << Describe(after);
}

TEST_F(HostileTraffic, TrilatProcStoppedAccountsForEveryRangeSetItMissed) {
  Listener listener("");
  ChildProcess trilat({BinDir() + "/trilat_proc", "--config", DemoSitePath(), "--lcm-url",
                       kSmallBufferUrl, "--log-level", "error"});
  double rss = 0;
  ASSERT_TRUE(WaitReady(&listener, "trilat_proc", &trilat, &rss));
  process_status_t before, after;
  ASSERT_NO_FATAL_FAILURE(
      SendWhileStopped(&sender_, &listener, &trilat, "trilat_proc", "RANGES", &before, &after));
  const int64_t taken = after.inputs - before.inputs;
  const int64_t missed = kSentWhileStopped - taken;
  std::printf("trilat_proc stopped: %lld of %d range sets taken, %lld missed, dropped +%lld\n",
              static_cast<long long>(taken), kSentWhileStopped, static_cast<long long>(missed),
              static_cast<long long>(after.dropped - before.dropped));
  ASSERT_NO_FATAL_FAILURE(ExpectMissedCounted(missed, before, after));
  trilat.Signal(SIGINT);
  EXPECT_EQ(trilat.Wait(5), 0);
}

TEST_F(HostileTraffic, LoggerStoppedAccountsForEveryMessageItMissed) {
  TempDir dir;
  const std::string path = dir.File("stopped.lcm");
  Listener listener("");
  ChildProcess logger({BinDir() + "/roomfix_logger", path, "--channel", "SEQ", "--lcm-url",
                       kSmallBufferUrl, "--log-level", "error"});
  double rss = 0;
  ASSERT_TRUE(WaitReady(&listener, "roomfix_logger", &logger, &rss));
  process_status_t before, after;
  ASSERT_NO_FATAL_FAILURE(
      SendWhileStopped(&sender_, &listener, &logger, "roomfix_logger", "SEQ", &before, &after));
  logger.Signal(SIGINT);
  EXPECT_EQ(logger.Wait(10), 0);
  int64_t logged = 0;
  lcm::LogFile log(path, "r");
  ASSERT_TRUE(log.good());
  while (const lcm::LogEvent* e = log.readNextEvent()) logged += e->channel == "SEQ" ? 1 : 0;
  const int64_t missed = kSentWhileStopped - logged;
  std::printf("roomfix_logger stopped: %lld of %d logged, %lld missed, dropped +%lld\n",
              static_cast<long long>(logged), kSentWhileStopped, static_cast<long long>(missed),
              static_cast<long long>(after.dropped - before.dropped));
  ASSERT_NO_FATAL_FAILURE(ExpectMissedCounted(missed, before, after));
}

}  // namespace
}  // namespace roomfix

namespace roomfix {
namespace {

// Issue #28, item 1: one forged 259 KB SITE (the demo site with, as its
// camera's calibration, a flat map of about 13 600 keys, and a valid hash)
// held `roomfix listen --config` about 20 s: the comparison with --config
// looked each key up by a scan of the mapping. A stream of them, each a new
// site: good traffic is answered within kAnswerWithinS during the stream
// and after it, and every forged site examined is named with its count of
// differing keys.
// The calibration text of the issue's 259 KB message (the demo site's text
// is the rest), under the 256 KiB a site_t carries per file.
constexpr size_t kForgedCalibrationBytes = 250 * 1024;
constexpr int kForgedSites = 20;
constexpr double kForgedSiteRateHz = 10.0;
// After SIGINT, listen examines at most LiveSiteWatch::kMaxPending (8)
// waiting sites and exits: a few seconds even on a loaded machine.
constexpr double kListenExitS = 20.0;

TEST_F(HostileTraffic, ListenWithConfigAnswersGoodTrafficAmidAStreamOfForgedSites) {
  TempDir dir;
  const std::string out = dir.File("listen.out");
  const std::string err = dir.File("listen.err");
  ChildProcess listen(
      {"/bin/sh", "-c", "exec \"$0\" listen --config \"$2\" --channel 'PROBE_.*' 2>\"$1\"",
       BinDir() + "/roomfix", err, DemoSitePath()},
      out);
  SleepS(0.5);
  ASSERT_TRUE(Alive(&listen));
  FileTail tail(out, "\"channel\":\"PROBE_");
  Probe probe{[&](int64_t id) {
                sender_.Publish("PROBE_" + std::to_string(id),
                                Encode(hostile::GoodPose(pose2d_t::SOURCE_CAMERA, id, NowUtime())));
              },
              [&](int64_t id) { return tail.Contains(id); }};
  AnswerTimeS(probe);  // warm
  const size_t keys = testing::FlatKeysForBytes(kForgedCalibrationBytes);
  std::vector<Bytes> forged;
  for (int k = 0; k < kForgedSites; ++k) {
    forged.push_back(Encode(testing::ForgedSiteWithFlatCalibration(keys, k + 1, "forger")));
  }
  ASSERT_GE(forged.front().size(), 259000u);
  const auto start = Clock::now();
  for (int k = 0; k < kForgedSites; ++k) {
    ASSERT_TRUE(sender_.Publish("SITE", forged[k]));
    const double t = AnswerTimeS(probe);
    EXPECT_LE(t, kAnswerWithinS) << "good traffic after forged SITE " << k << " answered in " << t
                                 << " s";
    const auto due = start + std::chrono::duration<double>((k + 1) / kForgedSiteRateHz);
    std::this_thread::sleep_until(due);
  }
  SleepS(1.0);
  const double after = AnswerTimeS(probe);
  EXPECT_LE(after, kAnswerWithinS) << "good traffic after the stream answered in " << after << " s";
  ASSERT_TRUE(Alive(&listen));
  listen.Signal(SIGINT);
  EXPECT_EQ(listen.Wait(kListenExitS), 0);
  // The demo calibration's own top-level keys are absent from the forged one
  // and every forged key from the real one.
  const std::string warnings = testing::ReadFile(err);
  EXPECT_NE(warnings.find("and SITE from forger ("), std::string::npos) << warnings.substr(0, 2000);
  EXPECT_NE(warnings.find(" keys: calibration '../calibration/demo_room_camera.yaml' "),
            std::string::npos)
      << warnings.substr(0, 2000);
}

}  // namespace
}  // namespace roomfix
