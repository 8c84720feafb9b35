// The run loop (doc/theory.md, "Architecture"): one driver owns the steps of an analysis, for the
// app and the tests alike. Static analyses take load steps 1..n (each a linear solve, or the
// corotational fixed-point iteration, Simulation::static_step); dynamic ones take Newmark steps
// (Simulation::newmark_step) with the energy check (EnergyMonitor). Around the steps: the deck's
// cut events (static: all on the undeformed body before the first solve; dynamic: each in the
// deformed configuration at the start of the step that reaches its time), the follow-up of a
// topology change (a new Simulation for the new DM, the output's tables), the result output and
// checkpoints per the deck's output section, and a limit on the steps of one invocation
// (-hexcut_max_steps). A cut may re-partition the cells (Model::repartition_imbalance, in
// analysis::rebuild_topology); follow_topology() then drops the composite elements it would
// otherwise carry.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <vector>

#include "analysis/cutting.hpp"
#include "analysis/energy.hpp"
#include "analysis/model.hpp"
#include "analysis/result_output.hpp"
#include "analysis/simulation.hpp"
#include "analysis/state.hpp"

namespace hexcut::analysis {

/// What the driver reports to its user (progress lines, tests' probes); all optional.
struct DriverHooks {
  /// After every linear solve (static: each fixed-point iteration; dynamic: each step).
  std::function<void(const State&, const solve::SolveRecord&)> on_solve;
  /// After each completed step, once its output is written. After the last step of a run
  /// with an output the Simulation is already released (Driver::write).
  std::function<void(const State&)> on_step;
  /// After cut events were applied at time t (report.events > 0), the topology followed.
  std::function<void(const CutReport&, double t)> on_cuts;
};

/// The driver's members that do PETSc work return a PetscErrorCode (common/petsc_check.hpp);
/// its constructor does none.
class Driver {
 public:
  /// The analysis of `model` from `state` (both must outlive the driver). `sim` holds the
  /// analysis' Simulation (Simulation::create): the driver replaces it after every topology
  /// change (so a caller's pointer to it stays the one to use).
  Driver(MPI_Comm comm, const deck::Deck& deck, Model& model, State& state,
         std::unique_ptr<Simulation>& sim, DriverHooks hooks = {});

  /// Result output: each step per output.every (and the first and last), checkpoints per
  /// output.checkpoint_every (and at the last step of the run); the output's tables follow
  /// every topology change. Null: no output.
  void set_output(ResultOutput* out) { out_ = out; }

  /// Before any output exists: a static analysis applies every cut event to the undeformed
  /// body and requires every piece held by its supports (PETSC_ERR_NOT_CONVERGED
  /// otherwise); a dynamic one does nothing. Collective.
  PetscErrorCode prepare();
  /// A new dynamic run, after set_output: the cuts due at t = 0, the initial acceleration
  /// and the output of the initial state. Nothing for static runs. Collective.
  PetscErrorCode begin();
  /// A restart: the cut links of the checkpoint (in their order) are applied to the uncut
  /// model, the state is re-created on the new DM and the Simulation and output follow.
  /// Read the checkpoint into the state afterwards, then call resume(). Collective.
  PetscErrorCode restore_cuts(const std::vector<lattice::CutLink>& links);
  /// After the checkpoint was read: the cut events up to the state's time count as
  /// applied; static bodies must be held by their supports. Collective.
  PetscErrorCode resume();

  /// Takes steps from state.step to the analysis' end, at most `max_steps` of them
  /// (0: no limit). `reached_end` (may be null): true when the analysis reached its end,
  /// false when it stopped at the limit (the last step taken is written and
  /// checkpointed). PETSC_ERR_NOT_CONVERGED (exit 3) when a solve fails or a dynamic step
  /// creates energy; what was written stays.
  PetscErrorCode run(std::int64_t max_steps = 0, bool* reached_end = nullptr);

  /// Steps of the whole analysis: load steps (static) or time steps (dynamic).
  std::int64_t total_steps() const;
  bool dynamic() const;
  const EnergyMonitor& energy() const { return energy_; }
  /// The current Simulation; released when run() wrote the last step to an output.
  Simulation& simulation() { return *sim_; }

 private:
  /// Applies the cut events due by time t (in the configuration of the state) and follows
  /// the topology when links were cut.
  PetscErrorCode cut(double t);
  /// After the topology changed: a Simulation (solver, multigrid hierarchy) for the new DM
  /// and the output's tables for the new vertex copies.
  PetscErrorCode follow_topology();
  /// The step's output and/or a checkpoint (nothing without an output). `last`: the
  /// analysis' last step; the Simulation is released before the output is written (with
  /// an output only), so simulation() must not be called after run() reached the end.
  PetscErrorCode write(const State& s, bool step, bool checkpoint, bool last = false);

  MPI_Comm comm_;
  const deck::Deck& deck_;
  Model& model_;
  State& state_;
  std::unique_ptr<Simulation>& sim_;
  DriverHooks hooks_;
  Cutter cutter_;
  EnergyMonitor energy_;
  ResultOutput* out_ = nullptr;
  int repartitions_seen_ = 0;  // model_.repartitions when the Simulation was made
};

}  // namespace hexcut::analysis
