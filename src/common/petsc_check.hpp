// Bridges PETSc error codes into C++ exceptions for code that is not a PetscErrorCode
// function (constructors, drivers). PETSc has already printed its traceback.
#pragma once

#include <petscsys.h>

#include <stdexcept>
#include <string>

namespace hexcut {

inline void check_petsc(PetscErrorCode ierr, const char* what) {
  if (ierr) throw std::runtime_error(std::string("PETSc error ") + std::to_string(int(ierr)) + " in " + what);
}

}  // namespace hexcut
