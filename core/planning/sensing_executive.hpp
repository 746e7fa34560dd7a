#pragma once
// ExecuteSensing (paper Fig. 3) as a heap-free state machine that a target steps:
//
//   begin(two initial images)            -> MeasurementSource::initialize
//   loop: action = next()
//     kEvaluateGrid: the target evaluates the view grid (its threads), then calls on_grid_evaluated():
//                    ComputeNBV (the reachable free cell of minimal cost), SplitPath, PredictModel(nu*)
//     kMoveTo:       the target moves the robot to action.view, then calls on_arrived(pose)
//     kCapture:      the target grabs a frame at action.view, then calls on_image(frame, pose):
//                    UpdateModel; stop when PrecisionLevel(M) < rho (and the ExternalGoal, e.g. coverage
//                    in simulation); replan when U(M_nu*, M) < eta, when PathQry(x(nu), x(nu*)) fails
//                    after the update, or at the end of the path
//     kDone:         goals reached or image budget exhausted (done_reason)
//     kFailed:       no free cell, no path, a robot that did not arrive ... (failure + reason text)
//
// Motion between waypoints follows PathQry cell by cell (one kMoveTo per cell), so the robot never
// enters a non-free cell. Images are taken at SplitPath's waypoints; with capture_on_segments also at
// every intermediate cell of the connecting A* segments. With the default epsilon (0.75 cells) SplitPath
// already places a waypoint at every single-cell displacement (the paper's sampling rate), so both
// settings agree in open space and differ only where PathQry detours around obstacles.
//
// NBV unreachable (in another free component, e.g. enclosed): the executive plans to the minimal-cost
// cell reachable from the current one and counts it (unreachable_nbv_count()). SplitPath returning
// FALSE (an empty set S at some level, e.g. both ends hugging a thin wall) although PathQry connects the
// ends: the executive falls back to the PathQry cells as waypoints and counts it (split_fallback_count()).
//
// Stagnation guard. Proposition 1 (section V.C) relies on repeated images from the NBV consuming its
// criterion value. When the measurement source does not update the primitives that make the cell
// attractive (their true surface is occluded or grazing, a match fails), the NBV stays at the robot's
// cell forever. After stagnation_repeats NBVs in a row at the robot's cell, that cell is taboo for
// ComputeNBV during tabu_iterations NBV iterations (at most kMaxTabuCells cells at once; when every
// reachable cell is taboo the guard is ignored). stagnation_count() counts the interventions.
//
// The robot's own cell counts as free even when the grid marks it otherwise: the robot stands there, so
// a mark there comes from model error (e.g. a badly triangulated primitive near the camera). A grid
// with no free cell at all still fails with kNoFreeCell.
//
// U(M_nu*, M) = sum over the primitives visible from nu* (at PredictModel time) of det(Sigma_now) -
// det(Sigma_predicted). Both dets come from the same primitive index; primitives erased since then are
// left out of the sum, and so are primitives flagged primitive_flags::kUnconsumed (at PredictModel or
// since): the measurement source rejects their observations, so images do not consume their value (the
// criterion gives them w = 0 in F for the same reason; core/planning/README.md, "The cycling trap").
//
// The object holds every buffer (about 3 MB with the default pool capacity): keep it in static storage.
#include <cstddef>
#include <cstdint>

#include <Eigen/Core>

#include "core/common/span.hpp"
#include "core/common/status.hpp"
#include "core/frontend/measurement_source.hpp"
#include "core/geometry/viewpoint.hpp"
#include "core/grid/grid_geometry.hpp"
#include "core/image/gray_image.hpp"
#include "core/model/primitive_pool.hpp"
#include "core/planning/baselines.hpp"
#include "core/planning/path_query.hpp"
#include "core/planning/planner_policy.hpp"
#include "core/planning/planning_grid.hpp"
#include "core/planning/split_path.hpp"

