#include "core/frontend/match_covariance.hpp"

#include <Eigen/Cholesky>
#include <Eigen/LU>

#include "core/frontend/correlated_residuals.hpp"

namespace vantage {

bool correlated_match_covariance(const GrayImageView& image, const NccTemplate& tmpl, const Eigen::Vector2d& uv_px,
                                 Eigen::Matrix2d* covariance_px2) {
  using Matrix4d = Eigen::Matrix<double, 4, 4>;
  if (!uv_px.allFinite() || tmpl.valid_count < 8) return false;
  const double x0 = uv_px.x() - kPatchRadius;
  const double y0 = uv_px.y() - kPatchRadius;
  // One more pixel each side for the central differences.
  if (!(x0 >= 1.0 && y0 >= 1.0 && x0 + kPatchSize - 1 < image.width_px - 2.0 &&
        y0 + kPatchSize - 1 < image.height_px - 2.0)) {
    return false;
  }
  PatchResiduals<4> fit;
  std::array<double, kPatchPixels> values{};
  // Gain and offset at this shift: least squares of the image values on the template's.
  double s_t = 0.0;
  double s_tt = 0.0;
  double s_v = 0.0;
  double s_tv = 0.0;
  int count = 0;
  for (int ty = 0; ty < kPatchSize; ++ty) {
    for (int tx = 0; tx < kPatchSize; ++tx) {
      const std::size_t i = static_cast<std::size_t>(ty * kPatchSize + tx);
      if (!(tmpl.mask[i] > 0.5f)) continue;
      const double x = x0 + tx;
      const double y = y0 + ty;
      const double t = tmpl.values[i];
      values[i] = sample_bilinear(image, x, y);
      const Eigen::Vector2d g(0.5 * (sample_bilinear(image, x + 1.0, y) - sample_bilinear(image, x - 1.0, y)),
                              0.5 * (sample_bilinear(image, x, y + 1.0) - sample_bilinear(image, x, y - 1.0)));
      fit.J[i] << g.x(), g.y(), -t, -1.0;
      fit.valid[i] = true;
      s_t += t;
      s_tt += t * t;
      s_v += values[i];
      s_tv += t * values[i];
      ++count;
    }
  }
  const double det = s_tt * count - s_t * s_t;
  if (!(det > 0.0)) return false;
  const double alpha = (s_tv * count - s_t * s_v) / det;
  const double beta = (s_v - alpha * s_t) / count;
  Matrix4d H = Matrix4d::Zero();
  double sum_r2 = 0.0;
  for (std::size_t i = 0; i < fit.r.size(); ++i) {
    if (!fit.valid[i]) continue;
    fit.r[i] = values[i] - alpha * tmpl.values[i] - beta;
    sum_r2 += fit.r[i] * fit.r[i];
    H += fit.J[i] * fit.J[i].transpose();
  }
  if (count <= 4) return false;
  const double sigma2 = sum_r2 / (count - 4);
  const Matrix4d meat = correlated_information_meat(fit, lag_one_correlation(fit, 1, 0), lag_one_correlation(fit, 0, 1));
  const Eigen::LDLT<Matrix4d> ldlt(H);
  if (ldlt.info() != Eigen::Success || !ldlt.isPositive()) return false;
  const Matrix4d H_inv = ldlt.solve(Matrix4d::Identity());
  const Matrix4d covariance = sigma2 * H_inv * meat * H_inv;
  const Eigen::Matrix2d shift = 0.5 * (covariance.topLeftCorner<2, 2>() + covariance.topLeftCorner<2, 2>().transpose());
  if (!shift.allFinite() || !(shift.determinant() > 0.0)) return false;
  *covariance_px2 = shift;
  return true;
}

}  // namespace vantage
