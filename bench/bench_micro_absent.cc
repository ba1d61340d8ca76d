// roomfix_bench micro in a build without Google Benchmark (libbenchmark-dev
// is a test package: `make demo` builds without it). The command still
// exists, so `roomfix_bench micro` says what is missing instead of CLI11's
// "unexpected argument", and the tool's other files compile with the same
// flags whether or not the library is installed: installing it later (as
// `make test` does after `make demo`) rebuilds this library alone.
#include <CLI/CLI.hpp>
#include <iostream>

#include "bench/commands.h"

namespace roomfix {

void AddBenchMicroCommand(CLI::App* bench, int* exit_code) {
  auto* cmd = bench->add_subcommand(
      "micro", "Google Benchmark timings of the camera path's kernels (not in this build)");
  cmd->allow_extras();
  cmd->callback([exit_code] {
    std::cerr << "roomfix_bench micro: this roomfix_bench was built without Google Benchmark; "
                 "apt-get install libbenchmark-dev, then rebuild (cmake picks it up)\n";
    *exit_code = 1;
  });
}

}  // namespace roomfix
