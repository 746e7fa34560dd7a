#include "core/frontend/patch_search.hpp"

#include <cmath>
#include <cstdlib>
#include <limits>

#include <Eigen/Cholesky>

#include "core/geometry/projection.hpp"

namespace vantage {

namespace {

// Subpixel refinement at an integer peak from its 4-neighbours' NCC.
Eigen::Vector2d refine(std::int32_t x, std::int32_t y, float centre, float left, float right, float up, float down) {
  return Eigen::Vector2d(x + parabola_peak_offset(left, centre, right), y + parabola_peak_offset(up, centre, down));
}

}  // namespace

bool refine_subpixel(const GrayImageView& image, const NccTemplate& tmpl, std::int32_t x, std::int32_t y,
                     int iterations, Eigen::Vector2d* uv_px, Eigen::Matrix2d* covariance_px2) {
  // Block of image values around the peak: the patch, +-1 px of shift, one more for the bilinear cell and
  // one for the central-difference gradient.
  constexpr int kMargin = 3;
  constexpr int kBlock = kPatchSize + 2 * kMargin;
  if (!patch_inside(image, x, y, kMargin) || tmpl.valid_count < 8) return false;
  Eigen::Vector2d d = *uv_px - Eigen::Vector2d(x, y);
  if (!(std::abs(d.x()) < 1.0 && std::abs(d.y()) < 1.0)) return false;
  float block[kBlock][kBlock];
  float gx[kBlock][kBlock];
  float gy[kBlock][kBlock];
  for (int j = 0; j < kBlock; ++j) {
    const std::uint8_t* row = image.pixels + (y - kPatchRadius - kMargin + j) * image.stride_bytes + (x - kPatchRadius - kMargin);
    for (int i = 0; i < kBlock; ++i) block[j][i] = row[i];
  }
  for (int j = 1; j < kBlock - 1; ++j) {
    for (int i = 1; i < kBlock - 1; ++i) {
      gx[j][i] = 0.5f * (block[j][i + 1] - block[j][i - 1]);
      gy[j][i] = 0.5f * (block[j + 1][i] - block[j - 1][i]);
    }
  }
  double alpha = 1.0;
  double beta = 0.0;
  {
    double sum = 0.0;
    for (int ty = 0; ty < kPatchSize; ++ty) {
      for (int tx = 0; tx < kPatchSize; ++tx) sum += tmpl.mask[ty * kPatchSize + tx] * block[ty + kMargin][tx + kMargin];
    }
    beta = sum / tmpl.valid_count;
  }
  Eigen::Matrix2d covariance = Eigen::Matrix2d::Identity();
  for (int iteration = 0; iteration < iterations; ++iteration) {
    const int ix = static_cast<int>(std::floor(d.x()));
    const int iy = static_cast<int>(std::floor(d.y()));
    const float fx = static_cast<float>(d.x() - ix);
    const float fy = static_cast<float>(d.y() - iy);
    const float w00 = (1.0f - fx) * (1.0f - fy);
    const float w01 = fx * (1.0f - fy);
    const float w10 = (1.0f - fx) * fy;
    const float w11 = fx * fy;
    // Upper triangle of J^T J and J^T r as scalars (J = [gx, gy, -t, -1]): this loop is the tracker's hot path.
    double s_xx = 0, s_xy = 0, s_xt = 0, s_x = 0, s_yy = 0, s_yt = 0, s_y = 0, s_tt = 0, s_t = 0, s_1 = 0;
    double r_x = 0, r_y = 0, r_t = 0, r_1 = 0, r_r = 0;
    for (int ty = 0; ty < kPatchSize; ++ty) {
      const int j = ty + kMargin + iy;
      for (int tx = 0; tx < kPatchSize; ++tx) {
        const int k = ty * kPatchSize + tx;
        if (tmpl.mask[k] <= 0.5f) continue;
        const int i = tx + kMargin + ix;
        const float value = w00 * block[j][i] + w01 * block[j][i + 1] + w10 * block[j + 1][i] + w11 * block[j + 1][i + 1];
        const float grad_x = w00 * gx[j][i] + w01 * gx[j][i + 1] + w10 * gx[j + 1][i] + w11 * gx[j + 1][i + 1];
        const float grad_y = w00 * gy[j][i] + w01 * gy[j][i + 1] + w10 * gy[j + 1][i] + w11 * gy[j + 1][i + 1];
        const double gx_d = grad_x;
        const double gy_d = grad_y;
        const double t = tmpl.values[k];
        const double r = value - alpha * t - beta;
        s_xx += gx_d * gx_d;
        s_xy += gx_d * gy_d;
        s_xt += gx_d * t;
        s_x += gx_d;
        s_yy += gy_d * gy_d;
        s_yt += gy_d * t;
        s_y += gy_d;
        s_tt += t * t;
        s_t += t;
        s_1 += 1.0;
        r_x += gx_d * r;
        r_y += gy_d * r;
        r_t += t * r;
        r_1 += r;
        r_r += r * r;
      }
    }
    Eigen::Matrix4d JtJ;
    JtJ << s_xx, s_xy, -s_xt, -s_x,
           s_xy, s_yy, -s_yt, -s_y,
           -s_xt, -s_yt, s_tt, s_t,
           -s_x, -s_y, s_t, s_1;
    const Eigen::Vector4d Jtr(r_x, r_y, -r_t, -r_1);
    const Eigen::LDLT<Eigen::Matrix4d> ldlt(JtJ);
    if (ldlt.info() != Eigen::Success) return false;
    const Eigen::Vector4d step = -ldlt.solve(Jtr);
    if (!step.allFinite()) return false;
    const bool last = iteration + 1 == iterations || step.head<2>().norm() < 1e-3;
    if (last) {
      // Least-squares covariance of the shift: residual variance (image noise plus what the model misses,
      // 4 parameters fitted) times the shift block of (J^T J)^-1.
      const double dof = s_1 - 4.0;
      const Eigen::Matrix4d JtJ_inv = ldlt.solve(Eigen::Matrix4d::Identity());
      covariance = (dof > 0.0 ? r_r / dof : 0.0) * JtJ_inv.topLeftCorner<2, 2>();
    }
    d += step.head<2>();
    alpha += step(2);
    beta += step(3);
    if (!(std::abs(d.x()) < 1.0 && std::abs(d.y()) < 1.0) || !(alpha > 0.0)) return false;
    if (step.head<2>().norm() < 1e-3) break;
  }
  if (!covariance.allFinite()) return false;
  *uv_px = Eigen::Vector2d(x, y) + d;
  if (covariance_px2 != nullptr) *covariance_px2 = 0.5 * (covariance + covariance.transpose());
  return true;
}

MatchOutcome search_window(const GrayImageView& image, const NccTemplate& tmpl, const WindowQuery& query,
                           const MatchConfig& config, Span<float> scratch, Eigen::Vector2d* uv_px, float* best_ncc,
                           Eigen::Matrix2d* covariance_px2) {
  if (!query.predicted_px.allFinite() || query.half_width_px < 1 || query.half_height_px < 1) {
    return MatchOutcome::kNoRoom;
  }
  const std::int32_t cx = static_cast<std::int32_t>(std::lround(query.predicted_px.x()));
  const std::int32_t cy = static_cast<std::int32_t>(std::lround(query.predicted_px.y()));
  // The box holds the window plus a one-pixel ring so every candidate has its 4-neighbours' NCC.
  std::int32_t x0 = cx - query.half_width_px - 1;
  std::int32_t x1 = cx + query.half_width_px + 1;
  std::int32_t y0 = cy - query.half_height_px - 1;
  std::int32_t y1 = cy + query.half_height_px + 1;
  if (x0 < kPatchRadius) x0 = kPatchRadius;
  if (y0 < kPatchRadius) y0 = kPatchRadius;
  if (x1 > image.width_px - 1 - kPatchRadius) x1 = image.width_px - 1 - kPatchRadius;
  if (y1 > image.height_px - 1 - kPatchRadius) y1 = image.height_px - 1 - kPatchRadius;
  const std::int32_t w = x1 - x0 + 1;
  const std::int32_t h = y1 - y0 + 1;
  if (w < 3 || h < 3 || static_cast<std::size_t>(w) * static_cast<std::size_t>(h) > scratch.size()) {
    return MatchOutcome::kNoRoom;
  }
  // NCC evaluated lazily: only the candidates inside the ellipse and their 8-neighbours are ever needed.
  float* ncc = scratch.data();
  constexpr float kUnset = -3.0f;
  for (std::int32_t i = 0; i < w * h; ++i) ncc[i] = kUnset;
  auto value = [&](std::int32_t x, std::int32_t y) {
    float& v = ncc[(y - y0) * w + x - x0];
    if (v == kUnset) v = ncc_at(image, x, y, tmpl);
    return v;
  };
  auto is_local_max = [&](std::int32_t x, std::int32_t y) {
    const float c = value(x, y);
    for (std::int32_t dy = -1; dy <= 1; ++dy) {
      for (std::int32_t dx = -1; dx <= 1; ++dx) {
        if ((dx != 0 || dy != 0) && value(x + dx, y + dy) > c) return false;
      }
    }
    return true;
  };
  auto inside = [&](std::int32_t x, std::int32_t y) {
    const Eigen::Vector2d d(x - query.predicted_px.x(), y - query.predicted_px.y());
    return (x == cx && y == cy) || d.dot(query.S_inv * d) <= query.gate_chi2;
  };
  // Best local maximum inside the gate ellipse (the pixel nearest the prediction always counts as inside,
  // so a tiny ellipse between pixel centres still has a candidate).
  float best = -2.0f;
  std::int32_t bx = 0;
  std::int32_t by = 0;
  for (std::int32_t y = y0 + 1; y < y1; ++y) {
    for (std::int32_t x = x0 + 1; x < x1; ++x) {
      if (!inside(x, y) || value(x, y) <= best || !is_local_max(x, y)) continue;
      best = value(x, y);
      bx = x;
      by = y;
    }
  }
  *best_ncc = best;
  if (best < config.ncc_min) return MatchOutcome::kBelowThreshold;
  // Uniqueness over the other local maxima inside the ellipse: the region the prior allows.
  for (std::int32_t y = y0 + 1; y < y1; ++y) {
    for (std::int32_t x = x0 + 1; x < x1; ++x) {
      if (std::abs(x - bx) <= 1 && std::abs(y - by) <= 1) continue;
      if (inside(x, y) && value(x, y) >= config.uniqueness_ratio * best && is_local_max(x, y)) {
        return MatchOutcome::kAmbiguous;
      }
    }
  }
  Eigen::Vector2d uv = refine(bx, by, best, value(bx - 1, by), value(bx + 1, by), value(bx, by - 1), value(bx, by + 1));
  Eigen::Matrix2d covariance = Eigen::Matrix2d::Constant(std::numeric_limits<double>::quiet_NaN());
  if (config.subpixel_iterations > 0 &&
      !refine_subpixel(image, tmpl, bx, by, config.subpixel_iterations, &uv, &covariance)) {
    return MatchOutcome::kNoSubpixel;
  }
  *uv_px = uv;
  if (covariance_px2 != nullptr) *covariance_px2 = covariance;
  return MatchOutcome::kMatched;
}

MatchOutcome search_epipolar(const GrayImageView& second_image, const NccTemplate& tmpl, const EpipolarQuery& query,
                             const PinholeIntrinsics& intrinsics, const MatchConfig& config, Span<float> scratch_ncc,
                             Span<std::int32_t> scratch_xy, Eigen::Vector2d* uv_second_px, float* best_ncc,
                             Eigen::Matrix2d* covariance_px2) {
  *best_ncc = -2.0f;
  if (!(query.depth_min > 0.0) || !(query.depth_max > query.depth_min)) return MatchOutcome::kNoRoom;
  const Eigen::Vector3d ray = back_project_ray_world(query.uv_first_px, query.first, intrinsics);
  const double ray_z = ray.dot(query.first.R_world_cam.col(2));
  if (!(ray_z > 0.0)) return MatchOutcome::kNoRoom;
  // Knots uniform in inverse depth, joined by straight pieces: exact without distortion, close with it.
  constexpr int kKnots = 16;
  const std::size_t capacity = scratch_ncc.size() < scratch_xy.size() / 2 ? scratch_ncc.size() : scratch_xy.size() / 2;
  std::size_t count = 0;
  std::int32_t last_x = -1;
  std::int32_t last_y = -1;
  bool have_previous = false;  // the first knot has no piece before it
  Eigen::Vector2d previous_px = Eigen::Vector2d::Zero();
  for (int k = 0; k < kKnots; ++k) {
    const double s = static_cast<double>(k) / (kKnots - 1);
    const double inverse_depth = (1.0 - s) / query.depth_min + s / query.depth_max;
    const Eigen::Vector3d X = query.first.position_world + ray * (1.0 / inverse_depth / ray_z);
    Eigen::Vector2d px;
    if (!ok(project(X, query.second, intrinsics, &px)) || !px.allFinite() ||
        std::abs(px.x()) > 1e6 || std::abs(px.y()) > 1e6) {
      return MatchOutcome::kNoRoom;  // part of the depth range behind the second camera
    }
    if (have_previous) {
      const Eigen::Vector2d step = px - previous_px;
      const int pieces = static_cast<int>(std::ceil(step.cwiseAbs().maxCoeff())) + 1;
      for (int i = 0; i <= pieces; ++i) {
        const Eigen::Vector2d p = previous_px + step * (static_cast<double>(i) / pieces);
        const std::int32_t x = static_cast<std::int32_t>(std::lround(p.x()));
        const std::int32_t y = static_cast<std::int32_t>(std::lround(p.y()));
        if (x == last_x && y == last_y) continue;
        // A depth range that leaves the image may hold the true match where it cannot be searched: then
        // the best in-image peak proves nothing, so the seed is not matched at all.
        if (!patch_inside(second_image, x, y, 1)) return MatchOutcome::kNoRoom;
        if (count == capacity) return MatchOutcome::kNoRoom;
        scratch_xy[2 * count] = x;
        scratch_xy[2 * count + 1] = y;
        scratch_ncc[count] = ncc_at(second_image, x, y, tmpl);
        ++count;
        last_x = x;
        last_y = y;
      }
    }
    previous_px = px;
    have_previous = true;
  }
  if (count < 3) return MatchOutcome::kNoRoom;
  // Interior local maxima of the sequence; the ends are not candidates (a peak there may lie beyond the
  // depth range).
  float best = -2.0f;
  std::size_t best_i = 0;
  for (std::size_t i = 1; i + 1 < count; ++i) {
    const float c = scratch_ncc[i];
    if (c > best && c >= scratch_ncc[i - 1] && c >= scratch_ncc[i + 1]) {
      best = c;
      best_i = i;
    }
  }
  *best_ncc = best;
  if (best < config.ncc_min) return MatchOutcome::kBelowThreshold;
  const std::int32_t seq_x = scratch_xy[2 * best_i];
  const std::int32_t seq_y = scratch_xy[2 * best_i + 1];
  for (std::size_t i = 1; i + 1 < count; ++i) {
    const std::int32_t x = scratch_xy[2 * i];
    const std::int32_t y = scratch_xy[2 * i + 1];
    if (std::abs(x - seq_x) <= 1 && std::abs(y - seq_y) <= 1) continue;
    const float c = scratch_ncc[i];
    if (c >= config.uniqueness_ratio * best && c >= scratch_ncc[i - 1] && c >= scratch_ncc[i + 1]) {
      return MatchOutcome::kAmbiguous;
    }
  }
  // Rounding to the pixel grid can land beside the 2D peak: climb to it (at most two steps), then refine.
  std::int32_t bx = scratch_xy[2 * best_i];
  std::int32_t by = scratch_xy[2 * best_i + 1];
  for (int climb = 0; climb < 2; ++climb) {
    std::int32_t next_x = bx;
    std::int32_t next_y = by;
    for (std::int32_t dy = -1; dy <= 1; ++dy) {
      for (std::int32_t dx = -1; dx <= 1; ++dx) {
        if ((dx == 0 && dy == 0) || !patch_inside(second_image, bx + dx, by + dy, 1)) continue;
        const float c = ncc_at(second_image, bx + dx, by + dy, tmpl);
        if (c > best) {
          best = c;
          next_x = bx + dx;
          next_y = by + dy;
        }
      }
    }
    if (next_x == bx && next_y == by) break;
    bx = next_x;
    by = next_y;
  }
  *best_ncc = best;
  const float left = ncc_at(second_image, bx - 1, by, tmpl);
  const float right = ncc_at(second_image, bx + 1, by, tmpl);
  const float up = ncc_at(second_image, bx, by - 1, tmpl);
  const float down = ncc_at(second_image, bx, by + 1, tmpl);
  Eigen::Vector2d uv = refine(bx, by, best, left, right, up, down);
  Eigen::Matrix2d covariance = Eigen::Matrix2d::Constant(std::numeric_limits<double>::quiet_NaN());
  if (config.subpixel_iterations > 0 &&
      !refine_subpixel(second_image, tmpl, bx, by, config.subpixel_iterations, &uv, &covariance)) {
    return MatchOutcome::kNoSubpixel;
  }
  *uv_second_px = uv;
  if (covariance_px2 != nullptr) *covariance_px2 = covariance;
  return MatchOutcome::kMatched;
}

}  // namespace vantage
