#include "analysis/simulation.hpp"

#include <cmath>

#include "analysis/events.hpp"
#include "common/errors.hpp"
#include "common/petsc_check.hpp"
#include "element/newmark.hpp"

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
  parse_petsc_options(
      [&] { check_petsc(solve::create_solver(comm, model.dm, deck.solver, &ksp_), "create_solver"); });
  if (uses_multigrid()) {
    auto options = parse_petsc_options([] { return multigrid::read_options(); });
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
    PC pc;
    check_petsc(KSPGetPC(ksp_, &pc), "KSPGetPC");
    check_petsc(mg_->attach(pc), "attach");
  } else {
    check_petsc(assembly::create_matrix(comm, model.copies, model.partition, model.layout, &A_),
                "create_matrix");
  }
}

bool Simulation::uses_multigrid() const {
  return deck_.solver.type == deck::Solver::Type::gmg ||
         deck_.solver.type == deck::Solver::Type::gmg_cycles;
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
    mg_->update(model_.cells, w, model_.boundary.constraints.rows);
    check_petsc(KSPSetOperators(ksp_, mg_->fine_operator(), mg_->fine_operator()),
                "KSPSetOperators");
  } else {
    check_petsc(assembly::assemble_matrix(model_.layout, model_.cells, w, A_), "assemble_matrix");
    check_petsc(assembly::constrain_matrix(model_.boundary.constraints, A_), "constrain_matrix");
    check_petsc(solve::set_operator(ksp_, deck_.solver, A_, model_.coordinates), "set_operator");
  }
  assembled_ = true;
}

void Simulation::refresh_rotations(Vec u) {
  Vec ul;
  check_petsc(DMGetLocalVector(model_.dm, &ul), "DMGetLocalVector");
  check_petsc(assembly::global_to_local(model_.dm, u, ul), "global_to_local");
  const PetscScalar* a;
  check_petsc(VecGetArrayRead(ul, &a), "VecGetArrayRead");
  assembly::update_rotations(model_.layout, a, model_.cells);
  check_petsc(VecRestoreArrayRead(ul, &a), "VecRestoreArrayRead");
  check_petsc(DMRestoreLocalVector(model_.dm, &ul), "DMRestoreLocalVector");
}

void Simulation::run_static(State& s, const Observer& obs) {
  const auto& an = deck_.analysis;
  const int n = an.load_steps;
  const assembly::OperatorWeights w{1.0, 0.0, true};
  const double t_eval = 1.0;  // time functions at the end of the load
  ScratchVec b(model_.dm), u_new(model_.dm);
  assembly::set_identity_rotations(model_.cells);
  for (int step = int(s.step) + 1; step <= n; ++step) {
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
      if (obs.on_solve) obs.on_solve(s, rec);
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
    if (obs.on_step) obs.on_step(s);
  }
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
  check_petsc(assembly::create_matrix(comm_, model_.copies, model_.partition, model_.layout, &M),
              "create_matrix");
  check_petsc(assembly::assemble_matrix(model_.layout, model_.cells, mass_only, M),
              "assemble_matrix");
  check_petsc(assembly::constrain_matrix(model_.boundary.constraints, M), "constrain_matrix");
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

solve::SolveRecord Simulation::newmark_step(State& s) {
  const auto& an = deck_.analysis;
  const auto c = element::newmark_coefficients(an.dt);
  const bool lumped = an.mass == deck::Analysis::Mass::lumped;
  // A = a0 M + a1 D + K^ with D = alpha1 M + alpha2 K^.
  const assembly::OperatorWeights w{1.0 + c.a1 * an.rayleigh_stiffness,
                                    c.a0 + c.a1 * an.rayleigh_mass, lumped};
  if (corotational()) refresh_rotations(s.u);
  if (corotational() || !assembled_) assemble(w);
  // t = n dt, not a running sum: summing dt drifts (0.1 + 0.1 + ... = 2.9999999999999583)
  // and then a time that a user asks for (ParaView, a cut time) falls on the step before.
  const double t1 = double(s.step + 1) * an.dt;
  ScratchVec b(model_.dm), hist(model_.dm), tmp(model_.dm), u_new(model_.dm);
  auto& M = model_;
  check_petsc(assembly::assemble_loads(M.dm, M.layout, M.cells, M.boundary, t1, 1.0, b),
              "assemble_loads");
  if (corotational())
    check_petsc(assembly::add_corotational_rhs(M.dm, M.layout, M.cells, 1.0, b),
                "corotational_rhs");
  // + M (a0 u + a2 v + a)
  check_petsc(VecAXPBYPCZ(hist, c.a0, c.a2, 0.0, s.u, s.v), "VecAXPBYPCZ");
  check_petsc(VecAXPY(hist, 1.0, s.a), "VecAXPY");
  check_petsc(assembly::apply(M.dm, M.layout, M.cells, {0.0, 1.0, lumped}, hist, tmp), "apply");
  check_petsc(VecAXPY(b, 1.0, tmp), "VecAXPY");
  // + D (a1 u + v)
  if (an.rayleigh_mass != 0.0 || an.rayleigh_stiffness != 0.0) {
    check_petsc(VecAXPBYPCZ(hist, c.a1, 1.0, 0.0, s.u, s.v), "VecAXPBYPCZ");
    check_petsc(assembly::apply(M.dm, M.layout, M.cells,
                                {an.rayleigh_stiffness, an.rayleigh_mass, lumped}, hist, tmp),
                "apply");
    check_petsc(VecAXPY(b, 1.0, tmp), "VecAXPY");
  }
  check_petsc(
      assembly::constrain_rhs(M.dm, M.layout, M.cells, w, M.boundary.constraints, t1, 1.0, b),
      "constrain_rhs");
  check_petsc(VecCopy(s.u, u_new), "VecCopy");
  solve::SolveRecord rec;
  {
    EventScope scope(events().solve);
    rec = solve::solve(ksp_, b, u_new);
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
  return rec;
}

void Simulation::run_dynamic(State& s, const Observer& obs) {
  while (s.step < deck_.analysis.steps) {
    const auto rec = newmark_step(s);
    if (obs.on_solve) obs.on_solve(s, rec);
    if (obs.on_step) obs.on_step(s);
  }
}

double Simulation::kinetic_energy(const State& s) {
  const bool lumped = deck_.analysis.mass == deck::Analysis::Mass::lumped;
  ScratchVec Mv(model_.dm);
  check_petsc(assembly::apply(model_.dm, model_.layout, model_.cells, {0.0, 1.0, lumped}, s.v, Mv),
              "apply");
  PetscScalar e;
  check_petsc(VecDot(s.v, Mv, &e), "VecDot");
  return 0.5 * e;
}

double Simulation::elastic_energy(const State& s) {
  ScratchVec Ku(model_.dm);
  check_petsc(assembly::apply(model_.dm, model_.layout, model_.cells, {1.0, 0.0, true}, s.u, Ku),
              "apply");
  PetscScalar e;
  check_petsc(VecDot(s.u, Ku, &e), "VecDot");
  return 0.5 * e;
}

}  // namespace hexcut::analysis
