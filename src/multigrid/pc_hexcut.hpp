// hexcut's multigrid as a PETSc preconditioner type, PCHEXCUT = "hexcut" (doc/user-guide.md,
// "Solvers"). Registered with PCRegister, so `-pc_type hexcut` selects it like any PETSc PC and
// `-pc_type gamg` replaces it like any other; its options (-gmg_*, under the PC's options prefix)
// are read by PCSetFromOptions in a PetscOptions block with help text, so `hexcut deck.yaml
// -help` lists them. The PC applies one cycle (V or W) of a Multigrid that the analysis builds
// for its model and hands over with pc_set_multigrid: the hierarchy needs the lattice, which a
// PC cannot get from its operator.
#pragma once

#include <petscpc.h>

#include "multigrid/gmg.hpp"

namespace hexcut::multigrid {

/// The type name: "hexcut".
extern const char* const PCHEXCUT;

/// Registers PCHEXCUT (once per process; later calls do nothing). Call before any
/// KSPSetFromOptions that may select it.
PetscErrorCode register_pc();

/// The options the PC read in its last PCSetFromOptions (defaults if it was never called).
/// pc must be of type PCHEXCUT.
PetscErrorCode pc_get_options(PC pc, Options* options);

/// The multigrid the PC applies (not owned; it must outlive the PC's use). pc must be of
/// type PCHEXCUT; applying it without a multigrid is an error.
PetscErrorCode pc_set_multigrid(PC pc, Multigrid* mg);

}  // namespace hexcut::multigrid
