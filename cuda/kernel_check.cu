// Device-code check of the kernel bodies (doc/theory.md, "Kernel bodies for a CUDA backend").
//
// One __global__ wrapper per HEXCUT_HD function of src/element/*.hpp and
// src/multigrid/kernels.hpp, each running its body once per thread on the slice of the
// arrays that the thread's index selects (a cell, a vertex, a coarse cell), so that nvcc
// really generates device code for every body: a header that is merely included generates
// none. The build compiles this file for sm_80 and sm_90 and fails when a stack frame
// exceeds the limit (cuda/CMakeLists.txt). The wrappers are not a backend and are never
// launched: there are no launch configurations, no colouring of scatters, and no host code.
#include "element/corotation.hpp"
#include "element/fine_cell.hpp"
#include "element/kinematics.hpp"
#include "element/newmark.hpp"
#include "element/polar.hpp"
#include "element/reference.hpp"
#include "element/trilinear.hpp"
#include "multigrid/kernels.hpp"
#include "assembly/fine_cell_kernels.hpp"
#include "backend/restriction.hpp"
#include "multigrid/stored_cell_kernels.hpp"

namespace el = hexcut::element;
namespace mg = hexcut::multigrid;
namespace as = hexcut::assembly;
namespace be = hexcut::backend;

namespace {

__device__ int thread_index() { return int(blockIdx.x * blockDim.x + threadIdx.x); }

/// The fine cell e of the arrays: its rotation (or none), its own stiffness when
/// `own_stiffness` is set (otherwise the shared K), consistent mass when M is given.
__device__ el::FineCell fine_cell(int e, const double* K, const double* R, double w, double m,
                                  const double* M, bool own_stiffness) {
  return el::FineCell{own_stiffness ? K + el::kElementMatrixSize * e : K, R ? R + 9 * e : nullptr,
                      w, m, M};
}

}  // namespace

// --- the loop layer's functors (backend/restriction.hpp around the per-cell operators of
// assembly/fine_cell_kernels.hpp and multigrid/stored_cell_kernels.hpp): what a backend
// launches, one thread per cell of a colour. Templates, so outside extern "C". ---

template <class Kernel>
__global__ void check_functor(Kernel k, int n) {
  const int e = thread_index();
  if (e < n) k(e);
}
template __global__ void check_functor<be::CellApplyAdd<as::FineCellOps>>(
    be::CellApplyAdd<as::FineCellOps>, int);
template __global__ void check_functor<be::CellColourRows<as::FineCellOps>>(
    be::CellColourRows<as::FineCellOps>, int);
template __global__ void check_functor<be::CellDiagonal<as::FineCellOps>>(
    be::CellDiagonal<as::FineCellOps>, int);
template __global__ void check_functor<be::CellApplyAdd<mg::StoredCellOps>>(
    be::CellApplyAdd<mg::StoredCellOps>, int);
template __global__ void check_functor<be::CellColourRows<mg::StoredCellOps>>(
    be::CellColourRows<mg::StoredCellOps>, int);
template __global__ void check_functor<be::CellDiagonal<mg::StoredCellOps>>(
    be::CellDiagonal<mg::StoredCellOps>, int);
template __global__ void check_functor<be::CellApplyAdd<mg::StoredCellOpsSingle>>(
    be::CellApplyAdd<mg::StoredCellOpsSingle>, int);
template __global__ void check_functor<be::CellColourRows<mg::StoredCellOpsSingle>>(
    be::CellColourRows<mg::StoredCellOpsSingle>, int);
template __global__ void check_functor<be::CellDiagonal<mg::StoredCellOpsSingle>>(
    be::CellDiagonal<mg::StoredCellOpsSingle>, int);
// The float vectors of the single-precision V-cycle (multigrid/loop_cycle.hpp).
template __global__ void check_functor<be::CellApplyAdd<as::FineCellOps, float>>(
    be::CellApplyAdd<as::FineCellOps, float>, int);
template __global__ void check_functor<be::CellApplyAdd<as::FineCellOpsSingle, float>>(
    be::CellApplyAdd<as::FineCellOpsSingle, float>, int);
template __global__ void check_functor<be::CellApplyAdd<mg::StoredCellOps, float>>(
    be::CellApplyAdd<mg::StoredCellOps, float>, int);
template __global__ void check_functor<be::CellApplyAdd<mg::StoredCellOpsSingle, float>>(
    be::CellApplyAdd<mg::StoredCellOpsSingle, float>, int);
