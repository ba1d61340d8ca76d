#ifndef ROOMFIX_CORE_TRILAT_NLOS_MODEL_H_
#define ROOMFIX_CORE_TRILAT_NLOS_MODEL_H_

#include <cmath>

namespace roomfix::trilat {

// The two models of a range's excess e over its direct path (m) that the
// NLOS belief tracks and the robust solver weighs with, in one place:
//  - on its direct path, Gaussian noise of standard deviation sigma:
//      N(e; 0, sigma);
//  - an echo, whose detour is taken uniform on [0, L] (L the room's
//    diagonal: the first-order echoes of docs/trilateration.md, "Obstacles
//    and non-line-of-sight", are longer than the direct path by anything up
//    to that), plus the same noise:
//      U(e) = (Phi(e / sigma) - Phi((e - L) / sigma)) / L.
// U is one-sided: a range shorter than its path by a few sigma is not an
// echo. Both are densities per metre.
inline double LineOfSightLikelihood(double e, double sigma) {
  return std::exp(-0.5 * (e / sigma) * (e / sigma)) / (sigma * std::sqrt(2.0 * M_PI));
}

inline double EchoLikelihood(double e, double sigma, double span_m) {
  const double k = 1.0 / (sigma * std::sqrt(2.0));
  // Phi(x) = erfc(-x / sqrt 2) / 2.
  return 0.5 * (std::erfc(-e * k) - std::erfc(-(e - span_m) * k)) / span_m;
}

}  // namespace roomfix::trilat

#endif  // ROOMFIX_CORE_TRILAT_NLOS_MODEL_H_
