#include "analysis/simulation.hpp"

// PetscObjectStateGet (a documented function that PETSc 3.18 declares only here).
#include <petsc/private/petscimpl.h>

#include <cmath>
#include <cstdio>

#include "analysis/composite.hpp"
#include "analysis/events.hpp"
#include "common/petsc_check.hpp"
#include "element/newmark.hpp"
#include "multigrid/pc_hexcut.hpp"

namespace hexcut::analysis {
namespace {

/// A global vector borrowed from the DM for the scope. Like assembly::LocalValues, PETSc's
/// way rather than a constructor that borrows (which could only throw): declared first,
/// borrowed by get() (PetscCall(borrow(dm, a, b, ...)) for several), given back by the
/// destructor on every way out of the scope.
class ScratchVec {
 public:
  ScratchVec() = default;
  ~ScratchVec() {
    if (v_) DMRestoreGlobalVector(dm_, &v_);
  }
  ScratchVec(const ScratchVec&) = delete;
  ScratchVec& operator=(const ScratchVec&) = delete;
  PetscErrorCode get(DM dm) {
    PetscFunctionBeginUser;
    PetscCheck(!v_, PETSC_COMM_SELF, PETSC_ERR_ORDER, "ScratchVec::get called twice");
    dm_ = dm;
    PetscCall(DMGetGlobalVector(dm_, &v_));
    PetscFunctionReturn(0);
  }
  operator Vec() const { return v_; }

