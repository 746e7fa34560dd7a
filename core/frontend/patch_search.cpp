#include "core/frontend/patch_search.hpp"

#include <cmath>
#include <cstdlib>

#include "core/geometry/projection.hpp"

namespace vantage {

namespace {

// Subpixel refinement at an integer peak from its 4-neighbours' NCC.
Eigen::Vector2d refine(std::int32_t x, std::int32_t y, float centre, float left, float right, float up, float down) {
  return Eigen::Vector2d(x + parabola_peak_offset(left, centre, right), y + parabola_peak_offset(up, centre, down));
}

}  // namespace

MatchOutcome search_window(const GrayImageView& image, const NccTemplate& tmpl, const WindowQuery& query,
                           const MatchConfig& config, Span<float> scratch, Eigen::Vector2d* uv_px, float* best_ncc) {
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
  float* ncc = scratch.data();
  for (std::int32_t y = y0; y <= y1; ++y) {
    for (std::int32_t x = x0; x <= x1; ++x) ncc[(y - y0) * w + x - x0] = ncc_at(image, x, y, tmpl);
  }
  auto value = [&](std::int32_t x, std::int32_t y) { return ncc[(y - y0) * w + x - x0]; };
  auto is_local_max = [&](std::int32_t x, std::int32_t y) {
    const float c = value(x, y);
    for (std::int32_t dy = -1; dy <= 1; ++dy) {
      for (std::int32_t dx = -1; dx <= 1; ++dx) {
        if ((dx != 0 || dy != 0) && value(x + dx, y + dy) > c) return false;
      }
    }
    return true;
  };
  // Best local maximum inside the gate ellipse (the pixel nearest the prediction always counts as inside,
  // so a tiny ellipse between pixel centres still has a candidate).
  float best = -2.0f;
  std::int32_t bx = 0;
  std::int32_t by = 0;
  for (std::int32_t y = y0 + 1; y < y1; ++y) {
    for (std::int32_t x = x0 + 1; x < x1; ++x) {
      const Eigen::Vector2d d(x - query.predicted_px.x(), y - query.predicted_px.y());
      const bool inside = (x == cx && y == cy) || d.dot(query.S_inv * d) <= query.gate_chi2;
      if (!inside || value(x, y) <= best || !is_local_max(x, y)) continue;
      best = value(x, y);
      bx = x;
      by = y;
    }
  }
  *best_ncc = best;
  if (best < config.ncc_min) return MatchOutcome::kBelowThreshold;
  // Uniqueness over every interior local maximum of the box, inside the ellipse or not.
  for (std::int32_t y = y0 + 1; y < y1; ++y) {
    for (std::int32_t x = x0 + 1; x < x1; ++x) {
      if (std::abs(x - bx) <= 1 && std::abs(y - by) <= 1) continue;
      if (value(x, y) >= config.uniqueness_ratio * best && is_local_max(x, y)) return MatchOutcome::kAmbiguous;
    }
  }
  *uv_px = refine(bx, by, best, value(bx - 1, by), value(bx + 1, by), value(bx, by - 1), value(bx, by + 1));
  return MatchOutcome::kMatched;
}

MatchOutcome search_epipolar(const GrayImageView& second_image, const NccTemplate& tmpl, const EpipolarQuery& query,
                             const PinholeIntrinsics& intrinsics, const MatchConfig& config, Span<float> scratch_ncc,
                             Span<std::int32_t> scratch_xy, Eigen::Vector2d* uv_second_px, float* best_ncc) {
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
  bool have_previous = false;
  Eigen::Vector2d previous_px = Eigen::Vector2d::Zero();
  for (int k = 0; k < kKnots; ++k) {
    const double s = static_cast<double>(k) / (kKnots - 1);
    const double inverse_depth = (1.0 - s) / query.depth_min + s / query.depth_max;
    const Eigen::Vector3d X = query.first.position_world + ray * (1.0 / inverse_depth / ray_z);
    Eigen::Vector2d px;
    if (!ok(project(X, query.second, intrinsics, &px)) || !px.allFinite() ||
        std::abs(px.x()) > 1e6 || std::abs(px.y()) > 1e6) {
      have_previous = false;
      continue;
    }
    if (have_previous) {
      const Eigen::Vector2d step = px - previous_px;
      const int pieces = static_cast<int>(std::ceil(step.cwiseAbs().maxCoeff())) + 1;
      for (int i = 0; i <= pieces; ++i) {
        const Eigen::Vector2d p = previous_px + step * (static_cast<double>(i) / pieces);
        const std::int32_t x = static_cast<std::int32_t>(std::lround(p.x()));
        const std::int32_t y = static_cast<std::int32_t>(std::lround(p.y()));
        if ((x == last_x && y == last_y) || !patch_inside(second_image, x, y, 1)) continue;
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
  *uv_second_px = refine(bx, by, best, left, right, up, down);
  return MatchOutcome::kMatched;
}

}  // namespace vantage