namespace vantage {

// The largest model region PredictModel tracks: primitives visible from nu* beyond this are left out of U.
inline constexpr std::size_t kMaxPredictedPrimitives = kDefaultPrimitiveCapacity;
inline constexpr std::size_t kMaxTabuCells = 32;

struct SensingConfig {
  PlannerPolicy policy = PlannerPolicy::kNbv;
  SplitPathConfig split{};
  double rho_sigma = 0.008;          // PrecisionLevel goal: stop when the average sigma < rho (scene units)
  double eta_utility = 0.0;          // replan when U < eta (units^6, a sum of covariance determinants)
  // Also replan when U < eta_relative * U_0, U_0 = U right after PredictModel: the fraction of the NBV's
  // predicted benefit still outstanding (scale-free; see core/planning/README.md). 0: off.
  double eta_relative = 0.0;
  std::uint32_t max_images = 600;    // image budget, the two initial images included
  bool capture_on_segments = false;  // also sense at every intermediate cell of the A* segments
  double orbit_radius_m = 40.0;      // orbit baseline: circle radius around the grid centre
  std::uint64_t random_seed = 1;     // random baseline
  // Stagnation guard (not in the paper, see the file comment): after this many NBVs in a row at the
  // robot's own cell, that cell is left out of ComputeNBV for tabu_iterations NBV iterations. 0: off.
  std::uint32_t stagnation_repeats = 3;
  std::uint32_t tabu_iterations = 10;
  Eigen::Matrix2d R_px2 = Eigen::Matrix2d::Identity() * 0.25;  // measurement noise used by PredictModel

  // kInvalidArgument when a field is out of range (invalid_field() names it).
  Status validate() const;
  // The name of the first invalid field, or nullptr when the config is valid.
  const char* invalid_field() const;
};

enum class SensingActionKind : std::uint8_t { kEvaluateGrid, kMoveTo, kCapture, kDone, kFailed };
enum class DoneReason : std::uint8_t { kNone, kGoalsReached, kBudgetExhausted };
enum class ReplanReason : std::uint8_t { kNone, kInitial, kUtility, kPathBlocked, kPathEnd, kEveryImage };

const char* to_string(SensingActionKind kind);
const char* to_string(DoneReason reason);
const char* to_string(ReplanReason reason);

struct SensingAction {
  SensingActionKind kind = SensingActionKind::kFailed;
  GridCell cell{};                    // kMoveTo, kCapture: the cell of view
  Viewpoint view{};                   // kMoveTo, kCapture: where to be
  DoneReason done = DoneReason::kNone;
  ReplanReason replan = ReplanReason::kNone;  // kEvaluateGrid: why the plan is being renewed
  Status failure = Status::kOk;       // kFailed: the status behind it
  const char* reason = "";            // kFailed / kDone: one line for humans
};

class SensingExecutive {
 public:
  // The executive keeps references: every argument must outlive it. goal may be null.
  SensingExecutive(PrimitivePoolView& pool, MeasurementSource& measurement, PlanningGrid& grid, ExternalGoal* goal);

  // Starts a mission from the two initial small-baseline images (paper section VI). On error (bad
  // config, bad images or poses) the executive stays idle and next() reports kFailed.
  Status begin(const SensingConfig& config, const GrayImageView& first, const Viewpoint& first_view,
               const GrayImageView& second, const Viewpoint& second_view);

  const SensingAction& next() const { return action_; }

  // After kEvaluateGrid: the grid's map() is current. Runs ComputeNBV, SplitPath and PredictModel.
  void on_grid_evaluated();
  // After kMoveTo: the robot's pose now.
  void on_arrived(const Viewpoint& pose);
  // After kCapture: the frame and the pose it was taken from. A frame the measurement source rejects
  // still counts against the budget (the image was taken); the model stays unchanged.
  void on_image(const GrayImageView& image, const Viewpoint& pose);

