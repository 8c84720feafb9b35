// Composite elements as the simulation's discretization (doc/theory.md, "Composite elements";
// Wu 2014, ch. 4). The composite elements are the cells of multigrid hierarchy level l: each
// a connected piece of a (2^l)^3 block of fine cells, so pieces that cuts or holes separate
// get their own elements. Their DOFs are level l's vertex copies; the fine displacement is
// u = I u~ with I = P_0 P_1 ... P_(l-1) the trilinear interpolation of the hierarchy, and the
// element matrices are the Galerkin blocks K~ = I^T K I, M~ = I^T M I the multigrid already
// builds (multigrid::Options::first_level).
//
// The simulation keeps its state on the fine copies, always in the range of I: each linear
// system A u = b of a step (static, Newmark) is solved in the composite space,
//
//     I_f^T A I_f u~_f = I_f^T (b - A u_L),   u = u_L + I_f u~_f,   u_L = I_x g~,
//
// with I_f, I_x the columns of free and fixed composite DOFs and g~ the fixed values. Loads,
// velocities, accelerations and energies are the fine ones of a field in range(I), so they
// are exactly the composite ones (1/2 v^T M v = 1/2 v~^T M~ v~), and output, stresses and
// surfaces are those of the fine cells under the interpolated displacement.
//
// Supports (Wu's fixation propagation): a composite DOF is fixed when it carries weight
// from a prescribed fine DOF (per component). Its value g~ is the weighted mean of the
// prescribed values it carries weight from, exact when they are uniform (a fixed or moved
// support); the prescribed fine DOFs then hold (I g~), not g, where g varies.
#pragma once

#include <petscksp.h>
#include <petscvec.h>

#include "deck/deck.hpp"
#include "multigrid/gmg.hpp"

namespace hexcut::analysis {

/// The composite interpolation I = P_0 P_1 ... P_(l-1) as an AIJ matrix (fine rows,
/// composite columns; l = mg.first_level() >= 1). The caller destroys it. Collective.
PetscErrorCode composite_interpolation_matrix(const multigrid::Multigrid& mg, Mat* I);

/// x~ with I x~ = x for fine vectors x in range(I) (a state after a cut or a restart, whose
/// composite values are not known): the least-squares solution of (I^T I) x~ = I^T x, by a
/// Cholesky factorization of I^T I (SPD: every corner of an element carries weight from
/// one of its fine cells' corners) made on first use. `misfit` gets ||I x~ - x||_inf (in
/// the units of x): round-off when x is in range(I). Its factorization reads options with
/// the prefix -hexcut_preimage_ (not the solver's -mat_mumps_...).
class CompositePreimage {
 public:
  explicit CompositePreimage(multigrid::Multigrid& mg) : mg_(mg) {}
  ~CompositePreimage();
  CompositePreimage(const CompositePreimage&) = delete;
  CompositePreimage& operator=(const CompositePreimage&) = delete;
  /// x: fine global vector; xc: global vector of mg.dm(mg.first_level()). Collective.
  PetscErrorCode solve(Vec x, Vec xc, double* misfit);

 private:
  multigrid::Multigrid& mg_;
  Mat I_ = nullptr, gram_ = nullptr;
  KSP ksp_ = nullptr;
};

/// g~ on the fixed composite DOFs (0 on free ones), global vector of the composite level:
/// the weighted mean of the entries of `values` on the prescribed fine DOFs that each
/// fixed composite DOF carries weight from (mg.mask(0) marks the free fine DOFs). Collective.
PetscErrorCode composite_prescribed(multigrid::Multigrid& mg, Vec values, Vec g);

/// x~ = I^T x: the fine global vector `fine` restricted to the composite level of `mg`
/// (mg.first_level()); `composite` is a global vector of that level. Collective.
PetscErrorCode restrict_composite(multigrid::Multigrid& mg, Vec fine, Vec composite);

/// x = I x~ (fine global vector from a composite one). Collective.
PetscErrorCode prolong_composite(multigrid::Multigrid& mg, Vec composite, Vec fine);

/// The composite right-hand side of the constrained fine system A u = b whose prescribed
/// rows hold their values g: bc = I_f^T (b - A u_L) on free composite DOFs and g~ on fixed
/// ones, and the fixed entries of `uc` (the initial guess) set to g~. `deviation` (may be
/// null) gets max |(I g~) - g| / max |g| over the prescribed fine DOFs (0 when all g = 0).
/// The multigrid must be updated (mg.update) with the system's operator. Collective.
PetscErrorCode composite_rhs(multigrid::Multigrid& mg, Vec b, Vec bc, Vec uc,
                             double* deviation = nullptr);

/// ||I_f^T (m0 r) + add||_2: the composite residual of a fine one (free fine rows only; the
/// rows of fixed composite DOFs dropped), plus a composite part `add` (may be null; a
/// global vector of the composite level). Collective.
PetscErrorCode composite_norm(multigrid::Multigrid& mg, Vec r, PetscReal* norm, Vec add = nullptr);

/// Reference positions [m] of the composite level's owned copies (bs 3), for the rigid-body
/// modes of the AMG solvers. Collective.
PetscErrorCode composite_positions(const multigrid::Multigrid& mg, Vec* x);

/// How the supports compose (after the first mg.update): the fine DOFs that the composite
/// model holds fixed (every weight of theirs on a fixed composite DOF) against those the deck
/// prescribes. Prints a "warning:" line on rank 0, naming the deck's discretization line,
/// when composing fixes more than twice as many fine DOFs as the supports (a support on a
/// small region then clamps whole composite elements). `clamped`, `prescribed` (may be null)
/// get the global counts. Collective.
PetscErrorCode check_composite_supports(MPI_Comm comm, multigrid::Multigrid& mg,
                                        const deck::Deck& deck, PetscInt* clamped = nullptr,
                                        PetscInt* prescribed = nullptr);

}  // namespace hexcut::analysis
