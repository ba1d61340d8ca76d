#include "core/trilat/trilateration.h"

#include <gsl/gsl_cdf.h>
#include <gsl/gsl_multimin.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <memory>
#include <sstream>

#include "core/trilat/nlos_model.h"
#include "core/world/gsl_errors.h"

namespace roomfix::trilat {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();
// Receivers closer than this to a common line (2D) are collinear.
constexpr double kCollinear_m = 0.01;
// Receivers whose out-of-plane spread is below this, or below this fraction
// of their in-plane spread, are treated as coplanar in 3D: the linear start
// cannot see the out-of-plane coordinate, and the mirror image fits as well.
constexpr double kCoplanar_m = 0.01;
constexpr double kCoplanarRatio = 0.05;
// Levenberg-Marquardt stops after a step shorter than this. With zero
// residuals Gauss-Newton converges quadratically, so the error after such a
// step is about its square (1e-12 m); with noisy ranges convergence is
// linear at a rate near residual / distance (a few percent), so what is left
// is a few percent of a micrometre, far below any range noise.
constexpr double kStepTolerance_m = 1e-6;
// Consensus subsets are solved only to decide which ranges to keep, against
// thresholds of centimetres; a tenth of a millimetre is plenty, and the chosen
// set is refined to kStepTolerance_m afterwards.
constexpr double kSubsetStepTolerance_m = 1e-4;
// Nelder-Mead stops when the simplex is smaller than this (GSL's "size":
// mean distance of the vertices from their centre): the same micrometre at
// which Levenberg-Marquardt stops, so the benchmark compares the two at equal
// convergence rather than handicapping the baseline with a tighter target.
constexpr double kSimplexTolerance_m = 1e-6;
// A consensus subset must fit its ranges to within their noise as a whole:
// cost / sigma^2 below the chi-square quantile at this probability for its
// redundant ranges. Per-range residuals within the threshold are not enough:
// ranges that are all long by different calibration biases (real receivers
// before their offsets are surveyed) leave every subset inconsistent, and
// dropping the most biased one would only make the fix worse (the LIAS data
// in docs/trilateration.md); consistent biases are not outliers.
constexpr double kConsensusChiSquareProbability = 0.999;

// The ranges in the solver's own coordinates: anchors in the D free
// coordinates, plus a fixed offset along the others (the beacon-to-receiver
// height difference in kFixedHeight2D), so that the distance is
// sqrt(|p - a_i|^2 + off2_i).
template <int D>
struct Ranges {
  using Vec = Eigen::Matrix<double, D, 1>;
  std::vector<Vec> a;
  std::vector<double> off2;
  std::vector<double> d;
  std::vector<int> ids;
  // Weight of each range in F (1 except in the Cauchy M-estimator).
  std::vector<double> w;
  // Indices (into the vectors above) of the ranges in the current fit.
  std::vector<int> active;
  // The ranges share an unknown offset b (FitSharedLevel): residuals and
  // Jacobian rows are taken about their weighted means. That is variable
  // projection: for a fixed p the best b is the mean residual, and
  // eliminating it leaves F(p) = sum w (e_i - mean e)^2 with rows
  // j_i - mean j, so sigma^2 (J_c^T J_c)^-1 is p's covariance with b
  // marginalised (never smaller than without the offset).
  bool level_free = false;
  // Range residuals evaluated so far (Fix::range_evaluations).
  mutable int64_t evaluations = 0;
};

template <int D>
double Cost(const Ranges<D>& r, const std::vector<int>& active,
            const Eigen::Matrix<double, D, 1>& p) {
  r.evaluations += static_cast<int64_t>(active.size());
  double cost = 0.0, sum_w = 0.0, sum_we = 0.0;
  for (int i : active) {
    const double e = std::sqrt((p - r.a[i]).squaredNorm() + r.off2[i]) - r.d[i];
    cost += r.w[i] * e * e;
    sum_w += r.w[i];
    sum_we += r.w[i] * e;
  }
  if (r.level_free && sum_w > 0.0) cost -= sum_we * sum_we / sum_w;
  return cost;
}

// J^T J and J^T e for e_i = |p - a_i| - d_i, J_i = (p - a_i)^T / |p - a_i|.
template <int D>
double NormalEquations(const Ranges<D>& r, const std::vector<int>& active,
                       const Eigen::Matrix<double, D, 1>& p, Eigen::Matrix<double, D, D>* jtj,
                       Eigen::Matrix<double, D, 1>* jte) {
  r.evaluations += static_cast<int64_t>(active.size());
  jtj->setZero();
  jte->setZero();
  double cost = 0.0, sum_w = 0.0, sum_we = 0.0;
  Eigen::Matrix<double, D, 1> sum_wj = Eigen::Matrix<double, D, 1>::Zero();
  for (int i : active) {
    const Eigen::Matrix<double, D, 1> diff = p - r.a[i];
    const double dist = std::sqrt(diff.squaredNorm() + r.off2[i]);
    const double e = dist - r.d[i];
    cost += r.w[i] * e * e;
    sum_w += r.w[i];
    sum_we += r.w[i] * e;
    // At a receiver the gradient is undefined; that range then adds nothing
    // to the step (it cannot say which way to go).
    if (dist < 1e-12) continue;
    const Eigen::Matrix<double, D, 1> j = diff / dist;
    *jtj += r.w[i] * j * j.transpose();
    *jte += r.w[i] * j * e;
    sum_wj += r.w[i] * j;
  }
  if (r.level_free && sum_w > 0.0) {
    // The centred sums (Ranges::level_free), from the raw ones in one pass.
    *jtj -= sum_wj * sum_wj.transpose() / sum_w;
    *jte -= sum_wj * (sum_we / sum_w);
    cost -= sum_we * sum_we / sum_w;
  }
  return cost;
}

// Levenberg-Marquardt with Marquardt's diagonal scaling. Returns the number
// of iterations; *converged is false when the limit was reached.
template <int D>
int Refine(const Ranges<D>& r, const std::vector<int>& active, int max_iterations,
           Eigen::Matrix<double, D, 1>* p, bool* converged,
           double step_tolerance_m = kStepTolerance_m) {
  using Vec = Eigen::Matrix<double, D, 1>;
  using Mat = Eigen::Matrix<double, D, D>;
  Mat jtj;
  Vec jte;
  double cost = NormalEquations(r, active, *p, &jtj, &jte);
  double lambda = 1e-6;
  *converged = false;
  int it = 0;
  while (it < max_iterations) {
    ++it;
    Mat a = jtj;
    // A small absolute term keeps the system solvable where a coordinate has
    // no gradient at all (a point on the receivers' plane in 3D).
    const double floor = 1e-12 * std::max(1.0, jtj.diagonal().maxCoeff());
    for (int k = 0; k < D; ++k) a(k, k) = jtj(k, k) * (1.0 + lambda) + lambda * floor;
    const Vec step = -a.inverse() * jte;
    if (!step.allFinite()) break;
    if (step.norm() < step_tolerance_m) {
      // A step this short cannot raise the cost by anything that matters;
      // take it without evaluating it (the caller evaluates the final point).
      *p += step;
      *converged = true;
      break;
    }
    const Vec candidate = *p + step;
    // The candidate's normal equations cost little more than its cost alone
    // and are needed anyway when the step is accepted, which is the rule.
    Mat candidate_jtj;
    Vec candidate_jte;
    const double candidate_cost =
        NormalEquations(r, active, candidate, &candidate_jtj, &candidate_jte);
    if (candidate_cost <= cost) {
      *p = candidate;
      cost = candidate_cost;
      jtj = candidate_jtj;
      jte = candidate_jte;
      lambda = std::max(lambda * 0.1, 1e-12);
    } else {
      lambda *= 10.0;
    }
    // No step lowers the cost any more: lambda has grown past any use.
    if (lambda > 1e8) {
      *converged = true;
      break;
    }
  }
  return it;
}

// Spread of points: eigenvalues (ascending) and eigenvectors of their
// scatter matrix divided by n, and the centroid.
template <int D>
struct Spread {
  Eigen::Matrix<double, D, 1> centroid;
  Eigen::Matrix<double, D, 1> variances;
  Eigen::Matrix<double, D, D> axes;
};

// Eigen-decomposition of a symmetric 2x2 or 3x3 matrix in closed form
// (Eigen's computeDirect): iterative solvers cost more than the rest of a
// 4-receiver solve.
template <int D>
void EigenSymmetric(const Eigen::Matrix<double, D, D>& m, Eigen::Matrix<double, D, 1>* values,
                    Eigen::Matrix<double, D, D>* vectors) {
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, D, D>> eig;
  eig.computeDirect(m, vectors != nullptr ? Eigen::ComputeEigenvectors : Eigen::EigenvaluesOnly);
  *values = eig.eigenvalues();
  if (vectors != nullptr) *vectors = eig.eigenvectors();
}

template <int D>
Spread<D> SpreadOf(const Ranges<D>& r, const std::vector<int>& active) {
  Spread<D> s;
  s.centroid.setZero();
  for (int i : active) s.centroid += r.a[i];
  s.centroid /= static_cast<double>(active.size());
  Eigen::Matrix<double, D, D> scatter = Eigen::Matrix<double, D, D>::Zero();
  for (int i : active) {
    const Eigen::Matrix<double, D, 1> c = r.a[i] - s.centroid;
    scatter += c * c.transpose();
  }
  scatter /= static_cast<double>(active.size());
  EigenSymmetric<D>(scatter, &s.variances, D == 3 ? &s.axes : nullptr);
  s.variances = s.variances.cwiseMax(0.0);
  return s;
}

// The linear start: subtracting the mean of the squared range equations
//   d_i^2 - off2_i - |a_i|^2 = |p|^2 - 2 a_i.p
// removes |p|^2 and leaves -2 (a_i - mean a).p = c_i - mean c, solved by
// least squares. False when the anchors do not span the D coordinates.
template <int D>
bool LinearStart(const Ranges<D>& r, const std::vector<int>& active,
                 Eigen::Matrix<double, D, 1>* p) {
  using Vec = Eigen::Matrix<double, D, 1>;
  using Mat = Eigen::Matrix<double, D, D>;
  r.evaluations += 2 * static_cast<int64_t>(active.size());
  Vec mean_a = Vec::Zero();
  double mean_c = 0.0;
  for (int i : active) {
    mean_a += r.a[i];
    mean_c += r.d[i] * r.d[i] - r.off2[i] - r.a[i].squaredNorm();
  }
  const double n = static_cast<double>(active.size());
  mean_a /= n;
  mean_c /= n;
  Mat m = Mat::Zero();
  Vec rhs = Vec::Zero();
  for (int i : active) {
    const Vec row = -2.0 * (r.a[i] - mean_a);
    const double c = r.d[i] * r.d[i] - r.off2[i] - r.a[i].squaredNorm() - mean_c;
    m += row * row.transpose();
    rhs += row * c;
  }
  const double scale = m.trace();
  if (!(scale > 0.0) || std::abs(m.determinant()) < 1e-12 * std::pow(scale, D)) return false;
  *p = m.inverse() * rhs;
  return p->allFinite();
}

// ---------------------------------------------------------------------------
// Nelder-Mead through GSL, the reference method.

template <int D>
struct NelderMeadParams {
  const Ranges<D>* r;
  const std::vector<int>* active;
};

template <int D>
double NelderMeadCost(const gsl_vector* x, void* params) {
  const auto* np = static_cast<const NelderMeadParams<D>*>(params);
  Eigen::Matrix<double, D, 1> p;
  for (int k = 0; k < D; ++k) p[k] = gsl_vector_get(x, k);
  return Cost(*np->r, *np->active, p);
}

// GSL's workspaces are kept per thread and dimension, so the baseline is not
// charged for allocations a real user of it would also avoid.
struct GslMinimizer {
  gsl_multimin_fminimizer* s = nullptr;
  gsl_vector* x = nullptr;
  gsl_vector* step = nullptr;
  explicit GslMinimizer(int d)
      : s(gsl_multimin_fminimizer_alloc(gsl_multimin_fminimizer_nmsimplex2, d)),
        x(gsl_vector_alloc(d)),
        step(gsl_vector_alloc(d)) {}
  ~GslMinimizer() {
    gsl_multimin_fminimizer_free(s);
    gsl_vector_free(x);
    gsl_vector_free(step);
  }
};

template <int D>
int NelderMead(const Ranges<D>& r, const std::vector<int>& active, int max_iterations,
               Eigen::Matrix<double, D, 1>* p, bool* converged) {
  thread_local GslMinimizer m(D);
  NelderMeadParams<D> params{&r, &active};
  gsl_multimin_function f;
  f.n = D;
  f.f = &NelderMeadCost<D>;
  f.params = &params;
  for (int k = 0; k < D; ++k) {
    gsl_vector_set(m.x, k, (*p)[k]);
    gsl_vector_set(m.step, k, 0.5);
  }
  gsl_multimin_fminimizer_set(m.s, &f, m.x, m.step);
  *converged = false;
  int it = 0;
  while (it < max_iterations * 20) {
    ++it;
    if (gsl_multimin_fminimizer_iterate(m.s) != GSL_SUCCESS) break;
    if (gsl_multimin_test_size(gsl_multimin_fminimizer_size(m.s), kSimplexTolerance_m) ==
        GSL_SUCCESS) {
      *converged = true;
      break;
    }
  }
  for (int k = 0; k < D; ++k) (*p)[k] = gsl_vector_get(m.s->x, k);
  return it;
}

// ---------------------------------------------------------------------------

struct Workspace {
  Ranges<2> r2;
  Ranges<3> r3;
  std::vector<int> subset;
  std::vector<int> saved_active;
  std::vector<int> excluded;
  std::vector<int> sorted_ids;
  std::vector<double> excess;
  std::vector<double> sorted_excess;
};

Workspace& ThreadWorkspace() {
  thread_local Workspace w;
  return w;
}

template <int D>
void Clear(Ranges<D>* r) {
  r->a.clear();
  r->off2.clear();
  r->d.clear();
  r->ids.clear();
  r->w.clear();
  r->active.clear();
  r->level_free = false;
  r->evaluations = 0;
}

// Sorts the input into valid ranges and rejected ones.
template <int D>
void Collect(const std::vector<RangeMeasurement>& input, const SolverOptions& o, Ranges<D>* r,
             Fix* fix) {
  Clear(r);
  // Sorted ids find duplicates in n log n: the input's size is bounded by
  // the caller's max_ranges only.
  std::vector<int>& ids = ThreadWorkspace().sorted_ids;
  ids.clear();
  for (const RangeMeasurement& m : input) ids.push_back(m.receiver_id);
  std::sort(ids.begin(), ids.end());
  for (size_t i = 0; i < input.size(); ++i) {
    const RangeMeasurement& m = input[i];
    auto reject = [&](RangeRejection why) { fix->rejected.push_back({m.receiver_id, why}); };
    // A receiver id heard twice in one firing is a corrupted set: neither
    // range can be trusted, so every copy goes.
    const auto same = std::equal_range(ids.begin(), ids.end(), m.receiver_id);
    const bool duplicate = same.second - same.first > 1;
    if (duplicate) {
      reject(RangeRejection::kDuplicateReceiver);
    } else if (!m.receiver_m.allFinite()) {
      reject(RangeRejection::kNonFiniteReceiver);
    } else if (!std::isfinite(m.range_m)) {
      reject(RangeRejection::kNonFinite);
    } else if (m.range_m < 0.0) {
      reject(RangeRejection::kNegative);
    } else if (m.range_m > o.max_range_m) {
      reject(RangeRejection::kTooLong);
    } else {
      Eigen::Matrix<double, D, 1> a;
      double off2 = 0.0;
      if constexpr (D == 2) {
        a = m.receiver_m.head<2>();
        if (o.dimension == Dimension::kFixedHeight2D) {
          const double dz = o.fixed_height_m - m.receiver_m.z();
          off2 = dz * dz;
        }
      } else {
        a = m.receiver_m;
      }
      r->active.push_back(static_cast<int>(r->a.size()));
      r->a.push_back(a);
      r->off2.push_back(off2);
      r->d.push_back(m.range_m);
      r->ids.push_back(m.receiver_id);
      r->w.push_back(1.0);
    }
  }
  if (!fix->rejected.empty()) fix->flags |= kBadRangesDropped;
}

// Where to start: the caller's guess, or the linear solution. For coplanar
// receivers in 3D the linear system has no out-of-plane information; the
// in-plane point comes from it and the height above the plane from the mean
// of d_i^2 - |q - q_i|^2, on the room side.
template <int D>
bool Start(const Ranges<D>& r, const std::vector<int>& active, const SolverOptions& o,
           const Eigen::Vector3d* guess, const Spread<D>& spread, bool coplanar,
           Eigen::Matrix<double, D, 1>* p) {
  if (guess != nullptr && guess->allFinite()) {
    if constexpr (D == 2) {
      *p = guess->head<2>();
    } else {
      *p = *guess;
    }
    return true;
  }
  if constexpr (D == 3) {
    if (coplanar) {
      Ranges<2> q;
      const Eigen::Vector3d e1 = spread.axes.col(2);
      const Eigen::Vector3d e2 = spread.axes.col(1);
      const Eigen::Vector3d normal = spread.axes.col(0);
      std::vector<int> all;
      for (int i : active) {
        const Eigen::Vector3d c = r.a[i] - spread.centroid;
        all.push_back(static_cast<int>(q.a.size()));
        q.a.emplace_back(e1.dot(c), e2.dot(c));
        const double out = normal.dot(c);
        q.off2.push_back(out * out);
        q.d.push_back(r.d[i]);
        q.w.push_back(1.0);
      }
      Eigen::Vector2d in_plane;
      if (!LinearStart(q, all, &in_plane)) return false;
      double h2 = 0.0;
      for (size_t k = 0; k < all.size(); ++k) {
        h2 += q.d[k] * q.d[k] - (in_plane - q.a[k]).squaredNorm();
      }
      const double h = std::sqrt(std::max(0.0, h2 / static_cast<double>(all.size())));
      Eigen::Vector3d side_point = o.room_side_point_m;
      if (!side_point.allFinite()) side_point = {spread.centroid.x(), spread.centroid.y(), 0.0};
      const double side_sign = normal.dot(side_point - spread.centroid) < 0.0 ? -1.0 : 1.0;
      *p = spread.centroid + e1 * in_plane.x() + e2 * in_plane.y() + normal * (side_sign * h);
      return true;
    }
  }
  (void)o;
  (void)spread;
  (void)coplanar;
  return LinearStart(r, active, p);
}

template <int D>
void Residuals(const Ranges<D>& r, const std::vector<int>& active,
               const Eigen::Matrix<double, D, 1>& p, double* max_abs) {
  r.evaluations += static_cast<int64_t>(active.size());
  *max_abs = 0.0;
  for (int i : active) {
    *max_abs =
        std::max(*max_abs, std::abs(std::sqrt((p - r.a[i]).squaredNorm() + r.off2[i]) - r.d[i]));
  }
}

// The chi-square quantile at kConsensusChiSquareProbability, cached for the
// few degrees of freedom a room has.
double ChiSquareQuantile(int dof) {
  static const std::vector<double> table = [] {
    std::vector<double> t(65);
    for (int k = 1; k < static_cast<int>(t.size()); ++k) {
      t[k] = gsl_cdf_chisq_Pinv(kConsensusChiSquareProbability, k);
    }
    return t;
  }();
  if (dof < static_cast<int>(table.size())) return table[dof];
  return gsl_cdf_chisq_Pinv(kConsensusChiSquareProbability, dof);
}

// Residual of range i at p: measured minus predicted, positive when the range
// is long (a reflected path).
template <int D>
double Excess(const Ranges<D>& r, int i, const Eigen::Matrix<double, D, 1>& p) {
  r.evaluations += 1;
  return r.d[i] - std::sqrt((p - r.a[i]).squaredNorm() + r.off2[i]);
}

template <int D>
double DistanceToPrior(const Eigen::Matrix<double, D, 1>& p, const PositionPrior& prior) {
  if constexpr (D == 2) {
    return (p - prior.position_m.head<2>()).norm();
  } else {
    return (p - prior.position_m).norm();
  }
}

// Of the two points at horizontal distance rho_i = sqrt(d_i^2 - off2_i) from
// anchors a and b, the one nearer the prior; when the circles do not meet,
// the point on the line between the anchors that least squares would give
// (the gap split evenly). False for coincident anchors or a range shorter
// than its fixed vertical offset.
template <int D>
bool CircleIntersection(const Ranges<D>& r, int i, int j, const PositionPrior& prior,
                        Eigen::Matrix<double, D, 1>* out) {
  if constexpr (D != 2) {
    return false;
  } else {
    r.evaluations += 2;
    const double ri2 = r.d[i] * r.d[i] - r.off2[i];
    const double rj2 = r.d[j] * r.d[j] - r.off2[j];
    if (ri2 < 0.0 || rj2 < 0.0) return false;
    const Eigen::Vector2d ab = r.a[j] - r.a[i];
    const double l = ab.norm();
    if (l < kCollinear_m) return false;
    const Eigen::Vector2d u = ab / l;
    const Eigen::Vector2d n(-u.y(), u.x());
    // Along the baseline from a: x = (l^2 + ri^2 - rj^2) / 2l; across: h.
    const double ri = std::sqrt(ri2), rj = std::sqrt(rj2);
    if (ri + rj <= l || std::abs(ri - rj) >= l) {
      const double x = ri + rj <= l
                           ? ri + 0.5 * (l - ri - rj)
                           : (ri > rj ? ri - 0.5 * (ri - rj - l) : -ri + 0.5 * (rj - ri - l));
      *out = r.a[i] + u * x;
      return true;
    }
    const double x = (l * l + ri2 - rj2) / (2.0 * l);
    const double h = std::sqrt(std::max(0.0, ri2 - x * x));
    const Eigen::Vector2d base = r.a[i] + u * x;
    const Eigen::Vector2d p1 = base + n * h, p2 = base - n * h;
    const Eigen::Vector2d pr = prior.position_m.head<2>();
    *out = (p1 - pr).squaredNorm() <= (p2 - pr).squaredNorm() ? p1 : p2;
    return true;
  }
}

// A consensus subset converges in a handful of Levenberg-Marquardt steps
// from the linear start or the prior (quadratically once close); one that
// has not within this many is not a consensus (two circles that do not
// meet, a subset holding a reflection), and its remaining iterations would
// set the solver's worst-case time.
constexpr int kSubsetIterations = 12;

// What every stage of one solve shares: the options, the valid ranges in the
// solver's coordinates, the fix being filled, the thread's scratch vectors,
// and the receivers' spread (from which the start and the mirror resolution
// work). Built once per solve on the stack; no allocation.
template <int D>
struct SolveContext {
  // Over-determined needs D + 1 ranges: one more than the unknowns, so that
  // a range can be checked against the others.
  static constexpr int kOverDetermined = D + 1;

