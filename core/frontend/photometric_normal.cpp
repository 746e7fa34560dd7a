#include "core/frontend/photometric_normal.hpp"

#include <cmath>

#include <Eigen/Cholesky>

#include "core/frontend/correlated_residuals.hpp"
#include "core/frontend/patch_warp.hpp"
#include "core/geometry/projection.hpp"

namespace vantage {

namespace {

constexpr int kParams = 6;  // u (2), tilt (2), gain, offset
using Matrix6d = Eigen::Matrix<double, kParams, kParams>;
using Vector6d = Eigen::Matrix<double, kParams, 1>;
// Residual variance floor: the 8-bit quantization of both images.
constexpr double kMinResidualVariance = 2.0 / 12.0;

// What the plane maps need of the two views, the same for every normal tried: the directions to the
// cameras and the Jacobians of X's projections (plane_affine's, computed once per estimate).
struct PlaneViews {
  Eigen::Vector3d to_reference;
  Eigen::Vector3d to_target;
  Eigen::Matrix<double, 2, 3> H_reference;
  Eigen::Matrix<double, 2, 3> H_target;
};

// False when X is behind either camera.
bool plane_views(const PhotometricNormalQuery& q, const PinholeIntrinsics& k, PlaneViews* out) {
  out->to_reference = (q.reference.position_world - q.X_world).normalized();
  out->to_target = (q.target.position_world - q.X_world).normalized();
  Eigen::Vector2d unused;
  return ok(project_with_jacobian(q.X_world, q.reference, k, &unused, &out->H_reference)) &&
         ok(project_with_jacobian(q.X_world, q.target, k, &unused, &out->H_target));
}

// The target-per-reference map of the plane with normal n at X (inverse of plane_affine's).
Status target_map(const PhotometricNormalQuery& q, const PlaneViews& views, const Eigen::Vector3d& n,
                  Eigen::Matrix2d* M) {
  if (!(n.dot(views.to_reference) > q.min_facing_cos) || !(n.dot(views.to_target) > q.min_facing_cos)) {
    return Status::kBehindCamera;
  }
  // plane_affine's checks and map with the Jacobians computed once.
  const Eigen::Vector3f n_float = n.cast<float>();
  const Eigen::Vector3d n_checked = n_float.cast<double>();
  if (!n_checked.allFinite() || std::abs(n_checked.norm() - 1.0) > 1e-3) return Status::kBehindCamera;
  Eigen::Matrix2d A;
  if (!ok(plane_affine_from_jacobians(views.H_reference, views.H_target, n_float, &A, nullptr))) {
    return Status::kBehindCamera;
  }
  *M = A.inverse();
  return M->allFinite() ? Status::kOk : Status::kBehindCamera;
}

// LDLT solves one column at a time (vector solves; a matrix right-hand side goes through Eigen's blocked
// triangular solver, more code for a 6x6).
Matrix6d solve_columns(const Eigen::LDLT<Matrix6d>& ldlt, const Matrix6d& rhs) {
  Matrix6d out;
  for (int j = 0; j < kParams; ++j) {
    const Vector6d column = rhs.col(j);
    out.col(j) = ldlt.solve(column);
  }
  return out;
}

// The bilinear sample at (x, y) and the central differences of its samples one pixel away on each axis,
// from one 4x4 neighbourhood: the five samples share their fractional parts, so the eight row blends
// serve them all (12 pixel reads instead of 20). The same arithmetic as interpolating each of the five
// on its own (to the last bit while x +- 1 and y +- 1 keep x's and y's binary exponent). The caller keeps x, y in
// [1, size - 2).
void sample_with_gradient(const GrayImageView& image, double x, double y, double* value, Eigen::Vector2d* g) {
  const BilinearCell cell = bilinear_cell(x, y);
  const std::int32_t x0 = cell.x0;
  const std::int32_t y0 = cell.y0;
  const double fx = cell.fx;
  const double fy = cell.fy;
  // Row r's blend of columns c and c + 1.
  auto blend = [&](std::int32_t c, std::int32_t r) { return (1.0 - fx) * image.at(c, r) + fx * image.at(c + 1, r); };
  auto vertical = [fy](double top, double bottom) { return (1.0 - fy) * top + fy * bottom; };
  const double centre_0 = blend(x0, y0);
  const double centre_1 = blend(x0, y0 + 1);
  *value = vertical(centre_0, centre_1);
  const double right = vertical(blend(x0 + 1, y0), blend(x0 + 1, y0 + 1));
  const double left = vertical(blend(x0 - 1, y0), blend(x0 - 1, y0 + 1));
  const double down = vertical(centre_1, blend(x0, y0 + 2));
  const double up = vertical(blend(x0, y0 - 1), centre_0);
  *g = Eigen::Vector2d(0.5 * (right - left), 0.5 * (down - up));
}

struct NormalEquations {
  Matrix6d JtJ = Matrix6d::Zero();
  Vector6d Jtr = Vector6d::Zero();
  double sum_r2 = 0.0;
  int count = 0;
  PatchResiduals<kParams> rows;  // for the correlation model
};

// The normal equations of the photometric fit at parameters theta (u, t, gain, offset). Not inlined:
// its temporaries would share the caller's stack frame, beyond the core's limit under ASan.
[[gnu::noinline]] Status accumulate(const GrayImageView& image, const std::array<std::uint8_t, kPatchPixels>& patch,
                  const PhotometricNormalQuery& q, const PlaneViews& views, const Eigen::Vector3d& e1,
                  const Eigen::Vector3d& e2, const Vector6d& theta, NormalEquations* out) {
  const Eigen::Vector3d n0 = q.normal_world.cast<double>();
  auto normal_at = [&](double t1, double t2) { return (n0 + t1 * e1 + t2 * e2).normalized(); };
  Eigen::Matrix2d M;
  Status status = target_map(q, views, normal_at(theta(2), theta(3)), &M);
  if (!ok(status)) return status;
  constexpr double kStep = 1e-3;  // rad; float normals in plane_affine resolve ~1e-7
  Eigen::Matrix2d dM[2];
  for (int j = 0; j < 2; ++j) {
    Eigen::Matrix2d M_step;
    status = target_map(q, views, normal_at(theta(2) + (j == 0 ? kStep : 0.0), theta(3) + (j == 1 ? kStep : 0.0)), &M_step);
    if (!ok(status)) return status;
    dM[j] = (M_step - M) / kStep;
  }
  const Eigen::Vector2d u = theta.head<2>();
  out->JtJ.setZero();
  out->Jtr.setZero();
  out->sum_r2 = 0.0;
  out->count = 0;
  for (int ty = 0; ty < kPatchSize; ++ty) {
    for (int tx = 0; tx < kPatchSize; ++tx) {
      const Eigen::Vector2d y(tx - kPatchRadius, ty - kPatchRadius);
      const Eigen::Vector2d p = u + M * y;
      // One more pixel each side for the central differences.
      if (!(p.x() >= 1.0 && p.y() >= 1.0 && p.x() < image.width_px - 2.0 && p.y() < image.height_px - 2.0)) {
        return Status::kOutsideImage;
      }
      double value;
      Eigen::Vector2d g;
      sample_with_gradient(image, p.x(), p.y(), &value, &g);
      const double T = patch[static_cast<std::size_t>(ty * kPatchSize + tx)];
      const double r = value - theta(4) * T - theta(5);
      Vector6d J;
      J << g.x(), g.y(), g.dot(dM[0] * y), g.dot(dM[1] * y), -T, -1.0;
      // The upper triangle only (mirrored below): each entry the same products in the same order.
      for (int col = 0; col < kParams; ++col) {
        for (int row = 0; row <= col; ++row) out->JtJ(row, col) += J(row) * J(col);
      }
      out->Jtr += J * r;
      const std::size_t index = static_cast<std::size_t>(ty * kPatchSize + tx);
      out->rows.J[index] = J;
      out->rows.r[index] = r;
      out->rows.valid[index] = true;
      out->sum_r2 += r * r;
      ++out->count;
    }
  }
  for (int col = 0; col < kParams; ++col) {
    for (int row = col + 1; row < kParams; ++row) out->JtJ(row, col) = out->JtJ(col, row);
  }
  return Status::kOk;
}

// The residual variance per pixel (the 8-bit floor below dof > 0 residuals' own).
double residual_variance(const NormalEquations& eq) {
  const double dof = eq.count - kParams;
  return dof > 0 ? std::fmax(eq.sum_r2 / dof, kMinResidualVariance) : kMinResidualVariance;
}

// The Gauss-Newton step -information^-1 gradient. Not inlined, for the caller's stack frame (ASan).
[[gnu::noinline]] Status gauss_newton_step(const Matrix6d& information, const Vector6d& gradient, Vector6d* step) {
  const Eigen::LDLT<Matrix6d> ldlt(information);
  if (ldlt.info() != Eigen::Success || !ldlt.isPositive()) return Status::kNotSpd;
  *step = -ldlt.solve(gradient);
  return step->allFinite() ? Status::kOk : Status::kNotSpd;
}

// The tilt's posterior covariance at the solution whose normal equations are eq. The residuals of a
// resampled patch are not white (bilinear interpolation mixes neighbouring pixels' noise; the
// interpolation's model error is smooth): the pixels' information is that of a correlated field,
// H M^-1 H / sigma^2 with M = J^T C J (sandwich form), C from the residuals' own lag-one correlations.
// White residuals give M = H. Its own function (not inlined): the 6x6 factorizations would otherwise
// share one stack frame with the iteration's, beyond the core's frame limit under ASan.
[[gnu::noinline]] Status tilt_covariance_of(const NormalEquations& eq, double prior_information,
                                            Eigen::Matrix2d* tilt_covariance) {
  const double sigma2 = residual_variance(eq);
  double rho_x = 0.0;
  double rho_y = 0.0;
  lag_one_correlations(eq.rows, &rho_x, &rho_y);
  const Matrix6d meat = correlated_information_meat(eq.rows, rho_x, rho_y);
  const Eigen::LDLT<Matrix6d> meat_ldlt(meat);
  if (meat_ldlt.info() != Eigen::Success || !meat_ldlt.isPositive()) return Status::kNotSpd;
  Matrix6d information = eq.JtJ * solve_columns(meat_ldlt, eq.JtJ) / sigma2;
  information = 0.5 * (information + information.transpose()).eval();
  information(2, 2) += prior_information;
  information(3, 3) += prior_information;
  const Eigen::LDLT<Matrix6d> ldlt(information);
  if (ldlt.info() != Eigen::Success || !ldlt.isPositive()) return Status::kNotSpd;
  const Matrix6d covariance = solve_columns(ldlt, Matrix6d::Identity());
  if (!covariance.allFinite()) return Status::kNotSpd;
  *tilt_covariance = 0.5 * (covariance.block<2, 2>(2, 2) + covariance.block<2, 2>(2, 2).transpose());
  return Status::kOk;
}

}  // namespace

Status estimate_photometric_normal(const GrayImageView& image, const std::array<std::uint8_t, kPatchPixels>& patch,
                                   const PhotometricNormalQuery& query, const PinholeIntrinsics& intrinsics,
                                   PhotometricNormalEstimate* estimate) {
  const Eigen::Vector3d n0 = query.normal_world.cast<double>();
  if (!n0.allFinite() || std::abs(n0.norm() - 1.0) > 1e-3 || !(query.prior_tilt_variance > 0.0) ||
      !std::isfinite(query.prior_tilt_variance) || query.iterations < 1 || query.iterations > 20 ||
      !query.uv_target_px.allFinite() || !query.X_world.allFinite()) {
    return Status::kInvalidArgument;
  }
  if (!ok(image.validate())) return Status::kInvalidImage;
  // The tilt axes: an orthonormal basis of the prior normal's plane.
  const Eigen::Matrix<double, 3, 2> basis = plane_basis(n0);
  const Eigen::Vector3d e1 = basis.col(0);
  const Eigen::Vector3d e2 = basis.col(1);
  const double prior_information = 1.0 / query.prior_tilt_variance;
  Vector6d theta;
  theta << query.uv_target_px, 0.0, 0.0, 1.0, 0.0;
  PlaneViews views;
  if (!plane_views(query, intrinsics, &views)) return Status::kBehindCamera;
  NormalEquations eq;
  Matrix6d information;
  for (int iteration = 0; iteration <= query.iterations; ++iteration) {
    const Status status = accumulate(image, patch, query, views, e1, e2, theta, &eq);
    if (!ok(status)) return status;
    const double sigma2 = residual_variance(eq);
    // MAP: pixels weighted by the residual variance, the prior on the tilt.
    information = eq.JtJ / sigma2;
    information(2, 2) += prior_information;
    information(3, 3) += prior_information;
    if (iteration == query.iterations) break;  // the last pass only evaluates the solution
    Vector6d gradient = eq.Jtr / sigma2;
    gradient(2) += prior_information * theta(2);
    gradient(3) += prior_information * theta(3);
    Vector6d step;
    const Status step_status = gauss_newton_step(information, gradient, &step);
    if (!ok(step_status)) return step_status;
    // Trust region on the tilt: a linearized warp is good to a few tenths of a radian.
    const double tilt_step = step.segment<2>(2).norm();
    constexpr double kMaxTiltStep = 0.3;
    if (tilt_step > kMaxTiltStep) step *= kMaxTiltStep / tilt_step;
    theta += step;
    // Converged: the system just solved is the solution's to well within its own uncertainty.
    if (step.head<2>().norm() < 1e-3 && step.segment<2>(2).norm() < 1e-4) break;
    if ((theta.head<2>() - query.uv_target_px).norm() > 1.5) return Status::kOutsideImage;
  }
  Eigen::Matrix2d tilt_covariance;
  const Status covariance_status = tilt_covariance_of(eq, prior_information, &tilt_covariance);
  if (!ok(covariance_status)) return covariance_status;
  // Eigenvalues of the symmetric 2x2 in closed form (Eigen's solver references the heap here).
  const double half_trace = 0.5 * (tilt_covariance(0, 0) + tilt_covariance(1, 1));
  const double half_difference = 0.5 * (tilt_covariance(0, 0) - tilt_covariance(1, 1));
  const double radius = std::sqrt(half_difference * half_difference + tilt_covariance(0, 1) * tilt_covariance(0, 1));
  const double largest = half_trace + radius;
  if (!(half_trace - radius > 0.0)) return Status::kNotSpd;
  estimate->normal_world = (n0 + theta(2) * e1 + theta(3) * e2).normalized().cast<float>();
  estimate->tilt_covariance = tilt_covariance;
  estimate->tilt_variance = largest;
  estimate->uv_target_px = theta.head<2>();
  estimate->residual_variance_gray2 = eq.count > kParams ? eq.sum_r2 / (eq.count - kParams) : 0.0;
  return Status::kOk;
}

}  // namespace vantage
