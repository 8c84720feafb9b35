// Per-cell and per-vertex kernel bodies of the geometric multigrid (doc/theory.md, "Geometric
// multigrid", "Kernel bodies for a CUDA backend"). Plain inline functions on raw arrays, free of
// PETSc and STL containers, so a CUDA backend can run the same bodies (HEXCUT_HD marks them
// __host__ __device__ under nvcc).
//
// Conventions: corner q = a + 2b + 4c (x fastest), element DOF 3q + d, 24x24 matrices
// row-major. The child of a coarse cell in octant o = a + 2b + 4c is the fine cell at
// offset (a,b,c) in the 2x2x2 block.
#pragma once

#include <utility>

#include "element/fine_cell.hpp"
#include "element/host_device.hpp"
#include "element/reference.hpp"
#include "element/trilinear.hpp"

namespace hexcut::multigrid {

using element::fine_cell_apply_add;
using element::fine_row_block;
using element::FineCell;
using element::three_rows;

using element::child_weight;
using element::corner_colour;
using element::corner_of_colour;

/// A_parent += W^T A_child W with W = kron(w, I3), w(i, j) = child_weight(octant, i, j)
/// the weight of coarse corner j at fine corner i (24x24 row-major; A_child need not be
/// symmetric).
///
/// With both corner indices reflected by the octant, w(i, j) = w0(i ^ octant, j ^ octant),
/// w0 the weights of octant 0, whose fine corner k sits at k/2 in the coarse cell:
/// w0(k, K) = 2^-|k| when the bits of K are a subset of those of k, else 0 (27 nonzeros of
/// 64). So the loops are the same for every octant, with constant weights once unrolled
/// (zero terms dropped), and the octant only moves the rows and columns read and written.
/// Per row (K, e) of the result, K a coarse corner in the reflected frame:
///   t = sum_k w0(k, K) A_child[row (k ^ octant, e)]         (row of W^T A, 24 wide)
///   A_parent[row (K ^ octant, e)][corner K' ^ octant] += sum_k' w0(k', K') t[corner k' ^ octant]
/// About 3.9k multiply-adds (both products over the nonzeros only) with 24 doubles of
/// scratch, registers or 192 bytes of stack per GPU thread (doc/theory.md, "Kernel bodies
/// for a CUDA backend"), where two 24x24 intermediates took 9.6 KB.
HEXCUT_HD inline void galerkin_accumulate(const double* A_child, int octant, double* A_parent) {
  HEXCUT_UNROLL
  for (int K = 0; K < 8; ++K)
    for (int e = 0; e < 3; ++e) {
      double t[24];
      for (int c = 0; c < 24; ++c) t[c] = 0.0;
      HEXCUT_UNROLL
      for (int k = 0; k < 8; ++k) {
        const double w = child_weight(0, k, K);
        if (w == 0.0) continue;
        const double* a = A_child + 24 * (3 * (k ^ octant) + e);
        for (int c = 0; c < 24; ++c) t[c] += w * a[c];
      }
      double* out = A_parent + 24 * (3 * (K ^ octant) + e);
      HEXCUT_UNROLL
      for (int Kc = 0; Kc < 8; ++Kc) {
        double s0 = 0.0, s1 = 0.0, s2 = 0.0;
        HEXCUT_UNROLL
        for (int kc = 0; kc < 8; ++kc) {
          const double w = child_weight(0, kc, Kc);
          if (w == 0.0) continue;
          const double* tk = t + 3 * (kc ^ octant);
          s0 += w * tk[0];
          s1 += w * tk[1];
          s2 += w * tk[2];
        }
        double* o = out + 3 * (Kc ^ octant);
        o[0] += s0;
        o[1] += s1;
        o[2] += s2;
      }
    }
}

/// A_parent += W^T A_child W for a general interpolation W of the child (24x24 row-major:
/// row 3q + a is fine DOF a of child corner q, column 3j + b coarse DOF b of parent corner
/// j), as energy-minimizing interpolation gives (doc/theory.md, "Coarse spaces"). Row p of
/// A_child W is formed in 24 doubles of scratch, then added as the rank-one update
/// W[p]^T (A_child W)[p]: 2 x 24^3 multiply-adds, registers or 192 bytes of stack per GPU
/// thread, like galerkin_accumulate. Zero entries of W (most of a trilinear row) are
/// skipped in the update.
HEXCUT_HD inline void galerkin_accumulate_general(const double* A_child, const double* W,
                                                  double* A_parent) {
  for (int p = 0; p < 24; ++p) {
    double t[24];
    for (int j = 0; j < 24; ++j) t[j] = 0.0;
    const double* a = A_child + 24 * p;
    for (int q = 0; q < 24; ++q) {
      const double aq = a[q];
      if (aq == 0.0) continue;
      const double* w = W + 24 * q;
      for (int j = 0; j < 24; ++j) t[j] += aq * w[j];
    }
    const double* wp = W + 24 * p;
    for (int i = 0; i < 24; ++i) {
      const double wi = wp[i];
      if (wi == 0.0) continue;
      double* out = A_parent + 24 * i;
      for (int j = 0; j < 24; ++j) out[j] += wi * t[j];
    }
  }
}

/// A += w R^ G R^T with R^ = diag(R, ..., R) (8 copies of the 3x3 rotation R, row-major):
/// the Galerkin block of a rotated fine cell from its unrotated one. For trilinear W =
/// kron(w, I3), W^T R^ = R^ W^T, so W^T (R^ K R^T) W = R^ (W^T K W) R^T: with G = W^T K W
/// formed once per stiffness and octant, a corotational rebuild rotates G instead of
/// forming R^ K R^T and the product (doc/theory.md, "Geometric multigrid", "Corotation").
/// G symmetric (24x24 row-major); both triangles of A are written. 36 block products of
/// 54 multiply-adds, 18 doubles of scratch.
HEXCUT_HD inline void rotated_block_add(const double* G, const double* R, double w, double* A) {
  for (int P = 0; P < 8; ++P)
    for (int Q = P; Q < 8; ++Q) {
      double T[9];  // G_PQ R^T
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) {
          const double* g = G + 24 * (3 * P + i) + 3 * Q;
          T[3 * i + j] = g[0] * R[3 * j] + g[1] * R[3 * j + 1] + g[2] * R[3 * j + 2];
        }
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) {
          const double b =
              w * (R[3 * i] * T[j] + R[3 * i + 1] * T[3 + j] + R[3 * i + 2] * T[6 + j]);
          A[24 * (3 * P + i) + 3 * Q + j] += b;
          if (Q != P) A[24 * (3 * Q + j) + 3 * P + i] += b;
        }
    }
}

