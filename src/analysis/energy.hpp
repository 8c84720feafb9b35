// Energy balance of a dynamic run (doc/theory.md "Energy balance"): what each time step
// did to the kinetic and strain energy, what the loads and supports put in and what the
// damping took out, and the rest, the energy the time integration itself created. A run
// whose scheme creates energy (lagged rotations, a step that is not energy-consistent)
// is stopped with a solver failure (PETSC_ERR_NOT_CONVERGED, exit 3) instead of ending with
// exit 0.
#pragma once

#include <petscsys.h>

#include <cstdint>
#include <string>

namespace hexcut::analysis {

/// The energy terms of one time step from t_n to t_n+1 [J].
struct StepEnergy {
  double kinetic0 = 0, kinetic1 = 0;  ///< 1/2 v^T M v at t_n and t_n+1
  double strain0 = 0, strain1 = 0;    ///< sum over cells of 1/2 d^T K d (corotated d)
  double external_work = 0;           ///< (u_n+1 - u_n) . (f(t_n) + f(t_n+1))/2: loads
  double support_work = 0;            ///< the same with the support reactions
  double dissipated = 0;              ///< (u_n+1 - u_n)^T D (u_n+1 - u_n)/dt >= 0: damping
  /// Energy the scheme created in the step (0 for an energy-consistent one):
  /// change of kinetic + strain energy - work done on the body + dissipated energy.
  double created() const {
    return kinetic1 + strain1 - kinetic0 - strain0 - external_work - support_work + dissipated;
  }
};

/// Sums the steps' energy terms and checks them.
///
/// supplied = E_0 + max(0, max over steps of the net work of loads and supports so far),
/// E_0 the kinetic + strain energy before the first step this monitor saw (after a
/// restart: at the checkpoint). The run stops when the created energy (summed over steps)
/// exceeds tolerance * supplied. Linear runs create energy only by round-off and solver
/// tolerance; the mid-point corotational step little (second order in the rotation per step).
class EnergyMonitor {
 public:
  /// The steps' energies are the same on every rank of `comm` (they are sums over it).
  EnergyMonitor(MPI_Comm comm, double tolerance) : comm_(comm), tolerance_(tolerance) {}
  /// Adds the step that ended at `step`, time `t` [s]. PETSC_ERR_NOT_CONVERGED on the
  /// communicator when the created energy exceeds tolerance * supplied.
  PetscErrorCode add(const StepEnergy& e, std::int64_t step, double t);
  double energy() const { return energy_; }      ///< kinetic + strain after the last step [J]
  double created() const { return created_; }    ///< sum of StepEnergy::created() [J]
  double supplied() const { return supplied_; }  ///< see above [J]
  double dissipated() const { return dissipated_; }
  /// "E 1.234 J  created 5.6e-09 J" for the progress line (empty before the first step).
  std::string summary() const;

 private:
  MPI_Comm comm_;
  double tolerance_;
  bool started_ = false;
  double initial_ = 0, energy_ = 0, work_ = 0, max_work_ = 0, created_ = 0, supplied_ = 0,
         dissipated_ = 0, peak_ = 0;
};

}  // namespace hexcut::analysis
