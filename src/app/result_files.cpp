#include "app/result_files.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "common/errors.hpp"
#include "common/mpi_gather.hpp"
#include "output/result_writer.hpp"

namespace hexcut::app {
namespace {

namespace fs = std::filesystem;

/// Rank 0 runs `f`, which returns an error message ("" = fine); every rank throws
/// InputError with it, so all ranks leave together.
template <class F>
void on_rank0_or_throw(MPI_Comm comm, F&& f) {
  int rank;
  MPI_Comm_rank(comm, &rank);
  std::string error;
  if (rank == 0) {
    try {
      error = f();
    } catch (const std::exception& e) {
      error = e.what();
    }
  }
  broadcast_string(comm, &error);
  if (!error.empty()) throw InputError(error);
}

std::string stem_of(const std::string& path) {
  const std::string ext = ".h5";
  if (path.size() > ext.size() && path.compare(path.size() - ext.size(), ext.size(), ext) == 0)
    return path.substr(0, path.size() - ext.size());
  return path;
}

std::string hostname() {
  char buf[256] = "";
  gethostname(buf, sizeof buf - 1);
  return buf;
}

}  // namespace

std::string output_directory_problem(const std::string& directory) {
  // The nearest part of the path that exists must be a writable directory: then every
  // missing part below it can be created.
  std::error_code ec;
  fs::path p = fs::absolute(directory, ec);
  while (!p.empty() && !fs::exists(p, ec) && p != p.parent_path()) p = p.parent_path();
  const std::string head = "output directory '" + directory +
                           "' (output.directory, or -hexcut_output_directory) cannot be used: ";
  if (!fs::is_directory(p, ec)) return head + p.string() + " is not a directory";
  if (::access(p.c_str(), W_OK | X_OK) != 0) return head + p.string() + ": " + std::strerror(errno);
  return "";
}

std::string ResultLock::path_for(const std::string& result_path) {
  return stem_of(result_path) + ".lock";
}

ResultLock::ResultLock(MPI_Comm comm, const std::string& result_path) {
  int rank;
  MPI_Comm_rank(comm, &rank);
  on_rank0_or_throw(comm, [&]() -> std::string {
    const auto lock = path_for(result_path);
    const auto dir = fs::path(lock).parent_path();
    if (!dir.empty()) {
      if (auto problem = output_directory_problem(dir.string()); !problem.empty()) return problem;
      std::error_code ec;
      fs::create_directories(dir, ec);
      if (ec) return "cannot create the output directory " + dir.string() + ": " + ec.message();
    }
    fd_ = ::open(lock.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    if (fd_ < 0) return "cannot create the lock file " + lock + ": " + std::strerror(errno);
    if (::flock(fd_, LOCK_EX | LOCK_NB) != 0) {
      const int err = errno;
      std::ifstream in(lock);
      std::string holder;
      std::getline(in, holder);
      ::close(fd_);
      fd_ = -1;
      if (err != EWOULDBLOCK) return "cannot lock " + lock + ": " + std::strerror(err);
      return result_path + " is being written by another hexcut run" +
             (holder.empty() ? std::string() : " (" + holder + ")") +
             "; two runs must not write one result: wait for it to end or choose another "
             "output.name (lock: " +
             lock + ")";
    }
    // Who holds it, for the message another run prints.
    std::ostringstream who;
    const std::time_t now = std::time(nullptr);
    char when[64];
    std::strftime(when, sizeof when, "%Y-%m-%d %H:%M:%S", std::localtime(&now));
    who << "process " << ::getpid() << " on " << hostname() << ", started " << when << "\n";
    const auto text = who.str();
    if (::ftruncate(fd_, 0) != 0 || ::write(fd_, text.data(), text.size()) < 0) {
      // The lock holds without the note; only the message of a refused run is poorer.
    }
    return "";
  });
}

ResultLock::~ResultLock() {
  if (fd_ >= 0) ::close(fd_);  // closing the descriptor releases the flock
}

std::string result_path(const deck::Deck& deck) {
  return (fs::path(deck.output.directory) / (deck.output.name + ".h5")).string();
}

ResultPaths plan_result(MPI_Comm comm, const deck::Deck& deck, const JobOptions& options) {
  ResultPaths p;
  if (!options.restart_path.empty()) {
    p.final_path = p.write_path = options.restart_path;
    on_rank0_or_throw(comm, [&]() -> std::string {
      if (!fs::is_regular_file(p.final_path))
        return "--restart " + p.final_path + ": no such result file";
      return "";
    });
    return p;
  }
  p.final_path = p.write_path = result_path(deck);
  const bool overwrite = options.overwrite || deck.output.overwrite;
  on_rank0_or_throw(comm, [&]() -> std::string {
    std::error_code ec;
    fs::create_directories(deck.output.directory, ec);
    if (ec)
      return "cannot create the output directory " + deck.output.directory + ": " + ec.message();
    if (!fs::exists(p.final_path)) return "";
    if (!overwrite)
      return deck.path + ":" + std::to_string(deck.output.where.line) + ": " + p.final_path +
             " exists (the result of an earlier run); hexcut does not replace results unless "
             "told: --overwrite (or output.overwrite: true) replaces it when this run ends, "
             "--restart " +
             p.final_path + " continues it, or choose another output.name";
    return "";
  });
  if (overwrite) {
    int exists = 0, rank;
    MPI_Comm_rank(comm, &rank);
    if (rank == 0) exists = fs::exists(p.final_path);
    MPI_Bcast(&exists, 1, MPI_INT, 0, comm);
    if (exists) {
      p.write_path = stem_of(p.final_path) + ".new.h5";
      p.replaces = true;
    }
  }
  return p;
}

void commit_result(MPI_Comm comm, const ResultPaths& p) {
  if (!p.replaces) return;
  MPI_Barrier(comm);  // every rank has closed the file
  int rank;
  MPI_Comm_rank(comm, &rank);
  std::string error;
  if (rank == 0) {
    try {
      fs::rename(p.write_path, p.final_path);  // rename(2): atomic replace
      output::write_indexes(p.final_path);
      for (const std::string& index : output::index_paths(p.write_path)) fs::remove(index);
    } catch (const std::exception& e) {
      error = e.what();
    }
  }
  broadcast_string(comm, &error);
  if (!error.empty())
    throw std::runtime_error("could not replace " + p.final_path + " by " + p.write_path + ": " +
                             error);
}

}  // namespace hexcut::app
