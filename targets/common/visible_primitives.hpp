#pragma once
// PlanningGrid::visible_primitives for the targets' grids (the sim's GridDriver, the onboard OnboardGrid):
// the criterion cache is refreshed first when the pool changed since its last refresh.
#include <cstddef>

#include "core/common/span.hpp"
#include "core/criterion/criterion_model.hpp"
#include "core/geometry/pinhole_intrinsics.hpp"
#include "core/geometry/viewpoint.hpp"
#include "core/model/primitive_pool.hpp"

namespace vantage::targets {

// The pool indices of the primitives visible from view, at most out.size() of them (the rest are dropped,
// as the executive's buffer allows). 0 when the cache cannot be refreshed from the pool or the view is
// rejected (the executive then sees nothing to consume there).
std::size_t visible_primitives_refreshed(CriterionModelView& model, const PrimitivePoolView& pool, const Viewpoint& view,
                                         const PinholeIntrinsics& intrinsics, CriterionScratchView& scratch,
                                         Span<PrimitiveIndex> out);

}  // namespace vantage::targets
