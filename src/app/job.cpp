#include "app/job.hpp"

#include <petscsys.h>
#include <petsctime.h>

#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

#include "analysis/cutting.hpp"
#include "analysis/driver.hpp"
#include "analysis/events.hpp"
#include "analysis/model.hpp"
#include "analysis/reference_state.hpp"
#include "analysis/result_output.hpp"
#include "analysis/simulation.hpp"
#include "app/options.hpp"
#include "app/result_files.hpp"
#include "common/errors.hpp"
#include "common/mpi_gather.hpp"
#include "common/petsc_check.hpp"
#include "deck/compare.hpp"
#include "output/h5_file.hpp"
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
  // The partition stays (a cut changes links, not cells); the copies it adds may unbalance it,
  // and -hexcut_repartition then re-partitions.
  std::string balance;
  if (model.partition.num_ranks > 1) {
    const auto s = topology::partition_balance(model.partition);
    char buf[128];
    std::snprintf(buf, sizeof buf, " (DOFs max/mean over ranks %.3f)", s.copy_imbalance());
    if (r.repartitioned)
      std::snprintf(buf, sizeof buf,
                    " (DOFs max/mean over ranks %.3f, re-partitioned: cells max/mean %.3f)",
                    s.copy_imbalance(), s.cell_imbalance());
    balance = buf;
  }
  PetscPrintf(comm, "%s%d cut event(s) disconnected %lld links; %d piece(s), %d vertex copies%s\n",
              when, r.events, (long long)r.links, int(pieces.size()), int(model.copies.num_copies),
              balance.c_str());
  for (const auto& p : pieces) PetscPrintf(comm, "  %s\n", analysis::describe(p).c_str());
}

/// hexcut's options and the names of the options the user set (command line and the
/// deck's petsc_options).
struct OptionSetup {
  HexcutOptions hexcut;
  std::set<std::string> user_options;
};

OptionSetup setup_options(const deck::Deck& deck) {
  OptionSetup o;
  throw_on_petsc_error(solve::insert_deck_options(deck.solver));
  o.user_options = options_in_database();
  o.hexcut = read_hexcut_options();
  output::set_collective_buffer(o.hexcut.io_buffer_mib << 20);
  return o;
}

/// What the command line changed in the deck (-hexcut_refine, -hexcut_output_directory).
void print_overrides(MPI_Comm comm, const deck::Deck& deck, const HexcutOptions& o) {
  const auto& s = deck.lattice;
  if (o.refine != 1.0) {
    char line[160];  // (std::snprintf: PetscPrintf's %g prints 2 as "2.")
    std::snprintf(line, sizeof line,
                  "hexcut: -hexcut_refine %g: lattice h = %g m, dims %d x %d x %d\n", o.refine, s.h,
                  s.dims[0], s.dims[1], s.dims[2]);
    PetscPrintf(comm, "%s", line);
  }
  if (!o.output_directory.empty())
    PetscPrintf(comm, "hexcut: -hexcut_output_directory: output goes to %s\n",
                o.output_directory.c_str());
}

/// On several ranks: how the partition balances cells and DOFs and what it cuts (rank 0).
void print_partition(MPI_Comm comm, const analysis::Model& model, const HexcutOptions& o) {
  const auto& P = model.partition;
  int rank;
  MPI_Comm_rank(comm, &rank);
  if (P.num_ranks < 2 || rank != 0) return;
  const auto s = topology::partition_stats(model.lattice, model.copies, P);
  PetscPrintf(PETSC_COMM_SELF,
              "hexcut: partition %s, super-blocks of %d: cells max/mean %.3f, DOFs max/mean %.3f, "
              "%lld links between ranks, ghost DOFs %.2f%% of all (%lld on the rank with most)\n",
              topology::method_name(o.partition), P.superblock, s.cell_imbalance(),
              s.copy_imbalance(), (long long)s.cut_links,
              100.0 * double(s.ghosts) / double(model.copies.num_copies),
              3 * (long long)s.max_ghosts);
  if (s.empty_ranks > 0)
    PetscFPrintf(
        PETSC_COMM_SELF, PETSC_STDERR,
        "hexcut: warning: %lld of %d ranks hold no cells (too few super-blocks of %d cells "
        "per side; -hexcut_superblock smaller, or fewer ranks)\n",
        (long long)s.empty_ranks, P.num_ranks, P.superblock);
}

