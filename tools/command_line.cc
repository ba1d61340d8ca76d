#include "tools/command_line.h"

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <iostream>

namespace roomfix {

int RunCommandLine(CLI::App* app, const std::string& program, int argc, char** argv,
                   const int* exit_code) {
  try {
    app->parse(argc, argv);
  } catch (const CLI::ValidationError& e) {
    // A flag's value refused by its check (tools/flag_checks.h, CLI11's
    // IsMember or Range): one line naming the command and exit 1, as a
    // command's own refusals.
    std::string command = program;
    for (const CLI::App* a = app; !a->get_subcommands().empty();) {
      a = a->get_subcommands().front();
      command += " " + a->get_name();
    }
    std::cerr << command << ": " << e.what() << "\n";
    return 1;
  } catch (const CLI::ParseError& e) {
    return app->exit(e);
  }
  // Standard output is an output like any file (bench --json, frames,
  // map): a command whose output was lost (`> /dev/full`, a full disk)
  // has failed, whatever it computed.
  errno = 0;
  std::cout.flush();
  if (std::fflush(stdout) != 0 || std::ferror(stdout) != 0 || !std::cout) {
    std::cerr << program << ": standard output: cannot write: "
              << (errno != 0 ? std::strerror(errno) : "an earlier write failed (a full disk?)")
              << "\n";
    return 1;
  }
  return *exit_code;
}

}  // namespace roomfix
