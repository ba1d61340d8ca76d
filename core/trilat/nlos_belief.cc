#include "core/trilat/nlos_belief.h"

#include <algorithm>
#include <cmath>

#include "core/trilat/nlos_model.h"

namespace roomfix::trilat {
namespace {

// Neither state is ever certain, so one firing can always move the belief.
constexpr double kMinProbability = 1e-4;
constexpr double kMaxProbability = 1.0 - 1e-4;

}  // namespace

bool NlosBeliefOptions::IsValid(std::string* error) const {
  auto fail = [&](const char* what) {
    if (error != nullptr) *error = what;
    return false;
  };
  if (!(persistence_s > 0.0) || !std::isfinite(persistence_s)) {
    return fail("persistence_s must be positive");
  }
  if (!(base_probability > 0.0 && base_probability < 1.0)) {
    return fail("base_probability must be between 0 and 1");
  }
  if (!(suspect_above > 0.0 && suspect_above < 1.0)) {
    return fail("suspect_above must be between 0 and 1");
  }
  if (!(max_excess_m > 0.0) || !std::isfinite(max_excess_m)) {
    return fail("max_excess_m must be positive");
  }
  if (!(range_sigma_m > 0.0) || !std::isfinite(range_sigma_m)) {
    return fail("range_sigma_m must be positive");
  }
  return true;
}

double NlosBelief::Predict(const State& state, int64_t utime) const {
  // Callers keep times within an hour of the receive clock
  // (msgio/time_limits.h), so the difference is exact enough in a double.
  const double dt_s =
      std::abs(static_cast<double>(utime) - static_cast<double>(state.utime)) * 1e-6;
  const double b = options_.base_probability;
  return b + (state.probability - b) * std::exp(-dt_s / options_.persistence_s);
}

NlosBelief::State* NlosBelief::Find(int receiver_id) {
  for (State& s : states_) {
    if (s.receiver_id == receiver_id) return &s;
  }
  return nullptr;
}

const NlosBelief::State* NlosBelief::Find(int receiver_id) const {
  for (const State& s : states_) {
    if (s.receiver_id == receiver_id) return &s;
  }
  return nullptr;
}

double NlosBelief::Probability(int receiver_id, int64_t utime) const {
  const State* state = Find(receiver_id);
  return state == nullptr ? options_.base_probability : Predict(*state, utime);
}

const std::vector<NlosSuspicion>& NlosBelief::Suspected(int64_t utime) {
  suspected_.clear();
  for (const State& s : states_) {
    const double p = Predict(s, utime);
    if (p > options_.suspect_above) suspected_.push_back({s.receiver_id, p, options_.max_excess_m});
  }
  std::sort(
      suspected_.begin(), suspected_.end(),
      [](const NlosSuspicion& a, const NlosSuspicion& b) { return a.receiver_id < b.receiver_id; });
  return suspected_;
}

bool NlosBelief::Observe(int64_t utime, const std::vector<RangeMeasurement>& ranges,
                         const Fix& fix) {
  if (!IsCheckedFix(fix) || !fix.position_m.allFinite() || !fix.covariance_m2.allFinite()) {
    return false;
  }
  const double s2 = options_.range_sigma_m * options_.range_sigma_m + fix.covariance_m2(0, 0) +
                    fix.covariance_m2(1, 1);
  const double s = std::sqrt(s2);
  const double span = options_.max_excess_m;
  // Only ranges the fix judged: used, or excluded as an echo (a duplicate
  // receiver or an invalid range says nothing about the path).
  auto judged = [&fix](int id) {
    if (std::find(fix.used.begin(), fix.used.end(), id) != fix.used.end()) return true;
    for (const RejectedRange& r : fix.rejected) {
      if (r.receiver_id == id && r.reason == RangeRejection::kOutlier) return true;
    }
    return false;
  };
  for (const RangeMeasurement& range : ranges) {
    if (!std::isfinite(range.range_m) || !range.receiver_m.allFinite() ||
        !judged(range.receiver_id)) {
      continue;
    }
    const double e =
        range.range_m - (fix.position_m - range.receiver_m).norm() - fix.shared_level_m;
    const double los = LineOfSightLikelihood(e, s);
    const double echo = EchoLikelihood(e, s, span);
    State* state = Find(range.receiver_id);
    if (state == nullptr) {
      states_.push_back({range.receiver_id, options_.base_probability, utime});
      state = &states_.back();
    }
    const double prior = Predict(*state, utime);
    double posterior = prior * echo / (prior * echo + (1.0 - prior) * los);
    // Both likelihoods underflow only far out: an echo longer than the span
    // (certainly not the direct path) or a range far too short (certainly
    // not an echo).
    if (!std::isfinite(posterior)) posterior = e > 0.0 ? kMaxProbability : kMinProbability;
    state->probability = std::clamp(posterior, kMinProbability, kMaxProbability);
    // A set the radio delivered late updates the belief but never moves its
    // clock back: the next firing's relaxation runs from the newest time.
    state->utime = std::max(state->utime, utime);
  }
  return true;
}

}  // namespace roomfix::trilat
