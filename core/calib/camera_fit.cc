#include "core/calib/camera_fit.h"

#include <gsl/gsl_multifit_nlinear.h>
#include <gsl/gsl_vector.h>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <sstream>

#include "core/world/gsl_errors.h"

namespace roomfix::calib {
namespace {

// The full parameter vector; FitCamera frees a subset of it.
enum Param { kFx, kFy, kCx, kCy, kK1, kK2, kK3, kK4, kW0, kW1, kW2, kC0, kC1, kC2, kNumParams };

// The room point's pixel without ProjectToPixel's Z > 0 check: the formula
// continues smoothly past 90 degrees, which keeps the least-squares cost
// differentiable should an iterate swing a point behind the camera.
Eigen::Vector2d ProjectAny(const CameraModel& m, const Eigen::Vector3d& room_m) {
  const Eigen::Vector3d p = m.pose.R_room_from_camera.transpose() * (room_m - m.pose.position_m);
  const double r_xy = std::hypot(p.x(), p.y());
  const double theta = std::atan2(r_xy, p.z());
  const double t2 = theta * theta;
  const auto& k = m.intrinsics.k;
  const double theta_d = theta * (1 + t2 * (k[0] + t2 * (k[1] + t2 * (k[2] + t2 * k[3]))));
  const double scale = r_xy > 1e-12 * std::abs(p.z()) ? theta_d / r_xy : 1.0 / p.z();
  return {m.intrinsics.fx_px * scale * p.x() + m.intrinsics.cx_px,
          m.intrinsics.fy_px * scale * p.y() + m.intrinsics.cy_px};
}

Eigen::Matrix3d ExpRotation(const Eigen::Vector3d& w) {
  const double angle = w.norm();
  if (angle < 1e-300) return Eigen::Matrix3d::Identity();
  return Eigen::AngleAxisd(angle, w / angle).toRotationMatrix();
}

struct Problem {
  const std::vector<Correspondence>* points = nullptr;
  std::vector<size_t> used;  // indices into *points
  CameraModel initial;
  CameraFitOptions options;
  std::vector<int> free;  // Param of each free parameter
  double full[kNumParams] = {};

  size_t Residuals() const {
    return 2 * used.size() + (options.position_prior_sigma_m > 0 ? 3 : 0);
  }

