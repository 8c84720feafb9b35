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
