#include "msgio/install_paths.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <string>

#include "tests/testing/test_paths.h"

namespace roomfix {
namespace {

// An installed program reads its data beside its prefix, wherever the prefix
// is: the .deb's /usr, an /opt tree, a package unpacked into a folder.
TEST(InstallPathsTest, InstalledProgramReadsDataUnderItsOwnPrefix) {
  EXPECT_EQ(DataDirFor("/usr/bin"), "/usr/share/roomfix");
  EXPECT_EQ(DataDirFor("/opt/roomfix/bin"), "/opt/roomfix/share/roomfix");
  EXPECT_EQ(DataDirFor("/tmp/unpacked/usr/bin"), "/tmp/unpacked/usr/share/roomfix");
}

// A program run from this build tree reads the source tree, so an edit to
// config/ is seen without installing; also through a path spelled
// differently (a trailing "/.", as a symbolic link or a script might give).
TEST(InstallPathsTest, BuildTreeProgramReadsTheSourceTree) {
  EXPECT_EQ(DataDirFor(testing::BinDir()), testing::SourceDir());
  EXPECT_EQ(DataDirFor(testing::BinDir() + "/."), testing::SourceDir());
}

// This test binary is in the build tree's bin folder, so the demo site is
// found in the source tree whatever the current folder is.
TEST(InstallPathsTest, DataFileDoesNotDependOnTheCurrentFolder) {
  const std::filesystem::path before = std::filesystem::current_path();
  ASSERT_EQ(::chdir("/"), 0);
  const std::string site = DataFile("config/sites/demo_room.yaml");
  std::filesystem::current_path(before);
  EXPECT_EQ(site, testing::SourceDir() + "/config/sites/demo_room.yaml");
  EXPECT_TRUE(std::filesystem::is_regular_file(site)) << site;
}

}  // namespace
}  // namespace roomfix
