#include "core/analysis/circle_fit.h"

#include <gsl/gsl_blas.h>
#include <gsl/gsl_matrix.h>
#include <gsl/gsl_multifit_nlinear.h>
#include <gsl/gsl_vector.h>

#include <cmath>
#include <functional>

#include "core/world/gsl_errors.h"

namespace roomfix::analysis {
namespace {

constexpr double kPi = 3.14159265358979323846;

// Residuals and Jacobian of one model at parameters x.
struct Model {
  const std::vector<TimedPoint>* points;
  size_t residuals;
  std::function<void(const gsl_vector*, gsl_vector*)> f;
  std::function<void(const gsl_vector*, gsl_matrix*)> df;
};

int ModelF(const gsl_vector* x, void* params, gsl_vector* f) {
  static_cast<Model*>(params)->f(x, f);
  return GSL_SUCCESS;
}
int ModelDf(const gsl_vector* x, void* params, gsl_matrix* j) {
  static_cast<Model*>(params)->df(x, j);
  return GSL_SUCCESS;
}

struct Solution {
  bool ok = false;
  std::string message;
  std::vector<double> x, sigma;
  double rss = 0;
  int iterations = 0;
};

// Runs GSL's trust-region solver from `start`; sigmas from s^2 (J^T J)^-1.
Solution Solve(Model* model, const std::vector<double>& start) {
  Solution s;
  const size_t p = start.size();
  const size_t n = model->residuals;
  gsl_multifit_nlinear_fdf fdf;
  fdf.f = ModelF;
  fdf.df = ModelDf;
  fdf.fvv = nullptr;
  fdf.n = n;
  fdf.p = p;
  fdf.params = model;
  gsl_multifit_nlinear_parameters params = gsl_multifit_nlinear_default_parameters();
  gsl_multifit_nlinear_workspace* w =
      gsl_multifit_nlinear_alloc(gsl_multifit_nlinear_trust, &params, n, p);
  gsl_vector* x0 = gsl_vector_alloc(p);
  for (size_t k = 0; k < p; ++k) gsl_vector_set(x0, k, start[k]);
  int info = 0;
  int status = gsl_multifit_nlinear_init(x0, &fdf, w);
  if (status == GSL_SUCCESS) {
    status = gsl_multifit_nlinear_driver(200, 1e-10, 1e-10, 0.0, nullptr, nullptr, &info, w);
  }
  if (status != GSL_SUCCESS) {
    s.message = std::string("the fit did not converge: ") + gsl_strerror(status);
  } else {
    gsl_matrix* covar = gsl_matrix_alloc(p, p);
    gsl_multifit_nlinear_covar(gsl_multifit_nlinear_jac(w), 0.0, covar);
    double rss = 0;
    gsl_blas_ddot(gsl_multifit_nlinear_residual(w), gsl_multifit_nlinear_residual(w), &rss);
    const double s2 = rss / static_cast<double>(n - p);
    s.rss = rss;
    for (size_t k = 0; k < p; ++k) {
      s.x.push_back(gsl_vector_get(gsl_multifit_nlinear_position(w), k));
      s.sigma.push_back(std::sqrt(s2 * gsl_matrix_get(covar, k, k)));
    }
    s.iterations = static_cast<int>(gsl_multifit_nlinear_niter(w));
    s.ok = true;
    for (double v : s.x) s.ok = s.ok && std::isfinite(v);
    for (double v : s.sigma) s.ok = s.ok && std::isfinite(v);
    if (!s.ok) s.message = "degenerate: the points do not determine every parameter";
    gsl_matrix_free(covar);
  }
  gsl_vector_free(x0);
  gsl_multifit_nlinear_free(w);
  return s;
}

// The first five parameters of either fit are (r, x0, y0, vx, vy). A
// negative radius is the same circle (the motion fit absorbs it in its
// phase), so the magnitude is kept.
void SetCircle(const Solution& s, DriftingCircle* c) {
  c->radius_m = std::abs(s.x[0]);
  c->cx_m = s.x[1];
  c->cy_m = s.x[2];
  c->vx_mps = s.x[3];
  c->vy_mps = s.x[4];
  c->radius_sigma_m = s.sigma[0];
  c->cx_sigma_m = s.sigma[1];
  c->cy_sigma_m = s.sigma[2];
  c->vx_sigma_mps = s.sigma[3];
  c->vy_sigma_mps = s.sigma[4];
}

// Algebraic (Kasa) circle: x^2 + y^2 + D x + E y + F = 0 by linear least
// squares; a start for the drifting-circle fit. False for collinear points.
bool AlgebraicCircle(const std::vector<TimedPoint>& pts, double* cx, double* cy, double* r) {
  double sxx = 0, sxy = 0, syy = 0, sx = 0, sy = 0, sxz = 0, syz = 0, sz = 0;
  const double n = static_cast<double>(pts.size());
  for (const auto& p : pts) {
    const double z = p.x_m * p.x_m + p.y_m * p.y_m;
    sxx += p.x_m * p.x_m;
    sxy += p.x_m * p.y_m;
    syy += p.y_m * p.y_m;
    sx += p.x_m;
    sy += p.y_m;
    sxz += p.x_m * z;
    syz += p.y_m * z;
    sz += z;
  }
  // Normal equations for (D, E, F): [sxx sxy sx; sxy syy sy; sx sy n] = -[sxz syz sz].
  const double a[3][3] = {{sxx, sxy, sx}, {sxy, syy, sy}, {sx, sy, n}};
  const double b[3] = {-sxz, -syz, -sz};
  const double det = a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1]) -
                     a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0]) +
                     a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0]);
  if (std::abs(det) < 1e-12 * std::pow(sxx + syy + n, 3)) return false;
  auto solve = [&](int col) {
    double m[3][3];
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) m[i][j] = j == col ? b[i] : a[i][j];
    }
    return (m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) -
            m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
            m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])) /
           det;
  };
  const double d = solve(0), e = solve(1), f = solve(2);
  *cx = -d / 2;
  *cy = -e / 2;
  const double r2 = *cx * *cx + *cy * *cy - f;
  if (!(r2 > 0)) return false;
  *r = std::sqrt(r2);
  return true;
}

}  // namespace

