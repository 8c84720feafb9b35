#include "analysis/driver.hpp"

#include <limits>

#include "analysis/events.hpp"
#include "common/petsc_check.hpp"

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
      energy_(deck.analysis.energy_tolerance) {
  if (!sim_) sim_ = std::make_unique<Simulation>(comm, model, deck);
}

bool Driver::dynamic() const {
  return deck_.analysis.type == deck::Analysis::Type::dynamic;
}

std::int64_t Driver::total_steps() const {
  return dynamic() ? deck_.analysis.steps : deck_.analysis.load_steps;
}

void Driver::follow_topology() {
  sim_.reset();
  sim_ = std::make_unique<Simulation>(comm_, model_, deck_);
  if (out_) out_->topology_changed();
}

CutReport Driver::cut(double t) {
  const auto r =
      apply_due_cuts(comm_, deck_, cutter_, t, &model_, &state_, [this] { follow_topology(); });
  if (r.events > 0 && hooks_.on_cuts) hooks_.on_cuts(r, t);
  return r;
}

void Driver::prepare() {
  if (dynamic()) return;
  // Static analyses: every cut acts on the undeformed body before the solve, and every
  // piece must then be held by the supports (a static stiffness is singular otherwise).
  cut(std::numeric_limits<double>::infinity());
  require_supported(find_pieces(comm_, model_));
}

void Driver::begin() {
  if (!dynamic()) return;
  cut(0.0);
  sim_->initial_acceleration(state_);
  write(state_, true, false);
}

void Driver::restore_cuts(const std::vector<lattice::CutLink>& links) {
  if (links.empty()) return;
  check_petsc(destroy_state(&state_), "destroy_state");
  check_petsc(analysis::restore_cuts(comm_, deck_, links, &model_), "restore_cuts");
  check_petsc(create_state(model_.dm, &state_), "create_state");
  follow_topology();
}

void Driver::resume() {
  cutter_.skip_due(state_.time);
  if (!dynamic()) require_supported(find_pieces(comm_, model_));
}

void Driver::write(const State& s, bool step, bool checkpoint) {
  if (!out_) return;
  if (step) {
    PetscLogEventBegin(events().output, 0, 0, 0, 0);
    out_->write_step(s, sim_->corotational());
    PetscLogEventEnd(events().output, 0, 0, 0, 0);
  }
  if (checkpoint) out_->write_checkpoint(s);
}

bool Driver::run(std::int64_t max_steps) {
  const std::int64_t total = total_steps(), first = state_.step;
  auto on_solve = [this](const State& s, const solve::SolveRecord& r) {
    if (out_) out_->record_solve(s.step, s.time, r);
    if (hooks_.on_solve) hooks_.on_solve(s, r);
  };
  while (state_.step < total) {
    if (dynamic()) {
      // Cuts due by the end of this step act on the configuration at its start; then the
      // operator, preconditioner and output tables follow the new topology.
      if (cutter_.pending()) cut(double(state_.step + 1) * deck_.analysis.dt);
      const auto rec = sim_->newmark_step(state_);
      energy_.add(sim_->last_step_energy(), state_.step, state_.time);  // exit 3 if created
      on_solve(state_, rec);
    } else {
      sim_->static_step(state_, on_solve);
    }
    const bool last = state_.step == total;
    const bool stop = max_steps > 0 && state_.step - first >= max_steps && !last;
    const int every = deck_.output.every, ce = deck_.output.checkpoint_every;
    write(state_, last || stop || state_.step % every == 0,
          last || stop || (ce > 0 && state_.step % ce == 0));
    if (hooks_.on_step) hooks_.on_step(state_);
    if (stop) return false;
  }
  return true;
}

}  // namespace hexcut::analysis
