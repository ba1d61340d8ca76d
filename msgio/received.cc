#include "msgio/received.h"

#include <cmath>

#include "msgio/message_conversions.h"
#include "msgio/time_limits.h"

namespace roomfix {
namespace {

bool Refuse(InputProblem kind, std::string why, std::string* error, InputProblem* problem) {
  *problem = kind;
  *error = std::move(why);
  return false;
}

// Infinity anywhere, or (unless lost) NaN in the position or its covariance.
bool PoseIsFinite(const pose2d_t& msg) {
  bool infinite = std::isinf(msg.x_m) || std::isinf(msg.y_m) || std::isinf(msg.z_m) ||
                  std::isinf(msg.heading_rad);
  for (const auto& row : msg.covariance) {
    for (double v : row) infinite = infinite || std::isinf(v);
  }
  if (infinite) return false;
  if (msg.status == pose2d_t::STATUS_LOST) return true;
  return std::isfinite(msg.x_m) && std::isfinite(msg.y_m) && std::isfinite(msg.covariance[0][0]) &&
         std::isfinite(msg.covariance[0][1]) && std::isfinite(msg.covariance[1][0]) &&
         std::isfinite(msg.covariance[1][1]);
}

}  // namespace

const char* InputProblemCounter(InputProblem problem) {
  switch (problem) {
    case InputProblem::kNone:
      return "";
    case InputProblem::kUtimeOutOfRange:
      return "utime_out_of_range";
    case InputProblem::kUnknownRobot:
      return "unknown_robot";
    case InputProblem::kNonFinite:
      return "non_finite";
    case InputProblem::kTooManyRanges:
      return "too_many_ranges";
    case InputProblem::kNegativeExpected:
      return "negative_expected";
    case InputProblem::kUnknownReceiver:
      return "unknown_receiver";
  }
  return "";
}

bool ReceivePose(const pose2d_t& msg, const Site& site, int64_t recv_utime, Pose2d* pose,
                 std::string* error, InputProblem* problem) {
  if (!UtimeNear(msg.utime, recv_utime)) {
    return Refuse(InputProblem::kUtimeOutOfRange,
                  "measurement time " + std::to_string(msg.utime) +
                      " us is more than an hour before or 0.1 s after its receive time",
                  error, problem);
  }
  if (site.FindRobot(msg.robot_id) == nullptr) {
    return Refuse(InputProblem::kUnknownRobot, "the site file does not list this robot", error,
                  problem);
  }
  if (!PoseIsFinite(msg)) {
    return Refuse(InputProblem::kNonFinite,
                  "a position, covariance or heading that is not a finite number", error, problem);
  }
  *pose = FromMessage(msg);
  *problem = InputProblem::kNone;
  return true;
}

bool CheckRangeSet(const range_set_t& set, const Site& site, int64_t recv_utime, std::string* error,
                   InputProblem* problem) {
  if (!UtimeNear(set.utime, recv_utime)) {
    return Refuse(InputProblem::kUtimeOutOfRange,
                  "firing time " + std::to_string(set.utime) +
                      " us is more than an hour before or 0.1 s after its receive time " +
                      std::to_string(recv_utime) + " us",
                  error, problem);
  }
  if (!std::isfinite(set.speed_of_sound_mps) || !std::isfinite(set.temperature_c)) {
    return Refuse(InputProblem::kNonFinite, "speed of sound or temperature is not a finite number",
                  error, problem);
  }
  if (set.ranges.size() > site.receivers.size()) {
    return Refuse(InputProblem::kTooManyRanges,
                  std::to_string(set.ranges.size()) + " ranges, but the site has " +
                      std::to_string(site.receivers.size()) + " receivers",
                  error, problem);
  }
  if (set.num_expected < 0) {
    return Refuse(InputProblem::kNegativeExpected,
                  "num_expected " + std::to_string(set.num_expected) + " is negative", error,
                  problem);
  }
  *problem = InputProblem::kNone;
  return true;
}

const Receiver* CheckRange(const range_t& range, const Site& site, std::string* error,
                           InputProblem* problem) {
  if (!std::isfinite(range.receiver_position_m[0]) ||
      !std::isfinite(range.receiver_position_m[1]) ||
      !std::isfinite(range.receiver_position_m[2]) || !std::isfinite(range.range_m) ||
      !std::isfinite(range.time_of_flight_us)) {
    Refuse(InputProblem::kNonFinite,
           "receiver " + std::to_string(range.receiver_id) +
               ": a range, time of flight or position that is not a finite number",
           error, problem);
    return nullptr;
  }
  const Receiver* receiver = site.FindReceiver(range.receiver_id);
  if (receiver == nullptr) {
    Refuse(InputProblem::kUnknownReceiver,
           "receiver " + std::to_string(range.receiver_id) + ", which the site file does not list",
           error, problem);
    return nullptr;
  }
  *problem = InputProblem::kNone;
  return receiver;
}

}  // namespace roomfix
