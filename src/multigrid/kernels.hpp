// Per-cell and per-vertex kernel bodies of the geometric multigrid (design.md §5). Plain
// inline functions on raw arrays, free of PETSc and STL containers, so a CUDA backend
// can run the same bodies (HEXCUT_HD marks them __host__ __device__ under nvcc).
//
// Conventions: corner q = a + 2b + 4c (x fastest), element DOF 3q + d, 24x24 matrices
// row-major. The child of a coarse cell in octant o = a + 2b + 4c is the fine cell at
// offset (a,b,c) in the 2x2x2 block.
#pragma once

#include "element/host_device.hpp"
#include "element/reference.hpp"

namespace hexcut::multigrid {

/// Trilinear weight of coarse corner j at fine corner i of the child in octant o:
/// w = prod_d (t_d if bit d of j else 1 - t_d), t_d = (o_d + i_d) / 2 in {0, 1/2, 1}.
HEXCUT_HD inline double child_weight(int octant, int i, int j) {
  double w = 1.0;
  for (int d = 0; d < 3; ++d) {
    const double t = 0.5 * double(((octant >> d) & 1) + ((i >> d) & 1));
    w *= ((j >> d) & 1) ? t : 1.0 - t;
  }
  return w;
}

/// A_parent += W^T A_child W with W = kron(w, I3), w the 8x8 child weights of `octant`.
/// Exploits the Kronecker structure: T = A_child W (24x24 via 8x8 weights) then W^T T.
HEXCUT_HD inline void galerkin_accumulate(const double* A_child, int octant, double* A_parent) {
  double w[64];
  for (int i = 0; i < 8; ++i)
    for (int j = 0; j < 8; ++j) w[8 * i + j] = child_weight(octant, i, j);
  double T[576];  // T = A_child W
  for (int r = 0; r < 24; ++r)
    for (int J = 0; J < 8; ++J)
      for (int d = 0; d < 3; ++d) {
        double s = 0.0;
        for (int i = 0; i < 8; ++i) s += A_child[24 * r + 3 * i + d] * w[8 * i + J];
        T[24 * r + 3 * J + d] = s;
      }
  for (int I = 0; I < 8; ++I)
    for (int e = 0; e < 3; ++e)
      for (int c = 0; c < 24; ++c) {
        double s = 0.0;
        for (int i = 0; i < 8; ++i) s += w[8 * i + I] * T[24 * (3 * i + e) + c];
        A_parent[24 * (3 * I + e) + c] += s;
      }
}

/// y3 = rows 3q..3q+2 of the dense 24x24 A times x24.
HEXCUT_HD inline void dense_row_block(const double* A, int q, const double* x24, double* y3) {
  for (int e = 0; e < 3; ++e) {
    double s = 0.0;
    for (int c = 0; c < 24; ++c) s += A[24 * (3 * q + e) + c] * x24[c];
    y3[e] = s;
  }
}

/// y24 += A x24 for a dense 24x24 A.
HEXCUT_HD inline void dense_apply_add(const double* A, const double* x24, double* y24) {
  for (int r = 0; r < 24; ++r) {
    double s = 0.0;
    for (int c = 0; c < 24; ++c) s += A[24 * r + c] * x24[c];
    y24[r] += s;
  }
}

/// What a fine cell's operator w_K R^ K R^T + w_M M needs: its unrotated stiffness K
/// (24x24, shared per material), its rotation (nullptr = identity), and the mass
/// weight m = w_M rho h^3 with the reference consistent mass (nullptr = lumped, m/8).
struct FineCell {
  const double* K;
  const double* R;
  double w_stiffness;
  double mass;
  const double* consistent_mass;
};

/// y3 = rows of corner q of the fine cell's operator times x24.
HEXCUT_HD inline void fine_row_block(const FineCell& c, int q, const double* x24, double* y3) {
  double yl[3];
  if (c.R) {
    const double* R = c.R;
    double xl[24];  // R^T x, corner by corner
    for (int p = 0; p < 8; ++p)
      for (int i = 0; i < 3; ++i)
        xl[3 * p + i] = R[i] * x24[3 * p] + R[3 + i] * x24[3 * p + 1] + R[6 + i] * x24[3 * p + 2];
    for (int e = 0; e < 3; ++e) {
      double s = 0.0;
      for (int k = 0; k < 24; ++k) s += c.K[24 * (3 * q + e) + k] * xl[k];
      yl[e] = s;
    }
    for (int i = 0; i < 3; ++i) y3[i] = c.w_stiffness * (R[3 * i] * yl[0] + R[3 * i + 1] * yl[1] + R[3 * i + 2] * yl[2]);
  } else {
    for (int e = 0; e < 3; ++e) {
      double s = 0.0;
      for (int k = 0; k < 24; ++k) s += c.K[24 * (3 * q + e) + k] * x24[k];
      y3[e] = c.w_stiffness * s;
    }
  }
  if (c.mass != 0.0) {
    if (!c.consistent_mass) {
      for (int e = 0; e < 3; ++e) y3[e] += 0.125 * c.mass * x24[3 * q + e];
    } else {
      for (int e = 0; e < 3; ++e) {
        double s = 0.0;
        for (int k = 0; k < 24; ++k) s += c.consistent_mass[24 * (3 * q + e) + k] * x24[k];
        y3[e] += c.mass * s;
      }
    }
  }
}

/// Inverse of a 3x3 matrix (row-major); returns false when singular.
HEXCUT_HD inline bool invert3(const double* a, double* inv) {
  const double c00 = a[4] * a[8] - a[5] * a[7], c01 = a[5] * a[6] - a[3] * a[8], c02 = a[3] * a[7] - a[4] * a[6];
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

/// Parity colour (0..7) of corner q of a cell at level position p: the colour of the
/// lattice vertex p + offset(q). The 8 corners of a cell have 8 different colours.
HEXCUT_HD inline int corner_colour(const int* p, int q) {
  return ((p[0] + (q & 1)) & 1) + 2 * ((p[1] + ((q >> 1) & 1)) & 1) + 4 * ((p[2] + ((q >> 2) & 1)) & 1);
}

/// The corner of a cell at position p that has colour k.
HEXCUT_HD inline int corner_of_colour(const int* p, int k) {
  return ((k & 1) ^ (p[0] & 1)) + 2 * (((k >> 1) & 1) ^ (p[1] & 1)) + 4 * (((k >> 2) & 1) ^ (p[2] & 1));
}

}  // namespace hexcut::multigrid

namespace hexcut::multigrid {

/// y24 += (w_K R^ K R^T + w_M M) x24 for a fine cell, without forming the rotated
/// matrix: rotate x into the cell frame, apply K, rotate back.
HEXCUT_HD inline void fine_cell_apply_add(const FineCell& c, const double* x24, double* y24) {
  double xl[24], yl[24];
  const double* xin = x24;
  if (c.R) {
    const double* R = c.R;
    for (int p = 0; p < 8; ++p)
      for (int i = 0; i < 3; ++i)
        xl[3 * p + i] = R[i] * x24[3 * p] + R[3 + i] * x24[3 * p + 1] + R[6 + i] * x24[3 * p + 2];
    xin = xl;
  }
  for (int r = 0; r < 24; ++r) {
    double s = 0.0;
    for (int k = 0; k < 24; ++k) s += c.K[24 * r + k] * xin[k];
    yl[r] = c.w_stiffness * s;
  }
  if (c.R) {
    const double* R = c.R;
    for (int p = 0; p < 8; ++p)
      for (int i = 0; i < 3; ++i)
        y24[3 * p + i] += R[3 * i] * yl[3 * p] + R[3 * i + 1] * yl[3 * p + 1] + R[3 * i + 2] * yl[3 * p + 2];
  } else {
    for (int r = 0; r < 24; ++r) y24[r] += yl[r];
  }
  if (c.mass != 0.0) {
    if (!c.consistent_mass) {
      for (int r = 0; r < 24; ++r) y24[r] += 0.125 * c.mass * x24[r];
    } else {
      for (int r = 0; r < 24; ++r) {
        double s = 0.0;
        for (int k = 0; k < 24; ++k) s += c.consistent_mass[24 * r + k] * x24[k];
        y24[r] += c.mass * s;
      }
    }
  }
}

}  // namespace hexcut::multigrid
