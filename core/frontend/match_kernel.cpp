// The matcher's inner loops for the baseline ISA of the target (SSE2 on x86-64, NEON on aarch64), and the
// run-time choice between the builds: see match_kernel.hpp. Compiled with -O3 -fno-trapping-math
// -fno-math-errno (core/CMakeLists.txt).
#define VANTAGE_MATCH_KERNEL_NS baseline
#include "core/frontend/match_kernel_impl.hpp"

namespace vantage {

const char* to_string(MatchKernel kernel) {
  switch (kernel) {
    case MatchKernel::kAuto:
      return "auto";
    case MatchKernel::kBaseline:
#if defined(__x86_64__)
      return "baseline (SSE2)";
#elif defined(__aarch64__)
      return "baseline (NEON)";
#else
      return "baseline";
#endif
    case MatchKernel::kAvx2Fma:
      return "AVX2+FMA";
  }
  return "unknown";
}

bool match_kernel_supported(MatchKernel kernel) {
  switch (kernel) {
    case MatchKernel::kAuto:
    case MatchKernel::kBaseline:
      return true;
    case MatchKernel::kAvx2Fma:
#if VANTAGE_MATCH_HAS_AVX2_KERNEL
      // libgcc's CPU model (it also checks that the OS saves the AVX registers); a load and a bit test
      // once initialized, so it is asked on every search instead of cached in mutable state.
      __builtin_cpu_init();
      return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
#else
      return false;
#endif
  }
  return false;
}

namespace match_kernel {

Functions functions(MatchKernel kernel) {
#if VANTAGE_MATCH_HAS_AVX2_KERNEL
  if ((kernel == MatchKernel::kAuto || kernel == MatchKernel::kAvx2Fma) &&
      match_kernel_supported(MatchKernel::kAvx2Fma)) {
    return {avx2_fma::ncc_box, avx2_fma::refine};
  }
#endif
  (void)kernel;
  return {baseline::ncc_box, baseline::refine};
}

}  // namespace match_kernel
}  // namespace vantage
