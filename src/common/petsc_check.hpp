// Bridges PETSc error codes into C++ exceptions for code that is not a PetscErrorCode
// function (constructors, drivers). PETSc has already printed its traceback.
#pragma once

#include <petscsys.h>

#include <stdexcept>
#include <string>
#include <vector>

#include "common/errors.hpp"

namespace hexcut {

inline void check_petsc(PetscErrorCode ierr, const char* what) {
  if (ierr)
    throw std::runtime_error(std::string("PETSc error ") + std::to_string(int(ierr)) + " in " +
                             what);
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

/// Runs `call`, a step that reads the user's PETSc options (solver types, numbers): an
/// error there is a mistake in the input, so it becomes an InputError carrying PETSc's own
/// message (exit 2) instead of PETSc's traceback (exit 1). `call` may use check_petsc.
template <class F>
decltype(auto) parse_petsc_options(F&& call) {
  struct Quiet {  // PETSc's error handlers print; this one only returns the code
    Quiet() { PetscPushErrorHandler(PetscReturnErrorHandler, nullptr); }
    ~Quiet() { PetscPopErrorHandler(); }
  } quiet;
  try {
    return call();
  } catch (const InputError&) {
    throw;
  } catch (const std::runtime_error& e) {
    char* specific = nullptr;
    PetscErrorMessage(0, nullptr, &specific);  // the message of the error that started it
    throw InputError(std::string("invalid PETSc option: ") +
                     (specific && *specific ? specific : e.what()));
  }
}

}  // namespace hexcut
