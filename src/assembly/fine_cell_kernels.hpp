// The fine cells' kernels (doc/theory.md, "Architecture", "Kernel bodies for a CUDA backend"):
// functors over local cells for the loop layer (backend/loop.hpp). Their data, FineCellData, are
// plain pointers into buffers that the backend owns (structure of arrays, one entry per local
// cell unless noted), free of STL and host-only calls, so a CUDA backend launches these same
// functors. FineCells (fine_cells.hpp) fills FineCellData from CellData and runs them.
#pragma once

#include <cstdint>

#include "element/corotation.hpp"
#include "element/fine_cell.hpp"
#include "element/host_device.hpp"
#include "element/kinematics.hpp"
#include "element/polar.hpp"
#include "element/reference.hpp"
#include "element/trilinear.hpp"

namespace hexcut::assembly {

struct FineCellData {
  const std::int32_t* corners = nullptr;         // 8 local copies per cell
  const std::int32_t* kind = nullptr;            // index into kind_stiffness, or -1
  const double* kind_stiffness = nullptr;        // 576 per kind: h (lambda K_lambda + mu K_mu)
  const std::int32_t* own = nullptr;             // index into own_stiffness, or -1 (null: none)
  const double* own_stiffness = nullptr;         // 576 per cell without a kind, formed once
  const double* lambda = nullptr;                // [Pa]
  const double* mu = nullptr;                    // [Pa]
  const double* rho = nullptr;                   // [kg/m^3]
  const double* rotation = nullptr;              // 9 per cell, row-major; null: identity
  const element::ReferenceMatrices* reference = nullptr;  // K_lambda, K_mu, consistent mass
  double h = 1.0;                                // lattice spacing [m]
  double w_stiffness = 1.0, w_mass = 0.0;        // A_e = w_K R K R^T + w_M M_e
  bool lumped_mass = true;
  const double* mask = nullptr;                  // 3 per local copy: 1 free, 0 masked; null: none
  const char* cell_masked = nullptr;             // per cell: has a masked DOF
  // Float copies for FineCellOpsSingle (null where not made: FineCells without cache).
  const float* kind_stiffness_single = nullptr;  // 576 per kind
  const float* reference_single = nullptr;       // 3 x 576: K_lambda, K_mu, consistent mass
};

/// The kernel view of cell e: its stiffness (the kind's, the cell's own formed once, or
/// h (lambda K_lambda + mu K_mu) applied as two reference matrices, never formed: no 24x24
/// scratch per cell), rotation and mass.
HEXCUT_HD inline element::FineCell fine_cell(const FineCellData& d, std::int32_t e) {
  element::FineCell f;
  if (d.kind[e] >= 0) {
    f.K = d.kind_stiffness + 576 * std::int64_t(d.kind[e]);
  } else if (d.own && d.own[e] >= 0) {
    f.K = d.own_stiffness + 576 * std::int64_t(d.own[e]);
  } else {
    f.K = d.reference->k_lambda;
    f.K_mu = d.reference->k_mu;
    f.k_lambda = d.h * d.lambda[e];
    f.k_mu = d.h * d.mu[e];
  }
  f.R = d.rotation ? d.rotation + 9 * std::int64_t(e) : nullptr;
  f.w_stiffness = d.w_stiffness;
  f.mass = d.w_mass * d.rho[e] * d.h * d.h * d.h;
  f.consistent_mass = d.lumped_mass ? nullptr : d.reference->mass;
  return f;
}

/// The same view in float (FineCellOpsSingle): the kind's stiffness in float, or, for a cell
/// without a kind, h (lambda K_lambda + mu K_mu) from the float reference matrices (the
/// operator a cell's own formed stiffness is, element::cell_stiffness).
HEXCUT_HD inline element::FineCellOf<float> fine_cell_single(const FineCellData& d,
                                                             std::int32_t e) {
  element::FineCellOf<float> f;
  if (d.kind[e] >= 0) {
    f.K = d.kind_stiffness_single + 576 * std::int64_t(d.kind[e]);
  } else {
    f.K = d.reference_single;
    f.K_mu = d.reference_single + 576;
    f.k_lambda = d.h * d.lambda[e];
    f.k_mu = d.h * d.mu[e];
  }
  f.R = d.rotation ? d.rotation + 9 * std::int64_t(e) : nullptr;
  f.w_stiffness = d.w_stiffness;
  f.mass = d.w_mass * d.rho[e] * d.h * d.h * d.h;
  f.consistent_mass = d.lumped_mass ? nullptr : d.reference_single + 2 * 576;
  return f;
}

HEXCUT_HD inline bool cell_is_masked(const FineCellData& d, std::int32_t e) {
  return d.mask && d.cell_masked[e];
}

/// ye += A_e xe for cell e seen as `cell` (fine_cell or fine_cell_single), with the rows and
/// columns of masked DOFs zeroed: masked DOFs enter as 0 (xe is masked in place) and receive
/// nothing. T: the cell's arithmetic.
template <class T>
HEXCUT_HD inline void masked_cell_apply_add(const FineCellData& d, std::int32_t e,
                                            const std::int32_t* corners,
                                            const element::FineCellOf<T>& cell, T* xe, T* ye) {
  if (!cell_is_masked(d, e)) {
    element::fine_cell_apply_add(cell, xe, ye);
    return;
  }
  for (int q = 0; q < 8; ++q)
    for (int k = 0; k < 3; ++k) xe[3 * q + k] *= T(d.mask[3 * corners[q] + k]);
  element::fine_cell_apply_add(cell, xe, ye);
  for (int q = 0; q < 8; ++q)
    for (int k = 0; k < 3; ++k) ye[3 * q + k] *= T(d.mask[3 * corners[q] + k]);
}

/// The fine cells' per-cell operator for backend/restriction.hpp's kernels: A_e with the rows
/// and columns of masked DOFs zeroed (masked DOFs enter as 0 and receive nothing).
struct FineCellOps {
  FineCellData d;
  HEXCUT_HD void apply_add(std::int32_t e, const std::int32_t* corners, double* xe,
                           double* ye) const {
    masked_cell_apply_add(d, e, corners, fine_cell(d, e), xe, ye);
  }
  HEXCUT_HD void row_block(std::int32_t e, const std::int32_t* corners, int q, double* xe,
                           double* y3) const {
    const auto cell = fine_cell(d, e);
    if (!cell_is_masked(d, e)) {
      element::fine_row_block(cell, q, xe, y3);
      return;
    }
    for (int p = 0; p < 8; ++p)
      for (int c = 0; c < 3; ++c) xe[3 * p + c] *= d.mask[3 * corners[p] + c];
    element::fine_row_block(cell, q, xe, y3);
    for (int c = 0; c < 3; ++c) y3[c] *= d.mask[3 * corners[q] + c];
  }
  HEXCUT_HD void diagonal_block(std::int32_t e, const std::int32_t* corners, int q,
                                double* D) const {
    element::fine_diagonal_block(fine_cell(d, e), q, D);
    if (!d.mask) return;
    const auto v = corners[q];
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) D[3 * i + j] *= d.mask[3 * v + i] * d.mask[3 * v + j];
  }
};

