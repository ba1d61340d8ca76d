#include "msgio/install_paths.h"

#include <unistd.h>

#include <climits>
#include <cstdlib>
#include <filesystem>
#include <system_error>

// Set by msgio/CMakeLists.txt.
#ifndef ROOMFIX_BUILD_BIN_DIR
#error "ROOMFIX_BUILD_BIN_DIR must be defined"
#endif

namespace roomfix {
namespace {

// Canonical form for comparing folders; the path itself when it does not
// exist (a build tree removed after installing).
std::string Canonical(const std::string& path) {
  std::error_code ec;
  const std::filesystem::path p = std::filesystem::weakly_canonical(path, ec);
  return ec ? path : p.string();
}

}  // namespace

std::string ExecutableDir() {
  char buffer[PATH_MAX];
  const ssize_t n = ::readlink("/proc/self/exe", buffer, sizeof(buffer) - 1);
  if (n <= 0) return "";
  buffer[n] = '\0';
  return std::filesystem::path(buffer).parent_path().string();
}

std::string DataDirFor(const std::string& exe_dir) {
  if (!exe_dir.empty() && Canonical(exe_dir) == Canonical(ROOMFIX_BUILD_BIN_DIR)) {
    return ROOMFIX_SOURCE_DIR;
  }
  return (std::filesystem::path(exe_dir) / ROOMFIX_BIN_TO_DATA_DIR).lexically_normal().string();
}

std::string DataFile(const std::string& relative) {
  std::string dir = DataDirFor(ExecutableDir());
  if (!dir.empty() && dir.back() == '/') dir.pop_back();
  return dir + "/" + relative;
}

}  // namespace roomfix
