#ifndef ROOMFIX_MSGIO_RECEIVED_H_
#define ROOMFIX_MSGIO_RECEIVED_H_

// The checks a message from the bus passes before a node uses it, one
// function per received type, so that trilat_proc, fusion_proc, camera_proc
// and the viewer refuse the same things for the same reasons (they each had
// their own). DecodeChecked has already refused what cannot be decoded
// (wire_check.h); these refuse what decodes but cannot be used: a time far
// from the receive time (time_limits.h), an id the site does not list, an
// infinity, or NaN where the message has no "unknown". Each returns false
// with one line for STATUS's last_error in *error and the kind in *problem,
// decided here, so a node counts the kind (InputProblemCounter) without
// reading the text. What a node does about a refused message (drop it, drop
// one range, keep its last picture) stays the node's.

#include <cstdint>
#include <string>

#include "core/world/site.h"
#include "msgio/messages.h"
#include "roomfix/pose2d_t.hpp"
#include "roomfix/range_set_t.hpp"

namespace roomfix {

enum class InputProblem {
  kNone,
  kUtimeOutOfRange,   // utime outside UtimeNear of the receive time
  kUnknownRobot,      // a robot id the site does not list
  kNonFinite,         // an infinity, or NaN where a number is required
  kTooManyRanges,     // more ranges than the site has receivers
  kNegativeExpected,  // range_set_t.num_expected below 0
  kUnknownReceiver,   // a receiver id the site does not list
};

// The STATUS reject counter a node counts a problem under:
// "utime_out_of_range", "unknown_robot", "non_finite", "too_many_ranges",
// "negative_expected", "unknown_receiver" ("" for kNone).
const char* InputProblemCounter(InputProblem problem);

// A pose2d_t as a Pose2d, refused (in this order) when its utime is not near
// recv_utime, its robot is not the site's, or it holds an infinity, or,
// unless it is LOST, a NaN position or position covariance. NaN is
// "unknown" where the message allows it: heading and its covariances, z,
// and everything of a LOST pose. The source is not checked: fusion_proc
// takes it from the channel, the viewer from the message.
bool ReceivePose(const pose2d_t& msg, const Site& site, int64_t recv_utime, Pose2d* pose,
                 std::string* error, InputProblem* problem);

// The checks of a whole range_set_t, before any of its ranges is looked at
// (in this order): its firing time near recv_utime, a finite speed of sound
// and temperature, at most one range per site receiver (so the work a
// message costs is bounded by the site), num_expected not negative. The
// beacon is left to the node: trilat_proc may accept beacons the site does
// not list (TrilatNodeOptions::unknown_beacon_height_m).
bool CheckRangeSet(const range_set_t& set, const Site& site, int64_t recv_utime, std::string* error,
                   InputProblem* problem);

// One range of a set: its receiver in the site, or nullptr when the range,
// its time of flight or its receiver's position is not finite (kNonFinite,
// checked first) or the site does not list its receiver (kUnknownReceiver).
// The position the message carries is only a copy of the site's.
const Receiver* CheckRange(const range_t& range, const Site& site, std::string* error,
                           InputProblem* problem);

}  // namespace roomfix

#endif  // ROOMFIX_MSGIO_RECEIVED_H_
