// roomfix: the project's command-line tool.
#include <CLI/CLI.hpp>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <iostream>

#include "msgio/process.h"
#include "tools/commands.h"

int main(int argc, char** argv) {
  // Library log lines (a node run inside a benchmark, say) go to standard
  // error, and only warnings: standard output is the command's own, often
  // JSON for another program.
  roomfix::SetUpLogging("roomfix", "warn");
  CLI::App app{"roomfix: indoor robot localisation tools"};
  app.require_subcommand(1);
  int exit_code = 0;
  roomfix::AddVersionCommand(&app, &exit_code);
  roomfix::AddCheckConfigCommand(&app, &exit_code);
  roomfix::AddLogInfoCommand(&app, &exit_code);
  roomfix::AddListenCommand(&app, &exit_code);
  roomfix::AddSolveCommand(&app, &exit_code);
  roomfix::AddBenchCommand(&app, &exit_code);
  roomfix::AddCompareCommand(&app, &exit_code);
  roomfix::AddFramesCommand(&app, &exit_code);
  roomfix::AddAnalyzeCommand(&app, &exit_code);
  roomfix::AddCalibrateCommand(&app, &exit_code);
  roomfix::AddMapCommand(&app, &exit_code);
  roomfix::AddRenderCameraCommand(&app, &exit_code);
  roomfix::AddSurveyCommand(&app, &exit_code);
  roomfix::AddReplayCommand(&app, &exit_code);
  CLI11_PARSE(app, argc, argv);
  // Standard output is an output like any file (bench --json, frames,
  // map): a command whose output was lost (`> /dev/full`, a full disk)
  // has failed, whatever it computed.
  errno = 0;
  std::cout.flush();
  if (std::fflush(stdout) != 0 || std::ferror(stdout) != 0 || !std::cout) {
    std::cerr << "roomfix: standard output: cannot write: "
              << (errno != 0 ? std::strerror(errno) : "an earlier write failed (a full disk?)")
              << "\n";
    return 1;
  }
  return exit_code;
}
