#include "msgio/site_message.h"

#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <functional>
#include <string>
#include <vector>

#include "core/world/file_io.h"
#include "msgio/log.h"
#include "msgio/process.h"
#include "msgio/wire_check.h"
#include "tests/testing/demo_site.h"
#include "tests/testing/forged_site.h"
#include "tests/testing/test_paths.h"
#include "tests/testing/wire_test_messages.h"

namespace roomfix {
namespace {

using testing::DemoSitePath;
using testing::Encode;
using testing::TempDir;

LoadedSite LoadDemo() {
  LoadedSite loaded;
  std::string error;
  EXPECT_TRUE(LoadSiteWithTexts(DemoSitePath(), &loaded, &error)) << error;
  return loaded;
}

site_t DemoMessage(const LoadedSite& loaded) {
  site_t msg;
  std::string error;
  EXPECT_TRUE(MakeSiteMessage(loaded, "trilat_proc", 1700000000000000, &msg, &error)) << error;
  return msg;
}

// The bytes a receiver gets, decoded the only way roomfix decodes them.
site_t ThroughTheWire(const site_t& msg) {
  const std::vector<uint8_t> bytes = Encode(msg);
  site_t out;
  std::string reason;
  EXPECT_TRUE(DecodeChecked(bytes.data(), static_cast<int>(bytes.size()), &out, &reason)) << reason;
  return out;
}

std::string Replace(std::string text, const std::string& from, const std::string& to) {
  const size_t at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  if (at != std::string::npos) text.replace(at, from.size(), to);
  return text;
}

TEST(SiteMessage, ASiteFileTravelsAndComesBackAsTheSameSite) {
  const LoadedSite original = LoadDemo();
  // The demo names one calibration, read beside the site file.
  ASSERT_EQ(original.texts.files.size(), 1u);
  EXPECT_EQ(original.texts.files.begin()->first, "../calibration/demo_room_camera.yaml");
  EXPECT_TRUE(original.texts.missing.empty());
  EXPECT_EQ(original.content_hash.size(), 64u);

  const site_t msg = ThroughTheWire(DemoMessage(original));
  EXPECT_EQ(msg.content_hash, original.content_hash);
  EXPECT_EQ(msg.roomfix_version, RoomfixVersion());
  EXPECT_EQ(msg.process, "trilat_proc");

  LoadedSite back;
  std::string error;
  ASSERT_TRUE(LoadSiteFromMessage(msg, "test SITE", &back, &error)) << error;
  EXPECT_EQ(back.content_hash, original.content_hash);
  EXPECT_TRUE(SiteDifferences(original.texts, back.texts).empty());
  EXPECT_EQ(back.site.name, "demo_room");
  ASSERT_EQ(back.site.receivers.size(), original.site.receivers.size());
  for (size_t i = 0; i < back.site.receivers.size(); ++i) {
    EXPECT_EQ(back.site.receivers[i].id, original.site.receivers[i].id);
    EXPECT_EQ(back.site.receivers[i].address, original.site.receivers[i].address);
    EXPECT_EQ(back.site.receivers[i].position_m, original.site.receivers[i].position_m);
    EXPECT_EQ(back.site.receivers[i].range_offset_m, original.site.receivers[i].range_offset_m);
  }
  ASSERT_EQ(back.site.cameras.size(), 1u);
  EXPECT_EQ(back.site.simulation.robots.size(), original.site.simulation.robots.size());
  // The calibration resolves to the carried text, not to a path on disk.
  EXPECT_EQ(back.site.cameras[0].calibration_file, "../calibration/demo_room_camera.yaml");
  const std::string* text = SiteCalibrationText(back, 0);
  ASSERT_NE(text, nullptr);
  std::string on_disk;
  ASSERT_TRUE(ReadConfigFile(testing::SourceDir() + "/config/calibration/demo_room_camera.yaml",
                             &on_disk, &error));
  EXPECT_EQ(*text, on_disk);
  // And from the original too, whose path was resolved against its folder.
  ASSERT_NE(SiteCalibrationText(original, 0), nullptr);
  EXPECT_EQ(*SiteCalibrationText(original, 0), on_disk);
}

TEST(SiteMessage, TheCarriedCalibrationIsUsedEvenWhereNoFileIsOnDisk) {
  // The site in a temporary folder with no calibration beside it: loaded
  // from the message, the calibration is still there.
  LoadedSite original = LoadDemo();
  original.texts.files.begin()->second = "model: full\n# edited\n";
  original.content_hash = SiteContentHash(original.texts);
  LoadedSite back;
  std::string error;
  ASSERT_TRUE(LoadSiteFromMessage(ThroughTheWire(DemoMessage(original)), "m", &back, &error));
  EXPECT_EQ(*SiteCalibrationText(back, 0), "model: full\n# edited\n");
}

TEST(SiteMessage, TheHashChangesWithAnyTextAndNotWithFileOrder) {
  SiteTexts a;
  a.site_text = "name: x\n";
  a.files["a.yaml"] = "1";
  a.files["b.yaml"] = "2";
  SiteTexts b = a;
  EXPECT_EQ(SiteContentHash(a), SiteContentHash(b));
  b.files["a.yaml"] = "12";
  b.files["b.yaml"] = "";
  // The same bytes moved between files: length prefixes tell them apart.
  EXPECT_NE(SiteContentHash(a), SiteContentHash(b));
  SiteTexts c = a;
  c.site_text = "name: y\n";
  EXPECT_NE(SiteContentHash(a), SiteContentHash(c));
  // SHA-256 of the framed texts, in hex: a known value pins the framing, so
  // that a change to it (which would make every recorded hash disagree) is
  // deliberate.
  SiteTexts empty;
  EXPECT_EQ(SiteContentHash(empty).size(), 64u);
  EXPECT_EQ(SiteHashCounterText(SiteHashCounterValue(SiteContentHash(a))),
            SiteContentHash(a).substr(0, 15));
  EXPECT_EQ(SiteHashCounterValue("zz"), -1);
}

TEST(SiteMessage, AMismatchNamesTheDifferingKeysByPath) {
  const LoadedSite original = LoadDemo();
  LoadedSite moved = original;
  moved.texts.site_text =
      Replace(Replace(original.texts.site_text, "position_m: [4.0, 3.0, 2.5], range_offset_m: 0.0",
                      "position_m: [4.05, 3.0, 2.5], range_offset_m: 0.03"),
              "height_m: 3.3 ", "height_m: 3.30 ");  // the same number written otherwise
  moved.content_hash = SiteContentHash(moved.texts);
  const std::vector<std::string> keys = SiteDifferences(original.texts, moved.texts);
  EXPECT_EQ(keys, (std::vector<std::string>{"receivers[2].position_m[0]: 4.0 -> 4.05",
                                            "receivers[2].range_offset_m: 0.0 -> 0.03"}));
  const std::string warning = SiteMismatchWarning(original, "the log's site", moved, "--config");
  EXPECT_NE(warning.find("differ at 2 keys: receivers[2].position_m[0]: 4.0 -> 4.05; "
                         "receivers[2].range_offset_m: 0.0 -> 0.03"),
            std::string::npos)
      << warning;
  EXPECT_EQ(SiteMismatchWarning(original, "a", original, "b"), "");

  // Calibration files differ by name and key too; added keys are named.
  moved = original;
  moved.texts.files.begin()->second =
      Replace(moved.texts.files.begin()->second, "fx_px: 916.47728685868469", "fx_px: 917.0");
  const std::vector<std::string> cal = SiteDifferences(original.texts, moved.texts);
  ASSERT_EQ(cal.size(), 1u);
  EXPECT_EQ(cal[0],
            "calibration '../calibration/demo_room_camera.yaml' intrinsics.fx_px: "
            "916.47728685868469 -> 917.0");
  // A key present on one side only is named as absent on the other.
  moved.texts.site_text = original.texts.site_text + "beacons_note: x\n";
  EXPECT_EQ(SiteDifferences(original.texts, moved.texts)[0], "beacons_note: absent -> x");
}

TEST(SiteMessage, ACommentOnlyChangeIsADifferentHashButNoKey) {
  const LoadedSite original = LoadDemo();
  LoadedSite commented = original;
  commented.texts.site_text += "# surveyed again 2026-11-20\n";
  commented.content_hash = SiteContentHash(commented.texts);
  EXPECT_NE(SiteMismatchWarning(original, "a", commented, "b").find("only in layout or comments"),
            std::string::npos);
}

// Issue #28, item 1: one forged SITE of 259 KB (a calibration of a flat map
// of tens of thousands of keys, with a valid hash) held `roomfix listen
// --config` about 20 s, because each key was looked up by yaml-cpp's
// operator[], which scans the mapping. The work is now counted: at most 2
// node pairs per byte of the texts compared (plus 64 per text), and doubling
// the keys doubles the work (a quadratic walk would quadruple it).
constexpr int64_t kVisitsPerByte = 2;
constexpr int64_t kVisitsPerText = 64;
// A walk linear in the keys visits twice the pairs for twice the keys, give
// or take the few keys of the real calibration on the other side; a
// quadratic one would visit four times as many.
constexpr double kLinearGrowthMax = 2.1;
// The calibration text of the issue's 259 KB message (the demo site's text
// is the rest), under the 256 KiB a site_t carries per file.
constexpr size_t kForgedCalibrationBytes = 250 * 1024;

SiteTexts TextsOf(const site_t& msg) {
  LoadedSite loaded;
  std::string error;
  EXPECT_TRUE(LoadSiteFromMessage(msg, "forged SITE", &loaded, &error)) << error;
  return loaded.texts;
}

int64_t Bytes(const SiteTexts& a, const SiteTexts& b) {
  int64_t n = static_cast<int64_t>(a.site_text.size() + b.site_text.size());
  for (const auto& [name, text] : a.files) n += static_cast<int64_t>(text.size());
  for (const auto& [name, text] : b.files) n += static_cast<int64_t>(text.size());
  return n;
}

TEST(SiteMessage, ComparingAFlatMapOfTensOfThousandsOfKeysIsLinearInItsSize) {
  const LoadedSite config = LoadDemo();
  const size_t keys = testing::FlatKeysForBytes(kForgedCalibrationBytes);
  ASSERT_GT(keys, 10000u);
  const site_t forged_msg = testing::ForgedSiteWithFlatCalibration(keys, 1, "forger");
  EXPECT_GE(Encode(forged_msg).size(), 259000u);
  const SiteTexts forged = TextsOf(forged_msg);
  const SiteDiff diff = CompareSiteTexts(config.texts, forged);
  // Every forged key is absent from the real calibration, and every real
  // top-level key (intrinsics, pose, ...) from the forged one.
  const size_t real_keys = YAML::Load(config.texts.files.begin()->second).size();
  EXPECT_EQ(diff.count, keys + real_keys);
  EXPECT_FALSE(diff.incomplete);
  EXPECT_EQ(diff.lines.size(), 64u);  // the default: the first 64 are spelt out
  EXPECT_LE(diff.nodes_visited, kVisitsPerByte * Bytes(config.texts, forged) + 2 * kVisitsPerText);
  // Half the keys, half the work.
  const SiteTexts half = TextsOf(testing::ForgedSiteWithFlatCalibration(keys / 2, 1, "forger"));
  const SiteDiff diff_half = CompareSiteTexts(config.texts, half);
  EXPECT_EQ(diff_half.count, keys / 2 + real_keys);
  EXPECT_LE(static_cast<double>(diff.nodes_visited),
            kLinearGrowthMax * static_cast<double>(diff_half.nodes_visited));
  // The warning names the count and the first keys, not all of them.
  LoadedSite forged_site;
  std::string error;
  ASSERT_TRUE(LoadSiteFromMessage(forged_msg, "SITE from forger", &forged_site, &error));
  const std::string warning = SiteMismatchWarning(config, "--config", forged_site, "SITE");
  EXPECT_NE(warning.find("differ at " + std::to_string(keys + real_keys) + " keys: "),
            std::string::npos)
      << warning.substr(0, 300);
  EXPECT_LT(warning.size(), 2000u);
}

TEST(SiteMessage, AliasesThatExpandATextBeyondItsSizeStopTheComparison) {
  // 9 levels of 10 aliases: 300 bytes of text, 10^9 leaves as a tree, every
  // one differing between the two sites.
  const SiteTexts x = TextsOf(testing::ForgedSiteWithAliasBomb(9, 10, "x", "forger"));
  const SiteTexts y = TextsOf(testing::ForgedSiteWithAliasBomb(9, 10, "y", "forger"));
  const SiteDiff diff = CompareSiteTexts(x, y);
  EXPECT_TRUE(diff.incomplete);
  EXPECT_GE(diff.count, 1u);
  EXPECT_LE(diff.nodes_visited, kVisitsPerByte * Bytes(x, y) + 2 * kVisitsPerText);
  LoadedSite site_x, site_y;
  std::string error;
  ASSERT_TRUE(LoadSiteFromMessage(testing::ForgedSiteWithAliasBomb(9, 10, "x", "forger"), "SITE",
                                  &site_x, &error));
  ASSERT_TRUE(LoadSiteFromMessage(testing::ForgedSiteWithAliasBomb(9, 10, "y", "forger"), "SITE",
                                  &site_y, &error));
  const std::string warning = SiteMismatchWarning(site_x, "--config", site_y, "SITE");
  EXPECT_NE(warning.find(" or more keys: "), std::string::npos) << warning;
  EXPECT_NE(warning.find("and stopped"), std::string::npos) << warning;

  // An alias inside its own anchor: yaml-cpp makes it a cycle (or refuses
  // it); either way the comparison ends, within the same budget.
  SiteTexts cycle_x = x, cycle_y = x;
  cycle_x.files.begin()->second = "a: &a [x, *a]\n";
  cycle_y.files.begin()->second = "a: &a [y, *a]\n";
  const SiteDiff cyclic = CompareSiteTexts(cycle_x, cycle_y);
  EXPECT_GE(cyclic.count, 1u);
  EXPECT_LE(cyclic.nodes_visited, kVisitsPerByte * Bytes(cycle_x, cycle_y) + 2 * kVisitsPerText);
}

TEST(SiteMessage, HostileSiteMessagesAreRefusedWithAReason) {
  const LoadedSite original = LoadDemo();
  LoadedSite out;
  std::string error;

  site_t wrong_hash = DemoMessage(original);
  wrong_hash.content_hash[0] = wrong_hash.content_hash[0] == '0' ? '1' : '0';
  EXPECT_FALSE(LoadSiteFromMessage(wrong_hash, "m", &out, &error));
  EXPECT_NE(error.find("content_hash"), std::string::npos) << error;

  // Text edited after hashing: the hash no longer matches.
  site_t edited = DemoMessage(original);
  edited.site_text += "\n";
  EXPECT_FALSE(LoadSiteFromMessage(edited, "m", &out, &error));
  EXPECT_NE(error.find("does not match"), std::string::npos) << error;

  // Not YAML, with a matching hash: the site file's own error.
  LoadedSite broken = original;
  broken.texts.site_text = "name: [unclosed\n";
  broken.content_hash = SiteContentHash(broken.texts);
  site_t invalid = DemoMessage(broken);
  EXPECT_FALSE(LoadSiteFromMessage(invalid, "log.lcm: SITE", &out, &error));
  EXPECT_EQ(error.rfind("log.lcm: SITE:", 0), 0u) << error;

  // A duplicated key, which yaml-cpp alone would accept (last wins).
  broken.texts.site_text = original.texts.site_text + "name: other_room\n";
  broken.content_hash = SiteContentHash(broken.texts);
  EXPECT_FALSE(LoadSiteFromMessage(DemoMessage(broken), "m", &out, &error));
  EXPECT_NE(error.find("duplicated key 'name'"), std::string::npos) << error;

  // Valid YAML, invalid site: two receivers only.
  broken.texts.site_text = Replace(original.texts.site_text,
                                   "  - {id: 4, address: \"0x0013A20041000004\", position_m: "
                                   "[0.0, 3.0, 2.5], range_offset_m: 0.0}\n",
                                   "");
  broken.texts.site_text = Replace(broken.texts.site_text,
                                   "  - {id: 3, address: \"0x0013A20041000003\", position_m: "
                                   "[4.0, 3.0, 2.5], range_offset_m: 0.0}\n",
                                   "");
  broken.content_hash = SiteContentHash(broken.texts);
  EXPECT_FALSE(LoadSiteFromMessage(DemoMessage(broken), "m", &out, &error));
  EXPECT_NE(error.find("receivers"), std::string::npos) << error;

  // The same file twice.
  site_t twice = DemoMessage(original);
  twice.files.push_back(twice.files[0]);
  twice.num_files = 2;
  EXPECT_FALSE(LoadSiteFromMessage(twice, "m", &out, &error));
  EXPECT_NE(error.find("carried twice"), std::string::npos) << error;

  // Over the configuration file cap, when not through the wire check.
  site_t huge = DemoMessage(original);
  huge.site_text.assign(kConfigFileCapBytes + 1, '#');
  EXPECT_FALSE(LoadSiteFromMessage(huge, "m", &out, &error));
  EXPECT_NE(error.find("cap for configuration files"), std::string::npos) << error;
}

TEST(SiteMessage, ASiteOverTheWireCapIsNotMadeIntoAMessage) {
  LoadedSite big = LoadDemo();
  big.texts.site_text.append(wire_cap::kSiteTextBytes, '#');
  site_t msg;
  std::string error;
  EXPECT_FALSE(MakeSiteMessage(big, "p", 0, &msg, &error));
  EXPECT_NE(error.find("over the 1048575 bytes a site_t carries"), std::string::npos) << error;
}

// Writes a log of the given SITE payloads (and a STATUS) for ReadSiteFromLog.
std::string WriteLog(const TempDir& dir, const std::vector<std::vector<uint8_t>>& sites,
                     const std::vector<process_status_t>& statuses = {}) {
  const std::string path = dir.File("site.lcm");
  std::string error;
  auto writer = LogWriter::Create(path, true, &error);
  EXPECT_NE(writer, nullptr) << error;
  int64_t t = 1700000000000000;
  for (const auto& bytes : sites) {
    EXPECT_TRUE(writer->Write(t += 1000, kSiteChannel, bytes.data(), static_cast<int>(bytes.size()),
                              &error))
        << error;
  }
  for (const auto& s : statuses) {
    const auto bytes = Encode(s);
    EXPECT_TRUE(writer->Write(t += 1000, kStatusChannel, bytes.data(),
                              static_cast<int>(bytes.size()), &error));
  }
  EXPECT_TRUE(writer->Flush(&error));
  return path;
}

TEST(SiteFromLog, TakesTheFirstGoodSiteAndCountsTheRefusedOnes) {
  const LoadedSite original = LoadDemo();
  site_t wrong_hash = DemoMessage(original);
  wrong_hash.content_hash = std::string(64, 'f');
  std::vector<uint8_t> oversized = Encode(DemoMessage(original));
  testing::PutInt32(&oversized, 8 + 8 + 4 + 10, wire_cap::kSiteTextBytes + 1);  // site_path len
  TempDir dir;
  const std::string path =
      WriteLog(dir, {Encode(wrong_hash), oversized, Encode(DemoMessage(original))});
  SiteFromLog from_log;
  std::string error;
  ASSERT_TRUE(ReadSiteFromLog(path, &from_log, &error)) << error;
  EXPECT_EQ(from_log.accepted, 1);
  EXPECT_EQ(from_log.refused, 2);
  EXPECT_EQ(from_log.refused_by_reason.at("hash_mismatch"), 1);
  EXPECT_EQ(from_log.refused_by_reason.count("hash_mismatch") +
                from_log.refused_by_reason.count("string_over_cap") +
                from_log.refused_by_reason.count("truncated"),
            2u);
  EXPECT_EQ(from_log.site.content_hash, original.content_hash);
  EXPECT_EQ(from_log.site.process, "trilat_proc");
  EXPECT_EQ(from_log.disagreement, "");
}

TEST(SiteFromLog, ALogWithoutASiteIsAClearError) {
  TempDir dir;
  const std::string path = WriteLog(dir, {}, {testing::MakeTestStatus()});
  SiteFromLog from_log;
  std::string error;
  EXPECT_FALSE(ReadSiteFromLog(path, &from_log, &error));
  EXPECT_NE(error.find("holds no SITE message"), std::string::npos) << error;
  EXPECT_NE(error.find("--config"), std::string::npos) << error;

  const ToolSite resolved = ResolveToolSite("", path);
  EXPECT_FALSE(resolved.known);
  EXPECT_NE(resolved.error.find("holds no SITE message"), std::string::npos) << resolved.error;
}

TEST(SiteFromLog, ProcessesStatingDifferentSitesAreNamed) {
  const LoadedSite original = LoadDemo();
  process_status_t other = testing::MakeTestStatus();
  other.process = "fusion_proc";
  other.host = "lab-pc2";
  other.counters.push_back(testing::MakeTestCounter(kSiteHashCounter, 0x123456789abcdefLL));
  other.num_counters = static_cast<int32_t>(other.counters.size());
  TempDir dir;
  const std::string path = WriteLog(dir, {Encode(DemoMessage(original))}, {other});
  SiteFromLog from_log;
  std::string error;
  ASSERT_TRUE(ReadSiteFromLog(path, &from_log, &error)) << error;
  EXPECT_NE(from_log.disagreement.find("processes disagree on the site"), std::string::npos);
  EXPECT_NE(from_log.disagreement.find("123456789abc by fusion_proc@lab-pc2"), std::string::npos)
      << from_log.disagreement;
  EXPECT_NE(from_log.disagreement.find(ShortSiteHash(original.content_hash) + " by trilat_proc@"),
            std::string::npos)
      << from_log.disagreement;
}

process_status_t StatusWithHash(const std::string& process, const std::string& host, int64_t hash) {
  process_status_t s = testing::MakeTestStatus();
  s.process = process;
  s.host = host;
  s.counters = {testing::MakeTestCounter(kSiteHashCounter, hash)};
  s.num_counters = 1;
  return s;
}

// fusion_proc started with a stale site, is restarted with the corrected
// one: its next STATUS ends the disagreement (each process counts with its
// latest hash), where before the old hash stayed listed forever.
TEST(SiteHashTracker, AProcessRestartedWithTheRightSiteEndsTheDisagreement) {
  constexpr int64_t kT0 = 1700000000000000;
  SiteHashTracker tracker;
  tracker.ObserveStatus(StatusWithHash("trilat_proc", "lab-pc", 0x0123456789abcdeLL), kT0);
  tracker.ObserveStatus(StatusWithHash("fusion_proc", "lab-pc2", 0x0fedcba98765432LL), kT0);
  EXPECT_EQ(tracker.Disagreement(),
            "processes disagree on the site: 0123456789ab by trilat_proc@lab-pc; "
            "0fedcba98765 by fusion_proc@lab-pc2");
  tracker.ObserveStatus(StatusWithHash("fusion_proc", "lab-pc2", 0x0123456789abcdeLL),
                        kT0 + 1'000'000);
  EXPECT_EQ(tracker.Disagreement(), "");
  EXPECT_EQ(tracker.distinct_hashes(), 1u);
}

// A process that stopped (its host gone with the old site) is forgotten
// once it has been silent for kSiteExpiryUs of message time, not before.
TEST(SiteHashTracker, AProcessSilentForThreeSitePeriodsIsForgotten) {
  constexpr int64_t kT0 = 1700000000000000;
  SiteHashTracker tracker;
  const process_status_t trilat = StatusWithHash("trilat_proc", "lab-pc", 0x0123456789abcdeLL);
  tracker.ObserveStatus(StatusWithHash("old_proc", "lab-pc2", 0x0fedcba98765432LL), kT0);
  tracker.ObserveStatus(trilat, kT0);
  tracker.ObserveStatus(trilat, kT0 + SiteHashTracker::kSiteExpiryUs);
  EXPECT_NE(tracker.Disagreement(), "") << "silent for exactly the expiry: still counted";
  tracker.ObserveStatus(trilat, kT0 + SiteHashTracker::kSiteExpiryUs + 1);
  EXPECT_EQ(tracker.Disagreement(), "");
}

// The demo site with a comment line of its own: a distinct valid site.
site_t VariantMessage(const LoadedSite& original, int n) {
  LoadedSite variant = original;
  variant.texts.site_text += "\n# variant " + std::to_string(n) + "\n";
  variant.content_hash = SiteContentHash(variant.texts);
  return DemoMessage(variant);
}

bool Contains(const std::vector<std::string>& lines, const std::string& part) {
  for (const std::string& line : lines) {
    if (line.find(part) != std::string::npos) return true;
  }
  return false;
}

// A forged SITE carrying the real hash with other texts came first: it is
// refused and counted, and the real site is still described when it comes
// (before, the hash was marked seen before the check and the real one was
// never shown).
TEST(SiteListing, AForgedSiteWithTheRealHashDoesNotHideTheRealOne) {
  const LoadedSite original = LoadDemo();
  site_t forged = DemoMessage(original);
  forged.site_text = Replace(forged.site_text, "demo_room", "forged_room");
  SiteListing listing(nullptr);
  std::vector<std::string> lines;
  listing.ObserveSite(forged, 1, &lines);
  EXPECT_EQ(listing.refused(), 1);
  EXPECT_EQ(listing.listed(), 0u);
  EXPECT_TRUE(Contains(lines, "warning: site refused")) << ::testing::PrintToString(lines);
  lines.clear();
  listing.ObserveSite(DemoMessage(original), 2, &lines);
  EXPECT_EQ(listing.listed(), 1u);
  EXPECT_TRUE(Contains(lines, "site on SITE: " + original.site.name))
      << ::testing::PrintToString(lines);
}

// Invented hashes (texts that do not match) are refused, so they no longer
// fill the list; 64 valid sites do, and the first one over is said once.
TEST(SiteListing, InventedHashesDoNotFillTheListAndTheCapIsSaidOnce) {
  const LoadedSite original = LoadDemo();
  SiteListing listing(nullptr);
  std::vector<std::string> lines;
  for (int i = 0; i < 64; ++i) {
    site_t invented = DemoMessage(original);
    invented.content_hash = std::string(63, '0') + "123456789abcdef"[i % 15];
    invented.content_hash[0] = static_cast<char>('a' + i % 6);
    listing.ObserveSite(invented, i, &lines);
  }
  EXPECT_EQ(listing.refused(), 64);
  EXPECT_EQ(listing.listed(), 0u);
  listing.ObserveSite(DemoMessage(original), 100, &lines);
  EXPECT_EQ(listing.listed(), 1u);
  for (int i = 1; i < static_cast<int>(SiteListing::kMaxListed); ++i) {
    listing.ObserveSite(VariantMessage(original, i), 100 + i, &lines);
  }
  ASSERT_EQ(listing.listed(), SiteListing::kMaxListed);
  lines.clear();
  listing.ObserveSite(VariantMessage(original, 1000), 300, &lines);
  listing.ObserveSite(VariantMessage(original, 1001), 301, &lines);
  EXPECT_EQ(listing.not_listed(), 2);
  int said = 0;
  for (const std::string& line : lines) said += line.find("64 sites listed") != std::string::npos;
  EXPECT_EQ(said, 1) << ::testing::PrintToString(lines);
}

// Two publishers with different valid sites in one log: without --config a
// tool must not pick one; the error lists both hashes with their publishers
// and asks for --config. With --config the disagreement stays a warning.
TEST(SiteFromLog, ALogOfTwoSitesNeedsConfigAndNamesBoth) {
  const LoadedSite original = LoadDemo();
  site_t other = VariantMessage(original, 1);
  other.process = "fusion_proc";
  other.host = "lab-pc2";
  TempDir dir;
  const std::string path = WriteLog(dir, {Encode(DemoMessage(original)), Encode(other)});
  const ToolSite without_config = ResolveToolSite("", path);
  EXPECT_FALSE(without_config.known);
  const std::string& error = without_config.error;
  EXPECT_NE(error.find("holds SITE messages of 2 different sites"), std::string::npos) << error;
  EXPECT_NE(error.find(ShortSiteHash(original.content_hash) + " by trilat_proc@"),
            std::string::npos)
      << error;
  EXPECT_NE(error.find(ShortSiteHash(other.content_hash) + " by fusion_proc@lab-pc2"),
            std::string::npos)
      << error;
  EXPECT_NE(error.find("--config"), std::string::npos) << error;

  const ToolSite with_config = ResolveToolSite(DemoSitePath(), path);
  ASSERT_TRUE(with_config.known) << with_config.error;
  EXPECT_TRUE(Contains(with_config.warnings, "processes disagree on the site"))
      << ::testing::PrintToString(with_config.warnings);
}

// A process repeats its site every 5 s: a repeat with the same texts is not
// parsed again, a message with the same hash but other texts still is (and
// is refused).
TEST(SiteFromLog, RepeatsOfAVerifiedSiteAreNotParsedAgain) {
  const LoadedSite original = LoadDemo();
  site_t forged = DemoMessage(original);
  forged.site_text = Replace(forged.site_text, "demo_room", "forged_room");
  TempDir dir;
  const std::string path =
      WriteLog(dir, {Encode(DemoMessage(original)), Encode(DemoMessage(original)), Encode(forged),
                     Encode(DemoMessage(original))});
  SiteFromLog from_log;
  std::string error;
  ASSERT_TRUE(ReadSiteFromLog(path, &from_log, &error)) << error;
  EXPECT_EQ(from_log.accepted, 3);
  EXPECT_EQ(from_log.repeats_not_reparsed, 2);
  EXPECT_EQ(from_log.refused_by_reason.at("hash_mismatch"), 1);
  EXPECT_EQ(from_log.publishers_by_hash.size(), 1u);
}

TEST(SiteFromLog, ConfigBesideALogWarnsWithTheDifferingKeys) {
  LoadedSite logged = LoadDemo();
  logged.texts.site_text = Replace(logged.texts.site_text, "range_offset_m: 0.0}\n  - {id: 2",
                                   "range_offset_m: 0.02}\n  - {id: 2");
  logged.content_hash = SiteContentHash(logged.texts);
  TempDir dir;
  const std::string path = WriteLog(dir, {Encode(DemoMessage(logged))});

  const ToolSite with_config = ResolveToolSite(DemoSitePath(), path);
  ASSERT_TRUE(with_config.known) << with_config.error;
  EXPECT_EQ(with_config.line.rfind("site from --config " + DemoSitePath(), 0), 0u)
      << with_config.line;
  ASSERT_EQ(with_config.warnings.size(), 1u);
  EXPECT_NE(with_config.warnings[0].find("receivers[0].range_offset_m: 0.02 -> 0.0"),
            std::string::npos)
      << with_config.warnings[0];

  const ToolSite from_log = ResolveToolSite("", path);
  ASSERT_TRUE(from_log.known) << from_log.error;
  EXPECT_TRUE(from_log.warnings.empty());
  EXPECT_EQ(from_log.site.content_hash, logged.content_hash);
  const std::string& line = from_log.line;
  EXPECT_EQ(
      line.rfind("site from " + path + ": demo_room, hash " + ShortSiteHash(logged.content_hash) +
                     ", roomfix " + RoomfixVersion() + ", published by trilat_proc@",
                 0),
      0u)
      << line;
}

TEST(ProcessSite, PublishedAtTheFirstHeartbeatAndEveryFiveSeconds) {
  const LoadedSite original = LoadDemo();
  SetProcessSite(std::make_shared<site_t>(DemoMessage(original)));
  LoopbackBus bus;
  std::vector<int64_t> site_utimes;
  bus.Subscribe<site_t>(
      kSiteChannel, [&](const site_t& m, const MessageInfo&) { site_utimes.push_back(m.utime); });
  std::vector<process_status_t> statuses;
  bus.Subscribe<process_status_t>(
      kStatusChannel,
      [&](const process_status_t& m, const MessageInfo&) { statuses.push_back(m); });
  StatusReporter status("trilat_proc", 0);
  const int64_t t0 = 1700000000000000;
  // A heartbeat every second for 11 s: SITE at 0, 5 and 10 s.
  for (int s = 0; s <= 11; ++s) status.MaybePublish(&bus, t0 + s * 1000000LL);
  EXPECT_EQ(site_utimes, (std::vector<int64_t>{t0, t0 + 5000000, t0 + 10000000}));
  ASSERT_EQ(statuses.size(), 12u);
  bool stated = false;
  for (const auto& c : statuses.back().counters) {
    if (c.name == kSiteHashCounter) {
      stated = true;
      EXPECT_EQ(SiteHashCounterText(c.count), original.content_hash.substr(0, 15));
    }
  }
  EXPECT_TRUE(stated);
  SetProcessSite(nullptr);
  status.Publish(&bus, t0 + 20000000);
  EXPECT_EQ(site_utimes.size(), 3u);
}

// --- SitePublishSchedule: the site is sent when it matters (issue #28) ------

site_t Publisher(const std::string& process, int32_t pid, const std::string& hash) {
  site_t m;
  m.process = process;
  m.host = "lab-pc";
  m.pid = pid;
  m.content_hash = hash;
  return m;
}

process_status_t StatusOf(const std::string& process, int32_t pid) {
  process_status_t m;
  m.process = process;
  m.host = "lab-pc";
  m.pid = pid;
  return m;
}

constexpr int64_t kT0 = 1700000000000000;
constexpr int64_t kSecondUs = 1000000;

// The publish times of `schedule` over `seconds` of heartbeats every 100 ms,
// with `hear(t)` called before each.
std::vector<int64_t> PublishTimes(SitePublishSchedule* schedule, int seconds,
                                  const std::function<void(int64_t)>& hear) {
  std::vector<int64_t> times;
  for (int64_t t = kT0; t <= kT0 + seconds * kSecondUs; t += kSecondUs / 10) {
    hear(t);
    if (schedule->Due(t)) times.push_back(t - kT0);
  }
  return times;
}

TEST(SitePublishSchedule, AloneItPublishesAtStartAndEveryPeriod) {
  SitePublishSchedule schedule;
  schedule.Reset(Publisher("trilat_proc", 20, "aaaa"));
  EXPECT_EQ(PublishTimes(&schedule, 11, [](int64_t) {}),
            (std::vector<int64_t>{0, kSitePeriodUs, 2 * kSitePeriodUs}));
  EXPECT_STREQ(schedule.last_reason(), "period");
}

TEST(SitePublishSchedule, OnlyTheSmallestPublisherOfASiteRepeatsIt) {
  SitePublishSchedule trilat;
  trilat.Reset(Publisher("trilat_proc", 20, "aaaa"));
  // fusion_proc sorts first and publishes the same site every period.
  const site_t fusion = Publisher("fusion_proc", 30, "aaaa");
  const auto hear = [&](int64_t t) {
    if ((t - kT0) % kSitePeriodUs == 0) trilat.ObserveSite(fusion, t);
  };
  EXPECT_EQ(PublishTimes(&trilat, 30, hear), (std::vector<int64_t>{0}));
  EXPECT_FALSE(trilat.elected(kT0 + 30 * kSecondUs));
}

TEST(SitePublishSchedule, APublisherOfAnotherSiteOrALargerNameSilencesNothing) {
  SitePublishSchedule fusion;
  fusion.Reset(Publisher("fusion_proc", 30, "aaaa"));
  const site_t other_site = Publisher("camera_proc", 10, "bbbb");
  const site_t larger = Publisher("trilat_proc", 20, "aaaa");
  const auto hear = [&](int64_t t) {
    fusion.ObserveSite(other_site, t);
    fusion.ObserveSite(larger, t);
  };
  EXPECT_EQ(PublishTimes(&fusion, 11, hear),
            (std::vector<int64_t>{0, kSitePeriodUs, 2 * kSitePeriodUs}));
}

TEST(SitePublishSchedule, WhenTheElectedOneStopsTheNextTakesOverWithinTheWindow) {
  SitePublishSchedule trilat;
  trilat.Reset(Publisher("trilat_proc", 20, "aaaa"));
  const site_t fusion = Publisher("fusion_proc", 30, "aaaa");
  // fusion_proc publishes at 0 and 5 s, then stops.
  const auto hear = [&](int64_t t) {
    if (t - kT0 <= kSitePeriodUs && (t - kT0) % kSitePeriodUs == 0) trilat.ObserveSite(fusion, t);
  };
  const std::vector<int64_t> times = PublishTimes(&trilat, 20, hear);
  ASSERT_EQ(times.size(), 2u);
  // trilat_proc's own start, then the first heartbeat after the election
  // window has passed since fusion_proc's last SITE (5 s).
  EXPECT_EQ(times[0], 0);
  EXPECT_EQ(times[1], kSitePeriodUs + SitePublishSchedule::kSiteElectionWindowUs + kSecondUs / 10);
}

TEST(SitePublishSchedule, TheElectedOneAnswersANewcomerWithinAboutASecond) {
  SitePublishSchedule fusion;
  fusion.Reset(Publisher("fusion_proc", 30, "aaaa"));
  // trilat_proc sends STATUS every second from 0 s; a viewer appears at 2.5 s.
  const auto hear = [&](int64_t t) {
    if ((t - kT0) % kSecondUs == 0) fusion.ObserveStatus(StatusOf("trilat_proc", 20), t);
    if (t - kT0 >= 2500000 && (t - kT0 - 2500000) % kSecondUs == 0) {
      fusion.ObserveStatus(StatusOf("roomfix_viewer", 40), t);
    }
  };
  // 0: start (which also serves trilat_proc, new at 0 s); 2.5 s: the
  // viewer, at its first STATUS; then the period, counted from the last SITE.
  EXPECT_EQ(PublishTimes(&fusion, 8, hear), (std::vector<int64_t>{0, 2500000, 7500000}));
  EXPECT_STREQ(fusion.last_reason(), "period");
}

TEST(SitePublishSchedule, AFloodOfInventedNamesGetsAtMostOneAnswerPerGap) {
  SitePublishSchedule fusion;
  fusion.Reset(Publisher("fusion_proc", 30, "aaaa"));
  int32_t pid = 1000;
  // 100 new names every 100 ms for 10 s (10 000 in all).
  const auto hear = [&](int64_t t) {
    for (int i = 0; i < 100; ++i) fusion.ObserveStatus(StatusOf("forged", pid++), t);
  };
  const std::vector<int64_t> times = PublishTimes(&fusion, 10, hear);
  EXPECT_EQ(times.size(), 11u);  // start, then one per kSiteAnswerGapUs
  for (size_t i = 1; i < times.size(); ++i) {
    EXPECT_GE(times[i] - times[i - 1], SitePublishSchedule::kSiteAnswerGapUs);
  }
}

TEST(SitePublishSchedule, ANewSiteIsPublishedAtOnceWhateverWasHeard) {
  SitePublishSchedule trilat;
  trilat.Reset(Publisher("trilat_proc", 20, "aaaa"));
  EXPECT_TRUE(trilat.Due(kT0));
  trilat.ObserveSite(Publisher("fusion_proc", 30, "aaaa"), kT0);
  EXPECT_FALSE(trilat.Due(kT0 + kSitePeriodUs));
  trilat.Reset(Publisher("trilat_proc", 20, "cccc"));
  EXPECT_TRUE(trilat.Due(kT0 + kSitePeriodUs + 1));
  EXPECT_STREQ(trilat.last_reason(), "start");
}

// A forged SITE from a name that sorts first, claiming this process's hash
// over other texts, is hashed, found false and ignored: the process keeps
// repeating its site. The same message with the true texts does silence it
// (that publisher then carries the site). Real bus plumbing: FollowSitePeers
// on a loopback bus, the process's StatusReporter beating every second.
std::vector<int64_t> OwnSitesWhileHearing(const site_t& heard, int seconds) {
  const LoadedSite original = LoadDemo();
  SetProcessSite(std::make_shared<site_t>(DemoMessage(original)));
  LoopbackBus bus;
  FollowSitePeers(&bus);
  std::vector<int64_t> own;
  bus.Subscribe<site_t>(kSiteChannel, [&](const site_t& m, const MessageInfo&) {
    if (m.process == "trilat_proc") own.push_back(m.utime - kT0);
  });
  StatusReporter status("trilat_proc", 0);
  const std::vector<uint8_t> bytes = Encode(heard);
  for (int s = 0; s <= seconds; ++s) {
    bus.Inject(kSiteChannel, bytes.data(), static_cast<int>(bytes.size()), kT0 + s * kSecondUs);
    status.MaybePublish(&bus, kT0 + s * kSecondUs);
  }
  SetProcessSite(nullptr);
  return own;
}

TEST(ProcessSite, AForgedSiteWithThisProcesssHashButOtherTextsSilencesNothing) {
  site_t forged = DemoMessage(LoadDemo());
  forged.process = "camera_proc";  // sorts before trilat_proc
  forged.site_text += "\n# forged\n";
  EXPECT_EQ(OwnSitesWhileHearing(forged, 11),
            (std::vector<int64_t>{0, kSitePeriodUs, 2 * kSitePeriodUs}));
  site_t genuine = DemoMessage(LoadDemo());
  genuine.process = "camera_proc";
  EXPECT_EQ(OwnSitesWhileHearing(genuine, 11), (std::vector<int64_t>{0}));
}

}  // namespace
}  // namespace roomfix
