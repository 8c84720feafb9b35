// Additive Schwarz on cell patches, the preconditioner of the Chebyshev smoother where point
// blocks are too small (doc/theory.md, "Coarse spaces after cuts and on thin pieces").
//
// A patch is the set of DOFs of one coarse cell's children (the level-l copies at the corners of
// the children of a level-(l+1) cell: up to 27 copies, 81 DOFs). Point-block Jacobi smooths
// only what varies from copy to copy; a thin piece, a flap hinged on a ligament or a crack tip
// has low-energy modes that are smooth on that scale and still badly represented by the coarse
// space. The patch solve resolves them within each coarse cell:
//
//     M r = sum_p R_p^T A_pp^-1 R_p r      (free DOFs of no patch: the point-block inverse),
//
// A_pp the principal submatrix of the level's operator (all cells around the patch, on every
// rank), factored once per operator build (dense Cholesky). M is symmetric, so the smoother and
// the cycle stay symmetric for CG. Patches are made only for irregular coarse cells
// (energy_interpolation.hpp); a solid block keeps point-block Jacobi.
#pragma once

#include <petscdm.h>
#include <petscmat.h>

#include <cstdint>
#include <vector>

#include "assembly/cell_operator.hpp"
#include "hierarchy/hierarchy.hpp"

namespace hexcut::multigrid {

class Schwarz {
 public:
  /// Patches of level `fine` for the cells of `coarse` marked in `coarse_selected`
  /// (canonical ids; local ones only), without the DOFs that `mask` (global, 1 free) marks 0.
  /// `op` is the level's operator, assembled once here to take the patches' submatrices.
  /// Collective.
  static PetscErrorCode create(MPI_Comm comm, DM dm, const hierarchy::Level& fine,
                               const hierarchy::Level& coarse,
                               const std::vector<char>& coarse_selected,
                               const assembly::CellOperator& op, Vec mask, Schwarz* out);

  /// z = M r on global vectors of the level: replaces z on the DOFs some patch covers by
  /// the sum of their patch solves and keeps z elsewhere, so a z that holds the point-block
  /// Jacobi D^-1 r on entry (identity on masked DOFs) gives M r. Collective.
  PetscErrorCode apply(Vec r, Vec z) const;

  std::int64_t num_patches() const { return std::int64_t(offset_.size()) - 1; }
  /// Numbers held: the packed factors.
  std::size_t stored_numbers() const { return factor_.size(); }
  bool empty() const { return offset_.size() <= 1; }

 private:
  DM dm_ = nullptr;
  std::vector<std::int64_t> offset_{0};  // per patch + 1: into dof_
  std::vector<std::int64_t> factor_offset_{0};
  std::vector<std::int32_t> dof_;  // local DOF (3 x local copy + component)
  std::vector<double> factor_;     // per patch: lower Cholesky factor, packed by rows
  std::vector<char> covered_;      // per owned DOF: in some patch
};

}  // namespace hexcut::multigrid
