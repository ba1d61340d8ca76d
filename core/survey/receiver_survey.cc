#include "core/survey/receiver_survey.h"

#include <fmt/format.h>
#include <gsl/gsl_matrix.h>
#include <gsl/gsl_multilarge_nlinear.h>
#include <gsl/gsl_vector.h>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <numeric>

#include "core/trilat/trilateration.h"
#include "core/world/gsl_errors.h"

namespace roomfix::survey {
namespace {

using Eigen::Matrix2d;
using Eigen::MatrixXd;
using Eigen::Vector2d;
using Eigen::Vector3d;
using Eigen::VectorXd;

double Median(std::vector<double> v) {
  if (v.empty()) return kNaN;
  const size_t mid = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + static_cast<long>(mid), v.end());
  double m = v[mid];
  if (v.size() % 2 == 0) {
    m = 0.5 * (m + *std::max_element(v.begin(), v.begin() + static_cast<long>(mid)));
  }
  return m;
}

// The least-squares problem: receiver ("global") parameters first, then two
// per firing when the beacon positions are unknown. Each residual touches
// one firing, so the beacons are eliminated firing by firing (Reduced).
struct Problem {
  struct Obs {
    int firing = 0;
    int receiver = 0;
    double d = 0.0;
    bool inlier = true;
  };
  std::vector<ReceiverModel> rx;
  std::vector<std::array<int, 3>> pos_idx;
  std::vector<int> off_idx;
  std::vector<int> scale_idx;
  int num_global = 0;
  // Beacon positions; the x, y of firing f are parameters num_global + 2 f
  // when free_beacons.
  std::vector<Vector3d> beacon;
  bool free_beacons = false;
  std::vector<Obs> obs;

  int NumParams() const {
    return num_global + (free_beacons ? 2 * static_cast<int>(beacon.size()) : 0);
  }

  VectorXd Pack() const {
    VectorXd x(NumParams());
    for (size_t r = 0; r < rx.size(); ++r) {
      for (int k = 0; k < 3; ++k) {
        if (pos_idx[r][k] >= 0) x[pos_idx[r][k]] = rx[r].position_m[k];
      }
      if (off_idx[r] >= 0) x[off_idx[r]] = rx[r].range_offset_m;
      if (scale_idx[r] >= 0) x[scale_idx[r]] = rx[r].range_scale;
    }
    if (free_beacons) {
      for (size_t f = 0; f < beacon.size(); ++f)
        x.segment<2>(num_global + 2 * f) = beacon[f].head<2>();
    }
    return x;
  }

  void Unpack(const VectorXd& x) {
    for (size_t r = 0; r < rx.size(); ++r) {
      for (int k = 0; k < 3; ++k) {
        if (pos_idx[r][k] >= 0) rx[r].position_m[k] = x[pos_idx[r][k]];
      }
      if (off_idx[r] >= 0) rx[r].range_offset_m = x[off_idx[r]];
      if (scale_idx[r] >= 0) rx[r].range_scale = x[scale_idx[r]];
    }
    if (free_beacons) {
      for (size_t f = 0; f < beacon.size(); ++f)
        beacon[f].head<2>() = x.segment<2>(num_global + 2 * f);
    }
  }

