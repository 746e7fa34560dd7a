#include "core/frontend/photometric_normal.hpp"

// The float lanes below (Float8) are always inlined: GCC's note on passing 32-byte vectors without AVX
// (it is reported at the end of the file, so a push/pop around them does not silence it) does not apply.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wpsabi"
#endif

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
  // plane_affine's map with the Jacobians computed once; plane_affine_from_jacobians checks the float
  // normal's length (a non-finite component makes it non-finite).
  const Eigen::Vector3f n_float = n.cast<float>();
  Eigen::Matrix2d A;
  if (!ok(plane_affine_from_jacobians(views.H_reference, views.H_target, n_float, &A, nullptr))) {
    return Status::kBehindCamera;
  }
  *M = A.inverse();
  return M->allFinite() ? Status::kOk : Status::kBehindCamera;
}

// Solves A X = B for every column of B, A symmetric 6x6: a plain Cholesky factorization when A is
// positive definite (the usual case), else Eigen's LDLT with its positivity check, as before (it also
// takes semidefinite systems, giving zero for the components of zero pivots). False when neither holds.
// Only the columns wanted are passed (a step: one; the shift and tilt covariances: four of the identity), so no
// 6x6 right-hand side is built, zeroed or copied for them.
template <int Cols>
[[gnu::noinline]] bool solve_spd(const Matrix6d& A, const Eigen::Matrix<double, kParams, Cols>& B,
                                 Eigen::Matrix<double, kParams, Cols>* X) {
  // Fully unrolled (the loops' bookkeeping was most of the 860 instructions of a one-column solve); the
  // same operations in the same order.
  double L[kParams][kParams] = {};
  bool positive = true;
#pragma GCC unroll 6
  for (int j = 0; j < kParams; ++j) {
    double d = A(j, j);
#pragma GCC unroll 6
    for (int k = 0; k < j; ++k) d -= L[j][k] * L[j][k];
    if (!(d > 0.0) || !std::isfinite(d)) {
      positive = false;
      break;
    }
    L[j][j] = std::sqrt(d);
    const double inverse = 1.0 / L[j][j];
#pragma GCC unroll 6
    for (int i = j + 1; i < kParams; ++i) {
      double v = A(i, j);
#pragma GCC unroll 6
      for (int k = 0; k < j; ++k) v -= L[i][k] * L[j][k];
      L[i][j] = v * inverse;
    }
  }
  if (positive) {
    for (int c = 0; c < Cols; ++c) {
      double y[kParams];
#pragma GCC unroll 6
      for (int i = 0; i < kParams; ++i) {
        double v = B(i, c);
#pragma GCC unroll 6
        for (int k = 0; k < i; ++k) v -= L[i][k] * y[k];
        y[i] = v / L[i][i];
      }
#pragma GCC unroll 6
      for (int i = kParams - 1; i >= 0; --i) {
        double v = y[i];
#pragma GCC unroll 6
        for (int k = i + 1; k < kParams; ++k) v -= L[k][i] * (*X)(k, c);
        (*X)(i, c) = v / L[i][i];
      }
    }
    return true;
  }
  const Eigen::LDLT<Matrix6d> ldlt(A);
  if (ldlt.info() != Eigen::Success || !ldlt.isPositive()) return false;
  for (int c = 0; c < Cols; ++c) {
    const Vector6d column = B.col(c);
    X->col(c) = ldlt.solve(column);
  }
  return true;
}