  SolveContext(const SolverOptions& solver_options, const PositionPrior* position_prior,
               const std::vector<NlosSuspicion>* suspected_nlos, Ranges<D>* solver_ranges, Fix* out)
      : options(solver_options),
        prior(position_prior),
        suspected(suspected_nlos),
        ranges(solver_ranges),
        fix(out),
        workspace(ThreadWorkspace()),
        spread(SpreadOf(*solver_ranges, solver_ranges->active)),
        threshold(solver_options.OutlierThreshold()),
        sigma2(solver_options.range_sigma_m * solver_options.range_sigma_m) {}

  const SolverOptions& options;
  const PositionPrior* prior;
  // Receivers the caller's NLOS belief suspects (ascending ids), or null.
  const std::vector<NlosSuspicion>* suspected;
  Ranges<D>* ranges;
  Fix* fix;
  Workspace& workspace;
  const Spread<D> spread;
  bool coplanar = false;
  // The outlier threshold in effect, and the range variance sigma^2.
  const double threshold;
  const double sigma2;
};

// The receivers must span the free coordinates: in 2D not all on one line
// (the fix would be mirror-ambiguous across it and the normal equations
// singular along it), in 3D not all on one line either. Receivers that are
// merely coplanar in 3D (the usual ceiling installation) are allowed and
// noted: the start and the mirror resolution treat them specially. False
// (flagged) when collinear.
template <int D>
bool CheckGeometry(SolveContext<D>* ctx) {
  // variances ascending: [0] smallest.
  const double second = std::sqrt(ctx->spread.variances[D == 2 ? 0 : 1]);
  if (second < kCollinear_m) {
    ctx->fix->flags |= kCollinearReceivers;
    return false;
  }
  if constexpr (D == 3) {
    const double smallest = std::sqrt(ctx->spread.variances[0]);
    ctx->coplanar = smallest < kCoplanar_m || smallest < kCoplanarRatio * second;
  }
  return true;
}

// Fits the ranges in `active` from the caller's guess or the linear start
// (Start), by Nelder-Mead for the reference method and Levenberg-Marquardt
// otherwise. A budget below the solver's own marks a consensus subset, which
// stops at kSubsetStepTolerance_m. Returns the iterations, or -1 when the
// start is degenerate (anchors that do not span the coordinates).
template <int D>
int SolveSubset(const SolveContext<D>& ctx, const std::vector<int>& active,
                const Eigen::Vector3d* start_guess, Eigen::Matrix<double, D, 1>* p, bool* converged,
                int max_iterations) {
  if (!Start(*ctx.ranges, active, ctx.options, start_guess, ctx.spread, ctx.coplanar, p)) return -1;
  if (ctx.options.method == Method::kNelderMead) {
    return NelderMead(*ctx.ranges, active, max_iterations, p, converged);
  }
  return Refine(
      *ctx.ranges, active, max_iterations, p, converged,
      max_iterations < ctx.options.max_iterations ? kSubsetStepTolerance_m : kStepTolerance_m);
}

// The kRobust consensus search's state: the best admissible subset so far
// (least score) and how many subsets were admissible at all.
template <int D>
struct Consensus {
  bool found = false;
  bool exhausted = false;
  int admissible = 0;
  double best_score = kInf;
  Eigen::Matrix<double, D, 1> best_p;
  int best_converged = 0;
  int best_size = 0;
  // Where subset solves start: the prior's position, or the linear start.
  const Eigen::Vector3d* start = nullptr;
  // The prior's shortcut subset was the consensus.
  bool identified_by_prior = false;
};

// Whether every excluded range is long against the kept ranges' fix q: above
// their mean excess at q (a common offset, such as an uncalibrated receiver
// bias or a wrong speed of sound, lengthens every range, identifies none,
// and a fixed-height fit cannot absorb it) by the threshold plus five times
// their RMS scatter about that mean (kept ranges that scatter more than the
// noise model says, as differently biased receivers do, make a range stand
// out less). A reflection is long against the others. The scatter is
// estimated with its degrees of freedom (m ranges less D coordinates and the
// mean) and, where it has any, never below the configured range noise: a
// handful of kept ranges that happen to fit tighter than the noise is
// chance, not evidence, and would otherwise make a consistently biased
// receiver (the LIAS data, docs/trilateration.md) look like a reflection.
template <int D>
bool ExcludedAreLong(const SolveContext<D>& ctx, const Eigen::Matrix<double, D, 1>& q) {
  const Ranges<D>& r = *ctx.ranges;
  const std::vector<int>& subset = ctx.workspace.subset;
  double sub_mean = 0.0, sub_square = 0.0;
  for (int i : subset) {
    const double e = Excess(r, i, q);
    sub_mean += e;
    sub_square += e * e;
  }
  const double m_count = static_cast<double>(subset.size());
  sub_mean /= m_count;
  const int scatter_dof = static_cast<int>(subset.size()) - D - 1;
  double scatter = std::sqrt(std::max(0.0, (sub_square - m_count * sub_mean * sub_mean) /
                                               (scatter_dof > 0 ? scatter_dof : m_count)));
  if (scatter_dof > 0) scatter = std::max(scatter, ctx.options.range_sigma_m);
  bool long_enough = true;
  for (int i : ctx.workspace.excluded) {
    long_enough =
        long_enough && Excess(r, i, q) - std::max(0.0, sub_mean) > ctx.threshold + 5.0 * scatter;
  }
  return long_enough;
}

// Distance of a subset's fix q from the prior, as a fraction of how far it
// may be: the prior's radius plus three of the subset fix's own standard
// deviations (its largest, sigma / sqrt of the smallest eigenvalue of
// J^T J): an exactly determined pair of ranges at a shallow angle is
// centimetres of noise times its dilution of precision away from the truth.
// Above 1: not near. Infinite reach (singular J^T J) gives 0.
template <int D>
double PriorReachFraction(const SolveContext<D>& ctx, const Eigen::Matrix<double, D, 1>& q) {
  Eigen::Matrix<double, D, D> q_jtj;
  Eigen::Matrix<double, D, 1> q_jte;
  NormalEquations(*ctx.ranges, ctx.workspace.subset, q, &q_jtj, &q_jte);
  Eigen::Matrix<double, D, 1> q_values;
  EigenSymmetric<D>(q_jtj, &q_values, nullptr);
  const double q_sigma =
      q_values.minCoeff() > 0.0 ? ctx.options.range_sigma_m / std::sqrt(q_values.minCoeff()) : kInf;
  const double reach = ctx.prior->radius_m + 3.0 * q_sigma;
  return DistanceToPrior(q, *ctx.prior) / reach;
}

// Solves ctx.workspace.subset (ctx.workspace.excluded left out) and keeps it as the best so
// far when it is admissible: its fit converged, every kept residual is
// within the threshold, every excluded range is long (ExcludedAreLong), the
// fix is near the prior (PriorReachFraction <= 1) and the subset fits its
// ranges as a whole (cost / sigma^2 within the chi-square quantile for its
// redundant ranges). Its score is cost / sigma^2 plus the squared reach
// fraction. True when admissible.
template <int D>
bool EvaluateSubset(const SolveContext<D>& ctx, Consensus<D>* cs) {
  const std::vector<int>& subset = ctx.workspace.subset;
  Eigen::Matrix<double, D, 1> q;
  bool c = false;
  int its = 0;
  if (D == 2 && subset.size() == 2 && ctx.prior != nullptr) {
    // Exactly determined in 2D: the two circles' intersection nearest the
    // prior, in closed form (a tenth of a Levenberg-Marquardt solve, which
    // for the worst sets, two reflections among four ranges and six such
    // pairs, decides the solver's p99 time).
    c = CircleIntersection(*ctx.ranges, subset[0], subset[1], *ctx.prior, &q);
  } else {
    its = SolveSubset(ctx, subset, cs->start, &q, &c,
                      std::min(ctx.options.max_iterations, kSubsetIterations));
  }
  if (its < 0 || !c) return false;
  ctx.fix->iterations += its;
  double sub_worst = 0.0;
  Residuals(*ctx.ranges, subset, q, &sub_worst);
  const bool long_enough = ExcludedAreLong(ctx, q);
  double score = Cost(*ctx.ranges, subset, q) / ctx.sigma2;
  bool near = true;
  if (ctx.prior != nullptr) {
    const double d = PriorReachFraction(ctx, q);
    near = d <= 1.0;
    score += d * d;
  }
  const int dof = static_cast<int>(subset.size()) - D;
  const bool fits = dof <= 0 || Cost(*ctx.ranges, subset, q) / ctx.sigma2 <= ChiSquareQuantile(dof);
  if (!(sub_worst <= ctx.threshold && long_enough && near && fits)) return false;
  ++cs->admissible;
  if (score < cs->best_score) {
    cs->best_score = score;
    cs->best_p = q;
    cs->best_converged = c;
    cs->best_size = static_cast<int>(subset.size());
  }
  return true;
}

// With a prior, a range longer than the prior predicts by more than the
// prior's radius plus the threshold is long against wherever the beacon can
// be (|d_pred(p) - d_pred(prior)| <= |p - prior| <= radius), so it is a
// reflection whatever the other ranges say. Excluding exactly those first
// settles the common case in one subset solve instead of all C(n, 1) +
// C(n, 2): two reflections among four ranges otherwise cost ten, which set
// the solver's p99 time. The subset must pass the same tests as any other;
// when it does not (a reflection too short to stand out against the prior, a
// wrong prior) the exhaustive search runs as without the shortcut.
template <int D>
void TryPriorShortcut(const SolveContext<D>& ctx, int max_out, Consensus<D>* cs) {
  Workspace& w = ctx.workspace;
  w.subset.clear();
  w.excluded.clear();
  const Eigen::Matrix<double, D, 1> prior_p = ctx.prior->position_m.template head<D>();
  for (int i : ctx.ranges->active) {
    if (Excess(*ctx.ranges, i, prior_p) > ctx.prior->radius_m + ctx.threshold) {
      w.excluded.push_back(i);
    } else {
      w.subset.push_back(i);
    }
  }
  const int excluded = static_cast<int>(w.excluded.size());
  if (excluded >= 1 && excluded <= max_out && ctx.options.max_consensus_solves > 0) {
    ++ctx.fix->consensus_solves;
    cs->found = EvaluateSubset(ctx, cs);
    cs->identified_by_prior = cs->found;
  }
}

// The exhaustive search: every way of excluding k = 1, 2, ... max_out of the
// n active ranges, in lexicographic order, stopping at the first k with an
// admissible subset (the fewest exclusions) or when max_consensus_solves
// subsets have been solved (cs->exhausted).
template <int D>
void SearchSubsets(const SolveContext<D>& ctx, int max_out, Consensus<D>* cs) {
  Workspace& w = ctx.workspace;
  const std::vector<int>& active = ctx.ranges->active;
  const int n = static_cast<int>(active.size());
  for (int k = 1; k <= max_out && !cs->found && !cs->exhausted; ++k) {
    std::vector<int> pick(k);
    for (int j = 0; j < k; ++j) pick[j] = j;
    while (true) {
      if (ctx.fix->consensus_solves >= ctx.options.max_consensus_solves) {
        cs->exhausted = true;
        break;
      }
      ++ctx.fix->consensus_solves;
      w.subset.clear();
      w.excluded.clear();
      for (int i = 0, j = 0; i < n; ++i) {
        if (j < k && pick[j] == i) {
          w.excluded.push_back(active[i]);
          ++j;
        } else {
          w.subset.push_back(active[i]);
        }
      }
      if (EvaluateSubset(ctx, cs)) cs->found = true;
      // Next combination of k indices out of n.
      int j = k - 1;
      while (j >= 0 && pick[j] == n - k + j) --j;
      if (j < 0) break;
      ++pick[j];
      for (int t = j + 1; t < k; ++t) pick[t] = pick[t - 1] + 1;
    }
  }
}

// Adopts the consensus: re-admits any excluded range that agrees with the
// consensus point (within the threshold), rejects the rest as outliers, and
// refits on the final set. The prior is credited (kPriorIdentified) when it
// did the choosing: its shortcut settled it, several subsets were
// admissible, an exactly determined subset won, or the full set was
// consistent and the search ran only because the fix lay beyond the prior.
template <int D>
void AdoptConsensus(const SolveContext<D>& ctx, const Consensus<D>& cs, double worst,
                    Eigen::Matrix<double, D, 1>* p, bool* converged) {
  Ranges<D>* r = ctx.ranges;
  Fix* fix = ctx.fix;
  ctx.workspace.subset.clear();
  for (int i : r->active) {
    if (std::abs(Excess(*r, i, cs.best_p)) <= ctx.threshold) {
      ctx.workspace.subset.push_back(i);
    } else {
      fix->rejected.push_back({r->ids[i], RangeRejection::kOutlier});
    }
  }
  r->active = ctx.workspace.subset;
  *p = cs.best_p;
  *converged = cs.best_converged;
  fix->iterations += Refine(*r, r->active, ctx.options.max_iterations, p, converged);
  fix->flags |= kOutliersRejected;
  if (ctx.prior != nullptr &&
      (cs.identified_by_prior || cs.admissible > 1 ||
       cs.best_size < SolveContext<D>::kOverDetermined || worst <= ctx.threshold)) {
    fix->flags |= kPriorIdentified;
  }
}

// The one-sided IRLS of kRobust above max_consensus_ranges: rounds and
// Levenberg-Marquardt iterations per round. Each round is warm-started from
// the last, so a few iterations suffice; the bounds make the work at most
// kOneSidedRounds * (kOneSidedIterations + 2) * n residuals, linear in n.
constexpr int kOneSidedRounds = 20;
constexpr int kOneSidedIterations = 20;

// The median of the active ranges' excesses at p (filled into w.excess in
// active order), clamped at 0: the level the ranges share. A shared bias
// (a wrong speed of sound, an uncalibrated offset common to all) moves the
// level, and a range is suspected only for its excess over the level, so
// the ranges are never sorted out by a bias they share. Clamped at 0
// because ranges shorter on the whole than the fix predicts are not a
// reflection's signature.
template <int D>
double SharedLevel(const SolveContext<D>& ctx, const Eigen::Matrix<double, D, 1>& p) {
  Workspace& w = ctx.workspace;
  w.excess.clear();
  for (int i : ctx.ranges->active) w.excess.push_back(Excess(*ctx.ranges, i, p));
  w.sorted_excess = w.excess;
  const size_t mid = w.sorted_excess.size() / 2;
  std::nth_element(w.sorted_excess.begin(), w.sorted_excess.begin() + mid, w.sorted_excess.end());
  return std::max(0.0, w.sorted_excess[mid]);
}

// kRobust for a set too large for the consensus search (more than
// max_consensus_ranges ranges): iteratively reweighted least squares with a
// one-sided loss. A reflection only lengthens a range, so a range whose
// excess over the shared level (SharedLevel) is e > 0 gets the Cauchy weight
// 1 / (1 + (e / c)^2), c = 2.3849 sigma, and a range that is short or on the
// level keeps weight 1 (the Gaussian's). Ranges still long by more than the
// outlier threshold at the end are rejected as reflections when enough
// remain to over-determine the fix, and the rest are refitted with unit
// weights (the covariance is that of an ordinary fit on them). Cost linear
// in the ranges (kOneSidedRounds). Failure mode: when more than about half
// the ranges are long by different amounts the median level is itself long
// and the fix is pulled; the status then says so (inconsistent_ranges).
template <int D>
void ReweightOneSided(const SolveContext<D>& ctx, Eigen::Matrix<double, D, 1>* p, bool* converged) {
  Ranges<D>* r = ctx.ranges;
  Fix* fix = ctx.fix;
  Workspace& w = ctx.workspace;
  const double c = 2.3849 * ctx.options.range_sigma_m;
  const int iterations = std::min(ctx.options.max_iterations, kOneSidedIterations);
  for (int round = 0; round < kOneSidedRounds; ++round) {
    const double level = SharedLevel(ctx, *p);
    for (size_t k = 0; k < r->active.size(); ++k) {
      const double e = w.excess[k] - level;
      r->w[r->active[k]] = e <= 0.0 ? 1.0 : 1.0 / (1.0 + (e / c) * (e / c));
    }
    const Eigen::Matrix<double, D, 1> previous = *p;
    fix->iterations += Refine(*r, r->active, iterations, p, converged);
    if ((*p - previous).norm() < kStepTolerance_m) break;
  }
  const double level = SharedLevel(ctx, *p);
  w.subset.clear();
  for (size_t k = 0; k < r->active.size(); ++k) {
    if (w.excess[k] - level <= ctx.threshold) w.subset.push_back(r->active[k]);
  }
  for (int i : r->active) r->w[i] = 1.0;
  if (w.subset.size() == r->active.size() ||
      static_cast<int>(w.subset.size()) < SolveContext<D>::kOverDetermined) {
    return;
  }
  for (size_t k = 0; k < r->active.size(); ++k) {
    if (w.excess[k] - level > ctx.threshold) {
      fix->rejected.push_back({r->ids[r->active[k]], RangeRejection::kOutlier});
    }
  }
  r->active = w.subset;
  fix->flags |= kOutliersRejected;
  fix->iterations += Refine(*r, r->active, ctx.options.max_iterations, p, converged);
}

// The caller's suspicion of range i's receiver, or null.
template <int D>
const NlosSuspicion* SuspicionOf(const SolveContext<D>& ctx, int i) {
  if (ctx.suspected == nullptr) return nullptr;
  const int id = ctx.ranges->ids[i];
  const auto it = std::lower_bound(
      ctx.suspected->begin(), ctx.suspected->end(), id,
      [](const NlosSuspicion& s, int receiver_id) { return s.receiver_id < receiver_id; });
  return it != ctx.suspected->end() && it->receiver_id == id ? &*it : nullptr;
}

// The weight of a suspected range long by e > 0: the probability that it is
// on its direct path after all, given the belief's probability q that it is
// an echo, from the mixture of the two models NlosBelief tracks
// (core/trilat/nlos_model.h):
//   w = (1 - q) N(e) / ((1 - q) N(e) + q U(e)).
// At q = 0.95 and 2 cm noise in a 5 m room a range 6 cm long keeps 5 % of
// its weight and one on its path 91 %; ranges that read short keep weight 1
// (one-sided: an echo is never short).
double EchoWeight(double e, double sigma, const NlosSuspicion& s) {
  const double los = LineOfSightLikelihood(e, sigma);
  const double echo = EchoLikelihood(e, sigma, s.echo_span_m);
  const double q = std::clamp(s.probability, 0.0, 1.0);
  const double w = (1.0 - q) * los / ((1.0 - q) * los + q * echo);
  return std::isfinite(w) ? w : 0.0;
}

// kRobust with the caller's NLOS belief (NlosBelief), first: a range from a
// receiver that was hidden a firing ago is probably still an echo, and an
// echo is only ever long. Each suspected range is judged against the fix of
// the unsuspected ranges alone, p_o: its deleted residual e = d - |p_o - a|,
// whose variance on the direct path is s^2 = sigma^2 (1 + h), h = j^T
// (J_o^T J_o)^-1 j the leverage of the others' fix in its direction. It then
// gets EchoWeight(e, s) when e > 0 and weight 1 when it reads short or on
// its path (a one-sided loss), and the fix is refitted once with those
// weights. One step rather than iterated reweighting, because a range
// refitted with the others moves the fix towards itself: with four
// receivers a 5 cm detour leaves a residual under 2 cm at the joint fit,
// which then looks on its path, and iterating converges there (measured:
// 21.8 mm off, against 27.6 mm blind and 17.3 mm in one step; the others'
// fix predicts that range only to s = 1.6 sigma, so 5 cm is weak evidence
// and the range keeps some weight, as it should). This is what
// catches an echo too short for the threshold, a detour of a few
// centimetres that the consensus cannot tell from noise; a long echo ends
// with a residual of nearly its own length and the consensus then excludes
// it as ever (its search starts from unit weights). Applied only when the
// unsuspected ranges over-determine the fix by themselves, so that
// down-weighting never leaves a fix that nothing checks. The covariance is
// that of the weighted fit (the down-weighted range informs it less), and
// the fix is flagged kNlosSuspected (degraded) when a suspected range kept
// less than half its weight. Failure mode: a receiver suspected wrongly
// loses weight for positive noise only, a bias of a fraction of sigma for
// the one firing its belief takes to clear.
template <int D>
void DownweightSuspected(const SolveContext<D>& ctx, Eigen::Matrix<double, D, 1>* p,
                         bool* converged) {
  if (ctx.suspected == nullptr || ctx.suspected->empty()) return;
  Ranges<D>* r = ctx.ranges;
  int unsuspected = 0;
  for (int i : r->active) unsuspected += SuspicionOf(ctx, i) == nullptr ? 1 : 0;
  if (unsuspected == static_cast<int>(r->active.size()) ||
      unsuspected < SolveContext<D>::kOverDetermined) {
    return;
  }
  const Eigen::Matrix<double, D, 1> saved_p = *p;
  const bool saved_converged = *converged;
  for (int i : r->active) r->w[i] = SuspicionOf(ctx, i) == nullptr ? 1.0 : 0.0;
  ctx.fix->iterations += Refine(*r, r->active, ctx.options.max_iterations, p, converged);
  Eigen::Matrix<double, D, D> jtj;
  Eigen::Matrix<double, D, 1> jte;
  NormalEquations(*r, r->active, *p, &jtj, &jte);
  const Eigen::Matrix<double, D, D> jtj_inverse = jtj.inverse();
  if (!jtj_inverse.allFinite()) {
    // The others alone do not fix the point (on the line of collinear
    // receivers): nothing to judge the suspects by; everything as it was.
    for (int i : r->active) r->w[i] = 1.0;
    *p = saved_p;
    *converged = saved_converged;
    return;
  }
  const double sigma = ctx.options.range_sigma_m;
  bool weighted = false;
  for (int i : r->active) {
    const NlosSuspicion* suspicion = SuspicionOf(ctx, i);
    if (suspicion == nullptr) continue;
    const Eigen::Matrix<double, D, 1> diff = *p - r->a[i];
    const double dist = std::sqrt(diff.squaredNorm() + r->off2[i]);
    const Eigen::Matrix<double, D, 1> j = dist > 1e-12 ? Eigen::Matrix<double, D, 1>(diff / dist)
                                                       : Eigen::Matrix<double, D, 1>::Zero();
    const double s = sigma * std::sqrt(1.0 + j.dot(jtj_inverse * j));
    const double e = Excess(*r, i, *p);
    r->w[i] = e <= 0.0 ? 1.0 : EchoWeight(e, s, *suspicion);
    weighted = weighted || r->w[i] < 0.5;
  }
  ctx.fix->iterations += Refine(*r, r->active, ctx.options.max_iterations, p, converged);
  if (weighted) ctx.fix->flags |= kNlosSuspected;
}

// When the consensus search finds no admissible subset because more ranges
// are long than max_outliers allows (a hall's 12 receivers with a robot
// among people and pillars: four echoes among eleven ranges happen), the
// one-sided reweighting still separates them as long as fewer than about
// half are long. Its answer is taken only when it leaves at least D + 2
// ranges (so that they still check each other after the level) that all fit
// within the threshold; otherwise p, the active set and the rejections are
// restored and the caller flags the fix inconsistent as before. Linear
// cost (the membership test is n per kept range, n <= max_consensus_ranges
// here), so the solve stays bounded.
template <int D>
bool FallBackOneSided(const SolveContext<D>& ctx, Eigen::Matrix<double, D, 1>* p, bool* converged) {
  Ranges<D>* r = ctx.ranges;
  Fix* fix = ctx.fix;
  const Eigen::Matrix<double, D, 1> saved_p = *p;
  const bool saved_converged = *converged;
  std::vector<int>& saved_active = ctx.workspace.saved_active;
  saved_active = r->active;
  const size_t saved_rejected = fix->rejected.size();
  const uint32_t saved_flags = fix->flags;
  ReweightOneSided(ctx, p, converged);
  double worst = 0.0;
  Residuals(*r, r->active, *p, &worst);
  // The ranges it rejected must stand out from the kept ones as the
  // consensus demands of any exclusion (ExcludedAreLong): receivers biased
  // differently by a few centimetres each (the LIAS data) are not echoes.
  Workspace& w = ctx.workspace;
  w.subset = r->active;
  w.excluded.clear();
  for (int i : saved_active) {
    if (std::find(r->active.begin(), r->active.end(), i) == r->active.end()) {
      w.excluded.push_back(i);
    }
  }
  // Nothing rejected is nothing gained: the reweighted point of a set that
  // stays inconsistent as a whole is no fix of its ranges.
  if (!w.excluded.empty() && static_cast<int>(r->active.size()) >= D + 2 &&
      worst <= ctx.threshold && *converged && ExcludedAreLong(ctx, *p)) {
    return true;
  }
  *p = saved_p;
  *converged = saved_converged;
  r->active = saved_active;
  fix->rejected.resize(saved_rejected);
  fix->flags = saved_flags;
  return false;
}

// kRobust: when the full set's fix p leaves a residual above the threshold
// (or lies beyond the prior with no more than one redundant range), the
// consensus: the fewest excluded ranges such that
//  - every remaining residual is within the threshold,
//  - every excluded range is long against the subset's fix by more than the
//    threshold (a reflection only lengthens a path: a subset that explains a
//    range as too short is physically impossible),
//  - with a prior, the fix is within the prior's radius;
// and among those the least score, cost / sigma^2, plus (distance to the
// prior / radius)^2 with a prior. Exhaustive over subsets, a few dozen small
// solves for a room; max_consensus_solves caps it for anything larger
// (C(n, 2) subsets of n ranges would let one message of 800 ranges take half
// a minute). With no admissible subset p stays and the fix is flagged
// inconsistent.
template <int D>
void RejectOutliers(const SolveContext<D>& ctx, Eigen::Matrix<double, D, 1>* p, bool* converged) {
  constexpr int over_determined = SolveContext<D>::kOverDetermined;
  const PositionPrior* prior = ctx.prior;
  double worst = 0.0;
  Residuals(*ctx.ranges, ctx.ranges->active, *p, &worst);
  const int n = static_cast<int>(ctx.ranges->active.size());
  // With a prior, exactly determined subsets (D ranges) are admissible in
  // 2D: the prior picks the right one of the two circle intersections and
  // tells the long range apart. In 3D the smallest subset stays D + 1.
  const int smallest_subset = (prior != nullptr && D == 2) ? D : over_determined;
  const int max_out = std::min(ctx.options.max_outliers, n - smallest_subset);
  // A consistent set with a single redundant range can still hide a long
  // range (the fit absorbs it); beyond the prior it is searched too. With
  // two or more redundant ranges a consistent set is trusted over the prior
  // (a robot lifted and put down elsewhere).
  const bool far = prior != nullptr && DistanceToPrior(*p, *prior) > prior->radius_m;
  const bool search = worst > ctx.threshold || (far && n <= over_determined);
  if (!search || max_out <= 0) return;
  // The search (and the reweighting of large sets) judges ranges with unit
  // weights: a suspected range's down-weighting (DownweightSuspected) has
  // done its part in p.
  for (int i : ctx.ranges->active) ctx.ranges->w[i] = 1.0;
  ctx.fix->flags &= ~static_cast<uint32_t>(kNlosSuspected);
  if (n > ctx.options.max_consensus_ranges) {
    ReweightOneSided(ctx, p, converged);
    return;
  }
  Consensus<D> cs;
  cs.best_p = *p;
  cs.best_size = n;
  cs.start = prior != nullptr ? &prior->position_m : nullptr;
  if (prior != nullptr) TryPriorShortcut(ctx, max_out, &cs);
  SearchSubsets(ctx, max_out, &cs);
  if (cs.found) {
    AdoptConsensus(ctx, cs, worst, p, converged);
  } else if (worst > ctx.threshold) {
    if (cs.exhausted) ctx.fix->flags |= kConsensusBudgetExhausted;
    if (!FallBackOneSided(ctx, p, converged)) ctx.fix->flags |= kInconsistentRanges;
  }
}

// The active ranges that count as degrees of freedom: a range the NLOS
// belief left with less than half its weight (DownweightSuspected) informs
// the fix too little to check the others.
template <int D>
int CountedRanges(const Ranges<D>& r) {
  int n = 0;
  for (int i : r.active) n += r.w[i] >= 0.5 ? 1 : 0;
  return n;
}

// A shared level is adopted only when it lowers the cost by more than the
// chi-square quantile for one degree of freedom at 99.9 % (10.83) times the
// residual variance: with no shared offset in the ranges it is adopted by
// chance in about one set in a thousand (measured 6 in 20 000 simulated
// 4-receiver sets at 2 cm), and then costs only a slightly larger
// covariance.
constexpr double kSharedLevelChiSquare = 10.83;

// kRobust, last stage: whether the kept ranges share a positive offset b
// (range_i = |p - a_i| + b + noise). Real receivers read long by a common
// amount (a UWB antenna delay, an ultrasonic detector's threshold crossing
// after the true arrival, both uncalibrated until `roomfix survey`); a
// fixed-height fit cannot absorb a common offset, so it shifts the fix
// towards the receivers' centroid by an amount that grows with b (15 cm
// mean error on the LIAS data at b about 17 cm). Fitting b with p
// (Ranges::level_free) costs one degree of freedom, so it needs D + 2 kept
// ranges, and it is adopted only when b > 0 (a delay never shortens a
// time of flight) and the cost falls by kSharedLevelChiSquare residual
// variances, the variance being the level fit's own (cost / (m - D - 1)),
// floored at sigma^2 (biases that differ per receiver scatter more than
// the noise, which then takes more evidence). Adopted, every kept range is
// shortened by b, the fix is flagged kSharedLevel and the covariance is
// the level fit's (b marginalised). Otherwise nothing changes. Failure
// mode: receivers all on one side of the beacon make b and the distance to
// them nearly the same thing; the covariance then grows, and a fix whose
// covariance passes max_position_sigma_m is flagged poor geometry as ever.
template <int D>
bool FitSharedLevel(const SolveContext<D>& ctx, Eigen::Matrix<double, D, 1>* p, bool* converged) {
  Ranges<D>* r = ctx.ranges;
  const int m = CountedRanges(*r);
  if (m < D + 2 || r->level_free) return false;
  // The plain cost at the plain fit's minimum (p may be a reweighted point
  // whose weights were since reset, which would overstate it).
  Eigen::Matrix<double, D, 1> plain_p = *p;
  bool plain_converged = false;
  Refine(*r, r->active, ctx.options.max_iterations, &plain_p, &plain_converged);
  const double plain_cost = Cost(*r, r->active, plain_p);
  Eigen::Matrix<double, D, 1> q = *p;
  bool level_converged = false;
  r->level_free = true;
  const int iterations = Refine(*r, r->active, ctx.options.max_iterations, &q, &level_converged);
  const double level_cost = Cost(*r, r->active, q);
  // The weighted mean excess: the level the centred fit removed.
  double level = 0.0, weight = 0.0;
  for (int i : r->active) {
    level += r->w[i] * Excess(*r, i, q);
    weight += r->w[i];
  }
  level /= weight;
  const double variance = std::max(ctx.sigma2, level_cost / static_cast<double>(m - D - 1));
  if (!level_converged || !(level > 0.0) ||
      !((plain_cost - level_cost) / variance > kSharedLevelChiSquare)) {
    r->level_free = false;
    return false;
  }
  ctx.fix->iterations += iterations;
  for (int i : r->active) r->d[i] -= level;
  ctx.fix->shared_level_m = level;
  ctx.fix->flags |= kSharedLevel;
  *p = q;
  *converged = level_converged;
  return true;
}

// The level before any exclusion needs this many ranges beyond the D + 1
// unknowns: with fewer, one echo is absorbed by the level and the position
// together (four ceiling receivers, one range 25 cm long: the level fit
// leaves every residual under the threshold and a fix off by centimetres),
// while with three or more residual degrees of freedom an echo stays a
// residual of nearly its own length.
constexpr int kLevelFirstRedundancy = 3;

// kRobust, before the consensus search: "never exclude a range only because
// the remaining ones disagree about a bias they share". When the plain fit
// leaves a residual above the threshold but a fit with a shared level
// (FitSharedLevel) leaves none, the ranges are all long by about the same
// amount and no echo stands out: that fit is kept and nothing is searched.
// The LIAS sessions are the case: eight anchors long by 4-27 cm each, where
// the consensus used to exclude the longest of them and move the fix 10 to
// 20 cm further from the truth than least squares. Otherwise everything is
// put back as it was. True when the level fit was kept.
template <int D>
bool LevelBeforeExclusion(const SolveContext<D>& ctx, Eigen::Matrix<double, D, 1>* p,
                          bool* converged) {
  Ranges<D>* r = ctx.ranges;
  if (CountedRanges(*r) < D + 1 + kLevelFirstRedundancy) return false;
  double worst = 0.0;
  Residuals(*r, r->active, *p, &worst);
  if (worst <= ctx.threshold) return false;
  const Eigen::Matrix<double, D, 1> saved_p = *p;
  const bool saved_converged = *converged;
  const uint32_t saved_flags = ctx.fix->flags;
  if (!FitSharedLevel(ctx, p, converged)) return false;
  Residuals(*r, r->active, *p, &worst);
  if (worst <= ctx.threshold) return true;
  for (int i : r->active) r->d[i] += ctx.fix->shared_level_m;
  r->level_free = false;
  ctx.fix->shared_level_m = 0.0;
  ctx.fix->flags = saved_flags;
  *p = saved_p;
  *converged = saved_converged;
  return false;
}

// kCauchy: iteratively reweighted least squares with the Cauchy loss
// rho(e) = c^2/2 log(1 + (e/c)^2), weight 1 / (1 + (e/c)^2), with
// c = 2.3849 sigma (95% efficiency on Gaussian noise), until a round moves
// the fix less than kStepTolerance_m (at most 30 rounds). Ranges whose
// residual ends above the outlier threshold are reported as rejected: they
// still pull the estimate, with weight under a few percent, and leave the
// active set only when enough remain to over-determine the fix.
template <int D>
void ReweightCauchy(const SolveContext<D>& ctx, Eigen::Matrix<double, D, 1>* p, bool* converged) {
  Ranges<D>* r = ctx.ranges;
  Fix* fix = ctx.fix;
  const double c = 2.3849 * ctx.options.range_sigma_m;
  for (int round = 0; round < 30; ++round) {
    r->evaluations += static_cast<int64_t>(r->active.size());
    for (int i : r->active) {
      const double e = std::sqrt((*p - r->a[i]).squaredNorm() + r->off2[i]) - r->d[i];
      r->w[i] = 1.0 / (1.0 + (e / c) * (e / c));
    }
    const Eigen::Matrix<double, D, 1> previous = *p;
    fix->iterations += Refine(*r, r->active, ctx.options.max_iterations, p, converged);
    if ((*p - previous).norm() < kStepTolerance_m) break;
  }
  ctx.workspace.subset.clear();
  r->evaluations += static_cast<int64_t>(r->active.size());
  for (int i : r->active) {
    const double e = std::sqrt((*p - r->a[i]).squaredNorm() + r->off2[i]) - r->d[i];
    if (std::abs(e) <= ctx.threshold) {
      ctx.workspace.subset.push_back(i);
    } else {
      fix->rejected.push_back({r->ids[i], RangeRejection::kOutlier});
      fix->flags |= kOutliersRejected;
    }
  }
  if (static_cast<int>(ctx.workspace.subset.size()) >= SolveContext<D>::kOverDetermined) {
    r->active = ctx.workspace.subset;
  }
}

// k3D with coplanar receivers: the mirror image of p through the receivers'
// plane (normal n, the spread's least axis, through their centroid c) fits
// equally well, p' = p - 2 ((p - c).n) n; keep the one on the side of
// room_side_point_m (default: the floor below the centroid).
void ResolveMirror(const SolveContext<3>& ctx, Eigen::Vector3d* p) {
  const Spread<3>& spread = ctx.spread;
  const Eigen::Vector3d normal = spread.axes.col(0);
  Eigen::Vector3d side_point = ctx.options.room_side_point_m;
  if (!side_point.allFinite()) side_point = {spread.centroid.x(), spread.centroid.y(), 0.0};
  const double side = normal.dot(side_point - spread.centroid);
  const double offset = normal.dot(*p - spread.centroid);
  if (side * offset < 0.0) *p -= 2.0 * offset * normal;
  ctx.fix->flags |= kMirrorResolved;
}

// The covariance from the range noise alone, sigma^2 (J^T J)^-1 at p
// (infinite where J^T J is singular to working precision), flagging poor
// geometry when its largest eigenvalue exceeds max_position_sigma_m^2, and
// the fix's residual RMS, sqrt(F(p) / n).
template <int D>
Eigen::Matrix<double, D, D> NoiseCovariance(const SolveContext<D>& ctx,
                                            const Eigen::Matrix<double, D, 1>& p) {
  Eigen::Matrix<double, D, D> jtj;
  Eigen::Matrix<double, D, 1> jte;
  const double cost = NormalEquations(*ctx.ranges, ctx.ranges->active, p, &jtj, &jte);
  Eigen::Matrix<double, D, D> cov = Eigen::Matrix<double, D, D>::Constant(kInf);
  const double scale = jtj.trace();
  if (scale > 0.0 && std::abs(jtj.determinant()) > 1e-14 * std::pow(scale, D)) {
    cov = ctx.sigma2 * jtj.inverse();
  }
  Eigen::Matrix<double, D, 1> cov_values = Eigen::Matrix<double, D, 1>::Constant(kInf);
  if (cov.allFinite()) EigenSymmetric<D>(cov, &cov_values, nullptr);
  if (!(cov_values.maxCoeff() <=
        ctx.options.max_position_sigma_m * ctx.options.max_position_sigma_m)) {
    ctx.fix->flags |= kPoorGeometry;
  }
  ctx.fix->residual_rms_m = std::sqrt(cost / static_cast<double>(ctx.ranges->active.size()));
  return cov;
}

// Grows the covariance for what the ranges could not check (Fix::covariance_m2):
// no redundant range, ranges that disagree, a fix beyond the prior. False when
// the fix is no position after all: ranges that disagree among themselves,
// with no subset the prior admits, and a fix where the robot cannot be (with
// consistent ranges a fix beyond the prior is kept: the robot may have been
// moved).
template <int D>
bool GrowCovariance(const SolveContext<D>& ctx, const Eigen::Matrix<double, D, 1>& p,
                    Eigen::Matrix<double, D, D>* cov) {
  Fix* fix = ctx.fix;
  const double sigma2 = ctx.sigma2;
  if ((fix->flags & kUnchecked) != 0) {
    *cov *= (sigma2 + ctx.threshold * ctx.threshold / 3.0) / sigma2;
  }
  if ((fix->flags & kInconsistentRanges) != 0) {
    *cov *= std::max(1.0, fix->residual_rms_m * fix->residual_rms_m / sigma2);
  }
  if (ctx.prior != nullptr) {
    const double d = DistanceToPrior(p, *ctx.prior);
    if (d > ctx.prior->radius_m) {
      fix->flags |= kPriorDisagrees;
      if ((fix->flags & kInconsistentRanges) != 0) {
        fix->residual_rms_m = kNaN;
        return false;
      }
      // chi-square with 2 degrees of freedom at 95%: 5.99.
      cov->diagonal().array() += d * d / 5.99;
    }
  }
  return true;
}

// Fills the fix from the final point p and active set: the flags that judge
// it (not converged, inconsistent, unchecked, poor geometry, prior
// disagrees), the covariance, the position in room coordinates, the ranges
// used, and the status: ok only for an over-determined, consistent fix that
// nothing had to be taken out of.
template <int D>
void Finish(const SolveContext<D>& ctx, const Eigen::Matrix<double, D, 1>& p, bool converged) {
  Fix* fix = ctx.fix;
  const Ranges<D>& r = *ctx.ranges;
  if (!converged) fix->flags |= kNotConverged;
  // Whatever the method, a residual beyond the outlier threshold means the
  // ranges disagree: with too little redundancy to tell which one is wrong
  // (three ranges in 2D), or outside robust mode, the fix is still flagged.
  double worst_residual = 0.0;
  Residuals(r, r.active, p, &worst_residual);
  if (worst_residual > ctx.threshold) fix->flags |= kInconsistentRanges;
  // Ranges that count (CountedRanges) less the unknowns, the shared level
  // being one when it was fitted.
  fix->redundant_ranges = CountedRanges(r) - D - ((fix->flags & kSharedLevel) != 0 ? 1 : 0);
  if (fix->redundant_ranges <= 0) fix->flags |= kUnchecked;
  // Poor geometry is judged on the range noise alone, before any growth.
  Eigen::Matrix<double, D, D> cov = NoiseCovariance(ctx, p);
  if (!GrowCovariance(ctx, p, &cov)) return;
  fix->covariance_m2.setZero();
  fix->covariance_m2.topLeftCorner<D, D>() = cov;
  if constexpr (D == 2) {
    fix->position_m = {
        p.x(), p.y(),
        ctx.options.dimension == Dimension::kFixedHeight2D ? ctx.options.fixed_height_m : 0.0};
  } else {
    fix->position_m = p;
  }
  for (int i : r.active) fix->used.push_back(r.ids[i]);
  const uint32_t degrading = kBadRangesDropped | kOutliersRejected | kInconsistentRanges |
                             kPoorGeometry | kNotConverged | kConsensusBudgetExhausted |
                             kUnchecked | kPriorDisagrees | kNlosSuspected;
  fix->status = (fix->flags & degrading) != 0 ? FixStatus::kDegraded : FixStatus::kOk;
}

// One solve in D free coordinates, by stages: collect the valid ranges,
// check that they can determine a point, fit all of them, then per method
// reject outliers by consensus (kRobust) or down-weight them (kCauchy),
// resolve the mirror ambiguity of coplanar receivers, and judge the result.
template <int D>
void SolveIn(const std::vector<RangeMeasurement>& input, const SolverOptions& o,
             const Eigen::Vector3d* guess, const PositionPrior* prior,
             const std::vector<NlosSuspicion>* suspected, Ranges<D>* r, Fix* fix) {
  Collect(input, o, r, fix);
  // Three receivers in 3D are enough when the mirror through their plane is
  // resolved to the room side (three points are always coplanar): exactly
  // determined, flagged unchecked.
  const int minimum = D == 3 ? 3 : SolveContext<D>::kOverDetermined;
  if (static_cast<int>(r->active.size()) < minimum) {
    fix->flags |= kTooFewRanges;
    return;
  }
  SolveContext<D> ctx(o, prior, suspected, r, fix);
  if (!CheckGeometry(&ctx)) return;
  Eigen::Matrix<double, D, 1> p;
  bool converged = false;
  const int iterations = SolveSubset(ctx, r->active, guess, &p, &converged, o.max_iterations);
  if (iterations < 0) {
    fix->flags |= kDegenerateGeometry;
    return;
  }
  fix->iterations = iterations;
  if (o.method == Method::kRobust) DownweightSuspected(ctx, &p, &converged);
  if (o.method == Method::kRobust && !LevelBeforeExclusion(ctx, &p, &converged)) {
    RejectOutliers(ctx, &p, &converged);
    // Ranges that no subset made consistent say nothing trustworthy about
    // a level: it would absorb their echoes as readily as a bias.
    if ((fix->flags & kInconsistentRanges) == 0) FitSharedLevel(ctx, &p, &converged);
  }
  if (o.method == Method::kCauchy) ReweightCauchy(ctx, &p, &converged);
  if constexpr (D == 3) {
    if (ctx.coplanar) ResolveMirror(ctx, &p);
  }
  Finish(ctx, p, converged);
}

}  // namespace

