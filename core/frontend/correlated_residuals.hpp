#pragma once
// Least-squares covariances for residuals that are not white. A patch fit's residuals (image resampled
// bilinearly minus a template) are correlated between neighbouring pixels: interpolation mixes
// neighbouring pixels' noise and its model error is smooth. Taking them as white makes the fit's
// covariance too small. Here the correlation C is separable with lag-one correlations rho_x, rho_y
// between horizontal and vertical neighbours (rho_x rho_y diagonally, none farther), estimated from the
// fit's own residual field, and the covariance is the sandwich sigma^2 H^-1 (J^T C J) H^-1, H = J^T J.
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>

#include <Eigen/Core>

#include "core/frontend/ncc.hpp"
#include "core/image/gray_image.hpp"

namespace vantage {

// The pixel cell holding (x, y): its top-left pixel and the fractional position inside it.
struct BilinearCell {
  std::int32_t x0 = 0;
  std::int32_t y0 = 0;
  double fx = 0.0;
  double fy = 0.0;
};

inline BilinearCell bilinear_cell(double x, double y) {
  const double fx0 = std::floor(x);
  const double fy0 = std::floor(y);
  return BilinearCell{static_cast<std::int32_t>(fx0), static_cast<std::int32_t>(fy0), x - fx0, y - fy0};
}

// Jacobian rows and residuals of a fit over the p x p patch (row-major); valid[i] false for pixels not
// in the fit (their rows and residuals are ignored).
template <int P>
struct PatchResiduals {
  std::array<Eigen::Matrix<double, P, 1>, kPatchPixels> J;
  std::array<double, kPatchPixels> r{};
  std::array<bool, kPatchPixels> valid{};
};

// One lag-one correlation from the field's sums: the mean product over `pairs` neighbour pairs against
// the mean square over `count` pixels, clamped to [0, 0.45] (the truncated separable model stays positive
// definite below 0.5); 0 for a zero field or no pairs.
inline double clamped_lag_one_correlation(double products, int pairs, double squares, int count) {
  if (!(squares > 0.0) || pairs == 0) return 0.0;
  const double rho = (products / pairs) / (squares / count);
  return rho < 0.0 ? 0.0 : (rho > 0.45 ? 0.45 : rho);
}

// Lag-one correlations of the residual field between horizontal (*rho_x) and vertical (*rho_y)
// neighbours (clamped_lag_one_correlation).
template <int P>
void lag_one_correlations(const PatchResiduals<P>& fit, double* rho_x, double* rho_y) {
  double squares = 0.0;
  double products_x = 0.0;
  double products_y = 0.0;
  int count = 0;
  int pairs_x = 0;
  int pairs_y = 0;
  for (int y = 0; y < kPatchSize; ++y) {
    for (int x = 0; x < kPatchSize; ++x) {
      const std::size_t i = static_cast<std::size_t>(y * kPatchSize + x);
      if (!fit.valid[i]) continue;
      const double r = fit.r[i];
      squares += r * r;
      ++count;
      if (x + 1 < kPatchSize && fit.valid[i + 1]) {
        products_x += r * fit.r[i + 1];
        ++pairs_x;
      }
      if (y + 1 < kPatchSize && fit.valid[i + kPatchSize]) {
        products_y += r * fit.r[i + kPatchSize];
        ++pairs_y;
      }
    }
  }
  *rho_x = clamped_lag_one_correlation(products_x, pairs_x, squares, count);
  *rho_y = clamped_lag_one_correlation(products_y, pairs_y, squares, count);
}

// Calls add(j, rho) for pixel (x, y)'s right, lower, lower-right and lower-left neighbours j (row-major
// index i = y p + x) with their correlation weights, in that order.
// Always inlined: called per pixel, its lambda's accumulators must stay in registers.
template <typename Add>
[[gnu::always_inline]] inline void for_each_correlated_neighbour(int x, int y, std::size_t i, double rho_x, double rho_y, Add add) {
  const double rho_xy = rho_x * rho_y;
  const bool right = x + 1 < kPatchSize;
  const bool down = y + 1 < kPatchSize;
  if (right) add(i + 1, rho_x);
  if (down) add(i + kPatchSize, rho_y);
  if (right && down) add(i + kPatchSize + 1, rho_xy);
  if (x > 0 && down) add(i + kPatchSize - 1, rho_xy);
}

// J^T C J for the correlations above (J^T J when both are zero): J^T J + P + P^T with P the sum over
// pixels of J_i times the correlation-weighted rows of its right, lower and lower diagonal neighbours.
// J^T J itself goes to *gram_out when it is not null.
template <int P>
Eigen::Matrix<double, P, P> correlated_information_meat(const PatchResiduals<P>& fit, double rho_x, double rho_y,
                                                         Eigen::Matrix<double, P, P>* gram_out = nullptr) {
  using Matrix = Eigen::Matrix<double, P, P>;
  using Vector = Eigen::Matrix<double, P, 1>;
  Matrix gram = Matrix::Zero();
  Matrix cross = Matrix::Zero();
  for (int y = 0; y < kPatchSize; ++y) {
    for (int x = 0; x < kPatchSize; ++x) {
      const std::size_t i = static_cast<std::size_t>(y * kPatchSize + x);
      if (!fit.valid[i]) continue;
      gram += fit.J[i] * fit.J[i].transpose();
      Vector neighbours = Vector::Zero();
      for_each_correlated_neighbour(x, y, i, rho_x, rho_y, [&](std::size_t j, double rho) {
        if (fit.valid[j]) neighbours += rho * fit.J[j];
      });
      cross += fit.J[i] * neighbours.transpose();
    }
  }
  if (gram_out != nullptr) *gram_out = gram;
  return gram + cross + cross.transpose();
}

}  // namespace vantage
