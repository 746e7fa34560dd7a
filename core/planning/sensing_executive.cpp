#include "core/planning/sensing_executive.hpp"

#include <cmath>

#include "core/estimation/ekf.hpp"
#include "core/planning/precision_level.hpp"

namespace vantage {

namespace {

// Replans in a row without an image in between: beyond this the plan cannot make progress.
constexpr std::uint32_t kMaxReplansWithoutImage = 4;

double step_length_cells(const GridCell& a, const GridCell& b) {
  const std::int32_t dx = std::abs(a.ix - b.ix);
  const std::int32_t dy = std::abs(a.iy - b.iy);
  const std::int32_t lo = dx < dy ? dx : dy;
  const std::int32_t hi = dx < dy ? dy : dx;
  return (hi - lo) + kSqrt2 * lo;
}

// Alive and not flagged kUnconsumed: images are expected to reduce its uncertainty. A flagged primitive
// is left out of PredictModel and U, as the criterion leaves it out of F (its gain would never come true).
bool consumable(const PrimitivePoolView& pool, PrimitiveIndex index) {
  return pool.is_alive(index) && (pool[index].flags & primitive_flags::kUnconsumed) == 0;
}

}  // namespace

const char* SensingConfig::invalid_field() const {
  if (!ok(split.validate())) return "split.epsilon_cells";
  if (!std::isfinite(rho_sigma) || rho_sigma < 0.0) return "rho_sigma";
  if (!std::isfinite(eta_utility)) return "eta_utility";
  if (!std::isfinite(eta_relative) || eta_relative < 0.0 || eta_relative >= 1.0) return "eta_relative";
  if (max_images < 2) return "max_images";
  if (!std::isfinite(orbit_radius_m) || orbit_radius_m <= 0.0) return "orbit_radius_m";
  if (!R_px2.allFinite() || R_px2(0, 0) <= 0.0 || R_px2(1, 1) <= 0.0 || R_px2.determinant() <= 0.0) return "R_px2";
  return nullptr;
}

Status SensingConfig::validate() const { return invalid_field() == nullptr ? Status::kOk : Status::kInvalidArgument; }

const char* to_string(SensingActionKind kind) {
  switch (kind) {
    case SensingActionKind::kEvaluateGrid: return "evaluate-grid";
    case SensingActionKind::kMoveTo: return "move-to";
    case SensingActionKind::kCapture: return "capture";
    case SensingActionKind::kDone: return "done";
    case SensingActionKind::kFailed: return "failed";
  }
  return "unknown";
}

const char* to_string(DoneReason reason) {
  switch (reason) {
    case DoneReason::kNone: return "none";
    case DoneReason::kGoalsReached: return "goals reached";
    case DoneReason::kBudgetExhausted: return "image budget exhausted";
  }
  return "unknown";
}

const char* to_string(ReplanReason reason) {
  switch (reason) {
    case ReplanReason::kNone: return "none";
    case ReplanReason::kInitial: return "initial";
    case ReplanReason::kUtility: return "utility below eta";
    case ReplanReason::kPathBlocked: return "path blocked";
    case ReplanReason::kPathEnd: return "end of path";
    case ReplanReason::kEveryImage: return "every image";
  }
  return "unknown";
}

SensingExecutive::SensingExecutive(PrimitivePoolView& pool, MeasurementSource& measurement, PlanningGrid& grid,
                                   ExternalGoal* goal)
    : pool_(pool), measurement_(measurement), grid_(grid), goal_(goal) {
  fail(Status::kInvalidArgument, "mission not started: call begin()");
}

void SensingExecutive::fail(Status status, const char* reason) {
  action_ = SensingAction{};
  action_.kind = SensingActionKind::kFailed;
  action_.failure = status;
  action_.reason = reason;
}

void SensingExecutive::finish(DoneReason reason, const char* text) {
  action_ = SensingAction{};
  action_.kind = SensingActionKind::kDone;
  action_.done = reason;
  action_.reason = text;
}

Status SensingExecutive::begin(const SensingConfig& config, const GrayImageView& first, const Viewpoint& first_view,
                               const GrayImageView& second, const Viewpoint& second_view) {
  images_ = rejected_images_ = nbv_iterations_ = unreachable_nbv_ = split_fallbacks_ = 0;
  replans_without_image_ = stagnations_ = same_cell_nbvs_ = 0;
  tabu_size_ = 0;
  path_length_cells_ = utility_ = utility_planned_ = precision_ = 0.0;
  plan_size_ = plan_pos_ = segment_size_ = segment_pos_ = predicted_size_ = 0;
  last_replan_ = ReplanReason::kNone;
  last_update_ = UpdateReport{};
  if (!ok(config.validate())) {
    fail(Status::kInvalidArgument, "invalid sensing config");
    return Status::kInvalidArgument;
  }
  config_ = config;
  rng_ = SplitMix64(config.random_seed);
  const Status init = measurement_.initialize(first, first_view, second, second_view, pool_, &last_update_);
  last_measurement_ = init;
  if (!ok(init)) {
    fail(init, "the initial image pair was rejected by the measurement source");
    return init;
  }
  images_ = 2;
  pose_ = second_view;
  precision_ = average_sigma(pool_);
  if (goals_reached()) {
    finish(DoneReason::kGoalsReached, "goals reached by the initial images");
  } else if (images_ >= config_.max_images) {
    finish(DoneReason::kBudgetExhausted, "image budget exhausted");
  } else {
    request_replan(ReplanReason::kInitial);
  }
  return Status::kOk;
}

bool SensingExecutive::goals_reached() {
  if (pool_.size() == 0 || !(precision_ < config_.rho_sigma)) return false;
  return goal_ == nullptr || goal_->reached(pool_);
}

void SensingExecutive::request_replan(ReplanReason reason) {
  last_replan_ = reason;
  if (++replans_without_image_ > kMaxReplansWithoutImage) {
    fail(Status::kNoPath, "no progress: the plan was renewed repeatedly without reaching a sensing position");
    return;
  }
  if (policy_uses_criterion(config_.policy) || reason == ReplanReason::kInitial) {
    action_ = SensingAction{};
    action_.kind = SensingActionKind::kEvaluateGrid;
    action_.replan = reason;
    return;
  }
  replan_now();  // orbit and random do not read the criterion: no grid evaluation needed
}

bool SensingExecutive::locate(const Viewpoint& pose, const GridMapView& map, GridCell* cell) const {
  if (!pose.position_world.allFinite()) return false;
  *cell = map.geometry.cell_of(pose.position_world.head<2>());
  return map.geometry.contains(*cell);
}

void SensingExecutive::on_grid_evaluated() {
  if (action_.kind != SensingActionKind::kEvaluateGrid) {
    fail(Status::kInvalidArgument, "on_grid_evaluated() without a pending kEvaluateGrid");
    return;
  }
  replan_now();
}

GridMapView SensingExecutive::planning_map(std::int32_t* free_count) {
  GridMapView map = grid_.map();
  std::int32_t count = 0;
  if (map.free != nullptr && map.geometry.cells_per_side > 0 && map.geometry.cells_per_side <= kMaxPlanningGridSide) {
    const std::int32_t n = map.geometry.cell_count();
    for (std::int32_t i = 0; i < n; ++i) {
      free_copy_[i] = map.free[i];
      count += map.free[i] != 0 ? 1 : 0;
    }
    if (map.geometry.contains(current_)) free_copy_[map.geometry.flat_index(current_)] = 1;
    map.free = free_copy_;
  }
  if (free_count != nullptr) *free_count = count;
  return map;
}

void SensingExecutive::replan_now() {
  const GridMapView raw = grid_.map();
  if (raw.free == nullptr || raw.geometry.cells_per_side <= 0 || raw.geometry.cells_per_side > kMaxPlanningGridSide ||
      (policy_uses_criterion(config_.policy) && raw.cost == nullptr)) {
    fail(Status::kInvalidArgument, "the grid map is missing or larger than the planner supports");
    return;
  }
  if (!locate(pose_, raw, &current_)) {
    fail(Status::kInvalidArgument, "the robot is outside the grid");
    return;
  }
  std::int32_t free_count = 0;
  const GridMapView map = planning_map(&free_count);
  if (free_count == 0) {
    fail(Status::kNoFreeCell, "no free cell in the grid");
    return;
  }
  GridCell goal{};
  if (!choose_goal(map, &goal)) return;
  if (policy_uses_criterion(config_.policy) && config_.stagnation_repeats > 0 && nbv_iterations_ > 0) {
    same_cell_nbvs_ = (goal == current_ && nbv_ == current_) ? same_cell_nbvs_ + 1 : 0;
    if (same_cell_nbvs_ >= config_.stagnation_repeats) {
      ++stagnations_;
      same_cell_nbvs_ = 0;
      add_tabu(current_);
      if (!choose_goal(map, &goal)) return;
    }
  }
  if (!build_plan(map, goal)) return;
  nbv_ = goal;
  ++nbv_iterations_;
  predicted_size_ = 0;
  utility_ = utility_planned_ = 0.0;
  if (policy_uses_criterion(config_.policy)) predict_model(goal);
  plan_pos_ = 0;
  segment_size_ = segment_pos_ = 0;
  advance();
}

bool SensingExecutive::is_tabu(const GridCell& cell) const {
  for (std::size_t k = 0; k < tabu_size_; ++k) {
    if (tabu_cells_[k] == cell && nbv_iterations_ < tabu_until_[k]) return true;
  }
  return false;
}

void SensingExecutive::add_tabu(const GridCell& cell) {
  // Reuse an expired slot, else the oldest-expiring one.
  std::size_t slot = tabu_size_;
  for (std::size_t k = 0; k < tabu_size_; ++k) {
    if (nbv_iterations_ >= tabu_until_[k] || tabu_cells_[k] == cell) {
      slot = k;
      break;
    }
  }
  if (slot == kMaxTabuCells) {
    slot = 0;
    for (std::size_t k = 1; k < tabu_size_; ++k) {
      if (tabu_until_[k] < tabu_until_[slot]) slot = k;
    }
  }
  if (slot == tabu_size_) ++tabu_size_;
  tabu_cells_[slot] = cell;
  tabu_until_[slot] = nbv_iterations_ + config_.tabu_iterations;
}

bool SensingExecutive::choose_goal(const GridMapView& map, GridCell* goal) {
  const Status label = query_.label_component(map, current_);
  if (!ok(label)) {
    fail(label, "cannot label the free cells reachable from the robot");
    return false;
  }
  const GridGeometry& geo = map.geometry;
  switch (config_.policy) {
    case PlannerPolicy::kNbv:
    case PlannerPolicy::kReactive:
    case PlannerPolicy::kDirect: {
      // ComputeNBV: the free cell of minimal cost (the criterion's maximum). When it lies outside the
      // robot's component (enclosed), take the best reachable one instead.
      bool any_free = false, any_reachable = false;
      float best_free = 0.0f, best_reachable = 0.0f;
      for (int pass = 0; pass < 2 && !any_reachable; ++pass) {
        const bool honour_tabu = pass == 0 && tabu_size_ > 0;
        any_free = false;
        for (std::int32_t i = 0; i < geo.cell_count(); ++i) {
          if (map.free[i] == 0) continue;
          const GridCell cell = geo.cell_at(i);
          if (honour_tabu && is_tabu(cell)) continue;
          const float cost = map.cost[i];
          if (!any_free || cost < best_free) {
            any_free = true;
            best_free = cost;
          }
          if (query_.in_component(cell) && (!any_reachable || cost < best_reachable)) {
            any_reachable = true;
            best_reachable = cost;
            *goal = cell;
          }
        }
        if (tabu_size_ == 0) break;
      }
      if (!any_free || !any_reachable) {
        fail(Status::kNoFreeCell, "no free cell in the grid");
        return false;
      }
      if (best_free < best_reachable) ++unreachable_nbv_;
      return true;
    }
    case PlannerPolicy::kRandom: {
      const Status pick = random_component_cell(map, query_, current_, rng_, goal);
      if (!ok(pick)) {
        fail(pick, "no free cell reachable from the robot");
        return false;
      }
      return true;
    }
    case PlannerPolicy::kOrbit:
      *goal = current_;  // build_plan fills the lap; the goal is its last cell
      return true;
  }
  return false;
}

bool SensingExecutive::build_plan(const GridMapView& map, const GridCell& goal) {
  plan_size_ = 0;
  switch (config_.policy) {
    case PlannerPolicy::kNbv:
    case PlannerPolicy::kReactive: {
      const Status split = split_.plan(map, current_, goal, config_.split, query_);
      if (ok(split)) {
        const Span<const GridCell> waypoints = split_.waypoints();
        for (const GridCell& cell : waypoints) plan_[plan_size_++] = cell;
      } else {
        const Status direct = query_.find(map, current_, goal);
        if (!ok(direct)) {
          fail(direct, "no path from the robot to the NBV");
          return false;
        }
        ++split_fallbacks_;  // Fig. 2 returned FALSE: sense at every PathQry cell instead
        const Span<const GridCell> path = query_.path();
        for (std::size_t i = path.size() > 1 ? 1 : 0; i < path.size(); ++i) plan_[plan_size_++] = path[i];
      }
      if (config_.policy == PlannerPolicy::kReactive) plan_size_ = 1;  // one step, then a new NBV
      return true;
    }
    case PlannerPolicy::kDirect:
    case PlannerPolicy::kRandom:
      plan_[plan_size_++] = goal;
      return true;
    case PlannerPolicy::kOrbit: {
      std::size_t count = 0;
      const Status lap = orbit_cells(map, config_.orbit_radius_m, pose_.position_world.head<2>(),
                                     Span<GridCell>(segment_, kMaxPlanningGridCells), &count);
      if (!ok(lap)) {
        fail(lap, lap == Status::kNoFreeCell ? "no free cell on the orbit" : "the orbit does not fit the grid");
        return false;
      }
      for (std::size_t i = 0; i < count; ++i) {
        if (segment_[i] == current_ || !query_.in_component(segment_[i])) continue;
        plan_[plan_size_++] = segment_[i];
      }
      if (plan_size_ == 0) plan_[plan_size_++] = current_;
      return true;
    }
  }
  return false;
}

void SensingExecutive::predict_model(const GridCell& goal) {
  Viewpoint view;
  if (!ok(grid_.viewpoint(goal, &view))) return;
  const std::size_t visible =
      grid_.visible_primitives(view, pool_, Span<PrimitiveIndex>(predicted_index_, kMaxPredictedPrimitives));
  std::size_t kept = 0;
  for (std::size_t k = 0; k < visible && k < kMaxPredictedPrimitives; ++k) {
    const PrimitiveIndex index = predicted_index_[k];
    if (!consumable(pool_, index)) continue;
    Eigen::Matrix3d Sigma_predicted;
    if (!ok(predict_covariance(pool_[index], view, measurement_.intrinsics(), config_.R_px2, &Sigma_predicted))) {
      continue;
    }
    predicted_index_[kept] = index;
    predicted_det_[kept] = Sigma_predicted.determinant();
    ++kept;
  }
  predicted_size_ = kept;
  utility_ = compute_utility();
  utility_planned_ = utility_;
}

double SensingExecutive::compute_utility() const {
  double u = 0.0;
  for (std::size_t k = 0; k < predicted_size_; ++k) {
    const PrimitiveIndex index = predicted_index_[k];
    if (!consumable(pool_, index)) continue;
    u += pool_[index].Sigma_world.determinant() - predicted_det_[k];
  }
  return u;
}

void SensingExecutive::advance() {
  if (plan_pos_ >= plan_size_) {
    request_replan(ReplanReason::kPathEnd);
    return;
  }
  const GridMapView map = planning_map();
  if (segment_size_ == 0) {
    // PathQry to the next waypoint: the motion follows it cell by cell.
    const GridCell target = plan_[plan_pos_];
    if (target != current_) {
      if (!ok(query_.find(map, current_, target))) {
        request_replan(ReplanReason::kPathBlocked);
        return;
      }
      const Span<const GridCell> path = query_.path();
      for (std::size_t i = 1; i < path.size(); ++i) segment_[segment_size_++] = path[i];
    }
    segment_pos_ = 0;
  }
  if (segment_pos_ < segment_size_) {
    const GridCell next = segment_[segment_pos_];
    if (!map.is_free(next)) {
      request_replan(ReplanReason::kPathBlocked);
      return;
    }
    action_ = SensingAction{};
    action_.kind = SensingActionKind::kMoveTo;
    action_.cell = next;
    if (!ok(grid_.viewpoint(next, &action_.view))) fail(Status::kInvalidArgument, "the grid has no viewpoint for a cell");
    return;
  }
  issue_capture();
}

void SensingExecutive::issue_capture() {
  if (images_ >= config_.max_images) {
    finish(DoneReason::kBudgetExhausted, "image budget exhausted");
    return;
  }
  action_ = SensingAction{};
  action_.kind = SensingActionKind::kCapture;
  action_.cell = current_;
  if (!ok(grid_.viewpoint(current_, &action_.view))) fail(Status::kInvalidArgument, "the grid has no viewpoint for a cell");
}

void SensingExecutive::on_arrived(const Viewpoint& pose) {
  if (action_.kind != SensingActionKind::kMoveTo) {
    fail(Status::kInvalidArgument, "on_arrived() without a pending kMoveTo");
    return;
  }
  const GridMapView map = grid_.map();
  GridCell cell{};
  if (!locate(pose, map, &cell) || cell != action_.cell) {
    fail(Status::kInvalidArgument, "the robot stopped outside the commanded cell");
    return;
  }
  path_length_cells_ += step_length_cells(current_, cell);
  current_ = cell;
  pose_ = pose;
  ++segment_pos_;
  if (segment_pos_ < segment_size_ && config_.capture_on_segments) {
    issue_capture();
    return;
  }
  advance();
}

void SensingExecutive::on_image(const GrayImageView& image, const Viewpoint& pose) {
  if (action_.kind != SensingActionKind::kCapture) {
    fail(Status::kInvalidArgument, "on_image() without a pending kCapture");
    return;
  }
  ++images_;
  replans_without_image_ = 0;
  pose_ = pose;
  last_update_ = UpdateReport{};
  last_measurement_ = measurement_.update(image, pose, pool_, &last_update_);
  if (!ok(last_measurement_)) ++rejected_images_;
  grid_.refresh_free_cells(pool_);
  precision_ = average_sigma(pool_);
  utility_ = compute_utility();
  if (goals_reached()) {
    finish(DoneReason::kGoalsReached, "goals reached");
    return;
  }
  if (images_ >= config_.max_images) {
    finish(DoneReason::kBudgetExhausted, "image budget exhausted");
    return;
  }
  const bool at_waypoint = segment_pos_ >= segment_size_;
  if (at_waypoint) {
    ++plan_pos_;
    segment_size_ = segment_pos_ = 0;
  }
  switch (config_.policy) {
    case PlannerPolicy::kNbv: {
      const bool benefit_met = utility_ < config_.eta_utility ||
                               (config_.eta_relative > 0.0 && utility_ < config_.eta_relative * utility_planned_);
      if (predicted_size_ > 0 && benefit_met) {
        request_replan(ReplanReason::kUtility);
        return;
      }
      const GridMapView map = planning_map();
      if (!ok(query_.find(map, current_, nbv_))) {
        request_replan(ReplanReason::kPathBlocked);
        return;
      }
      break;
    }
    case PlannerPolicy::kReactive:
      request_replan(ReplanReason::kEveryImage);
      return;
    case PlannerPolicy::kDirect:
    case PlannerPolicy::kOrbit:
    case PlannerPolicy::kRandom:
      break;
  }
  advance();  // replans at the end of the path
}

}  // namespace vantage