 private:
  DM dm_ = nullptr;
  Vec v_ = nullptr;
};

/// ScratchVec::get for each of `v`.
template <class... V>
PetscErrorCode borrow(DM dm, V&... v) {
  PetscFunctionBeginUser;
  for (ScratchVec* s : {&v...}) PetscCall(s->get(dm));
  PetscFunctionReturn(0);
}

}  // namespace

Simulation::Simulation(MPI_Comm comm, Model& model, const deck::Deck& deck)
    : comm_(comm), model_(model), deck_(deck) {}

PetscErrorCode Simulation::create(MPI_Comm comm, Model& model, const deck::Deck& deck,
                                  std::unique_ptr<Simulation>* sim, CompositeCarry* carry) {
  PetscFunctionBeginUser;
  std::unique_ptr<Simulation> s(new Simulation(comm, model, deck));
  PetscCall(s->setup(carry));
  *sim = std::move(s);
  PetscFunctionReturn(0);
}

namespace {

/// -gmg_backend host_loop and cuda run the loop-layer cycle (multigrid/loop_cycle.hpp), which
/// does not have every option of the host cycle yet: refused as invalid input before any work.
PetscErrorCode check_backend(const multigrid::Options& o) {
  PetscFunctionBeginUser;
  if (o.backend == multigrid::Backend::host) PetscFunctionReturn(0);
  const char* name = o.backend == multigrid::Backend::cuda ? "cuda" : "host_loop";
  std::string no_device;
  if (o.backend == multigrid::Backend::cuda && multigrid::device_count(&no_device) == 0)
    throw InputError("-gmg_backend cuda: " + no_device + "; use -gmg_backend host");
  if (const char* why = multigrid::loop_cycle_refusal(o))
    throw InputError(std::string("-gmg_backend ") + name + " does not support " + why +
                     " yet (doc/user-guide.md, \"Not yet\"); use -gmg_backend host");
  PetscFunctionReturn(0);
}

}  // namespace

PetscErrorCode Simulation::setup(CompositeCarry* carry) {
  PetscFunctionBeginUser;
  // Option errors (an unknown type, a value that is not a number) are input errors.
  PC pc;
  PetscBool hexcut_pc = PETSC_FALSE;
  PetscCall(parse_petsc_options(comm_, [&]() -> PetscErrorCode {
    PetscFunctionBeginUser;
    PetscCall(solve::create_solver(comm_, model_.dm, deck_.solver, &ksp_));
    PetscCall(KSPGetPC(ksp_, &pc));
    PetscCall(PetscObjectTypeCompare((PetscObject)pc, multigrid::PCHEXCUT, &hexcut_pc));
    PetscFunctionReturn(0);
  }));
  hexcut_pc_ = hexcut_pc;
  if (composite()) PetscFunctionReturn(setup_composite(pc, hexcut_pc, carry));
  if (hexcut_pc) {
    multigrid::Options options;
    PetscCall(multigrid::pc_get_options(pc, &options));
    // After cuts, coarse cells may be wider than the pieces (rods, slivers): their coarse
    // spaces approximate bending poorly, and a W-cycle solves those levels better. For
    // static solves that pays (32^3 cube cut into 16 rods, 4 levels: 11 CG iterations
    // instead of 17, 10% less time); in dynamics the mass term keeps the V-cycle cheaper
    // (doc/benchmarks.md). -gmg_cycle overrides.
    if (!options.cycle_set && !model_.lattice.cut_links.empty() &&
        deck_.analysis.type == deck::Analysis::Type::static_)
      options.cycle_gamma = 2;
    PetscCall(check_backend(options));
    mg_ = std::make_unique<multigrid::Multigrid>(
        comm_, model_.lattice, model_.copies, model_.partition, model_.layout, model_.dm, options);
    PetscCall(multigrid::pc_set_multigrid(pc, mg_.get()));
  } else {
    PetscCall(assembly::create_matrix(comm_, model_.copies, model_.layout, &A_));
  }
  PetscFunctionReturn(0);
}

PetscErrorCode Simulation::setup_composite(PC pc, bool hexcut_pc, CompositeCarry* carry) {
  PetscFunctionBeginUser;
  // The hierarchy up to the composite level always exists: its Galerkin blocks are the
  // composite elements. With gmg it continues below as the preconditioner (-gmg_levels
  // counts the levels from the composite one down); other solvers get the composite
  // system assembled (the coarsest level's matrix, not factored).
  const int l = deck_.discretization.level;
  multigrid::Options options;
  if (hexcut_pc) {
    PetscCall(multigrid::pc_get_options(pc, &options));
    if (options.interpolation == multigrid::Interpolation::smoothed)
      throw InputError(
          "-gmg_interpolation smoothed is not available with composite elements "
          "(discretization.level > 0): its assembled coarse levels have no "
          "composite blocks; use trilinear or energy");
    if (options.hierarchy.levels > 0) options.hierarchy.levels += l;
    if (!options.cycle_set && !model_.lattice.cut_links.empty() &&
        deck_.analysis.type == deck::Analysis::Type::static_)
      options.cycle_gamma = 2;  // as for the fine hexahedra (setup)
  } else {
    options.hierarchy.levels = l + 1;
    options.factor_coarsest = false;
  }
  options.first_level = l;
  if (hexcut_pc) PetscCall(check_backend(options));
  options.hierarchy.min_levels = l + 1;
  PetscBool rotate = PETSC_TRUE;
  PetscCall(PetscOptionsGetBool(nullptr, nullptr, "-hexcut_composite_rotate", &rotate, nullptr));
  options.rotate_composite = rotate;
  PetscBool midpoint = PETSC_TRUE;
  PetscCall(
      PetscOptionsGetBool(nullptr, nullptr, "-hexcut_composite_midpoint", &midpoint, nullptr));
  composite_midpoint_ = midpoint;
  mg_ = std::make_unique<multigrid::Multigrid>(comm_, model_.lattice, model_.copies,
                                               model_.partition, model_.layout, model_.dm, options);
  if (hexcut_pc) PetscCall(multigrid::pc_set_multigrid(pc, mg_.get()));
  // After a cut, the elements it left whole keep their blocks and data (Wu rebuilds "only
  // the few affected elements"); -hexcut_composite_carry false rebuilds all, for comparison.
  PetscBool reuse = PETSC_TRUE;
  PetscCall(PetscOptionsGetBool(nullptr, nullptr, "-hexcut_composite_carry", &reuse, nullptr));
  if (carry && reuse) {
    mg_->carry_composite_blocks(std::move(carry->blocks));
    carried_elements_ = std::move(carry->elements);
  }
  // One rotation per composite element (corotational runs): the fine cells of an element
  // form a rotation group (assembly::cell_rotations), so the Galerkin blocks of the rotated
  // fine cells are the element's block rotated, R^ K~ R^T.
  model_.cells.rotation_group = mg_->composite_elements();
  model_.cells.num_rotation_groups = l > 0 ? std::int32_t(mg_->level(l).layout().cells.size()) : 0;
  PetscCall(KSPSetDM(ksp_, mg_->dm(l)));
  PetscCall(KSPSetDMActive(ksp_, PETSC_FALSE));
  PetscCall(composite_positions(*mg_, &composite_coordinates_));
  PetscFunctionReturn(0);
}

std::vector<double> Simulation::composite_element_ids() const {
  if (!composite() || !mg_) return {};
  const int l = mg_->first_level();
  const auto& cells = mg_->level(l).layout().cells;
  const auto& element = mg_->composite_elements();
  std::vector<double> ids(model_.layout.cells.size());
  for (std::size_t e = 0; e < ids.size(); ++e)
    ids[e] = l == 0 ? double(model_.layout.cells[e]) : double(cells[std::size_t(element[e])]);
  return ids;
}

CompositeCarry Simulation::composite_carry() {
  CompositeCarry c;
  if (!composite() || !mg_) return c;
  c.blocks = mg_->composite_blocks();
  c.elements = std::move(composite_elements_);
  return c;
}

bool Simulation::uses_multigrid() const {
  return hexcut_pc_;
}

bool Simulation::composite() const {
  return deck_.discretization.type == deck::Discretization::Type::composite;
}

Simulation::~Simulation() {
  KSPDestroy(&ksp_);
  MatDestroy(&A_);
  VecDestroy(&composite_u_);
  VecDestroy(&composite_state_);
  VecDestroy(&composite_velocity_);
  VecDestroy(&composite_coordinates_);
}

PetscErrorCode Simulation::solve_system(Vec b, Vec u, solve::SolveRecord* rec, bool guess,
                                        Vec composite_add) {
  PetscFunctionBeginUser;
  EventScope scope(events().solve);
  if (!composite()) {
    PetscCall(solve::solve(ksp_, b, u, rec));
    PetscFunctionReturn(0);
  }
  const int l = mg_->first_level();
  if (!composite_u_) {
    PetscCall(DMCreateGlobalVector(mg_->dm(l), &composite_u_));
    PetscCall(VecSet(composite_u_, 0.0));
  }
  if (!guess) PetscCall(VecSet(composite_u_, 0.0));
  Vec bc;
  PetscCall(DMGetGlobalVector(mg_->dm(l), &bc));
  double deviation = 0.0;
  PetscCall(composite_rhs(*mg_, b, bc, composite_u_, &deviation));
  if (composite_add) {  // on the free composite DOFs only
    Vec t;
    PetscCall(DMGetGlobalVector(mg_->dm(l), &t));
    PetscCall(VecPointwiseMult(t, composite_add, mg_->mask(l)));
    PetscCall(VecAXPY(bc, 1.0, t));
    PetscCall(DMRestoreGlobalVector(mg_->dm(l), &t));
  }
  if (deviation > 1e-3 && !deviation_warned_) {
    // Prescribed values that vary over a composite element cannot be met exactly.
    PetscCall(PetscPrintf(comm_,
                          "%swarning: composite elements meet the prescribed displacements "
                          "only to %.2g of their largest value (they vary within composite "
                          "elements; doc/user-guide.md, \"Discretization\")\n",
                          deck_.discretization.where.prefix().c_str(), deviation));
    deviation_warned_ = true;
  }
  PetscCall(solve::solve(ksp_, bc, composite_u_, rec));
  PetscCall(DMRestoreGlobalVector(mg_->dm(l), &bc));
  PetscCall(prolong_composite(*mg_, composite_u_, u));
  PetscFunctionReturn(0);
}

PetscErrorCode Simulation::composite_state(const State& s, bool* known) {
  PetscFunctionBeginUser;
  // u~_n, v~_n with u_n = I u~_n, v_n = I v~_n: those the last step of this simulation left
  // (checked on the numbers, so that any other change of the state is noticed), else the
  // preimages of u_n and v_n (after a set-up, a cut or a restart: the state is in range(I),
  // doc/theory.md "Composite elements"). Not known when they do not interpolate the state.
  *known = false;
  const int l = mg_->first_level();
  ScratchVec t;
  PetscCall(borrow(model_.dm, t));
  // The scale of each check: |u|, and for v, |v| + (2/dt)|u| (v~ is updated from
  // differences of u~, so its round-off is that of u's, which matters when the body is
  // nearly at rest).
  PetscReal un = 0, vn = 0;
  PetscCall(VecNorm(s.u, NORM_INFINITY, &un));
  PetscCall(VecNorm(s.v, NORM_INFINITY, &vn));
  const double scale[2] = {un, vn + 2.0 * un / deck_.analysis.dt};
  if (composite_state_ && composite_state_step_ == s.step) {
    bool same = true;
    const Vec xc[2] = {composite_state_, composite_velocity_}, x[2] = {s.u, s.v};
    for (int k = 0; k < 2; ++k) {
      PetscCall(prolong_composite(*mg_, xc[k], t));
      PetscCall(VecAXPY(t, -1.0, x[k]));
      PetscReal d = 0;
      PetscCall(VecNorm(t, NORM_INFINITY, &d));
      same = same && d <= 1e-12 * scale[k];
    }
    if (same) {
      *known = true;
      PetscFunctionReturn(0);
    }
  }
  if (!composite_state_) {
    PetscCall(DMCreateGlobalVector(mg_->dm(l), &composite_state_));
    PetscCall(VecDuplicate(composite_state_, &composite_velocity_));
  }
  if (!composite_preimage_) composite_preimage_ = std::make_unique<CompositePreimage>(*mg_);
  double mu = 0, mv = 0;
  PetscCall(composite_preimage_->solve(s.u, composite_state_, &mu));
  PetscCall(composite_preimage_->solve(s.v, composite_velocity_, &mv));
  *known = mu <= 1e-10 * scale[0] && mv <= 1e-10 * scale[1];
  composite_state_step_ = *known ? s.step : -1;
  PetscFunctionReturn(0);
}

bool Simulation::corotational() const {
  return deck_.analysis.formulation == deck::Analysis::Formulation::corotational;
}

PetscErrorCode Simulation::assemble(const assembly::OperatorWeights& w) {
  PetscFunctionBeginUser;
  EventScope scope(events().assembly);
  if (mg_) {
    // Matrix-free: the fine operator reads the cell data; the hierarchy is rebuilt. A
    // singular point-block diagonal is a solver failure (exit 3).
    const PetscErrorCode ierr = mg_->update(model_.cells, w, model_.boundary.constraints.rows);
    if (ierr == PETSC_ERR_MAT_LU_ZRPVT)
      SETERRQ(comm_, PETSC_ERR_NOT_CONVERGED, "%s",
              "the multigrid's set-up failed: a singular 3x3 diagonal block");
    PetscCall(ierr);
    if (hexcut_pc_ || !composite()) {
      PetscCall(KSPSetOperators(ksp_, mg_->fine_operator(), mg_->fine_operator()));
    } else {
      // The assembled composite system (identity rows on fixed composite DOFs).
      PetscCall(
          solve::set_operator(ksp_, deck_.solver, mg_->coarsest_matrix(), composite_coordinates_));
    }
    if (composite() && !supports_checked_) {
      PetscCall(check_composite_supports(comm_, *mg_, deck_));
      supports_checked_ = true;
    }
  } else {
    PetscCall(assembly::assemble_constrained_matrix(model_.dm, model_.layout, model_.cells, w,
                                                    model_.boundary.constraints, A_));
    PetscCall(solve::set_operator(ksp_, deck_.solver, A_, model_.coordinates));
  }
  assembled_ = true;
  PetscFunctionReturn(0);
}

namespace {

/// Whether `kept` was computed at `u` as it is now.
PetscErrorCode kept_at(const std::vector<double>& R, PetscObjectId id, PetscObjectState state,
                       Vec u, bool* same) {
  PetscFunctionBeginUser;
  PetscObjectId uid;
  PetscObjectState ustate;
  PetscCall(PetscObjectGetId((PetscObject)u, &uid));
  PetscCall(PetscObjectStateGet((PetscObject)u, &ustate));
  *same = !R.empty() && uid == id && ustate == state;
  PetscFunctionReturn(0);
}

}  // namespace

PetscErrorCode Simulation::refresh_rotations(Vec u) {
  PetscFunctionBeginUser;
  auto& kept = kept_rotations_;
  bool same = false;
  PetscCall(kept_at(kept.R, kept.id, kept.state, u, &same));
  if (same && kept.R.size() == 9 * model_.layout.cells.size()) {
    // The cells' old rotations become the buffer of the next kept ones.
    model_.cells.identity_rotations = false;
    model_.cells.rotation.swap(kept.R);
    kept.R.clear();
    PetscFunctionReturn(0);
  }
  assembly::LocalValues ul;
  PetscCall(ul.get(model_.dm, u));
  assembly::update_rotations(model_.layout, ul.data(), model_.cells);
  PetscFunctionReturn(0);
}

PetscErrorCode Simulation::static_step(State& s, const OnSolve& on_solve) {
  PetscFunctionBeginUser;
  const auto& an = deck_.analysis;
  const int n = an.load_steps;
  const assembly::OperatorWeights w{1.0, 0.0, true};
  const double t_eval = 1.0;  // time functions at the end of the load
  ScratchVec b, u_new;
  PetscCall(borrow(model_.dm, b, u_new));
  if (!corotational()) assembly::set_identity_rotations(model_.cells);
  const int step = int(s.step) + 1;
  const double lf = double(step) / n;
  bool converged = false;
  double change = 0.0;
  const int max_iter = corotational() ? an.max_iterations : 1;
  for (int k = 0; k < max_iter && !converged; ++k) {
    if (corotational()) PetscCall(refresh_rotations(s.u));
    if (corotational() || !assembled_) PetscCall(assemble(w));
    PetscCall(assembly::assemble_loads(model_.dm, model_.layout, model_.cells, model_.boundary,
                                       t_eval, lf, b));
    if (corotational())
      PetscCall(assembly::add_corotational_rhs(model_.dm, model_.layout, model_.cells, 1.0, b));
    PetscCall(assembly::constrain_rhs(model_.dm, model_.layout, model_.cells, w,
                                      model_.boundary.constraints, t_eval, lf, b));
    PetscCall(VecCopy(s.u, u_new));
    solve::SolveRecord rec;
    PetscCall(solve_system(b, u_new, &rec));
    s.time = lf;
    s.step = step;
    if (on_solve) on_solve(s, rec);
    if (corotational()) {
      // Fixed-point convergence test on the displacement update.
      PetscReal du = 0, un = 0;
      PetscCall(VecAXPY(s.u, -1.0, u_new));
      PetscCall(VecNorm(s.u, NORM_2, &du));
      PetscCall(VecNorm(u_new, NORM_2, &un));
      change = un > 0 ? du / un : du;
      converged = change <= an.tolerance;
    } else {
      converged = true;
    }
    PetscCall(VecCopy(u_new, s.u));
  }
  if (!converged) {
    const std::string msg =
        "corotational fixed-point iteration did not converge in load step " + std::to_string(step) +
        " of " + std::to_string(n) + ": relative update " + std::to_string(change) +
        " > tolerance " + std::to_string(an.tolerance) + " after " +
        std::to_string(an.max_iterations) + " iterations (try more analysis.load_steps)";
    SETERRQ(comm_, PETSC_ERR_NOT_CONVERGED, "%s", msg.c_str());
  }
  PetscFunctionReturn(0);
}

PetscErrorCode Simulation::initial_acceleration(State& s) {
  PetscFunctionBeginUser;
  // M a0 = f(t0) + b^(u0) - K u0: solved with CG + Jacobi on the (constrained) mass matrix,
  // which is well conditioned, so this is cheap even for consistent mass.
  const bool lumped = deck_.analysis.mass == deck::Analysis::Mass::lumped;
  const assembly::OperatorWeights mass_only{0.0, 1.0, lumped};
  ScratchVec r, Ku;
  PetscCall(borrow(model_.dm, r, Ku));
  if (corotational()) PetscCall(refresh_rotations(s.u));
  PetscCall(assembly::assemble_loads(model_.dm, model_.layout, model_.cells, model_.boundary,
                                     s.time, 1.0, r));
  if (corotational())
    PetscCall(assembly::add_corotational_rhs(model_.dm, model_.layout, model_.cells, 1.0, r));
  PetscCall(assembly::apply(model_.dm, model_.layout, model_.cells, {1.0, 0.0, true}, s.u, Ku));
  PetscCall(VecAXPY(r, -1.0, Ku));
  if (composite()) {
    // M~ a~0 = I^T r with the Galerkin mass, by the run's own solver; prescribed rows 0.
    PetscCall(assembly::set_prescribed_values(model_.boundary.constraints, s.time, 0.0, r));
    PetscCall(assemble(mass_only));
    solve::SolveRecord rec;
    PetscCall(solve_system(r, s.a, &rec, false));
    PetscCall(VecSet(composite_u_, 0.0));  // not a displacement: no initial guess for the step
    assembled_ = false;                    // the step's operator is assembled at the first step
    PetscFunctionReturn(0);
  }
  Mat M;
  KSP k;
  PetscCall(assembly::create_matrix(comm_, model_.copies, model_.layout, &M));
  PetscCall(assembly::assemble_constrained_matrix(model_.dm, model_.layout, model_.cells, mass_only,
                                                  model_.boundary.constraints, M));
  // Prescribed rows: zero initial acceleration.
  for (PetscInt row : model_.boundary.constraints.rows)
    PetscCall(VecSetValue(r, row, 0.0, INSERT_VALUES));
  PetscCall(VecAssemblyBegin(r));
  PetscCall(VecAssemblyEnd(r));
  PetscCall(KSPCreate(comm_, &k));
  PetscCall(KSPSetOperators(k, M, M));
  PetscCall(KSPSetType(k, KSPCG));
  PC pc;
  PetscCall(KSPGetPC(k, &pc));
  PetscCall(PCSetType(pc, PCJACOBI));
  PetscCall(KSPSetTolerances(k, 1e-14, 1e-300, PETSC_DEFAULT, 10000));
  PetscCall(KSPSetOptionsPrefix(k, "mass_"));
  PetscCall(KSPSetFromOptions(k));
  PetscCall(KSPSolve(k, r, s.a));
  KSPConvergedReason reason;
  PetscCall(KSPGetConvergedReason(k, &reason));
  PetscCall(KSPDestroy(&k));
  PetscCall(MatDestroy(&M));
  if (reason < 0) {
    const std::string msg =
        "initial acceleration (mass solve) failed: " + solve::reason_string(reason);
    SETERRQ(comm_, PETSC_ERR_NOT_CONVERGED, "%s", msg.c_str());
  }
  PetscFunctionReturn(0);
}

PetscErrorCode Simulation::linearized_step(State& s, Vec u_new, solve::SolveRecord* rec) {
  PetscFunctionBeginUser;
  const auto& an = deck_.analysis;
  const auto c = element::newmark_coefficients(an.dt);
  const bool lumped = an.mass == deck::Analysis::Mass::lumped;
  // A = a0 M + a1 D + K^ with D = alpha1 M + alpha2 K^.
  const assembly::OperatorWeights w{1.0 + c.a1 * an.rayleigh_stiffness,
                                    c.a0 + c.a1 * an.rayleigh_mass, lumped};
  if (corotational()) PetscCall(refresh_rotations(s.u));
  if (corotational() || !assembled_) PetscCall(assemble(w));
  const double t1 = double(s.step + 1) * an.dt;
  ScratchVec b, hist, tmp;
  PetscCall(borrow(model_.dm, b, hist, tmp));
  PetscCall(assembly::assemble_loads(model_.dm, model_.layout, model_.cells, model_.boundary, t1,
                                     1.0, b));
  if (corotational())
    PetscCall(assembly::add_corotational_rhs(model_.dm, model_.layout, model_.cells, 1.0, b));
  // + M (a0 u + a2 v + a)
  PetscCall(VecAXPBYPCZ(hist, c.a0, c.a2, 0.0, s.u, s.v));
  PetscCall(VecAXPY(hist, 1.0, s.a));
  PetscCall(assembly::apply(model_.dm, model_.layout, model_.cells, {0.0, 1.0, lumped}, hist, tmp));
  PetscCall(VecAXPY(b, 1.0, tmp));
  // + D (a1 u + v)
  if (an.rayleigh_mass != 0.0 || an.rayleigh_stiffness != 0.0) {
    PetscCall(VecAXPBYPCZ(hist, c.a1, 1.0, 0.0, s.u, s.v));
    PetscCall(assembly::apply(model_.dm, model_.layout, model_.cells,
                              {an.rayleigh_stiffness, an.rayleigh_mass, lumped}, hist, tmp));
    PetscCall(VecAXPY(b, 1.0, tmp));
  }
  PetscCall(assembly::constrain_rhs(model_.dm, model_.layout, model_.cells, w,
                                    model_.boundary.constraints, t1, 1.0, b));
  PetscCall(VecCopy(s.u, u_new));
  PetscCall(solve_system(b, u_new, rec));
  PetscFunctionReturn(0);
}

PetscErrorCode Simulation::midpoint_step(const State& s, Vec load_sum, Vec u_new, Vec fbar,
                                         double* fbar_work, solve::SolveRecord* total) {
  PetscFunctionBeginUser;
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
  ScratchVec fixed, b, r, du, u_prev;
  PetscCall(borrow(model_.dm, fixed, b, r, du, u_prev));
  // The part of r that does not change within the step: f(t_n) + f(t_n+1) + a0 dt M v_n.
  PetscCall(assembly::apply(model_.dm, model_.layout, model_.cells, {0.0, c.a0 * an.dt, lumped},
                            s.v, fixed));
  PetscCall(VecAXPY(fixed, 1.0, load_sum));
  // Predictor: constant velocity, and the prescribed values at t_n+1.
  PetscCall(VecWAXPY(u_new, an.dt, s.v, s.u));
  PetscCall(assembly::set_prescribed_values(model_.boundary.constraints, t1, 1.0, u_new));
  *total = solve::SolveRecord{};
  double change = 0.0, previous_change = 0.0, energy[2];
  solves_ = 0;
  std::vector<double> frozen_rotations;  // composite runs: those of the solver's operator
  // Composite runs work with u~_n, v~_n (composite_state): the predictor is u~_n + dt v~_n
  // with g~(t_n+1) on the fixed composite DOFs, so that every iterate is u = I u~ and the
  // mid-point force can be computed on the composite level, fc = -2 I^T fbar: the same
  // numbers for a fraction of the work (analysis/composite_midpoint.hpp).
  bool known = false, composite_force = false;
  if (composite() && mg_->first_level() > 0) {
    const int l = mg_->first_level();
    PetscCall(composite_state(s, &known));
    if (known) {
      if (!composite_u_) PetscCall(DMCreateGlobalVector(mg_->dm(l), &composite_u_));
      ScratchVec g;
      PetscCall(g.get(mg_->dm(l)));
      PetscCall(composite_prescribed(*mg_, u_new, g));
      PetscCall(VecWAXPY(composite_u_, an.dt, composite_velocity_, composite_state_));
      PetscCall(VecPointwiseMult(composite_u_, composite_u_, mg_->mask(l)));
      PetscCall(VecAXPY(composite_u_, 1.0, g));
      PetscCall(prolong_composite(*mg_, composite_u_, u_new));
    }
    composite_force = known && composite_midpoint_;
    if (composite_force && !composite_elements_) {
      composite_elements_ = std::make_unique<CompositeElements>(
          build_composite_elements(*mg_, model_.cells, carried_elements_.get()));
      carried_elements_.reset();
    }
  }
  ScratchVec fc;  // composite_force: -2 I^T fbar, in place of fbar
  if (composite_force) PetscCall(fc.get(mg_->dm(mg_->first_level())));
  if (!composite_force) {
    EventScope scope(events().energy);
    PetscCall(
        assembly::corotated_displacements(model_.dm, model_.layout, model_.cells, s.u, &start_d_));
  }
  for (;;) {
    {
      EventScope scope(events().energy);
      if (composite_force) {
        PetscCall(composite_midpoint_force(*mg_, *composite_elements_, composite_state_,
                                           composite_u_, fc, model_.cells, energy));
        PetscCall(VecScale(fc, -2.0));
      } else {
        PetscCall(assembly::assemble_midpoint_force(model_.dm, model_.layout, model_.cells,
                                                    start_d_, s.u, u_new, fbar, energy));
      }
    }
    // The operator (and preconditioner) of the predictor's mid-point serves the step: b
    // below uses that same operator, so the iteration still converges to r = 0, and a
    // further iteration costs a solve, not an assembly and preconditioner set-up. (The
    // matrix-free gmg operator of hexahedra reads the current rotations; its hierarchy
    // stays.) A frozen operator (composite elements, assembled solvers) is re-formed at
    // the iterate's rotations when an update shrank by less than half: the rotations have
    // moved far from the predictor's (small composite elements that turn fast after a
    // cut), and the iteration would creep (bunny_cuts at composite level 1, dt 5 ms:
    // contraction 0.87 per iteration and no convergence at t = 0.07 s without it).
    const bool frozen = composite() || !hexcut_pc_;
    if (solves_ == 0 || (frozen && solves_ >= 2 && change > 0.5 * previous_change)) {
      PetscCall(assemble(w));
      // The composite operator is built from the rotations of this moment; the fine one
      // (level 0 with gmg) reads the iterate's rotations at each application.
      if (composite() && (mg_->first_level() > 0 || !hexcut_pc_))
        frozen_rotations = model_.cells.rotation;
    }
    // r = fixed - 2 f_alg - (a0 + a1 alpha1) M du - a1 alpha2 K^ du; no equation on the
    // prescribed rows.
    PetscCall(VecWAXPY(du, -1.0, s.u, u_new));
    PetscCall(assembly::apply(model_.dm, model_.layout, model_.cells, inertia, du, r));
    if (composite_force)
      PetscCall(VecAYPX(r, -1.0, fixed));  // -2 I^T fbar is added on the composite level
    else
      PetscCall(VecAXPBYPCZ(r, 1.0, -2.0, -1.0, fixed, fbar));
    PetscCall(assembly::set_prescribed_values(model_.boundary.constraints, t1, 0.0, r));
    // b = A u_k + r with the solver's own operator (constrained: identity rows); composite
    // runs: the fine operator with the rotations the composite one was built from (its
    // Galerkin product), not those of the iterate, or the iteration would converge to
    // (A - A_k) u = r.
    if (composite() && !frozen_rotations.empty()) {
      std::swap(model_.cells.rotation, frozen_rotations);
      const PetscErrorCode ierr = mg_->apply_level(0, u_new, b);
      std::swap(model_.cells.rotation, frozen_rotations);
      PetscCall(ierr);
    } else if (composite()) {
      PetscCall(mg_->apply_level(0, u_new, b));
    } else {
      Mat A;
      PetscCall(KSPGetOperators(ksp_, &A, nullptr));
      PetscCall(MatMult(A, u_new, b));
    }
    PetscCall(VecAXPY(b, 1.0, r));
    PetscCall(assembly::set_prescribed_values(model_.boundary.constraints, t1, 1.0, b));
    // Converged when the last update was below the tolerance, or when the residual is as
    // small as a linear solve leaves it (||b - A u|| <= rtol ||b||; twice that, so that a
    // solve that just met it counts): below that, updates are the linear solver's noise,
    // which the relative change could not tell from progress.
    // Composite runs: the composite residual I_f^T r (the fine one does not vanish).
    PetscReal rn = 0, bn = 0;
    if (composite()) {
      Vec add = composite_force ? Vec(fc) : nullptr;
      PetscCall(composite_norm(*mg_, r, &rn, add));
      PetscCall(composite_norm(*mg_, b, &bn, add));
    } else {
      PetscCall(VecNorm(r, NORM_2, &rn));
      PetscCall(VecNorm(b, NORM_2, &bn));
    }
    if ((solves_ > 0 && change <= an.tolerance) || rn <= 2 * deck_.solver.rtol * bn) break;
    if (solves_ == an.max_iterations) {
      char msg[400];
      std::snprintf(msg, sizeof msg,
                    "corotational step %lld (t = %g s) did not converge: relative change %.3g > "
                    "analysis.tolerance %g and residual %.3g > 2 solver.rtol after "
                    "analysis.max_iterations = %d iterations (try a smaller analysis.dt)",
                    (long long)(s.step + 1), t1, change, an.tolerance, rn / bn, an.max_iterations);
      SETERRQ(comm_, PETSC_ERR_NOT_CONVERGED, "%s", msg);
    }
    PetscCall(VecCopy(u_new, u_prev));
    solve::SolveRecord rec;
    PetscCall(solve_system(b, u_new, &rec, true, composite_force ? Vec(fc) : nullptr));
    ++solves_;
    total->iterations += rec.iterations;
    total->setup_seconds += rec.setup_seconds;
    total->solve_seconds += rec.solve_seconds;
    total->residual = rec.residual;
    total->residual_norm = rec.residual_norm;
    total->reason = rec.reason;
    PetscReal dk = 0, dn = 0;
    PetscCall(VecAXPY(u_prev, -1.0, u_new));
    PetscCall(VecNorm(u_prev, NORM_2, &dk));
    PetscCall(VecWAXPY(du, -1.0, s.u, u_new));
    PetscCall(VecNorm(du, NORM_2, &dn));
    previous_change = change;
    change = dn > 0 ? dk / dn : dk;
  }
  // fbar (or fc) and the energies are those of the converged u_n+1.
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, energy, 2, MPI_DOUBLE, MPI_SUM, comm_));
  *fbar_work = NAN;
  if (known) {
    // u_n+1 = I u~_n+1 and v_n+1 = I v~_n+1 (the Newmark update is linear): the state the
    // next step starts from.
    // v~_n+1 = (2/dt)(u~_n+1 - u~_n) - v~_n
    PetscCall(VecAYPX(composite_state_, -1.0, composite_u_));  // du~
    if (composite_force) {  // du . fbar = du~ . I^T fbar = -1/2 du~ . fc
      PetscScalar w;
      PetscCall(VecDot(composite_state_, fc, &w));
      *fbar_work = -0.5 * w;
    }
    PetscCall(VecAXPBY(composite_velocity_, 2.0 / an.dt, -1.0, composite_state_));
    PetscCall(VecCopy(composite_u_, composite_state_));
    composite_state_step_ = s.step + 1;
  }
  energy_.strain0 = energy[0];
  energy_.strain1 = energy[1];
  PetscFunctionReturn(0);
}

