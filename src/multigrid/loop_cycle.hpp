// The multigrid cycle on the loop layer (issue 13; doc/theory.md, "The CUDA backend: the
// cycle on the loop layer"): the V- or W-cycle of Multigrid::cycle (Chebyshev on point-block
// Jacobi or coloured block Gauss-Seidel, trilinear or energy-minimizing transfers, the coarsest
// level solved by the caller) written once over an executor, so that the host backend and the CUDA
// backend run the same algorithm with the same pointwise bodies. Everything here is plain data and
// HEXCUT_HD functors on 3 values per vertex copy (structure of arrays), free of PETSc, so nvcc
// compiles it too.
//
// An executor `Exec` provides, for levels l = 0..num_levels()-1 (all arrays in its memory):
//   using Scalar = double or float;                 the work vectors' type
//   int num_levels() const; int gamma() const;      1: V-cycle, 2: W-cycle
//   const LoopLevel& level(int l) const;            the level's arrays (below)
//   Scalar *b(l), *x(l), *r(l), *dir(l);            work vectors, 3 per copy
//   void for_each(std::int64_t n, const K& k);      k(i) for i < n (any order, no races)
//   void apply_add(int l, const Scalar* x, Scalar* y);  y += A_l x, the level's cells
//   void apply_add_colour(int l, int k, const Scalar* x, Scalar* y);  the same for the rows
//        of the copies of parity colour k only (Gauss-Seidel; other entries untouched)
//   void solve_coarsest(const Scalar* b, Scalar* x);    x = A_c^-1 b on the last level
//   void exchange(int l, Scalar* x);     the ghost entries of x get their owners' values
//   void accumulate(int l, Scalar* y);   the ghost entries of y are added into their owners
// A level's vectors hold its owned copies first, then its ghost copies (LoopLevel::num_local
// in all): the copies its rank's cells touch and the coarse copies its transfers reach. The
// pointwise bodies run on the owned copies; the cells scatter into ghosts too, and
// accumulate() sums those into the owners (on one rank there are no ghosts, and exchange and
// accumulate do nothing).
// With Scalar = float the cycle is the single-precision V-cycle of mixed precision (doc/theory.md,
// "Mixed precision"): vectors and level data (diagonal blocks, mask, transfer weights: the
// LoopLevel's float twins, level_data) in float, each pointwise body computing in double from
// float loads and rounding once per store.
#pragma once

#include <cstdint>
#include <type_traits>
#include <vector>

#include "element/host_device.hpp"

