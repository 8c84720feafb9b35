// PETSc log events of hexcut's stages, so -log_view shows where the time goes.
#pragma once

#include <petsclog.h>

namespace hexcut::analysis {

struct Events {
  // setup (the model) holds voxelize (the body on the lattice) and topology (vertex copies,
  // partition, DOF layout, boundary data).
  PetscLogEvent setup, voxelize, topology, assembly, solve, stress, output, cut_links, rebuild,
      energy;
};

/// Registers the events once (idempotent) and returns them. The registration's error codes
/// are not checked: it runs in a static initializer, which cannot return one, and a failed
/// registration costs only the event in -log_view.
const Events& events();

/// A PETSc log event for the scope. RAII rather than PetscCall(PetscLogEventBegin/End): the
/// event is closed on every way out of the scope, an error return included (a PetscCall that
/// fails returns before a closing call), and a logging call has no error worth reporting in
/// hexcut's place, so the codes are not checked.
class EventScope {
 public:
  explicit EventScope(PetscLogEvent e) : e_(e) { PetscLogEventBegin(e_, 0, 0, 0, 0); }
  ~EventScope() { PetscLogEventEnd(e_, 0, 0, 0, 0); }
  EventScope(const EventScope&) = delete;
  EventScope& operator=(const EventScope&) = delete;

 private:
  PetscLogEvent e_;
};

}  // namespace hexcut::analysis