/// Warnings of the deck and of the model build, once (rank 0, stderr).
void print_warnings(MPI_Comm comm, const deck::Deck& deck, const analysis::Model& model) {
  for (const auto* list : {&deck.warnings, &model.warnings})
    for (const auto& w : *list) PetscFPrintf(comm, PETSC_STDERR, "%s\n", w.c_str());
}

/// --restart: the checkpoint must come from the same physics. Compares the deck stored
/// in the result file with this deck (deck::physics_differences) and the file's reference
/// mesh with this model's lattice (lattice spacing, origin, dims; every cell's lattice
/// index, material and Young's modulus, which also catches a changed mesh or image
/// file). Throws InputError naming what differs. Collective.
void require_same_physics(MPI_Comm comm, const deck::Deck& deck, const analysis::Model& model,
                          const std::string& path) {
  // A file hexcut cannot continue (not a result, another layout version) is the user's
  // input, not an internal error.
  try {
    output::ResultWriter::open(path, comm);
  } catch (const std::runtime_error& e) {
    throw InputError("--restart " + path + ": " + e.what());
  }
  auto f = output::H5File::open(path, comm, output::H5File::Access::kReadOnly);
  std::vector<std::string> diffs;
  if (f.exists("/input/deck")) {
    diffs = deck::physics_differences(f.read_string_dataset("/input/deck"), deck.text);
  } else {
    diffs.push_back("(the file stores no deck)");
  }
  const auto& L = model.lattice;
  const auto dims = f.read_attribute_int64s("/mesh", "lattice_dims");
  const auto origin = f.read_attribute_doubles("/mesh", "lattice_origin");
  const bool same_lattice = f.read_attribute_double("/mesh", "lattice_h") == L.spec.h &&
                            dims.size() == 3 && origin.size() == 3 && dims[0] == L.spec.dims[0] &&
                            dims[1] == L.spec.dims[1] && dims[2] == L.spec.dims[2] &&
                            origin[0] == L.spec.origin[0] && origin[1] == L.spec.origin[1] &&
                            origin[2] == L.spec.origin[2];
  const auto n = f.read_attribute_int64("/mesh", "num_cells");
  if (!same_lattice) {
    diffs.push_back("the lattice (h, origin or dims)");
  } else if (n != L.num_cells()) {
    diffs.push_back("the body (" + std::to_string(n) + " cells in the file, " +
                    std::to_string(L.num_cells()) + " now)");
  } else {
    // Each rank compares an even slab of the cell tables with its copy of the lattice.
    int rank, size;
    MPI_Comm_rank(comm, &rank);
    MPI_Comm_size(comm, &size);
    const std::int64_t lo = n * rank / size, rows = n * (rank + 1) / size - lo;
    std::vector<std::int32_t> ijk(3 * rows), material(rows);
    std::vector<double> youngs(rows);
    f.read_rows("/mesh/cell_lattice_index", n, 3, lo, rows, ijk.data());
    f.read_rows("/mesh/cell_material", n, 0, lo, rows, material.data());
    f.read_rows("/mesh/cell_youngs_modulus", n, 0, lo, rows, youngs.data());
    int mismatch[2] = {0, 0};  // body, material or E
    for (std::int64_t i = 0; i < rows; ++i) {
      const auto c = lo + i;
      for (int d = 0; d < 3; ++d) mismatch[0] |= ijk[3 * i + d] != L.ijk[c][d];
      mismatch[1] |= material[i] != L.material[c] || youngs[i] != L.youngs[c];
    }
    MPI_Allreduce(MPI_IN_PLACE, mismatch, 2, MPI_INT, MPI_LOR, comm);
    if (mismatch[0]) diffs.push_back("the body (which cells are filled)");
    if (mismatch[1]) diffs.push_back("the cells' materials or Young's moduli");
  }
  f.close();
  if (diffs.empty()) return;
  std::string list;
  for (std::size_t i = 0; i < diffs.size() && i < 12; ++i) list += "\n  " + diffs[i];
  if (diffs.size() > 12) list += "\n  ... (" + std::to_string(diffs.size() - 12) + " more)";
  throw InputError(deck.path + ":1: --restart " + path +
                   ": this deck's physics differs from the run that wrote the checkpoint "
                   "(solver and output settings and the end time may change, nothing else):" +
                   list);
}

}  // namespace

