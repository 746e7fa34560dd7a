#include "core/frontend/patch_search.hpp"

#include <cmath>
#include <cstdlib>
#include <limits>

#include "core/frontend/float4.hpp"
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
  // Rows padded to whole lane groups with finite zeros: the lanes past the patch are computed and dropped.
  constexpr int kBlockStride = 16;
  constexpr int kLanes = 8;  // a patch row as two Float4, the eighth lane masked
  constexpr int kResampled = kPatchSize + 2;  // the patch plus a one-pixel ring for the gradient
  constexpr int kResampledStride = 12;
  static_assert(kPatchSize <= kLanes && kResampled + 3 <= kResampledStride &&
                    kMargin - 1 + kResampledStride + 1 <= kBlockStride,
                "lane padding too small for the patch size");
  if (!patch_inside(image, x, y, kMargin) || tmpl.valid_count < 8) return false;
  Eigen::Vector2d d = *uv_px - Eigen::Vector2d(x, y);
  if (!(std::abs(d.x()) < 1.0 && std::abs(d.y()) < 1.0)) return false;
  alignas(16) float block[kBlock][kBlockStride];
  const std::int32_t block_x = x - kPatchRadius - kMargin;
  for (int j = 0; j < kBlock; ++j) {
    bytes_to_floats(image.pixels + (y - kPatchRadius - kMargin + j) * image.stride_bytes + block_x, kBlock,
                    image.width_px - block_x, block[j], kBlockStride);
  }
  // The template in rows of 8 lanes (the template holds 0 at masked pixels; the eighth lane is masked).
  alignas(16) float t8[kPatchSize][kLanes];
  alignas(16) float m8[kPatchSize][kLanes];
  for (int ty = 0; ty < kPatchSize; ++ty) {
    for (int tx = 0; tx < kLanes; ++tx) {
      t8[ty][tx] = tx < kPatchSize ? tmpl.values[ty * kPatchSize + tx] : 0.0f;
      m8[ty][tx] = tx < kPatchSize ? tmpl.mask[ty * kPatchSize + tx] : 0.0f;
    }
  }
  // Template-only sums of J^T J (J = [gx, gy, -t, -1]) do not change between iterations; beta starts at
  // the mean of the image patch.
  Float4 sum_tt = splat4(0.0f);
  Float4 sum_t = splat4(0.0f);
  Float4 sum_image = splat4(0.0f);
  for (int ty = 0; ty < kPatchSize; ++ty) {
    for (int lane = 0; lane < kLanes; lane += 4) {
      const Float4 t = load4(&t8[ty][lane]);
      sum_tt += t * t;
      sum_t += t;
      sum_image += load4(&m8[ty][lane]) * load4(&block[ty + kMargin][kMargin + lane]);
    }
  }
  const double s_tt = sum_lanes(sum_tt);
  const double s_t = sum_lanes(sum_t);
  double beta = static_cast<double>(sum_lanes(sum_image)) / tmpl.valid_count;
  const double s_1 = tmpl.valid_count;
  double alpha = 1.0;
  // The photometric block C = [[s_tt, s_t], [s_t, s_1]] of J^T J and its inverse (the 4x4 normal
  // equations are solved by the Schur complement on the shift: same solution, 2x2 inverses only).
  const double det_c = s_tt * s_1 - s_t * s_t;
  if (!(det_c > 0.0)) return false;
  Eigen::Matrix2d C_inv;
  C_inv << s_1 / det_c, -s_t / det_c, -s_t / det_c, s_tt / det_c;
  Eigen::Matrix2d covariance = Eigen::Matrix2d::Identity();
  for (int iteration = 0; iteration < iterations; ++iteration) {
    const int ix = static_cast<int>(std::floor(d.x()));
    const int iy = static_cast<int>(std::floor(d.y()));
    const float fx = static_cast<float>(d.x() - ix);
    const float fy = static_cast<float>(d.y() - iy);
    const Float4 w00 = splat4((1.0f - fx) * (1.0f - fy));
    const Float4 w01 = splat4(fx * (1.0f - fy));
    const Float4 w10 = splat4((1.0f - fx) * fy);
    const Float4 w11 = splat4(fx * fy);
    // The image resampled at the shifted patch and its ring: resampled[j][i] = I(patch (i - 1, j - 1) + d).
    // Bilinear interpolation is linear and shift-invariant, so central differences of the resampled
    // values equal the resampled central-difference gradients: one interpolation per pixel, not three.
    alignas(16) float resampled[kResampled][kResampledStride];
    for (int j = 0; j < kResampled; ++j) {
      const float* r0 = &block[j + kMargin - 1 + iy][kMargin - 1 + ix];
      const float* r1 = r0 + kBlockStride;
      for (int i = 0; i < kResampledStride; i += 4) {
        store4(&resampled[j][i],
               w00 * load4(r0 + i) + w01 * load4(r0 + i + 1) + w10 * load4(r1 + i) + w11 * load4(r1 + i + 1));
      }
    }
    // J^T J and J^T r as lane sums (r = I(p + d) - alpha * t - beta): this loop is the tracker's hot path.
    const Float4 alpha4 = splat4(static_cast<float>(alpha));
    const Float4 beta4 = splat4(static_cast<float>(beta));
    const Float4 half = splat4(0.5f);
    Float4 a_xx = splat4(0.0f), a_xy = a_xx, a_xt = a_xx, a_x = a_xx, a_yy = a_xx, a_yt = a_xx, a_y = a_xx;
    Float4 b_x = a_xx, b_y = a_xx, b_t = a_xx, b_1 = a_xx, b_rr = a_xx;
    for (int ty = 0; ty < kPatchSize; ++ty) {
      for (int lane = 0; lane < kLanes; lane += 4) {
        const float* row = &resampled[ty + 1][lane];
        const Float4 m = load4(&m8[ty][lane]);
        const Float4 t = load4(&t8[ty][lane]);
        const Float4 gx = half * (load4(row + 2) - load4(row)) * m;
        const Float4 gy = half * (load4(row + 1 + kResampledStride) - load4(row + 1 - kResampledStride)) * m;
        const Float4 r = (load4(row + 1) - alpha4 * t - beta4) * m;
        a_xx += gx * gx;
        a_xy += gx * gy;
        a_xt += gx * t;
        a_x += gx;
        a_yy += gy * gy;
        a_yt += gy * t;
        a_y += gy;
        b_x += gx * r;
        b_y += gy * r;
        b_t += t * r;
        b_1 += r;
        b_rr += r * r;
      }
    }
    // Normal equations [[A, B], [B^T, C]] (shift, photometric) step = -(g_a, g_c).
    Eigen::Matrix2d A;
    A << sum_lanes(a_xx), sum_lanes(a_xy), sum_lanes(a_xy), sum_lanes(a_yy);
    Eigen::Matrix2d B;
    B << -sum_lanes(a_xt), -sum_lanes(a_x), -sum_lanes(a_yt), -sum_lanes(a_y);
    const Eigen::Vector2d g_a(sum_lanes(b_x), sum_lanes(b_y));
    const Eigen::Vector2d g_c(-sum_lanes(b_t), -sum_lanes(b_1));
    // Schur complement: its inverse is the shift block of (J^T J)^-1.
    const Eigen::Matrix2d schur = A - B * C_inv * B.transpose();
    const double det_s = schur(0, 0) * schur(1, 1) - schur(0, 1) * schur(1, 0);
    if (!(det_s > 0.0) || !(schur(0, 0) > 0.0)) return false;
    Eigen::Matrix2d schur_inv;
    schur_inv << schur(1, 1) / det_s, -schur(0, 1) / det_s, -schur(1, 0) / det_s, schur(0, 0) / det_s;
    const Eigen::Vector2d step_shift = -schur_inv * (g_a - B * (C_inv * g_c));
    const Eigen::Vector2d step_photometric = -C_inv * (g_c + B.transpose() * step_shift);
    if (!step_shift.allFinite() || !step_photometric.allFinite()) return false;
    const bool last = iteration + 1 == iterations || step_shift.norm() < 1e-3;
    if (last) {
      // Least-squares covariance of the shift: residual variance (image noise plus what the model misses,
      // 4 parameters fitted) times the shift block of (J^T J)^-1.
      const double dof = s_1 - 4.0;
      covariance = (dof > 0.0 ? static_cast<double>(sum_lanes(b_rr)) / dof : 0.0) * schur_inv;
    }
    d += step_shift;
    alpha += step_photometric(0);
    beta += step_photometric(1);
    if (!(std::abs(d.x()) < 1.0 && std::abs(d.y()) < 1.0) || !(alpha > 0.0)) return false;
    if (step_shift.norm() < 1e-3) break;
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
  if (w < 3 || h < 3) return MatchOutcome::kNoRoom;
  const std::size_t box_size = static_cast<std::size_t>(w) * static_cast<std::size_t>(h);
  const std::size_t ncc_size = static_cast<std::size_t>(h) * static_cast<std::size_t>(ncc_box_out_stride(w));
  if (box_size + ncc_size > scratch.size()) return MatchOutcome::kNoRoom;
  // Candidates inside the gate ellipse (the pixel nearest the prediction always counts as inside, so a
  // tiny ellipse between pixel centres still has one), and the rectangle that holds them.
  float* inside = scratch.data();
  const double a = query.S_inv(0, 0);
  const double b = query.S_inv(0, 1);
  const double c = query.S_inv(1, 0);
  const double e = query.S_inv(1, 1);
  std::int32_t in_x0 = x1;
  std::int32_t in_x1 = x0;
  std::int32_t in_y0 = y1;
  std::int32_t in_y1 = y0;
  for (std::int32_t y = y0 + 1; y < y1; ++y) {
    const double dy = y - query.predicted_px.y();
    for (std::int32_t x = x0 + 1; x < x1; ++x) {
      const double dx = x - query.predicted_px.x();
      const bool in = (x == cx && y == cy) || dx * (a * dx + b * dy) + dy * (c * dx + e * dy) <= query.gate_chi2;
      inside[(y - y0) * w + x - x0] = in ? 1.0f : 0.0f;
      if (!in) continue;
      in_x0 = x < in_x0 ? x : in_x0;
      in_x1 = x > in_x1 ? x : in_x1;
      in_y0 = y < in_y0 ? y : in_y0;
      in_y1 = y > in_y1 ? y : in_y1;
    }
  }
  *best_ncc = -2.0f;
  if (in_x0 > in_x1) return MatchOutcome::kBelowThreshold;
  // NCC of that rectangle and its one-pixel ring (every candidate's 8-neighbours) at once: vectorized,
  // cheaper than evaluating the needed centres one by one.
  const std::int32_t n_x0 = in_x0 - 1;
  const std::int32_t n_y0 = in_y0 - 1;
  const std::int32_t n_w = in_x1 - in_x0 + 3;
  const std::int32_t n_h = in_y1 - in_y0 + 3;
  const std::int32_t n_stride = ncc_box_out_stride(n_w);
  float* ncc = inside + box_size;
  float* const rest = ncc + ncc_size;
  if (!ncc_box(image, tmpl, n_x0, n_y0, n_w, n_h, Span<float>(rest, scratch.size() - box_size - ncc_size), ncc)) {
    return MatchOutcome::kNoRoom;
  }
  auto value = [&](std::int32_t x, std::int32_t y) { return ncc[(y - n_y0) * n_stride + x - n_x0]; };
  auto is_inside = [&](std::int32_t x, std::int32_t y) { return inside[(y - y0) * w + x - x0] != 0.0f; };
  auto is_local_max = [&](std::int32_t x, std::int32_t y) {
    const float centre = value(x, y);
    for (std::int32_t dy = -1; dy <= 1; ++dy) {
      for (std::int32_t dx = -1; dx <= 1; ++dx) {
        if ((dx != 0 || dy != 0) && value(x + dx, y + dy) > centre) return false;
      }
    }
    return true;
  };
  // Best local maximum inside the gate ellipse.
  float best = -2.0f;
  std::int32_t bx = 0;
  std::int32_t by = 0;
  for (std::int32_t y = in_y0; y <= in_y1; ++y) {
    for (std::int32_t x = in_x0; x <= in_x1; ++x) {
      if (!is_inside(x, y) || value(x, y) <= best || !is_local_max(x, y)) continue;
      best = value(x, y);
      bx = x;
      by = y;
    }
  }
  *best_ncc = best;
  if (best < config.ncc_min) return MatchOutcome::kBelowThreshold;
  // Uniqueness over the other local maxima inside the ellipse: the region the prior allows.
  for (std::int32_t y = in_y0; y <= in_y1; ++y) {
    for (std::int32_t x = in_x0; x <= in_x1; ++x) {
      if (std::abs(x - bx) <= 1 && std::abs(y - by) <= 1) continue;
      if (is_inside(x, y) && value(x, y) >= config.uniqueness_ratio * best && is_local_max(x, y)) {
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
