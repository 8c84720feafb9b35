#include "app/job.hpp"

#include <petscsys.h>
#include <petsctime.h>

#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>

#include "analysis/cutting.hpp"
#include "analysis/events.hpp"
#include "analysis/model.hpp"
#include "analysis/result_output.hpp"
#include "analysis/simulation.hpp"
#include "common/errors.hpp"
#include "common/petsc_check.hpp"
#include "solve/linear_solver.hpp"

namespace hexcut::app {
namespace {

/// Peak resident memory of this process [bytes] (VmHWM), 0 where /proc is unavailable.
double peak_memory_bytes() {
  std::ifstream status("/proc/self/status");
  std::string line;
  while (std::getline(status, line))
    if (line.rfind("VmHWM:", 0) == 0) return 1024.0 * std::stod(line.substr(6));
  return 0.0;
}

std::string format_seconds(double s) {
  char buf[32];
  if (s < 120)
    std::snprintf(buf, sizeof buf, "%.1f s", s);
  else if (s < 7200)
    std::snprintf(buf, sizeof buf, "%.1f min", s / 60);
  else
    std::snprintf(buf, sizeof buf, "%.1f h", s / 3600);
  return buf;
}

/// One line per application of cut events, then the pieces when links were cut.
void print_cut_report(MPI_Comm comm, const analysis::Model& model, const analysis::CutReport& r,
                      double t) {
  if (r.events == 0) return;
  char when[64];  // (std::snprintf: PetscPrintf's %g prints 0 as "0.")
  std::snprintf(when, sizeof when, "hexcut: t = %g s: ", t);
  if (r.links == 0) {
    PetscPrintf(comm, "%s%d cut event(s) crossed no link\n", when, r.events);
    return;
  }
  const auto pieces = analysis::find_pieces(comm, model);
  PetscPrintf(comm, "%s%d cut event(s) disconnected %lld links; %d piece(s), %d vertex copies\n",
              when, r.events, (long long)r.links, int(pieces.size()), int(model.copies.num_copies));
  for (const auto& p : pieces) PetscPrintf(comm, "  %s\n", analysis::describe(p).c_str());
}

}  // namespace

deck::Deck read_deck(MPI_Comm comm, const std::string& path) {
  int rank;
  MPI_Comm_rank(comm, &rank);
  std::string text;
  int ok = 1;
  if (rank == 0) {
    std::ifstream in(path, std::ios::binary);
    if (!in) ok = 0;
    std::ostringstream ss;
    ss << in.rdbuf();
    text = ss.str();
  }
  MPI_Bcast(&ok, 1, MPI_INT, 0, comm);
  if (!ok) throw InputError(path + ": cannot open the deck file");
  long n = long(text.size());
  MPI_Bcast(&n, 1, MPI_LONG, 0, comm);
  text.resize(n);
  MPI_Bcast(text.data(), int(n), MPI_CHAR, 0, comm);
  return deck::parse_deck(text, path);
}

void check_job(MPI_Comm comm, const deck::Deck& deck) {
  analysis::Model model;
  check_petsc(analysis::build_model(comm, deck, 8, &model), "build_model");
  PetscPrintf(comm, "%s: deck is valid: %d cells, %d DOFs, %d prescribed\n", deck.path.c_str(),
              int(model.lattice.num_cells()), 3 * int(model.copies.num_copies),
              int(model.boundary.constraints.global_count));
  check_petsc(analysis::destroy_model(&model), "destroy_model");
}

void run_job(MPI_Comm comm, const deck::Deck& deck, const JobOptions& options) {
  namespace an = analysis;
  const auto& ev = an::events();
  int rank;
  MPI_Comm_rank(comm, &rank);
  PetscLogDouble t_start;
  PetscTime(&t_start);

  PetscInt superblock = 8, max_steps = -1;
  check_petsc(PetscOptionsGetInt(nullptr, nullptr, "-hexcut_superblock", &superblock, nullptr),
              "options");
  check_petsc(PetscOptionsGetInt(nullptr, nullptr, "-hexcut_max_steps", &max_steps, nullptr),
              "options");
  if (superblock < 1 || (superblock & (superblock - 1)))
    throw InputError("-hexcut_superblock must be a power of two, got " +
                     std::to_string(superblock));
  check_petsc(solve::set_default_options(deck.solver), "set_default_options");

  an::Model model;
  PetscLogEventBegin(ev.setup, 0, 0, 0, 0);
  check_petsc(an::build_model(comm, deck, int(superblock), &model), "build_model");
  PetscLogEventEnd(ev.setup, 0, 0, 0, 0);
  PetscPrintf(comm, "hexcut: %d cells, %d vertex copies, %d DOFs (%d prescribed), %d rank(s)\n",
              int(model.lattice.num_cells()), int(model.copies.num_copies),
              3 * int(model.copies.num_copies), int(model.boundary.constraints.global_count),
              model.layout.num_ranks);

  const bool restart = !options.restart_path.empty();
  std::string path = options.restart_path;
  if (!restart) {
    if (rank == 0) std::filesystem::create_directories(deck.output.directory);
    path = (std::filesystem::path(deck.output.directory) / (deck.output.name + ".h5")).string();
  }
  const bool dynamic = deck.analysis.type == deck::Analysis::Type::dynamic;
  an::State state;
  check_petsc(an::create_state(model.dm, &state), "create_state");
  an::ResultOutput out(comm, model, deck, path, options.command_line, restart);
  auto sim = std::make_unique<an::Simulation>(comm, model, deck);
  {
    KSPType ksp_type;
    PCType pc_type;
    PC pc;
    check_petsc(KSPGetType(sim->ksp(), &ksp_type), "KSPGetType");
    check_petsc(KSPGetPC(sim->ksp(), &pc), "KSPGetPC");
    check_petsc(PCGetType(pc, &pc_type), "PCGetType");
    PetscPrintf(comm, "hexcut: solver %s (KSP %s, PC %s), rtol %g\n",
                deck::to_string(deck.solver.type), ksp_type, pc_type ? pc_type : "none",
                deck.solver.rtol);
  }
  // Cuts (design.md §6). Static analyses apply every cut to the undeformed body before
  // solving; dynamic ones apply each when its time comes, in the deformed configuration.
  an::Cutter cutter(deck, model.lattice);
  // After the topology changed: a solver (and multigrid hierarchy) for the new DM, and
  // output tables for the new vertex copies.
  auto follow_topology = [&] {
    sim.reset();
    sim = std::make_unique<an::Simulation>(comm, model, deck);
    out.topology_changed();
  };
  auto apply_cuts = [&](double t) {
    const auto r = an::apply_due_cuts(comm, deck, cutter, t, &model, &state);
    if (r.links > 0) {
      PetscLogEventBegin(ev.rebuild, 0, 0, 0, 0);
      follow_topology();
      PetscLogEventEnd(ev.rebuild, 0, 0, 0, 0);
    }
    print_cut_report(comm, model, r, t);
  };
  if (!restart) apply_cuts(dynamic ? 0.0 : std::numeric_limits<double>::infinity());
  if (!dynamic) an::require_supported(an::find_pieces(comm, model));

  const std::int64_t total = dynamic ? deck.analysis.steps : deck.analysis.load_steps;
  if (restart) {
    // A run that was cut: rebuild the cut topology from the checkpoint's links first.
    const auto links = out.checkpoint_cut_links();
    if (!links.empty()) {
      check_petsc(an::destroy_state(&state), "destroy_state");
      check_petsc(an::restore_cuts(comm, deck, links, &model), "restore_cuts");
      check_petsc(an::create_state(model.dm, &state), "create_state");
      follow_topology();
    }
    out.read_checkpoint(&state);
    cutter.skip_due(state.time);
    PetscPrintf(comm,
                "hexcut: restarting from %s at step %lld, t = %g s (%lld cut links restored)\n",
                path.c_str(), (long long)state.step, state.time, (long long)links.size());
  } else if (dynamic) {
    sim->initial_acceleration(state);
    PetscLogEventBegin(ev.output, 0, 0, 0, 0);
    out.write_step(state, sim->corotational());
    PetscLogEventEnd(ev.output, 0, 0, 0, 0);
  }
  const std::int64_t first_step = state.step;

  PetscLogDouble t_loop;
  PetscTime(&t_loop);
  an::Observer obs;
  std::int64_t last_its = 0;
  double last_res = 0;
  obs.on_solve = [&](const an::State& s, const solve::SolveRecord& r) {
    last_its = r.iterations;
    last_res = r.residual;
    out.record_solve(s.step, s.time, r);
  };
  bool stopped_early = false;
  obs.on_step = [&](const an::State& s) {
    PetscLogDouble now;
    PetscTime(&now);
    const double wall = now - t_loop;
    const double per_step = wall / double(s.step - first_step);
    PetscPrintf(comm, "step %lld/%lld  t = %.6g s  its %lld  res %.2e  wall %s  eta %s\n",
                (long long)s.step, (long long)total, s.time, (long long)last_its, last_res,
                format_seconds(wall).c_str(),
                format_seconds(per_step * double(total - s.step)).c_str());
    const bool last = s.step == total;
    const bool stop = max_steps > 0 && s.step - first_step >= max_steps && !last;
    if (last || stop || s.step % deck.output.every == 0) {
      PetscLogEventBegin(ev.output, 0, 0, 0, 0);
      out.write_step(s, sim->corotational());
      PetscLogEventEnd(ev.output, 0, 0, 0, 0);
    }
    const int ce = deck.output.checkpoint_every;
    if (last || stop || (ce > 0 && s.step % ce == 0)) out.write_checkpoint(s);
    if (stop) {
      stopped_early = true;
      throw std::logic_error("stop");  // unwinds the analysis loop; caught below
    }
  };
  try {
    if (dynamic) {
      while (state.step < total) {
        // Cuts due by the end of this step act on the configuration at its start; then
        // the operator, preconditioner and output tables follow the new topology.
        if (cutter.pending()) apply_cuts(double(state.step + 1) * deck.analysis.dt);
        const auto rec = sim->newmark_step(state);
        obs.on_solve(state, rec);
        obs.on_step(state);
      }
    } else {
      sim->run_static(state, obs);
    }
  } catch (const std::logic_error&) {
    if (!stopped_early) throw;
    PetscPrintf(
        comm, "hexcut: stopped after %lld steps (-hexcut_max_steps); continue with --restart %s\n",
        (long long)max_steps, path.c_str());
  }
  PetscLogDouble t_end;
  PetscTime(&t_end);
  double peak = peak_memory_bytes(), total_peak = 0;
  MPI_Allreduce(&peak, &total_peak, 1, MPI_DOUBLE, MPI_SUM, comm);
  PetscPrintf(comm, "hexcut: wrote %s and %s (%.2f s, peak memory %.1f MiB over all ranks)\n",
              out.path().c_str(), out.writer().xdmf_path().c_str(), t_end - t_start,
              total_peak / (1024.0 * 1024.0));
  check_petsc(an::destroy_state(&state), "destroy_state");
  check_petsc(an::destroy_model(&model), "destroy_model");
}

}  // namespace hexcut::app
