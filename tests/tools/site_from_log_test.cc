// Issue #20: the tools take the site from the log when --config is not
// given and say which they used; with --config a difference from the log's
// site is a warning naming the keys; a log with neither is an error where
// the tool needs a site. tests/data/site_sample.lcm is a real recording
// (scripts/record_test_logs.sh) of trilat_proc and roomfix_sim, both
// publishing SITE.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <string>

#include "msgio/site_message.h"
#include "tests/testing/demo_site.h"
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

}  // namespace
}  // namespace roomfix
