// The block kernel in its own translation unit, compiled with -fno-trapping-math -fno-math-errno
// (core/CMakeLists.txt) so that GCC vectorizes it.
#include "core/criterion/block_kernel.hpp"

#include "core/criterion/block_kernel_impl.hpp"

namespace vantage {

void block_kernel(const CriterionArrays& arrays, std::size_t base, const BlockConstants& constants, BlockOutput& out) {
  block_kernel_body(arrays, base, constants, out);
}

}  // namespace vantage
