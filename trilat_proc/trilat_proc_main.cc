// trilat_proc: range sets (RANGES) to ultrasonic poses (POSE_ULTRASOUND).
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <iostream>

#include "msgio/process.h"
#include "trilat_proc/trilat_node.h"

int main(int argc, char** argv) {
  roomfix::ProcessOptions process;
  roomfix::TrilatNodeOptions options;
  std::string method = "default";
  std::string dimension = "fixed-height";
  CLI::App app{"trilat_proc: trilaterates each range set on RANGES into a pose on POSE_ULTRASOUND"};
  roomfix::AddProcessFlags(&app, &process, /*config_required=*/true);
  app.add_option("--method", method,
                 "nelder-mead (the reference), default, robust (consensus), or cauchy "
                 "(M-estimator)")
      ->capture_default_str()
      ->check(CLI::IsMember({"nelder-mead", "default", "robust", "cauchy"}));
  app.add_option("--dimension", dimension,
                 "fixed-height (2D, beacon height from the site file), planar, or 3d")
      ->capture_default_str()
      ->check(CLI::IsMember({"fixed-height", "planar", "3d"}));
  app.add_option("--range-sigma", options.solver.range_sigma_m,
                 "Range standard deviation for the covariance, m")
      ->capture_default_str();
  app.add_option("--outlier-threshold", options.solver.outlier_threshold_m,
                 "Robust mode: residual above which a range is an outlier, m (0: 4 sigma)")
      ->capture_default_str();
  app.add_option("--warm-start-max-age", options.warm_start_max_age_s,
                 "Seed a solve with the beacon's previous fix when it is at most this old, s")
      ->capture_default_str();
  app.add_option("--forget-after", options.forget_after_s,
                 "Forget a beacon's warm-start state after this long without its ranges, s")
      ->capture_default_str();
  app.add_option("--unknown-beacon-height", options.unknown_beacon_height_m,
                 "Height for beacons missing from the site file, m (default: refuse them)");
  bool no_prior = false;
  app.add_flag("--no-prior", no_prior,
               "Solve each range set alone, without the beacon's temporal prior "
               "(docs/trilateration.md, \"Temporal prior\")");
  app.add_option("--prior-reset-after", options.prior.reset_after,
                 "Replace a beacon's prior after this many consistent fixes that disagree with it")
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  options.use_prior = !no_prior;

  roomfix::trilat::ParseMethod(method, &options.solver.method);
  options.solver.dimension = dimension == "3d"       ? roomfix::trilat::Dimension::k3D
                             : dimension == "planar" ? roomfix::trilat::Dimension::kPlanar2D
                                                     : roomfix::trilat::Dimension::kFixedHeight2D;
  std::string error;
  if (!options.IsValid(&error)) {
    std::cerr << "trilat_proc: " << error << "\n";
    return 1;
  }
  auto ctx = roomfix::StartProcess("trilat_proc", process, &error);
  if (ctx == nullptr) {
    std::cerr << "trilat_proc: " << error << "\n";
    return 1;
  }
  if (process.check) {
    std::cout << "trilat_proc: ok: " << method << " solver, " << dimension << ", "
              << ctx->site.receivers.size() << " receivers, " << ctx->site.beacons.size()
              << " beacons, on " << process.lcm_url << "\n";
    return 0;
  }
  roomfix::TrilatNode node(ctx->site, ctx->bus.get(), options, roomfix::NowUtime());
  spdlog::info("{} solver, {}; listening on {}", method, dimension, roomfix::kRangesChannel);
  const int rc = roomfix::RunLoop(ctx->bus.get(), [&](int64_t now) { node.Tick(now); }, {});
  node.Stop(roomfix::NowUtime());
  return rc;
}
