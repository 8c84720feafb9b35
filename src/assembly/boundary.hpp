// Supports and loads (design.md §4 "Dirichlet", "Loads"): which DOFs are prescribed
// and the external force vector at a time t. Selectors are resolved once, after
// voxelization; a selector that selects nothing is an input error naming its deck line.
#pragma once

#include <petscdm.h>
#include <petscmat.h>

#include <vector>

#include "assembly/operator.hpp"
#include "deck/deck.hpp"

namespace hexcut::assembly {

/// The prescribed DOFs owned by this rank and their time functions.
struct Constraints {
  std::vector<PetscInt> rows;                    // global DOF indices, ascending
  std::vector<const deck::TimeFunction*> value;  // per row
  PetscInt global_count = 0;
};

/// Boundary data resolved against the body: prescribed DOFs, traction faces, point
/// load targets.
struct Boundary {
  Constraints constraints;
  struct Face {  // a boundary face with a traction
    std::array<std::int32_t, 4> local_copies;
    const deck::Traction* traction;
  };
  std::vector<Face> faces;
  struct Point {   // a point load on an owned copy
    PetscInt dof;  // global index of the x DOF
    const deck::PointLoad* load;
  };
  std::vector<Point> points;
  Eigen::Vector3d gravity{0, 0, 0};
  deck::Centrifugal centrifugal;
};

/// Resolves the deck's selectors. Throws InputError when one selects nothing (on every
/// rank: counts are reduced over the communicator).
Boundary resolve_boundary(MPI_Comm comm, const deck::Deck& deck, const lattice::Lattice& lattice,
                          const topology::VertexCopies& copies, const topology::DofLayout& layout);

/// f = scale * external force at time t (gravity, tractions, point loads); overwritten.
PetscErrorCode assemble_loads(DM dm, const topology::DofLayout& layout, const CellData& cells,
                              const Boundary& boundary, double t, double scale, Vec f);

/// x[row] = scale * prescribed value at time t for every constrained row; other entries
/// untouched. (Static load steps use scale < 1.)
PetscErrorCode set_prescribed_values(const Constraints& c, double t, double scale, Vec x);

/// Symmetric elimination of the prescribed rows (design.md §4): the rows and columns of
/// A become identity. Call once per assembly of A.
PetscErrorCode constrain_matrix(const Constraints& c, Mat A);

/// The right-hand side that matches constrain_matrix: b_free -= A_free,fixed u0 and
/// b_fixed = u0, where the action of the unconstrained A is taken element by element.
/// u0 = scale * prescribed values at time t.
PetscErrorCode constrain_rhs(DM dm, const topology::DofLayout& layout, const CellData& cells,
                             const OperatorWeights& w, const Constraints& c, double t, double scale,
                             Vec b);

}  // namespace hexcut::assembly