  double Residual(const Obs& o) const {
    const ReceiverModel& m = rx[o.receiver];
    return m.range_scale * (m.position_m - beacon[o.firing]).norm() + m.range_offset_m - o.d;
  }
};

// The least-squares problem GSL sees: the receiver parameters only. With
// free beacons, each firing's (x, y) is eliminated (variable projection):
// for given receiver parameters it is the best fit to that firing's inlier
// ranges (SolveBeacon), and the Jacobian is the receiver block projected
// off the beacon directions, J = J_g - J_b (J_b^T J_b)^-1 J_b^T J_g per
// firing (Kaufman's approximation). At a solution J_b^T r = 0, so
// J^T r = J_g^T r: the same stationary points as the joint problem, which
// GSL could only solve densely (600 firings: 1240 unknowns) where this is
// a 40-column fit.
struct Reduced {
  Problem* p = nullptr;
  std::vector<int> inliers;                 // obs indices, in residual order
  std::vector<std::vector<int>> by_firing;  // inlier obs indices per firing
};

// The derivatives of observation o's residual: by the receiver parameters
// (k entries at idx) and by the beacon's x, y (w).
int ResidualGradient(const Problem& p, const Problem::Obs& o, std::array<int, 5>* idx,
                     std::array<double, 5>* val, Vector2d* w) {
  const ReceiverModel& m = p.rx[o.receiver];
  const Vector3d delta = m.position_m - p.beacon[o.firing];
  const double dist = std::max(delta.norm(), 1e-9);
  const Vector3d u = delta / dist;
  int k = 0;
  for (int c = 0; c < 3; ++c) {
    if (p.pos_idx[o.receiver][c] >= 0) {
      (*idx)[k] = p.pos_idx[o.receiver][c];
      (*val)[k++] = m.range_scale * u[c];
    }
  }
  if (p.off_idx[o.receiver] >= 0) {
    (*idx)[k] = p.off_idx[o.receiver];
    (*val)[k++] = 1.0;
  }
  if (p.scale_idx[o.receiver] >= 0) {
    (*idx)[k] = p.scale_idx[o.receiver];
    (*val)[k++] = dist;
  }
  *w = -m.range_scale * u.head<2>();
  return k;
}

double FiringCost(const Problem& p, const std::vector<int>& obs) {
  double c = 0.0;
  for (int i : obs) c += std::pow(p.Residual(p.obs[i]), 2);
  return c;
}

// Gauss-Newton on one firing's (x, y), from its last estimate, halving a
// step that does not lower the cost. Stops when the step is below 1e-12 m
// or no step helps; a beacon no range constrains keeps its position.
void SolveBeacon(Problem* p, const std::vector<int>& obs, int firing) {
  Vector3d& q = p->beacon[static_cast<size_t>(firing)];
  std::array<int, 5> idx{};
  std::array<double, 5> val{};
  for (int it = 0; it < 50; ++it) {
    Matrix2d h = Matrix2d::Identity() * 1e-12;
    Vector2d g = Vector2d::Zero();
    for (int i : obs) {
      Vector2d w;
      ResidualGradient(*p, p->obs[i], &idx, &val, &w);
      h += w * w.transpose();
      g += w * p->Residual(p->obs[i]);
    }
    const Vector2d step = -h.ldlt().solve(g);
    if (!step.allFinite()) return;
    const double cost = FiringCost(*p, obs);
    const Vector2d start = q.head<2>();
    double t = 1.0;
    for (; t > 1e-6; t *= 0.5) {
      q.head<2>() = start + t * step;
      if (FiringCost(*p, obs) <= cost) break;
    }
    if (t <= 1e-6) {
      q.head<2>() = start;
      return;
    }
    if (t * step.norm() < 1e-12) return;
  }
}

double SquaredNorm(const gsl_vector* v) {
  double sum = 0.0;
  for (size_t i = 0; i < v->size; ++i) sum += gsl_vector_get(v, i) * gsl_vector_get(v, i);
  return sum;
}

void SolveBeacons(Reduced* r) {
  if (!r->p->free_beacons) return;
  for (size_t f = 0; f < r->by_firing.size(); ++f) {
    SolveBeacon(r->p, r->by_firing[f], static_cast<int>(f));
  }
}

// The receiver parameters from GSL's x, then the beacons that fit them best.
void SetGlobals(const gsl_vector* x, Reduced* r) {
  Problem* p = r->p;
  VectorXd full = p->Pack();
  for (int i = 0; i < p->num_global; ++i) full[i] = gsl_vector_get(x, static_cast<size_t>(i));
  p->Unpack(full);
  SolveBeacons(r);
}

int ReducedF(const gsl_vector* x, void* params, gsl_vector* f) {
  auto* r = static_cast<Reduced*>(params);
  SetGlobals(x, r);
  for (size_t i = 0; i < r->inliers.size(); ++i) {
    gsl_vector_set(f, i, r->p->Residual(r->p->obs[static_cast<size_t>(r->inliers[i])]));
  }
  return GSL_SUCCESS;
}

// J u, J^T u and J^T J of the projected Jacobian without forming it (GSL's
// multilarge interface): row i is g_i - w_i^T A_f^-1 C_f, with g_i the
// receiver row (at most 5 entries), w_i the beacon row, A_f = sum w w^T and
// C_f = sum w g^T over firing f's inliers. As the projection is idempotent,
// J^T J = sum g g^T - sum_f C_f^T A_f^-1 C_f: the Schur complement the
// normal equations had, a num_global-square matrix.
struct Products {
  MatrixXd jtj;            // J^T J, num_global square
  VectorXd jtu;            // J^T u for u by observation (u_of)
  std::vector<double> ju;  // J ug by observation
};

Products ReducedProducts(const Reduced& r, const std::vector<double>& u_of, const VectorXd& ug) {
  const Problem& p = *r.p;
  const Eigen::Index ng = p.num_global;
  Products out{MatrixXd::Zero(ng, ng), VectorXd::Zero(ng), std::vector<double>(p.obs.size(), 0.0)};
  std::array<int, 5> idx{};
  std::array<double, 5> val{};
  // With fixed beacons every observation is its own group, without projection.
  const auto& groups = p.free_beacons ? r.by_firing : std::vector<std::vector<int>>{r.inliers};
  for (const std::vector<int>& obs : groups) {
    Matrix2d a = Matrix2d::Identity() * 1e-12;
    Eigen::Matrix<double, 2, Eigen::Dynamic> c =
        Eigen::Matrix<double, 2, Eigen::Dynamic>::Zero(2, ng);
    Vector2d wu = Vector2d::Zero();
    std::vector<Vector2d> ws;
    for (int i : obs) {
      Vector2d w;
      const int k = ResidualGradient(p, p.obs[static_cast<size_t>(i)], &idx, &val, &w);
      const double ui = u_of[static_cast<size_t>(i)];
      double gu = 0.0;
      for (int e = 0; e < k; ++e) {
        out.jtu[idx[e]] += val[e] * ui;
        gu += val[e] * ug[idx[e]];
        for (int f = 0; f < k; ++f) out.jtj(idx[e], idx[f]) += val[e] * val[f];
        c.col(idx[e]) += w * val[e];
      }
      out.ju[static_cast<size_t>(i)] = gu;
      a += w * w.transpose();
      wu += w * ui;
      ws.push_back(w);
    }
    if (!p.free_beacons) continue;
    const Eigen::Matrix<double, 2, Eigen::Dynamic> ainv_c = a.ldlt().solve(c);
    out.jtj.noalias() -= c.transpose() * ainv_c;
    out.jtu.noalias() -= ainv_c.transpose() * wu;
    const Vector2d cu = ainv_c * ug;
    for (size_t j = 0; j < obs.size(); ++j) out.ju[static_cast<size_t>(obs[j])] -= ws[j].dot(cu);
  }
  return out;
}

int ReducedDf(CBLAS_TRANSPOSE_t trans, const gsl_vector* x, const gsl_vector* u, void* params,
              gsl_vector* v, gsl_matrix* jtj) {
  auto* r = static_cast<Reduced*>(params);
  SetGlobals(x, r);
  const Problem& p = *r->p;
  const Eigen::Index ng = p.num_global;
  std::vector<double> u_of(p.obs.size(), 0.0);
  VectorXd ug = VectorXd::Zero(ng);
  if (trans == CblasTrans) {
    for (size_t i = 0; i < r->inliers.size(); ++i) {
      u_of[static_cast<size_t>(r->inliers[i])] = gsl_vector_get(u, i);
    }
  } else {
    for (Eigen::Index j = 0; j < ng; ++j) ug[j] = gsl_vector_get(u, static_cast<size_t>(j));
  }
  const Products products = ReducedProducts(*r, u_of, ug);
  if (trans == CblasTrans) {
    for (Eigen::Index j = 0; j < ng; ++j) {
      gsl_vector_set(v, static_cast<size_t>(j), products.jtu[j]);
    }
  } else {
    for (size_t i = 0; i < r->inliers.size(); ++i) {
      gsl_vector_set(v, i, products.ju[static_cast<size_t>(r->inliers[i])]);
    }
  }
  if (jtj != nullptr) {
    for (Eigen::Index i = 0; i < ng; ++i) {
      for (Eigen::Index j = 0; j < ng; ++j) {
        gsl_matrix_set(jtj, static_cast<size_t>(i), static_cast<size_t>(j), products.jtj(i, j));
      }
    }
  }
  return GSL_SUCCESS;
}

Reduced MakeReduced(Problem* p) {
  Reduced r;
  r.p = p;
  r.by_firing.assign(p->beacon.size(), {});
  for (size_t i = 0; i < p->obs.size(); ++i) {
    if (!p->obs[i].inlier) continue;
    r.inliers.push_back(static_cast<int>(i));
    r.by_firing[static_cast<size_t>(p->obs[i].firing)].push_back(static_cast<int>(i));
  }
  return r;
}

// Levenberg-Marquardt on the inliers (GSL's trust-region solver over the
// receiver parameters, beacons eliminated). Returns the iterations used;
// a fit GSL cannot start (fewer ranges than parameters) or that stops
// early keeps the best parameters reached, and the caller judges them by
// their residuals and covariance.
int Minimise(Problem* p, int max_iterations) {
  Reduced r = MakeReduced(p);
  const size_t n = r.inliers.size();
  const size_t np = static_cast<size_t>(p->num_global);
  if (np == 0 || n < np) {
    if (np == 0) SolveBeacons(&r);
    return 0;
  }
  gsl_multilarge_nlinear_fdf fdf;
  fdf.f = ReducedF;
  fdf.df = ReducedDf;
  fdf.fvv = nullptr;
  fdf.n = n;
  fdf.p = np;
  fdf.params = &r;
  fdf.nevalf = fdf.nevaldfu = fdf.nevaldf2 = fdf.nevalfvv = 0;
  gsl_multilarge_nlinear_parameters params = gsl_multilarge_nlinear_default_parameters();
  gsl_multilarge_nlinear_workspace* w =
      gsl_multilarge_nlinear_alloc(gsl_multilarge_nlinear_trust, &params, n, np);
  if (w == nullptr) return 0;
  const VectorXd start = p->Pack();
  gsl_vector* x0 = gsl_vector_alloc(np);
  for (size_t j = 0; j < np; ++j) gsl_vector_set(x0, j, start[static_cast<Eigen::Index>(j)]);
  int iterations = 0;
  if (gsl_multilarge_nlinear_init(x0, &fdf, w) == GSL_SUCCESS) {
    // Each iterate is one accepted step (GSL_ENOPROG: none lowers the cost).
    // Converged when the cost falls by no more than 1e-14 of itself or no
    // parameter moves by 1e-10 (0.1 nm on metres): GSL's own relative step
    // test never passes for a parameter at 0, an offset say.
    double cost = SquaredNorm(gsl_multilarge_nlinear_residual(w));
    std::vector<double> last(np);
    while (iterations < max_iterations) {
      for (size_t j = 0; j < np; ++j)
        last[j] = gsl_vector_get(gsl_multilarge_nlinear_position(w), j);
      if (gsl_multilarge_nlinear_iterate(w) != GSL_SUCCESS) break;
      ++iterations;
      const double new_cost = SquaredNorm(gsl_multilarge_nlinear_residual(w));
      double step = 0.0;
      for (size_t j = 0; j < np; ++j) {
        step = std::max(step,
                        std::abs(gsl_vector_get(gsl_multilarge_nlinear_position(w), j) - last[j]));
      }
      const double improvement = cost - new_cost;
      cost = new_cost;
      if (improvement <= 1e-14 * (cost + 1e-12) || step < 1e-10) break;
    }
    SetGlobals(gsl_multilarge_nlinear_position(w), &r);
  }
  gsl_vector_free(x0);
  gsl_multilarge_nlinear_free(w);
  return iterations;
}

struct RobustFit {
  int iterations = 0;
  double sigma = kNaN;
  double rms = kNaN;
  int inliers = 0;
  int rejected = 0;
};

RobustFit FitRobust(Problem* p, const SurveyOptions& options) {
  RobustFit out;
  for (int round = 0; round < options.max_rejection_rounds; ++round) {
    out.iterations += Minimise(p, options.max_iterations);
    std::vector<double> r(p->obs.size());
    for (size_t i = 0; i < p->obs.size(); ++i) r[i] = p->Residual(p->obs[i]);
    const double med = Median(r);
    std::vector<double> dev(r.size());
    for (size_t i = 0; i < r.size(); ++i) dev[i] = std::abs(r[i] - med);
    out.sigma = std::max(1.4826 * Median(dev), options.min_sigma_m);
    bool changed = false;
    for (size_t i = 0; i < r.size(); ++i) {
      const bool inlier = std::abs(r[i] - med) <= options.outlier_k * out.sigma;
      changed |= inlier != p->obs[i].inlier;
      p->obs[i].inlier = inlier;
    }
    if (!changed) break;
  }
  double ss = 0.0;
  out.inliers = 0;
  for (const auto& o : p->obs) {
    if (o.inlier) {
      ss += std::pow(p->Residual(o), 2);
      ++out.inliers;
    }
  }
  out.rejected = static_cast<int>(p->obs.size()) - out.inliers;
  out.rms = out.inliers > 0 ? std::sqrt(ss / out.inliers) : kNaN;
  return out;
}

void AssignIndices(Problem* p, const SurveyOptions& options, bool with_scale) {
  int next = 0;
  p->pos_idx.assign(p->rx.size(), {-1, -1, -1});
  p->off_idx.assign(p->rx.size(), -1);
  p->scale_idx.assign(p->rx.size(), -1);
  for (size_t r = 0; r < p->rx.size(); ++r) {
    const bool pinned = std::find(options.pinned_ids.begin(), options.pinned_ids.end(),
                                  p->rx[r].id) != options.pinned_ids.end();
    if (options.estimate_positions && !(p->free_beacons && pinned)) {
      p->pos_idx[r][0] = next++;
      p->pos_idx[r][1] = next++;
      if (options.estimate_heights) p->pos_idx[r][2] = next++;
    }
    if (options.estimate_offsets) p->off_idx[r] = next++;
    if (with_scale) p->scale_idx[r] = next++;
  }
  p->num_global = next;
}

// Fills the result from a fitted problem.
void Summarise(const Problem& p, const RobustFit& fit, const SurveyOptions& options,
               SurveyResult* result) {
  // S: J^T J of the receiver parameters with the beacons eliminated (the
  // Schur complement of the full J^T J), regularised by 1e-12 as the fit's.
  Problem copy = p;
  const Reduced reduced = MakeReduced(&copy);
  MatrixXd s =
      ReducedProducts(reduced, std::vector<double>(p.obs.size(), 0.0), VectorXd::Zero(p.num_global))
          .jtj;
  s.diagonal().array() += 1e-12;
  const Eigen::Index ng = s.rows();
  // Column scaling so that the condition number is unit-free.
  VectorXd d(ng);
  for (Eigen::Index i = 0; i < ng; ++i) d[i] = s(i, i) > 0 ? 1.0 / std::sqrt(s(i, i)) : 1.0;
  const MatrixXd scaled = d.asDiagonal() * s * d.asDiagonal();
  MatrixXd cov = MatrixXd::Zero(ng, ng);
  const int dof = fit.inliers - p.NumParams();
  const double sigma2 = dof > 0 ? fit.rms * fit.rms * fit.inliers / dof : kNaN;
  if (ng > 0) {
    Eigen::SelfAdjointEigenSolver<MatrixXd> eig(scaled);
    const VectorXd ev = eig.eigenvalues();
    // Sorted ascending.
    const double max_ev = ev[ng - 1];
    const double threshold = 1e-12 * max_ev;
    int nulls = 0;
    double min_ev = max_ev;
    VectorXd inv_ev(ng);
    for (Eigen::Index i = 0; i < ng; ++i) {
      if (ev[i] <= threshold) {
        ++nulls;
        inv_ev[i] = 0.0;
      } else {
        inv_ev[i] = 1.0 / ev[i];
        min_ev = std::min(min_ev, ev[i]);
      }
    }
    result->null_directions = nulls;
    result->condition_number =
        nulls > 0 ? std::numeric_limits<double>::infinity() : max_ev / min_ev;
    cov = d.asDiagonal() * eig.eigenvectors() * inv_ev.asDiagonal() *
          eig.eigenvectors().transpose() * d.asDiagonal() * sigma2;
  } else {
    result->condition_number = 1.0;
  }
  auto sigma_of = [&](int i) { return i >= 0 ? std::sqrt(std::max(cov(i, i), 0.0)) : 0.0; };
  std::map<int, std::pair<int, int>> counts;
  for (const auto& o : p.obs) {
    auto& c = counts[p.rx[o.receiver].id];
    (o.inlier ? c.first : c.second)++;
  }
  result->receivers.clear();
  for (size_t r = 0; r < p.rx.size(); ++r) {
    ReceiverEstimate e;
    e.id = p.rx[r].id;
    e.position_m = p.rx[r].position_m;
    for (int k = 0; k < 3; ++k) e.position_sigma_m[k] = sigma_of(p.pos_idx[r][k]);
    e.range_offset_m = p.rx[r].range_offset_m;
    e.range_offset_sigma_m = sigma_of(p.off_idx[r]);
    e.range_scale = p.rx[r].range_scale;
    e.range_scale_sigma = sigma_of(p.scale_idx[r]);
    e.position_estimated = p.pos_idx[r][0] >= 0;
    e.height_estimated = p.pos_idx[r][2] >= 0;
    e.scale_estimated = p.scale_idx[r] >= 0;
    e.pinned = p.free_beacons && !e.position_estimated && options.estimate_positions;
    e.ranges_used = counts[e.id].first;
    e.ranges_rejected = counts[e.id].second;
    result->receivers.push_back(e);
    // What the data did not determine.
    const char* axes = "xyz";
    for (int k = 0; k < 3; ++k) {
      if (p.pos_idx[r][k] >= 0 && !(e.position_sigma_m[k] <= options.undetermined_sigma_m &&
                                    cov(p.pos_idx[r][k], p.pos_idx[r][k]) > 0)) {
        result->notes.push_back(
            "receiver " + std::to_string(e.id) + ": " + axes[k] +
            fmt::format(" not determined (1-sigma {:.3f} m)", e.position_sigma_m[k]));
      }
    }
    if (p.off_idx[r] >= 0 && !(e.range_offset_sigma_m <= options.undetermined_sigma_m)) {
      result->notes.push_back(
          "receiver " + std::to_string(e.id) +
          fmt::format(": offset not determined (1-sigma {:.3f} m)", e.range_offset_sigma_m));
    }
  }
  result->ranges_used = fit.inliers;
  result->ranges_rejected = fit.rejected;
  result->residual_rms_m = fit.rms;
  result->sigma_m = fit.sigma;
  result->iterations = fit.iterations;
  result->parameters = p.NumParams();
  if (result->null_directions > 0) {
    result->notes.push_back(std::to_string(result->null_directions) +
                            " parameter combination(s) not determined by the data "
                            "(J^T J singular): their values stay at the starting ones");
  }
  result->notes.push_back(
      fmt::format("condition number of the scaled normal matrix {:.3g}", result->condition_number));
}

bool CollectObservations(const std::vector<ReceiverModel>& initial,
                         const std::vector<Firing>& firings, const SurveyOptions& options,
                         bool need_reference, size_t min_ranges, Problem* p,
                         std::vector<const Firing*>* used, int* invalid) {
  p->rx = initial;
  std::map<int, int> index;
  for (size_t r = 0; r < initial.size(); ++r) index[initial[r].id] = static_cast<int>(r);
  *invalid = 0;
  for (const Firing& f : firings) {
    if (need_reference && !f.has_reference()) continue;
    std::vector<Problem::Obs> obs;
    for (const RangeObservation& o : f.ranges) {
      auto it = index.find(o.receiver_id);
      if (it == index.end() || !std::isfinite(o.raw_range_m) || o.raw_range_m <= 0 ||
          o.raw_range_m > options.max_range_m) {
        ++*invalid;
        continue;
      }
      bool duplicate = false;
      for (const auto& prev : obs) duplicate |= prev.receiver == it->second;
      if (duplicate) {
        ++*invalid;
        continue;
      }
      obs.push_back({static_cast<int>(used->size()), it->second, o.raw_range_m, true});
    }
    if (obs.size() < min_ranges) continue;
    p->obs.insert(p->obs.end(), obs.begin(), obs.end());
    used->push_back(&f);
  }
  return !used->empty();
}

// Fits with and without scale as the options say; returns the fit kept.
SurveyResult FitAndSummarise(Problem base, const SurveyOptions& options, int invalid,
                             int firings_used) {
  SurveyResult result;
  result.ranges_invalid = invalid;
  result.firings_used = firings_used;
  bool with_scale = options.scale == ScaleMode::kOn;
  Problem p = base;
  AssignIndices(&p, options, with_scale);
  RobustFit fit = FitRobust(&p, options);
  if (options.scale == ScaleMode::kAuto) {
    // Span of geometric ranges per receiver.
    std::map<int, std::pair<double, double>> span;
    for (const auto& o : p.obs) {
      const double dist = (p.rx[o.receiver].position_m - p.beacon[o.firing]).norm();
      auto [it, fresh] = span.try_emplace(o.receiver, dist, dist);
      it->second.first = std::min(it->second.first, dist);
      it->second.second = std::max(it->second.second, dist);
    }
    double min_span = std::numeric_limits<double>::infinity();
    for (const auto& [r, s] : span) min_span = std::min(min_span, s.second - s.first);
    if (min_span < options.min_range_span_for_scale_m) {
      result.notes.push_back(fmt::format(
          "scale not estimated: some receiver's ranges span only {:.2f} m (< {:.2f} m needed to "
          "tell a scale from an offset)",
          min_span, options.min_range_span_for_scale_m));
    } else {
      Problem q = base;
      AssignIndices(&q, options, true);
      RobustFit fit_q = FitRobust(&q, options);
      SurveyResult probe;
      Summarise(q, fit_q, options, &probe);
      double max_z = 0.0;
      for (const auto& e : probe.receivers) {
        if (e.range_scale_sigma > 0) {
          max_z = std::max(max_z, std::abs(e.range_scale - 1.0) / e.range_scale_sigma);
        }
      }
      if (max_z > 3.0) {
        with_scale = true;
        p = q;
        fit = fit_q;
        result.notes.push_back(
            fmt::format("scale estimated: ranges span >= {:.2f} m per receiver and a scale differs "
                        "from 1 by {:.1f} sigma",
                        min_span, max_z));
      } else {
        result.notes.push_back(
            fmt::format("scale not estimated: no scale differs from 1 by more than 3 sigma "
                        "(largest {:.1f} sigma)",
                        max_z));
      }
    }
  } else if (with_scale) {
    result.notes.push_back("scale estimated: requested");
  }
  result.scale_estimated = with_scale;
  Summarise(p, fit, options, &result);
  result.usable = fit.inliers > result.parameters && std::isfinite(fit.rms);
  result.message = result.usable ? "ok" : "fewer inlier ranges than parameters";
  return result;
}

}  // namespace

