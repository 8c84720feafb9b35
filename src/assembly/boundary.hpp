// Supports and loads (doc/theory.md, "Supports and loads"): which DOFs are prescribed and the
// external force vector at a time t. Selectors are resolved once, after voxelization; a selector
// that selects nothing is an input error naming its deck line.
#pragma once

#include <petscdm.h>
#include <petscmat.h>

#include <string>
#include <vector>

#include "assembly/operator.hpp"
#include "deck/deck.hpp"

namespace hexcut::assembly {

/// The prescribed DOFs owned by this rank and their values.
struct Constraints {
  std::vector<PetscInt> rows;             // global DOF indices, ascending
  std::vector<const deck::Field*> value;  // per row
  std::vector<Eigen::Vector3d> position;  // per row: reference position of the vertex [m]
  PetscInt global_count = 0;
  bool expressions = false;  // some support value of the deck is an expression (every rank)
};

/// Boundary data resolved against the body: prescribed DOFs, loaded boundary faces,
/// point load targets.
struct Boundary {
  Constraints constraints;
  /// A boundary face with a traction or a pressure. Corner n of local_copies is at
  /// origin + h ((n & 1) e_a + (n >> 1) e_b), a < b the axes other than `axis`.
  struct Face {
    std::array<std::int32_t, 4> local_copies;
    Eigen::Vector3d origin{0, 0, 0};           // reference position of corner 0 [m]
    int axis = 0;                              // the normal's axis
    int side = 0;                              // outward normal: +e_axis when 1, -e_axis when 0
    const deck::Traction* traction = nullptr;  // exactly one of traction and pressure
    const deck::Pressure* pressure = nullptr;
    enum class Kind { uniform, fixed_in_time, varying };
    Kind kind = Kind::uniform;  // uniform: no expression; else expressions without / with t
    /// uniform: the load per reference area [Pa] (a traction's value, -p n for a pressure,
    /// a traction's force / the area of its faces), without `scale`.
    Eigen::Vector3d density{0, 0, 0};
    std::array<Eigen::Vector3d, 4> nodal;  // fixed_in_time: the consistent loads [N] (no scale)
  };
  std::vector<Face> faces;
  bool face_expressions = false;  // some traction or pressure is an expression (every rank)

  struct Point {   // a point load on an owned copy
    PetscInt dof;  // global index of the x DOF
    const deck::PointLoad* load;
  };
  std::vector<Point> points;
  Eigen::Vector3d gravity{0, 0, 0};
  deck::Centrifugal centrifugal;
  /// The load of the initial stress on the local copies, 3 per local copy [N]
  /// (assembly::initial_stress_load); empty: none. Constant in time; it changes with cuts.
  std::vector<double> initial_stress_load;
};

/// Resolves the deck's selectors. Throws InputError when one selects nothing (on every
/// rank: counts are reduced over the communicator).
Boundary resolve_boundary(MPI_Comm comm, const deck::Deck& deck, const lattice::Lattice& lattice,
                          const topology::VertexCopies& copies, const topology::DofLayout& layout);

/// Consistent nodal forces of a face's traction or pressure at time t, without its
/// `scale` time function: f_n = ∫ N_n t(x) dA over the face [N], N_n the bilinear shape
/// function of corner n, with 2x2 Gauss points (exact for a bilinear t). A pressure p
/// gives t = -p n, n the outward normal. The first non-finite value found is described in
/// `bad` ("deck.yaml:LINE: ..."), unless `bad` already holds one.
std::array<Eigen::Vector3d, 4> consistent_face_loads(const Boundary::Face& face, double h, double t,
                                                     std::string& bad);

/// f = scale * external force at time t (gravity, tractions, pressures, point loads, the
/// load of the initial stress);
/// overwritten. A traction or pressure expression that is not finite somewhere throws
/// InputError naming its deck line, on every rank (collective).
PetscErrorCode assemble_loads(DM dm, const topology::DofLayout& layout, const CellData& cells,
                              const Boundary& boundary, double t, double scale, Vec f);

/// x[row] = scale * prescribed value at time t for every constrained row; other entries
/// untouched. (Static load steps use scale < 1.) An expression that is not finite at a
/// vertex throws InputError naming its deck line, on every rank (collective).
PetscErrorCode set_prescribed_values(const Constraints& c, double t, double scale, Vec x);

/// The Dirichlet mask of the prescribed rows, the one definition of which DOFs the
/// constrained operator eliminates (the assembled matrix here, the multigrid's fine level):
/// 1 free, 0 on `rows` (owned, global DOF indices), as `global_mask`, a global vector of
/// `dm` (the identity rows of assembly::assemble and apply), and as `local_mask`, per local
/// DOF of the DM, owned and ghosts (FineCells::set_mask: the zeroed rows and columns).
/// Collective on the DM.
PetscErrorCode dirichlet_mask(DM dm, const std::vector<PetscInt>& rows, Vec global_mask,
                              std::vector<double>* local_mask);

/// Zeroes A (create_matrix) and assembles the constrained operator, the symmetric elimination
/// of the prescribed rows (doc/theory.md, "Supports and loads"): w_K K^ + w_M M with the rows
/// and columns of c.rows those of the identity. It is assembly::assemble of the fine cells
/// masked by dirichlet_mask, the operator the multigrid's fine level applies, with A's nonzero
/// pattern kept (zeros stay entries). Call at every assembly of A.
PetscErrorCode assemble_constrained_matrix(DM dm, const topology::DofLayout& layout,
                                           const CellData& cells, const OperatorWeights& w,
                                           const Constraints& c, Mat A);

/// The right-hand side that matches the constrained operator (assemble_constrained_matrix):
/// b_free -= A_free,fixed u0 and b_fixed = u0, where the action of the unconstrained A is
/// taken element by element. u0 = scale * prescribed values at time t.
PetscErrorCode constrain_rhs(DM dm, const topology::DofLayout& layout, const CellData& cells,
                             const OperatorWeights& w, const Constraints& c, double t, double scale,
                             Vec b);

}  // namespace hexcut::assembly