const char* MethodName(Method method) {
  switch (method) {
    case Method::kNelderMead:
      return "nelder-mead";
    case Method::kDefault:
      return "default";
    case Method::kRobust:
      return "robust";
    case Method::kCauchy:
      return "cauchy";
  }
  return "?";
}

bool ParseMethod(const std::string& name, Method* method) {
  for (Method m : {Method::kNelderMead, Method::kDefault, Method::kRobust, Method::kCauchy}) {
    if (name == MethodName(m)) {
      *method = m;
      return true;
    }
  }
  return false;
}

const char* RangeRejectionName(RangeRejection reason) {
  switch (reason) {
    case RangeRejection::kNonFinite:
      return "non_finite_range";
    case RangeRejection::kNegative:
      return "negative_range";
    case RangeRejection::kTooLong:
      return "range_too_long";
    case RangeRejection::kDuplicateReceiver:
      return "duplicate_receiver";
    case RangeRejection::kNonFiniteReceiver:
      return "non_finite_receiver_position";
    case RangeRejection::kOutlier:
      return "outlier";
  }
  return "?";
}

const char* FixFlagName(FixFlag flag) {
  switch (flag) {
    case kTooFewRanges:
      return "too_few_ranges";
    case kCollinearReceivers:
      return "collinear_receivers";
    case kDegenerateGeometry:
      return "degenerate_geometry";
    case kBadRangesDropped:
      return "bad_ranges_dropped";
    case kOutliersRejected:
      return "outliers_rejected";
    case kInconsistentRanges:
      return "inconsistent_ranges";
    case kPoorGeometry:
      return "poor_geometry";
    case kNotConverged:
      return "not_converged";
    case kMirrorResolved:
      return "mirror_resolved";
    case kTooManyRanges:
      return "too_many_ranges";
    case kConsensusBudgetExhausted:
      return "consensus_budget_exhausted";
    case kPriorIdentified:
      return "prior_identified";
    case kUnchecked:
      return "unchecked";
    case kPriorDisagrees:
      return "prior_disagrees";
    case kSharedLevel:
      return "shared_level";
    case kNlosSuspected:
      return "nlos_suspected";
  }
  return "?";
}