/// Packed storage of a symmetric 24x24 matrix: the upper triangle column by column (LAPACK's
/// "upper packed" format, AP(r + c(c+1)/2) = A(r, c) for r <= c), 300 numbers instead of 576
/// (coarse Galerkin blocks are symmetric). Column c starts at c(c+1)/2 and holds rows 0..c, so
/// every column is contiguous and starts at row 0: the apply below runs over fixed-length,
/// aligned-at-row-0 slices (doc/theory.md, "Storing and applying the coarse blocks").
constexpr int kPackedSize = 300;
HEXCUT_HD inline int packed_index(int r, int c) {
  if (r > c) {
    const int t = r;
    r = c;
    c = t;
  }
  return r + (c * (c + 1)) / 2;
}

// The packed blocks may be stored in float (-gmg_precision single: half the memory and
// memory traffic of the coarse levels); T is the stored type, the arithmetic is double.
template <class T>
HEXCUT_HD inline void pack_symmetric(const double* A, T* P) {
  for (int c = 0; c < 24; ++c)
    for (int r = 0; r <= c; ++r) P[packed_index(r, c)] = T(A[24 * r + c]);
}

template <class T>
HEXCUT_HD inline void unpack_symmetric(const T* P, double* A) {
  for (int r = 0; r < 24; ++r)
    for (int c = 0; c < 24; ++c) A[24 * r + c] = double(P[packed_index(r, c)]);
}

/// y3 = rows 3q..3q+2 of the packed symmetric matrix times x24.
template <class T>
HEXCUT_HD inline void packed_row_block(const T* P, int q, const double* x24, double* y3) {
  double rows[72];  // the three rows, unpacked
  for (int e = 0; e < 3; ++e)
    for (int c = 0; c < 24; ++c) rows[24 * e + c] = double(P[packed_index(3 * q + e, c)]);
  three_rows(rows, x24, y3);
}

namespace detail {
// Column C of the upper packed matrix: its rows 0..C-1 add x_C times the column to the
// accumulators (the upper triangle) and their dot product with x to y_C (the lower
// triangle, by symmetry), the diagonal once. C is a template argument so that the
// lengths are constants: the loops vectorize and the accumulators stay in registers.
template <int C, class T>
HEXCUT_HD HEXCUT_INLINE void packed_column(const T* P, const double* x24, double* acc,
                                           double* dot) {
  const T* col = P + (C * (C + 1)) / 2;
  const double xc = x24[C];
  double d = 0.0;
  HEXCUT_UNROLL
  for (int r = 0; r < C; ++r) {
    const double p = double(col[r]);
    acc[r] += p * xc;
    d += p * x24[r];
  }
  dot[C] = d + double(col[C]) * xc;
}

template <class T, int... C>
HEXCUT_HD HEXCUT_INLINE void packed_columns(const T* P, const double* x24, double* acc, double* dot,
                                            std::integer_sequence<int, C...>) {
  (packed_column<C>(P, x24, acc, dot), ...);
}
}  // namespace detail

/// y24 += P x24 for a packed symmetric matrix: each off-diagonal entry is used twice, once
/// in its column's multiply-add (upper triangle) and once in its dot product (lower); the
/// diagonal once.
template <class T>
HEXCUT_HD inline void packed_apply_add(const T* P, const double* x24, double* y24) {
  double acc[24] = {0.0}, dot[24];
  detail::packed_columns(P, x24, acc, dot, std::make_integer_sequence<int, 24>{});
  for (int r = 0; r < 24; ++r) y24[r] += acc[r] + dot[r];
}

/// Inverse of a 3x3 matrix (row-major); returns false when singular.
HEXCUT_HD inline bool invert3(const double* a, double* inv) {
  const double c00 = a[4] * a[8] - a[5] * a[7], c01 = a[5] * a[6] - a[3] * a[8],
               c02 = a[3] * a[7] - a[4] * a[6];
  const double det = a[0] * c00 + a[1] * c01 + a[2] * c02;
  if (det == 0.0) return false;
  const double s = 1.0 / det;
  inv[0] = c00 * s;
  inv[1] = (a[2] * a[7] - a[1] * a[8]) * s;
  inv[2] = (a[1] * a[5] - a[2] * a[4]) * s;
  inv[3] = c01 * s;
  inv[4] = (a[0] * a[8] - a[2] * a[6]) * s;
  inv[5] = (a[2] * a[3] - a[0] * a[5]) * s;
  inv[6] = c02 * s;
  inv[7] = (a[1] * a[6] - a[0] * a[7]) * s;
  inv[8] = (a[0] * a[4] - a[1] * a[3]) * s;
  return true;
}

}  // namespace hexcut::multigrid
