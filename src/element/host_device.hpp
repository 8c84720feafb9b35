// Marker for per-cell kernel bodies that a CUDA backend will also compile (doc/theory.md, "Kernel
// bodies for a CUDA backend"). Under nvcc the functions become __host__ __device__; otherwise the
// macro is empty so the same bodies stay plain inline C++ for the CPU backend and the tests.
#pragma once

#ifndef HEXCUT_HD
#if defined(__CUDACC__)
#define HEXCUT_HD __host__ __device__
#else
#define HEXCUT_HD
#endif
#endif

// Full unrolling of a short loop with a constant trip count (at most 8), for loops whose
// unrolled indices let the compiler fold weights to constants and drop zero terms:
// `#pragma unroll` in nvcc's device pass, GCC's `#pragma GCC unroll 8`, nothing elsewhere
// (nvcc's host pass knows neither pragma in a way its host compiler accepts silently).
#ifndef HEXCUT_UNROLL
#if defined(__CUDA_ARCH__)
#define HEXCUT_UNROLL _Pragma("unroll")
#elif defined(__CUDACC__)
#define HEXCUT_UNROLL
#elif defined(__GNUC__) && !defined(__clang__)
#define HEXCUT_UNROLL _Pragma("GCC unroll 8")
#else
#define HEXCUT_UNROLL
#endif
#endif

// Inlining a kernel body into its loop: a cell's data then stay in registers instead of
// passing through a struct on the stack at every call (about 20 instructions per cell on
// the fine operator, whose body alone is ~120).
#ifndef HEXCUT_INLINE
#if defined(__CUDACC__)
#define HEXCUT_INLINE __forceinline__
#elif defined(__GNUC__)
#define HEXCUT_INLINE inline __attribute__((always_inline))
#else
#define HEXCUT_INLINE inline
#endif
#endif
