// hexcut's own options (-hexcut_*), read from PETSc's options database (the command line
// and the deck's solver.petsc_options), and the warning for options nobody used.
// A typo in a hexcut option is an input error: it would otherwise be ignored silently
// (-hexcut_max_step 10 running every step); a typo in a PETSc option gets PETSc's warning.
#pragma once

#include <mpi.h>

#include <cstdint>
#include <set>
#include <string>

#include "deck/deck.hpp"
#include "topology/partition.hpp"

namespace hexcut::app {

struct HexcutOptions {
  int superblock = 8;  // -hexcut_superblock: cells per partition super-block side
  // -hexcut_partition metis|ptscotch|sfc: how super-blocks are assigned to ranks.
  topology::PartitionMethod partition = topology::PartitionMethod::metis;
  std::int64_t max_steps = -1;  // -hexcut_max_steps: stop after this many steps (-1: all)
  // -hexcut_refine R: the deck's lattice with cells R times smaller (h / R; dims * R rounded
  // up, so the lattice still covers the deck's box), for convergence and weak-scaling studies.
  double refine = 1.0;
  std::string output_directory;  // -hexcut_output_directory DIR: replaces output.directory
  // -hexcut_repartition X: after a cut, re-partition when the DOFs' max/mean over ranks
  // exceeds X (>= 1; 0: never).
  double repartition = 0;
  // -hexcut_io_buffer MiB: the MPI-IO collective buffer of the result files (0: the MPI
  // library's own default and hints).
  std::int64_t io_buffer_mib = 4;
};

/// Reads and validates every -hexcut_* option in the options database. Throws
/// InputError (exit 2) for an unknown -hexcut_* name (with the closest known one) or a
/// value of the wrong kind (-hexcut_max_steps abc, 0 or -3). Call after PetscInitialize
/// and after the deck's petsc_options are in the database.
HexcutOptions read_hexcut_options();

/// The deck as the run uses it: `deck` with the command line's -hexcut_refine and
/// -hexcut_output_directory applied. Throws InputError (exit 2) when the refined lattice has
/// more than 2e9 cells.
deck::Deck apply_overrides(const deck::Deck& deck, const HexcutOptions& options);

/// Names (lower case, with '-') of every option now in the database: call right after
/// PetscInitialize and after the deck's options went in, before hexcut's own defaults.
std::set<std::string> options_in_database();

/// Prints PETSc's "WARNING! There are options you set that were not used!" for the
/// options in `user_options` that nothing queried (PETSc itself prints it only in debug
/// builds or with -options_left, which this leaves to PETSc). Collective.
void warn_unused_options(MPI_Comm comm, const std::set<std::string>& user_options);

}  // namespace hexcut::app
