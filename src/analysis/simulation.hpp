// The analyses (doc/theory.md, "Static analysis", "Dynamics: Newmark", "Mid-point corotational
// step"): static (linear, or corotational by fixed-point iteration per load step) and dynamic
// (Newmark beta = 1/4, gamma = 1/2, Rayleigh damping, lumped or consistent mass, linear or
// corotational).
#pragma once

#include <petscksp.h>

#include <cmath>
#include <functional>
#include <memory>

#include "analysis/composite.hpp"
#include "analysis/composite_midpoint.hpp"
#include "analysis/energy.hpp"
#include "analysis/model.hpp"
#include "analysis/state.hpp"
#include "multigrid/gmg.hpp"
#include "solve/linear_solver.hpp"

namespace hexcut::analysis {

/// Called after every linear solve (solver history, progress).
using OnSolve = std::function<void(const State&, const solve::SolveRecord&)>;

/// What a composite Simulation hands to the next one after a cut (Driver::follow_topology):
/// the composite blocks and the elements' mid-point data, reused for the elements the cut
/// left whole (their fine cells are the same; doc/theory.md, "Composite elements").
struct CompositeCarry {
  multigrid::CompositeBlocks blocks;
  std::unique_ptr<CompositeElements> elements;  // null when the run never built them
};

/// The physics of one step on one topology: owns the system matrix (or the multigrid) and the
/// KSP. The steps are taken by analysis::Driver (analysis/driver.hpp), which replaces the
/// Simulation when the topology changes. PETSc-style: every member that does PETSc work
/// returns a PetscErrorCode; a solve that fails is PETSC_ERR_NOT_CONVERGED with hexcut's
/// message (common/petsc_check.hpp).
class Simulation {
 public:
  /// Creates the Simulation of `model` (both must outlive it): the solver, whose PETSc
  /// options are parsed here (an error in them is PETSC_ERR_USER_INPUT), and the multigrid
  /// hierarchy or the matrix.
  /// `carry` (may be null; composite runs after a cut): the previous topology's
  /// composite_carry(), used unless -hexcut_composite_carry false.
  static PetscErrorCode create(MPI_Comm comm, Model& model, const deck::Deck& deck,
                               std::unique_ptr<Simulation>* sim, CompositeCarry* carry = nullptr);
  ~Simulation();
  Simulation(const Simulation&) = delete;
  Simulation& operator=(const Simulation&) = delete;

  /// Load step state.step + 1 of n of a static analysis (pseudo-time s/n; time functions at
  /// t = 1, loads and prescribed displacements scaled by s/n). Linear: one solve.
  /// Corotational: fixed-point iteration, rotations from the last iterate, until
  /// ||u_k+1 - u_k|| <= tolerance ||u_k+1||; on_solve after each solve.
  /// PETSC_ERR_NOT_CONVERGED if it does not converge.
  PetscErrorCode static_step(State& state, const OnSolve& on_solve = {});

  /// Sets the initial acceleration from M a0 = f(t0) - K u0 + b^ (prescribed rows: 0).
  PetscErrorCode initial_acceleration(State& state);
  /// One time step (exposed for tests): Newmark beta = 1/4, gamma = 1/2 for linear runs
  /// and lagged rotations (one solve); for corotational runs with analysis.rotations:
  /// iterated the mid-point step (doc/theory.md "Mid-point corotational step"), which
  /// iterates until ||u_k+1 - u_k|| <= tolerance ||u_k+1 - u_n|| and fails with
  /// PETSC_ERR_NOT_CONVERGED after analysis.max_iterations. `rec` (may be null) gets the
  /// sum of the Krylov iterations and times of the step's solves (residuals: the last
  /// solve's). Also fills last_step_energy().
  PetscErrorCode newmark_step(State& state, solve::SolveRecord* rec = nullptr);
  /// The energy terms of the last newmark_step (doc/theory.md "Energy balance").
  const StepEnergy& last_step_energy() const { return energy_; }
  /// Linear solves of the last newmark_step (1 unless rotations are iterated).
  int last_step_solves() const { return solves_; }

  /// Energies of a state [J]: kinetic 1/2 v^T M v and strain sum_e 1/2 d^T K d with the
  /// corotated displacement d of each cell (rotations from s.u; linear runs: 1/2 u^T K u).
  PetscErrorCode kinetic_energy(const State& s, double* energy);
  PetscErrorCode elastic_energy(const State& s, double* energy);

