// roomfix: the project's command-line tool.
#include <CLI/CLI.hpp>

#include "msgio/process.h"
#include "tools/command_line.h"
#include "tools/commands.h"

int main(int argc, char** argv) {
  // Library log lines (a node run by replay, say) go to standard error, and
  // only warnings: standard output is the command's own, often JSON for
  // another program.
  roomfix::SetUpLogging("roomfix", "warn");
  CLI::App app{"roomfix: indoor robot localisation tools"};
  app.require_subcommand(1);
  int exit_code = 0;
  roomfix::AddVersionCommand(&app, &exit_code);
  roomfix::AddCheckConfigCommand(&app, &exit_code);
  roomfix::AddLogInfoCommand(&app, &exit_code);
  roomfix::AddListenCommand(&app, &exit_code);
  roomfix::AddSolveCommand(&app, &exit_code);
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
  return roomfix::RunCommandLine(&app, "roomfix", argc, argv, &exit_code);
}
