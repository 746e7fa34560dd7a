#include "core/criterion/view_grid.hpp"

#include <cmath>

namespace vantage {

Status ViewGridView::configure(const GridGeometry& geometry, const Eigen::Vector3d& look_target_world) {
  if (!std::isfinite(geometry.cell_size_m) || !std::isfinite(geometry.elevation_m) || !geometry.center_xy.allFinite() ||
      !look_target_world.allFinite()) {
    return Status::kNonFiniteInput;
  }
  if (geometry.cells_per_side != cells_per_side_ || !(geometry.cell_size_m > 0.0)) return Status::kInvalidArgument;
  geometry_ = geometry;
  const std::int32_t n = cell_count();
  for (std::int32_t i = 0; i < n; ++i) {
    const Eigen::Vector3d position = geometry_.cell_center_world(geometry_.cell_at(i));
    Viewpoint view;
    Status status = look_at(position, look_target_world, Eigen::Vector3d::UnitZ(), &view);
    if (!ok(status)) status = look_at(position, look_target_world, Eigen::Vector3d::UnitY(), &view);
    view_ok_[i] = ok(status) ? 1 : 0;
    views_[i] = ok(status) ? view : Viewpoint{};
    views_[i].position_world = position;
    F_[i] = 0.0;
    cost_[i] = 1.0f;
    object_[i] = 0;
    evaluated_[i] = 0;
  }
  recompute_free();
  has_nbv_ = false;
  configured_ = true;
  return Status::kOk;
}

void ViewGridView::recompute_free() {
  const std::int32_t n = cell_count();
  for (std::int32_t i = 0; i < n; ++i) free_[i] = (object_[i] == 0 && blocked_[i] == 0) ? 1 : 0;
}

Status ViewGridView::update_free_mask(const CriterionModelView& model, double safety_margin_m) {
  if (!std::isfinite(safety_margin_m)) return Status::kNonFiniteInput;
  if (!configured_ || safety_margin_m < 0.0) return Status::kInvalidArgument;
  const std::int32_t n = cell_count();
  for (std::int32_t i = 0; i < n; ++i) object_[i] = 0;
  const double m2 = safety_margin_m * safety_margin_m;
  const double half = 0.5 * cells_per_side_;
  const float* xs = model.slot_x();
  const float* ys = model.slot_y();
  for (std::size_t s = 0; s < model.primitive_count(); ++s) {
    const Eigen::Vector2d xy(xs[s], ys[s]);
    // Cells whose centres may lie within the margin: centre index range of [xy - m, xy + m].
    const Eigen::Vector2d lo = (xy - geometry_.center_xy).array() / geometry_.cell_size_m + half - 0.5 -
                               safety_margin_m / geometry_.cell_size_m;
    const Eigen::Vector2d hi = (xy - geometry_.center_xy).array() / geometry_.cell_size_m + half - 0.5 +
                               safety_margin_m / geometry_.cell_size_m;
    const std::int32_t ix0 = static_cast<std::int32_t>(std::fmax(std::ceil(lo.x()), 0.0));
    const std::int32_t iy0 = static_cast<std::int32_t>(std::fmax(std::ceil(lo.y()), 0.0));
    const std::int32_t ix1 = static_cast<std::int32_t>(std::fmin(std::floor(hi.x()), cells_per_side_ - 1.0));
    const std::int32_t iy1 = static_cast<std::int32_t>(std::fmin(std::floor(hi.y()), cells_per_side_ - 1.0));
    for (std::int32_t iy = iy0; iy <= iy1; ++iy) {
      for (std::int32_t ix = ix0; ix <= ix1; ++ix) {
        const GridCell cell{ix, iy};
        if ((geometry_.cell_center_xy(cell) - xy).squaredNorm() <= m2) object_[geometry_.flat_index(cell)] = 1;
      }
    }
  }
  recompute_free();
  return Status::kOk;
}

Status ViewGridView::set_blocked(const GridCell& cell, bool blocked) {
  if (!geometry_.contains(cell)) return Status::kNotFound;
  const std::int32_t i = geometry_.flat_index(cell);
  blocked_[i] = blocked ? 1 : 0;
  free_[i] = (object_[i] == 0 && blocked_[i] == 0) ? 1 : 0;
  return Status::kOk;
}

void ViewGridView::clear_blocked() {
  for (std::int32_t i = 0; i < cell_count(); ++i) blocked_[i] = 0;
  recompute_free();
}

Status ViewGridView::evaluate(const CriterionModelView& model, const PinholeIntrinsics& intrinsics, std::int32_t begin,
                              std::int32_t end, CriterionScratchView& scratch) {
  if (!configured_ || begin < 0 || end < begin || end > cell_count()) return Status::kInvalidArgument;
  if (intrinsics.width_px <= 0 || intrinsics.height_px <= 0) return Status::kInvalidImage;
  const Status intrinsics_status = intrinsics.validate();
  if (!ok(intrinsics_status)) return intrinsics_status;
  if (scratch.capacity() < round_up_to_clusters(model.primitive_count())) return Status::kInvalidArgument;
  for (std::int32_t i = begin; i < end; ++i) {
    double F = 0.0;
    if (view_ok_[i] != 0) {
      const Status status = model.evaluate(views_[i], intrinsics, scratch, &F);
      if (!ok(status)) return status;  // unreachable after the checks above, kept for safety
    }
    F_[i] = F;
    evaluated_[i] = 1;
  }
  return Status::kOk;
}

Status ViewGridView::finalize() {
  const std::int32_t n = cell_count();
  if (!configured_) return Status::kInvalidArgument;
  for (std::int32_t i = 0; i < n; ++i) {
    if (evaluated_[i] == 0) return Status::kInvalidArgument;
  }
  double F_max = 0.0;
  double F_min = 0.0;
  for (std::int32_t i = 0; i < n; ++i) {
    if (!(F_[i] > 0.0)) continue;
    F_max = F_[i] > F_max ? F_[i] : F_max;
    F_min = (F_min == 0.0 || F_[i] < F_min) ? F_[i] : F_min;
  }
  // cost = (1/F - 1/F_max) / (1/F_min - 1/F_max): 0 at the best cell, 1 at the worst seeing cell and
  // at every cell that sees nothing (F = 0).
  const double span = F_max > 0.0 ? F_max / F_min - 1.0 : 0.0;
  bool any_free = false;
  std::int32_t best = -1;
  for (std::int32_t i = 0; i < n; ++i) {
    if (F_[i] > 0.0) {
      cost_[i] = span > 0.0 ? static_cast<float>((F_max / F_[i] - 1.0) / span) : 0.0f;
    } else {
      cost_[i] = 1.0f;
    }
    if (free_[i] == 0) continue;
    any_free = true;
    if (F_[i] > 0.0 && (best < 0 || F_[i] > F_[best])) best = i;
  }
  for (std::int32_t i = 0; i < n; ++i) evaluated_[i] = 0;
  has_nbv_ = best >= 0;
  if (has_nbv_) nbv_ = geometry_.cell_at(best);
  if (!any_free) return Status::kNoFreeCell;
  return has_nbv_ ? Status::kOk : Status::kNotFound;
}

GridMapView ViewGridView::map() const {
  GridMapView m;
  m.geometry = geometry_;
  m.free = free_;
  m.cost = cost_;
  return m;
}

}  // namespace vantage
