#include "analysis/events.hpp"

namespace hexcut::analysis {

const Events& events() {
  static Events e = [] {
    Events r{};
    PetscClassId id;
    PetscClassIdRegister("hexcut", &id);
    PetscLogEventRegister("hexcutSetup", id, &r.setup);
    PetscLogEventRegister("hexcutAssembly", id, &r.assembly);
    PetscLogEventRegister("hexcutSolve", id, &r.solve);
    PetscLogEventRegister("hexcutStress", id, &r.stress);
    PetscLogEventRegister("hexcutOutput", id, &r.output);
    // Link tests, topology rebuild, state transfer and the new solver/hierarchy.
    PetscLogEventRegister("hexcutCut", id, &r.cut);
    return r;
  }();
  return e;
}

}  // namespace hexcut::analysis
