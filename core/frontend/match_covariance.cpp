#include "core/frontend/match_covariance.hpp"

#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>

#include <Eigen/LU>

#include "core/frontend/correlated_residuals.hpp"

namespace vantage {

bool correlated_match_covariance(const GrayImageView& image, const NccTemplate& tmpl, const Eigen::Vector2d& uv_px,
                                 Eigen::Matrix2d* covariance_px2) {
  using Matrix4d = Eigen::Matrix<double, 4, 4>;
  if (!uv_px.allFinite() || tmpl.valid_count < 8) return false;
  // The patch and a one-pixel ring for the central differences, resampled once: every sample shares the
  // shift's fractional part, so one set of bilinear weights serves the whole block.
  constexpr int kRing = kPatchSize + 2;
  const double left = uv_px.x() - kPatchRadius - 1;
  const double top = uv_px.y() - kPatchRadius - 1;
  if (!(left >= 0.0 && top >= 0.0 && left + kRing < image.width_px - 1.0 && top + kRing < image.height_px - 1.0)) {
    return false;
  }
  const BilinearCell cell = bilinear_cell(left, top);
  const std::int32_t x0 = cell.x0;
  const std::int32_t y0 = cell.y0;
  const double fx = cell.fx;
  const double fy = cell.fy;
  const double w00 = (1.0 - fx) * (1.0 - fy);
  const double w01 = fx * (1.0 - fy);
  const double w10 = (1.0 - fx) * fy;
  const double w11 = fx * fy;
  std::array<std::array<double, kRing>, kRing> block{};
  for (int j = 0; j < kRing; ++j) {
    const std::uint8_t* row0 = image.pixels + static_cast<std::ptrdiff_t>(y0 + j) * image.stride_bytes + x0;
    const std::uint8_t* row1 = row0 + image.stride_bytes;
    for (int i = 0; i < kRing; ++i) {
      block[static_cast<std::size_t>(j)][static_cast<std::size_t>(i)] =
          w00 * row0[i] + w01 * row0[i + 1] + w10 * row1[i] + w11 * row1[i + 1];
    }
  }
  PatchResiduals<4> fit;
  // Gain and offset at this shift: least squares of the image values on the template's.
  double s_t = 0.0;
  double s_tt = 0.0;
  double s_v = 0.0;
  double s_tv = 0.0;
  int count = 0;
  for (int ty = 0; ty < kPatchSize; ++ty) {
    const auto& above = block[static_cast<std::size_t>(ty)];
    const auto& row = block[static_cast<std::size_t>(ty + 1)];
    const auto& below = block[static_cast<std::size_t>(ty + 2)];
    for (int tx = 0; tx < kPatchSize; ++tx) {
      const std::size_t i = static_cast<std::size_t>(ty * kPatchSize + tx);
      if (!(tmpl.mask[i] > 0.5f)) continue;
      const auto c = static_cast<std::size_t>(tx + 1);
      const double t = tmpl.values[i];
      const double value = row[c];
      fit.J[i] << 0.5 * (row[c + 1] - row[c - 1]), 0.5 * (below[c] - above[c]), -t, -1.0;
      fit.r[i] = value;  // the residual once gain and offset are known
      fit.valid[i] = true;
      s_t += t;
      s_tt += t * t;
      s_v += value;
      s_tv += t * value;
      ++count;
    }
  }
  const double det = s_tt * count - s_t * s_t;
  if (!(det > 0.0) || count <= 4) return false;
  const double alpha = (s_tv * count - s_t * s_v) / det;
  const double beta = (s_v - alpha * s_t) / count;
  double sum_r2 = 0.0;
  for (std::size_t i = 0; i < fit.r.size(); ++i) {
    if (!fit.valid[i]) continue;
    fit.r[i] -= alpha * tmpl.values[i] + beta;
    sum_r2 += fit.r[i] * fit.r[i];
  }
  const double sigma2 = sum_r2 / (count - 4);
  double rho_x = 0.0;
  double rho_y = 0.0;
  lag_one_correlations(fit, &rho_x, &rho_y);
  Matrix4d H;
  const Matrix4d meat = correlated_information_meat(fit, rho_x, rho_y, &H);
  const double det_H = H.determinant();
  if (!(det_H > 0.0) || !std::isfinite(det_H)) return false;
  const Matrix4d H_inv = H.inverse();
  const Eigen::Matrix<double, 2, 4> rows = H_inv.topRows<2>();
  const Eigen::Matrix2d shift = sigma2 * rows * meat * rows.transpose();
  const Eigen::Matrix2d symmetric = 0.5 * (shift + shift.transpose());
  if (!symmetric.allFinite() || !(symmetric.determinant() > 0.0)) return false;
  *covariance_px2 = symmetric;
  return true;
}

}  // namespace vantage