std::string DescribeFlags(uint32_t flags) {
  std::string out;
  for (uint32_t bit = 1; bit != 0 && bit <= kLastFixFlag; bit <<= 1) {
    if ((flags & bit) == 0) continue;
    if (!out.empty()) out += ",";
    out += FixFlagName(static_cast<FixFlag>(bit));
  }
  return out;
}

bool SolverOptions::IsValid(std::string* error) const {
  auto fail = [&](const char* what) {
    if (error != nullptr) *error = what;
    return false;
  };
  if (dimension == Dimension::kFixedHeight2D && !std::isfinite(fixed_height_m)) {
    return fail("fixed_height_m must be finite");
  }
  if (!(range_sigma_m > 0.0) || !std::isfinite(range_sigma_m)) {
    return fail("range_sigma_m must be positive");
  }
  if (!(max_range_m > 0.0)) return fail("max_range_m must be positive");
  if (outlier_threshold_m < 0.0 || !std::isfinite(outlier_threshold_m)) {
    return fail("outlier_threshold_m must be zero (automatic) or positive");
  }
  if (max_outliers < 0) return fail("max_outliers must not be negative");
  if (!(max_position_sigma_m > 0.0)) return fail("max_position_sigma_m must be positive");
  if (max_iterations < 1) return fail("max_iterations must be at least 1");
  if (max_ranges < 1) return fail("max_ranges must be at least 1");
  if (max_consensus_solves < 0) return fail("max_consensus_solves must not be negative");
  if (max_consensus_ranges < 0) return fail("max_consensus_ranges must not be negative");
  return true;
}

