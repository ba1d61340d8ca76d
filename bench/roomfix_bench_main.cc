// roomfix_bench: the benchmarks, a developer program of its own so that the
// `roomfix` tool links none of what they measure (the simulator's devices,
// the bridge, the viewer's renderer, Google Benchmark).
#include <CLI/CLI.hpp>

#include "bench/commands.h"
#include "msgio/process.h"
#include "tools/command_line.h"

int main(int argc, char** argv) {
  // Library log lines (a node run inside a benchmark, say) go to standard
  // error, and only warnings: standard output is the figures, or JSON.
  roomfix::SetUpLogging("roomfix_bench", "warn");
  CLI::App app{"roomfix_bench: benchmarks that print figures"};
  app.require_subcommand(1);
  int exit_code = 0;
  roomfix::AddBenchCommands(&app, &exit_code);
  return roomfix::RunCommandLine(&app, "roomfix_bench", argc, argv, &exit_code);
}
