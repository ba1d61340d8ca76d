#ifndef ROOMFIX_TESTS_TESTING_EXACT_RANGES_H_
#define ROOMFIX_TESTS_TESTING_EXACT_RANGES_H_

#include <Eigen/Core>
#include <vector>

#include "core/trilat/trilateration.h"

namespace roomfix::testing {

// The noiseless range from each receiver to the beacon, receiver ids 1..n
// in the order given: the solver tests' starting point, to which each test
// adds its own errors.
inline std::vector<trilat::RangeMeasurement> ExactRanges(
    const std::vector<Eigen::Vector3d>& receivers, const Eigen::Vector3d& beacon) {
  std::vector<trilat::RangeMeasurement> out;
  for (size_t i = 0; i < receivers.size(); ++i) {
    out.push_back({static_cast<int>(i) + 1, receivers[i], (receivers[i] - beacon).norm()});
  }
  return out;
}

}  // namespace roomfix::testing

#endif  // ROOMFIX_TESTS_TESTING_EXACT_RANGES_H_
