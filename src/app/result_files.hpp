// Where a run writes its result, and the rules that keep a user's results safe
// (doc/user-guide.md, "Result files"):
//  - one run at a time per result: an exclusive lock (flock) on "<result>.lock" beside it,
//    held by rank 0 for the whole run and released by the kernel even when the run is
//    killed, so a second run on the same result is refused at start and never touches it;
//  - an existing result is never replaced unless asked (--overwrite or output.overwrite):
//    then the run writes "NAME.new.h5" and renames it over "NAME.h5" only when it ends
//    successfully, so a failed rerun leaves the earlier result as it was.
#pragma once

#include <mpi.h>

#include <string>

#include "app/job.hpp"
#include "deck/deck.hpp"

namespace hexcut::app {

/// The exclusive lock of one result file. Collective: rank 0 takes it, every rank learns
/// the outcome. Throws InputError when another process holds it (naming that process).
class ResultLock {
 public:
  ResultLock(MPI_Comm comm, const std::string& result_path);
  ~ResultLock();  // releases the lock (the lock file stays: removing it would race)
  ResultLock(const ResultLock&) = delete;
  ResultLock& operator=(const ResultLock&) = delete;
  /// "<result without .h5>.lock".
  static std::string path_for(const std::string& result_path);

 private:
  int fd_ = -1;  // rank 0 only
};

/// The result of one run: where it ends up and where the run writes it.
struct ResultPaths {
  std::string final_path;  // output.directory/NAME.h5, or the --restart file
  std::string write_path;  // final_path, or output.directory/NAME.new.h5 when replacing
  bool replaces = false;   // write_path != final_path: rename at the end (commit_result)
};

/// Why the output directory cannot be created and written (its nearest existing part is not a
/// writable directory), or "" when it can. --check reports it; a run refuses to start.
std::string output_directory_problem(const std::string& directory);

/// "output.directory/NAME.h5" of a deck.
std::string result_path(const deck::Deck& deck);

/// Decides where the run writes (the lock on final_path must be held). Creates the output
/// directory. Collective. Throws InputError (exit 2) when final_path exists and neither
/// --overwrite nor output.overwrite is given (fresh runs), or when the restart file does
/// not exist.
ResultPaths plan_result(MPI_Comm comm, const deck::Deck& deck, const JobOptions& options);

/// After a successful run that replaces an earlier result: renames write_path over
/// final_path (atomic within a file system), writes the XDMF indexes for the final name
/// (output::write_indexes) and removes the temporary ones (output::index_paths). No-op when
/// paths.replaces is false. Collective.
void commit_result(MPI_Comm comm, const ResultPaths& paths);

}  // namespace hexcut::app
