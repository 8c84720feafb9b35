// Newmark (average acceleration) on a free-vibrating cantilever: the undamped linear
// system conserves energy to round-off, and the first bending period matches beam
// theory (Euler-Bernoulli with the Timoshenko shear and rotary-inertia correction).
#include <cmath>

#include "fixture.hpp"

namespace hexcut::testing {
namespace {

TEST(Dynamic, FreeVibrationConservesEnergyAndHasBeamPeriod) {
  const double L = 1.0, b = 0.1, t = 0.1, E = 200e9, nu = 0.3, rho = 7800;
  const double h = 0.025;
  const double A = b * t, I = b * t * t * t / 12;
  // Euler-Bernoulli first clamped-free mode: omega = (1.8751)^2 sqrt(EI / (rho A L^4)).
  const double beta = 1.875104;
  const double omega_eb = beta * beta * std::sqrt(E * I / (rho * A * L * L * L * L));
  const double period_eb = 2 * M_PI / omega_eb;
  const double dt = period_eb / 100;

  // Initial state: the static deflection under a tip load, released at t = 0.
  Job loaded(PETSC_COMM_WORLD,
             cantilever_deck(h, "{type: static}", "{type: direct}", L, b, t, 1000.0));
  loaded.run();
  const std::string dyn =
      "{type: dynamic, dt: " + std::to_string(dt) + ", steps: 1000, mass: consistent}";
  std::string yaml = cantilever_deck(h, dyn, "{type: direct}", L, b, t, 0.0);
  Job job(PETSC_COMM_WORLD, yaml);
  VecCopy(loaded.state.u, job.state.u);
  job.initial_acceleration();

  const double e0 = job.energy();
  ASSERT_GT(e0, 0.0);
  // Tip deflection history: mean uz over the copies at x = L (owned by this rank).
  const auto& D = job.model.layout;
  std::vector<std::int32_t> tip;
  for (std::int32_t i = 0; i < D.num_owned; ++i)
    if (std::abs(job.position(D.copies[i])[0] - L) < 1e-9) tip.push_back(i);
  auto tip_uz = [&]() {
    const PetscScalar* a;
    VecGetArrayRead(job.state.u, &a);
    double s = 0, n = double(tip.size());
    for (auto i : tip) s += a[3 * i + 2];
    VecRestoreArrayRead(job.state.u, &a);
    MPI_Allreduce(MPI_IN_PLACE, &s, 1, MPI_DOUBLE, MPI_SUM, PETSC_COMM_WORLD);
    MPI_Allreduce(MPI_IN_PLACE, &n, 1, MPI_DOUBLE, MPI_SUM, PETSC_COMM_WORLD);
    return s / n;
  };
  double max_drift = 0;
  std::vector<double> crossings;
  double prev = tip_uz(), prev_t = 0;
  for (int n = 0; n < 1000; ++n) {
    job.newmark_step();
    const double e = job.energy();
    max_drift = std::max(max_drift, std::abs(e - e0) / e0);
    const double cur = tip_uz();
    if ((prev < 0) != (cur < 0)) crossings.push_back(prev_t + dt * prev / (prev - cur));
    prev = cur;
    prev_t = job.state.time;
  }
  EXPECT_LT(max_drift, 1e-9) << "energy drift";
  ASSERT_GE(crossings.size(), 10u);
  const double period = 2 * (crossings.back() - crossings.front()) / double(crossings.size() - 1);
  // Timoshenko correction of the first mode for shear and rotary inertia (slender
  // beam, first order): omega_T / omega_EB ~ 1 - (beta^2/2) (r/L)^2 (1 + E/(kappa G)).
  const double kappa = 10 * (1 + nu) / (12 + 11 * nu), G = E / (2 * (1 + nu));
  const double r2 = I / A;
  const double corr = 1 - 0.5 * beta * beta * (r2 / (L * L)) * (1 + E / (kappa * G));
  const double period_beam = period_eb / corr;
  std::printf("period %.6f s, beam theory %.6f s (EB %.6f), deviation %.2f%%, energy drift %.2e\n",
              period, period_beam, period_eb, 100 * (period / period_beam - 1), max_drift);
  EXPECT_LT(std::abs(period / period_beam - 1), 0.03);
}

// A corotational step keeps the rotations its energy balance computed at the end-of-step
// displacement for the next step's operator (Simulation::refresh_rotations). Changing the
// displacement in between (a restart, a caller's edit) must drop them: the next step then
// equals that of a fresh simulation started from the changed state.
TEST(Dynamic, KeptRotationsAreDroppedWhenTheDisplacementChanges) {
  const std::string yaml = cantilever_deck(
      0.05, "{type: dynamic, formulation: corotational, rotations: lagged, dt: 0.01, steps: 4}",
      "{type: direct}", 0.6, 0.1, 0.1, 2.0e5);
  Job a(PETSC_COMM_WORLD, yaml), b(PETSC_COMM_WORLD, yaml);
  a.initial_acceleration();
  a.newmark_step();
  // Turn the displaced body by 40 degrees about the beam's axis (u <- Q (x + u) - x): the
  // rotations a kept are now wrong by that much.
  const double c = std::cos(0.7), s = std::sin(0.7);
  const auto& D = a.model.layout;
  PetscScalar* u;
  VecGetArray(a.state.u, &u);
  for (std::int32_t i = 0; i < D.num_owned; ++i) {
    const auto x = a.position(D.copies[i]);
    const double y = x[1] + u[3 * i + 1], z = x[2] + u[3 * i + 2];
    u[3 * i + 1] = c * y - s * z - x[1];
    u[3 * i + 2] = s * y + c * z - x[2];
  }
  VecRestoreArray(a.state.u, &u);
  VecCopy(a.state.u, b.state.u);
  VecCopy(a.state.v, b.state.v);
  VecCopy(a.state.a, b.state.a);
  b.state.time = a.state.time;
  b.state.step = a.state.step;
  a.newmark_step();
  b.newmark_step();
  EXPECT_LT(rel_max_difference(b.state.u, a.state.u), 1e-12);
}

}  // namespace
}  // namespace hexcut::testing
