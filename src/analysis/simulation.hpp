// The analyses (design.md §4): static (linear, or corotational by fixed-point
// iteration per load step) and dynamic (Newmark beta = 1/4, gamma = 1/2, Rayleigh
// damping, lumped or consistent mass, linear or corotational).
#pragma once

#include <petscksp.h>

#include <functional>

#include "analysis/model.hpp"
#include "analysis/result_output.hpp"
#include "multigrid/gmg.hpp"
#include "solve/linear_solver.hpp"

namespace hexcut::analysis {

/// Called after every solve (for solver history) and every completed step (for output
/// and progress).
struct Observer {
  std::function<void(const State&, const solve::SolveRecord&)> on_solve;
  std::function<void(const State&)> on_step;
};

/// Owns the system matrix and the KSP of one analysis.
class Simulation {
 public:
  Simulation(MPI_Comm comm, Model& model, const deck::Deck& deck);
  ~Simulation();
  Simulation(const Simulation&) = delete;
  Simulation& operator=(const Simulation&) = delete;

  /// Static analysis: load steps 1..n (pseudo-time s/n; time functions at t = 1, loads
  /// and prescribed displacements scaled by s/n). Linear: one solve per load step.
  /// Corotational: fixed-point iteration, rotations from the last iterate, until
  /// ||u_k+1 - u_k|| <= tolerance ||u_k+1||. Throws SolverError if it does not converge.
  void run_static(State& state, const Observer& observer);

  /// Sets the initial acceleration from M a0 = f(t0) - K u0 + b^ (prescribed rows: 0).
  void initial_acceleration(State& state);
  /// Dynamic analysis from state.step to deck.analysis.steps.
  void run_dynamic(State& state, const Observer& observer);
  /// One Newmark step (exposed for tests).
  solve::SolveRecord newmark_step(State& state);

  /// Energies of a state: kinetic 1/2 v^T M v and elastic 1/2 u^T K^ u (current rotations).
  double kinetic_energy(const State& s);
  double elastic_energy(const State& s);

  bool corotational() const;
  bool uses_multigrid() const;
  KSP ksp() const { return ksp_; }
  /// The multigrid preconditioner (solver gmg or gmg-cycles), else null.
  multigrid::Multigrid* multigrid() const { return mg_.get(); }

 private:
  void assemble(const assembly::OperatorWeights& w);
  void refresh_rotations(Vec u);

  MPI_Comm comm_;
  Model& model_;
  const deck::Deck& deck_;
  Mat A_ = nullptr;  // assembled operator (not created for gmg)
  std::unique_ptr<multigrid::Multigrid> mg_;
  KSP ksp_ = nullptr;
  bool assembled_ = false;
};

}  // namespace hexcut::analysis