PetscErrorCode Simulation::newmark_step(State& s, solve::SolveRecord* record) {
  PetscFunctionBeginUser;
  const auto& an = deck_.analysis;
  const double t0 = double(s.step) * an.dt;
  // t = n dt, not a running sum: summing dt drifts (0.1 + 0.1 + ... = 2.9999999999999583)
  // and then a time that a user asks for (ParaView, a cut time) falls on the step before.
  const double t1 = double(s.step + 1) * an.dt;
  ScratchVec u0, v0, loads, tmp, u_new, fbar;
  PetscCall(borrow(model_.dm, u0, v0, loads, tmp, u_new, fbar));
  PetscCall(VecCopy(s.u, u0));
  PetscCall(VecCopy(s.v, v0));
  PetscCall(assembly::assemble_loads(model_.dm, model_.layout, model_.cells, model_.boundary, t0,
                                     1.0, loads));
  PetscCall(assembly::assemble_loads(model_.dm, model_.layout, model_.cells, model_.boundary, t1,
                                     1.0, tmp));
  PetscCall(VecAXPY(loads, 1.0, tmp));
  const bool midpoint = corotational() && an.rotations == deck::Analysis::Rotations::iterated;
  solve::SolveRecord rec;
  double fbar_work = NAN;
  if (midpoint) {
    PetscCall(midpoint_step(s, loads, u_new, fbar, &fbar_work, &rec));
  } else {
    PetscCall(linearized_step(s, u_new, &rec));
    solves_ = 1;
  }
  // v, a from the consistent Newmark update (in place).
  PetscInt n;
  PetscCall(VecGetLocalSize(s.u, &n));
  const PetscScalar *uo, *un;
  PetscScalar *v, *a;
  PetscCall(VecGetArrayRead(s.u, &uo));
  PetscCall(VecGetArrayRead(u_new, &un));
  PetscCall(VecGetArray(s.v, &v));
  PetscCall(VecGetArray(s.a, &a));
  element::newmark_update(int(n), an.dt, uo, v, a, un, v, a);
  PetscCall(VecRestoreArray(s.a, &a));
  PetscCall(VecRestoreArray(s.v, &v));
  PetscCall(VecRestoreArrayRead(u_new, &un));
  PetscCall(VecRestoreArrayRead(s.u, &uo));
  PetscCall(VecCopy(u_new, s.u));
  s.time = t1;
  s.step += 1;
  EventScope scope(events().energy);
  if (midpoint) {
    PetscCall(account_energy(u0, v0, s, loads, fbar, energy_.strain0, energy_.strain1, fbar_work));
  } else {
    double strain0 = cached_strain_, strain1 = 0.0;
    if (cached_step_ != s.step - 1) PetscCall(strain_energy(u0, &strain0));
    PetscCall(strain_energy(s.u, &strain1));
    PetscCall(account_energy(u0, v0, s, loads, nullptr, strain0, strain1));
  }
  if (record) *record = rec;
  PetscFunctionReturn(0);
}

