// One hexcut job: deck -> model -> analysis -> result file. main() only parses the
// command line and maps exceptions to exit codes. The job calls the analysis, whose PETSc
// errors travel as error codes, through the one boundary that turns them into those
// exceptions (throw_on_petsc_error, common/petsc_check.hpp).
#pragma once

#include <mpi.h>

#include <string>

#include "deck/deck.hpp"

namespace hexcut::app {

struct JobOptions {
  std::string restart_path;  // --restart FILE: continue from FILE's last checkpoint
  std::string command_line;  // stored in the result file
  bool overwrite = false;    // --overwrite: replace an existing result when the run ends
  bool check_only = false;   // --check
};

/// Runs the job. Throws InputError, SolverError or std::exception.
void run_job(MPI_Comm comm, const deck::Deck& deck, const JobOptions& options);

/// Validates the job without solving or writing: the options (hexcut's and PETSc's, by
/// creating the solver), the body (voxelized, every selector resolved), and for static
/// analyses the cuts (applied) and the supports of every piece. Throws what run_job
/// would before its first step: InputError, or SolverError for a piece the supports
/// leave free to move.
void check_job(MPI_Comm comm, const deck::Deck& deck, const JobOptions& options);

/// Reads the deck on rank 0, broadcasts it, and parses it on every rank.
deck::Deck read_deck(MPI_Comm comm, const std::string& path);

}  // namespace hexcut::app
