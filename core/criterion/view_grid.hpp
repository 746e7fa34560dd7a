#pragma once
// The view grid of the paper (section V): M x M cells on the plane z = elevation around the object, one
// viewpoint per cell at its centre looking at the object's centre, F(nu) of every cell, and the cost the
// path planner reads (cost = inverse of F scaled linearly to [0, 1], lower is better).
//
// Free mask: the core knows the object only through its primitives, so a cell is not free when its
// centre lies within safety_margin_m (scene units, horizontal distance) of the xy projection of any
// primitive, whatever the primitive's height (conservative: the robot flies at one elevation, the
// object may reach it anywhere). Obstacles the core cannot see (walls, a table, no-fly zones) are
// the target's to add with set_blocked(). free = not under the object and not blocked.
//
// Evaluation: evaluate(model, intrinsics, begin, end, scratch) fills F for the flat cell range
// [begin, end) using the caller's scratch; disjoint ranges may run on different threads at once, each
// with its own CriterionScratch (the core starts no threads). finalize() then needs every cell evaluated
// since the last configure() or finalize(): it computes the costs and the NBV, the free cell of largest
// F (= minimal cost; ties go to the lowest flat index).
#include <array>
#include <cstdint>

#include <Eigen/Core>

#include "core/common/status.hpp"
#include "core/criterion/criterion_model.hpp"
#include "core/geometry/pinhole_intrinsics.hpp"
#include "core/geometry/viewpoint.hpp"
#include "core/grid/grid_geometry.hpp"

namespace vantage {

inline constexpr double kDefaultSafetyMargin = 2.0;  // scene units: one default cell

class ViewGridView {
 public:
  ViewGridView(const ViewGridView&) = delete;
  ViewGridView& operator=(const ViewGridView&) = delete;

  // Sets the geometry (cells_per_side must be this grid's M) and every cell's viewpoint: at the cell
  // centre, looking at look_target_world, image up towards +z (+y for a cell straight above or below the
  // target; no viewpoint, F = 0, for a cell centre on the target). Resets F, the costs, the NBV and the
  // object mask; keeps the blocked cells. kNonFiniteInput or kInvalidArgument (M mismatch,
  // non-positive cell size), nothing changed.
  Status configure(const GridGeometry& geometry, const Eigen::Vector3d& look_target_world);

  // Marks the cells under the model's primitives (see the file comment). kNonFiniteInput or
  // kInvalidArgument (negative margin), kInvalidArgument before configure(); nothing changed on error.
  Status update_free_mask(const CriterionModelView& model, double safety_margin_m);
  // kNotFound for a cell outside the grid.
  Status set_blocked(const GridCell& cell, bool blocked);
  void clear_blocked();

  // F for the cells [begin, end) (flat indices). kInvalidArgument for a bad range or before configure(),
  // and the errors of CriterionModelView::evaluate (checked before any cell is written).
  Status evaluate(const CriterionModelView& model, const PinholeIntrinsics& intrinsics, std::int32_t begin,
                  std::int32_t end, CriterionScratchView& scratch);
  // Costs and NBV. kInvalidArgument when some cell was not evaluated, kNoFreeCell when no cell is free,
  // kNotFound when no free cell sees any primitive (F = 0 everywhere free): no NBV then.
  Status finalize();

  bool configured() const { return configured_; }
  bool has_nbv() const { return has_nbv_; }
  GridCell nbv() const { return nbv_; }
  double F(const GridCell& cell) const { return F_[geometry_.flat_index(cell)]; }
  float cost(const GridCell& cell) const { return cost_[geometry_.flat_index(cell)]; }
  bool is_free(const GridCell& cell) const { return geometry_.contains(cell) && free_[geometry_.flat_index(cell)] != 0; }
  bool is_blocked(const GridCell& cell) const { return geometry_.contains(cell) && blocked_[geometry_.flat_index(cell)] != 0; }
  bool has_viewpoint(const GridCell& cell) const { return view_ok_[geometry_.flat_index(cell)] != 0; }
  const Viewpoint& viewpoint(const GridCell& cell) const { return views_[geometry_.flat_index(cell)]; }
  const GridGeometry& geometry() const { return geometry_; }
  std::int32_t cells_per_side() const { return cells_per_side_; }
  std::int32_t cell_count() const { return cells_per_side_ * cells_per_side_; }
  // For the path planner: free mask and costs (valid after finalize()).
  GridMapView map() const;

 protected:
  ViewGridView(std::int32_t cells_per_side, Viewpoint* views, std::uint8_t* view_ok, double* F, float* cost,
               std::uint8_t* object, std::uint8_t* blocked, std::uint8_t* free_mask, std::uint8_t* evaluated)
      : cells_per_side_(cells_per_side), views_(views), view_ok_(view_ok), F_(F), cost_(cost), object_(object),
        blocked_(blocked), free_(free_mask), evaluated_(evaluated) {
    geometry_.cells_per_side = cells_per_side;
  }
  ~ViewGridView() = default;

 private:
  void recompute_free();

  std::int32_t cells_per_side_;
  Viewpoint* views_;
  std::uint8_t* view_ok_;
  double* F_;
  float* cost_;
  std::uint8_t* object_;
  std::uint8_t* blocked_;
  std::uint8_t* free_;
  std::uint8_t* evaluated_;
  GridGeometry geometry_{};
  GridCell nbv_{};
  bool has_nbv_ = false;
  bool configured_ = false;
};

// The grid's arrays, a base class constructed before ViewGridView receives pointers to them.
template <std::size_t Cells>
struct ViewGridStorage {
  std::array<Viewpoint, Cells> views_{};
  std::array<std::uint8_t, Cells> view_ok_{};
  std::array<double, Cells> F_{};
  std::array<float, Cells> cost_{};
  std::array<std::uint8_t, Cells> object_{};
  std::array<std::uint8_t, Cells> blocked_{};
  std::array<std::uint8_t, Cells> free_{};
  std::array<std::uint8_t, Cells> evaluated_{};
};

template <std::int32_t M = 60>
class ViewGrid : private ViewGridStorage<static_cast<std::size_t>(M) * static_cast<std::size_t>(M)>,
                 public ViewGridView {
 public:
  static_assert(M > 0 && M <= 4096, "grid side out of range");
  static constexpr std::int32_t kCellsPerSide = M;
  static constexpr std::size_t kCells = static_cast<std::size_t>(M) * static_cast<std::size_t>(M);
  ViewGrid()
      : ViewGridView(M, Storage::views_.data(), Storage::view_ok_.data(), Storage::F_.data(), Storage::cost_.data(),
                     Storage::object_.data(), Storage::blocked_.data(), Storage::free_.data(),
                     Storage::evaluated_.data()) {}

 private:
  using Storage = ViewGridStorage<kCells>;  // qualified: the view has members of the same names
};

}  // namespace vantage
