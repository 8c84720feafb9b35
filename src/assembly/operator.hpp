// The system operator A = w_K K^ + w_M M of the rank's cells (doc/theory.md, "Elements",
// "Corotation"), both as an assembled PETSc AIJ matrix (block size 3) and as an element-by-element
// action on local vectors. K^ = sum R^ h(lambda K_lambda + mu K_mu) R^T uses each cell's rotation
// (identity for linear elasticity); M is the consistent or lumped mass.
#pragma once

#include <petscdm.h>
#include <petscmat.h>

#include <vector>

#include "element/fine_cell.hpp"
#include "lattice/lattice.hpp"
#include "topology/dof_layout.hpp"
#include "topology/partition.hpp"
#include "topology/vertex_copies.hpp"

namespace hexcut::assembly {

/// Material coefficients and rotations of the rank's local cells (index = position in
/// DofLayout::cells).
struct CellData {
  double h = 1.0;
  std::vector<double> lambda, mu, rho;  // per local cell
  std::vector<double> rotation;         // 9 per local cell, row-major; empty when identity
  bool identity_rotations = true;       // every rotation is I (linear runs): none stored
  // Rotation groups (composite elements, doc/theory.md "Composite elements"): per local cell
  // its group; the cells of a group (all on this rank) share one rotation, the polar factor
  // of their mean centre deformation gradient (Wu 2014, eq. 4.7). Empty: each cell its own.
  std::vector<std::int32_t> rotation_group;
  std::int32_t num_rotation_groups = 0;
  std::vector<std::array<double, 3>> origin;  // per local cell: minimum corner [m]
  // Initial stress sigma0, 6 per local cell (ParaView order) [Pa]; empty: none
  // (assembly/initial_stress.hpp). The stress output is sigma0 + sigma(u).
  std::vector<double> initial_stress;
  // Cells with the same (lambda, mu) share one stiffness K = h (lambda K_lambda + mu
  // K_mu): a few 24x24 matrices per material, never one per cell. kind = -1 when there
  // are too many distinct values (per-cell E from an image): K is formed on the fly.
  std::vector<std::int32_t> kind;  // per local cell
  std::vector<std::array<double, 576>> kind_stiffness;
};

/// Unrotated stiffness of local cell e: the shared matrix of its kind, or formed into
/// `buffer` (576 doubles) when it has none.
const double* cell_stiffness(const CellData& cells, std::size_t e, double* buffer);

CellData make_cell_data(const lattice::Lattice& lattice, const topology::DofLayout& layout);

/// Weights of the operator A = stiffness*K^ + mass*M.
struct OperatorWeights {
  double stiffness = 1.0;
  double mass = 0.0;
  bool lumped_mass = true;
};

/// Sets every rotation to the identity (linear elasticity): cells.rotation is emptied.
void set_identity_rotations(CellData& cells);

/// The rotation of every local cell (9 each into R, row-major) at the displacement of the local
/// copies (3 per local copy): the polar factor of the cell's centre deformation gradient
/// (doc/theory.md, "Corotation"), or of its rotation group's mean one.
void cell_rotations(const topology::DofLayout& layout, const CellData& cells, const double* u_local,
                    double* R);

/// Stores cell_rotations() in cells.rotation.
void update_rotations(const topology::DofLayout& layout, const double* u_local, CellData& cells);

/// Strain energy of the rank's cells, sum_e 1/2 d_e^T K_e d_e with the corotated
/// displacement d_e = R^T (x + u) - x (doc/theory.md "Corotation"); `rotations`: 9 per
/// local cell, cell_rotations() at u_local (corotational runs), or null for the identity
/// (linear runs). CellData's stored rotations are not read. [J] (local part; sum over
/// ranks). Cells shared by no rank twice: each local cell once.
double strain_energy_local(const topology::DofLayout& layout, const CellData& cells,
                           const double* u_local, const double* rotations);

/// An AIJ matrix with block size 3, preallocated exactly for the copy adjacency.
PetscErrorCode create_matrix(MPI_Comm comm, const topology::VertexCopies& copies,
                             const topology::DofLayout& layout, Mat* A);

/// Zeroes A and assembles w_K K^ + w_M M into it: assemble(FineCells(layout, cells, w)).
PetscErrorCode assemble_matrix(const topology::DofLayout& layout, const CellData& cells,
                               const OperatorWeights& w, Mat A);

/// y = A x on global vectors (ghost exchange through the DM); y is overwritten:
/// apply(dm, FineCells(layout, cells, w), x, y).
PetscErrorCode apply(DM dm, const topology::DofLayout& layout, const CellData& cells,
                     const OperatorWeights& w, Vec x, Vec y);

/// b += sum over cells of -R^ K (R^T x_e - x_e): the corotational right-hand side
/// (zero for identity rotations).
PetscErrorCode add_corotational_rhs(DM dm, const topology::DofLayout& layout, const CellData& cells,
                                    double stiffness_weight, Vec b);

/// The corotated displacements d = R^T (x + u) - x of the local cells at the global
/// displacement u (24 per cell, R from cell_rotations), for assemble_midpoint_force.
PetscErrorCode corotated_displacements(DM dm, const topology::DofLayout& layout,
                                       const CellData& cells, Vec u, std::vector<double>* d);

/// f = sum over cells of the mid-point corotational force of the step u0 -> u1
/// (element::midpoint_force, doc/theory.md "Mid-point corotational step"); f is
/// overwritten. d0: corotated_displacements at u0. Sets each local cell's rotation to that
/// of the mid-point (u0 + u1)/2, the operator of the step's iteration. energy[0],
/// energy[1]: this rank's strain energy at u0 and u1 [J].
PetscErrorCode assemble_midpoint_force(DM dm, const topology::DofLayout& layout, CellData& cells,
                                       const std::vector<double>& d0, Vec u0, Vec u1, Vec f,
                                       double energy[2]);

/// Reference positions of the owned copies as a global vector (bs 3), for rigid-body
/// modes and output.
PetscErrorCode reference_positions(DM dm, const lattice::Lattice& lattice,
                                   const topology::VertexCopies& copies,
                                   const topology::DofLayout& layout, Vec* x);

/// Scatter a global vector to a local array (owned + ghosts), through the DM.
PetscErrorCode global_to_local(DM dm, Vec global, Vec local);

/// Read access to the local (owned + ghost) values of a global vector of a DM for the
/// scope: a local vector borrowed from the DM, filled by global_to_local. PETSc's way rather
/// than a constructor that borrows: a constructor cannot return PETSc's error code (it would
/// have to throw, a second error path beside PetscCall), so the object is declared first and
/// get() borrows and fills, PetscCall(values.get(dm, u)); the destructor gives back what
/// get() borrowed, on every way out of the scope. Collective on the DM.
class LocalValues {
 public:
  LocalValues() = default;
  ~LocalValues() {
    if (a_) VecRestoreArrayRead(l_, &a_);
    if (l_) DMRestoreLocalVector(dm_, &l_);
  }
  LocalValues(const LocalValues&) = delete;
  LocalValues& operator=(const LocalValues&) = delete;
  /// Borrows a local vector of `dm` and fills it with the local values of `global` (once).
  PetscErrorCode get(DM dm, Vec global) {
    PetscFunctionBeginUser;
    PetscCheck(!l_, PETSC_COMM_SELF, PETSC_ERR_ORDER, "LocalValues::get called twice");
    dm_ = dm;
    PetscCall(DMGetLocalVector(dm_, &l_));
    PetscCall(global_to_local(dm_, global, l_));
    PetscCall(VecGetArrayRead(l_, &a_));
    PetscFunctionReturn(0);
  }
  /// 3 values per local vertex copy, in the layout's local order (after get()).
  const PetscScalar* data() const { return a_; }

 private:
  DM dm_ = nullptr;
  Vec l_ = nullptr;
  const PetscScalar* a_ = nullptr;
};

}  // namespace hexcut::assembly
