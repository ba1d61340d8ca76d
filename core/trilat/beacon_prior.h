#ifndef ROOMFIX_CORE_TRILAT_BEACON_PRIOR_H_
#define ROOMFIX_CORE_TRILAT_BEACON_PRIOR_H_

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "core/trilat/trilateration.h"

namespace roomfix::trilat {

struct BeaconPriorOptions {
  // The robot's top speed (the site's robots[].max_speed_mps).
  double max_speed_mps = 1.0;
  // A fix's own error, added to the distance the robot can have driven: 10 cm
  // is five range sigmas of the default 2 cm, more than any fix the
  // consensus admits is off without a reflection.
  double margin_m = 0.1;
  // A prior older than this is none: by then the robot can be anywhere a
  // fix could say, and the ranges stand alone.
  double max_age_s = 1.0;
  // This many fixes in a row that agree with each other (within the same
  // speed bound) but not with the prior replace it: the robot was lifted and
  // put down elsewhere, or the prior followed a wrong fix.
  int reset_after = 3;

  bool IsValid(std::string* error) const;
};

// The temporal prior of one beacon: where it can be at a firing, from its
// recent fixes and the robot's top speed. It identifies and never
// fabricates: Solve() uses it only to choose among range subsets, so every
// published position comes from ranges.
//
// Time is an argument (the firing time of the range set), so a replay gives
// the same fixes. The prior at time t is the last followed fix p_k at t_k and
// the radius margin_m + max_speed_mps |t - t_k| (|.|: a range set that the
// radio reordered is a little older than the last fix, and its beacon was as
// near), or none when |t - t_k| > max_age_s.
//
// Observe() feeds each fix back (a fix with inconsistent ranges, poor
// geometry or no convergence is ignored):
//  - within the radius: followed (the prior moves to the fix);
//  - no prior (none yet, or expired): a checked fix (over-determined and
//    consistent) starts one; an unchecked fix does not;
//  - beyond the radius: a checked fix is a reset candidate; reset_after
//    candidates in a row, each within the speed bound of the one before, make
//    the last of them the prior. Unchecked fixes never reset it.
class BeaconPrior {
 public:
  enum class Outcome { kNone, kStarted, kFollowed, kDisagreed, kReset };

  explicit BeaconPrior(const BeaconPriorOptions& options = {}) : options_(options) {}

  // The prior at `utime`, or nullptr when there is none. The pointer stays
  // valid until the next call.
  const PositionPrior* At(int64_t utime);
  Outcome Observe(int64_t utime, const Fix& fix);
  void Clear();
  bool has_prior() const { return has_prior_; }

 private:
  struct Candidate {
    int64_t utime;
    Eigen::Vector3d position_m;
  };
  double Radius(int64_t from_utime, int64_t to_utime) const;
  bool Usable(int64_t utime) const;

  BeaconPriorOptions options_;
  bool has_prior_ = false;
  int64_t utime_ = 0;
  Eigen::Vector3d position_m_ = Eigen::Vector3d::Zero();
  std::vector<Candidate> candidates_;
  PositionPrior prior_;
};

const char* BeaconPriorOutcomeName(BeaconPrior::Outcome outcome);

}  // namespace roomfix::trilat

#endif  // ROOMFIX_CORE_TRILAT_BEACON_PRIOR_H_