  // The model for the free parameters x (the rest from `full`).
  CameraModel Model(const gsl_vector* x) const {
    double q[kNumParams];
    std::copy(full, full + kNumParams, q);
    for (size_t i = 0; i < free.size(); ++i) q[free[i]] = gsl_vector_get(x, i);
    if (options.equal_focal_lengths) {
      q[kFy] = q[kFx] * initial.intrinsics.fy_px / initial.intrinsics.fx_px;
    }
    CameraModel m = initial;
    m.intrinsics.fx_px = q[kFx];
    m.intrinsics.fy_px = q[kFy];
    m.intrinsics.cx_px = q[kCx];
    m.intrinsics.cy_px = q[kCy];
    for (int j = 0; j < 4; ++j) m.intrinsics.k[j] = q[kK1 + j];
    m.pose.R_room_from_camera =
        initial.pose.R_room_from_camera * ExpRotation(Eigen::Vector3d(q[kW0], q[kW1], q[kW2]));
    m.pose.position_m = Eigen::Vector3d(q[kC0], q[kC1], q[kC2]);
    return m;
  }
};

int ResidualF(const gsl_vector* x, void* params, gsl_vector* f) {
  const auto* problem = static_cast<const Problem*>(params);
  const CameraModel m = problem->Model(x);
  const auto& pts = *problem->points;
  for (size_t i = 0; i < problem->used.size(); ++i) {
    const Correspondence& c = pts[problem->used[i]];
    const Eigen::Vector2d uv = ProjectAny(m, Eigen::Vector3d(c.x_m, c.y_m, c.height_m));
    gsl_vector_set(f, 2 * i, uv.x() - c.u_px);
    gsl_vector_set(f, 2 * i + 1, uv.y() - c.v_px);
  }
  if (problem->options.position_prior_sigma_m > 0) {
    const double w = problem->options.pixel_sigma_px / problem->options.position_prior_sigma_m;
    const auto& prior = problem->options.prior_position_m;
    const Eigen::Vector3d centre = prior ? Eigen::Vector3d((*prior)[0], (*prior)[1], (*prior)[2])
                                         : problem->initial.pose.position_m;
    const Eigen::Vector3d d = m.pose.position_m - centre;
    for (int a = 0; a < 3; ++a) gsl_vector_set(f, 2 * problem->used.size() + a, w * d[a]);
  }
  return GSL_SUCCESS;
}

struct SolveResult {
  bool ok = false;
  std::string message;
  CameraModel model;
  int iterations = 0;
};

// One Levenberg-Marquardt run over problem->used, from problem->full.
SolveResult Solve(Problem* problem) {
  SolveResult out;
  const size_t p = problem->free.size();
  const size_t n = problem->Residuals();
  gsl_multifit_nlinear_fdf fdf;
  fdf.f = ResidualF;
  fdf.df = nullptr;  // finite differences (central, below)
  fdf.fvv = nullptr;
  fdf.n = n;
  fdf.p = p;
  fdf.params = problem;
  gsl_multifit_nlinear_parameters params = gsl_multifit_nlinear_default_parameters();
  params.fdtype = GSL_MULTIFIT_NLINEAR_CTRDIFF;
  gsl_multifit_nlinear_workspace* w =
      gsl_multifit_nlinear_alloc(gsl_multifit_nlinear_trust, &params, n, p);
  gsl_vector* x0 = gsl_vector_alloc(p);
  for (size_t j = 0; j < p; ++j) gsl_vector_set(x0, j, problem->full[problem->free[j]]);
  int info = 0;
  int status = gsl_multifit_nlinear_init(x0, &fdf, w);
  if (status == GSL_SUCCESS) {
    status = gsl_multifit_nlinear_driver(static_cast<size_t>(problem->options.max_iterations),
                                         1e-12, 1e-12, 0.0, nullptr, nullptr, &info, w);
  }
  out.iterations = static_cast<int>(gsl_multifit_nlinear_niter(w));
  if (status != GSL_SUCCESS) {
    out.message = std::string("the fit did not converge: ") + gsl_strerror(status) + " after " +
                  std::to_string(out.iterations) + " iterations";
  } else {
    const gsl_vector* x = gsl_multifit_nlinear_position(w);
    out.ok = true;
    for (size_t j = 0; j < p; ++j) out.ok = out.ok && std::isfinite(gsl_vector_get(x, j));
    if (out.ok) {
      out.model = problem->Model(x);
      for (size_t j = 0; j < p; ++j) problem->full[problem->free[j]] = gsl_vector_get(x, j);
    } else {
      out.message = "the fit did not converge: non-finite parameters";
    }
  }
  gsl_vector_free(x0);
  gsl_multifit_nlinear_free(w);
  return out;
}

void Reject(const std::string& why, const CameraModel& initial, CameraFitSummary* s) {
  s->usable = false;
  s->model = initial;
  s->message = why;
}

// Whether the options and the initial model can start a fit at all: valid
// options, at least kMinPoints points (fewer leave too few degrees of freedom
// to see an outlier), positive focal lengths and image size, a finite pose.
bool CheckSetup(size_t num_points, const CameraModel& initial, const CameraFitOptions& options,
                std::string* why) {
  std::string error;
  if (!options.IsValid(&error)) {
    *why = "invalid options: " + error;
    return false;
  }
  const int n = static_cast<int>(num_points);
  if (n < kMinPoints) {
    *why = "too few points: need at least " + std::to_string(kMinPoints) + ", got " +
           std::to_string(n);
    return false;
  }
  const FisheyeIntrinsics& in = initial.intrinsics;
  if (!(in.fx_px > 0 && in.fy_px > 0 && in.width_px > 0 && in.height_px > 0) ||
      !initial.pose.position_m.allFinite() || !initial.pose.R_room_from_camera.allFinite()) {
    *why = "invalid initial model: focal lengths and image size must be positive";
    return false;
  }
  return true;
}

// Whether point i can be a view of a marker by the initial camera: finite,
// inside the image (give or take CameraModel::kPixelMarginPx), at a height
// between the floor and the camera at camera_z_m, and in front of the
// initial camera (Z > 0 in its frame): a ceiling camera sees every marker in
// front of it, so a marker at or behind it means the initial pose is wrong,
// not the point.
bool CheckPoint(int i, const Correspondence& c, const CameraModel& initial, double camera_z_m,
                std::string* why) {
  const FisheyeIntrinsics& in = initial.intrinsics;
  const double margin = CameraModel::kPixelMarginPx;
  const std::string where = "point " + std::to_string(i) + ": ";
  if (!std::isfinite(c.u_px) || !std::isfinite(c.v_px) || !std::isfinite(c.x_m) ||
      !std::isfinite(c.y_m)) {
    *why = where + "non-finite pixel or position";
    return false;
  }
  if (!(c.u_px >= -margin && c.u_px <= in.width_px + margin && c.v_px >= -margin &&
        c.v_px <= in.height_px + margin)) {
    std::ostringstream os;
    os << where << "pixel (" << c.u_px << ", " << c.v_px << ") is outside the " << in.width_px
       << " x " << in.height_px << " image";
    *why = os.str();
    return false;
  }
  if (!std::isfinite(c.height_m) || c.height_m < 0 || c.height_m >= camera_z_m) {
    std::ostringstream os;
    os << where << "height " << c.height_m << " m is inconsistent: must be >= 0 and below the "
       << "camera at " << camera_z_m << " m";
    *why = os.str();
    return false;
  }
  const Eigen::Vector3d p_cam =
      initial.pose.R_room_from_camera.transpose() *
      (Eigen::Vector3d(c.x_m, c.y_m, c.height_m) - initial.pose.position_m);
  if (!(p_cam.z() > 0)) {
    *why = where + "the marker is behind the initial camera: wrong initial pose";
    return false;
  }
  return true;
}

// Whether the points span the floor in two directions: the smaller principal
// standard deviation of their (x, y), the square root of the scatter
// matrix's smaller eigenvalue, must reach 1 cm. Points on a line leave the
// rotation about it, and the mapping across it, undetermined.
bool CheckSpread(const std::vector<Correspondence>& points, std::string* why) {
  const int n = static_cast<int>(points.size());
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (const Correspondence& c : points) mean += Eigen::Vector2d(c.x_m, c.y_m);
  mean /= n;
  Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();
  for (const Correspondence& c : points) {
    const Eigen::Vector2d d = Eigen::Vector2d(c.x_m, c.y_m) - mean;
    cov += d * d.transpose();
  }
  cov /= n;
  const double smallest_spread_m = std::sqrt(
      std::max(0.0, Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(cov).eigenvalues()(0)));
  if (smallest_spread_m < 0.01) {
    std::ostringstream os;
    os << "all points lie on a line: their spread across it is " << smallest_spread_m * 1000
       << " mm (need 10 mm)";
    *why = os.str();
    return false;
  }
  return true;
}

// Every check FitCamera's header lists before a fit is tried, in that order;
// *why is the first that fails.
bool CheckInputs(const std::vector<Correspondence>& points, const CameraModel& initial,
                 const CameraFitOptions& options, std::string* why) {
  if (!CheckSetup(points.size(), initial, options, why)) return false;
  // Markers lie below the camera: the initial one and, when the mount was
  // measured, the mount.
  const double camera_z_m =
      options.prior_position_m && options.position_prior_sigma_m > 0
          ? std::min(initial.pose.position_m.z(), (*options.prior_position_m)[2])
          : initial.pose.position_m.z();
  for (size_t i = 0; i < points.size(); ++i) {
    if (!CheckPoint(static_cast<int>(i), points[i], initial, camera_z_m, why)) return false;
  }
  return CheckSpread(points, why);
}

// The least-squares problem over all points: the full parameter vector from
// the initial model (the rotation perturbation w at 0, so R = R_initial), and
// the parameters the options free: fy only without equal_focal_lengths,
// k1..k_n only with fit_distortion (n = distortion_terms).
Problem MakeProblem(const std::vector<Correspondence>& points, const CameraModel& initial,
                    const CameraFitOptions& options) {
  const FisheyeIntrinsics& in = initial.intrinsics;
  Problem problem;
  problem.points = &points;
  problem.initial = initial;
  problem.options = options;
  problem.full[kFx] = in.fx_px;
  problem.full[kFy] = in.fy_px;
  problem.full[kCx] = in.cx_px;
  problem.full[kCy] = in.cy_px;
  for (int j = 0; j < 4; ++j) problem.full[kK1 + j] = in.k[j];
  for (int a = 0; a < 3; ++a) problem.full[kC0 + a] = initial.pose.position_m[a];
  for (int q = 0; q < kNumParams; ++q) {
    if (q == kFy && options.equal_focal_lengths) continue;
    if (q >= kK1 && q <= kK4 && (!options.fit_distortion || q - kK1 >= options.distortion_terms)) {
      continue;
    }
    problem.free.push_back(q);
  }
  for (size_t i = 0; i < points.size(); ++i) problem.used.push_back(i);
  return problem;
}

// The fit with its outliers left out, and every point's residual against it.
struct OutlierFit {
  CameraModel model;
  int iterations = 0;
  // Per input point: |pixel - projection| against `model`, and whether it
  // was left out.
  std::vector<double> residual_px;
  std::vector<bool> outlier;
};

// Fits, then leaves out the worst point while its residual exceeds
// outlier_px and more than kMinPoints remain, refitting each time from the
// previous solution (a least-squares fit spreads one outlier's error over
// all points, so only the worst is surely one). Refuses at once when more
// points than max_outliers are over outlier_px: refitting once per outlier
// is quadratic in the points. False with *why when GSL fails or the points
// do not fit one camera; fit->iterations counts every run either way.
bool FitLeavingOutOutliers(Problem* problem, OutlierFit* fit, std::string* why) {
  const std::vector<Correspondence>& points = *problem->points;
  const CameraFitOptions& options = problem->options;
  const int n = static_cast<int>(points.size());
  fit->outlier.assign(n, false);
  fit->residual_px.assign(n, 0.0);
  std::vector<bool>& outlier = fit->outlier;
  std::vector<double>& residual = fit->residual_px;
  int above_before = -1;  // points off the fit before the last one was left out
  for (;;) {
    const SolveResult r = Solve(problem);
    fit->iterations += r.iterations;
    if (!r.ok) {
      *why = r.message;
      return false;
    }
    fit->model = r.model;
    int worst = -1;
    for (int i = 0; i < n; ++i) {
      const Correspondence& c = points[i];
      const Eigen::Vector2d uv = ProjectAny(r.model, Eigen::Vector3d(c.x_m, c.y_m, c.height_m));
      residual[i] = std::hypot(uv.x() - c.u_px, uv.y() - c.v_px);
      if (!outlier[i] && (worst < 0 || residual[i] > residual[worst])) worst = i;
    }
    if (residual[worst] <= options.outlier_px ||
        static_cast<int>(problem->used.size()) <= kMinPoints) {
      return true;
    }
    if (options.max_outliers >= 0) {
      int left_out = 0, above = 0;
      for (int i = 0; i < n; ++i) {
        left_out += outlier[i] ? 1 : 0;
        above += !outlier[i] && residual[i] > options.outlier_px ? 1 : 0;
      }
      // One wrong row (a swapped or mistyped coordinate) pulls the whole
      // least-squares fit, so that every point may be off by more than
      // outlier_px while it is in: leaving the worst out and refitting is
      // then what shows it (issue #28: all 36 points were called off for
      // one wrong row). So the worst is left out while that brings the
      // points off the fit down by more than itself; refused when it does
      // not, with every residual against the last fit (the caller names the
      // worst point).
      const bool leaving_out_helped = above_before < 0 || above < above_before - 1;
      if (left_out + above > options.max_outliers && !leaving_out_helped) {
        std::ostringstream os;
        os << left_out + above << " of " << n << " points are more than " << options.outlier_px
           << " px off the fit, over the " << options.max_outliers
           << " that may be left out as outliers: the points do not fit one camera";
        *why = os.str();
        return false;
      }
      above_before = above;
    }
    outlier[worst] = true;
    problem->used.erase(
        std::find(problem->used.begin(), problem->used.end(), static_cast<size_t>(worst)));
  }
}

// The summary of a usable fit: RMS and maximum residual over the points
// used, and the one-line message. A point still above outlier_px (kept
// because no more could be left out) is marked an outlier in the summary,
// though it was fitted.
void Summarise(const OutlierFit& fit, size_t num_used, const CameraFitOptions& options,
               CameraFitSummary* s) {
  const std::vector<double>& residual = fit.residual_px;
  s->usable = true;
  s->model = fit.model;
  s->iterations = fit.iterations;
  s->residual_px = residual;
  s->outlier = fit.outlier;
  double sum2 = 0;
  int flagged = 0, still_above = 0;
  for (size_t i = 0; i < residual.size(); ++i) {
    if (fit.outlier[i]) {
      ++flagged;
      continue;
    }
    sum2 += residual[i] * residual[i];
    s->max_px = std::max(s->max_px, residual[i]);
    if (residual[i] > options.outlier_px) {
      ++still_above;
      s->outlier[i] = true;
    }
  }
  s->rms_px = std::sqrt(sum2 / static_cast<double>(num_used));
  std::ostringstream os;
  os.precision(3);
  os << "fitted " << num_used << " points, rms " << s->rms_px << " px";
  if (flagged > 0)
    os << "; " << flagged << " outlier(s) above " << options.outlier_px << " px left out";
  if (still_above > 0) {
    os << "; " << still_above << " more above " << options.outlier_px
       << " px kept (too few points to leave out)";
  }
  s->message = os.str();
}

}  // namespace

bool CameraFitOptions::IsValid(std::string* error) const {
  std::string e;
  if (max_iterations < 1) e = "max_iterations must be at least 1";
  if (!(outlier_px > 0)) e = "outlier_px must be positive";
  if (distortion_terms < 1 || distortion_terms > 4) e = "distortion_terms must be 1 to 4";
  if (!(position_prior_sigma_m >= 0) || !std::isfinite(position_prior_sigma_m)) {
    e = "position_prior_sigma_m must be finite and >= 0 (0: no prior)";
  }
  if (!(pixel_sigma_px > 0) || !std::isfinite(pixel_sigma_px)) {
    e = "pixel_sigma_px must be finite and positive";
  }
  if (prior_position_m &&
      !(std::isfinite((*prior_position_m)[0]) && std::isfinite((*prior_position_m)[1]) &&
        std::isfinite((*prior_position_m)[2]))) {
    e = "prior_position_m must be finite";
  }
  if (error != nullptr) *error = e;
  return e.empty();
}

CameraFitSummary FitCamera(const std::vector<Correspondence>& points, const CameraModel& initial,
                           const CameraFitOptions& options) {
  CameraFitSummary s;
  s.model = initial;
  std::string why;
  if (!CheckInputs(points, initial, options, &why)) {
    Reject(why, initial, &s);
    return s;
  }
  Problem problem = MakeProblem(points, initial, options);
  OutlierFit fit;
  if (!FitLeavingOutOutliers(&problem, &fit, &why)) {
    Reject(why, initial, &s);
    s.iterations = fit.iterations;
    // Against the last fit tried: the caller names the worst point.
    s.residual_px = fit.residual_px;
    return s;
  }
  Summarise(fit, problem.used.size(), options, &s);
  return s;
}

}  // namespace roomfix::calib