DriftingCircleFit FitDriftingCircle(const std::vector<TimedPoint>& points) {
  DriftingCircleFit out;
  if (points.size() < 6) {
    out.message = "need at least 6 points for 5 parameters, got " + std::to_string(points.size());
    return out;
  }
  double cx, cy, r;
  if (!AlgebraicCircle(points, &cx, &cy, &r)) {
    out.message = "degenerate: the points lie on a line";
    return out;
  }
  Model m;
  m.points = &points;
  m.residuals = points.size();
  // x = (r, x0, y0, vx, vy)
  m.f = [&points](const gsl_vector* x, gsl_vector* f) {
    for (size_t i = 0; i < points.size(); ++i) {
      const auto& p = points[i];
      const double dx = gsl_vector_get(x, 1) + gsl_vector_get(x, 3) * p.t_s - p.x_m;
      const double dy = gsl_vector_get(x, 2) + gsl_vector_get(x, 4) * p.t_s - p.y_m;
      gsl_vector_set(f, i, gsl_vector_get(x, 0) - std::hypot(dx, dy));
    }
  };
  m.df = [&points](const gsl_vector* x, gsl_matrix* j) {
    for (size_t i = 0; i < points.size(); ++i) {
      const auto& p = points[i];
      const double dx = gsl_vector_get(x, 1) + gsl_vector_get(x, 3) * p.t_s - p.x_m;
      const double dy = gsl_vector_get(x, 2) + gsl_vector_get(x, 4) * p.t_s - p.y_m;
      const double d = std::max(std::hypot(dx, dy), 1e-12);
      gsl_matrix_set(j, i, 0, 1.0);
      gsl_matrix_set(j, i, 1, -dx / d);
      gsl_matrix_set(j, i, 2, -dy / d);
      gsl_matrix_set(j, i, 3, -dx / d * p.t_s);
      gsl_matrix_set(j, i, 4, -dy / d * p.t_s);
    }
  };
  const Solution s = Solve(&m, {r, cx, cy, 0.0, 0.0});
  out.message = s.message;
  out.iterations = s.iterations;
  if (!s.ok) return out;
  out.usable = true;
  SetCircle(s, &out);
  out.residual_std_m = std::sqrt(s.rss / static_cast<double>(points.size() - 5));
  return out;
}

