#ifndef ROOMFIX_TOOLS_COMMAND_LINE_H_
#define ROOMFIX_TOOLS_COMMAND_LINE_H_

#include <CLI/CLI.hpp>
#include <string>

namespace roomfix {

// The end of a subcommand-style tool's main (roomfix, roomfix_bench): parses
// argv into `app`, whose subcommands' callbacks run a command and set
// *exit_code; prints a flag's value refused by its check (flag_checks.h,
// CLI11's IsMember or Range) as one line naming the command ("roomfix solve:
// ..."), exit 1; and fails (exit 1, saying so) when standard output could
// not be written. Returns the exit code for main to return.
int RunCommandLine(CLI::App* app, const std::string& program, int argc, char** argv,
                   const int* exit_code);

}  // namespace roomfix

#endif  // ROOMFIX_TOOLS_COMMAND_LINE_H_
