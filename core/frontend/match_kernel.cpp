// The matcher's inner loops for the baseline ISA of the target (SSE2 on x86-64, NEON on aarch64): see
// match_kernel.hpp (the run-time choice between the builds is in ncc.cpp). Compiled with -O3
// -fno-trapping-math -fno-math-errno (core/CMakeLists.txt).
#define VANTAGE_MATCH_KERNEL_NS baseline
#include "core/frontend/match_kernel_impl.hpp"
