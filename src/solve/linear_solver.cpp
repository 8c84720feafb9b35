#include "solve/linear_solver.hpp"

#include <petsctime.h>

#include "common/petsc_check.hpp"
#include "multigrid/pc_hexcut.hpp"

namespace hexcut::solve {
namespace {

struct History {
  FILE* file = nullptr;
  int solve = 0;
  PetscLogDouble start = 0;
};
History g_history;  // one per process; hexcut runs one solver at a time

PetscErrorCode history_monitor(KSP, PetscInt it, PetscReal rnorm, void*) {
  PetscFunctionBeginUser;
  PetscLogDouble now;
  PetscCall(PetscTime(&now));
  if (g_history.file)
    std::fprintf(g_history.file, "%d %d %.6f %.10e\n", g_history.solve, int(it),
                 now - g_history.start, double(rnorm));
  PetscFunctionReturn(0);
}

}  // namespace

PetscErrorCode insert_deck_options(const deck::Solver& s) {
  PetscFunctionBeginUser;
  // The command line was parsed by PetscInitialize and wins.
  for (const auto& [name, value] : s.petsc_options)
    PetscCall(set_option_if_unset(name.c_str(), value.empty() ? nullptr : value.c_str()));
  PetscFunctionReturn(0);
}

namespace {

/// The chosen solver's KSP and PC types and settings, on this KSP before KSPSetFromOptions,
/// so the command line and the deck's petsc_options override each of them.
PetscErrorCode set_solver_defaults(KSP ksp, const deck::Solver& s, ScopedOptionDefaults* db) {
  PetscFunctionBeginUser;
  PC pc;
  PetscCall(KSPGetPC(ksp, &pc));
  switch (s.type) {
    case deck::Solver::Type::cg_jacobi:
      PetscCall(KSPSetType(ksp, KSPCG));
      PetscCall(PCSetType(pc, PCJACOBI));
      break;
    case deck::Solver::Type::hypre:
      // BoomerAMG for 3D elasticity (doc/user-guide.md, "hypre settings"):
      //  - nodal coarsening (1: the x,y,z unknowns of a vertex are coarsened together,
      //    strength from the Frobenius norm of its 3x3 blocks);
      //  - interpolation variant 2 (GM-2) with the rigid-body modes as interpolation
      //    vectors (taken from MatSetNearNullSpace), limited to 4 per row (qmax), so
      //    rotations are interpolated exactly: this halves the iteration count;
      //  - strong threshold 0.5, the usual value in 3D (0.25 is for 2D);
      //  - HMIS + extended+i interpolation, 4 entries per row, aggressive coarsening on
      //    the first level: keeps the operator complexity, hence setup time and memory,
      //    low. Without it the vector interpolation costs more time than it saves.
      // Measured on the cantilever example (20k DOFs): nodal_coarsen 6 took 146
      // iterations; this set 58 and is the fastest of the combinations tried
      // (doc/benchmarks.md). PETSc has setters only for the type: the rest are options,
      // read by this KSP's PCSetFromOptions.
      PetscCall(KSPSetType(ksp, KSPCG));
      PetscCall(PCSetType(pc, PCHYPRE));
      PetscCall(PCHYPRESetType(pc, "boomeramg"));
      PetscCall(db->add("-pc_hypre_boomeramg_nodal_coarsen", "1"));
      PetscCall(db->add("-pc_hypre_boomeramg_vec_interp_variant", "2"));
      PetscCall(db->add("-pc_hypre_boomeramg_vec_interp_qmax", "4"));
      PetscCall(db->add("-pc_hypre_boomeramg_strong_threshold", "0.5"));
      PetscCall(db->add("-pc_hypre_boomeramg_coarsen_type", "HMIS"));
      PetscCall(db->add("-pc_hypre_boomeramg_interp_type", "ext+i"));
      PetscCall(db->add("-pc_hypre_boomeramg_P_max", "4"));
      PetscCall(db->add("-pc_hypre_boomeramg_agg_nl", "1"));
      break;
    case deck::Solver::Type::gamg:
      // Smoothed aggregation with the 6 rigid-body modes (MatNullSpaceCreateRigidBody);
      // the levels' Chebyshev/Jacobi smoothers are GAMG's own defaults.
      PetscCall(KSPSetType(ksp, KSPCG));
      PetscCall(PCSetType(pc, PCGAMG));
      PetscCall(PCGAMGSetType(pc, PCGAMGAGG));
      {
        PetscReal threshold[1] = {0.01};
        PetscCall(PCGAMGSetThreshold(pc, threshold, 1));
      }
      break;
    case deck::Solver::Type::gmg:
      // CG preconditioned by hexcut's multigrid (the analysis builds and attaches it).
      PetscCall(KSPSetType(ksp, KSPCG));
      PetscCall(PCSetType(pc, multigrid::PCHEXCUT));
      break;
    case deck::Solver::Type::gmg_cycles:
      // The theses' real-time mode: a fixed number of multigrid cycles (Richardson),
      // warm-started from the previous step, no convergence test.
      PetscCall(KSPSetType(ksp, KSPRICHARDSON));
      PetscCall(PCSetType(pc, multigrid::PCHEXCUT));
      break;
    case deck::Solver::Type::direct:
      // Cholesky through MUMPS (parallel); the matrix is SPD after symmetric elimination.
      PetscCall(KSPSetType(ksp, KSPPREONLY));
      PetscCall(PCSetType(pc, PCCHOLESKY));
      PetscCall(PCFactorSetMatSolverType(pc, MATSOLVERMUMPS));
      break;
  }
  PetscFunctionReturn(0);
}

}  // namespace

PetscErrorCode create_solver(MPI_Comm comm, DM dm, const deck::Solver& s, KSP* ksp) {
  PetscFunctionBeginUser;
  PetscCall(multigrid::register_pc());
  PetscCall(KSPCreate(comm, ksp));
  PetscCall(KSPSetDM(*ksp, dm));
  PetscCall(KSPSetDMActive(*ksp, PETSC_FALSE));  // operators come from hexcut, not the DM
  if (s.type == deck::Solver::Type::gmg_cycles) {
    PetscCall(KSPSetTolerances(*ksp, PETSC_DEFAULT, PETSC_DEFAULT, PETSC_DEFAULT, s.cycles));
    PetscCall(KSPSetNormType(*ksp, KSP_NORM_NONE));
    PetscCall(KSPSetConvergenceTest(*ksp, KSPConvergedSkip, nullptr, nullptr));
  } else {
    PetscCall(KSPSetTolerances(*ksp, s.rtol, PETSC_DEFAULT, PETSC_DEFAULT, s.max_iterations));
    PetscCall(KSPSetNormType(*ksp, KSP_NORM_UNPRECONDITIONED));
  }
  {
    ScopedOptionDefaults defaults;
    PetscCall(set_solver_defaults(*ksp, s, &defaults));
    PetscCall(KSPSetFromOptions(*ksp));
  }
  // Iterative solvers start from the last solution (time steps, load steps, fixed-point
  // iterations); a direct solve (preonly) rejects an initial guess.
  PetscBool preonly = PETSC_FALSE;
  PetscCall(PetscObjectTypeCompare((PetscObject)*ksp, KSPPREONLY, &preonly));
  PetscCall(KSPSetInitialGuessNonzero(*ksp, preonly ? PETSC_FALSE : PETSC_TRUE));
  PetscCall(attach_residual_history(*ksp));
  PetscFunctionReturn(0);
}

PetscErrorCode set_operator(KSP ksp, const deck::Solver&, Mat A, Vec coordinates) {
  PetscFunctionBeginUser;
  // The algebraic multigrids build their coarse spaces from the rigid-body modes, whatever
  // chose them (the deck or -pc_type).
  PC pc;
  PetscBool algebraic = PETSC_FALSE;
  PetscCall(KSPGetPC(ksp, &pc));
  PetscCall(PetscObjectTypeCompareAny((PetscObject)pc, &algebraic, PCHYPRE, PCGAMG, ""));
  if (coordinates && algebraic) {
    MatNullSpace rigid;
    PetscCall(MatNullSpaceCreateRigidBody(coordinates, &rigid));
    PetscCall(MatSetNearNullSpace(A, rigid));
    PetscCall(MatNullSpaceDestroy(&rigid));
  }
  PetscCall(KSPSetOperators(ksp, A, A));
  PetscFunctionReturn(0);
}

PetscErrorCode solve(KSP ksp, Vec b, Vec x, SolveRecord* record) {
  PetscFunctionBeginUser;
  SolveRecord& r = *record;
  r = SolveRecord{};
  PetscLogDouble t0, t1, t2;
  PetscCall(PetscTime(&t0));
  g_history.start = t0;
  ++g_history.solve;
  PetscCall(KSPSetUp(ksp));
  PetscCall(PetscTime(&t1));
  PetscCall(KSPSolve(ksp, b, x));
  PetscCall(PetscTime(&t2));
  r.setup_seconds = t1 - t0;
  r.solve_seconds = t2 - t1;
  PetscCall(KSPGetIterationNumber(ksp, &r.iterations));
  PetscCall(KSPGetConvergedReason(ksp, &r.reason));
  // True residual, independent of the norm the KSP monitored.
  Mat A;
  Vec res;
  PetscCall(KSPGetOperators(ksp, &A, nullptr));
  PetscCall(VecDuplicate(b, &res));
  PetscCall(MatMult(A, x, res));
  PetscCall(VecAYPX(res, -1.0, b));
  PetscReal nr = 0, nb = 0;
  PetscCall(VecNorm(res, NORM_2, &nr));
  PetscCall(VecNorm(b, NORM_2, &nb));
  PetscCall(VecDestroy(&res));
  if (g_history.file) {  // the end point, also for direct solves that never monitor
    std::fprintf(g_history.file, "%d %d %.6f %.10e\n", g_history.solve, int(r.iterations), t2 - t0,
                 double(nr));
    std::fflush(g_history.file);
  }
  r.residual_norm = nr;
  r.residual = nb > 0 ? nr / nb : nr;
  // hexcut's messages are formatted here and passed as "%s": PETSc's own printf-style
  // formatting prints a plain %g of a whole number with a trailing point ("3.").
  const MPI_Comm comm = PetscObjectComm((PetscObject)ksp);
  if (r.reason < 0) {
    std::string msg = "linear solve failed: " + reason_string(r.reason) + " after " +
                      std::to_string(r.iterations) + " iterations (relative residual " +
                      std::to_string(r.residual) + ")";
    if (r.reason == KSP_DIVERGED_INDEFINITE_PC) {
      // CG needs a symmetric positive definite preconditioner. hexcut's multigrid is one in
      // double precision; with its coarse blocks rounded to float a coarse level of a large,
      // ill-conditioned (slender) body can turn indefinite (doc/theory.md, "Mixed precision").
      PC pc;
      PetscBool hexcut = PETSC_FALSE;
      PetscCall(KSPGetPC(ksp, &pc));
      PetscCall(PetscObjectTypeCompare((PetscObject)pc, multigrid::PCHEXCUT, &hexcut));
      multigrid::Options o;
      if (hexcut) PetscCall(multigrid::pc_get_options(pc, &o));
      msg += hexcut && o.precision == multigrid::Precision::single
                 ? ": the preconditioner is not positive definite; -gmg_precision single rounds "
                   "the coarse levels to float, which a system this large or ill-conditioned "
                   "does not tolerate: run it with -gmg_precision double (the default)"
                 : ": the preconditioner is not positive definite (CG needs a symmetric positive "
                   "definite one)";
    }
    SETERRQ(comm, PETSC_ERR_NOT_CONVERGED, "%s", msg.c_str());
  }
  // A converged Krylov method tests its recursively updated residual, which drifts from
  // the true one when the system is singular (a piece free to move) or very badly
  // conditioned (nu -> 0.5), and a direct solve tests nothing: the true residual decides.
  // Fixed-cycle solves (gmg-cycles, no norm) are not checked: they promise no tolerance.
  KSPNormType norm;
  PetscCall(KSPGetNormType(ksp, &norm));
  PetscReal rtol;
  PetscCall(KSPGetTolerances(ksp, &rtol, nullptr, nullptr, nullptr));
  if (norm != KSP_NORM_NONE && r.residual > kTrueResidualFactor * rtol) {
    char msg[400];
    std::snprintf(msg, sizeof msg,
                  "the solver reported convergence (%s, %d iterations), but the true relative "
                  "residual ||b - Ax||/||b|| = %.3g is more than %g x rtol = %.3g: the result "
                  "would be wrong. Causes: a body free to move (check the supports), or a "
                  "nearly singular system (Poisson's ratio near 0.5, extreme stiffness "
                  "contrasts); doc/user-guide.md, \"Exit codes\"",
                  reason_string(r.reason).c_str(), int(r.iterations), r.residual,
                  kTrueResidualFactor, kTrueResidualFactor * rtol);
    SETERRQ(comm, PETSC_ERR_NOT_CONVERGED, "%s", msg);
  }
  PetscFunctionReturn(0);
}

PetscErrorCode attach_residual_history(KSP ksp) {
  PetscFunctionBeginUser;
  char path[PETSC_MAX_PATH_LEN];
  PetscBool set = PETSC_FALSE;
  PetscCall(
      PetscOptionsGetString(nullptr, nullptr, "-hexcut_residual_history", path, sizeof path, &set));
  if (!set) PetscFunctionReturn(0);
  PetscMPIInt rank;
  PetscCallMPI(MPI_Comm_rank(PetscObjectComm((PetscObject)ksp), &rank));
  if (rank == 0 && !g_history.file) {
    g_history.file = std::fopen(path, "w");
    PetscCheck(g_history.file, PETSC_COMM_SELF, PETSC_ERR_FILE_OPEN, "cannot open %s", path);
    std::fprintf(g_history.file, "# solve iteration seconds residual\n");
  }
  PetscCall(KSPMonitorSet(ksp, history_monitor, nullptr, nullptr));
  PetscFunctionReturn(0);
}

std::string reason_string(KSPConvergedReason reason) {
  return KSPConvergedReasons[reason];
}

}  // namespace hexcut::solve
