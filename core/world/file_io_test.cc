// The configuration-file reader and output writer: what a site or
// calibration path may name, and what a failed write reports.
#include "core/world/file_io.h"

#include <gtest/gtest.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/stat.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "core/calib/calibration_file.h"
#include "core/world/site.h"
#include "core/world/yaml_reader.h"
#include "tests/testing/demo_site.h"
#include "tests/testing/test_paths.h"

namespace roomfix {
namespace {

using testing::DemoSitePath;
using testing::TempDir;

TEST(ReadConfigFile, ReadsARegularFileWhole) {
  TempDir dir;
  const std::string text = "name: x\nroom: {}\n";
  ASSERT_TRUE(testing::WriteFile(dir.File("a.yaml"), text));
  std::string read, error;
  ASSERT_TRUE(ReadConfigFile(dir.File("a.yaml"), &read, &error)) << error;
  EXPECT_EQ(read, text);
}

TEST(ReadConfigFile, RefusesDevZeroAtOnceInsteadOfReadingForever) {
  std::string text, error;
  EXPECT_FALSE(ReadConfigFile("/dev/zero", &text, &error));
  EXPECT_EQ(error, "/dev/zero: not a regular file (a character device)");
  EXPECT_TRUE(text.empty());
}

TEST(ReadConfigFile, RefusesAFifoWithoutWaitingForAWriter) {
  TempDir dir;
  const std::string fifo = dir.File("pipe.yaml");
  ASSERT_EQ(mkfifo(fifo.c_str(), 0600), 0);
  // A blocking open would hang here until a writer came: none will.
  const auto start = std::chrono::steady_clock::now();
  std::string text, error;
  EXPECT_FALSE(ReadConfigFile(fifo, &text, &error));
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_EQ(error, fifo + ": not a regular file (a FIFO)");
  EXPECT_LT(seconds, 1.0) << "the open must not wait for a writer";
}

TEST(ReadConfigFile, RefusesAFolderAndAMissingFileNamingThem) {
  TempDir dir;
  std::string text, error;
  EXPECT_FALSE(ReadConfigFile(dir.path(), &text, &error));
  EXPECT_EQ(error, dir.path() + ": not a regular file (a folder)");
  EXPECT_FALSE(ReadConfigFile(dir.File("none.yaml"), &text, &error));
  EXPECT_EQ(error, dir.File("none.yaml") + ": cannot open: No such file or directory");
}

TEST(ReadConfigFile, RefusesAFileOverTheCapAndAcceptsOneAtIt) {
  TempDir dir;
  const std::string big = dir.File("big.yaml");
  ASSERT_TRUE(testing::WriteFile(big, std::string(kConfigFileCapBytes + 1, '#')));
  std::string text, error;
  EXPECT_FALSE(ReadConfigFile(big, &text, &error));
  EXPECT_EQ(error, big + ": 4194305 bytes, over the 4 MiB cap for configuration files");
  ASSERT_TRUE(testing::WriteFile(big, std::string(kConfigFileCapBytes, '#')));
  EXPECT_TRUE(ReadConfigFile(big, &text, &error)) << error;
  EXPECT_EQ(text.size(), kConfigFileCapBytes);
}

TEST(LoadSite, RefusesDevZeroAFolderAndAFifo) {
  TempDir dir;
  ASSERT_EQ(mkfifo(dir.File("fifo").c_str(), 0600), 0);
  Site site;
  std::string error;
  EXPECT_FALSE(LoadSite("/dev/zero", &site, &error));
  EXPECT_EQ(error, "/dev/zero: not a regular file (a character device)");
  EXPECT_FALSE(LoadSite(dir.path(), &site, &error));
  EXPECT_EQ(error, dir.path() + ": not a regular file (a folder)");
  EXPECT_FALSE(LoadSite(dir.File("fifo"), &site, &error));
  EXPECT_EQ(error, dir.File("fifo") + ": not a regular file (a FIFO)");
}

TEST(LoadCalibration, RefusesDevZeroAndAFolder) {
  TempDir dir;
  calib::Calibration c;
  std::string error;
  EXPECT_FALSE(calib::LoadCalibration("/dev/zero", &c, &error));
  EXPECT_EQ(error, "/dev/zero: not a regular file (a character device)");
  EXPECT_FALSE(calib::LoadCalibration(dir.path(), &c, &error));
  EXPECT_EQ(error, dir.path() + ": not a regular file (a folder)");
}

// The demo site with one line appended or changed, in a temporary file.
std::string DemoSiteText() { return testing::ReadFile(DemoSitePath()); }

int LineOf(const std::string& text, const std::string& what) {
  const size_t at = text.find(what);
  if (at == std::string::npos) return -1;
  return 1 + static_cast<int>(std::count(text.begin(), text.begin() + static_cast<long>(at), '\n'));
}

TEST(LoadSite, RefusesATopLevelKeyGivenTwiceNamingBothLines) {
  TempDir dir;
  std::string text = DemoSiteText();
  ASSERT_NE(LineOf(text, "\nname:"), -1);
  const int first = LineOf(text, "\nname:") + 1;
  text += "name: second\n";
  const int second = static_cast<int>(std::count(text.begin(), text.end(), '\n'));
  const std::string path = dir.File("site.yaml");
  ASSERT_TRUE(testing::WriteFile(path, text));
  Site site;
  std::string error;
  EXPECT_FALSE(LoadSite(path, &site, &error));
  EXPECT_EQ(error, path + ":" + std::to_string(second) + ": duplicated key 'name' (first at line " +
                       std::to_string(first) + ")");
}

TEST(LoadSite, RefusesANestedKeyGivenTwiceNamingBothLines) {
  TempDir dir;
  const std::string text =
      "name: nested\n"
      "room:\n"
      "  size_x_m: 4.0\n"
      "  size_y_m: 3.0\n"
      "  size_x_m: 5.0\n";
  const std::string path = dir.File("site.yaml");
  ASSERT_TRUE(testing::WriteFile(path, text));
  Site site;
  std::string error;
  EXPECT_FALSE(LoadSite(path, &site, &error));
  EXPECT_EQ(error, path + ":5: duplicated key 'size_x_m' (first at line 3)");
}

TEST(FindDuplicateKey, SameKeyInSiblingMappingsIsNotADuplicate) {
  // Each list entry is its own mapping; aliases and flow style count too.
  const std::string text =
      "a: &x {id: 1, z: 2}\n"
      "b: *x\n"
      "list:\n"
      "  - {id: 1}\n"
      "  - id: 2\n"
      "    sub: {id: 3, id2: 4}\n";
  EXPECT_EQ(FindDuplicateKey(text, "f.yaml"), "");
  EXPECT_EQ(FindDuplicateKey("list:\n  - {id: 1, id: 2}\n", "f.yaml"),
            "f.yaml:2: duplicated key 'id' (first at line 2)");
}

TEST(LoadCalibration, RefusesADuplicatedKeyNamingFileAndLine) {
  TempDir dir;
  const std::string path = dir.File("cal.yaml");
  ASSERT_TRUE(testing::WriteFile(path,
                                 "model: full\n"
                                 "intrinsics:\n"
                                 "  width_px: 1920\n"
                                 "  height_px: 1080\n"
                                 "  fx_px: 900\n"
                                 "  fx_px: 917\n"));
  calib::Calibration c;
  std::string error;
  EXPECT_FALSE(calib::LoadCalibration(path, &c, &error));
  EXPECT_EQ(error, path + ":6: duplicated key 'fx_px' (first at line 5)");
}

TEST(ReadBoundedLine, ReadsLinesAndStopsAtAnOverlongOne) {
  std::istringstream in("a,b\n\nlast");
  std::string line;
  EXPECT_EQ(ReadBoundedLine(in, &line), LineRead::kLine);
  EXPECT_EQ(line, "a,b");
  EXPECT_EQ(ReadBoundedLine(in, &line), LineRead::kLine);
  EXPECT_EQ(line, "");
  EXPECT_EQ(ReadBoundedLine(in, &line), LineRead::kLine);
  EXPECT_EQ(line, "last");
  EXPECT_EQ(ReadBoundedLine(in, &line), LineRead::kEnd);
  std::istringstream at_cap(std::string(10, 'x') + "\n" + std::string(11, 'y') + "\n");
  EXPECT_EQ(ReadBoundedLine(at_cap, &line, 10), LineRead::kLine);
  EXPECT_EQ(line.size(), 10u);
  EXPECT_EQ(ReadBoundedLine(at_cap, &line, 10), LineRead::kTooLong);
}

TEST(ReadBoundedLine, StopsOnDevZeroAfterTheCap) {
  std::ifstream zero("/dev/zero", std::ios::binary);
  ASSERT_TRUE(zero.is_open());
  std::string line;
  EXPECT_EQ(ReadBoundedLine(zero, &line), LineRead::kTooLong);
  EXPECT_EQ(line.size(), kMaxInputLineBytes);
}

TEST(WriteOutputFile, ReportsAFullDeviceAsAFailedWrite) {
  std::string error;
  EXPECT_FALSE(WriteOutputFile("/dev/full", std::string(100000, 'x'), &error));
  EXPECT_EQ(error, "/dev/full: cannot write: No space left on device");
}

TEST(WriteOutputFile, WritesAndTruncates) {
  TempDir dir;
  std::string error;
  ASSERT_TRUE(WriteOutputFile(dir.File("o.txt"), "long text\n", &error)) << error;
  ASSERT_TRUE(WriteOutputFile(dir.File("o.txt"), "short\n", &error)) << error;
  EXPECT_EQ(testing::ReadFile(dir.File("o.txt")), "short\n");
  EXPECT_FALSE(WriteOutputFile(dir.File("no/such/o.txt"), "x", &error));
  EXPECT_EQ(error, dir.File("no/such/o.txt") + ": cannot write: No such file or directory");
}

// Issue #28: a write that fails part way (here the process's file size
// limit, RLIMIT_FSIZE, which fails a write() with EFBIG exactly as a disk
// that fills up fails it with ENOSPC) leaves the old file as it was and no
// partial file beside it; before, the file was truncated and half written.
TEST(WriteOutputFile, AWriteThatFailsPartWayLeavesTheOldFileAndNoPartialOne) {
  constexpr rlim_t kLimitBytes = 4096;
  TempDir dir;
  std::string error;
  ASSERT_TRUE(WriteOutputFile(dir.File("cal.yaml"), "old: 1\n", &error)) << error;
  struct sigaction ignore {};
  struct sigaction old_action {};
  ignore.sa_handler = SIG_IGN;  // else SIGXFSZ ends the process
  ASSERT_EQ(::sigaction(SIGXFSZ, &ignore, &old_action), 0);
  struct rlimit old_limit {};
  ASSERT_EQ(::getrlimit(RLIMIT_FSIZE, &old_limit), 0);
  struct rlimit limit = old_limit;
  limit.rlim_cur = kLimitBytes;
  ASSERT_EQ(::setrlimit(RLIMIT_FSIZE, &limit), 0);
  const bool ok = WriteOutputFile(dir.File("cal.yaml"), std::string(3 * kLimitBytes, 'x'), &error);
  const bool new_ok =
      WriteOutputFile(dir.File("new.yaml"), std::string(3 * kLimitBytes, 'x'), &error);
  ::setrlimit(RLIMIT_FSIZE, &old_limit);
  ::sigaction(SIGXFSZ, &old_action, nullptr);
  EXPECT_FALSE(ok);
  EXPECT_FALSE(new_ok);
  EXPECT_EQ(error, dir.File("new.yaml") + ": cannot write: File too large");
  EXPECT_EQ(testing::ReadFile(dir.File("cal.yaml")), "old: 1\n");
  std::vector<std::string> names;
  for (const auto& entry : std::filesystem::directory_iterator(dir.path())) {
    names.push_back(entry.path().filename().string());
  }
  EXPECT_EQ(names, std::vector<std::string>{"cal.yaml"}) << "no new.yaml, no partial file";
}

// A link is replaced at the file it names, and stays a link.
TEST(WriteOutputFile, ReplacesTheFileALinkNames) {
  TempDir dir;
  std::string error;
  ASSERT_TRUE(WriteOutputFile(dir.File("real.txt"), "old\n", &error)) << error;
  std::filesystem::create_symlink(dir.File("real.txt"), dir.File("link.txt"));
  ASSERT_TRUE(WriteOutputFile(dir.File("link.txt"), "new\n", &error)) << error;
  EXPECT_TRUE(std::filesystem::is_symlink(dir.File("link.txt")));
  EXPECT_EQ(testing::ReadFile(dir.File("real.txt")), "new\n");
}

TEST(SaveCalibration, ReportsAFullDevice) {
  calib::Calibration c;
  c.camera.intrinsics.width_px = 640;
  c.camera.intrinsics.height_px = 480;
  std::string error;
  EXPECT_FALSE(calib::SaveCalibration("/dev/full", c, "test", &error));
  EXPECT_EQ(error, "/dev/full: cannot write: No space left on device");
}

}  // namespace
}  // namespace roomfix