struct NormalEquations {
  Matrix6d JtJ = Matrix6d::Zero();
  Vector6d Jtr = Vector6d::Zero();
  double sum_r2 = 0.0;
  int count = 0;
  match_kernel::PhotometricPass pass{};  // its per-pixel rows feed the correlation model
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
  // The pixel loop (match_kernel.hpp: float lanes, one 32-bit read per row of each pixel's 4x4
  // neighbourhood, the value and both central differences from one set of bilinear weights).
  match_kernel::PhotometricPass& pass = out->pass;
  pass.u_x = theta(0);
  pass.u_y = theta(1);
  for (int k = 0; k < 4; ++k) {
    pass.M[k] = M(k / 2, k % 2);
    pass.dM0[k] = dM[0](k / 2, k % 2);
    pass.dM1[k] = dM[1](k / 2, k % 2);
  }
  pass.gain = theta(4);
  pass.offset = theta(5);
  const match_kernel::Image view{image.pixels, image.width_px, image.height_px, image.stride_bytes};
  if (!match_kernel::functions(q.kernel).photometric(view, patch.data(), &pass)) return Status::kOutsideImage;
  for (int row = 0; row < kParams; ++row) {
    for (int col = 0; col < kParams; ++col) out->JtJ(row, col) = pass.JtJ[row][col];
    out->Jtr(row) = pass.Jtr[row];
  }
  out->sum_r2 = pass.sum_r2;
  out->count = kPatchPixels;
  return Status::kOk;
}

// The residual variance per pixel (the 8-bit floor below dof > 0 residuals' own).
double residual_variance(const NormalEquations& eq) {
  const double dof = eq.count - kParams;
  return dof > 0 ? std::fmax(eq.sum_r2 / dof, kMinResidualVariance) : kMinResidualVariance;
}

// The Gauss-Newton step -information^-1 gradient. Not inlined, for the caller's stack frame (ASan).
[[gnu::noinline]] Status gauss_newton_step(const Matrix6d& information, const Vector6d& gradient, Vector6d* step) {
  Vector6d solution;
  if (!solve_spd<1>(information, gradient, &solution)) return Status::kNotSpd;
  *step = -solution;
  return step->allFinite() ? Status::kOk : Status::kNotSpd;
}

// The tilt's and the shift's posterior covariances at the solution whose normal equations are eq. The residuals of a
// resampled patch are not white (bilinear interpolation mixes neighbouring pixels' noise; the
// interpolation's model error is smooth): the pixels' information is that of a correlated field,
// H M^-1 H / sigma^2 with M = J^T C J (sandwich form), C from the residuals' own lag-one correlations.
// White residuals give M = H. Its own function (not inlined): the 6x6 factorizations would otherwise
// share one stack frame with the iteration's, beyond the core's frame limit under ASan.
[[gnu::noinline]] Status posterior_covariances(const NormalEquations& eq, const std::array<std::uint8_t, kPatchPixels>& patch,
                                            double prior_information, MatchKernel kernel,
                                            Eigen::Matrix2d* tilt_covariance, Eigen::Matrix2d* shift_covariance) {
  const double sigma2 = residual_variance(eq);
  double rho_x = 0.0;
  double rho_y = 0.0;
  const Matrix6d meat = photometric_correlated_meat(eq.pass, patch, &rho_x, &rho_y, kernel);
  Matrix6d meat_solved;
  if (!solve_spd<kParams>(meat, eq.JtJ, &meat_solved)) return Status::kNotSpd;
  Matrix6d information = eq.JtJ * meat_solved / sigma2;
  information = 0.5 * (information + information.transpose()).eval();
  information(2, 2) += prior_information;
  information(3, 3) += prior_information;
  // Only the shift and tilt blocks of the inverse: the columns of those four parameters (the first four),
  // from one factorization.
  Eigen::Matrix<double, kParams, 4> columns;
  if (!solve_spd<4>(information, Matrix6d::Identity().leftCols<4>(), &columns) || !columns.allFinite()) {
    return Status::kNotSpd;
  }
  *tilt_covariance = 0.5 * (columns.block<2, 2>(2, 2) + columns.block<2, 2>(2, 2).transpose());
  *shift_covariance = 0.5 * (columns.block<2, 2>(0, 0) + columns.block<2, 2>(0, 0).transpose());
  return Status::kOk;
}

}  // namespace

