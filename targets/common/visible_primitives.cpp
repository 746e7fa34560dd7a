#include "targets/common/visible_primitives.hpp"

namespace vantage::targets {

std::size_t visible_primitives_refreshed(CriterionModelView& model, const PrimitivePoolView& pool, const Viewpoint& view,
                                         const PinholeIntrinsics& intrinsics, CriterionScratchView& scratch,
                                         Span<PrimitiveIndex> out) {
  if (model.pool_revision() != pool.revision() || !model.refreshed()) {
    if (!ok(model.refresh(pool))) return 0;
  }
  std::size_t count = 0;
  const Status s = model.visible_primitives(view, intrinsics, scratch, out, &count);
  if (!ok(s) && s != Status::kPoolFull) return 0;
  return count < out.size() ? count : out.size();
}

}  // namespace vantage::targets