bool SurveyOptions::IsValid(std::string* error) const {
  auto fail = [error](const std::string& what) {
    if (error != nullptr) *error = what;
    return false;
  };
  if (!(outlier_k > 0)) return fail("outlier_k must be positive");
  if (!(min_sigma_m > 0)) return fail("min_sigma_m must be positive");
  if (max_rejection_rounds < 1) return fail("max_rejection_rounds must be at least 1");
  if (max_iterations < 1) return fail("max_iterations must be at least 1");
  if (!(max_range_m > 0)) return fail("max_range_m must be positive");
  if (max_self_calibration_firings < 1) return fail("max_self_calibration_firings must be >= 1");
  return true;
}

const ReceiverEstimate* SurveyResult::Find(int id) const {
  for (const auto& r : receivers) {
    if (r.id == id) return &r;
  }
  return nullptr;
}

std::vector<ReceiverModel> SurveyResult::Models() const {
  std::vector<ReceiverModel> out;
  for (const auto& r : receivers) out.push_back(r.Model());
  return out;
}

AlignmentSummary AlignToReference(const std::vector<ReferenceSample>& track, int64_t max_gap_us,
                                  std::vector<Firing>* firings) {
  AlignmentSummary s;
  std::vector<ReferenceSample> t = track;
  std::sort(t.begin(), t.end(), [](const auto& a, const auto& b) { return a.utime < b.utime; });
  for (Firing& f : *firings) {
    f.reference_m = Vector3d::Constant(kNaN);
    if (t.empty() || f.utime < t.front().utime || f.utime > t.back().utime) {
      ++s.outside_span;
      continue;
    }
    auto hi = std::lower_bound(t.begin(), t.end(), f.utime,
                               [](const ReferenceSample& a, int64_t u) { return a.utime < u; });
    if (hi->utime == f.utime) {
      f.reference_m = {hi->x_m, hi->y_m, f.beacon_height_m};
      ++s.aligned;
      continue;
    }
    auto lo = hi - 1;
    if (hi->utime - lo->utime > max_gap_us) {
      ++s.in_gap;
      continue;
    }
    const double a =
        static_cast<double>(f.utime - lo->utime) / static_cast<double>(hi->utime - lo->utime);
    f.reference_m = {lo->x_m + a * (hi->x_m - lo->x_m), lo->y_m + a * (hi->y_m - lo->y_m),
                     f.beacon_height_m};
    ++s.aligned;
  }
  return s;
}

