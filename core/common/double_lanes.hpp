#pragma once
// Where the core's functions on 4-double vector lanes (GCC vector extensions) run instead of their scalar
// forms: on x86-64 CPUs with AVX2 (a target attribute on the function, the CPU asked at run time; no FMA,
// so nothing is contracted), and on every AArch64 core (Advanced SIMD is part of the base ISA; a 4-double
// vector is two NEON registers). Elsewhere the scalar forms run. Such a function takes no vector
// arguments and calls no helper on vectors: a helper would not inherit the target attribute.
#if defined(__x86_64__)
#define VANTAGE_DOUBLE_LANES 1
#define VANTAGE_DOUBLE_LANES_TARGET __attribute__((target("avx2")))
#define VANTAGE_DOUBLE_LANES_AVAILABLE() __builtin_cpu_supports("avx2")
#elif defined(__aarch64__)
#define VANTAGE_DOUBLE_LANES 1
#define VANTAGE_DOUBLE_LANES_TARGET
#define VANTAGE_DOUBLE_LANES_AVAILABLE() true
#else
#define VANTAGE_DOUBLE_LANES 0
#endif
