#include "core/trilat/beacon_prior.h"

#include <cmath>
#include <cstdlib>

namespace roomfix::trilat {
namespace {

double SecondsBetween(int64_t a_utime, int64_t b_utime) {
  // Saturation is not needed: callers keep times within an hour of the
  // receive clock (msgio/time_limits.h), so the difference fits.
  return std::abs(static_cast<double>(b_utime) - static_cast<double>(a_utime)) * 1e-6;
}

}  // namespace

bool BeaconPriorOptions::IsValid(std::string* error) const {
  auto fail = [&](const char* what) {
    if (error != nullptr) *error = what;
    return false;
  };
  if (!(max_speed_mps > 0.0) || !std::isfinite(max_speed_mps)) {
    return fail("max_speed_mps must be positive");
  }
  if (!(margin_m > 0.0) || !std::isfinite(margin_m)) return fail("margin_m must be positive");
  if (!(max_age_s > 0.0) || !std::isfinite(max_age_s)) return fail("max_age_s must be positive");
  if (reset_after < 1) return fail("reset_after must be at least 1");
  return true;
}

double BeaconPrior::Radius(int64_t from_utime, int64_t to_utime) const {
  return options_.margin_m + options_.max_speed_mps * SecondsBetween(from_utime, to_utime);
}

bool BeaconPrior::Usable(int64_t utime) const {
  return has_prior_ && SecondsBetween(utime_, utime) <= options_.max_age_s;
}

const PositionPrior* BeaconPrior::At(int64_t utime) {
  if (!Usable(utime)) return nullptr;
  prior_.position_m = position_m_;
  prior_.radius_m = Radius(utime_, utime);
  return &prior_;
}

BeaconPrior::Outcome BeaconPrior::Observe(int64_t utime, const Fix& fix) {
  if (!fix.has_position() || !fix.position_m.allFinite()) return Outcome::kNone;
  const bool checked = IsCheckedFix(fix);
  auto adopt = [&] {
    has_prior_ = true;
    utime_ = utime;
    position_m_ = fix.position_m;
    candidates_.clear();
  };
  if (!Usable(utime)) {
    candidates_.clear();
    if (!checked) return Outcome::kNone;
    adopt();
    return Outcome::kStarted;
  }
  // A fix whose ranges disagree among themselves is followed by no one: a
  // prior drifting after bad fixes would stop identifying.
  constexpr uint32_t kNotFollowed =
      kInconsistentRanges | kPoorGeometry | kNotConverged | kConsensusBudgetExhausted;
  if ((fix.flags & kNotFollowed) != 0) return Outcome::kNone;
  if ((fix.position_m - position_m_).norm() <= Radius(utime_, utime)) {
    // A reordered, older set is used but does not move the prior back.
    if (utime >= utime_) adopt();
    return Outcome::kFollowed;
  }
  if (!checked) return Outcome::kDisagreed;
  if (!candidates_.empty()) {
    const Candidate& last = candidates_.back();
    if ((fix.position_m - last.position_m).norm() > Radius(last.utime, utime)) {
      candidates_.clear();
    }
  }
  candidates_.push_back({utime, fix.position_m});
  if (static_cast<int>(candidates_.size()) >= options_.reset_after) {
    adopt();
    return Outcome::kReset;
  }
  return Outcome::kDisagreed;
}

void BeaconPrior::Clear() {
  has_prior_ = false;
  candidates_.clear();
}

const char* BeaconPriorOutcomeName(BeaconPrior::Outcome outcome) {
  switch (outcome) {
    case BeaconPrior::Outcome::kNone:
      return "none";
    case BeaconPrior::Outcome::kStarted:
      return "prior_started";
    case BeaconPrior::Outcome::kFollowed:
      return "prior_followed";
    case BeaconPrior::Outcome::kDisagreed:
      return "prior_disagreed";
    case BeaconPrior::Outcome::kReset:
      return "prior_resets";
  }
  return "?";
}

}  // namespace roomfix::trilat
