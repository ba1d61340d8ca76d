#ifndef ROOMFIX_TESTS_TESTING_TEST_PATHS_H_
#define ROOMFIX_TESTS_TESTING_TEST_PATHS_H_

#include <string>
#include <vector>

namespace roomfix::testing {

// Folders handed to every test by ctest (cmake/RoomfixTesting.cmake).
std::string SourceDir();
std::string BuildDir();
// ../shared/data, or "" when it is absent (tests then GTEST_SKIP, saying so).
std::string SharedDataDir();
std::string BinDir();

// A fresh empty folder under $TMPDIR, removed when the object goes.
class TempDir {
 public:
  TempDir();
  ~TempDir();
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  const std::string& path() const { return path_; }
  std::string File(const std::string& name) const { return path_ + "/" + name; }

 private:
  std::string path_;
};

// A child process started with posix_spawn; stdout is captured to a file.
class ChildProcess {
 public:
  // argv[0] is the program (searched on PATH when it has no slash).
  explicit ChildProcess(const std::vector<std::string>& argv, const std::string& stdout_path = "");
  ~ChildProcess();  // SIGKILLs and reaps a child still running.
  bool started() const { return pid_ > 0; }
  int pid() const { return pid_; }
  // Waits up to timeout_s; returns the exit code, 128 + signal, or -1 on
  // time-out (the child is then left running).
  int Wait(double timeout_s);
  void Signal(int signal);

 private:
  int pid_ = -1;
  int status_ = -1;
};

// A built program (BinDir()/`program`) run with `args`, its standard output
// and standard error together, as a person sees them at a terminal.
struct ToolRun {
  int exit_code = 0;
  std::string out;
};
ToolRun RunTool(const std::string& program, const std::vector<std::string>& args,
                double timeout_s = 300.0);

std::string ReadFile(const std::string& path);
// Waits up to timeout_s for a path to exist (a pseudo-terminal's link, a log
// file); false on time-out.
bool WaitForPath(const std::string& path, double timeout_s);
bool WriteFile(const std::string& path, const std::string& text);

}  // namespace roomfix::testing

#endif  // ROOMFIX_TESTS_TESTING_TEST_PATHS_H_