SurveyResult SurveyWithReference(const std::vector<ReceiverModel>& initial,
                                 const std::vector<Firing>& firings, const SurveyOptions& options) {
  SurveyResult bad;
  if (!options.IsValid(&bad.message)) return bad;
  Problem p;
  std::vector<const Firing*> used;
  int invalid = 0;
  if (!CollectObservations(initial, firings, options, true, 1, &p, &used, &invalid)) {
    bad.message = "no firing with a reference position and a valid range";
    return bad;
  }
  for (const Firing* f : used) p.beacon.push_back(f->reference_m);
  SurveyResult result = FitAndSummarise(p, options, invalid, static_cast<int>(used.size()));
  if (options.estimate_positions && options.estimate_heights) {
    bool one_height = true;
    for (const Firing* f : used) one_height &= f->reference_m.z() == used.front()->reference_m.z();
    if (one_height) {
      result.notes.push_back(
          "the beacon rode at one height: each receiver's height is known up to its mirror "
          "image through that height, and the one on the side of the starting value was kept");
    }
  }
  return result;
}

SurveyResult SurveyWithoutReference(const std::vector<ReceiverModel>& initial,
                                    const std::vector<Firing>& firings,
                                    const SurveyOptions& options) {
  SurveyResult bad;
  if (!options.IsValid(&bad.message)) return bad;
  if (options.estimate_positions) {
    int pinned = 0;
    for (const auto& r : initial) {
      pinned += std::count(options.pinned_ids.begin(), options.pinned_ids.end(), r.id) > 0;
    }
    if (pinned < 2) {
      bad.message =
          "self-calibration needs two receivers with surveyed positions (pinned_ids): without "
          "them the floor-plane rotation and translation are not determined";
      return bad;
    }
  }
  // Evenly subsample firings heard by at least 4 receivers.
  std::vector<Firing> usable;
  for (const Firing& f : firings) {
    if (f.ranges.size() >= 4) usable.push_back(f);
  }
  std::vector<Firing> chosen;
  const size_t max_f = static_cast<size_t>(options.max_self_calibration_firings);
  if (usable.size() > max_f) {
    for (size_t i = 0; i < max_f; ++i) chosen.push_back(usable[i * usable.size() / max_f]);
  } else {
    chosen = usable;
  }
  Problem p;
  std::vector<const Firing*> used;
  int invalid = 0;
  CollectObservations(initial, chosen, options, false, 4, &p, &used, &invalid);
  // Start each beacon from trilateration with the initial receivers.
  trilat::SolverOptions so;
  so.dimension = trilat::Dimension::kFixedHeight2D;
  Problem q;
  q.rx = p.rx;
  std::vector<int> keep(used.size(), 0);
  for (size_t f = 0; f < used.size(); ++f) {
    so.fixed_height_m = used[f]->beacon_height_m;
    std::vector<trilat::RangeMeasurement> ranges;
    for (const auto& o : p.obs) {
      if (o.firing != static_cast<int>(f)) continue;
      ranges.push_back(
          {p.rx[o.receiver].id, p.rx[o.receiver].position_m, p.rx[o.receiver].Correct(o.d)});
    }
    const trilat::Fix fix = trilat::Solve(ranges, so);
    if (fix.has_position()) {
      keep[f] = static_cast<int>(q.beacon.size()) + 1;
      q.beacon.push_back(fix.position_m);
    }
  }
  for (const auto& o : p.obs) {
    if (keep[o.firing] > 0) q.obs.push_back({keep[o.firing] - 1, o.receiver, o.d, true});
  }
  if (q.beacon.size() < 3) {
    bad.message = "fewer than 3 firings heard by 4 or more receivers could be trilaterated";
    return bad;
  }
  q.free_beacons = true;
  SurveyResult result = FitAndSummarise(q, options, invalid, static_cast<int>(q.beacon.size()));
  if (options.estimate_positions) {
    std::string pins;
    for (int id : options.pinned_ids) pins += (pins.empty() ? "" : ",") + std::to_string(id);
    result.notes.push_back(
        "no reference: positions are relative to the pinned receivers " + pins +
        "; the mirror image through the vertical plane joining them fits equally well and the "
        "one nearer the starting positions was kept");
    if (options.estimate_heights) {
      result.notes.push_back(
          "receiver heights enter only as |z - beacon height|: the side of the starting value "
          "was kept");
    }
  }
  return result;
}

