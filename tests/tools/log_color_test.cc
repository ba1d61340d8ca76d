// --log-color as a process sees it: with stderr on a real pseudo-terminal
// (what bot-procman's deputy gives every command) and on a pipe (what a
// log file or `2>&1 | tee` gives), with and without NO_COLOR. The process is
// trilat_proc on memq:// (no network), which logs one info line at start-up.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <string>
#include <vector>

#include "sim/pseudo_terminal.h"
#include "tests/testing/demo_site.h"
#include "tests/testing/test_paths.h"

extern char** environ;

namespace roomfix {
namespace {

using testing::BinDir;
using testing::DemoSitePath;

// An ANSI SGR sequence, which is how spdlog colours the level name.
constexpr char kEscape[] = "\x1b[";
// The line trilat_proc logs once its bus is open.
constexpr char kStartLine[] = "listening on";
// Start-up of a process on memq:// takes milliseconds; 10 s only guards
// against a loaded machine.
constexpr double kStartTimeout_s = 10.0;

enum class Stderr { kTerminal, kPipe };

// Runs trilat_proc with `color` (or no --log-color when empty), stderr on a
// terminal or a pipe and NO_COLOR as given (nullptr: unset); returns what it
// wrote to stderr up to its start-up line, then stops it with SIGINT.
std::string StderrOf(Stderr where, const std::string& color, const char* no_color) {
  std::vector<std::string> args = {BinDir() + "/trilat_proc",
                                   "--config",
                                   DemoSitePath(),
                                   "--lcm-url",
                                   "memq://",
                                   "--log-level",
                                   "info"};
  if (!color.empty()) args.insert(args.end(), {"--log-color", color});
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);

  std::vector<std::string> env_strings;
  for (char** e = environ; *e != nullptr; ++e) {
    if (std::string(*e).rfind("NO_COLOR=", 0) != 0) env_strings.emplace_back(*e);
  }
  if (no_color != nullptr) env_strings.push_back(std::string("NO_COLOR=") + no_color);
  std::vector<char*> envp;
  for (auto& e : env_strings) envp.push_back(e.data());
  envp.push_back(nullptr);

  std::string error;
  std::unique_ptr<PseudoTerminal> pty;
  int read_fd = -1;
  int child_stderr = -1;
  int pipe_fds[2] = {-1, -1};
  if (where == Stderr::kTerminal) {
    pty = PseudoTerminal::Open("", &error);
    EXPECT_NE(pty, nullptr) << error;
    if (pty == nullptr) return "";
    child_stderr = ::open(pty->device_path().c_str(), O_RDWR | O_NOCTTY);
    read_fd = pty->master_fd();
  } else {
    EXPECT_EQ(::pipe(pipe_fds), 0);
    child_stderr = pipe_fds[1];
    read_fd = pipe_fds[0];
  }
  EXPECT_GE(child_stderr, 0);
  EXPECT_EQ(::isatty(child_stderr), where == Stderr::kTerminal ? 1 : 0);

  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_adddup2(&actions, child_stderr, STDERR_FILENO);
  pid_t pid = -1;
  const int rc = posix_spawn(&pid, argv[0], &actions, nullptr, argv.data(), envp.data());
  posix_spawn_file_actions_destroy(&actions);
  ::close(child_stderr);
  EXPECT_EQ(rc, 0);

  std::string out;
  const auto deadline =
      std::chrono::steady_clock::now() + std::chrono::duration<double>(kStartTimeout_s);
  while (out.find(kStartLine) == std::string::npos && std::chrono::steady_clock::now() < deadline) {
    pollfd p{read_fd, POLLIN, 0};
    if (::poll(&p, 1, 100) <= 0) continue;
    char buf[4096];
    const ssize_t n = ::read(read_fd, buf, sizeof(buf));
    if (n > 0) out.append(buf, static_cast<size_t>(n));
  }
  if (pid > 0) {
    ::kill(pid, SIGINT);
    int status = 0;
    ::waitpid(pid, &status, 0);
    EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << "status " << status;
  }
  if (pipe_fds[0] >= 0) ::close(pipe_fds[0]);
  EXPECT_NE(out.find(kStartLine), std::string::npos) << "no start-up line in: " << out;
  return out;
}

bool Coloured(const std::string& text) { return text.find(kEscape) != std::string::npos; }

TEST(LogColor, AutoColoursATerminalOnly) {
  EXPECT_TRUE(Coloured(StderrOf(Stderr::kTerminal, "auto", nullptr)));
  EXPECT_FALSE(Coloured(StderrOf(Stderr::kPipe, "auto", nullptr)));
}

TEST(LogColor, AutoIsTheDefault) {
  EXPECT_TRUE(Coloured(StderrOf(Stderr::kTerminal, "", nullptr)));
  EXPECT_FALSE(Coloured(StderrOf(Stderr::kPipe, "", nullptr)));
}

// no-color.org: any non-empty value disables colour; an empty one does not.
TEST(LogColor, AutoHonoursNoColorOnATerminal) {
  EXPECT_FALSE(Coloured(StderrOf(Stderr::kTerminal, "auto", "1")));
  EXPECT_FALSE(Coloured(StderrOf(Stderr::kTerminal, "auto", "0")));
  EXPECT_TRUE(Coloured(StderrOf(Stderr::kTerminal, "auto", "")));
}

// What bot-procman's .pmd files pass: its deputy runs commands on a
// pseudo-terminal, so auto would colour the sheriff's console.
TEST(LogColor, NeverLeavesATerminalPlain) {
  const std::string out = StderrOf(Stderr::kTerminal, "never", nullptr);
  EXPECT_FALSE(Coloured(out));
  EXPECT_NE(out.find("info"), std::string::npos) << out;
}

// A per-run argument overrides NO_COLOR (no-color.org).
TEST(LogColor, AlwaysColoursAPipeEvenWithNoColor) {
  EXPECT_TRUE(Coloured(StderrOf(Stderr::kPipe, "always", nullptr)));
  EXPECT_TRUE(Coloured(StderrOf(Stderr::kPipe, "always", "1")));
}

TEST(LogColor, AnUnknownModeIsRefusedByName) {
  std::string error;
  const std::string cmd =
      BinDir() + "/trilat_proc --config " + DemoSitePath() + " --log-color sometimes --check 2>&1";
  FILE* f = ::popen(cmd.c_str(), "r");
  ASSERT_NE(f, nullptr);
  std::string out;
  char buf[512];
  while (std::fgets(buf, sizeof(buf), f) != nullptr) out += buf;
  const int status = ::pclose(f);
  EXPECT_NE(WEXITSTATUS(status), 0);
  EXPECT_NE(out.find("--log-color"), std::string::npos) << out;
}

}  // namespace
}  // namespace roomfix
