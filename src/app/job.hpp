// One hexcut job: deck -> model -> analysis -> result file. main() only parses the
// command line and maps exceptions to exit codes.
#pragma once

#include <mpi.h>

#include <string>

#include "deck/deck.hpp"

namespace hexcut::app {

struct JobOptions {
  std::string restart_path;  // --restart FILE: continue from FILE's last checkpoint
  std::string command_line;  // stored in the result file
};

/// Runs the job. Throws InputError, SolverError or std::exception.
void run_job(MPI_Comm comm, const deck::Deck& deck, const JobOptions& options);

/// Validates the deck fully without solving: parses it, voxelizes the body and
/// resolves every selector. Throws InputError like run_job would.
void check_job(MPI_Comm comm, const deck::Deck& deck);

/// Reads the deck on rank 0, broadcasts it, and parses it on every rank.
deck::Deck read_deck(MPI_Comm comm, const std::string& path);

}  // namespace hexcut::app