double SolverOptions::OutlierThreshold() const {
  if (outlier_threshold_m > 0.0) return outlier_threshold_m;
  return std::max(4.0 * range_sigma_m, 0.05);
}

void Solve(const std::vector<RangeMeasurement>& ranges, const SolverOptions& options,
           const Eigen::Vector3d* initial_guess, Fix* fix) {
  Solve(ranges, options, initial_guess, nullptr, fix);
}

void Solve(const std::vector<RangeMeasurement>& ranges, const SolverOptions& options,
           const Eigen::Vector3d* initial_guess, const PositionPrior* prior, Fix* fix) {
  Solve(ranges, options, initial_guess, prior, nullptr, fix);
}

void Solve(const std::vector<RangeMeasurement>& ranges, const SolverOptions& options,
           const Eigen::Vector3d* initial_guess, const PositionPrior* prior,
           const std::vector<NlosSuspicion>* suspected_nlos, Fix* fix) {
  fix->redundant_ranges = 0;
  fix->status = FixStatus::kFailed;
  fix->flags = 0;
  fix->position_m.setConstant(kNaN);
  fix->covariance_m2.setZero();
  fix->residual_rms_m = kNaN;
  fix->used.clear();
  fix->rejected.clear();
  fix->iterations = 0;
  fix->range_evaluations = 0;
  fix->consensus_solves = 0;
  fix->shared_level_m = 0.0;
  if (static_cast<int64_t>(ranges.size()) > options.max_ranges) {
    fix->flags |= kTooManyRanges;
    return;
  }
  // A prior that cannot bound anything is no prior.
  if (prior != nullptr &&
      !(prior->position_m.allFinite() && prior->radius_m > 0.0 && std::isfinite(prior->radius_m))) {
    prior = nullptr;
  }
  Workspace& w = ThreadWorkspace();
  if (options.dimension == Dimension::k3D) {
    SolveIn<3>(ranges, options, initial_guess, prior, suspected_nlos, &w.r3, fix);
    fix->range_evaluations = w.r3.evaluations;
  } else {
    SolveIn<2>(ranges, options, initial_guess, prior, suspected_nlos, &w.r2, fix);
    fix->range_evaluations = w.r2.evaluations;
  }
}