void SplitByTime(const std::vector<Firing>& firings, double block_s, int period,
                 std::vector<Firing>* fit, std::vector<Firing>* held_out) {
  fit->clear();
  held_out->clear();
  if (firings.empty()) return;
  int64_t t0 = firings.front().utime;
  for (const auto& f : firings) t0 = std::min(t0, f.utime);
  const double block_us = std::max(block_s, 1e-3) * 1e6;
  for (const auto& f : firings) {
    const auto block = static_cast<int64_t>(static_cast<double>(f.utime - t0) / block_us);
    (period > 0 && block % period == period - 1 ? held_out : fit)->push_back(f);
  }
}

TrilaterationError EvaluateTrilateration(const std::vector<ReceiverModel>& receivers,
                                         const std::vector<Firing>& firings) {
  TrilaterationError out;
  std::map<int, const ReceiverModel*> index;
  for (const auto& r : receivers) index[r.id] = &r;
  std::vector<double> errors;
  trilat::SolverOptions so;
  so.dimension = trilat::Dimension::kFixedHeight2D;
  std::vector<trilat::RangeMeasurement> ranges;
  for (const Firing& f : firings) {
    if (!f.has_reference()) continue;
    ++out.firings;
    ranges.clear();
    for (const auto& o : f.ranges) {
      auto it = index.find(o.receiver_id);
      if (it == index.end() || !std::isfinite(o.raw_range_m) || o.raw_range_m <= 0) continue;
      ranges.push_back({o.receiver_id, it->second->position_m, it->second->Correct(o.raw_range_m)});
    }
    so.fixed_height_m = f.beacon_height_m;
    const trilat::Fix fix = trilat::Solve(ranges, so);
    if (!fix.has_position()) continue;
    errors.push_back((fix.position_m.head<2>() - f.reference_m.head<2>()).norm());
  }
  out.fixes = static_cast<int>(errors.size());
  if (errors.empty()) return out;
  double ss = 0.0;
  double sum = 0.0;
  for (double e : errors) {
    ss += e * e;
    sum += e;
  }
  out.rmse_m = std::sqrt(ss / errors.size());
  out.mean_m = sum / errors.size();
  std::sort(errors.begin(), errors.end());
  out.median_m = Median(errors);
  out.p95_m = errors[std::min(errors.size() - 1, static_cast<size_t>(0.95 * errors.size()))];
  out.max_m = errors.back();
  return out;
}

}  // namespace roomfix::survey
