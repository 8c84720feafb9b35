// Per-cell and per-vertex kernel bodies of the geometric multigrid (doc/theory.md, "Geometric
// multigrid", "Kernel bodies for a CUDA backend"). Plain inline functions on raw arrays, free of
// PETSc and STL containers, so a CUDA backend can run the same bodies (HEXCUT_HD marks them
// __host__ __device__ under nvcc).
//
// Conventions: corner q = a + 2b + 4c (x fastest), element DOF 3q + d, 24x24 matrices
// row-major. The child of a coarse cell in octant o = a + 2b + 4c is the fine cell at
// offset (a,b,c) in the 2x2x2 block.
#pragma once

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

/// A_parent += W^T A_child W with W = kron(w, I3), w the 8x8 child weights of `octant`
/// (A_child symmetric). w has 27 nonzeros of 64 (a fine corner lies on a coarse corner,
/// edge, face or centre: 1, 2, 4 or 8 weights), so both products run over the nonzeros
/// only, about 3.9k multiply-adds instead of 2 x 24^3. Both are written as sums of
/// scaled contiguous rows (U = W^T A, then W^T U^T = (U W)^T = U W by symmetry), which
/// the compiler vectorizes.
HEXCUT_HD inline void galerkin_accumulate(const double* A_child, int octant, double* A_parent) {
  int nz_i[27], nz_j[27];
  double nz_w[27];
  int n = 0;
  for (int i = 0; i < 8; ++i)
    for (int j = 0; j < 8; ++j) {
      const double w = child_weight(octant, i, j);
      if (w != 0.0) nz_i[n] = i, nz_j[n] = j, nz_w[n++] = w;
    }
  double U[576], Ut[576];
  for (int k = 0; k < 576; ++k) U[k] = 0.0;
  for (int k = 0; k < n; ++k)
    for (int e = 0; e < 3; ++e) {
      const double* a = &A_child[24 * (3 * nz_i[k] + e)];
      double* u = &U[24 * (3 * nz_j[k] + e)];
      for (int c = 0; c < 24; ++c) u[c] += nz_w[k] * a[c];
    }
  for (int r = 0; r < 24; ++r)
    for (int c = 0; c < 24; ++c) Ut[24 * c + r] = U[24 * r + c];
  for (int k = 0; k < n; ++k)
    for (int e = 0; e < 3; ++e) {
      const double* u = &Ut[24 * (3 * nz_i[k] + e)];
      double* a = &A_parent[24 * (3 * nz_j[k] + e)];
      for (int c = 0; c < 24; ++c) a[c] += nz_w[k] * u[c];
    }
}

/// Packed storage of a symmetric 24x24 matrix: the upper triangle row by row, 300
/// numbers instead of 576 (coarse Galerkin blocks are symmetric).
constexpr int kPackedSize = 300;
HEXCUT_HD inline int packed_index(int r, int c) {
  if (r > c) {
    const int t = r;
    r = c;
    c = t;
  }
  return r * 24 - (r * (r - 1)) / 2 + (c - r);
}

HEXCUT_HD inline void pack_symmetric(const double* A, double* P) {
  for (int r = 0; r < 24; ++r)
    for (int c = r; c < 24; ++c) P[packed_index(r, c)] = A[24 * r + c];
}

HEXCUT_HD inline void unpack_symmetric(const double* P, double* A) {
  for (int r = 0; r < 24; ++r)
    for (int c = 0; c < 24; ++c) A[24 * r + c] = P[packed_index(r, c)];
}

/// y3 = rows 3q..3q+2 of the packed symmetric matrix times x24.
HEXCUT_HD inline void packed_row_block(const double* P, int q, const double* x24, double* y3) {
  double rows[72];  // the three rows, unpacked
  for (int e = 0; e < 3; ++e)
    for (int c = 0; c < 24; ++c) rows[24 * e + c] = P[packed_index(3 * q + e, c)];
  three_rows(rows, x24, y3);
}

/// y24 += P x24 for a packed symmetric matrix: each stored entry is used twice.
HEXCUT_HD inline void packed_apply_add(const double* P, const double* x24, double* y24) {
  int k = 0;
  for (int r = 0; r < 24; ++r) {
    y24[r] += P[k] * x24[r];
    ++k;
    double s = 0.0;
    for (int c = r + 1; c < 24; ++c, ++k) {
      s += P[k] * x24[c];
      y24[c] += P[k] * x24[r];
    }
    y24[r] += s;
  }
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