deck::Deck read_deck(MPI_Comm comm, const std::string& path) {
  int rank;
  MPI_Comm_rank(comm, &rank);
  std::string text;
  int ok = 1;
  if (rank == 0) {
    std::ifstream in(path, std::ios::binary);
    // A directory opens as a stream on Linux; only regular files (or pipes) are decks.
    if (!in || std::filesystem::is_directory(path)) ok = 0;
    std::ostringstream ss;
    ss << in.rdbuf();
    text = ss.str();
  }
  MPI_Bcast(&ok, 1, MPI_INT, 0, comm);
  if (!ok)
    throw InputError(path + ": cannot open the deck file" +
                     (std::filesystem::is_directory(path) ? " (it is a directory)" : ""));
  broadcast_string(comm, &text);
  return deck::parse_deck(text, path);
}

void check_job(MPI_Comm comm, const deck::Deck& deck_in, const JobOptions&) {
  namespace an = analysis;
  const auto options = setup_options(deck_in);
  const deck::Deck deck = apply_overrides(deck_in, options.hexcut);
  print_overrides(comm, deck, options.hexcut);
  if (const auto problem = output_directory_problem(deck.output.directory); !problem.empty())
    throw InputError(problem);
  if (deck.compare) (void)an::ReferenceState{comm, *deck.compare, deck.lattice};  // its checks
  an::Model model;
  throw_on_petsc_error(an::build_model(comm, deck, options.hexcut.superblock, &model,
                                       options.hexcut.partition, options.hexcut.repartition));
  print_warnings(comm, deck, model);
  PetscPrintf(comm, "%s: %d cells, %d DOFs, %d prescribed\n", deck.path.c_str(),
              int(model.lattice.num_cells()), 3 * int(model.copies.num_copies),
              int(model.boundary.constraints.global_count));
  print_partition(comm, model, options.hexcut);
  an::State state;
  throw_on_petsc_error(an::create_state(model.dm, &state));
  {
    // The solver as the run creates it (PETSc parses the options here), and the static
    // cuts with the pieces they leave.
    std::unique_ptr<an::Simulation> sim;
    throw_on_petsc_error(an::Simulation::create(comm, model, deck, &sim));
    an::DriverHooks hooks;
    hooks.on_cuts = [&](const an::CutReport& r, double t) { print_cut_report(comm, model, r, t); };
    an::Driver driver(comm, deck, model, state, sim, hooks);
    if (driver.dynamic() && !deck.cuts.empty())
      PetscPrintf(comm,
                  "%s: %d cut(s) act during the run (not checked here: they depend on "
                  "the motion)\n",
                  deck.path.c_str(), int(deck.cuts.size()));
    throw_on_petsc_error(driver.prepare());
  }
  PetscPrintf(comm, "%s: deck is valid\n", deck.path.c_str());
  throw_on_petsc_error(an::destroy_state(&state));
  throw_on_petsc_error(an::destroy_model(&model));
}

