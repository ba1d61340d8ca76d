#ifndef ROOMFIX_CORE_WORLD_ULTRASOUND_MODEL_H_
#define ROOMFIX_CORE_WORLD_ULTRASOUND_MODEL_H_

#include <array>
#include <random>
#include <vector>

#include "core/world/acoustic_paths.h"
#include "core/world/site.h"

namespace roomfix {

// Speed of sound in air, m/s, from the temperature in degrees Celsius: the
// linearisation c = 331.3 + 0.606 T, good to about 0.1% between 0 and 40 C.
double SpeedOfSound(double temperature_c);

// How simulated ultrasonic ranges go wrong.
struct UltrasoundNoise {
  // Gaussian range noise, m.
  double sigma_m = 0.01;
  // Non-line-of-sight from the site's obstacles (core/world/acoustic_paths.h):
  // a receiver whose direct path is blocked measures the shortest audible
  // reflection, or nothing. No effect in a site without obstacles.
  bool geometric_nlos = true;
  // Probability that a range took a reflected, longer path (non-line of
  // sight) that the geometry does not explain (a person, a door, an open
  // window: the random NLOS of earlier versions), which adds a uniform
  // nlos_min_m..nlos_max_m, independently per range and per firing.
  double nlos_probability = 0.0;
  double nlos_min_m = 0.3;
  double nlos_max_m = 1.0;
  // Probability that a receiver does not hear a firing at all.
  double dropout_probability = 0.0;

  bool IsValid(std::string* error) const;
};

struct SimulatedRange {
  int receiver_id = 0;
  // The distance the sound travelled (true distance, noise, detours) plus
  // the receiver's calibrated range_offset_m: what its timer measures.
  double measured_m = 0.0;
  double time_of_flight_s = 0.0;
  // Which path the geometry gave (kDirect in a site without obstacles, or
  // with geometric_nlos off) and its detour over the direct segment, m.
  AudiblePath::Kind path = AudiblePath::Kind::kDirect;
  double detour_m = 0.0;
  // True when the random NLOS lengthened this range.
  bool random_nlos = false;
};

// What each receiver of the site measures for a beacon at `beacon_m` (room
// frame) at simulation time t_s (which places moving obstacles). Receivers
// that drop out, or that no audible path reaches, are absent from the
// result. Deterministic for a given generator state; the generator advances
// by the same draws whatever the geometry, so obstacles do not reshuffle
// the noise.
std::vector<SimulatedRange> SimulateRangesAt(const Site& site, double t_s,
                                             const std::array<double, 3>& beacon_m,
                                             double temperature_c, const UltrasoundNoise& noise,
                                             std::mt19937_64* rng);
// As SimulateRangesAt at t_s = 0 (fixed obstacles need no time).
std::vector<SimulatedRange> SimulateRanges(const Site& site, const std::array<double, 3>& beacon_m,
                                           double temperature_c, const UltrasoundNoise& noise,
                                           std::mt19937_64* rng);

}  // namespace roomfix

#endif  // ROOMFIX_CORE_WORLD_ULTRASOUND_MODEL_H_