namespace {

// Eight float lanes: a patch row of the pass (match_kernel.hpp), the eighth lane zero in every column.
// The compiler splits it into the ISA's vectors (two on SSE2 and NEON). The helpers are always inlined,
// so the ABI note on passing such vectors without AVX does not apply (-Wpsabi is off for this file, top).
using Float8 = float __attribute__((vector_size(32)));

[[gnu::always_inline]] inline Float8 load8(const float* p) {
  Float8 v;
  __builtin_memcpy(&v, p, sizeof v);
  return v;
}
[[gnu::always_inline]] inline Float8 splat8(float s) { return Float8{s, s, s, s, s, s, s, s}; }
[[gnu::always_inline]] inline double sum8(Float8 v) {
  return static_cast<double>(((v[0] + v[1]) + (v[2] + v[3])) + ((v[4] + v[5]) + (v[6] + v[7])));
}
// Lane x gets the row's pixel x + 1 (right neighbour; none for the last: the spare lane's zero).
[[gnu::always_inline]] inline Float8 right_neighbours(Float8 v) {
  return __builtin_shufflevector(v, Float8{}, 1, 2, 3, 4, 5, 6, 7, 8);
}
// Lane x gets pixel x - 1 (left neighbour; zero for the first).
[[gnu::always_inline]] inline Float8 left_neighbours(Float8 v) {
  return __builtin_shufflevector(v, Float8{}, 8, 0, 1, 2, 3, 4, 5, 6);
}

// photometric_correlated_meat's lanes (built twice below: the baseline and AVX2 without FMA, so the
// same operations per lane and the same bits).
[[gnu::always_inline]] inline void correlated_meat_lanes(const match_kernel::PhotometricPass& pass,
                                                         const std::array<std::uint8_t, kPatchPixels>& patch,
                                                         double* rho_x, double* rho_y, double (*meat)[kParams]) {
  static_assert(kPatchSize == 7, "a patch row is one group of eight lanes with one spare");
  // J's columns per patch row: gx, gy, the two tilt columns, T and 1 (the last two without their minus
  // signs, restored below); the spare lane is zero in each (the pass's weights, the constant's mask).
  Float8 columns[kParams][kPatchSize];
  const Float8 ones = Float8{1.0f, 1.0f, 1.0f, 1.0f, 1.0f, 1.0f, 1.0f, 0.0f};
  Float8 squares{};
  Float8 products_x{};
  Float8 products_y{};
  for (int y = 0; y < kPatchSize; ++y) {
    for (int c = 0; c < 4; ++c) columns[c][y] = load8(pass.rows[c][y]);
    const std::uint8_t* t = patch.data() + y * kPatchSize;
    columns[4][y] = Float8{static_cast<float>(t[0]), static_cast<float>(t[1]), static_cast<float>(t[2]),
                           static_cast<float>(t[3]), static_cast<float>(t[4]), static_cast<float>(t[5]),
                           static_cast<float>(t[6]), 0.0f};
    columns[5][y] = ones;
    // The residual field's lag-one sums (lag_one_correlations' over 49 pixels, 42 pairs each way).
    const Float8 r = load8(pass.rows[4][y]);
    squares += r * r;
    products_x += r * right_neighbours(r);
    if (y + 1 < kPatchSize) products_y += r * load8(pass.rows[4][y + 1]);
  }
  const double squares_sum = sum8(squares);
  constexpr int kPairs = kPatchSize * (kPatchSize - 1);  // each way, every pixel in the fit
  *rho_x = clamped_lag_one_correlation(sum8(products_x), kPairs, squares_sum, kPatchPixels);
  *rho_y = clamped_lag_one_correlation(sum8(products_y), kPairs, squares_sum, kPatchPixels);
  // Each pixel's correlation-weighted neighbours (right, lower, lower right and lower left, as
  // for_each_correlated_neighbour), a patch row at a time.
  const Float8 weight_x = splat8(static_cast<float>(*rho_x));
  const Float8 weight_y = splat8(static_cast<float>(*rho_y));
  const Float8 weight_xy = splat8(static_cast<float>(*rho_x * *rho_y));
  Float8 neighbours[kParams][kPatchSize];
  for (int c = 0; c < kParams; ++c) {
    for (int y = 0; y < kPatchSize; ++y) {
      Float8 sum = weight_x * right_neighbours(columns[c][y]);
      if (y + 1 < kPatchSize) {
        const Float8 below = columns[c][y + 1];
        sum += weight_y * below + weight_xy * (right_neighbours(below) + left_neighbours(below));
      }
      // The spare lane's sum is not zero (the left neighbour of the eighth lane is the seventh); every
      // column's zero there keeps it out of the products.
      neighbours[c][y] = sum;
    }
  }
  // The cross term P = sum_i J_i n_i^T; the meat is J^T J (the pass's) + P + P^T.
  double cross[kParams][kParams];
  for (int a = 0; a < kParams; ++a) {
    Float8 sums[kParams] = {};
    for (int y = 0; y < kPatchSize; ++y) {
      for (int c = 0; c < kParams; ++c) sums[c] += columns[a][y] * neighbours[c][y];
    }
    for (int c = 0; c < kParams; ++c) cross[a][c] = sum8(sums[c]);
  }
  constexpr double kSign[kParams] = {1.0, 1.0, 1.0, 1.0, -1.0, -1.0};
  for (int a = 0; a < kParams; ++a) {
    for (int c = 0; c < kParams; ++c) meat[a][c] = pass.JtJ[a][c] + kSign[a] * kSign[c] * (cross[a][c] + cross[c][a]);
  }
}

[[gnu::noinline]] void correlated_meat_baseline(const match_kernel::PhotometricPass& pass,
                                                const std::array<std::uint8_t, kPatchPixels>& patch, double* rho_x,
                                                double* rho_y, double (*meat)[kParams]) {
  correlated_meat_lanes(pass, patch, rho_x, rho_y, meat);
}

#if defined(__x86_64__)
// Eight-lane vectors are one AVX register each (SSE2 takes two instructions per operation); no FMA, so
// nothing is contracted.
[[gnu::noinline, gnu::target("avx2")]] void correlated_meat_avx2(const match_kernel::PhotometricPass& pass,
                                                                 const std::array<std::uint8_t, kPatchPixels>& patch,
                                                                 double* rho_x, double* rho_y, double (*meat)[kParams]) {
  correlated_meat_lanes(pass, patch, rho_x, rho_y, meat);
}
#endif

}  // namespace

