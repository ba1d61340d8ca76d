#include <CLI/CLI.hpp>

#include "bench/bench_trilat.h"
#include "bench/commands.h"

namespace roomfix {

void AddBenchCommands(CLI::App* bench, int* exit_code) {
  auto* trilat = bench->add_subcommand(
      "trilat",
      "The reference paper's Monte Carlo experiment for Nelder-Mead, the default and the robust "
      "solver, and trilat_proc's node throughput");
  auto options = std::make_shared<BenchTrilatOptions>();
  trilat->add_option("--trials", options->trials, "Random beacon positions per scenario")
      ->capture_default_str();
  trilat
      ->add_option("--node-sets", options->node_sets,
                   "Range sets pushed through trilat_proc's node")
      ->capture_default_str();
  trilat->add_option("--seed", options->seed, "Random seed")->capture_default_str();
  trilat->add_flag("--json", options->json, "Print one JSON object instead of tables");
  trilat->callback([options, exit_code] { *exit_code = RunTrilatBench(*options); });
  AddBenchLoggerCommand(bench, exit_code);
  AddBenchRadioCommand(bench, exit_code);
  AddBenchViewerCommand(bench, exit_code);
  AddBenchCameraCommand(bench, exit_code);
  AddBenchReplayCommand(bench, exit_code);
  AddBenchCapacityCommand(bench, exit_code);
  AddBenchMicroCommand(bench, exit_code);
  AddBenchFirmwareCommand(bench, exit_code);
}

}  // namespace roomfix
