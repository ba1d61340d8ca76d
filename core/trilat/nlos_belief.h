#ifndef ROOMFIX_CORE_TRILAT_NLOS_BELIEF_H_
#define ROOMFIX_CORE_TRILAT_NLOS_BELIEF_H_

#include <cstdint>
#include <string>
#include <vector>

#include "core/trilat/trilateration.h"

namespace roomfix::trilat {

struct NlosBeliefOptions {
  // How long a receiver stays hidden, s: the belief relaxes towards
  // base_probability with this time constant. A robot at 0.3 m/s takes
  // seconds to cross a pillar's shadow (the pillar demo hides it from
  // receiver 3 for about two thirds of a 14 s lap), while a person walking
  // through a path blocks it for about half a second; 2 s keeps a blocked
  // receiver suspected across a 10 Hz beacon's next firings and a 1 Hz
  // one's next firing, and lets go of it within a few seconds of silence.
  double persistence_s = 2.0;
  // The share of a receiver's ranges that are echoes with no history to go
  // by (the simulator's random NLOS is 5 %).
  double base_probability = 0.05;
  // A receiver is suspected (Suspected) while its probability is above this.
  double suspect_above = 0.5;
  // An echo's excess over the direct path is taken uniform on [0, this]:
  // the room's diagonal (the node sets it from the site).
  double max_excess_m = 5.0;
  // The range noise, for the likelihood of a range on its direct path.
  double range_sigma_m = 0.02;

  bool IsValid(std::string* error) const;
};

// Per receiver, the probability that one beacon's range to it is an echo
// (non-line-of-sight), tracked across firings: a two-state hidden Markov
// model whose state (line of sight or not) persists, observed through each
// fix's range excesses. Pure: time is the firing time of the range set, so
// a replay gives the same beliefs.
//
// Prediction to time t from the last update at t_k:
//   p(t) = b + (p_k - b) exp(-|t - t_k| / persistence_s),   b = base_probability
// (|.|: a set the radio reordered is as near in time either way).
// Update with a range whose excess over the fix is e (e = d - |fix - a| -
// the fix's shared level), the fix's own uncertainty added to the noise,
// s^2 = sigma^2 + cov_xx + cov_yy:
//   line of sight:  N(e; 0, s)
//   echo:           (Phi(e / s) - Phi((e - L) / s)) / L   (uniform [0, L] plus noise)
//   p' = p L_echo / (p L_echo + (1 - p) L_los), kept within [1e-4, 1 - 1e-4]
// so that neither state becomes certain and a receiver always recovers.
// The echo likelihood is one-sided: a range that is short or on its path
// clears the suspicion within one firing (at 2 cm noise, p 0.95 -> 0.09),
// while a range long by more than a few sigma makes it near certain.
//
// Observe only learns from a fix that can judge its ranges: positioned,
// converged, consistent, over-determined and of good geometry, and only
// from the ranges it used or excluded as echoes. A set delivered late
// updates a receiver's probability but never moves its time back. A receiver
// missing from a set (it heard nothing, which a blocked receiver often
// does) is left to the prediction. Memory: one entry per receiver id seen,
// bounded by the caller (trilat_proc passes only the site's receivers).
class NlosBelief {
 public:
  explicit NlosBelief(const NlosBeliefOptions& options = {}) : options_(options) {}

  // The probability that receiver_id's range at utime is an echo.
  double Probability(int receiver_id, int64_t utime) const;
  // The receivers suspected at utime with their probabilities, ascending
  // ids (for Solve). The reference stays valid until the next call.
  const std::vector<NlosSuspicion>& Suspected(int64_t utime);
  // Learns from the fix that `ranges` (the set as solved) gave at utime.
  // False when the fix could not judge its ranges (nothing learnt).
  bool Observe(int64_t utime, const std::vector<RangeMeasurement>& ranges, const Fix& fix);
  void Clear() { states_.clear(); }
  size_t receivers() const { return states_.size(); }

 private:
  struct State {
    int receiver_id = 0;
    double probability = 0.0;
    int64_t utime = 0;
  };
  double Predict(const State& state, int64_t utime) const;
  State* Find(int receiver_id);
  const State* Find(int receiver_id) const;

  NlosBeliefOptions options_;
  std::vector<State> states_;
  std::vector<NlosSuspicion> suspected_;
};

}  // namespace roomfix::trilat

#endif  // ROOMFIX_CORE_TRILAT_NLOS_BELIEF_H_
