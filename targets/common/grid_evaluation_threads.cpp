#include "targets/common/grid_evaluation_threads.hpp"

#include <atomic>
#include <thread>

namespace vantage::targets {

Status evaluate_grid_on_two_threads(ViewGridView& grid, const CriterionModelView& model,
                                    const PinholeIntrinsics& intrinsics, CriterionScratchView& scratch_calling,
                                    CriterionScratchView& scratch_helper) {
  const std::int32_t rows = grid.cells_per_side();
  std::atomic<std::int32_t> next_row{0};
  std::atomic<int> first_error{static_cast<int>(Status::kOk)};
  // Rows are handed out one at a time so a thread slowed by the shared machine does not hold the other up.
  auto worker = [&](CriterionScratchView& scratch) {
    for (std::int32_t row = next_row++; row < rows; row = next_row++) {
      const Status r = grid.evaluate(model, intrinsics, row * rows, (row + 1) * rows, scratch);
      if (!ok(r)) {
        int expected = static_cast<int>(Status::kOk);
        first_error.compare_exchange_strong(expected, static_cast<int>(r));
      }
    }
  };
  std::thread helper(worker, std::ref(scratch_helper));
  worker(scratch_calling);
  helper.join();
  if (first_error.load() != static_cast<int>(Status::kOk)) return static_cast<Status>(first_error.load());
  const Status s = grid.finalize();
  if (s == Status::kNotFound || s == Status::kNoFreeCell) return Status::kOk;
  return s;
}

}  // namespace vantage::targets
