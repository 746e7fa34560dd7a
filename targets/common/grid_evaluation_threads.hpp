#pragma once
// The one place where targets spread a view-grid evaluation over threads (the core starts none).
#include "core/common/status.hpp"
#include "core/criterion/criterion_model.hpp"
#include "core/criterion/view_grid.hpp"
#include "core/geometry/pinhole_intrinsics.hpp"

namespace vantage::targets {

// Evaluates every cell of grid, a row at a time, on the calling thread and one helper thread, each with
// its own scratch; then finalizes costs and the NBV. A grid with no free cell, or none that sees a
// primitive, is not an error here (kOk): the sensing executive decides what that means.
Status evaluate_grid_on_two_threads(ViewGridView& grid, const CriterionModelView& model,
                                    const PinholeIntrinsics& intrinsics, CriterionScratchView& scratch_calling,
                                    CriterionScratchView& scratch_helper);

}  // namespace vantage::targets
