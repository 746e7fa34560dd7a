// The criterion's inner loops built with -mavx2 -mfma (core/CMakeLists.txt, x86-64 only); chosen at run
// time when the CPU has both (criterion_kernel.cpp). Empty on other architectures.
#if defined(__x86_64__)
#if !defined(__AVX2__) || !defined(__FMA__)
#error "block_kernel_avx2.cpp must be compiled with -mavx2 -mfma"
#endif
#define VANTAGE_KERNEL_NS avx2_fma
#include "core/criterion/block_kernel_impl.hpp"
#endif
