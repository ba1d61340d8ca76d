#ifndef ROOMFIX_BENCH_COMMANDS_H_
#define ROOMFIX_BENCH_COMMANDS_H_

namespace CLI {
class App;
}

namespace roomfix {

// Each subcommand of `roomfix_bench` registers itself on the program's app
// and sets *exit_code from its callback. The benchmarks print figures and
// ratios against a baseline measured in the same run.

// Registers every benchmark below and `trilat` (bench_command.cc).
void AddBenchCommands(CLI::App* bench, int* exit_code);
// roomfix_bench logger (bench_logger.cc).
void AddBenchLoggerCommand(CLI::App* bench, int* exit_code);
// roomfix_bench radio (bench_radio.cc).
void AddBenchRadioCommand(CLI::App* bench, int* exit_code);
// roomfix_bench viewer (bench_viewer.cc).
void AddBenchViewerCommand(CLI::App* bench, int* exit_code);
// roomfix_bench camera (bench_camera.cc).
void AddBenchCameraCommand(CLI::App* bench, int* exit_code);
// roomfix_bench replay (bench_replay.cc).
void AddBenchReplayCommand(CLI::App* bench, int* exit_code);
// roomfix_bench capacity: cameras, range sets, robots and messages per core
// (bench_capacity.cc).
void AddBenchCapacityCommand(CLI::App* bench, int* exit_code);
// roomfix_bench micro (bench_micro.cc): Google Benchmark timings of the
// camera path's kernels against baselines in the same run; without Google
// Benchmark (bench_micro_absent.cc) a command that says it is missing.
void AddBenchMicroCommand(CLI::App* bench, int* exit_code);
// roomfix_bench firmware (bench_firmware.cc): the firmware-in-the-loop
// simulator's speed; without simavr (bench_firmware_absent.cc) a command
// that says it is missing.
void AddBenchFirmwareCommand(CLI::App* bench, int* exit_code);

}  // namespace roomfix

#endif  // ROOMFIX_BENCH_COMMANDS_H_
