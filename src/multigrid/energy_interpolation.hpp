// Energy-minimizing interpolation within the cell pattern (doc/theory.md, "Coarse spaces after
// cuts and on thin pieces"; Mandel, Brezina and Vanek 1999; Olson, Schroder and Tuminaro 2011;
// doc/references.md).
//
// Trilinear interpolation is the coarse space of a solid block. Where a coarse cell holds less
// than a solid block (a piece thinner than the cell, a cut that ends inside it, a boundary, a
// material jump), its trilinear functions restricted to the material are stiff in bending (the
// coarse space "locks") and the multigrid slows down at every level where coarse cells are wider
// than the pieces. There the interpolation is replaced by the one of least energy,
//
//     min sum_J  P_J^T A P_J   over P with the cell pattern, subject to  P B_c = B_f,
//
// P_J the column of coarse DOF J, A the finer level's operator, B the six rigid-body modes
// (translations and linearized rotations) on the coarse and fine copies: rigid motions stay
// interpolated exactly. The cell pattern lets fine copy f use coarse copy J only when J is a
// corner of the parent of every cell incident to f. Every child's interpolation then still
// involves only its parent's 8 corners, so the Galerkin coarse operator stays one 24x24 block
// per coarse cell (A_C = sum_c W_c^T A_c W_c with a general 24x24 W_c), and the rows of P are
// 3x3 blocks per coarse copy instead of a scalar weight times I3. The minimization is a
// Jacobi-preconditioned conjugate gradient on the rows (a few iterations), started from the
// trilinear P, with each row projected onto the constraint.
//
// Only rows that touch an irregular coarse cell (irregular_cells) are minimized and stored; the
// others stay trilinear, so a solid block keeps exactly today's multigrid.
#pragma once

#include <petscmat.h>
#include <petscvec.h>

#include <array>
#include <cstdint>
#include <vector>

#include "assembly/cell_operator.hpp"
#include "hierarchy/hierarchy.hpp"

namespace hexcut::multigrid {

/// The interpolation rows of level l (to it from level l+1) that are not trilinear. Indices
/// are local: fine copies of level l's layout, coarse copies of level l+1's layout.
struct InterpolationRows {
  std::vector<std::int32_t> row_of;                 // per local fine copy: stored row, or -1
  std::vector<std::array<std::int32_t, 8>> coarse;  // per stored row: its pattern (-1: unused)
  std::vector<double> block;                        // per stored row: 8 3x3 blocks, row-major
  bool empty() const { return coarse.empty(); }
  /// Whether any of a cell's 8 corners (local fine copies) has a stored row.
  bool touches(const std::int32_t* fine_corners) const;
};

/// W_e (24x24 row-major: row 3q + a = DOF a of fine corner q, column 3j + b = DOF b of parent
/// corner j) of a child with local fine corners `fine_corners`, in the octant `octant` of its
/// parent with local coarse corners `parent_corners`: stored rows where there are, trilinear
/// weights times I3 elsewhere.
void child_interpolation(const InterpolationRows& rows, const std::int32_t* fine_corners,
                         const std::int32_t* parent_corners, int octant, double* W);

/// Per cell of `coarse` (canonical ids): irregular when it has fewer than 8 children, when
/// its children are not linked by all 12 links of a solid 2x2x2 block, when one of them is
/// irregular (`fine_irregular`, per cell of `fine`; empty: none), or when the children's
/// Young's modulus or Poisson ratio differ (`youngs`, `poisson`: per cell of `fine`; empty on
/// coarse levels, where a jump below shows as an irregular child).
std::vector<char> irregular_cells(const hierarchy::Level& fine, const hierarchy::Level& coarse,
                                  const std::vector<char>& fine_irregular,
                                  const std::vector<double>& youngs,
                                  const std::vector<double>& poisson);

/// What energy_interpolation did (collective sums).
struct EnergyStats {
  std::int64_t rows = 0;     // fine copies whose rows were minimized
  double energy_before = 0;  // trace(P^T A P) of the trilinear rows
  double energy_after = 0;   // and of the minimized ones
  int iterations = 0;
};

/// Minimizes the energy of the interpolation rows of level `fine` that touch a cell of
/// `coarse` marked in `coarse_irregular` (canonical ids), with `op` the level's operator
/// (masked at level 0: rows of masked DOFs are zero), `diag_inv` its inverted 3x3 diagonal
/// blocks (9 per owned copy) and `mask` (global, 1 free, 0 prescribed or dead: such rows
/// stay zero). `iterations` conjugate-gradient steps from the trilinear rows. Collective.
PetscErrorCode energy_interpolation(MPI_Comm comm, const hierarchy::Level& fine,
                                    const hierarchy::Level& coarse,
                                    const std::vector<char>& coarse_irregular,
                                    const assembly::CellOperator& op,
                                    const std::vector<double>& diag_inv, Vec mask, int iterations,
                                    InterpolationRows* rows, EnergyStats* stats);

/// The interpolation from `coarse` to `fine` as a parallel BAIJ matrix (block size 3): the
/// stored rows, and trilinear weights times I3 for the others. Creates *P.
PetscErrorCode interpolation_matrix(MPI_Comm comm, const hierarchy::Level& fine,
                                    const hierarchy::Level& coarse, const InterpolationRows& rows,
                                    Mat* P);

}  // namespace hexcut::multigrid
