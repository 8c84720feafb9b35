// The solvers (doc/user-guide.md, "Solvers"): CG with hexcut's multigrid, and the comparison
// solvers CG + Jacobi, CG + hypre BoomerAMG, CG + PETSc GAMG and a sparse direct Cholesky
// (MUMPS). Each is a KSP configured with defaults that suit elasticity, set on that KSP before
// KSPSetFromOptions, so command-line and deck `petsc_options` always win.
#pragma once

#include <petscksp.h>

#include <cfloat>
#include <string>

#include "deck/deck.hpp"

namespace hexcut::solve {

/// What one linear solve did.
struct SolveRecord {
  PetscInt iterations = 0;
  double residual = 0.0;       // true relative residual ||b - A x|| / ||b||
  double residual_norm = 0.0;  // true residual ||b - A x||
  double setup_seconds = 0.0;  // KSPSetUp (preconditioner build, factorization)
  double solve_seconds = 0.0;  // KSPSolve after setup
  KSPConvergedReason reason = KSP_CONVERGED_ITERATING;
  bool roundoff_limited = false;  // above kTrueResidualFactor x rtol, at round-off: accepted
};

/// Puts the deck's solver.petsc_options into the options database, unless the command
/// line set them already.
PetscErrorCode insert_deck_options(const deck::Solver& solver);

/// Creates a KSP for the chosen solver over the DM's layout: the solver's KSP and PC types
/// and settings are set on this KSP (not in the options database), then KSPSetFromOptions,
/// so every PETSc option the user gives (command line, deck petsc_options) overrides them,
/// -pc_type included. With the PC type "hexcut" (solver gmg, gmg-cycles, or -pc_type
/// hexcut) the caller attaches the multigrid (multigrid::pc_set_multigrid).
PetscErrorCode create_solver(MPI_Comm comm, DM dm, const deck::Solver& solver, KSP* ksp);

/// With -hexcut_residual_history FILE, appends "solve iteration seconds residual" per
/// KSP iteration to FILE (rank 0): wall time since the start of the solve's set-up and
/// the monitored residual norm. For plots of residual against time.
PetscErrorCode attach_residual_history(KSP ksp);

/// Sets the operator (re-used pattern) and, for hypre and GAMG, the near-null space from
/// `coordinates` (owned reference positions, bs 3: the rigid-body modes).
PetscErrorCode set_operator(KSP ksp, const deck::Solver& solver, Mat A, Vec coordinates);

/// How far the true relative residual ||b - A x||/||b|| of a converged solve may exceed
/// the requested rtol before the solve counts as failed (doc/user-guide.md).
constexpr double kTrueResidualFactor = 10.0;

/// A true residual above kTrueResidualFactor x rtol is accepted (with a warning) when the
/// normwise backward error ||b - Ax|| / (||A|| ||x|| + ||b||) is at most this: the
/// round-off level of double precision, which rtol cannot push below (doc/user-guide.md,
/// "Exit codes").
constexpr double kRoundoffBackwardError = 100 * DBL_EPSILON;

/// Power-iteration products for the ||A|| of that backward error.
constexpr int kNormIterations = 30;

/// Solves A x = b (x holds the initial guess; nonzero guesses are used) and records
/// what happened in `record`. Fails with PETSC_ERR_NOT_CONVERGED (a solver failure, exit 3)
/// if the solve diverged or did not converge, or when its true relative residual exceeds
/// kTrueResidualFactor x rtol and its backward error exceeds kRoundoffBackwardError
/// (except for solves without a norm, gmg-cycles).
PetscErrorCode solve(KSP ksp, Vec b, Vec x, SolveRecord* record);

std::string reason_string(KSPConvergedReason reason);

}  // namespace hexcut::solve