void run_job(MPI_Comm comm, const deck::Deck& deck_in, const JobOptions& job) {
  namespace an = analysis;
  const auto& ev = an::events();
  PetscLogDouble t_start;
  PetscTime(&t_start);
  // Before anything is written: the options, then the result file's lock and paths.
  const auto options = setup_options(deck_in);
  if (!job.restart_path.empty() && !options.hexcut.output_directory.empty())
    throw InputError("--restart continues " + job.restart_path +
                     " in place; -hexcut_output_directory does not apply");
  const deck::Deck deck = apply_overrides(deck_in, options.hexcut);
  print_overrides(comm, deck, options.hexcut);
  const std::int64_t max_steps = options.hexcut.max_steps;
  const bool restart = !job.restart_path.empty();
  const ResultLock lock(comm, restart ? job.restart_path : result_path(deck));
  const ResultPaths paths = plan_result(comm, deck, job);
  // The reference of compare is checked (lattice, fields) before any work; it cannot be
  // the file this run writes into (a --restart of itself).
  if (deck.compare) {
    std::error_code ec;
    if (std::filesystem::equivalent(deck.compare->reference, paths.write_path, ec))
      throw InputError(deck.compare->where.prefix() + "compare.reference '" +
                       deck.compare->reference +
                       "' is the result file this run writes into; compare with a copy");
    (void)an::ReferenceState{comm, *deck.compare, deck.lattice};
  }

  an::Model model;
  {
    const an::EventScope scope(ev.setup);
    throw_on_petsc_error(an::build_model(comm, deck, options.hexcut.superblock, &model,
                                         options.hexcut.partition, options.hexcut.repartition));
  }
  print_warnings(comm, deck, model);
  PetscPrintf(comm, "hexcut: %d cells, %d vertex copies, %d DOFs (%d prescribed), %d rank(s)\n",
              int(model.lattice.num_cells()), int(model.copies.num_copies),
              3 * int(model.copies.num_copies), int(model.boundary.constraints.global_count),
              model.layout.num_ranks);
  print_partition(comm, model, options.hexcut);
  if (restart) require_same_physics(comm, deck, model, paths.final_path);
  if (paths.replaces)
    PetscPrintf(comm, "hexcut: writing %s; it replaces %s when the run ends\n",
                paths.write_path.c_str(), paths.final_path.c_str());

  an::State state;
  throw_on_petsc_error(an::create_state(model.dm, &state));
  std::unique_ptr<an::Simulation> sim;
  std::int64_t last_its = 0;
  double last_res = 0;
  std::int64_t first_step = 0;
  PetscLogDouble t_loop = 0;
  an::DriverHooks hooks;
  hooks.on_cuts = [&](const an::CutReport& r, double t) { print_cut_report(comm, model, r, t); };
  hooks.on_solve = [&](const an::State&, const solve::SolveRecord& r) {
    last_its = r.iterations;
    last_res = r.residual;
  };
  // The driver is created below; the progress line reads its energy monitor.
  std::unique_ptr<an::Driver> driver;
  hooks.on_step = [&](const an::State& s) {
    PetscLogDouble now;
    PetscTime(&now);
    const double wall = now - t_loop;
    const double per_step = wall / double(s.step - first_step);
    const auto total = driver->total_steps();
    PetscPrintf(comm, "step %lld/%lld  t = %.6g s  its %lld  res %.2e  %swall %s  eta %s\n",
                (long long)s.step, (long long)total, s.time, (long long)last_its, last_res,
                driver->dynamic() ? (driver->energy().summary() + "  ").c_str() : "",
                format_seconds(wall).c_str(),
                format_seconds(per_step * double(total - s.step)).c_str());
  };
  // Cuts (doc/theory.md, "Cutting"), steps, output and checkpoints: analysis::Driver.
  throw_on_petsc_error(an::Simulation::create(comm, model, deck, &sim));
  driver = std::make_unique<an::Driver>(comm, deck, model, state, sim, hooks);
  {
    KSPType ksp_type;
    PCType pc_type;
    PC pc;
    throw_on_petsc_error(KSPGetType(sim->ksp(), &ksp_type));
    throw_on_petsc_error(KSPGetPC(sim->ksp(), &pc));
    throw_on_petsc_error(PCGetType(pc, &pc_type));
    PetscPrintf(comm, "hexcut: solver %s (KSP %s, PC %s), rtol %g\n",
                deck::to_string(deck.solver.type), ksp_type, pc_type ? pc_type : "none",
                deck.solver.rtol);
    if (sim->composite()) {
      const auto* mg = sim->multigrid();
      const auto& lev = mg->level(mg->first_level());
      PetscPrintf(comm,
                  "hexcut: composite elements of level %d: %d elements, %d DOFs (%.1fx fewer "
                  "than the hexahedra)\n",
                  mg->first_level(), int(lev.graph.num_cells()), 3 * int(lev.copies().num_copies),
                  double(model.copies.num_copies) / double(lev.copies().num_copies));
    }
  }
  // A static body its supports do not hold stops here, before the result file exists.
  if (!restart) throw_on_petsc_error(driver->prepare());
  // The result file: created (mesh and input written) or, on restart, re-opened.
  std::unique_ptr<an::ResultOutput> out;
  throw_on_petsc_error(an::ResultOutput::create(comm, model, deck, paths.write_path,
                                                job.command_line, restart, &out));
  driver->set_output(out.get());
  if (restart) {
    // A run that was cut: rebuild the cut topology from the checkpoint's links first.
    const auto links = out->checkpoint_cut_links();
    throw_on_petsc_error(driver->restore_cuts(links));
    throw_on_petsc_error(out->read_checkpoint(&state));
    throw_on_petsc_error(driver->resume());
    PetscPrintf(
        comm, "hexcut: restarting from %s at step %lld, t = %g s (%lld cut links restored)\n",
        paths.final_path.c_str(), (long long)state.step, state.time, (long long)links.size());
  } else {
    throw_on_petsc_error(driver->begin());
  }
  first_step = state.step;
  PetscTime(&t_loop);
  try {
    bool reached_end = false;
    throw_on_petsc_error(driver->run(max_steps, &reached_end));
    if (!reached_end)
      PetscPrintf(
          comm,
          "hexcut: stopped after %lld steps (-hexcut_max_steps); continue with --restart %s\n",
          (long long)max_steps, paths.final_path.c_str());
  } catch (const SolverError&) {
    // What was written stays: the earlier result, when this run was to replace it, is
    // untouched, and this run's steps are in its own file.
    warn_unused_options(comm, options.user_options);
    if (paths.replaces)
      PetscFPrintf(comm, PETSC_STDERR,
                   "hexcut: %s is unchanged; the steps this run completed are in %s\n",
                   paths.final_path.c_str(), paths.write_path.c_str());
    throw;
  }
  driver.reset();
  out.reset();
  sim.reset();
  commit_result(comm, paths);
  PetscLogDouble t_end;
  PetscTime(&t_end);
  double peak = peak_memory_bytes(), total_peak = 0, max_peak = 0;
  MPI_Allreduce(&peak, &total_peak, 1, MPI_DOUBLE, MPI_SUM, comm);
  MPI_Allreduce(&peak, &max_peak, 1, MPI_DOUBLE, MPI_MAX, comm);
  std::string indexes;  // the indexes that exist (the surface one only with surfaces)
  for (const auto& index : output::index_paths(paths.final_path))
    if (std::filesystem::exists(index)) indexes += " and " + index;
  int size = 1;
  MPI_Comm_size(comm, &size);
  char per_rank[64] = "";
  if (size > 1)
    std::snprintf(per_rank, sizeof per_rank, ", %.1f MiB on the largest rank",
                  max_peak / (1024.0 * 1024.0));
  PetscPrintf(comm, "hexcut: wrote %s%s (%.2f s, peak memory %.1f MiB over all ranks%s)\n",
              paths.final_path.c_str(), indexes.c_str(), t_end - t_start,
              total_peak / (1024.0 * 1024.0), per_rank);
  warn_unused_options(comm, options.user_options);
  throw_on_petsc_error(an::destroy_state(&state));
  throw_on_petsc_error(an::destroy_model(&model));
}

}  // namespace hexcut::app