Fix Solve(const std::vector<RangeMeasurement>& ranges, const SolverOptions& options,
          const Eigen::Vector3d* initial_guess) {
  Fix fix;
  Solve(ranges, options, initial_guess, &fix);
  return fix;
}

bool IsCheckedFix(const Fix& fix) {
  constexpr uint32_t kUntrusted =
      kInconsistentRanges | kPoorGeometry | kNotConverged | kConsensusBudgetExhausted | kUnchecked;
  return fix.has_position() && fix.redundant_ranges >= 1 && (fix.flags & kUntrusted) == 0;
}

double CramerRaoRmse(const std::vector<Eigen::Vector3d>& receivers_m,
                     const Eigen::Vector3d& position_m, double sigma_m, Dimension dimension) {
  const int d = dimension == Dimension::k3D ? 3 : 2;
  Eigen::Matrix3d info = Eigen::Matrix3d::Zero();
  for (const Eigen::Vector3d& a : receivers_m) {
    Eigen::Vector3d u = position_m - a;
    if (dimension == Dimension::kPlanar2D) u.z() = 0.0;
    const double n = u.norm();
    if (n < 1e-12) continue;
    u /= n;
    info += u * u.transpose() / (sigma_m * sigma_m);
  }
  const Eigen::MatrixXd block = info.topLeftCorner(d, d);
  Eigen::FullPivLU<Eigen::MatrixXd> lu(block);
  if (!lu.isInvertible()) return kInf;
  return std::sqrt(lu.inverse().trace());
}

}  // namespace roomfix::trilat
