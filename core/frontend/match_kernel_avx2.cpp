// The matcher's inner loops built with -mavx2 -mfma (core/CMakeLists.txt, x86-64 only); chosen at run
// time when the CPU has both (match_kernel.cpp). Empty on other architectures.
#if defined(__x86_64__)
#if !defined(__AVX2__) || !defined(__FMA__)
#error "match_kernel_avx2.cpp must be compiled with -mavx2 -mfma"
#endif
#define VANTAGE_MATCH_KERNEL_NS avx2_fma
#include "core/frontend/match_kernel_impl.hpp"
#endif
