// Runs every fuzz target (tests/fuzz/CMakeLists.txt) on each file of its
// corpus, tests/data/fuzz/<name>/: the seeds and every crash input found so
// far. A target abort()s on a violated invariant, which kills this test; the
// last "fuzz input:" line on stderr names the file.

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "tests/testing/test_paths.h"

// The entry points, renamed from LLVMFuzzerTestOneInput for this binary.
#define ROOMFIX_FUZZ_TARGET(name) extern "C" int RoomfixFuzz_##name(const uint8_t*, size_t);
#include "fuzz_targets.inc"
#undef ROOMFIX_FUZZ_TARGET

namespace roomfix {
namespace {

namespace fs = std::filesystem;

using FuzzFunction = int (*)(const uint8_t* data, size_t size);

// Runs `fuzz` on every regular file of tests/data/fuzz/<corpus>/, in name
// order; returns how many ran. libFuzzer's own files (crash-*, ...) count too.
size_t RunCorpus(const std::string& corpus, FuzzFunction fuzz) {
  const fs::path dir = fs::path(testing::SourceDir()) / "tests/data/fuzz" / corpus;
  std::vector<fs::path> files;
  std::error_code error;
  for (const auto& entry : fs::directory_iterator(dir, error)) {
    if (entry.is_regular_file()) files.push_back(entry.path());
  }
  std::sort(files.begin(), files.end());
  for (const fs::path& file : files) {
    std::fprintf(stderr, "fuzz input: %s\n", file.c_str());
    std::ifstream in(file, std::ios::binary);
    const std::vector<uint8_t> bytes{std::istreambuf_iterator<char>(in),
                                     std::istreambuf_iterator<char>()};
    fuzz(bytes.data(), bytes.size());
  }
  return files.size();
}

#define ROOMFIX_FUZZ_TARGET(name)                                           \
  TEST(FuzzRegression, name) {                                              \
    EXPECT_GT(RunCorpus(#name, &RoomfixFuzz_##name), 0u)                    \
        << "no corpus files in tests/data/fuzz/" #name "/ (or unreadable)"; \
  }
#include "fuzz_targets.inc"
#undef ROOMFIX_FUZZ_TARGET

}  // namespace
}  // namespace roomfix
