#include "core/world/ultrasound_model.h"

#include <algorithm>
#include <cmath>
#include <optional>

namespace roomfix {

double SpeedOfSound(double temperature_c) { return 331.3 + 0.606 * temperature_c; }

bool UltrasoundNoise::IsValid(std::string* error) const {
  auto fail = [&](const char* what) {
    *error = what;
    return false;
  };
  if (!(sigma_m >= 0.0)) return fail("sigma_m must not be negative");
  if (!(nlos_probability >= 0.0 && nlos_probability <= 1.0)) {
    return fail("nlos_probability must be in [0, 1]");
  }
  if (!(dropout_probability >= 0.0 && dropout_probability <= 1.0)) {
    return fail("dropout_probability must be in [0, 1]");
  }
  if (!(nlos_min_m >= 0.0 && nlos_max_m >= nlos_min_m)) {
    return fail("need 0 <= nlos_min_m <= nlos_max_m");
  }
  return true;
}

std::vector<SimulatedRange> SimulateRangesAt(const Site& site, double t_s,
                                             const std::array<double, 3>& beacon_m,
                                             double temperature_c, const UltrasoundNoise& noise,
                                             std::mt19937_64* rng) {
  std::normal_distribution<double> gauss(0.0, 1.0);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const double c = SpeedOfSound(temperature_c);
  std::optional<AcousticScene> scene;
  if (noise.geometric_nlos && !site.obstacles.empty()) scene.emplace(site, temperature_c);
  std::vector<SimulatedRange> out;
  for (const Receiver& r : site.receivers) {
    // Draw every variate for every receiver, so that switching one fault on
    // does not reshuffle the others' noise.
    const double g = gauss(*rng);
    const double nlos_draw = unit(*rng);
    const double nlos_len = unit(*rng);
    const double drop_draw = unit(*rng);
    if (drop_draw < noise.dropout_probability) continue;
    SimulatedRange s;
    double path = 0.0;
    if (scene) {
      const AudiblePath heard = scene->ShortestAudiblePath(t_s, beacon_m, r.position_m);
      if (heard.kind == AudiblePath::Kind::kNone) continue;
      s.path = heard.kind;
      s.detour_m = heard.length_m - heard.direct_m;
      path = heard.length_m;
    } else {
      const double dx = r.position_m[0] - beacon_m[0];
      const double dy = r.position_m[1] - beacon_m[1];
      const double dz = r.position_m[2] - beacon_m[2];
      path = std::sqrt(dx * dx + dy * dy + dz * dz);
    }
    path += noise.sigma_m * g;
    if (nlos_draw < noise.nlos_probability) {
      path += noise.nlos_min_m + (noise.nlos_max_m - noise.nlos_min_m) * nlos_len;
      s.random_nlos = true;
    }
    path = std::max(0.0, path);
    s.receiver_id = r.id;
    s.measured_m = path + r.range_offset_m;
    s.time_of_flight_s = path / c;
    out.push_back(s);
  }
  return out;
}

std::vector<SimulatedRange> SimulateRanges(const Site& site, const std::array<double, 3>& beacon_m,
                                           double temperature_c, const UltrasoundNoise& noise,
                                           std::mt19937_64* rng) {
  return SimulateRangesAt(site, 0.0, beacon_m, temperature_c, noise, rng);
}

}  // namespace roomfix
