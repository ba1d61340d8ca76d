#ifndef ROOMFIX_BENCH_BENCH_TRILAT_H_
#define ROOMFIX_BENCH_BENCH_TRILAT_H_

#include <cstdint>

namespace roomfix {

struct BenchTrilatOptions {
  int trials = 20000;
  int node_sets = 200000;
  uint64_t seed = 1;
  bool json = false;
};

// Runs every scenario for every method in this one process and prints the
// figures (or one JSON object). Returns the exit code.
int RunTrilatBench(const BenchTrilatOptions& options);

}  // namespace roomfix

#endif  // ROOMFIX_BENCH_BENCH_TRILAT_H_
