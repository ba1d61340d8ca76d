#include "trilat_proc/trilat_options.h"

namespace roomfix {

void AddTrilatFlags(CLI::App* app, const std::string& prefix, TrilatNodeOptions* options,
                    TrilatOptions* flags) {
  const auto name = [&](const std::string& flag) { return "--" + prefix + flag; };
  app->add_option(name("method"), flags->method,
                  "nelder-mead (the reference), default, robust (consensus), or cauchy "
                  "(M-estimator)")
      ->capture_default_str()
      ->check(CLI::IsMember({"nelder-mead", "default", "robust", "cauchy"}));
  app->add_option(name("dimension"), flags->dimension,
                  "fixed-height (2D, beacon height from the site file), planar, or 3d")
      ->capture_default_str()
      ->check(CLI::IsMember({"fixed-height", "planar", "3d"}));
  app->add_option(name("range-sigma"), options->solver.range_sigma_m,
                  "Range standard deviation for the covariance, m")
      ->capture_default_str();
  app->add_option(name("outlier-threshold"), options->solver.outlier_threshold_m,
                  "Robust mode: residual above which a range is an outlier, m (0: 4 sigma)")
      ->capture_default_str();
  app->add_option(name("warm-start-max-age"), options->warm_start_max_age_s,
                  "Seed a solve with the beacon's previous fix when it is at most this old, s")
      ->capture_default_str();
  app->add_option(name("forget-after"), options->forget_after_s,
                  "Forget a beacon's warm-start state after this long without its ranges, s")
      ->capture_default_str();
  app->add_option(name("unknown-beacon-height"), options->unknown_beacon_height_m,
                  "Height for beacons missing from the site file, m (default: refuse them)");
  app->add_flag(name("no-prior"), flags->no_prior,
                "Solve each range set alone, without the beacon's temporal prior "
                "(docs/trilateration.md, \"Temporal prior\")");
  app->add_flag(name("no-nlos-belief"), flags->no_nlos_belief,
                "Solve without the per-receiver NLOS belief (docs/trilateration.md, "
                "\"NLOS belief\")");
  app->add_option(name("nlos-persistence"), options->nlos_belief.persistence_s,
                  "How long a hidden receiver stays suspected: the belief's time constant, s")
      ->capture_default_str();
  app->add_option(name("merge-deadline"), options->merge_deadline_s,
                  "Solve a firing's parts from several radios' bridges with what came this "
                  "long after the first part, s")
      ->capture_default_str();
  app->add_option(name("prior-reset-after"), options->prior.reset_after,
                  "Replace a beacon's prior after this many consistent fixes that disagree with it")
      ->capture_default_str();
}

bool ApplyTrilatFlags(const TrilatOptions& flags, TrilatNodeOptions* options, std::string* error) {
  if (!trilat::ParseMethod(flags.method, &options->solver.method)) {
    *error = "unknown method '" + flags.method + "'";
    return false;
  }
  if (flags.dimension == "3d") {
    options->solver.dimension = trilat::Dimension::k3D;
  } else if (flags.dimension == "planar") {
    options->solver.dimension = trilat::Dimension::kPlanar2D;
  } else if (flags.dimension == "fixed-height") {
    options->solver.dimension = trilat::Dimension::kFixedHeight2D;
  } else {
    *error = "unknown dimension '" + flags.dimension + "'";
    return false;
  }
  options->use_prior = !flags.no_prior;
  options->use_nlos_belief = !flags.no_nlos_belief;
  return true;
}

}  // namespace roomfix
