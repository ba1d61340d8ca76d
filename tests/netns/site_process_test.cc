// Issue #20: real processes publish their site on SITE at start and every
// 5 s (issue #28: one process per site, and to newcomers), state its hash in STATUS, and a log
// recorded by LCM's own lcm-logger carries it; two processes started with different sites are named
// by `roomfix analyze` and the viewer.
#include <gtest/gtest.h>
#include <signal.h>

#include <chrono>
#include <map>
#include <string>
#include <thread>
#include <vector>

#include "msgio/log.h"
#include "msgio/site_message.h"
#include "msgio/wire_check.h"
#include "tests/testing/demo_site.h"
#include "tests/testing/test_paths.h"

namespace roomfix {
namespace {

using testing::BinDir;
using testing::ChildProcess;
using testing::DemoSitePath;
using testing::ReadFile;
using testing::TempDir;

// A process republishes on its first heartbeat at least kSitePeriodUs after
// the last SITE; heartbeats come from a run loop ticking every 10 ms or so
// (50 ms for the sim's tick at 20 Hz). 0.3 s covers that and a loaded
// machine's scheduling.
constexpr int64_t kPeriodToleranceUs = 300000;

struct Recorded {
  std::map<std::string, std::vector<site_t>> sites;  // by process
  std::map<std::string, std::vector<process_status_t>> statuses;
};

Recorded ReadLog(const std::string& path) {
  Recorded r;
  std::string error;
  auto reader = LogReader::Open(path, &error);
  EXPECT_NE(reader, nullptr) << error;
  if (reader == nullptr) return r;
  LogEvent e;
  while (reader->Next(&e)) {
    const int n = static_cast<int>(e.data.size());
    if (e.channel == kSiteChannel) {
      site_t m;
      if (DecodeChecked(e.data.data(), n, &m, nullptr)) r.sites[m.process].push_back(m);
    } else if (e.channel == "STATUS") {
      process_status_t m;
      if (DecodeChecked(e.data.data(), n, &m, nullptr)) r.statuses[m.process].push_back(m);
    }
  }
  return r;
}

// The demo site with receiver 3 moved by 5 cm, beside its calibration.
std::string MovedSite(const TempDir& dir) {
  std::string error;
  const std::string path = testing::WriteDemoSiteVariant(
      dir, "moved", "position_m: [4.0, 3.0, 2.5]", "position_m: [4.05, 3.0, 2.5]", &error);
  EXPECT_NE(path, "") << error;
  return path;
}

TEST(SiteOnTheBus, ProcessesPublishTheirSiteAtStartToANewcomerAndEveryFiveSeconds) {
  TempDir dir;
  const std::string demo = DemoSitePath();
  const std::string moved = MovedSite(dir);
  ChildProcess logger({"lcm-logger", "-q", "-f", dir.File("run.lcm")});
  ASSERT_TRUE(logger.started());
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  ChildProcess trilat({BinDir() + "/trilat_proc", "--config", demo, "--log-level", "warn"});
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  // fusion_proc with another site: the disagreement the tools must name.
  ChildProcess fusion({BinDir() + "/fusion_proc", "--config", moved, "--log-level", "warn"});
  std::this_thread::sleep_for(std::chrono::milliseconds(11500));
  trilat.Signal(SIGINT);
  fusion.Signal(SIGINT);
  EXPECT_EQ(trilat.Wait(10), 0);
  EXPECT_EQ(fusion.Wait(10), 0);
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  logger.Signal(SIGINT);
  logger.Wait(5);

  const Recorded r = ReadLog(dir.File("run.lcm"));
  ASSERT_EQ(r.sites.count("trilat_proc"), 1u);
  const std::vector<site_t>& sites = r.sites.at("trilat_proc");
  const std::vector<process_status_t>& statuses = r.statuses.at("trilat_proc");
  // About 12 s of running, alone with its site (fusion_proc's differs):
  // SITE at start, an answer to fusion_proc, a newcomer 0.5 s later, at the
  // first heartbeat a second or more after that, then every 5 s: 0, 1, 6
  // and 11 s.
  ASSERT_EQ(sites.size(), 4u);
  // At start: with the first heartbeat.
  EXPECT_EQ(sites[0].utime, statuses.front().utime);
  constexpr int64_t kHeartbeatUs = 1000000;
  EXPECT_GE(sites[1].utime - sites[0].utime, SitePublishSchedule::kSiteAnswerGapUs);
  EXPECT_LE(sites[1].utime - sites[0].utime,
            SitePublishSchedule::kSiteAnswerGapUs + kHeartbeatUs + kPeriodToleranceUs);
  for (size_t i = 2; i < sites.size(); ++i) {
    EXPECT_NEAR(static_cast<double>(sites[i].utime - sites[i - 1].utime),
                static_cast<double>(kSitePeriodUs), kPeriodToleranceUs);
  }
  // The texts are the files', the hash theirs, and STATUS states it.
  LoadedSite on_disk;
  std::string error;
  ASSERT_TRUE(LoadSiteWithTexts(demo, &on_disk, &error)) << error;
  EXPECT_EQ(sites[0].site_text, on_disk.texts.site_text);
  EXPECT_EQ(sites[0].content_hash, on_disk.content_hash);
  EXPECT_EQ(sites[0].roomfix_version, RoomfixVersion());
  bool stated = false;
  for (const auto& c : statuses.back().counters) {
    if (c.name == kSiteHashCounter) {
      stated = true;
      EXPECT_EQ(SiteHashCounterText(c.count), on_disk.content_hash.substr(0, 15));
    }
  }
  EXPECT_TRUE(stated);
  ASSERT_EQ(r.sites.count("fusion_proc"), 1u);
  EXPECT_NE(r.sites.at("fusion_proc")[0].content_hash, on_disk.content_hash);

  // analyze, without --config: the log holds two sites, so it does not pick
  // one; the note names both hashes with their publishers and asks for
  // --config.
  ChildProcess analyze({"sh", "-c",
                        "exec '" + BinDir() + "/roomfix' analyze '" + dir.File("run.lcm") +
                            "' --no-figures --out '" + dir.File("report") + "' 2>'" +
                            dir.File("err.txt") + "'"});
  analyze.Wait(60);
  const std::string err = ReadFile(dir.File("err.txt"));
  EXPECT_NE(err.find(dir.File("run.lcm") + " holds SITE messages of 2 different sites"),
            std::string::npos)
      << err;
  EXPECT_NE(err.find(ShortSiteHash(on_disk.content_hash) + " by trilat_proc@"), std::string::npos)
      << err;
  EXPECT_NE(err.find(ShortSiteHash(r.sites.at("fusion_proc")[0].content_hash) + " by fusion_proc@"),
            std::string::npos)
      << err;
  EXPECT_NE(err.find("give the site file with --config"), std::string::npos) << err;

  // With --config: that site, and the disagreement naming both processes.
  ChildProcess analyze_config({"sh", "-c",
                               "exec '" + BinDir() + "/roomfix' analyze '" + dir.File("run.lcm") +
                                   "' --config '" + demo + "' --no-figures --out '" +
                                   dir.File("report2") + "' 2>'" + dir.File("err2.txt") + "'"});
  ASSERT_EQ(analyze_config.Wait(60), 0);
  const std::string err2 = ReadFile(dir.File("err2.txt"));
  EXPECT_NE(err2.find("warning: " + dir.File("run.lcm") + ": processes disagree on the site: "),
            std::string::npos)
      << err2;

  // The viewer, replaying it, warns too (the same tracker as live).
  ChildProcess viewer({"sh", "-c",
                       "exec '" + BinDir() + "/roomfix_viewer' --log '" + dir.File("run.lcm") +
                           "' --config '" + demo + "' --headless --png '" + dir.File("v.png") +
                           "' 2>'" + dir.File("viewer.txt") + "'"});
  ASSERT_EQ(viewer.Wait(60), 0);
  const std::string viewer_err = ReadFile(dir.File("viewer.txt"));
  EXPECT_NE(viewer_err.find("processes disagree on the site"), std::string::npos) << viewer_err;
}

// `roomfix listen --config` live: describes the site a process publishes
// and names the key where it differs from the file.
TEST(SiteOnTheBus, ListenNamesTheKeyWhereAPublishedSiteDiffersFromConfig) {
  TempDir dir;
  const std::string moved = MovedSite(dir);
  ChildProcess listen({"sh", "-c",
                       "exec '" + BinDir() +
                           "/roomfix' listen --channel SITE --count 1 --timeout 10 --config '" +
                           DemoSitePath() + "' 2>'" + dir.File("err.txt") + "'"});
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  ChildProcess trilat({BinDir() + "/trilat_proc", "--config", moved, "--log-level", "warn"});
  EXPECT_EQ(listen.Wait(15), 0);
  trilat.Signal(SIGINT);
  EXPECT_EQ(trilat.Wait(10), 0);
  const std::string err = ReadFile(dir.File("err.txt"));
  EXPECT_NE(err.find("roomfix listen: site on SITE: demo_room, hash "), std::string::npos) << err;
  EXPECT_NE(err.find("published by trilat_proc@"), std::string::npos) << err;
  EXPECT_NE(err.find("differ at 1 key: receivers[2].position_m[0]: 4.0 -> 4.05"), std::string::npos)
      << err;
}

// Issue #28 (the site was the loudest stream on the bus): of processes that
// share a site only the first by name repeats it every period; the others
// send it at start; a newcomer hears it within about a second of its first
// STATUS instead of a period.
TEST(SiteOnTheBus, OnlyOneProcessOfASiteRepeatsItAndANewcomerHearsItAtOnce) {
  TempDir dir;
  const std::string demo = DemoSitePath();
  ChildProcess logger({"lcm-logger", "-q", "-f", dir.File("run.lcm")});
  ASSERT_TRUE(logger.started());
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  ChildProcess fusion({BinDir() + "/fusion_proc", "--config", demo, "--log-level", "warn"});
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  ChildProcess trilat({BinDir() + "/trilat_proc", "--config", demo, "--log-level", "warn"});
  std::this_thread::sleep_for(std::chrono::milliseconds(6000));
  ChildProcess newcomer({BinDir() + "/trilat_proc", "--config", demo, "--log-level", "warn"});
  std::this_thread::sleep_for(std::chrono::milliseconds(6000));
  for (ChildProcess* p : {&fusion, &trilat, &newcomer}) p->Signal(SIGINT);
  for (ChildProcess* p : {&fusion, &trilat, &newcomer}) EXPECT_EQ(p->Wait(10), 0);
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  logger.Signal(SIGINT);
  logger.Wait(5);

  std::string error;
  auto reader = LogReader::Open(dir.File("run.lcm"), &error);
  ASSERT_NE(reader, nullptr) << error;
  std::map<int32_t, std::vector<int64_t>> site_utimes;  // by pid
  std::map<int32_t, int64_t> first_status_utime;
  std::map<int32_t, std::string> name;
  LogEvent e;
  while (reader->Next(&e)) {
    const int n = static_cast<int>(e.data.size());
    if (e.channel == kSiteChannel) {
      site_t m;
      if (DecodeChecked(e.data.data(), n, &m, nullptr)) {
        site_utimes[m.pid].push_back(e.utime);
        name[m.pid] = m.process;
      }
    } else if (e.channel == "STATUS") {
      process_status_t m;
      if (DecodeChecked(e.data.data(), n, &m, nullptr)) first_status_utime.emplace(m.pid, e.utime);
    }
  }
  ASSERT_EQ(site_utimes.size(), 3u);
  const int32_t fusion_pid = fusion.pid();
  const int32_t trilat_pid = trilat.pid();
  const int32_t newcomer_pid = newcomer.pid();
  // The two trilat_procs: once each, at start.
  EXPECT_EQ(site_utimes[trilat_pid].size(), 1u);
  EXPECT_EQ(site_utimes[newcomer_pid].size(), 1u);
  // fusion_proc (first by name): never more than a period between its SITEs.
  const std::vector<int64_t>& elected = site_utimes[fusion_pid];
  ASSERT_GE(elected.size(), 3u);
  for (size_t i = 1; i < elected.size(); ++i) {
    EXPECT_LE(elected[i] - elected[i - 1], kSitePeriodUs + kPeriodToleranceUs) << i;
  }
  // ... and it answered the newcomer's first STATUS at its next heartbeat
  // (once a second) at least the answer gap after its previous SITE: within
  // the gap plus a heartbeat (and scheduling) of the newcomer's arrival.
  constexpr int64_t kHeartbeatUs = 1000000;
  const int64_t arrived = first_status_utime.at(newcomer_pid);
  bool answered = false;
  for (int64_t t : elected) {
    answered |= t >= arrived && t - arrived <= SitePublishSchedule::kSiteAnswerGapUs +
                                                   kHeartbeatUs + kPeriodToleranceUs;
  }
  EXPECT_TRUE(answered) << "newcomer's first STATUS at " << arrived;
}

}  // namespace
}  // namespace roomfix
