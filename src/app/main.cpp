// hexcut: elastic bodies on voxel lattices, cut and solved with PETSc.
//   hexcut DECK.yaml [--restart RESULT.h5 | --overwrite] [PETSc options]
//   hexcut --check DECK.yaml
//   hexcut --version
// Exit codes: 0 ok, 1 other error, 2 invalid input, 3 solver failure.
#include <petscsys.h>

#include <cstring>
#include <iostream>
#include <new>
#include <string>
#include <vector>

#include "app/job.hpp"
#include "common/errors.hpp"
#include "common/petsc_check.hpp"
#include "hexcut_version.hpp"
#ifdef HEXCUT_HAVE_CUDA
#include "device_backend.hpp"  // -gmg_backend cuda
#endif

namespace {

const char* kUsage =
    "usage: hexcut DECK.yaml [--restart RESULT.h5 | --overwrite] [PETSc options]\n"
    "       hexcut --check DECK.yaml     validate the deck (and options) only\n"
    "       hexcut --version\n"
    "  --restart FILE   continue FILE (a result of the same deck) from its last checkpoint\n"
    "  --overwrite      replace an existing result of the same name when this run ends\n"
    "                   (same as output.overwrite: true; without it hexcut refuses)\n"
    "PETSc options on the command line override the deck's solver.petsc_options.\n"
    "hexcut options: -hexcut_superblock N (cells per partition block side, default 8),\n"
    "                -hexcut_partition metis|ptscotch|sfc (super-blocks to ranks),\n"
    "                -hexcut_repartition X (after a cut, re-partition when the DOFs'\n"
    "                max/mean over ranks exceeds X; 0 = never, the default),\n"
    "                -hexcut_max_steps N (stop after N steps; continue with --restart),\n"
    "                -hexcut_residual_history FILE (Krylov residuals of every solve),\n"
    "                -hexcut_refine R (the deck's lattice with cells R times smaller),\n"
    "                -hexcut_output_directory DIR (write the result there instead of\n"
    "                output.directory),\n"
    "                -hexcut_composite_rotate false (composite elements: rebuild blocks\n"
    "                by Galerkin products at rotation updates instead of rotating them)\n"
    "                -hexcut_composite_midpoint false (composite elements: mid-point\n"
    "                force from the fine cells instead of the composite level)\n"
    "                -hexcut_composite_carry false (composite elements: rebuild every\n"
    "                element after a cut, not only those the cut changed)\n"
    "Exit codes: 0 ok, 1 other error, 2 invalid input, 3 solver failure.\n"
    "See doc/user-guide.md for the deck reference.\n";

}  // namespace

int main(int argc, char** argv) {
  // hexcut's own flags are taken out before PETSc sees the rest.
  std::string deck_path, restart;
  bool check_only = false, overwrite = false;
  std::vector<char*> petsc_args{argv[0]};
  std::string command_line;
  for (int i = 0; i < argc; ++i) command_line += (i ? " " : "") + std::string(argv[i]);
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--version") {
      std::cout << "hexcut " << HEXCUT_VERSION << " (git " << HEXCUT_GIT_HASH << ")\n";
      return hexcut::kExitOk;
    } else if (a == "--help" || a == "-h") {
      std::cout << kUsage;
      return hexcut::kExitOk;
    } else if (a == "--check") {
      check_only = true;
    } else if (a == "--restart") {
      if (i + 1 >= argc) {
        std::cerr << "hexcut: --restart needs a result file\n" << kUsage;
        return hexcut::kExitInvalidInput;
      }
      restart = argv[++i];
    } else if (a == "--overwrite") {
      overwrite = true;
    } else if (a.rfind("--", 0) == 0) {
      // PETSc's options start with one '-'; a '--' word is a mistyped hexcut flag, and
      // ignoring it could start a fresh run over a partial result (--restrat FILE).
      std::cerr << "hexcut: unknown argument '" << a << "'\n" << kUsage;
      return hexcut::kExitInvalidInput;
    } else if (deck_path.empty() && a.size() > 0 && a[0] != '-') {
      deck_path = a;
    } else {
      petsc_args.push_back(argv[i]);
    }
  }
  if (deck_path.empty()) {
    std::cerr << "hexcut: no deck given\n" << kUsage;
    return hexcut::kExitInvalidInput;
  }
  if (check_only && (overwrite || !restart.empty())) {
    std::cerr << "hexcut: --check writes nothing; it takes no --restart or --overwrite\n";
    return hexcut::kExitInvalidInput;
  }
  if (overwrite && !restart.empty()) {
    std::cerr << "hexcut: --restart continues a result in place; --overwrite does not apply\n";
    return hexcut::kExitInvalidInput;
  }
  petsc_args.push_back(nullptr);
  int pargc = int(petsc_args.size()) - 1;
  char** pargv = petsc_args.data();
  if (PetscInitialize(&pargc, &pargv, nullptr, nullptr) != 0) return hexcut::kExitOther;
  // hexcut's own errors (solver failures, invalid input) reach the catch blocks below with
  // their one-line message, without PETSc's traceback (common/petsc_check.hpp).
  if (hexcut::push_error_handler() != 0) {
    PetscFinalize();
    return hexcut::kExitOther;
  }

#ifdef HEXCUT_HAVE_CUDA
  hexcut::multigrid::set_device_cycle_factory(hexcut::cuda::device_cycle,
                                              hexcut::cuda::device_count);
#endif
  int code = hexcut::kExitOk, rank = 0, size = 1;
  MPI_Comm_rank(PETSC_COMM_WORLD, &rank);
  MPI_Comm_size(PETSC_COMM_WORLD, &size);
  try {
    const auto deck = hexcut::app::read_deck(PETSC_COMM_WORLD, deck_path);
    hexcut::app::JobOptions options{restart, command_line, overwrite, check_only};
    if (check_only) {
      hexcut::app::check_job(PETSC_COMM_WORLD, deck, options);
    } else {
      hexcut::app::run_job(PETSC_COMM_WORLD, deck, options);
    }
  } catch (const std::bad_alloc&) {
    // Every rank holds the lattice description: one rank failing usually means all do.
    std::cerr << "hexcut: out of memory (rank " << rank
              << "): the job needs more memory than this machine has; see doc/user-guide.md, "
                 "\"Memory\"\n";
    if (size > 1) MPI_Abort(PETSC_COMM_WORLD, hexcut::kExitOther);
    code = hexcut::kExitOther;
  } catch (const hexcut::InputError& e) {
    // Input errors are found identically on every rank; rank 0 reports.
    if (rank == 0) std::cerr << e.what() << "\n";
    code = hexcut::kExitInvalidInput;
  } catch (const hexcut::SolverError& e) {
    if (rank == 0) std::cerr << "hexcut: solver failure: " << e.what() << "\n";
    code = hexcut::kExitSolverFailure;
  } catch (const std::exception& e) {
    std::cerr << "hexcut: error (rank " << rank << "): " << e.what() << "\n";
    // Other ranks may be waiting in a collective call: abort the whole job.
    if (size > 1) MPI_Abort(PETSC_COMM_WORLD, hexcut::kExitOther);
    code = hexcut::kExitOther;
  }
  PetscFinalize();
  return code;
}
