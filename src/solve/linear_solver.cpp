#include "solve/linear_solver.hpp"

#include <petsctime.h>

#include <algorithm>
#include <cfloat>
#include <cstdint>

#include "common/petsc_check.hpp"
#include "multigrid/pc_hexcut.hpp"

namespace hexcut::solve {
namespace {

struct History {
  FILE* file = nullptr;
  int solve = 0;
  PetscLogDouble start = 0;
  bool warned_roundoff = false;  // the round-off warning is printed once per run
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

/// ||A||_2 of the symmetric operator A, from below: power iteration from a fixed,
/// rank-independent start (a hash of the global index), `iterations` products. The
/// Rayleigh quotient of a symmetric matrix converges fast, and an underestimate only
/// makes the backward error below look larger (the check stricter).
PetscErrorCode operator_norm_estimate(Mat A, Vec like, int iterations, PetscReal* norm) {
  PetscFunctionBeginUser;
  Vec v, w;
  PetscCall(VecDuplicate(like, &v));
  PetscCall(VecDuplicate(like, &w));
  PetscInt begin, end;
  PetscCall(VecGetOwnershipRange(v, &begin, &end));
  PetscScalar* a;
  PetscCall(VecGetArray(v, &a));
  for (PetscInt i = begin; i < end; ++i) {
    std::uint64_t h = std::uint64_t(i) * 0x9E3779B97F4A7C15ull;
    h ^= h >> 29;
    a[i - begin] = double(h % 2001) / 1000.0 - 1.0;  // in [-1, 1]
  }
  PetscCall(VecRestoreArray(v, &a));
  PetscReal n = 0;
  PetscCall(VecNormalize(v, &n));
  *norm = 0;
  for (int k = 0; k < iterations && n > 0; ++k) {
    PetscCall(MatMult(A, v, w));
    PetscCall(VecNorm(w, NORM_2, &n));
    *norm = std::max(*norm, n);
    if (n > 0) PetscCall(VecAXPBY(v, 1.0 / n, 0.0, w));
  }
  PetscCall(VecDestroy(&v));
  PetscCall(VecDestroy(&w));
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
  // the true one when the system is very badly conditioned, or tests another norm or an
  // absolute tolerance when the options say so, and a direct solve tests nothing: the
  // true residual decides, with round-off as the only excuse.
  // Fixed-cycle solves (gmg-cycles, no norm) are not checked: they promise no tolerance.
  KSPNormType norm;
  PetscCall(KSPGetNormType(ksp, &norm));
  PetscReal rtol;
  PetscCall(KSPGetTolerances(ksp, &rtol, nullptr, nullptr, nullptr));
  if (norm != KSP_NORM_NONE && r.residual > kTrueResidualFactor * rtol) {
    // Above the tolerance: is that round-off? The computed residual b - Ax itself carries
    // an error of order eps ||A|| ||x||, which exceeds rtol ||b|| when ||A|| ||x|| / ||b||
    // (at most the condition number) is large: slender bodies, whose bending makes
    // kappa ~ (L/h)^2 (L/t)^2. The normwise backward error
    //   eta = ||b - Ax|| / (||A|| ||x|| + ||b||)
    // (Higham, Accuracy and Stability of Numerical Algorithms, 2002, Thm. 7.1;
    // doc/references.md) says how far x is from the exact solution of a nearby system;
    // a converged solve reaches 0.2-0.4 eps (CG with gmg and MUMPS alike, measured);
    // kRoundoffBackwardError = 100 eps leaves room, and no solver does better.
    PetscReal nA = 0, nx = 0;
    PetscCall(operator_norm_estimate(A, x, kNormIterations, &nA));
    PetscCall(VecNorm(x, NORM_2, &nx));
    const double eta = nr / (nA * nx + nb);
    r.roundoff_limited = eta <= kRoundoffBackwardError;
    if (r.roundoff_limited) {
      if (!g_history.warned_roundoff) {
        g_history.warned_roundoff = true;
        char msg[600];
        std::snprintf(msg, sizeof msg,
                      "hexcut: warning: solve %d: the true relative residual %.3g is above "
                      "10 x rtol = %.3g, but at the round-off level of double precision for "
                      "this system (backward error %.2g = %.2g eps; ||A|| ||x|| / ||b|| = %.3g): "
                      "rtol %.3g is below what any solver attains here, and the result is as "
                      "accurate as double allows; an rtol of %.1g or more saves the iterations "
                      "spent below it. Later solves of this run ending likewise are not "
                      "reported\n",
                      g_history.solve, r.residual, kTrueResidualFactor * rtol, eta,
                      eta / DBL_EPSILON, (nA * nx + nb) / nb, double(rtol), r.residual);
        PetscCall(PetscFPrintf(comm, PETSC_STDERR, "%s", msg));
      }
      PetscFunctionReturn(0);
    }
    char msg[600];
    std::snprintf(msg, sizeof msg,
                  "the solver reported convergence (%s, %d iterations), but the true relative "
                  "residual ||b - Ax||/||b|| = %.3g is more than %g x rtol = %.3g, and not "
                  "round-off (backward error %.2g = %.2g eps): the result would be wrong. "
                  "Causes: a stopping test other than rtol on the true residual (-ksp_atol, "
                  "-ksp_norm_type, -ksp_converged_use_* in the options), or an operator the "
                  "preconditioner does not match; doc/user-guide.md, \"Exit codes\"",
                  reason_string(r.reason).c_str(), int(r.iterations), r.residual,
                  kTrueResidualFactor, kTrueResidualFactor * rtol, eta, eta / DBL_EPSILON);
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