/// FineCellOps' product in float arithmetic (backend::CellApplyAdd gathers the 24 values into
/// float): the fine level of the single-precision V-cycle (-gmg_precision single with
/// host_loop or cuda), where float doubles the lanes of the 24 x 24 product; needs the float
/// copies of FineCellData. Only the product: the Gauss-Seidel rows and the diagonal blocks
/// stay FineCellOps'.
struct FineCellOpsSingle {
  using Arith = float;
  FineCellData d;
  HEXCUT_HD void apply_add(std::int32_t e, const std::int32_t* corners, float* xe,
                           float* ye) const {
    masked_cell_apply_add(d, e, corners, fine_cell_single(d, e), xe, ye);
  }
};

/// The dense masked A_e = w_K R K R^T + w_M M_e of cell e (576 doubles, row-major).
HEXCUT_HD inline void fine_cell_matrix(const FineCellData& d, std::int32_t e, double* A) {
  const auto cell = fine_cell(d, e);
  const double* K = cell.K;
  if (cell.K_mu) {  // formed in A itself (rotate_element_matrix may work in place)
    for (int i = 0; i < 576; ++i) A[i] = cell.k_lambda * cell.K[i] + cell.k_mu * cell.K_mu[i];
    K = A;
  }
  if (cell.R) {
    element::rotate_element_matrix(cell.R, K, A);
    for (int i = 0; i < 576; ++i) A[i] *= d.w_stiffness;
  } else {
    for (int i = 0; i < 576; ++i) A[i] = d.w_stiffness * K[i];
  }
  if (d.w_mass != 0.0) {
    // M_e acts on each component separately; the reference stores the full 24x24 form.
    if (d.lumped_mass) {
      for (int i = 0; i < 24; ++i) A[25 * i] += cell.mass / 8.0;
    } else {
      for (int i = 0; i < 576; ++i) A[i] += cell.mass * d.reference->mass[i];
    }
  }
  if (!cell_is_masked(d, e)) return;
  const std::int32_t* corners = d.corners + 8 * std::int64_t(e);
  double m[24];
  element::gather_cell(d.mask, corners, m);
  // Zeroed, not multiplied by the mask: a negative entry times 0 is -0, and the assembled
  // constrained matrix is to be the symmetric elimination's (+0) bit for bit.
  for (int r = 0; r < 24; ++r)
    for (int c = 0; c < 24; ++c)
      if (m[r] == 0.0 || m[c] == 0.0) A[24 * r + c] = 0.0;
}

/// The corotational rotation update (doc/theory.md, "Corotation"), per local cell e: R_e (9,
/// row-major) = the rotation of the polar decomposition of the deformation gradient at the
/// cell's centre (element::polar_rotation; inverted cells included), from the displacements
/// u (3 per local copy) of its 8 corners; h the cell size [m].
struct CellRotation {
  const std::int32_t* corners;  // 8 per cell
  const double* u;
  double h;
  double* R;
  HEXCUT_HD void operator()(std::int32_t e) const {
    double u24[24], F[9];
    element::gather_cell(u, corners + 8 * std::int64_t(e), u24);
    element::deformation_gradient_at_centre(u24, h, F);
    element::polar_rotation(F, R + 9 * std::int64_t(e));
  }
};

}  // namespace hexcut::assembly
