#include "analysis/driver.hpp"

#include <limits>

#include "analysis/events.hpp"

namespace hexcut::analysis {

Driver::Driver(MPI_Comm comm, const deck::Deck& deck, Model& model, State& state,
               std::unique_ptr<Simulation>& sim, DriverHooks hooks)
    : comm_(comm),
      deck_(deck),
      model_(model),
      state_(state),
      sim_(sim),
      hooks_(std::move(hooks)),
      cutter_(deck, model.lattice),
      energy_(comm, deck.analysis.energy_tolerance) {}

bool Driver::dynamic() const {
  return deck_.analysis.type == deck::Analysis::Type::dynamic;
}

std::int64_t Driver::total_steps() const {
  return dynamic() ? deck_.analysis.steps : deck_.analysis.load_steps;
}

PetscErrorCode Driver::follow_topology() {
  PetscFunctionBeginUser;
  // Composite runs reuse the elements the cut left whole (none on a restart's first set-up,
  // nor after a re-partition: the carried elements are those of this rank's old cells).
  CompositeCarry carry;
  if (sim_ && model_.repartitions == repartitions_seen_) carry = sim_->composite_carry();
  repartitions_seen_ = model_.repartitions;
  sim_.reset();
  PetscCall(Simulation::create(comm_, model_, deck_, &sim_, &carry));
  if (out_) PetscCall(out_->topology_changed());
  PetscFunctionReturn(0);
}

PetscErrorCode Driver::cut(double t) {
  PetscFunctionBeginUser;
  CutReport r;
  PetscCall(apply_due_cuts(comm_, deck_, cutter_, t, &model_, &state_, &r,
                           [this] { return follow_topology(); }));
  if (r.events > 0 && hooks_.on_cuts) hooks_.on_cuts(r, t);
  PetscFunctionReturn(0);
}

PetscErrorCode Driver::prepare() {
  PetscFunctionBeginUser;
  if (dynamic()) PetscFunctionReturn(0);
  // Static analyses: every cut acts on the undeformed body before the solve, and every
  // piece must then be held by the supports (a static stiffness is singular otherwise).
  PetscCall(cut(std::numeric_limits<double>::infinity()));
  PetscCall(require_supported(comm_, find_pieces(comm_, model_)));
  PetscFunctionReturn(0);
}

PetscErrorCode Driver::begin() {
  PetscFunctionBeginUser;
  if (!dynamic()) PetscFunctionReturn(0);
  PetscCall(cut(0.0));
  PetscCall(sim_->initial_acceleration(state_));
  PetscCall(write(state_, true, false));
  PetscFunctionReturn(0);
}

PetscErrorCode Driver::restore_cuts(const std::vector<lattice::CutLink>& links) {
  PetscFunctionBeginUser;
  if (links.empty()) PetscFunctionReturn(0);
  PetscCall(destroy_state(&state_));
  PetscCall(analysis::restore_cuts(comm_, deck_, links, &model_));
  PetscCall(create_state(model_.dm, &state_));
  PetscCall(follow_topology());
  PetscFunctionReturn(0);
}

PetscErrorCode Driver::resume() {
  PetscFunctionBeginUser;
  cutter_.skip_due(state_.time);
  if (!dynamic()) PetscCall(require_supported(comm_, find_pieces(comm_, model_)));
  PetscFunctionReturn(0);
}

PetscErrorCode Driver::write(const State& s, bool step, bool checkpoint, bool last) {
  PetscFunctionBeginUser;
  if (!out_) PetscFunctionReturn(0);
  if (step) {
    EventScope scope(events().output);
    // Collective: a rank without cells passes its empty table too.
    const bool ids = deck_.output.has_field("composite_element");
    std::vector<double> composite;
    if (ids) composite = sim_->composite_element_ids();
    const bool corotational = sim_->corotational();
    if (last) {
      // Nothing solves after the last step: the solver, the multigrid and the DM's cached
      // work vectors go before the output allocates its own, so that writing the result
      // is not the run's peak of memory (doc/benchmarks.md, "Memory per DOF").
      sim_.reset();
      PetscCall(DMClearGlobalVectors(model_.dm));
    }
    PetscCall(out_->write_step(s, corotational, ids ? &composite : nullptr));
  }
  if (checkpoint) PetscCall(out_->write_checkpoint(s));
  PetscFunctionReturn(0);
}

PetscErrorCode Driver::run(std::int64_t max_steps, bool* reached_end) {
  PetscFunctionBeginUser;
  const std::int64_t total = total_steps(), first = state_.step;
  if (reached_end) *reached_end = false;
  auto on_solve = [this](const State& s, const solve::SolveRecord& r) {
    if (out_) out_->record_solve(s.step, s.time, r);
    if (hooks_.on_solve) hooks_.on_solve(s, r);
  };
  while (state_.step < total) {
    if (dynamic()) {
      // Cuts due by the end of this step act on the configuration at its start; then the
      // operator, preconditioner and output tables follow the new topology.
      if (cutter_.pending()) PetscCall(cut(double(state_.step + 1) * deck_.analysis.dt));
      solve::SolveRecord rec;
      PetscCall(sim_->newmark_step(state_, &rec));
      // Exit 3 when the step created energy.
      PetscCall(energy_.add(sim_->last_step_energy(), state_.step, state_.time));
      on_solve(state_, rec);
    } else {
      PetscCall(sim_->static_step(state_, on_solve));
    }
    const bool last = state_.step == total;
    const bool stop = max_steps > 0 && state_.step - first >= max_steps && !last;
    const int every = deck_.output.every, ce = deck_.output.checkpoint_every;
    PetscCall(write(state_, last || stop || state_.step % every == 0,
                    last || stop || (ce > 0 && state_.step % ce == 0), last));
    if (hooks_.on_step) hooks_.on_step(state_);
    if (stop) PetscFunctionReturn(0);
  }
  if (reached_end) *reached_end = true;
  PetscFunctionReturn(0);
}

}  // namespace hexcut::analysis