template __global__ void check_functor<be::CellColourRows<as::FineCellOps, float>>(
    be::CellColourRows<as::FineCellOps, float>, int);
template __global__ void check_functor<be::CellColourRows<mg::StoredCellOpsSingle, float>>(
    be::CellColourRows<mg::StoredCellOpsSingle, float>, int);

// extern "C": readable names in the ptxas report.
extern "C" {

// --- element/reference.hpp ---

__global__ void check_corner_sign(double* out) {
  const int t = thread_index();
  out[t] = el::corner_sign(t % 8, t % 3);
}

__global__ void check_corner_positions(double h, const double* origins, double* x24) {
  const int e = thread_index();
  el::corner_positions(h, origins ? origins + 3 * e : nullptr, x24 + 24 * e);
}

__global__ void check_cell_stiffness(const el::ReferenceMatrices* ref, const double* h,
                                     const double* lambda, const double* mu, double* K) {
  const int e = thread_index();
  el::cell_stiffness(*ref, h[e], lambda[e], mu[e], K + el::kElementMatrixSize * e);
}

// --- element/trilinear.hpp ---

__global__ void check_trilinear_weight(const double* xi, double* w) {
  const int t = thread_index();
  w[t] = el::trilinear_weight(xi + 3 * (t / 8), t % 8);
}

__global__ void check_parity_octant(const long long* ijk, int* octant) {
  const int t = thread_index();
  octant[t] = el::parity_octant(ijk[3 * t], ijk[3 * t + 1], ijk[3 * t + 2]);
}

__global__ void check_child_weight(double* w) {
  const int t = thread_index();
  w[t] = el::child_weight((t >> 6) & 7, (t >> 3) & 7, t & 7);
}

// --- element/kinematics.hpp ---

__global__ void check_lame_from_young(const double* E, const double* nu, double* lambda,
                                      double* mu) {
  const int e = thread_index();
  el::lame_from_young(E[e], nu[e], lambda + e, mu + e);
}

__global__ void check_displacement_gradient_at_centre(const double* u, double h, double* G) {
  const int e = thread_index();
  el::displacement_gradient_at_centre(u + 24 * e, h, G + 9 * e);
}

__global__ void check_deformation_gradient_at_centre(const double* u, double h, double* F) {
  const int e = thread_index();
  el::deformation_gradient_at_centre(u + 24 * e, h, F + 9 * e);
}

__global__ void check_strain_at_centre(const double* u, double h, double* eps) {
  const int e = thread_index();
  el::strain_at_centre(u + 24 * e, h, eps + 6 * e);
}

__global__ void check_hooke_stress(const double* eps, double lambda, double mu, double* sigma) {
  const int e = thread_index();
  el::hooke_stress(eps + 6 * e, lambda, mu, sigma + 6 * e);
}

__global__ void check_rotate_tensor(const double* R, double* s) {
  const int e = thread_index();
  el::rotate_tensor(R + 9 * e, s + 6 * e, s + 6 * e);
}

// --- element/polar.hpp ---

__global__ void check_polar_rotation(const double* F, double* R) {
  const int e = thread_index();
  el::polar_rotation(F + 9 * e, R + 9 * e);
}

// --- element/corotation.hpp ---

__global__ void check_rotate_blocks_transposed(const double* R, double* v) {
  const int e = thread_index();
  el::rotate_blocks_transposed(R + 9 * e, v + 24 * e, v + 24 * e);
}

__global__ void check_rotate_blocks(const double* R, double* v) {
  const int e = thread_index();
  el::rotate_blocks(R + 9 * e, v + 24 * e, v + 24 * e);
}

__global__ void check_element_matvec(const double* K, const double* v, double* y) {
  const int e = thread_index();
  el::element_matvec(K, v + 24 * e, y + 24 * e);
}

__global__ void check_rotate_element_matrix(const double* R, const double* K, double* RKRt) {
  const int e = thread_index();
  el::rotate_element_matrix(R + 9 * e, K, RKRt + el::kElementMatrixSize * e);
}

__global__ void check_corotated_displacement(const double* R, const double* x24,
                                             const double* u, double* d) {
  const int e = thread_index();
  el::corotated_displacement(R + 9 * e, x24, u + 24 * e, d + 24 * e);
}

__global__ void check_corotational_rhs(const double* R, const double* K, const double* x24,
                                       double* b) {
  const int e = thread_index();
  el::corotational_rhs(R + 9 * e, K, x24, b + 24 * e);
}

__global__ void check_element_force(const double* R, const double* K, const double* x24,
                                    const double* u, double* f) {
  const int e = thread_index();
  el::element_force(R + 9 * e, K, x24, u + 24 * e, f + 24 * e);
}

__global__ void check_current_corotated_displacement(double h, const double* x24,
                                                     const double* u, double* d) {
  const int e = thread_index();
  el::current_corotated_displacement(h, x24, u + 24 * e, d + 24 * e);
}

// --- element/newmark.hpp (one vertex copy per thread) ---

__global__ void check_newmark_coefficients(const double* dt, double* a) {
  const int t = thread_index();
  const el::NewmarkCoefficients c = el::newmark_coefficients(dt[t]);
  a[3 * t] = c.a0;
  a[3 * t + 1] = c.a1;
  a[3 * t + 2] = c.a2;
}

__global__ void check_newmark_history(double dt, const double* u, const double* v,
                                      const double* a, double* mass_hist, double* damp_hist) {
  const int i = 3 * thread_index();
  el::newmark_history(3, dt, u + i, v + i, a + i, mass_hist + i, damp_hist + i);
}

__global__ void check_newmark_update(double dt, const double* u_old, double* v, double* a,
                                     const double* u_new) {
  const int i = 3 * thread_index();
  el::newmark_update(3, dt, u_old + i, v + i, a + i, u_new + i, v + i, a + i);
}

// --- element/fine_cell.hpp ---

__global__ void check_gather_cell(const double* v, const int* corners, double* out) {
  const int e = thread_index();
  el::gather_cell(v, corners + 8 * e, out + 24 * e);
}

__global__ void check_scatter_add_cell(const double* in, const int* corners, double* v,
                                       double scale) {
  const int e = thread_index();
  el::scatter_add_cell(in + 24 * e, corners + 8 * e, v, scale);
}

__global__ void check_three_rows(const double* K, const double* x, double* y) {
  const int e = thread_index();
  el::three_rows(K + 72 * (e % 8), x + 24 * e, y + 3 * e);
}

__global__ void check_fine_row_block(const double* K, const double* R, double w, double m,
                                     const double* M, const double* x, double* y) {
  const int t = thread_index(), e = t / 8;
  el::fine_row_block(fine_cell(e, K, R, w, m, M, false), t % 8, x + 24 * e, y + 3 * t);
}

__global__ void check_symmetric_apply_add(const double* S, double scale, const double* x,
                                          double* y) {
  const int e = thread_index();
  el::symmetric_apply_add(S, scale, x + 24 * e, y + 24 * e);
}

__global__ void check_fine_cell_apply_add(const double* K, const double* R, double w, double m,
                                          const double* M, const double* x, double* y) {
  const int e = thread_index();
  el::fine_cell_apply_add(fine_cell(e, K, R, w, m, M, true), x + 24 * e, y + 24 * e);
}

__global__ void check_fine_diagonal_block(const double* K, const double* R, double w, double m,
                                          const double* M, double* D) {
  const int t = thread_index(), e = t / 8;
  el::fine_diagonal_block(fine_cell(e, K, R, w, m, M, false), t % 8, D + 9 * t);
}

// --- multigrid/kernels.hpp ---

/// One coarse cell per thread: its packed block from its 8 children's full blocks.
__global__ void check_galerkin_accumulate(const double* children, double* parent,
                                          double* packed) {
  const int C = thread_index();
  double* A = parent + el::kElementMatrixSize * C;
  for (int o = 0; o < 8; ++o)
    mg::galerkin_accumulate(children + el::kElementMatrixSize * (8 * C + o), o, A);
  mg::pack_symmetric(A, packed + mg::kPackedSize * C);
}

/// One child per thread: its general Galerkin product into its own output block.
__global__ void check_galerkin_accumulate_general(const double* A, const double* W,
                                                  double* parent) {
  const int e = thread_index();
  mg::galerkin_accumulate_general(A + el::kElementMatrixSize * e, W + el::kElementMatrixSize * e,
                                  parent + el::kElementMatrixSize * e);
}

/// One child per thread: its rotated Galerkin block into its own output block.
__global__ void check_rotated_block_add(const double* G, const double* R, double* A) {
  const int e = thread_index();
  mg::rotated_block_add(G + el::kElementMatrixSize * e, R + 9 * e, 1.0,
                        A + el::kElementMatrixSize * e);
}

__global__ void check_packed_index(int* index) {
  const int t = thread_index();
  index[t] = mg::packed_index(t / 24, t % 24);
}

__global__ void check_pack_symmetric(const double* A, double* P) {
  const int e = thread_index();
  mg::pack_symmetric(A + el::kElementMatrixSize * e, P + mg::kPackedSize * e);
}

__global__ void check_unpack_symmetric(const double* P, double* A) {
  const int e = thread_index();
  mg::unpack_symmetric(P + mg::kPackedSize * e, A + el::kElementMatrixSize * e);
}

__global__ void check_packed_row_block(const double* P, const double* x, double* y) {
  const int t = thread_index(), e = t / 8;
  mg::packed_row_block(P + mg::kPackedSize * e, t % 8, x + 24 * e, y + 3 * t);
}

__global__ void check_packed_apply_add(const double* P, const double* x, double* y) {
  const int e = thread_index();
  mg::packed_apply_add(P + mg::kPackedSize * e, x + 24 * e, y + 24 * e);
}

__global__ void check_packed_apply_add_single(const float* P, const double* x, double* y) {
  const int e = thread_index();
  mg::packed_apply_add(P + mg::kPackedSize * e, x + 24 * e, y + 24 * e);
}

__global__ void check_invert3(const double* a, double* inv, int* ok) {
  const int t = thread_index();
  ok[t] = mg::invert3(a + 9 * t, inv + 9 * t);
}

__global__ void check_corner_colour(const int* p, int* colour) {
  const int t = thread_index(), e = t / 8;
  colour[t] = mg::corner_colour(p + 3 * e, t % 8);
}

// --- assembly/fine_cell_kernels.hpp ---

__global__ void check_fine_cell_matrix(as::FineCellData d, double* A) {
  const int e = thread_index();
  as::fine_cell_matrix(d, e, A + el::kElementMatrixSize * e);
}

__global__ void check_fine_cell_view(as::FineCellData d, double* out) {
  const int e = thread_index();
  const auto c = as::fine_cell(d, e);
  out[e] = as::cell_is_masked(d, e) ? c.mass : c.k_lambda;
}

__global__ void check_fine_cell_single_view(as::FineCellData d, double* out) {
  const int e = thread_index();
  const auto c = as::fine_cell_single(d, e);
  out[e] = c.K_mu ? c.k_lambda : c.mass;
}

__global__ void check_masked_cell_apply_add(as::FineCellData d, const std::int32_t* corners,
                                            double* x, double* y) {
  const int e = thread_index();
  as::masked_cell_apply_add(d, e, corners + 8 * e, as::fine_cell(d, e), x + 24 * e, y + 24 * e);
}

__global__ void check_fine_cell_apply_add_single(const float* K, const double* R, double w,
                                                 const float* x, float* y) {
  const int e = thread_index();
  const el::FineCellOf<float> c{K, R ? R + 9 * e : nullptr, w, 0.0, nullptr};
  el::fine_cell_apply_add(c, x + 24 * e, y + 24 * e);
}

// --- element/fine_cell.hpp: the stiffness of a cell without a kind, not formed ---

__global__ void check_stiffness_rows(const double* K_lambda, const double* K_mu,
                                     const double* k, const double* x, double* y) {
  const int t = thread_index(), e = t / 8, q = t % 8;
  el::FineCell c{K_lambda, nullptr, 1.0, 0.0, nullptr, K_mu, k[2 * e], k[2 * e + 1]};
  el::stiffness_rows(c, K_lambda + 24 * 3 * q, q, x + 24 * e, y + 3 * t);
}

__global__ void check_stiffness_apply_add(const double* K_lambda, const double* K_mu,
                                          const double* k, const double* x, double* y) {
  const int e = thread_index();
  el::FineCell c{K_lambda, nullptr, 1.0, 0.0, nullptr, K_mu, k[2 * e], k[2 * e + 1]};
  el::stiffness_apply_add(c, 1.0, x + 24 * e, y + 24 * e);
}

__global__ void check_corner_of_colour(const int* p, int* corner) {
  const int t = thread_index(), e = t / 8;
  corner[t] = mg::corner_of_colour(p + 3 * e, t % 8);
}

}  // extern "C"
