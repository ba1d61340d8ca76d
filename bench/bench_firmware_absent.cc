// roomfix_bench firmware in a build without simavr (libsimavr-dev is a test
// package: `make demo` builds without it). As bench_micro_absent.cc: the
// command still exists and says what is missing, and the tool's other files
// compile with the same flags whether or not simavr is installed, so
// installing it later (as `make test` does after `make demo`) rebuilds this
// library alone.
#include <CLI/CLI.hpp>
#include <iostream>

#include "bench/commands.h"

namespace roomfix {

void AddBenchFirmwareCommand(CLI::App* bench, int* exit_code) {
  auto* cmd = bench->add_subcommand(
      "firmware", "The firmware-in-the-loop simulator's speed (not in this build)");
  cmd->allow_extras();
  cmd->callback([exit_code] {
    std::cerr << "roomfix_bench firmware: this roomfix_bench was built without simavr; "
                 "apt-get install libsimavr-dev simavr gcc-avr avr-libc, then rebuild\n";
    *exit_code = 1;
  });
}

}  // namespace roomfix
