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
  roomfix::AddColoursCommand(&app, &exit_code);
  roomfix::AddDetectCommand(&app, &exit_code);
  roomfix::AddSurveyCommand(&app, &exit_code);
  roomfix::AddReplayCommand(&app, &exit_code);
  roomfix::AddExportCommand(&app, &exit_code);
  roomfix::AddDevicesCommand(&app, &exit_code);
  roomfix::AddGrabCommand(&app, &exit_code);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ValidationError& e) {
    // A flag's value refused by its check (tools/flag_checks.h, CLI11's
    // IsMember or Range): one line naming the command and exit 1, as a
    // command's own refusals.
    std::string command = "roomfix";
    for (const CLI::App* a = &app; !a->get_subcommands().empty();) {
      a = a->get_subcommands().front();
      command += " " + a->get_name();
    }
    std::cerr << command << ": " << e.what() << "\n";
    return 1;
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
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
