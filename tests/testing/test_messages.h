#ifndef ROOMFIX_TESTS_TESTING_TEST_MESSAGES_H_
#define ROOMFIX_TESTS_TESTING_TEST_MESSAGES_H_

#include <cmath>

#include "roomfix/pose2d_t.hpp"

namespace roomfix::testing {

// A fully populated pose for round-trip tests.
inline pose2d_t MakeTestPose(int64_t utime, int32_t robot_id, double x_m, double y_m) {
  pose2d_t p{};
  p.utime = utime;
  p.source = pose2d_t::SOURCE_ULTRASOUND;
  p.camera_id = -1;  // kNoCameraId (core/world/site.h): not a camera pose
  p.robot_id = robot_id;
  p.measurement_seq = utime / 100000;
  p.x_m = x_m;
  p.y_m = y_m;
  p.z_m = 1.3;
  p.heading_rad = NAN;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) p.covariance[r][c] = (r == c) ? 1e-4 : 0.0;
  }
  p.residual_m = 0.01;
  p.num_measurements = 4;
  p.status = pose2d_t::STATUS_OK;
  p.latency_us = 1500;
  return p;
}

}  // namespace roomfix::testing

#endif  // ROOMFIX_TESTS_TESTING_TEST_MESSAGES_H_