  bool corotational() const;
  /// The preconditioner is hexcut's multigrid (solver gmg or gmg-cycles).
  bool uses_multigrid() const;
  /// The discretization is composite elements (deck discretization.type composite): the
  /// linear systems are solved on the composite level, the state stays on the fine copies
  /// (u = I u~; doc/theory.md, "Composite elements").
  bool composite() const;
  /// Composite runs: per local fine cell the id of its composite element (the canonical
  /// cell id of the composite level, the same on every rank count), as output values;
  /// empty for hexahedra.
  std::vector<double> composite_element_ids() const;
  /// Composite runs: moves out what the Simulation of the next topology can reuse (this
  /// one is to be destroyed). Hexahedra: nothing.
  CompositeCarry composite_carry();
  KSP ksp() const { return ksp_; }
  /// The multigrid (solver gmg or gmg-cycles; composite runs: always, it holds the composite
  /// level and the interpolation to it), else null.
  multigrid::Multigrid* multigrid() const { return mg_.get(); }

 private:
  Simulation(MPI_Comm comm, Model& model, const deck::Deck& deck);
  PetscErrorCode setup(CompositeCarry* carry);
  PetscErrorCode setup_composite(PC pc, bool hexcut_pc, CompositeCarry* carry);
  /// Solves the step's constrained fine system A u = b (prescribed rows of b: their values;
  /// u: the initial guess) with the KSP; composite runs solve its Galerkin projection on the
  /// composite level and return u = I u~ (doc/theory.md, "Composite elements"). `guess`:
  /// start a composite solve from the last composite solution (else zero).
  PetscErrorCode solve_system(Vec b, Vec u, solve::SolveRecord* rec, bool guess = true,
                              Vec composite_add = nullptr);
  PetscErrorCode composite_state(const State& s, bool* known);
  PetscErrorCode assemble(const assembly::OperatorWeights& w);
  PetscErrorCode refresh_rotations(Vec u);
  /// One Newmark solve with the rotations of s.u (linear runs: identity).
  PetscErrorCode linearized_step(State& s, Vec u_new, solve::SolveRecord* rec);
  /// The mid-point corotational step; fbar: its mean internal force at the end, unless
  /// the composite level computed it: then fbar_work gets du . fbar (NaN otherwise).
  PetscErrorCode midpoint_step(const State& s, Vec load_sum, Vec u_new, Vec fbar, double* fbar_work,
                               solve::SolveRecord* rec);
  PetscErrorCode kinetic(Vec v, double* energy);
  PetscErrorCode strain_energy(Vec u, double* energy);
  /// Fills energy_ for the step (u0, v0) -> (s.u, s.v). fbar: the step's mean internal
  /// force, or null to compute (f(u0) + f(u1))/2; used only for support reactions.
  /// fbar_work (composite runs; NaN: unused): du . fbar, in place of fbar.
  PetscErrorCode account_energy(Vec u0, Vec v0, const State& s, Vec load_sum, Vec fbar,
                                double strain0, double strain1, double fbar_work = NAN);
  PetscErrorCode internal_force(Vec u, Vec f);

  MPI_Comm comm_;
  Model& model_;
  const deck::Deck& deck_;
  Mat A_ = nullptr;  // assembled operator (not created for gmg)
  std::unique_ptr<multigrid::Multigrid> mg_;
  bool hexcut_pc_ = false;
  KSP ksp_ = nullptr;
  Vec composite_u_ = nullptr;  // the last composite solution (initial guess)
  // Corotational composite runs: u~, v~ of the state at step composite_state_step_ (u = I u~,
  // v = I v~), the composite elements' data for the mid-point force on the composite level,
  // and the preimage solver that recovers u~, v~ after a set-up, cut or restart.
  Vec composite_state_ = nullptr, composite_velocity_ = nullptr;
  bool composite_midpoint_ = true;  // -hexcut_composite_midpoint: the force on that level
  std::int64_t composite_state_step_ = -1;
  std::unique_ptr<CompositeElements> composite_elements_;
  std::unique_ptr<CompositeElements> carried_elements_;  // the last topology's, until built
  std::unique_ptr<CompositePreimage> composite_preimage_;
  Vec composite_coordinates_ = nullptr;  // composite copies' reference positions (AMG)
  bool supports_checked_ = false, deviation_warned_ = false;
  bool assembled_ = false;
  StepEnergy energy_;
  int solves_ = 0;
  std::vector<double> start_d_;  // mid-point step: corotated displacements at u_n per cell
  // Kinetic and strain energy after the last step (for the next step's start): the state
  // is the one this simulation left at step cached_step_ (-1: none).
  std::int64_t cached_step_ = -1;
  double cached_kinetic_ = 0, cached_strain_ = 0;
  // The rotations (9 per local cell) that strain_energy() computed at the vector with PETSc
  // id `id` in object state `state`, kept for the next refresh_rotations() of the same,
  // unchanged vector: a step's energy balance and the next step's operator both rotate by
  // those at the end-of-step displacement, so each cell's polar decomposition is done once
  // per step, not twice (doc/theory.md, "Corotation"). Empty R: none kept.
  struct KeptRotations {
    std::vector<double> R;
    PetscObjectId id = 0;
    PetscObjectState state = 0;
  } kept_rotations_;
};

}  // namespace hexcut::analysis