Eigen::Matrix<double, 6, 6> photometric_correlated_meat(const match_kernel::PhotometricPass& pass,
                                                       const std::array<std::uint8_t, kPatchPixels>& patch,
                                                       double* rho_x, double* rho_y, MatchKernel kernel) {
  double meat[kParams][kParams];
#if defined(__x86_64__)
  // The CPU's flag read directly (libgcc sets it up before main), as template_gradient_moments does.
  if (kernel != MatchKernel::kBaseline && __builtin_cpu_supports("avx2")) {
    correlated_meat_avx2(pass, patch, rho_x, rho_y, meat);
  } else {
    correlated_meat_baseline(pass, patch, rho_x, rho_y, meat);
  }
#else
  (void)kernel;
  correlated_meat_baseline(pass, patch, rho_x, rho_y, meat);
#endif
  Eigen::Matrix<double, 6, 6> out;
  for (int a = 0; a < kParams; ++a) {
    for (int c = 0; c < kParams; ++c) out(a, c) = meat[a][c];
  }
  return out;
}

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
    if (query.stop_decrement > 0.0 && step.dot(information * step) < query.stop_decrement) break;
    if ((theta.head<2>() - query.uv_target_px).norm() > 1.5) return Status::kOutsideImage;
  }
  Eigen::Matrix2d tilt_covariance;
  Eigen::Matrix2d shift_covariance;
  const Status covariance_status =
      posterior_covariances(eq, patch, prior_information, query.kernel, &tilt_covariance, &shift_covariance);
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
  estimate->gain = theta(4);
  estimate->residual_variance_gray2 = eq.count > kParams ? eq.sum_r2 / (eq.count - kParams) : 0.0;
  estimate->shift_covariance_px2 = shift_covariance;
  return Status::kOk;
}

}  // namespace vantage
