// The operator of one fine cell, w_K R^ K R^T + w_M M, applied without forming the rotated 24x24
// matrix (doc/theory.md, "Geometric multigrid", "Operators"). Shared by the element-by-element
// operator of the assembly stage and the multigrid's fine level, and written as plain inline
// functions on raw arrays for a later CUDA backend.
#pragma once

#include "element/host_device.hpp"

namespace hexcut::element {

/// What a fine cell's operator needs: its unrotated stiffness K (24x24, symmetric,
/// shared per material), its rotation (nullptr = identity), the stiffness weight, and
/// the mass m = w_M rho h^3 with the reference consistent mass (nullptr = lumped, m/8).
/// T: the matrices' type and the arithmetic of fine_cell_apply_add (double; float for the
/// fine level of the single-precision V-cycle, assembly::FineCellOpsSingle).
template <class T>
struct FineCellOf {
  const T* K;
  const double* R;
  double w_stiffness;
  double mass;
  const T* consistent_mass;
  // A stiffness not formed (a cell without a shared kind, on a device where a 24x24
  // scratch per thread is too much): K = k_lambda K + k_mu K_mu, with K = the reference
  // K_lambda and K_mu set. Null K_mu: K is the stiffness itself.
  const T* K_mu = nullptr;
  double k_lambda = 1.0, k_mu = 0.0;
};
using FineCell = FineCellOf<double>;

/// The 24 values (3 per corner) of a cell from a vector with 3 values per vertex copy;
/// `corners` are the cell's 8 local copy indices. V: double, or float for the loop-layer
/// cycle's single-precision vectors; A: the cell's arithmetic (double, or float).
template <class V, class A>
HEXCUT_HD inline void gather_cell(const V* v, const int* corners, A* out24) {
  for (int q = 0; q < 8; ++q)
    for (int d = 0; d < 3; ++d) out24[3 * q + d] = A(v[3 * corners[q] + d]);
}

/// v += scale * in24 at the cell's 8 corners (3 values each; rounded to V once per add).
template <class V, class A>
HEXCUT_HD inline void scatter_add_cell(const A* in24, const int* corners, V* v, A scale = A(1)) {
  for (int q = 0; q < 8; ++q)
    for (int d = 0; d < 3; ++d) v[3 * corners[q] + d] += V(scale * in24[3 * q + d]);
}

/// Three rows of a 24x24 row-major matrix times x24, with six independent partial sums
/// (a single running sum per row would make the loop wait on add latency).
HEXCUT_HD inline void three_rows(const double* K, const double* x24, double* y3) {
  const double *k0 = K, *k1 = K + 24, *k2 = K + 48;
  double a0 = 0, a1 = 0, a2 = 0, b0 = 0, b1 = 0, b2 = 0;
  for (int k = 0; k < 24; k += 2) {
    a0 += k0[k] * x24[k];
    a1 += k1[k] * x24[k];
    a2 += k2[k] * x24[k];
    b0 += k0[k + 1] * x24[k + 1];
    b1 += k1[k + 1] * x24[k + 1];
    b2 += k2[k + 1] * x24[k + 1];
  }
  y3[0] = a0 + b0;
  y3[1] = a1 + b1;
  y3[2] = a2 + b2;
}

/// y3 = rows of corner q of the cell's unrotated stiffness times x24.
HEXCUT_HD inline void stiffness_rows(const FineCell& c, const double* Kq, int q, const double* x24,
                                     double* y3) {
  three_rows(Kq, x24, y3);
  if (!c.K_mu) return;
  double m3[3];
  three_rows(c.K_mu + 24 * 3 * q, x24, m3);
  for (int e = 0; e < 3; ++e) y3[e] = c.k_lambda * y3[e] + c.k_mu * m3[e];
}

/// y24 += scale K x24 with the cell's unrotated stiffness K, in the arithmetic T.
template <class T>
HEXCUT_HD inline void stiffness_apply_add(const FineCellOf<T>& c, T scale, const T* x24, T* y24);

/// y3 = rows of corner q of the fine cell's operator times x24.
HEXCUT_HD inline void fine_row_block(const FineCell& c, int q, const double* x24, double* y3) {
  const double* Kq = c.K + 24 * 3 * q;
  if (c.R) {
    const double* R = c.R;
    double xl[24];  // R^T x, corner by corner
    for (int p = 0; p < 8; ++p)
      for (int i = 0; i < 3; ++i)
        xl[3 * p + i] = R[i] * x24[3 * p] + R[3 + i] * x24[3 * p + 1] + R[6 + i] * x24[3 * p + 2];
    double yl[3];
    stiffness_rows(c, Kq, q, xl, yl);
    for (int i = 0; i < 3; ++i)
      y3[i] = c.w_stiffness * (R[3 * i] * yl[0] + R[3 * i + 1] * yl[1] + R[3 * i + 2] * yl[2]);
  } else {
    stiffness_rows(c, Kq, q, x24, y3);
    for (int e = 0; e < 3; ++e) y3[e] *= c.w_stiffness;
  }
  if (c.mass != 0.0) {
    if (!c.consistent_mass) {
      for (int e = 0; e < 3; ++e) y3[e] += 0.125 * c.mass * x24[3 * q + e];
    } else {
      double m3[3];
      three_rows(c.consistent_mass + 24 * 3 * q, x24, m3);
      for (int e = 0; e < 3; ++e) y3[e] += c.mass * m3[e];
    }
  }
}

/// y24 += S x24 for a symmetric 24x24 S, as a sum of rows scaled by x (row k of S is
/// column k): 24 independent accumulators that the compiler vectorizes. T: the stored type
/// of S (double, or float for the multigrid's single-precision blocks); A: the arithmetic
/// (double; float only with float S, the fine level of the single-precision V-cycle, where
/// the vector units hold twice the lanes).
template <class T, class A = double>
HEXCUT_HD HEXCUT_INLINE void symmetric_apply_add(const T* S, A scale, const A* x24, A* y24) {
  A acc[24] = {0};
  for (int k = 0; k < 24; ++k) {
    const A xk = x24[k];
    const T* row = S + 24 * k;
    for (int r = 0; r < 24; ++r) acc[r] += A(row[r]) * xk;
  }
  for (int r = 0; r < 24; ++r) y24[r] += scale * acc[r];
}

template <class T>
HEXCUT_HD inline void stiffness_apply_add(const FineCellOf<T>& c, T scale, const T* x24, T* y24) {
  if (!c.K_mu) {
    symmetric_apply_add<T, T>(c.K, scale, x24, y24);
    return;
  }
  symmetric_apply_add<T, T>(c.K, scale * T(c.k_lambda), x24, y24);
  symmetric_apply_add<T, T>(c.K_mu, scale * T(c.k_mu), x24, y24);
}

/// y24 += (w_K R^ K R^T + w_M M) x24 for a fine cell, without forming the rotated
/// matrix: rotate x into the cell frame, apply K (symmetric), rotate back. T: the cell's
/// matrices and arithmetic (FineCellOf<T>; the rotation is read as double and used in T).
template <class T>
HEXCUT_HD HEXCUT_INLINE void fine_cell_apply_add(const FineCellOf<T>& c, const T* x24, T* y24) {
  const T w = T(c.w_stiffness);
  if (c.R) {
    T R[9];
    for (int i = 0; i < 9; ++i) R[i] = T(c.R[i]);
    T xl[24], yl[24] = {0};
    for (int p = 0; p < 8; ++p)
      for (int i = 0; i < 3; ++i)
        xl[3 * p + i] = R[i] * x24[3 * p] + R[3 + i] * x24[3 * p + 1] + R[6 + i] * x24[3 * p + 2];
    stiffness_apply_add(c, w, xl, yl);
    for (int p = 0; p < 8; ++p)
      for (int i = 0; i < 3; ++i)
        y24[3 * p + i] +=
            R[3 * i] * yl[3 * p] + R[3 * i + 1] * yl[3 * p + 1] + R[3 * i + 2] * yl[3 * p + 2];
  } else {
    stiffness_apply_add(c, w, x24, y24);
  }
  if (c.mass != 0.0) {
    if (!c.consistent_mass) {
      const T m = T(0.125 * c.mass);
      for (int r = 0; r < 24; ++r) y24[r] += m * x24[r];
    } else {
      symmetric_apply_add<T, T>(c.consistent_mass, T(c.mass), x24, y24);
    }
  }
}

/// The 3x3 diagonal block of corner q of the fine cell's operator (row-major):
/// w_K R K_qq R^T + mass block.
HEXCUT_HD inline void fine_diagonal_block(const FineCell& c, int q, double* D) {
  double Kqq[9], T[9];
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      const int k = 24 * (3 * q + i) + 3 * q + j;
      Kqq[3 * i + j] = c.K_mu ? c.k_lambda * c.K[k] + c.k_mu * c.K_mu[k] : c.K[k];
    }
  if (c.R) {
    const double* R = c.R;
    for (int i = 0; i < 3; ++i)  // T = R Kqq
      for (int j = 0; j < 3; ++j)
        T[3 * i + j] = R[3 * i] * Kqq[j] + R[3 * i + 1] * Kqq[3 + j] + R[3 * i + 2] * Kqq[6 + j];
    for (int i = 0; i < 3; ++i)  // D = T R^T
      for (int j = 0; j < 3; ++j)
        D[3 * i + j] = c.w_stiffness * (T[3 * i] * R[3 * j] + T[3 * i + 1] * R[3 * j + 1] +
                                        T[3 * i + 2] * R[3 * j + 2]);
  } else {
    for (int i = 0; i < 9; ++i) D[i] = c.w_stiffness * Kqq[i];
  }
  if (c.mass != 0.0) {
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j)
        D[3 * i + j] += c.consistent_mass ? c.mass * c.consistent_mass[24 * (3 * q + i) + 3 * q + j]
                                          : (i == j ? 0.125 * c.mass : 0.0);
  }
}

}  // namespace hexcut::element
