// The criterion's inner loops for the baseline ISA of the target (SSE2 on x86-64, NEON on aarch64): see
// block_kernel.hpp. Compiled with -fno-trapping-math -fno-math-errno (core/CMakeLists.txt).
#define VANTAGE_KERNEL_NS baseline
#include "core/criterion/block_kernel_impl.hpp"
