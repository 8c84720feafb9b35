// An operator given by cells (doc/theory.md, "Architecture"): A = sum_e P_e^T A_e P_e over the
// rank's local cells, where P_e picks the 3 DOFs of each of the cell's 8 local vertex copies
// (topology::DofLayout::cell_corners) and A_e is the cell's 24x24 matrix. Every operator hexcut
// applies or assembles is one: the simulation's fine operator (FineCells: material stiffness,
// rotation and Newmark weights, formed on the fly) and the multigrid's coarse levels
// (multigrid::StoredCells: one Galerkin block per coarse cell; composite elements next).
//
// The same few actions serve the assembled path (hypre, GAMG, direct), the matrix-free MatShell,
// every multigrid level and its coarsest matrix:
//   apply_add           y += A x on local vectors (owned + ghost copies, 3 DOFs each;
//                       double, or float for the single-precision loop-layer cycle)
//   apply_add_colour    the rows of one parity colour only (Gauss-Seidel)
//   add_diagonal_blocks the 3x3 point-block diagonal (Jacobi, Chebyshev)
//   cell_matrix         A_e itself (assembly into AIJ, Galerkin products)
// Dirichlet masking, where an operator has it, is inside these actions: A_e with the rows and
// columns of masked DOFs zeroed. The PETSc-level helpers below add the identity on masked rows.
// Models: libCEED's CeedOperator, deal.II's MatrixFreeOperators::Base.
#pragma once

#include <petscdm.h>
#include <petscmat.h>

#include <array>
#include <cstddef>
#include <vector>

#include "topology/dof_layout.hpp"

namespace hexcut::assembly {

/// Lattice (or level) position of each local cell, for the parity colour of its corners.
using CellPositions = std::vector<std::array<int, 3>>;

class CellOperator {
 public:
  explicit CellOperator(const topology::DofLayout& layout) : layout_(&layout) {}
  virtual ~CellOperator() = default;
  CellOperator(const CellOperator&) = delete;
  CellOperator& operator=(const CellOperator&) = delete;

  /// The DOF layout whose local cells and copies this operator acts on.
  const topology::DofLayout& layout() const { return *layout_; }
  std::size_t num_cells() const { return layout_->cells.size(); }
  /// The cells' 8 local copies each, contiguous (for the loop layer's kernels).
  const std::int32_t* corners() const {
    return layout_->cell_corners.empty() ? nullptr : layout_->cell_corners[0].data();
  }

  /// y += A x; x, y: 3 values per local copy (owned, then ghosts). Contributions to ghost
  /// copies stay in y's ghost entries (sum them into their owners: apply()).
  virtual void apply_add(const double* x, double* y) const = 0;
  /// The same on single-precision vectors (the loop-layer cycle in single precision:
  /// -gmg_backend host_loop -gmg_precision single): each cell gathers its 24 values into
  /// double, acts in its own arithmetic and adds its 24 results rounded to float.
  virtual void apply_add(const float* x, float* y) const = 0;
  /// For every cell e, y at its corner q of parity colour k += (rows of corner q of A_e) x,
  /// with q = corner_of_colour(position[e], k): each cell has exactly one such corner, so a
  /// colour costs 1/8 of apply_add. Other entries of y are not touched.
  virtual void apply_add_colour(const CellPositions& position, int k, const double* x,
                                double* y) const = 0;
  /// The same on single-precision vectors (Gauss-Seidel in the float V-cycle).
  virtual void apply_add_colour(const CellPositions& position, int k, const float* x,
                                float* y) const = 0;
  /// diag += the 3x3 diagonal blocks of A (9 per local copy, row-major), local parts.
  virtual void add_diagonal_blocks(double* diag) const = 0;
  /// The 24x24 matrix A_e of local cell e (row-major, corner-major: DOF 3q + d).
  virtual void cell_matrix(std::size_t e, double* A) const = 0;

 private:
  const topology::DofLayout* layout_;
};

/// y = A x on global vectors of `dm` (the layout's DMShell), ghosts exchanged and summed;
/// where `identity_mask` (a global vector, may be null) is 0, y = x (identity rows of
/// prescribed or dead DOFs). y is overwritten.
PetscErrorCode apply(DM dm, const CellOperator& op, Vec x, Vec y, Vec identity_mask = nullptr);

/// Zeroes A (an AIJ matrix created by create_matrix for the operator's layout), adds every
/// A_e and, where `identity_mask` (may be null) is 0, a 1 on the diagonal; assembles A.
PetscErrorCode assemble(const CellOperator& op, Vec identity_mask, Mat A);

}  // namespace hexcut::assembly
