// hexcut's PETSc conventions and its one error boundary (doc/theory.md, "Architecture",
// "Errors"). Below src/app the code is PETSc's: PetscErrorCode functions, PetscCall, SETERRQ
// and PetscCheck(..., PETSC_COMM_SELF, ...) for rank-local conditions. hexcut's own solver
// failures are PETSC_ERR_NOT_CONVERGED errors and mistakes in the user's PETSc options
// PETSC_ERR_USER_INPUT errors, each with hexcut's message. The app turns an error code into an
// exception once, with throw_on_petsc_error, and main() maps the exceptions to exit codes.
//
// Validation of the input that is not PETSc work (deck, model, memory, the restart checks, a
// load or support expression that is not finite) throws InputError where it is found, also
// from within PetscErrorCode functions. That is safe because this PETSc is an optimized build
// (PETSC_USE_DEBUG is not defined: PetscFunctionBeginUser pushes nothing onto PETSc's stack that
// an exception would leave behind), and what a scope borrowed from PETSc is given back by RAII
// (ScratchVec, assembly::LocalValues) on every way out, error codes and exceptions alike.
#pragma once

#include <petscsys.h>

#include <stdexcept>
#include <string>
#include <vector>

#include "common/errors.hpp"

namespace hexcut {

/// PETSc's message of the error that started the one being handled (PetscErrorMessage's
/// "specific" text: the SETERRQ message, of which PETSc keeps the first 1023 characters).
inline std::string petsc_error_message() {
  char* specific = nullptr;
  PetscErrorMessage(0, nullptr, &specific);
  return specific ? specific : "";
}

/// The boundary between PETSc's error codes and hexcut's exceptions (src/app and the tests
/// call the analysis through it): nothing when ierr is 0, else an exception with PETSc's
/// message of the error that started it: PETSC_ERR_NOT_CONVERGED (a solver failure) throws
/// SolverError (exit 3), PETSC_ERR_USER_INPUT InputError (exit 2), any other code
/// std::runtime_error (exit 1; PETSc printed its traceback), naming `what` when given.
inline void throw_on_petsc_error(PetscErrorCode ierr, const char* what = nullptr) {
  if (!ierr) return;
  const std::string message = petsc_error_message();
  if (ierr == PETSC_ERR_NOT_CONVERGED) throw SolverError(message);
  if (ierr == PETSC_ERR_USER_INPUT) throw InputError(message);
  std::string text = "PETSc error " + std::to_string(int(ierr));
  if (what) text += std::string(" in ") + what;
  if (!message.empty()) text += ": " + message;
  throw std::runtime_error(text);
}

/// throw_on_petsc_error naming the call (the app's option handling, tests).
inline void check_petsc(PetscErrorCode ierr, const char* what) {
  throw_on_petsc_error(ierr, what);
}

/// hexcut's PETSc error handler, pushed after PetscInitialize (push_error_handler): hexcut's
/// own errors (PETSC_ERR_NOT_CONVERGED, PETSC_ERR_USER_INPUT) travel up the PetscCall frames
/// quietly, and the app prints their one-line message once ("hexcut: solver failure: ...");
/// every other error gets PETSc's traceback ("[0]PETSC ERROR: ...").
inline PetscErrorCode quiet_hexcut_errors(MPI_Comm comm, int line, const char* function,
                                          const char* file, PetscErrorCode n, PetscErrorType p,
                                          const char* message, void* ctx) {
  if (n == PETSC_ERR_NOT_CONVERGED || n == PETSC_ERR_USER_INPUT) return n;
  return PetscTraceBackErrorHandler(comm, line, function, file, n, p, message, ctx);
}

/// Installs quiet_hexcut_errors (main() after PetscInitialize; the tests' main).
inline PetscErrorCode push_error_handler() {
  return PetscPushErrorHandler(quiet_hexcut_errors, nullptr);
}

/// Sets option `name` (e.g. "-ksp_type") to `value` (nullptr: a flag) in the global
/// options database unless the user set it: hexcut's defaults, which the command line and
/// the deck's petsc_options override.
inline PetscErrorCode set_option_if_unset(const char* name, const char* value) {
  PetscFunctionBeginUser;
  PetscBool set = PETSC_FALSE;
  PetscCall(PetscOptionsHasName(nullptr, nullptr, name, &set));
  if (!set) PetscCall(PetscOptionsSetValue(nullptr, name, value));
  PetscFunctionReturn(0);
}

/// Options-database defaults for one object's set-up (e.g. BoomerAMG settings that have no
/// setter function): add() inserts an option only where the user did not set it, and the
/// destructor removes what it inserted, so the defaults reach what reads the database
/// within the scope (one KSPSetFromOptions) and never a later solver.
class ScopedOptionDefaults {
 public:
  ScopedOptionDefaults() = default;
  ScopedOptionDefaults(const ScopedOptionDefaults&) = delete;
  ScopedOptionDefaults& operator=(const ScopedOptionDefaults&) = delete;
  ~ScopedOptionDefaults() {
    for (const auto& name : inserted_) PetscOptionsClearValue(nullptr, name.c_str());
  }
  PetscErrorCode add(const char* name, const char* value) {
    PetscFunctionBeginUser;
    PetscBool set = PETSC_FALSE;
    PetscCall(PetscOptionsHasName(nullptr, nullptr, name, &set));
    if (!set) {
      PetscCall(PetscOptionsSetValue(nullptr, name, value));
      inserted_.emplace_back(name);
    }
    PetscFunctionReturn(0);
  }

 private:
  std::vector<std::string> inserted_;
};

/// Runs `call` (returns a PetscErrorCode), a step that reads the user's PETSc options
/// (solver types, numbers), with PETSc's error printing off: an error there is a mistake in
/// the input, so it comes back as PETSC_ERR_USER_INPUT on `comm` with PETSc's own message
/// ("invalid PETSc option: ...", exit 2) instead of PETSc's traceback (exit 1).
template <class F>
PetscErrorCode parse_petsc_options(MPI_Comm comm, F&& call) {
  PetscFunctionBeginUser;
  PetscErrorCode ierr = 0;
  {
    struct Quiet {  // PETSc's error handlers print; this one only returns the code
      Quiet() { PetscPushErrorHandler(PetscReturnErrorHandler, nullptr); }
      ~Quiet() { PetscPopErrorHandler(); }
    } quiet;
    ierr = call();
  }
  if (ierr) {
    std::string message = petsc_error_message();
    if (message.empty()) message = "PETSc error " + std::to_string(int(ierr));
    SETERRQ(comm, PETSC_ERR_USER_INPUT, "invalid PETSc option: %s", message.c_str());
  }
  PetscFunctionReturn(0);
}

}  // namespace hexcut
