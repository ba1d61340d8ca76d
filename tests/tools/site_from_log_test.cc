// Issue #20: the tools take the site from the log when --config is not
// given and say which they used; with --config a difference from the log's
// site is a warning naming the keys; a log with neither is an error where
// the tool needs a site. tests/data/site_sample.lcm is a real recording
// (scripts/record_test_logs.sh) of trilat_proc and roomfix_sim, both
// publishing SITE.
#include <gtest/gtest.h>
#include <sys/resource.h>

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "msgio/site_message.h"
#include "tests/testing/demo_site.h"
#include "tests/testing/forged_site.h"
#include "tests/testing/test_paths.h"

namespace roomfix {
namespace {

using testing::BinDir;
using testing::ChildProcess;
using testing::ReadFile;
using testing::SourceDir;
using testing::TempDir;

struct ToolRun {
  int exit_code = -1;
  std::string out;
  std::string err;
};

ToolRun RunTool(const TempDir& dir, const std::string& program, const std::string& args) {
  ToolRun run;
  ChildProcess p(
      {"sh", "-c",
       "exec '" + BinDir() + "/" + program + "' " + args + " 2>'" + dir.File("err.txt") + "'"},
      dir.File("out.txt"));
  run.exit_code = p.Wait(120);
  run.out = ReadFile(dir.File("out.txt"));
  run.err = ReadFile(dir.File("err.txt"));
  return run;
}

std::string SampleLog() { return SourceDir() + "/tests/data/site_sample.lcm"; }
std::string OldLog() { return SourceDir() + "/tests/data/trilat_replay.lcm"; }
std::string DemoSite() { return testing::DemoSitePath(); }

// The line every tool prints: which site, its hash, version and publisher.
std::string SampleSiteLine() {
  SiteFromLog from_log;
  std::string error;
  EXPECT_TRUE(ReadSiteFromLog(SampleLog(), &from_log, &error)) << error;
  return "site from " + SampleLog() + ": demo_room, hash " +
         ShortSiteHash(from_log.site.content_hash) + ", roomfix ";
}

// A copy of the demo site with receiver 2's range offset changed, beside a
// copy of its calibration so that it loads.
std::string ShiftedSite(const TempDir& dir) {
  std::string error;
  const std::string path = testing::WriteDemoSiteVariant(
      dir, "shifted", "position_m: [4.0, 0.0, 2.5], range_offset_m: 0.0}",
      "position_m: [4.0, 0.0, 2.5], range_offset_m: 0.04}", &error);
  EXPECT_NE(path, "") << error;
  return path;
}

TEST(ToolSiteFromLog, TheLogRecordedBothPublishersWithTheSameSite) {
  SiteFromLog from_log;
  std::string error;
  ASSERT_TRUE(ReadSiteFromLog(SampleLog(), &from_log, &error)) << error;
  EXPECT_EQ(from_log.accepted, 2);  // trilat_proc and roomfix_sim, once each in 2.5 s
  EXPECT_EQ(from_log.refused, 0);
  EXPECT_EQ(from_log.disagreement, "");
  EXPECT_EQ(from_log.site.site.name, "demo_room");
  EXPECT_EQ(from_log.site.site.receivers.size(), 4u);
}

TEST(ToolSiteFromLog, AnalyzeUsesTheLogsSiteAndSaysWhich) {
  TempDir dir;
  const ToolRun run = RunTool(
      dir, "roomfix",
      "analyze '" + SampleLog() + "' --json --no-figures --out '" + dir.File("report") + "'");
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_NE(run.err.find("roomfix analyze: " + SampleSiteLine()), std::string::npos) << run.err;
  const auto out = nlohmann::json::parse(run.out);
  EXPECT_EQ(out["logs"][0]["site"]["name"], "demo_room");
  EXPECT_EQ(out["logs"][0]["site"]["source"], "log");
  EXPECT_EQ(out["logs"][0]["site"]["content_hash"].get<std::string>().size(), 64u);
  EXPECT_NE(ReadFile(dir.File("report/report.md")).find(SampleSiteLine()), std::string::npos);
}

TEST(ToolSiteFromLog, CompareSurveyListenAndTheViewerUseTheLogsSite) {
  TempDir dir;
  ToolRun run = RunTool(dir, "roomfix", "compare '" + SampleLog() + "'");
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_NE(run.err.find("roomfix compare: " + SampleSiteLine()), std::string::npos) << run.err;

  // survey needs the site (its starting values): from the log, no --site.
  run = RunTool(dir, "roomfix",
                "survey '" + SampleLog() + "' --reference ground_truth --offsets-only");
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_NE(run.err.find("roomfix survey: " + SampleSiteLine()), std::string::npos) << run.err;
  EXPECT_NE(run.out.find("25 firings"), std::string::npos) << run.out;

  run = RunTool(dir, "roomfix",
                "listen --lcm-url 'file://" + SampleLog() + "?speed=0' --channel SITE");
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_NE(run.err.find("roomfix listen: " + SampleSiteLine()), std::string::npos) << run.err;
  EXPECT_NE(run.out.find("\"type\":\"roomfix.site_t\""), std::string::npos);

  run = RunTool(dir, "roomfix_viewer",
                "--log '" + SampleLog() + "' --headless --png '" + dir.File("v.png") + "'");
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_NE(run.err.find("roomfix_viewer: " + SampleSiteLine()), std::string::npos) << run.err;
}

// The viewer's help says when --config may be left out; the other
// processes keep the shared "Site file (YAML)".
TEST(ToolSiteFromLog, TheViewersHelpSaysALogBringsItsSite) {
  TempDir dir;
  const ToolRun viewer = RunTool(dir, "roomfix_viewer", "--help");
  EXPECT_EQ(viewer.exit_code, 0);
  EXPECT_NE(viewer.out.find("with --log the log's own site (SITE) is used when"), std::string::npos)
      << viewer.out;
  const ToolRun trilat = RunTool(dir, "trilat_proc", "--help");
  EXPECT_EQ(trilat.out.find("with --log the log's own site"), std::string::npos) << trilat.out;
  EXPECT_NE(trilat.out.find("Site file (YAML)"), std::string::npos) << trilat.out;
}

TEST(ToolSiteFromLog, AConfigThatDiffersIsAWarningNamingTheKey) {
  TempDir dir;
  const std::string shifted = ShiftedSite(dir);
  const std::string expected =
      "warning: the site in " + SampleLog() + " (";  // then hashes, then the key
  const std::string key = "receivers[1].range_offset_m: 0.0 -> 0.04";
  ToolRun run = RunTool(dir, "roomfix_viewer",
                        "--log '" + SampleLog() + "' --config '" + shifted +
                            "' --headless --png '" + dir.File("v.png") + "'");
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_NE(run.err.find("roomfix_viewer: site from --config " + shifted), std::string::npos)
      << run.err;
  EXPECT_NE(run.err.find(expected), std::string::npos) << run.err;
  EXPECT_NE(run.err.find("differ at 1 key: " + key), std::string::npos) << run.err;

  run = RunTool(dir, "roomfix",
                "analyze '" + SampleLog() + "' --config '" + shifted +
                    "' --json --no-figures --out '" + dir.File("report") + "'");
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_NE(run.err.find(key), std::string::npos) << run.err;
  const auto out = nlohmann::json::parse(run.out);
  EXPECT_EQ(out["logs"][0]["site"]["source"], "--config");
  EXPECT_NE(out["logs"][0]["site_warnings"][0].get<std::string>().find(key), std::string::npos);

  // The same file as the log's: no warning.
  run = RunTool(dir, "roomfix", "compare '" + SampleLog() + "' --config '" + DemoSite() + "'");
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_EQ(run.err.find("warning"), std::string::npos) << run.err;
}

TEST(ToolSiteFromLog, ALogWithoutSiteNeedsConfigWhereTheToolNeedsASite) {
  TempDir dir;
  const std::string why = OldLog() + " holds no SITE message";
  ToolRun run = RunTool(dir, "roomfix_viewer",
                        "--log '" + OldLog() + "' --headless --png '" + dir.File("v.png") + "'");
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_NE(run.err.find(why), std::string::npos) << run.err;
  EXPECT_NE(run.err.find("give the site file with --config"), std::string::npos) << run.err;

  run = RunTool(dir, "roomfix", "survey '" + OldLog() + "' --reference ground_truth");
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_NE(run.err.find("roomfix survey: " + why), std::string::npos) << run.err;

  // analyze computes nothing from the site: it says it is unknown and goes on.
  run = RunTool(dir, "roomfix",
                "analyze '" + OldLog() + "' --no-figures --out '" + dir.File("report") + "'");
  EXPECT_EQ(run.exit_code, 0) << run.err;
  EXPECT_NE(run.err.find("roomfix analyze: note: site unknown: " + why), std::string::npos)
      << run.err;

  // With --config the old log is viewed as before.
  run = RunTool(dir, "roomfix_viewer",
                "--log '" + OldLog() + "' --config '" + DemoSite() + "' --headless --png '" +
                    dir.File("v.png") + "'");
  EXPECT_EQ(run.exit_code, 0) << run.err;
}

// Issue #28, item 1: a log whose SITE is the demo site with a 259 KB
// calibration of a flat map (about 13 600 keys, valid hash) held analyze,
// compare, replay --site and viewer --config --log 5-9 s each: every tool
// compares the log's site with --config through CompareSiteTexts, whose
// work is counted and at most 2 node pairs per byte of the texts compared.
// The calibration text of the 259 KB message (the demo site's text
// is the rest), under the 256 KiB a site_t carries per file.
constexpr size_t kForgedCalibrationBytes = 250 * 1024;
constexpr int64_t kVisitsPerByte = 2;
// Per text compared (the site text, the one calibration): CompareSiteTexts'
// allowance for texts of a few bytes.
constexpr int64_t kVisitsPerText = 64;

TEST(ToolSiteFromLog, AForgedSiteOfTensOfThousandsOfKeysCostsWorkLinearInItsSize) {
  TempDir dir;
  const size_t keys = testing::FlatKeysForBytes(kForgedCalibrationBytes);
  const site_t forged = testing::ForgedSiteWithFlatCalibration(keys, 1, "forger");
  const std::string log = dir.File("forged.lcm");
  std::string error;
  ASSERT_TRUE(testing::CopyLogWithSite(SampleLog(), log, forged, &error)) << error;
  LoadedSite config;
  ASSERT_TRUE(LoadSiteWithTexts(DemoSite(), &config, &error)) << error;
  const int64_t bytes =
      static_cast<int64_t>(config.texts.site_text.size() + forged.site_text.size() +
                           config.texts.files.begin()->second.size() + forged.files[0].text.size());

  // In this process, as every tool resolves its site: the work counted.
  const int64_t before = SiteComparisonNodesVisited();
  const ToolSite used = ResolveToolSite(DemoSite(), log);
  ASSERT_TRUE(used.known) << used.error;
  const std::vector<std::string>& warnings = used.warnings;
  const int64_t work = SiteComparisonNodesVisited() - before;
  EXPECT_GT(work, static_cast<int64_t>(keys));
  EXPECT_LE(work, kVisitsPerByte * bytes + 2 * kVisitsPerText);
  // The demo calibration's top-level keys (fit_rms_px, pixel_sigma_px,
  // model, intrinsics, pose: the lines that start with a letter) are absent
  // from the forged one, and every forged key from the real one.
  size_t real_keys = 0;
  const std::string& real = config.texts.files.begin()->second;
  for (size_t at = 0; at < real.size(); at = real.find('\n', at) + 1) {
    real_keys += std::islower(static_cast<unsigned char>(real[at])) ? 1 : 0;
    if (real.find('\n', at) == std::string::npos) break;
  }
  ASSERT_EQ(real_keys, 5u);
  const std::string differ = "differ at " + std::to_string(keys + real_keys) + " keys: ";
  // The copied log keeps its recorded SITEs beside the forged one, so the
  // tool also says the processes disagree; the comparison is one warning.
  const auto compared = std::find_if(warnings.begin(), warnings.end(), [&](const std::string& w) {
    return w.find(" differ at ") != std::string::npos;
  });
  ASSERT_NE(compared, warnings.end());
  EXPECT_EQ(std::count_if(
                warnings.begin(), warnings.end(),
                [](const std::string& w) { return w.find(" differ at ") != std::string::npos; }),
            1);
  EXPECT_NE(compared->find(differ), std::string::npos) << compared->substr(0, 300);

  // Every tool says so and goes on.
  ToolRun run = RunTool(dir, "roomfix",
                        "analyze '" + log + "' --config '" + DemoSite() +
                            "' --json --no-figures --out '" + dir.File("report") + "'");
  EXPECT_EQ(run.exit_code, 0) << run.err.substr(0, 2000);
  EXPECT_NE(run.err.find(differ), std::string::npos) << run.err.substr(0, 2000);
  run = RunTool(dir, "roomfix", "compare '" + log + "' --config '" + DemoSite() + "'");
  EXPECT_EQ(run.exit_code, 0) << run.err.substr(0, 2000);
  EXPECT_NE(run.err.find(differ), std::string::npos) << run.err.substr(0, 2000);
  run =
      RunTool(dir, "roomfix",
              "replay '" + log + "' --site '" + DemoSite() + "' --out '" + dir.File("r.lcm") + "'");
  EXPECT_EQ(run.exit_code, 0) << run.err.substr(0, 2000);
  EXPECT_NE((run.out + run.err).find(differ), std::string::npos)
      << run.out.substr(0, 2000) << run.err.substr(0, 2000);
  run = RunTool(dir, "roomfix_viewer",
                "--log '" + log + "' --config '" + DemoSite() + "' --headless --png '" +
                    dir.File("v.png") + "'");
  EXPECT_EQ(run.exit_code, 0) << run.err.substr(0, 2000);
  EXPECT_NE(run.err.find(differ), std::string::npos) << run.err.substr(0, 2000);
}

// Issue #28, item 2: with no --config, a log whose SITE named 1 000
// receivers made survey run 76 s and take 614 MB (10 000: 24 GB, killed).
// A site over the cap is refused as a file would be, and receivers the
// beacon never heard are not unknowns of the fit.
TEST(ToolSiteFromLog, SurveyCostsTheReceiversHeardNotTheReceiversTheLogsSiteNames) {
  TempDir dir;
  std::string error;
  const std::string wide = dir.File("wide.lcm");
  ASSERT_TRUE(testing::CopyLogWithSite(
      SampleLog(), wide,
      testing::ForgedSiteWithText(testing::DemoSiteTextWithReceivers(200), "trilat_proc"), &error))
      << error;
  ToolRun run = RunTool(dir, "roomfix",
                        "survey '" + wide + "' --reference ground_truth --offsets-only --json '" +
                            dir.File("s.json") + "'");
  ASSERT_EQ(run.exit_code, 0) << run.err << run.out;
  const auto out = nlohmann::json::parse(ReadFile(dir.File("s.json")));
  EXPECT_EQ(out["receivers"].size(), 4u);
  EXPECT_EQ(out["receivers_not_heard"].size(), 200u);
  EXPECT_NE(run.out.find("note: 200 receivers of the site never heard from beacon 1"),
            std::string::npos)
      << run.out;

  const std::string over = dir.File("over.lcm");
  ASSERT_TRUE(testing::CopyLogWithSite(
      SampleLog(), over,
      testing::ForgedSiteWithText(testing::DemoSiteTextWithReceivers(1000), "trilat_proc"), &error))
      << error;
  run = RunTool(dir, "roomfix", "survey '" + over + "' --reference ground_truth --offsets-only");
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_NE(run.err.find("receivers: lists 1004 entries, over the cap of 256"), std::string::npos)
      << run.err;
}

// Issue #28, item 8: a log of 3 000 distinct SITEs was said to hold 16,
// the length of the list of hashes named, not the count.
constexpr int kDistinctSites = 40;

TEST(ToolSiteFromLog, ALogOfManySitesIsSaidToHoldEveryOne) {
  TempDir dir;
  std::vector<site_t> sites;
  for (int k = 0; k < kDistinctSites; ++k) {
    sites.push_back(testing::ForgedSiteWithFlatCalibration(8, k + 1, "p" + std::to_string(k)));
  }
  const std::string log = dir.File("many.lcm");
  std::string error;
  ASSERT_TRUE(testing::CopyLogWithSites(SampleLog(), log, sites, &error)) << error;
  SiteFromLog from_log;
  ASSERT_TRUE(ReadSiteFromLog(log, &from_log, &error)) << error;
  EXPECT_EQ(from_log.distinct_sites, kDistinctSites);
  EXPECT_EQ(from_log.publishers_by_hash.size(), SiteFromLog::kMaxSiteHashes);
  const ToolSite used = ResolveToolSite("", log);
  EXPECT_FALSE(used.known);
  EXPECT_NE(used.error.find("holds SITE messages of 40 different sites (the first 16 named): "),
            std::string::npos)
      << used.error;
}

// Issue #28, item 8: 30 distinct SITEs of 5 MB cost `compare` 109 MB over
// its footprint (the budget is 50 MB): every verified message was kept to
// recognise its repeats. 24 distinct SITEs of 4 MB against one: the peak
// resident size of compare (getrusage of the waited child) may grow by no
// more than the budget.
constexpr int kLargeSites = 24;
constexpr double kMemoryBudgetMiB = 50.0;

double PeakChildMiB() {
  struct rusage usage {};
  ::getrusage(RUSAGE_CHILDREN, &usage);
  return static_cast<double>(usage.ru_maxrss) / 1024.0;  // kilobytes on Linux
}

TEST(ToolSiteFromLog, ManyLargeSitesCostCompareNoMoreMemoryThanOne) {
  TempDir dir;
  std::vector<site_t> sites;
  for (int k = 0; k < kLargeSites; ++k) {
    sites.push_back(testing::ForgedSiteWithLargeFiles(k, "p" + std::to_string(k)));
  }
  std::string error;
  const std::string one = dir.File("one.lcm");
  const std::string many = dir.File("many.lcm");
  ASSERT_TRUE(testing::CopyLogWithSites(SampleLog(), one, {sites.front()}, &error)) << error;
  ASSERT_TRUE(testing::CopyLogWithSites(SampleLog(), many, sites, &error)) << error;
  sites.clear();
  ToolRun run = RunTool(dir, "roomfix", "compare '" + one + "' --config '" + DemoSite() + "'");
  ASSERT_EQ(run.exit_code, 0) << run.err.substr(0, 2000);
  const double baseline_mib = PeakChildMiB();
  run = RunTool(dir, "roomfix", "compare '" + many + "' --config '" + DemoSite() + "'");
  ASSERT_EQ(run.exit_code, 0) << run.err.substr(0, 2000);
  const double peak_mib = PeakChildMiB();
  std::printf("compare: peak %.1f MiB with one 4 MB site, %.1f MiB with %d\n", baseline_mib,
              peak_mib, kLargeSites);
#ifdef __SANITIZE_ADDRESS__
  // AddressSanitizer keeps freed memory in its quarantine (256 MiB by
  // default) and adds shadow memory, so the peak resident size is not the
  // program's (84 MiB over here, issue #28); the ordinary build judges it.
  std::printf("memory growth not judged under AddressSanitizer\n");
#else
  EXPECT_LE(peak_mib - baseline_mib, kMemoryBudgetMiB);
#endif
}

}  // namespace
}  // namespace roomfix