namespace hexcut::multigrid {

/// One level of the loop-layer cycle as plain arrays (the executor's memory). The transfer
/// is to this level from the next one: prolongation rows (8 coarse copies and weights per
/// fine copy, -1 unused) and, for the restriction, the same weights gathered per coarse copy
/// (CSR), so neither direction scatters and both backends sum in one fixed order.
struct LoopLevel {
  std::int64_t num_copies = 0;        // owned copies, 3 DOFs each
  std::int64_t num_local = 0;         // owned + ghost copies: the vectors' length / 3
  const double* diag_inv = nullptr;   // 9 per copy: inverted 3x3 diagonal blocks (row-major)
  const double* mask = nullptr;       // 3 per copy: 1 free, 0 prescribed or dead (identity row)
  double lambda_max = 0;              // of D^-1 A (power iteration, Multigrid::estimate_lambda_max)
  int presmooth = 0, postsmooth = 0;  // Chebyshev degrees, or Gauss-Seidel sweeps
  // Gauss-Seidel (-gmg_smoother gs): sweeps over the 8 parity colours of the owned copies
  // (colour k: colour_copy[colour_begin[k] .. colour_begin[k+1])), forward before the coarse
  // correction and backward after it, damped by omega. colour_begin is host memory (launch
  // sizes); colour_copy the executor's.
  bool gauss_seidel = false;
  double omega = 1.0;
  std::int64_t colour_begin[9] = {0, 0, 0, 0, 0, 0, 0, 0, 0};
  const std::int32_t* colour_copy = nullptr;
  // Transfer from level l+1 (null on the coarsest level). Each weight is weight_block numbers:
  // 1, a scalar times the identity (trilinear), or 9, a row-major 3x3 block (energy-minimizing
  // rows, -gmg_interpolation energy; the restriction applies it transposed).
  int weight_block = 1;
  const std::int32_t* prolong_coarse = nullptr;   // 8 per copy of this level
  const double* prolong_weight = nullptr;         // 8 per copy of this level
  std::int64_t num_coarse = 0;                    // local copies of level l+1 (with ghosts)
  const std::int32_t* restrict_offset = nullptr;  // num_coarse + 1
  const std::int32_t* restrict_fine = nullptr;    // fine copies of each coarse copy
  const double* restrict_weight = nullptr;        // one per restriction entry
  // The same level data in float, for an executor whose vectors are float (its Scalar; null
  // in a double one): the single-precision V-cycle reads its level data in its vectors' type.
  const float* diag_inv_single = nullptr;
  const float* mask_single = nullptr;
  const float* prolong_weight_single = nullptr;
  const float* restrict_weight_single = nullptr;
};

/// A level's data in the type V of an executor's vectors: LoopLevel's double arrays, or their
/// float twins.
template <class V>
struct LoopLevelData {
  const V* diag_inv;
  const V* mask;
  const V* prolong_weight;
  const V* restrict_weight;
};
template <class V>
LoopLevelData<V> level_data(const LoopLevel& L) {
  if constexpr (std::is_same_v<V, float>)
    return {L.diag_inv_single, L.mask_single, L.prolong_weight_single, L.restrict_weight_single};
  else
    return {L.diag_inv, L.mask, L.prolong_weight, L.restrict_weight};
}

/// A LoopLevel's arrays in host memory (Multigrid::loop_levels): what a backend uploads. The
/// diagonal blocks stay the Multigrid's (diag_inv points into it; a float executor holds float
/// copies instead and nulls it).
struct LoopLevelArrays {
  LoopLevelArrays() = default;
  // `view` points into the vectors: a move keeps their buffers, a copy would not.
  LoopLevelArrays(const LoopLevelArrays&) = delete;
  LoopLevelArrays& operator=(const LoopLevelArrays&) = delete;
  LoopLevelArrays(LoopLevelArrays&&) = default;
  LoopLevelArrays& operator=(LoopLevelArrays&&) = default;
  LoopLevel view;  // its pointers into the vectors below
  // Per ghost copy (local copies num_copies..num_local-1, in order): the rank that owns it and
  // its index among that rank's owned copies (what exchange() and accumulate() connect).
  std::vector<int> ghost_rank;
  std::vector<std::int32_t> ghost_index;
  std::vector<double> mask;
  std::vector<std::int32_t> colour_copy;
  std::vector<std::int32_t> prolong_coarse;
  std::vector<double> prolong_weight;
  std::vector<std::int32_t> restrict_offset, restrict_fine;
  std::vector<double> restrict_weight;
};

/// y = 0 (3 values per copy). V: the work vectors' type (Exec::Scalar) in all the bodies below,
/// and the type of the level data they read (level_data<V>).
template <class V>
struct Zero {
  V* y;
  HEXCUT_HD void operator()(std::int32_t i) const {
    for (int c = 0; c < 3; ++c) y[3 * std::int64_t(i) + c] = V(0);
  }
};

/// buf[3k..3k+2] = x at copy[k]: a halo's send copies packed (multigrid/halo.hpp).
template <class V>
struct PackCopies {
  const std::int32_t* copy;
  const V* x;
  V* buf;
  HEXCUT_HD void operator()(std::int32_t k) const {
    for (int c = 0; c < 3; ++c) buf[3 * std::int64_t(k) + c] = x[3 * std::int64_t(copy[k]) + c];
  }
};

/// y at copy[k] += buf[3k..3k+2]: the ghosts' summed values into their owners (the copies are
/// distinct, so no two threads add into one entry).
template <class V>
struct AddCopies {
  const std::int32_t* copy;
  const V* buf;
  V* y;
  HEXCUT_HD void operator()(std::int32_t k) const {
    for (int c = 0; c < 3; ++c) y[3 * std::int64_t(copy[k]) + c] += buf[3 * std::int64_t(k) + c];
  }
};

/// y = 0 at the listed copies.
template <class V>
struct ZeroAt {
  const std::int32_t* copy;
  V* y;
  HEXCUT_HD void operator()(std::int32_t i) const {
    for (int c = 0; c < 3; ++c) y[3 * std::int64_t(copy[i]) + c] = V(0);
  }
};

/// x_i += omega D_i^-1 (b_i - (A x)_i) at the listed copies (one colour: no copy's row reads
/// another listed copy), r holding the cells' (A x)_i; where the mask is 0 the row is the
/// identity's (Multigrid::gauss_seidel).
template <class V>
struct GaussSeidelUpdate {
  const std::int32_t* copy;
  const V* b;
  const V* r;
  const V* mask;
  const V* diag_inv;
  double omega;
  V* x;
  HEXCUT_HD void operator()(std::int32_t j) const {
    const auto i = std::int64_t(copy[j]);
    double res[3];
    for (int c = 0; c < 3; ++c) {
      const auto k = 3 * i + c;
      res[c] = double(b[k]) - double(r[k]) - (mask[k] == 0.0 ? double(x[k]) : 0.0);
    }
    const V* D = diag_inv + 9 * i;
    for (int c = 0; c < 3; ++c) {
      V& xc = x[3 * i + c];
      xc = V(double(xc) +
             omega * (D[3 * c] * res[0] + D[3 * c + 1] * res[1] + D[3 * c + 2] * res[2]));
    }
  }
};

/// r = b - (A x + identity rows): r holds A x from the cells on entry; where the mask is 0
/// the row is the identity's (assembly::apply's identity_mask), then the residual is formed.
/// With `masked`, the residual is zeroed where the mask is 0 (what the restriction sees).
template <class V>
struct Residual {
  const V* b;
  const V* x;
  const V* mask;
  bool masked;
  V* r;
  HEXCUT_HD void operator()(std::int32_t i) const {
    for (int c = 0; c < 3; ++c) {
      const auto k = 3 * std::int64_t(i) + c;
      const double Ax = mask[k] == 0.0 ? double(r[k]) + double(x[k]) : double(r[k]);
      r[k] = V(masked ? mask[k] * (double(b[k]) - Ax) : double(b[k]) - Ax);
    }
  }
};

/// dir = alpha D^-1 r + beta dir (beta = 0: dir's old values are not read).
template <class V>
struct JacobiDirection {
  const V* diag_inv;
  const V* r;
  double alpha, beta;
  V* dir;
  HEXCUT_HD void operator()(std::int32_t i) const {
    const V* D = diag_inv + 9 * std::int64_t(i);
    const V* ri = r + 3 * std::int64_t(i);
    const double r0 = ri[0], r1 = ri[1], r2 = ri[2];
    for (int c = 0; c < 3; ++c) {
      const double z = D[3 * c] * r0 + D[3 * c + 1] * r1 + D[3 * c + 2] * r2;
      V& d = dir[3 * std::int64_t(i) + c];
      d = V(beta == 0.0 ? alpha * z : alpha * z + beta * double(d));
    }
  }
};

/// x += y.
template <class V>
struct AddTo {
  const V* y;
  V* x;
  HEXCUT_HD void operator()(std::int32_t i) const {
    for (int c = 0; c < 3; ++c) x[3 * std::int64_t(i) + c] += y[3 * std::int64_t(i) + c];
  }
};

/// b_C = sum over the fine copies f of C of w_fC r_f (the transpose of the prolongation), per
/// coarse copy C. Block (energy rows): 9 weights per entry, the 3x3 block B_fC (row-major),
/// and b_C = sum of B_fC^T r_f.
template <class V, bool Block = false>
struct Restrict {
  const std::int32_t* offset;
  const std::int32_t* fine;
  const V* weight;
  const V* r;
  V* b;
  HEXCUT_HD void operator()(std::int32_t C) const {
    double s[3] = {0.0, 0.0, 0.0};
    for (auto k = offset[C]; k < offset[C + 1]; ++k) {
      const V* rf = r + 3 * std::int64_t(fine[k]);
      if constexpr (Block) {
        const V* B = weight + 9 * std::int64_t(k);
        for (int c = 0; c < 3; ++c)
          s[c] += double(B[c]) * rf[0] + double(B[3 + c]) * rf[1] + double(B[6 + c]) * rf[2];
      } else {
        for (int c = 0; c < 3; ++c) s[c] += double(weight[k]) * rf[c];
      }
    }
    for (int c = 0; c < 3; ++c) b[3 * std::int64_t(C) + c] = V(s[c]);
  }
};

/// x_f += mask_f sum_j w_fj x_C(j), per fine copy f (the coarse correction). Block (energy
/// rows): 72 weights per fine copy, its 8 3x3 blocks B_fj (row-major), and x_f += mask_f sum
/// B_fj x_C(j).
template <class V, bool Block = false>
struct ProlongAdd {
  const std::int32_t* coarse;
  const V* weight;
  const V* mask;
  const V* xc;
  V* x;
  HEXCUT_HD void operator()(std::int32_t f) const {
    double s[3] = {0.0, 0.0, 0.0};
    for (int j = 0; j < 8; ++j) {
      const auto C = coarse[8 * std::int64_t(f) + j];
      if (C < 0) break;
      const V* xj = xc + 3 * std::int64_t(C);
      if constexpr (Block) {
        const V* B = weight + 72 * std::int64_t(f) + 9 * j;
        for (int c = 0; c < 3; ++c)
          s[c] += double(B[3 * c]) * xj[0] + double(B[3 * c + 1]) * xj[1] +
                  double(B[3 * c + 2]) * xj[2];
      } else {
        const double w = weight[8 * std::int64_t(f) + j];
        for (int c = 0; c < 3; ++c) s[c] += w * xj[c];
      }
    }
    for (int c = 0; c < 3; ++c)
      x[3 * std::int64_t(f) + c] += V(mask[3 * std::int64_t(f) + c] * s[c]);
  }
};

namespace loop {

/// r = b - A_l x on the owned copies (masked: zero where the mask is 0); x's ghosts are
/// refreshed first.
template <class Exec, class V = typename Exec::Scalar>
void residual(Exec& ex, int l, const V* b, V* x, V* r, bool masked) {
  const LoopLevel& L = ex.level(l);
  ex.for_each(L.num_local, Zero<V>{r});  // the ghosts too: the cells scatter into them
  ex.exchange(l, x);
  ex.apply_add(l, x, r);
  ex.accumulate(l, r);
  ex.for_each(L.num_copies, Residual<V>{b, x, level_data<V>(L).mask, masked, r});
}

/// Chebyshev iteration on D^-1 A over [0.2, 1.1] lambda_max, `degree` steps from x (the
/// recurrence of Multigrid::chebyshev).
template <class Exec, class V = typename Exec::Scalar>
void chebyshev(Exec& ex, int l, const V* b, V* x, int degree) {
  const LoopLevel& L = ex.level(l);
  const double hi = 1.1 * L.lambda_max, lo = 0.2 * L.lambda_max;
  const double theta = 0.5 * (hi + lo), delta = 0.5 * (hi - lo), sigma = theta / delta;
  double rho_old = 1.0 / sigma;
  V *r = ex.r(l), *dir = ex.dir(l);
  residual(ex, l, b, x, r, false);
  const V* diag_inv = level_data<V>(L).diag_inv;
  ex.for_each(L.num_copies, JacobiDirection<V>{diag_inv, r, 1.0 / theta, 0.0, dir});
  for (int i = 0; i < degree; ++i) {
    ex.for_each(L.num_copies, AddTo<V>{dir, x});
    if (i + 1 == degree) break;
    residual(ex, l, b, x, r, false);
    const double rho = 1.0 / (2.0 * sigma - rho_old);
    ex.for_each(L.num_copies,
                JacobiDirection<V>{diag_inv, r, 2.0 * rho / delta, rho * rho_old, dir});
    rho_old = rho;
  }
}

/// One sweep of coloured block Gauss-Seidel over the 8 colours (reverse: 7 down to 0): per
/// colour, the cells' rows of its copies from the current x (ghosts refreshed, the ghosts'
/// partial rows summed into their owners), then the update of its copies.
template <class Exec, class V = typename Exec::Scalar>
void gauss_seidel(Exec& ex, int l, const V* b, V* x, bool reverse) {
  const LoopLevel& L = ex.level(l);
  const auto data = level_data<V>(L);
  V* r = ex.r(l);
  for (int kk = 0; kk < 8; ++kk) {
    const int k = reverse ? 7 - kk : kk;
    const std::int32_t* copies = L.colour_copy + L.colour_begin[k];
    const std::int64_t n = L.colour_begin[k + 1] - L.colour_begin[k];
    ex.for_each(n, ZeroAt<V>{copies, r});
    ex.for_each(L.num_local - L.num_copies, Zero<V>{r + 3 * L.num_copies});
    ex.exchange(l, x);
    ex.apply_add_colour(l, k, x, r);
    ex.accumulate(l, r);
    ex.for_each(n, GaussSeidelUpdate<V>{copies, b, r, data.mask, data.diag_inv, L.omega, x});
  }
}

/// The level's smoother from x: Chebyshev of degree `steps`, or `steps` Gauss-Seidel sweeps
/// (backward ones after the coarse correction: the cycle stays symmetric).
template <class Exec, class V = typename Exec::Scalar>
void smooth(Exec& ex, int l, const V* b, V* x, int steps, bool after) {
  if (steps <= 0) return;
  if (!ex.level(l).gauss_seidel) {
    chebyshev(ex, l, b, x, steps);
    return;
  }
  for (int s = 0; s < steps; ++s) gauss_seidel(ex, l, b, x, after);
}

/// One cycle on level l for ex.b(l) into ex.x(l) (from zero when zero_guess).
template <class Exec>
void cycle_level(Exec& ex, int l, bool zero_guess) {
  const int levels = ex.num_levels();
  if (l == levels - 1) {
    ex.solve_coarsest(ex.b(l), ex.x(l));
    return;
  }
  using V = typename Exec::Scalar;
  const LoopLevel& L = ex.level(l);
  const auto data = level_data<V>(L);
  V *b = ex.b(l), *x = ex.x(l), *r = ex.r(l);
  if (zero_guess) ex.for_each(L.num_copies, Zero<V>{x});
  smooth(ex, l, b, x, L.presmooth, false);
  residual(ex, l, b, x, r, true);
  // Each rank restricts its owned fine copies into the coarse copies they reach, its ghosts
  // included, and the ghosts' partial sums go to their owners.
  if (L.weight_block == 9)
    ex.for_each(L.num_coarse, Restrict<V, true>{L.restrict_offset, L.restrict_fine,
                                                data.restrict_weight, r, ex.b(l + 1)});
  else
    ex.for_each(L.num_coarse, Restrict<V>{L.restrict_offset, L.restrict_fine, data.restrict_weight,
                                          r, ex.b(l + 1)});
  ex.accumulate(l + 1, ex.b(l + 1));
  const int visits = l + 2 == levels ? 1 : ex.gamma();
  for (int v = 0; v < visits; ++v) cycle_level(ex, l + 1, v == 0);
  ex.exchange(l + 1, ex.x(l + 1));
  if (L.weight_block == 9)
    ex.for_each(L.num_copies, ProlongAdd<V, true>{L.prolong_coarse, data.prolong_weight, data.mask,
                                                  ex.x(l + 1), x});
  else
    ex.for_each(L.num_copies,
                ProlongAdd<V>{L.prolong_coarse, data.prolong_weight, data.mask, ex.x(l + 1), x});
  smooth(ex, l, b, x, L.postsmooth, true);
}

}  // namespace loop
}  // namespace hexcut::multigrid