PetscErrorCode Simulation::internal_force(Vec u, Vec f) {
  PetscFunctionBeginUser;
  if (corotational()) PetscCall(refresh_rotations(u));
  PetscCall(assembly::apply(model_.dm, model_.layout, model_.cells, {1.0, 0.0, true}, u, f));
  if (corotational()) {
    ScratchVec r;
    PetscCall(r.get(model_.dm));
    PetscCall(VecSet(r, 0.0));
    PetscCall(assembly::add_corotational_rhs(model_.dm, model_.layout, model_.cells, 1.0, r));
    PetscCall(VecAXPY(f, -1.0, r));
  }
  PetscFunctionReturn(0);
}

PetscErrorCode Simulation::account_energy(Vec u0, Vec v0, const State& s, Vec load_sum, Vec fbar,
                                          double strain0, double strain1, double fbar_work) {
  PetscFunctionBeginUser;
  const auto& an = deck_.analysis;
  const bool lumped = an.mass == deck::Analysis::Mass::lumped;
  StepEnergy& e = energy_;
  e = StepEnergy{};
  if (cached_step_ == s.step - 1)
    e.kinetic0 = cached_kinetic_;
  else
    PetscCall(kinetic(v0, &e.kinetic0));
  PetscCall(kinetic(s.v, &e.kinetic1));
  e.strain0 = strain0;
  e.strain1 = strain1;
  cached_step_ = s.step;
  cached_kinetic_ = e.kinetic1;
  cached_strain_ = e.strain1;
  ScratchVec du, Ddu;
  PetscCall(borrow(model_.dm, du, Ddu));
  PetscCall(VecWAXPY(du, -1.0, u0, s.u));
  PetscScalar x;
  PetscCall(VecDot(du, load_sum, &x));
  e.external_work = 0.5 * x;
  PetscCall(VecSet(Ddu, 0.0));
  if (an.rayleigh_mass != 0.0 || an.rayleigh_stiffness != 0.0) {
    // D with the rotations the step's operator used.
    PetscCall(assembly::apply(model_.dm, model_.layout, model_.cells,
                              {an.rayleigh_stiffness, an.rayleigh_mass, lumped}, du, Ddu));
    PetscCall(VecDot(du, Ddu, &x));
    e.dissipated = x / an.dt;
  }
  // Supports do work only where they move: reactions rho = M a_mean + D v_mean + f_mean
  // - f_ext,mean on the prescribed DOFs (the equation of motion with the reaction).
  const auto& rows = model_.boundary.constraints.rows;
  const PetscScalar* d;
  PetscCall(VecGetArrayRead(du, &d));
  PetscInt first;
  PetscCall(VecGetOwnershipRange(du, &first, nullptr));
  int moving = 0;
  for (PetscInt r : rows) moving |= d[r - first] != 0.0;
  PetscCall(VecRestoreArrayRead(du, &d));
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, &moving, 1, MPI_INT, MPI_LOR, comm_));
  if (moving) {
    ScratchVec rho, tmp;
    PetscCall(borrow(model_.dm, rho, tmp));
    PetscCall(VecWAXPY(tmp, -1.0, v0, s.v));
    PetscCall(assembly::apply(model_.dm, model_.layout, model_.cells, {0.0, 1.0 / an.dt, lumped},
                              tmp, rho));
    PetscCall(VecAXPBYPCZ(rho, 1.0 / an.dt, -0.5, 1.0, Ddu, load_sum));
    if (!std::isnan(fbar_work)) {
      // du . fbar is fbar_work (the composite level computed fbar); added below.
    } else if (fbar) {
      PetscCall(VecAXPY(rho, 1.0, fbar));
    } else {
      PetscCall(internal_force(u0, tmp));
      PetscCall(VecAXPY(rho, 0.5, tmp));
      PetscCall(internal_force(s.u, tmp));
      PetscCall(VecAXPY(rho, 0.5, tmp));
    }
    if (composite()) {
      // The composite equations hold on the free composite DOFs only, so rho does not
      // vanish on free fine rows; du = I dv~ and I_f^T rho = 0 make du . rho the work of
      // the fixed composite DOFs, the composite supports' reactions.
      PetscScalar w;
      PetscCall(VecDot(du, rho, &w));
      e.support_work = w + (std::isnan(fbar_work) ? 0.0 : fbar_work);
    } else {
      const PetscScalar* p;
      PetscCall(VecGetArrayRead(rho, &p));
      PetscCall(VecGetArrayRead(du, &d));
      double w = 0.0;
      for (PetscInt r : rows) w += d[r - first] * p[r - first];
      PetscCall(VecRestoreArrayRead(du, &d));
      PetscCall(VecRestoreArrayRead(rho, &p));
      PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, &w, 1, MPI_DOUBLE, MPI_SUM, comm_));
      e.support_work = w;
    }
  }
  PetscFunctionReturn(0);
}

