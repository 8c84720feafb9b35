#include "analysis/energy.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace hexcut::analysis {

PetscErrorCode EnergyMonitor::add(const StepEnergy& e, std::int64_t step, double t) {
  PetscFunctionBeginUser;
  if (!started_) {
    initial_ = e.kinetic0 + e.strain0;
    started_ = true;
  }
  energy_ = e.kinetic1 + e.strain1;
  work_ += e.external_work + e.support_work;
  max_work_ = std::max(max_work_, work_);
  dissipated_ += e.dissipated;
  created_ += e.created();
  supplied_ = initial_ + max_work_;
  peak_ = std::max(peak_, energy_);
  // Round-off creates energy of the order of 1e-16 of the energies involved; the floor
  // keeps it from tripping the check where nothing was supplied (a body at rest).
  const double floor = 1e-10 * std::max(supplied_, peak_);
  if (!std::isfinite(created_) || !std::isfinite(energy_) ||
      created_ > tolerance_ * supplied_ + floor) {
    char msg[512];
    std::snprintf(msg, sizeof msg,
                  "energy check: by step %lld (t = %g s) the time integration created %.4g J, "
                  "more than analysis.energy_tolerance = %g times the energy supplied (%.4g J: "
                  "initial %.4g J + work of loads and supports %.4g J); kinetic + strain energy "
                  "is now %.4g J. The time integration is not energy-consistent here: with "
                  "analysis.rotations: lagged use iterated (the default), else a smaller "
                  "analysis.dt (doc/theory.md, \"Energy balance\")",
                  (long long)step, t, created_, tolerance_, supplied_, initial_, max_work_,
                  energy_);
    SETERRQ(comm_, PETSC_ERR_NOT_CONVERGED, "%s", msg);
  }
  PetscFunctionReturn(0);
}

std::string EnergyMonitor::summary() const {
  if (!started_) return "";
  char buf[96];
  std::snprintf(buf, sizeof buf, "E %.5g J  created %.2g J", energy_, created_);
  return buf;
}

}  // namespace hexcut::analysis
