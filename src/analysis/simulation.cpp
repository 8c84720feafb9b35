#include "analysis/simulation.hpp"

#include <cmath>
#include <cstdio>

#include "analysis/events.hpp"
#include "common/errors.hpp"
#include "common/petsc_check.hpp"
#include "element/newmark.hpp"
#include "multigrid/pc_hexcut.hpp"

namespace hexcut::analysis {
namespace {

/// RAII scope of a PETSc log event.
class EventScope {
 public:
  explicit EventScope(PetscLogEvent e) : e_(e) { PetscLogEventBegin(e_, 0, 0, 0, 0); }
  ~EventScope() { PetscLogEventEnd(e_, 0, 0, 0, 0); }

 private:
  PetscLogEvent e_;
};

/// A global vector borrowed from the DM for the scope.
class ScratchVec {
 public:
  explicit ScratchVec(DM dm) : dm_(dm) {
    check_petsc(DMGetGlobalVector(dm_, &v_), "DMGetGlobalVector");
  }
  ~ScratchVec() { DMRestoreGlobalVector(dm_, &v_); }
  operator Vec() const { return v_; }

 private:
  DM dm_;
  Vec v_ = nullptr;
};

}  // namespace

Simulation::Simulation(MPI_Comm comm, Model& model, const deck::Deck& deck)
    : comm_(comm), model_(model), deck_(deck) {
  // Option errors (an unknown type, a value that is not a number) are input errors.
  PC pc;
  PetscBool hexcut_pc = PETSC_FALSE;
  parse_petsc_options([&] {
    check_petsc(solve::create_solver(comm, model.dm, deck.solver, &ksp_), "create_solver");
    check_petsc(KSPGetPC(ksp_, &pc), "KSPGetPC");
    check_petsc(PetscObjectTypeCompare((PetscObject)pc, multigrid::PCHEXCUT, &hexcut_pc), "type");
  });
  if (hexcut_pc) {
    multigrid::Options options;
    check_petsc(multigrid::pc_get_options(pc, &options), "pc_get_options");
    // After cuts, coarse cells may be wider than the pieces (rods, slivers): their coarse
    // spaces approximate bending poorly, and a W-cycle solves those levels better. For
    // static solves that pays (32^3 cube cut into 16 rods, 4 levels: 11 CG iterations
    // instead of 17, 10% less time); in dynamics the mass term keeps the V-cycle cheaper
    // (doc/benchmarks.md). -gmg_cycle overrides.
    if (!options.cycle_set && !model.lattice.cut_links.empty() &&
        deck.analysis.type == deck::Analysis::Type::static_)
      options.cycle_gamma = 2;
    mg_ = std::make_unique<multigrid::Multigrid>(comm, model.lattice, model.copies, model.partition,
                                                 model.layout, model.dm, options);
    check_petsc(multigrid::pc_set_multigrid(pc, mg_.get()), "pc_set_multigrid");
  } else {
    check_petsc(assembly::create_matrix(comm, model.copies, model.layout, &A_), "create_matrix");
  }
}

bool Simulation::uses_multigrid() const {
  return mg_ != nullptr;
}

Simulation::~Simulation() {
  KSPDestroy(&ksp_);
  MatDestroy(&A_);
}

bool Simulation::corotational() const {
  return deck_.analysis.formulation == deck::Analysis::Formulation::corotational;
}

void Simulation::assemble(const assembly::OperatorWeights& w) {
  EventScope scope(events().assembly);
  if (mg_) {
    // Matrix-free: the fine operator reads the cell data; the hierarchy is rebuilt.
    // The one boundary between the multigrid's PETSc error codes and exceptions; a
    // singular point-block diagonal is a solver failure (exit 3).
    const PetscErrorCode ierr = mg_->update(model_.cells, w, model_.boundary.constraints.rows);
    if (ierr == PETSC_ERR_MAT_LU_ZRPVT)
      throw SolverError("the multigrid's set-up failed: a singular 3x3 diagonal block");
    check_petsc(ierr, "Multigrid::update");
    check_petsc(KSPSetOperators(ksp_, mg_->fine_operator(), mg_->fine_operator()),
                "KSPSetOperators");
  } else {
    check_petsc(assembly::assemble_constrained_matrix(model_.dm, model_.layout, model_.cells, w,
                                                      model_.boundary.constraints, A_),
                "assemble_constrained_matrix");
    check_petsc(solve::set_operator(ksp_, deck_.solver, A_, model_.coordinates), "set_operator");
  }
  assembled_ = true;
}

void Simulation::refresh_rotations(Vec u) {
  const assembly::LocalValues ul(model_.dm, u);
  assembly::update_rotations(model_.layout, ul.data(), model_.cells);
}

void Simulation::static_step(State& s, const OnSolve& on_solve) {
  const auto& an = deck_.analysis;
  const int n = an.load_steps;
  const assembly::OperatorWeights w{1.0, 0.0, true};
  const double t_eval = 1.0;  // time functions at the end of the load
  ScratchVec b(model_.dm), u_new(model_.dm);
  if (!corotational()) assembly::set_identity_rotations(model_.cells);
  const int step = int(s.step) + 1;
  const double lf = double(step) / n;
  bool converged = false;
  double change = 0.0;
  const int max_iter = corotational() ? an.max_iterations : 1;
  for (int k = 0; k < max_iter && !converged; ++k) {
    if (corotational()) refresh_rotations(s.u);
    if (corotational() || !assembled_) assemble(w);
    check_petsc(assembly::assemble_loads(model_.dm, model_.layout, model_.cells, model_.boundary,
                                         t_eval, lf, b),
                "assemble_loads");
    if (corotational())
      check_petsc(assembly::add_corotational_rhs(model_.dm, model_.layout, model_.cells, 1.0, b),
                  "add_corotational_rhs");
    check_petsc(assembly::constrain_rhs(model_.dm, model_.layout, model_.cells, w,
                                        model_.boundary.constraints, t_eval, lf, b),
                "constrain_rhs");
    check_petsc(VecCopy(s.u, u_new), "VecCopy");
    solve::SolveRecord rec;
    {
      EventScope scope(events().solve);
      rec = solve::solve(ksp_, b, u_new);
    }
    s.time = lf;
    s.step = step;
    if (on_solve) on_solve(s, rec);
    if (corotational()) {
      // Fixed-point convergence test on the displacement update.
      PetscReal du = 0, un = 0;
      check_petsc(VecAXPY(s.u, -1.0, u_new), "VecAXPY");
      check_petsc(VecNorm(s.u, NORM_2, &du), "VecNorm");
      check_petsc(VecNorm(u_new, NORM_2, &un), "VecNorm");
      change = un > 0 ? du / un : du;
      converged = change <= an.tolerance;
    } else {
      converged = true;
    }
    check_petsc(VecCopy(u_new, s.u), "VecCopy");
  }
  if (!converged)
    throw SolverError("corotational fixed-point iteration did not converge in load step " +
                      std::to_string(step) + " of " + std::to_string(n) + ": relative update " +
                      std::to_string(change) + " > tolerance " + std::to_string(an.tolerance) +
                      " after " + std::to_string(an.max_iterations) +
                      " iterations (try more analysis.load_steps)");
}

void Simulation::initial_acceleration(State& s) {
  // M a0 = f(t0) + b^(u0) - K u0: solved with CG + Jacobi on the (constrained) mass matrix,
  // which is well conditioned, so this is cheap even for consistent mass.
  const bool lumped = deck_.analysis.mass == deck::Analysis::Mass::lumped;
  const assembly::OperatorWeights mass_only{0.0, 1.0, lumped};
  ScratchVec r(model_.dm), Ku(model_.dm);
  if (corotational()) refresh_rotations(s.u);
  check_petsc(assembly::assemble_loads(model_.dm, model_.layout, model_.cells, model_.boundary,
                                       s.time, 1.0, r),
              "assemble_loads");
  if (corotational())
    check_petsc(assembly::add_corotational_rhs(model_.dm, model_.layout, model_.cells, 1.0, r),
                "corotational_rhs");
  check_petsc(assembly::apply(model_.dm, model_.layout, model_.cells, {1.0, 0.0, true}, s.u, Ku),
              "apply");
  check_petsc(VecAXPY(r, -1.0, Ku), "VecAXPY");
  Mat M;
  KSP k;
  check_petsc(assembly::create_matrix(comm_, model_.copies, model_.layout, &M), "create_matrix");
  check_petsc(assembly::assemble_constrained_matrix(model_.dm, model_.layout, model_.cells,
                                                    mass_only, model_.boundary.constraints, M),
              "assemble_constrained_matrix");
  // Prescribed rows: zero initial acceleration.
  for (PetscInt row : model_.boundary.constraints.rows)
    check_petsc(VecSetValue(r, row, 0.0, INSERT_VALUES), "VecSetValue");
  check_petsc(VecAssemblyBegin(r), "VecAssemblyBegin");
  check_petsc(VecAssemblyEnd(r), "VecAssemblyEnd");
  check_petsc(KSPCreate(comm_, &k), "KSPCreate");
  check_petsc(KSPSetOperators(k, M, M), "KSPSetOperators");
  check_petsc(KSPSetType(k, KSPCG), "KSPSetType");
  PC pc;
  check_petsc(KSPGetPC(k, &pc), "KSPGetPC");
  check_petsc(PCSetType(pc, PCJACOBI), "PCSetType");
  check_petsc(KSPSetTolerances(k, 1e-14, 1e-300, PETSC_DEFAULT, 10000), "KSPSetTolerances");
  check_petsc(KSPSetOptionsPrefix(k, "mass_"), "KSPSetOptionsPrefix");
  check_petsc(KSPSetFromOptions(k), "KSPSetFromOptions");
  check_petsc(KSPSolve(k, r, s.a), "KSPSolve");
  KSPConvergedReason reason;
  check_petsc(KSPGetConvergedReason(k, &reason), "KSPGetConvergedReason");
  KSPDestroy(&k);
  MatDestroy(&M);
  if (reason < 0)
    throw SolverError("initial acceleration (mass solve) failed: " + solve::reason_string(reason));
}

solve::SolveRecord Simulation::linearized_step(State& s, Vec u_new) {
  const auto& an = deck_.analysis;
  const auto c = element::newmark_coefficients(an.dt);
  const bool lumped = an.mass == deck::Analysis::Mass::lumped;
  // A = a0 M + a1 D + K^ with D = alpha1 M + alpha2 K^.
  const assembly::OperatorWeights w{1.0 + c.a1 * an.rayleigh_stiffness,
                                    c.a0 + c.a1 * an.rayleigh_mass, lumped};
  if (corotational()) refresh_rotations(s.u);
  if (corotational() || !assembled_) assemble(w);
  const double t1 = double(s.step + 1) * an.dt;
  ScratchVec b(model_.dm), hist(model_.dm), tmp(model_.dm);
  check_petsc(
      assembly::assemble_loads(model_.dm, model_.layout, model_.cells, model_.boundary, t1, 1.0, b),
      "assemble_loads");
  if (corotational())
    check_petsc(assembly::add_corotational_rhs(model_.dm, model_.layout, model_.cells, 1.0, b),
                "corotational_rhs");
  // + M (a0 u + a2 v + a)
  check_petsc(VecAXPBYPCZ(hist, c.a0, c.a2, 0.0, s.u, s.v), "VecAXPBYPCZ");
  check_petsc(VecAXPY(hist, 1.0, s.a), "VecAXPY");
  check_petsc(
      assembly::apply(model_.dm, model_.layout, model_.cells, {0.0, 1.0, lumped}, hist, tmp),
      "apply");
  check_petsc(VecAXPY(b, 1.0, tmp), "VecAXPY");
  // + D (a1 u + v)
  if (an.rayleigh_mass != 0.0 || an.rayleigh_stiffness != 0.0) {
    check_petsc(VecAXPBYPCZ(hist, c.a1, 1.0, 0.0, s.u, s.v), "VecAXPBYPCZ");
    check_petsc(assembly::apply(model_.dm, model_.layout, model_.cells,
                                {an.rayleigh_stiffness, an.rayleigh_mass, lumped}, hist, tmp),
                "apply");
    check_petsc(VecAXPY(b, 1.0, tmp), "VecAXPY");
  }
  check_petsc(assembly::constrain_rhs(model_.dm, model_.layout, model_.cells, w,
                                      model_.boundary.constraints, t1, 1.0, b),
              "constrain_rhs");
  check_petsc(VecCopy(s.u, u_new), "VecCopy");
  EventScope scope(events().solve);
  return solve::solve(ksp_, b, u_new);
}

solve::SolveRecord Simulation::midpoint_step(const State& s, Vec load_sum, Vec u_new, Vec fbar) {
  // The mid-point form of the step (doc/theory.md "Mid-point corotational step"): with
  // du = u - u_n and the Newmark velocity v_n+1 = (2/dt) du - v_n, the step solves
  //   r(u) = f(t_n) + f(t_n+1) - 2 f_alg(u_n, u) - a0 M (du - dt v_n) - a1 D du = 0
  // on the free DOFs (D = alpha1 M + alpha2 K^). Each iteration solves
  //   A u_k+1 = A u_k + r(u_k)   (prescribed rows: u_k+1 = u0(t_n+1))
  // with the operator A = a0 M + a1 D + K^ of the solver, its rotations those of the
  // mid-point between u_n and the predictor.
  const auto& an = deck_.analysis;
  const auto c = element::newmark_coefficients(an.dt);
  const bool lumped = an.mass == deck::Analysis::Mass::lumped;
  const assembly::OperatorWeights w{1.0 + c.a1 * an.rayleigh_stiffness,
                                    c.a0 + c.a1 * an.rayleigh_mass, lumped};
  const assembly::OperatorWeights inertia{c.a1 * an.rayleigh_stiffness,
                                          c.a0 + c.a1 * an.rayleigh_mass, lumped};
  const double t1 = double(s.step + 1) * an.dt;
  ScratchVec fixed(model_.dm), b(model_.dm), r(model_.dm), du(model_.dm), u_prev(model_.dm);
  // The part of r that does not change within the step: f(t_n) + f(t_n+1) + a0 dt M v_n.
  check_petsc(assembly::apply(model_.dm, model_.layout, model_.cells, {0.0, c.a0 * an.dt, lumped},
                              s.v, fixed),
              "apply");
  check_petsc(VecAXPY(fixed, 1.0, load_sum), "VecAXPY");
  // Predictor: constant velocity, and the prescribed values at t_n+1.
  check_petsc(VecWAXPY(u_new, an.dt, s.v, s.u), "VecWAXPY");
  check_petsc(assembly::set_prescribed_values(model_.boundary.constraints, t1, 1.0, u_new),
              "set_prescribed_values");
  solve::SolveRecord total;
  double change = 0.0, energy[2];
  solves_ = 0;
  {
    EventScope scope(events().energy);
    check_petsc(
        assembly::corotated_displacements(model_.dm, model_.layout, model_.cells, s.u, &start_d_),
        "corotated_displacements");
  }
  for (;;) {
    {
      EventScope scope(events().energy);
      check_petsc(assembly::assemble_midpoint_force(model_.dm, model_.layout, model_.cells,
                                                    start_d_, s.u, u_new, fbar, energy),
                  "assemble_midpoint_force");
    }
    // The operator (and preconditioner) of the predictor's mid-point serves the whole
    // step: b below uses that same operator, so the iteration still converges to r = 0,
    // and a further iteration costs a solve, not an assembly and preconditioner set-up.
    // (The matrix-free gmg operator reads the current rotations; its hierarchy stays.)
    if (solves_ == 0) assemble(w);
    // r = fixed - 2 f_alg - (a0 + a1 alpha1) M du - a1 alpha2 K^ du; no equation on the
    // prescribed rows.
    check_petsc(VecWAXPY(du, -1.0, s.u, u_new), "VecWAXPY");
    check_petsc(assembly::apply(model_.dm, model_.layout, model_.cells, inertia, du, r), "apply");
    check_petsc(VecAXPBYPCZ(r, 1.0, -2.0, -1.0, fixed, fbar), "VecAXPBYPCZ");
    check_petsc(assembly::set_prescribed_values(model_.boundary.constraints, t1, 0.0, r),
                "set_prescribed_values");
    // b = A u_k + r with the solver's own operator (constrained: identity rows).
    Mat A;
    check_petsc(KSPGetOperators(ksp_, &A, nullptr), "KSPGetOperators");
    check_petsc(MatMult(A, u_new, b), "MatMult");
    check_petsc(VecAXPY(b, 1.0, r), "VecAXPY");
    check_petsc(assembly::set_prescribed_values(model_.boundary.constraints, t1, 1.0, b),
                "set_prescribed_values");
    // Converged when the last update was below the tolerance, or when the residual is as
    // small as a linear solve leaves it (||b - A u|| <= rtol ||b||; twice that, so that a
    // solve that just met it counts): below that, updates are the linear solver's noise,
    // which the relative change could not tell from progress.
    PetscReal rn = 0, bn = 0;
    check_petsc(VecNorm(r, NORM_2, &rn), "VecNorm");
    check_petsc(VecNorm(b, NORM_2, &bn), "VecNorm");
    if ((solves_ > 0 && change <= an.tolerance) || rn <= 2 * deck_.solver.rtol * bn) break;
    if (solves_ == an.max_iterations) {
      char msg[400];
      std::snprintf(msg, sizeof msg,
                    "corotational step %lld (t = %g s) did not converge: relative change %.3g > "
                    "analysis.tolerance %g and residual %.3g > 2 solver.rtol after "
                    "analysis.max_iterations = %d iterations (try a smaller analysis.dt)",
                    (long long)(s.step + 1), t1, change, an.tolerance, rn / bn, an.max_iterations);
      throw SolverError(msg);
    }
    check_petsc(VecCopy(u_new, u_prev), "VecCopy");
    solve::SolveRecord rec;
    {
      EventScope scope(events().solve);
      rec = solve::solve(ksp_, b, u_new);
    }
    ++solves_;
    total.iterations += rec.iterations;
    total.setup_seconds += rec.setup_seconds;
    total.solve_seconds += rec.solve_seconds;
    total.residual = rec.residual;
    total.residual_norm = rec.residual_norm;
    total.reason = rec.reason;
    PetscReal dk = 0, dn = 0;
    check_petsc(VecAXPY(u_prev, -1.0, u_new), "VecAXPY");
    check_petsc(VecNorm(u_prev, NORM_2, &dk), "VecNorm");
    check_petsc(VecWAXPY(du, -1.0, s.u, u_new), "VecWAXPY");
    check_petsc(VecNorm(du, NORM_2, &dn), "VecNorm");
    change = dn > 0 ? dk / dn : dk;
  }
  // fbar and the energies are those of the converged u_n+1.
  MPI_Allreduce(MPI_IN_PLACE, energy, 2, MPI_DOUBLE, MPI_SUM, comm_);
  energy_.strain0 = energy[0];
  energy_.strain1 = energy[1];
  return total;
}

solve::SolveRecord Simulation::newmark_step(State& s) {
  const auto& an = deck_.analysis;
  const double t0 = double(s.step) * an.dt;
  // t = n dt, not a running sum: summing dt drifts (0.1 + 0.1 + ... = 2.9999999999999583)
  // and then a time that a user asks for (ParaView, a cut time) falls on the step before.
  const double t1 = double(s.step + 1) * an.dt;
  ScratchVec u0(model_.dm), v0(model_.dm), loads(model_.dm), tmp(model_.dm), u_new(model_.dm),
      fbar(model_.dm);
  check_petsc(VecCopy(s.u, u0), "VecCopy");
  check_petsc(VecCopy(s.v, v0), "VecCopy");
  check_petsc(assembly::assemble_loads(model_.dm, model_.layout, model_.cells, model_.boundary, t0,
                                       1.0, loads),
              "assemble_loads");
  check_petsc(assembly::assemble_loads(model_.dm, model_.layout, model_.cells, model_.boundary, t1,
                                       1.0, tmp),
              "assemble_loads");
  check_petsc(VecAXPY(loads, 1.0, tmp), "VecAXPY");
  const bool midpoint = corotational() && an.rotations == deck::Analysis::Rotations::iterated;
  solve::SolveRecord rec;
  if (midpoint) {
    rec = midpoint_step(s, loads, u_new, fbar);
  } else {
    rec = linearized_step(s, u_new);
    solves_ = 1;
  }
  // v, a from the consistent Newmark update (in place).
  PetscInt n;
  check_petsc(VecGetLocalSize(s.u, &n), "VecGetLocalSize");
  const PetscScalar *uo, *un;
  PetscScalar *v, *a;
  check_petsc(VecGetArrayRead(s.u, &uo), "VecGetArrayRead");
  check_petsc(VecGetArrayRead(u_new, &un), "VecGetArrayRead");
  check_petsc(VecGetArray(s.v, &v), "VecGetArray");
  check_petsc(VecGetArray(s.a, &a), "VecGetArray");
  element::newmark_update(int(n), an.dt, uo, v, a, un, v, a);
  check_petsc(VecRestoreArray(s.a, &a), "VecRestoreArray");
  check_petsc(VecRestoreArray(s.v, &v), "VecRestoreArray");
  check_petsc(VecRestoreArrayRead(u_new, &un), "VecRestoreArrayRead");
  check_petsc(VecRestoreArrayRead(s.u, &uo), "VecRestoreArrayRead");
  check_petsc(VecCopy(u_new, s.u), "VecCopy");
  s.time = t1;
  s.step += 1;
  EventScope scope(events().energy);
  if (midpoint) {
    account_energy(u0, v0, s, loads, fbar, energy_.strain0, energy_.strain1);
  } else {
    const double strain0 = cached_step_ == s.step - 1 ? cached_strain_ : strain_energy(u0);
    account_energy(u0, v0, s, loads, nullptr, strain0, strain_energy(s.u));
  }
  return rec;
}

void Simulation::internal_force(Vec u, Vec f) {
  if (corotational()) refresh_rotations(u);
  check_petsc(assembly::apply(model_.dm, model_.layout, model_.cells, {1.0, 0.0, true}, u, f),
              "apply");
  if (corotational()) {
    ScratchVec r(model_.dm);
    check_petsc(VecSet(r, 0.0), "VecSet");
    check_petsc(assembly::add_corotational_rhs(model_.dm, model_.layout, model_.cells, 1.0, r),
                "rhs");
    check_petsc(VecAXPY(f, -1.0, r), "VecAXPY");
  }
}

void Simulation::account_energy(Vec u0, Vec v0, const State& s, Vec load_sum, Vec fbar,
                                double strain0, double strain1) {
  const auto& an = deck_.analysis;
  const bool lumped = an.mass == deck::Analysis::Mass::lumped;
  StepEnergy& e = energy_;
  e = StepEnergy{};
  e.kinetic0 = cached_step_ == s.step - 1 ? cached_kinetic_ : kinetic(v0);
  e.kinetic1 = kinetic(s.v);
  e.strain0 = strain0;
  e.strain1 = strain1;
  cached_step_ = s.step;
  cached_kinetic_ = e.kinetic1;
  cached_strain_ = e.strain1;
  ScratchVec du(model_.dm), Ddu(model_.dm);
  check_petsc(VecWAXPY(du, -1.0, u0, s.u), "VecWAXPY");
  PetscScalar x;
  check_petsc(VecDot(du, load_sum, &x), "VecDot");
  e.external_work = 0.5 * x;
  check_petsc(VecSet(Ddu, 0.0), "VecSet");
  if (an.rayleigh_mass != 0.0 || an.rayleigh_stiffness != 0.0) {
    // D with the rotations the step's operator used.
    check_petsc(assembly::apply(model_.dm, model_.layout, model_.cells,
                                {an.rayleigh_stiffness, an.rayleigh_mass, lumped}, du, Ddu),
                "apply");
    check_petsc(VecDot(du, Ddu, &x), "VecDot");
    e.dissipated = x / an.dt;
  }
  // Supports do work only where they move: reactions rho = M a_mean + D v_mean + f_mean
  // - f_ext,mean on the prescribed DOFs (the equation of motion with the reaction).
  const auto& rows = model_.boundary.constraints.rows;
  const PetscScalar* d;
  check_petsc(VecGetArrayRead(du, &d), "VecGetArrayRead");
  PetscInt first;
  check_petsc(VecGetOwnershipRange(du, &first, nullptr), "VecGetOwnershipRange");
  int moving = 0;
  for (PetscInt r : rows) moving |= d[r - first] != 0.0;
  check_petsc(VecRestoreArrayRead(du, &d), "VecRestoreArrayRead");
  MPI_Allreduce(MPI_IN_PLACE, &moving, 1, MPI_INT, MPI_LOR, comm_);
  if (moving) {
    ScratchVec rho(model_.dm), tmp(model_.dm);
    check_petsc(VecWAXPY(tmp, -1.0, v0, s.v), "VecWAXPY");
    check_petsc(assembly::apply(model_.dm, model_.layout, model_.cells, {0.0, 1.0 / an.dt, lumped},
                                tmp, rho),
                "apply");
    check_petsc(VecAXPBYPCZ(rho, 1.0 / an.dt, -0.5, 1.0, Ddu, load_sum), "VecAXPBYPCZ");
    if (fbar) {
      check_petsc(VecAXPY(rho, 1.0, fbar), "VecAXPY");
    } else {
      internal_force(u0, tmp);
      check_petsc(VecAXPY(rho, 0.5, tmp), "VecAXPY");
      internal_force(s.u, tmp);
      check_petsc(VecAXPY(rho, 0.5, tmp), "VecAXPY");
    }
    const PetscScalar* p;
    check_petsc(VecGetArrayRead(rho, &p), "VecGetArrayRead");
    check_petsc(VecGetArrayRead(du, &d), "VecGetArrayRead");
    double w = 0.0;
    for (PetscInt r : rows) w += d[r - first] * p[r - first];
    check_petsc(VecRestoreArrayRead(du, &d), "VecRestoreArrayRead");
    check_petsc(VecRestoreArrayRead(rho, &p), "VecRestoreArrayRead");
    MPI_Allreduce(MPI_IN_PLACE, &w, 1, MPI_DOUBLE, MPI_SUM, comm_);
    e.support_work = w;
  }
}

double Simulation::kinetic(Vec v) {
  const bool lumped = deck_.analysis.mass == deck::Analysis::Mass::lumped;
  ScratchVec Mv(model_.dm);
  check_petsc(assembly::apply(model_.dm, model_.layout, model_.cells, {0.0, 1.0, lumped}, v, Mv),
              "apply");
  PetscScalar e;
  check_petsc(VecDot(v, Mv, &e), "VecDot");
  return 0.5 * e;
}

double Simulation::strain_energy(Vec u) {
  double w = 0.0;
  {
    const assembly::LocalValues ul(model_.dm, u);
    w = assembly::strain_energy_local(model_.layout, model_.cells, ul.data(), corotational());
  }
  MPI_Allreduce(MPI_IN_PLACE, &w, 1, MPI_DOUBLE, MPI_SUM, comm_);
  return w;
}

double Simulation::kinetic_energy(const State& s) {
  return kinetic(s.v);
}

double Simulation::elastic_energy(const State& s) {
  return strain_energy(s.u);
}

}  // namespace hexcut::analysis