PetscErrorCode Simulation::kinetic(Vec v, double* energy) {
  PetscFunctionBeginUser;
  const bool lumped = deck_.analysis.mass == deck::Analysis::Mass::lumped;
  ScratchVec Mv;
  PetscCall(Mv.get(model_.dm));
  PetscCall(assembly::apply(model_.dm, model_.layout, model_.cells, {0.0, 1.0, lumped}, v, Mv));
  PetscScalar e;
  PetscCall(VecDot(v, Mv, &e));
  *energy = 0.5 * e;
  PetscFunctionReturn(0);
}

PetscErrorCode Simulation::strain_energy(Vec u, double* energy) {
  PetscFunctionBeginUser;
  double w = 0.0;
  {
    assembly::LocalValues ul;
    PetscCall(ul.get(model_.dm, u));
    const double* R = nullptr;
    if (corotational()) {
      auto& kept = kept_rotations_;
      kept.R.resize(9 * model_.layout.cells.size());
      assembly::cell_rotations(model_.layout, model_.cells, ul.data(), kept.R.data());
      PetscCall(PetscObjectGetId((PetscObject)u, &kept.id));
      PetscCall(PetscObjectStateGet((PetscObject)u, &kept.state));
      R = kept.R.data();
    }
    w = assembly::strain_energy_local(model_.layout, model_.cells, ul.data(), R);
  }
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, &w, 1, MPI_DOUBLE, MPI_SUM, comm_));
  *energy = w;
  PetscFunctionReturn(0);
}

PetscErrorCode Simulation::kinetic_energy(const State& s, double* energy) {
  return kinetic(s.v, energy);
}

PetscErrorCode Simulation::elastic_energy(const State& s, double* energy) {
  return strain_energy(s.u, energy);
}

}  // namespace hexcut::analysis
