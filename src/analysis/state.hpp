// The solution state a run carries from step to step.
#pragma once

#include <petscdm.h>
#include <petscvec.h>

#include <cstdint>

namespace hexcut::analysis {

/// Displacement u [m], velocity v [m/s] and acceleration a [m/s^2] as global vectors of
/// the model's DM (3 DOFs per owned vertex copy), at `time` [s] after `step` steps.
struct State {
  Vec u = nullptr, v = nullptr, a = nullptr;
  double time = 0.0;
  std::int64_t step = 0;
};

/// Creates the three vectors of `dm`, zeroed; u is named "displacement".
PetscErrorCode create_state(DM dm, State* s);
PetscErrorCode destroy_state(State* s);

}  // namespace hexcut::analysis
