#include "bench/bench_trilat.h"

#include <fmt/format.h>

#include <Eigen/LU>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <nlohmann/json.hpp>
#include <random>
#include <string>
#include <vector>

#include "core/analysis/track_error.h"
#include "core/trilat/beacon_prior.h"
#include "core/trilat/nlos_belief.h"
#include "core/trilat/trilateration.h"
#include "core/world/site.h"
#include "core/world/ultrasound_model.h"
#include "msgio/bus.h"
#include "msgio/process.h"
#include "msgio/radio_conversions.h"
#include "roomfix/pose2d_t.hpp"
#include "roomfix/range_set_t.hpp"
#include "trilat_proc/trilat_node.h"

namespace roomfix {
namespace {

using nlohmann::json;
using trilat::Method;

// The paper's room: receivers at the corners of a 4 x 3 m rectangle at 2.5 m
// (six: plus the middles of the long walls), beacon at 1.3 m anywhere on the
// floor at least 0.2 m from the walls.
constexpr double kReceiverHeight_m = 2.5;
constexpr double kBeaconHeight_m = 1.3;

struct Scenario {
  std::string name;
  std::string description;
  std::vector<Eigen::Vector3d> receivers;
  // Gaussian sigma, or the half-width of uniform noise when `uniform`.
  double noise_m;
  bool uniform = false;
  double nlos_fraction = 0.0;
  // The beacon drives a circle (r 0.8 m around the room's centre at
  // 0.3 rad/s, 0.24 m/s) fired at 10 Hz, so trials are a track and the
  // temporal prior can be used; otherwise each trial is anywhere.
  bool moving = false;
  // The pillar demo (config/sites/demo_room_pillar.yaml's geometry): the
  // beacon on the reference circle at 10 Hz beside a 0.5 m pillar, ranges
  // from the simulator's geometric NLOS (core/world/acoustic_paths.h):
  // receiver 3 reads an echo, or nothing, for much of each lap.
  bool pillar = false;
};

// Firing period of the moving scenario.
constexpr int64_t kFiringPeriod_us = 100000;
// The pillar scenario's room is the demo room's 4 x 3 m floor. A fix further
// outside it than trilat_proc's margin (0.2 m) is published lost there
// (outside_room), so in that scenario, whose trials are a room's geometry
// and not a solver exercise, it counts as lost here: the mirror ghost (receivers 1 and 2 on the
// wall y = 0 read the same for the beacon and its mirror image across that wall, and receivers 3
// and 4, both hidden, hear the echo off it: four ranges that agree on a point 1.7 m outside) is no
// published position.
constexpr double kRoomX_m = 4.0, kRoomY_m = 3.0, kOutsideRoomMargin_m = 0.2;

struct Trial {
  Eigen::Vector3d truth;
  std::vector<trilat::RangeMeasurement> ranges;
  double crlb_m;
};

struct MethodResult {
  double median_ns, p99_ns, rmse_m, p95_m, rmse_over_crlb, speedup;
  int failures;
  // Honesty: the 99th-percentile error, the worst fix flagged ok, and the
  // share of fixes whose error lies inside their own 95 % ellipse.
  double p99_m, worst_ok_m, inside_95;
};

// The demo room with the pillar of config/sites/demo_room_pillar.yaml (kept
// here so that the benchmark needs no file), and the reference circle.
Site PillarSite() {
  const std::string text =
      "name: bench_pillar\nroom: {size_m: [4, 3], height_m: 3.3}\nreceivers:\n"
      "  - {id: 1, address: '0x0000000000000001', position_m: [0, 0, 2.5]}\n"
      "  - {id: 2, address: '0x0000000000000002', position_m: [4, 0, 2.5]}\n"
      "  - {id: 3, address: '0x0000000000000003', position_m: [4, 3, 2.5]}\n"
      "  - {id: 4, address: '0x0000000000000004', position_m: [0, 3, 2.5]}\n"
      "obstacles:\n"
      "  - {type: cylinder, name: pillar, centre_m: [2.58, 1.98], radius_m: 0.25, top_m: 3.3}\n"
      "beacons:\n  - {id: 1, address: '0x0000000000000010', height_m: 1.3}\n"
      "robots:\n  - {id: 1, beacon_id: 1}\n"
      "simulation:\n  robots:\n    - {robot_id: 1, trajectory: {type: reference_circle}}\n";
  Site site;
  std::string error;
  if (!ParseSite(text, "bench_pillar.yaml", "", &site, &error)) {
    fmt::print(stderr, "roomfix_bench trilat: pillar site: {}\n", error.c_str());
  }
  return site;
}

std::vector<Trial> MakePillarTrials(const Scenario& s, int n, std::mt19937_64* rng) {
  const Site site = PillarSite();
  UltrasoundNoise noise;
  noise.sigma_m = s.noise_m;
  std::vector<Trial> trials(n);
  std::vector<Eigen::Vector3d> heard;
  for (size_t k = 0; k < trials.size(); ++k) {
    Trial& t = trials[k];
    const double t_s = static_cast<double>(k) * kFiringPeriod_us * 1e-6;
    const GroundTruthPose p = site.simulation.robots[0].trajectory->PoseAt(t_s);
    t.truth = {p.x_m, p.y_m, kBeaconHeight_m};
    heard.clear();
    for (const SimulatedRange& r :
         SimulateRangesAt(site, t_s, {p.x_m, p.y_m, kBeaconHeight_m}, 20.0, noise, rng)) {
      const auto& a = site.FindReceiver(r.receiver_id)->position_m;
      t.ranges.push_back({r.receiver_id, {a[0], a[1], a[2]}, r.measured_m});
      heard.push_back({a[0], a[1], a[2]});
    }
    t.crlb_m = trilat::CramerRaoRmse(heard, t.truth, s.noise_m, trilat::Dimension::kFixedHeight2D);
  }
  return trials;
}

// Standard deviation of the noise, which is what the Cramer-Rao bound and
// the solver's covariance take (uniform on [-a, a] has a / sqrt(3)).
double Sigma(const Scenario& s) { return s.uniform ? s.noise_m / std::sqrt(3.0) : s.noise_m; }

std::vector<Trial> MakeTrials(const Scenario& s, int n, std::mt19937_64* rng) {
  if (s.pillar) return MakePillarTrials(s, n, rng);
  std::uniform_real_distribution<double> x(0.2, 3.8), y(0.2, 2.8), unit(0.0, 1.0);
  std::normal_distribution<double> gauss(0.0, 1.0);
  std::vector<Trial> trials(n);
  for (size_t k = 0; k < trials.size(); ++k) {
    Trial& t = trials[k];
    if (s.moving) {
      const double a = 0.3 * 0.1 * static_cast<double>(k);
      t.truth = {2.0 + 0.8 * std::cos(a), 1.5 + 0.8 * std::sin(a), kBeaconHeight_m};
    } else {
      t.truth = {x(*rng), y(*rng), kBeaconHeight_m};
    }
    for (size_t i = 0; i < s.receivers.size(); ++i) {
      double e = s.uniform ? s.noise_m * (2.0 * unit(*rng) - 1.0) : s.noise_m * gauss(*rng);
      if (unit(*rng) < s.nlos_fraction) e += 0.3 + 0.7 * unit(*rng);
      t.ranges.push_back(
          {static_cast<int>(i) + 1, s.receivers[i], (s.receivers[i] - t.truth).norm() + e});
    }
    t.crlb_m =
        trilat::CramerRaoRmse(s.receivers, t.truth, Sigma(s), trilat::Dimension::kFixedHeight2D);
  }
  return trials;
}

// With use_prior the trials are fed in order through a BeaconPrior, and
// with use_belief through an NlosBelief, as trilat_proc does per beacon;
// their cost is inside the timed region.
MethodResult RunMethod(const Scenario& s, const std::vector<Trial>& trials, Method method,
                       bool use_prior = false, bool use_belief = false) {
  trilat::SolverOptions options;
  options.method = method;
  options.dimension = trilat::Dimension::kFixedHeight2D;
  options.fixed_height_m = kBeaconHeight_m;
  options.range_sigma_m = Sigma(s);
  trilat::Fix fix;
  std::vector<double> times_ns, errors;
  times_ns.reserve(trials.size());
  errors.reserve(trials.size());
  double sum2 = 0.0, crlb2 = 0.0, worst_ok = 0.0;
  int failures = 0, with_cov = 0, inside = 0;
  // One untimed pass warms caches and GSL's workspace.
  for (size_t k = 0; k < std::min<size_t>(200, trials.size()); ++k) {
    trilat::Solve(trials[k].ranges, options, nullptr, &fix);
  }
  trilat::BeaconPrior prior;
  trilat::NlosBeliefOptions belief_options;
  belief_options.range_sigma_m = Sigma(s);
  trilat::NlosBelief belief(belief_options);
  for (size_t k = 0; k < trials.size(); ++k) {
    const Trial& t = trials[k];
    const int64_t utime = static_cast<int64_t>(k) * kFiringPeriod_us;
    const auto start = std::chrono::steady_clock::now();
    trilat::Solve(t.ranges, options, nullptr, use_prior ? prior.At(utime) : nullptr,
                  use_belief ? &belief.Suspected(utime) : nullptr, &fix);
    if (use_prior) prior.Observe(utime, fix);
    if (use_belief) belief.Observe(utime, t.ranges, fix);
    const auto stop = std::chrono::steady_clock::now();
    times_ns.push_back(std::chrono::duration<double, std::nano>(stop - start).count());
    const Eigen::Vector3d& q = fix.position_m;
    const bool outside = q.x() < -kOutsideRoomMargin_m || q.x() > kRoomX_m + kOutsideRoomMargin_m ||
                         q.y() < -kOutsideRoomMargin_m || q.y() > kRoomY_m + kOutsideRoomMargin_m;
    if (!fix.has_position() || (s.pillar && outside)) {
      ++failures;
      continue;
    }
    const Eigen::Vector2d err = (fix.position_m - t.truth).head<2>();
    const double e = err.norm();
    errors.push_back(e);
    if (fix.status == trilat::FixStatus::kOk) worst_ok = std::max(worst_ok, e);
    const Eigen::Matrix2d cov = fix.covariance_m2.topLeftCorner<2, 2>();
    if (cov.allFinite() && cov.determinant() > 0.0) {
      ++with_cov;
      // chi-square with 2 degrees of freedom at 95 %: 5.991.
      inside += err.dot(cov.inverse() * err) <= 5.991;
    }
    sum2 += e * e;
    crlb2 += t.crlb_m * t.crlb_m;
  }
  MethodResult r{};
  r.median_ns = analysis::Percentile(times_ns, 0.5);
  r.p99_ns = analysis::Percentile(times_ns, 0.99);
  r.rmse_m = std::sqrt(sum2 / errors.size());
  r.p95_m = analysis::Percentile(errors, 0.95);
  r.p99_m = analysis::Percentile(errors, 0.99);
  r.worst_ok_m = worst_ok;
  r.inside_95 = with_cov > 0 ? static_cast<double>(inside) / with_cov : 0.0;
  r.rmse_over_crlb = r.rmse_m / std::sqrt(crlb2 / errors.size());
  r.failures = failures;
  return r;
}

// trilat_proc's node on memq://: range sets published and handled in
// batches, as LCM would deliver them from the network.
json NodeThroughput(int n, uint64_t seed) {
  Site site;
  std::string error;
  const std::string yaml =
      "name: bench\nroom: {size_m: [4, 3], height_m: 3.3}\nreceivers:\n"
      "  - {id: 1, address: '0x01', position_m: [0, 0, 2.5]}\n"
      "  - {id: 2, address: '0x02', position_m: [4, 0, 2.5]}\n"
      "  - {id: 3, address: '0x03', position_m: [4, 3, 2.5]}\n"
      "  - {id: 4, address: '0x04', position_m: [0, 3, 2.5]}\n"
      "beacons:\n  - {id: 1, address: '0x10', height_m: 1.3}\nrobots:\n  - {id: 1, beacon_id: 1}\n";
  // Addresses need 16 hex digits.
  std::string text = yaml;
  for (const char* a : {"0x01'", "0x02'", "0x03'", "0x04'", "0x10'"}) {
    const std::string from(a);
    const std::string to = "0x00000000000000" + from.substr(2);
    text.replace(text.find(from), from.size(), to);
  }
  if (!ParseSite(text, "bench.yaml", "", &site, &error)) return {{"error", error}};
  auto bus = LcmBus::Create("memq://", &error);
  if (bus == nullptr) return {{"error", error}};
  TrilatNode node(site, bus.get(), TrilatNodeOptions(), 0);
  int64_t poses = 0;
  bus->Subscribe<pose2d_t>(kUltrasoundPoseChannel,
                           [&](const pose2d_t&, const MessageInfo&) { ++poses; });

  std::mt19937_64 rng(seed);
  UltrasoundNoise noise;
  noise.sigma_m = 0.02;
  std::vector<std::vector<uint8_t>> encoded;
  const int distinct = 1000;
  // Firing times on the host clock, as the bridge stamps them: trilat_proc
  // refuses a set more than an hour from its receive time.
  const int64_t first_utime = NowUtime() - int64_t{distinct} * 100000;
  for (int k = 0; k < distinct; ++k) {
    const double t = k * 0.1;
    const std::array<double, 3> p = {2.0 + std::cos(t), 1.5 + std::sin(t), 1.3};
    radio::AssembledSet set;
    set.fire_utime = first_utime + k * 100000;
    set.beacon_id = 1;
    set.firing_seq = k;
    set.num_expected = 4;
    for (const SimulatedRange& s : SimulateRanges(site, p, 20.0, noise, &rng)) {
      radio::AssembledRange r;
      r.receiver_id = s.receiver_id;
      const Receiver* rc = site.FindReceiver(s.receiver_id);
      for (int i = 0; i < 3; ++i) r.receiver_position_m[i] = rc->position_m[i];
      r.range_m = s.measured_m;
      set.ranges.push_back(r);
    }
    const range_set_t msg = RangeSetFromAssembled(set);
    std::vector<uint8_t> bytes(msg.getEncodedSize());
    msg.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
    encoded.push_back(bytes);
  }
  const int batch = 500;
  const auto start = std::chrono::steady_clock::now();
  for (int k = 0; k < n; k += batch) {
    for (int j = k; j < std::min(n, k + batch); ++j) {
      const auto& b = encoded[j % distinct];
      bus->PublishRaw(kRangesChannel, b.data(), static_cast<int>(b.size()));
    }
    while (bus->Handle(0) > 0) {
    }
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return {{"range_sets", n},
          {"poses", poses},
          {"seconds", seconds},
          {"range_sets_per_s", n / seconds},
          {"transport", "memq://"}};
}

}  // namespace

int RunTrilatBench(const BenchTrilatOptions& options) {
  const std::vector<Eigen::Vector3d> four = {{0, 0, kReceiverHeight_m},
                                             {4, 0, kReceiverHeight_m},
                                             {4, 3, kReceiverHeight_m},
                                             {0, 3, kReceiverHeight_m}};
  std::vector<Eigen::Vector3d> six = four;
  six.push_back({2, 0, kReceiverHeight_m});
  six.push_back({2, 3, kReceiverHeight_m});
  const std::vector<Scenario> scenarios = {
      {"4rx_gauss_2cm", "4 receivers, Gaussian noise sigma 2 cm", four, 0.02},
      {"4rx_gauss_5cm", "4 receivers, Gaussian noise sigma 5 cm", four, 0.05},
      {"4rx_uniform_10cm", "4 receivers, uniform noise +-10 cm (the paper's)", four, 0.10, true},
      {"6rx_gauss_2cm", "6 receivers, Gaussian noise sigma 2 cm", six, 0.02},
      {"6rx_gauss_2cm_nlos10", "6 receivers, sigma 2 cm, 10% non-line-of-sight +0.3..1.0 m", six,
       0.02, false, 0.10},
      {"4rx_moving_nlos5", "4 receivers, moving beacon, sigma 2 cm, 5% non-line-of-sight per range",
       four, 0.02, false, 0.05, true},
      {"4rx_pillar",
       "4 receivers, reference circle beside a 0.5 m pillar, sigma 2 cm, NLOS from geometry", four,
       0.02, false, 0.0, true, true},
  };
  struct MethodRow {
    Method method;
    const char* key;
    bool prior;
    bool belief;
  };
  // robust_prior: the robust solver with the temporal prior (trilat_proc
  // --no-nlos-belief, its previous default); robust_prior_belief: with the
  // NLOS belief too, trilat_proc's default. They run the same trials in
  // order, so only where they are a track (the moving scenarios: elsewhere
  // each trial is anywhere).
  const std::vector<MethodRow> all_methods = {{Method::kNelderMead, "nelder_mead", false, false},
                                              {Method::kDefault, "default", false, false},
                                              {Method::kRobust, "robust", false, false},
                                              {Method::kCauchy, "cauchy", false, false},
                                              {Method::kRobust, "robust_prior", true, false},
                                              {Method::kRobust, "robust_prior_belief", true, true}};

  json out;
  std::mt19937_64 rng(options.seed);
  for (const Scenario& s : scenarios) {
    std::vector<MethodRow> methods;
    for (const MethodRow& row : all_methods) {
      if (!row.prior || s.moving) methods.push_back(row);
    }
    const auto trials = MakeTrials(s, options.trials, &rng);
    json methods_json;
    std::vector<MethodResult> results;
    for (const MethodRow& row : methods) {
      results.push_back(RunMethod(s, trials, row.method, row.prior, row.belief));
    }
    for (size_t m = 0; m < methods.size(); ++m) {
      MethodResult& r = results[m];
      r.speedup = results[0].median_ns / r.median_ns;
      methods_json[methods[m].key] = {{"median_ns", r.median_ns},
                                      {"p99_ns", r.p99_ns},
                                      {"p99_over_median", r.p99_ns / r.median_ns},
                                      {"rmse_m", r.rmse_m},
                                      {"p95_m", r.p95_m},
                                      {"rmse_over_crlb", r.rmse_over_crlb},
                                      {"p99_m", r.p99_m},
                                      {"worst_ok_m", r.worst_ok_m},
                                      {"share_inside_95", r.inside_95},
                                      {"speedup_vs_nelder_mead", r.speedup},
                                      {"failures", r.failures}};
    }
    out["scenarios"][s.name] = {
        {"description", s.description}, {"trials", options.trials}, {"methods", methods_json}};
    if (!options.json) {
      fmt::print("\n{} ({} trials)\n", s.description.c_str(), options.trials);
      fmt::print("  {:<19} {:>10} {:>10} {:>9} {:>9} {:>9} {:>9} {:>9} {:>8} {:>11} {:>9} {:>6}\n",
                 "method", "median_ns", "p99_ns", "p99/med", "rmse_m", "p95_m", "p99_m", "worst_ok",
                 "in95", "rmse/crlb", "speedup", "lost");
      for (size_t m = 0; m < methods.size(); ++m) {
        const MethodResult& r = results[m];
        fmt::print(
            "  {:<19} {:10.0f} {:10.0f} {:9.2f} {:9.4f} {:9.4f} {:9.4f} {:9.4f} {:7.1f}% {:11.3f} "
            "{:8.1f}x {:6}\n",
            methods[m].key, r.median_ns, r.p99_ns, r.p99_ns / r.median_ns, r.rmse_m, r.p95_m,
            r.p99_m, r.worst_ok_m, 100.0 * r.inside_95, r.rmse_over_crlb, r.speedup, r.failures);
      }
    }
  }
  const auto& clean = out["scenarios"]["6rx_gauss_2cm"]["methods"];
  const auto& nlos = out["scenarios"]["6rx_gauss_2cm_nlos10"]["methods"];
  json outlier_ratio;
  for (const char* m : {"nelder_mead", "default", "robust", "cauchy"}) {
    outlier_ratio[m] = nlos[m]["p95_m"].get<double>() / clean[m]["p95_m"].get<double>();
  }
  out["p95_with_outliers_over_without"] = outlier_ratio;
  out["node"] = NodeThroughput(options.node_sets, options.seed);
  if (options.json) {
    std::cout << out.dump() << "\n";
  } else {
    fmt::print("\n95th-percentile error with 10% outliers / without (6 receivers):\n");
    for (const char* m : {"nelder_mead", "default", "robust", "cauchy"}) {
      fmt::print("  {:<12} {:.2f}\n", m, outlier_ratio[m].get<double>());
    }
    const json& node = out["node"];
    if (node.contains("error")) {
      fmt::print("\ntrilat_proc node: {}\n", node["error"].get<std::string>().c_str());
      return 1;
    }
    fmt::print("\ntrilat_proc node on memq://: {:.0f} range sets/s ({} sets, {:.3f} s, {} poses)\n",
               node["range_sets_per_s"].get<double>(), node["range_sets"].get<int>(),
               node["seconds"].get<double>(), node["poses"].get<long long>());
  }
  return 0;
}

}  // namespace roomfix
