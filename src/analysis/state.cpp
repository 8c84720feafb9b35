#include "analysis/state.hpp"

namespace hexcut::analysis {

PetscErrorCode create_state(DM dm, State* s) {
  PetscFunctionBeginUser;
  PetscCall(DMCreateGlobalVector(dm, &s->u));
  PetscCall(PetscObjectSetName((PetscObject)s->u, "displacement"));
  PetscCall(VecDuplicate(s->u, &s->v));
  PetscCall(VecDuplicate(s->u, &s->a));
  PetscCall(VecSet(s->u, 0.0));
  PetscCall(VecSet(s->v, 0.0));
  PetscCall(VecSet(s->a, 0.0));
  PetscFunctionReturn(0);
}

PetscErrorCode destroy_state(State* s) {
  PetscFunctionBeginUser;
  PetscCall(VecDestroy(&s->u));
  PetscCall(VecDestroy(&s->v));
  PetscCall(VecDestroy(&s->a));
  PetscFunctionReturn(0);
}

}  // namespace hexcut::analysis