CircularMotionFit FitCircularMotion(const std::vector<TimedPoint>& points) {
  CircularMotionFit out;
  if (points.size() < 8) {
    out.message = "need at least 8 points, got " + std::to_string(points.size());
    return out;
  }
  const DriftingCircleFit circle = FitDriftingCircle(points);
  if (!circle.usable) {
    out.message = circle.message;
    return out;
  }
  // Start for w and phi: the angle about the (drifting) centre, unwrapped,
  // against time by linear least squares.
  double st = 0, sa = 0, stt = 0, sta = 0, previous = 0, offset = 0;
  const double n = static_cast<double>(points.size());
  for (size_t i = 0; i < points.size(); ++i) {
    const auto& p = points[i];
    const double raw = std::atan2(p.y_m - circle.cy_m - circle.vy_mps * p.t_s,
                                  p.x_m - circle.cx_m - circle.vx_mps * p.t_s);
    if (i > 0) {
      const double jump = raw + offset - previous;
      if (jump > kPi) offset -= 2 * kPi;
      if (jump < -kPi) offset += 2 * kPi;
    }
    const double angle = raw + offset;
    previous = angle;
    st += p.t_s;
    sa += angle;
    stt += p.t_s * p.t_s;
    sta += p.t_s * angle;
  }
  const double denom = n * stt - st * st;
  const double w0 = denom != 0 ? (n * sta - st * sa) / denom : 0.0;
  const double phi0 = (sa - w0 * st) / n;

  Model m;
  m.points = &points;
  m.residuals = 2 * points.size();
  // x = (r, x0, y0, vx, vy, w, phi); residuals (model - measured) in x, then y.
  m.f = [&points](const gsl_vector* x, gsl_vector* f) {
    for (size_t i = 0; i < points.size(); ++i) {
      const auto& p = points[i];
      const double a = gsl_vector_get(x, 5) * p.t_s + gsl_vector_get(x, 6);
      gsl_vector_set(f, 2 * i,
                     gsl_vector_get(x, 1) + gsl_vector_get(x, 3) * p.t_s +
                         gsl_vector_get(x, 0) * std::cos(a) - p.x_m);
      gsl_vector_set(f, 2 * i + 1,
                     gsl_vector_get(x, 2) + gsl_vector_get(x, 4) * p.t_s +
                         gsl_vector_get(x, 0) * std::sin(a) - p.y_m);
    }
  };
  m.df = [&points](const gsl_vector* x, gsl_matrix* j) {
    const double r = gsl_vector_get(x, 0);
    for (size_t i = 0; i < points.size(); ++i) {
      const double t = points[i].t_s;
      const double a = gsl_vector_get(x, 5) * t + gsl_vector_get(x, 6);
      const double c = std::cos(a), s = std::sin(a);
      const double row_x[7] = {c, 1, 0, t, 0, -r * s * t, -r * s};
      const double row_y[7] = {s, 0, 1, 0, t, r * c * t, r * c};
      for (size_t k = 0; k < 7; ++k) {
        gsl_matrix_set(j, 2 * i, k, row_x[k]);
        gsl_matrix_set(j, 2 * i + 1, k, row_y[k]);
      }
    }
  };
  const Solution s = Solve(
      &m, {circle.radius_m, circle.cx_m, circle.cy_m, circle.vx_mps, circle.vy_mps, w0, phi0});
  out.message = s.message;
  out.iterations = s.iterations;
  if (!s.ok) return out;
  out.usable = true;
  SetCircle(s, &out);
  out.angular_speed_radps = s.x[5];
  // A negative radius is the same circle half a turn on.
  out.phase_rad = s.x[6] + (s.x[0] < 0 ? kPi : 0.0);
  out.phase_rad = std::remainder(out.phase_rad, 2 * kPi);
  if (out.phase_rad < 0) out.phase_rad += 2 * kPi;
  out.angular_speed_sigma_radps = s.sigma[5];
  out.phase_sigma_rad = s.sigma[6];
  double sum = 0, sum2 = 0;
  for (const auto& p : points) {
    const double a = out.angular_speed_radps * p.t_s + out.phase_rad;
    const double e = std::hypot(out.cx_m + out.vx_mps * p.t_s + out.radius_m * std::cos(a) - p.x_m,
                                out.cy_m + out.vy_mps * p.t_s + out.radius_m * std::sin(a) - p.y_m);
    sum += e;
    sum2 += e * e;
  }
  out.mean_error_m = sum / n;
  out.std_error_m = std::sqrt(std::max(0.0, sum2 / n - out.mean_error_m * out.mean_error_m));
  return out;
}

}  // namespace roomfix::analysis
