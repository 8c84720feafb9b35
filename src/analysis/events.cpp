#include "analysis/events.hpp"

namespace hexcut::analysis {

const Events& events() {
  static Events e = [] {
    Events r{};
    PetscClassId id;
    PetscClassIdRegister("hexcut", &id);
    PetscLogEventRegister("hexcutSetup", id, &r.setup);
    PetscLogEventRegister("hexcutVoxelize", id, &r.voxelize);
    PetscLogEventRegister("hexcutTopology", id, &r.topology);
    PetscLogEventRegister("hexcutAssembly", id, &r.assembly);
    PetscLogEventRegister("hexcutSolve", id, &r.solve);
    PetscLogEventRegister("hexcutStress", id, &r.stress);
    PetscLogEventRegister("hexcutOutput", id, &r.output);
    // A cut: the link tests, then the topology rebuild (vertex copies, layout, DM, state
    // transfer, and the new solver with its multigrid hierarchy).
    PetscLogEventRegister("hexcutCutLinks", id, &r.cut_links);
    PetscLogEventRegister("hexcutRebuild", id, &r.rebuild);
    // Dynamics: the mid-point internal forces of the corotational step and the energy
    // terms of each step (doc/theory.md "Energy balance").
    PetscLogEventRegister("hexcutEnergy", id, &r.energy);
    return r;
  }();
  return e;
}

}  // namespace hexcut::analysis