  // Mission figures for progress lines and reports.
  std::uint32_t images() const { return images_; }
  std::uint32_t rejected_images() const { return rejected_images_; }
  std::uint32_t nbv_iterations() const { return nbv_iterations_; }
  double path_length_cells() const { return path_length_cells_; }
  double utility() const { return utility_; }            // U after the last update (or PredictModel)
  double precision_level() const { return precision_; }  // average sigma after the last update
  GridCell nbv_cell() const { return nbv_; }
  GridCell current_cell() const { return current_; }
  Span<const GridCell> plan() const { return Span<const GridCell>(plan_, plan_size_); }
  std::size_t plan_position() const { return plan_pos_; }
  std::size_t predicted_count() const { return predicted_size_; }
  std::uint32_t unreachable_nbv_count() const { return unreachable_nbv_; }
  std::uint32_t split_fallback_count() const { return split_fallbacks_; }
  std::uint32_t stagnation_count() const { return stagnations_; }
  ReplanReason last_replan_reason() const { return last_replan_; }
  const UpdateReport& last_update() const { return last_update_; }
  Status last_measurement_status() const { return last_measurement_; }

 private:
  void fail(Status status, const char* reason);
  void finish(DoneReason reason, const char* text);
  void request_replan(ReplanReason reason);
  void replan_now();
  bool goals_reached();
  bool locate(const Viewpoint& pose, const GridMapView& map, GridCell* cell) const;
  // ComputeNBV for the policy; false after fail().
  bool choose_goal(const GridMapView& map, GridCell* goal);
  bool is_tabu(const GridCell& cell) const;
  void add_tabu(const GridCell& cell);
  bool build_plan(const GridMapView& map, const GridCell& goal);
  void predict_model(const GridCell& goal);
  double compute_utility() const;
  // Issues the move or capture toward plan_[plan_pos_], or a replan at the end of the plan.
  void advance();
  void issue_capture();
  // The grid's map with the robot's own cell marked free (see the file comment); *free_count gets the
  // number of free cells the grid itself reports.
  GridMapView planning_map(std::int32_t* free_count = nullptr);

  PrimitivePoolView& pool_;
  MeasurementSource& measurement_;
  PlanningGrid& grid_;
  ExternalGoal* goal_;
  SensingConfig config_{};
  SensingAction action_{};
  SplitMix64 rng_{1};

  PathQuery query_;
  SplitPath split_;
  GridCell plan_[kMaxPlanningGridCells];     // waypoints: capture points, in order
  std::size_t plan_size_ = 0;
  std::size_t plan_pos_ = 0;                  // index of the waypoint being approached
  GridCell segment_[kMaxPlanningGridCells];  // PathQry cells from the last waypoint to plan_[plan_pos_]
  std::size_t segment_size_ = 0;
  std::size_t segment_pos_ = 0;               // index of the cell being approached

  std::uint8_t free_copy_[kMaxPlanningGridCells];

  PrimitiveIndex predicted_index_[kMaxPredictedPrimitives];
  double predicted_det_[kMaxPredictedPrimitives];
  std::size_t predicted_size_ = 0;

  Viewpoint pose_{};
  GridCell current_{};
  GridCell nbv_{};
  std::uint32_t images_ = 0;
  std::uint32_t rejected_images_ = 0;
  std::uint32_t nbv_iterations_ = 0;
  std::uint32_t unreachable_nbv_ = 0;
  std::uint32_t split_fallbacks_ = 0;
  std::uint32_t replans_without_image_ = 0;
  std::uint32_t stagnations_ = 0;
  std::uint32_t same_cell_nbvs_ = 0;
  GridCell tabu_cells_[kMaxTabuCells];
  std::uint32_t tabu_until_[kMaxTabuCells];  // taboo while nbv_iterations_ < this
  std::size_t tabu_size_ = 0;
  double path_length_cells_ = 0.0;
  double utility_ = 0.0;
  double utility_planned_ = 0.0;  // U_0: U right after PredictModel
  double precision_ = 0.0;
  ReplanReason last_replan_ = ReplanReason::kNone;
  UpdateReport last_update_{};
  Status last_measurement_ = Status::kOk;
};

}  // namespace vantage
