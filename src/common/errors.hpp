// Error types shared by every stage. They map one-to-one onto hexcut's exit codes
// (doc/user-guide.md, "Exit codes"), so main() only has to catch and translate.
#pragma once

#include <stdexcept>
#include <string>

namespace hexcut {

/// Exit codes of the hexcut executable.
enum ExitCode : int { kExitOk = 0, kExitOther = 1, kExitInvalidInput = 2, kExitSolverFailure = 3 };

/// Invalid input: a deck, mesh or image that cannot be used. The message is already
/// prefixed with "file:line: " when a location is known. Exit code 2.
class InputError : public std::runtime_error {
 public:
  explicit InputError(const std::string& message) : std::runtime_error(message) {}
  InputError(const std::string& file, int line, const std::string& message)
      : std::runtime_error(file + ":" + std::to_string(line) + ": " + message) {}
};

/// A solve that diverged or did not converge within its limits. Exit code 3. Below src/app
/// such a failure is a PETSC_ERR_NOT_CONVERGED error code; the app's boundary
/// (throw_on_petsc_error, common/petsc_check.hpp) turns it into this.
class SolverError : public std::runtime_error {
 public:
  explicit SolverError(const std::string& message) : std::runtime_error(message) {}
};

}  // namespace hexcut
