// PETSc log events of hexcut's stages, so -log_view shows where the time goes.
#pragma once

#include <petsclog.h>

namespace hexcut::analysis {

struct Events {
  PetscLogEvent setup, assembly, solve, stress, output, cut_links, rebuild, energy;
};

/// Registers the events once (idempotent) and returns them.
const Events& events();

}  // namespace hexcut::analysis
