// Energy of corotational dynamics (doc/theory.md "Mid-point corotational step", "Energy
// balance"): a free body spinning about a non-principal axis keeps its kinetic energy,
// centre of mass and angular momentum; a bar pinned at one end and swinging under gravity
// keeps kinetic + strain + gravitational energy; the energy bookkeeping of every step
// balances (linear Newmark with damping, loads and a moving support exactly, the
// mid-point corotational step nearly); and a run whose scheme creates energy (lagged
// rotations) is stopped.
#include <Eigen/Geometry>
#include <cmath>

#include "common/errors.hpp"
#include "fixture.hpp"

namespace hexcut::testing {
namespace {

/// Lumped mass per DOF and the rigid-body quantities of a state.
struct Probe {
  Job& job;
  Vec mass = nullptr;
  explicit Probe(Job& j) : job(j) {
    Vec ones;
    VecDuplicate(job.state.u, &ones);
    VecDuplicate(job.state.u, &mass);
    VecSet(ones, 1.0);
    assembly::apply(job.model.dm, job.model.layout, job.model.cells, {0.0, 1.0, true}, ones, mass);
    VecDestroy(&ones);
  }
  ~Probe() { VecDestroy(&mass); }

  /// Centre of mass [m] and angular momentum about the origin [kg m^2/s] of (u, v).
  void rigid(Eigen::Vector3d* centre, Eigen::Vector3d* momentum) const {
    const PetscScalar *m, *X, *u, *v;
    PetscInt n;
    VecGetLocalSize(job.state.u, &n);
    VecGetArrayRead(mass, &m);
    VecGetArrayRead(job.model.coordinates, &X);
    VecGetArrayRead(job.state.u, &u);
    VecGetArrayRead(job.state.v, &v);
    double s[7] = {0, 0, 0, 0, 0, 0, 0};
    for (PetscInt i = 0; i < n; i += 3) {
      const Eigen::Vector3d x(X[i] + u[i], X[i + 1] + u[i + 1], X[i + 2] + u[i + 2]);
      const Eigen::Vector3d p(m[i] * v[i], m[i + 1] * v[i + 1], m[i + 2] * v[i + 2]);
      const Eigen::Vector3d L = x.cross(p);
      for (int k = 0; k < 3; ++k) {
        s[k] += m[i + k] * x[k];
        s[3 + k] += L[k];
      }
      s[6] += m[i];
    }
    VecRestoreArrayRead(mass, &m);
    VecRestoreArrayRead(job.model.coordinates, &X);
    VecRestoreArrayRead(job.state.u, &u);
    VecRestoreArrayRead(job.state.v, &v);
    MPI_Allreduce(MPI_IN_PLACE, s, 7, MPI_DOUBLE, MPI_SUM, PETSC_COMM_WORLD);
    *centre = Eigen::Vector3d(s[0], s[1], s[2]) / s[6];
    *momentum = Eigen::Vector3d(s[3], s[4], s[5]);
  }

  /// v = omega x (X - c): a rigid spin of the undeformed body.
  void spin(const Eigen::Vector3d& omega, const Eigen::Vector3d& c) {
    const PetscScalar* X;
    PetscScalar* v;
    PetscInt n;
    VecGetLocalSize(job.state.v, &n);
    VecGetArrayRead(job.model.coordinates, &X);
    VecGetArray(job.state.v, &v);
    for (PetscInt i = 0; i < n; i += 3) {
      const Eigen::Vector3d w = omega.cross(Eigen::Vector3d(X[i], X[i + 1], X[i + 2]) - c);
      for (int k = 0; k < 3; ++k) v[i + k] = w[k];
    }
    VecRestoreArrayRead(job.model.coordinates, &X);
    VecRestoreArray(job.state.v, &v);
  }
};

// A rubber brick 0.4 x 0.2 x 0.1 m (8 x 4 x 2 cells), no supports, spinning at one
// revolution per second about an axis that is not a principal axis (so it tumbles),
// 1000 steps of 1 ms. Lagged rotations gain 8% kinetic energy here.
const std::string kSpinDeck =
    "lattice: {h: 0.05, dims: [8, 4, 2]}\n"
    "materials: {rubber: {E: 1.0e6, nu: 0.3, rho: 1000}}\n"
    "geometry: [{add: {box: {min: [0, 0, 0], max: [0.4, 0.2, 0.1]}}}]\n"
    "analysis: {type: dynamic, formulation: corotational, dt: 0.001, steps: 1000}\n"
    "solver: {type: cg-jacobi, rtol: 1.0e-12}\n";

TEST(CorotationalEnergy, FreeSpinningBodyKeepsEnergyCentreAndMomentum) {
  Job job(PETSC_COMM_WORLD, kSpinDeck);
  Probe probe(job);
  Eigen::Vector3d c0, L0;
  probe.rigid(&c0, &L0);
  probe.spin(2 * M_PI * Eigen::Vector3d(0.3, 0.2, 1.0).normalized(), c0);
  job.initial_acceleration();
  probe.rigid(&c0, &L0);
  const double k0 = job.kinetic_energy(job.state);
  double dk = 0, de = 0, dc = 0, dl = 0;
  int max_solves = 0;
  analysis::DriverHooks hooks;
  hooks.on_step = [&](const analysis::State& s) {
    max_solves = std::max(max_solves, job.sim->last_step_solves());
    const double k = job.kinetic_energy(s);
    const double e = k + job.elastic_energy(s);
    Eigen::Vector3d c, L;
    probe.rigid(&c, &L);
    dk = std::max(dk, std::abs(k / k0 - 1));
    de = std::max(de, std::abs(e / k0 - 1));
    dc = std::max(dc, (c - c0).norm());
    dl = std::max(dl, (L - L0).norm() / L0.norm());
  };
  // The driver checks the energy balance too: this run must pass it.
  job.run(hooks);
  EXPECT_EQ(job.state.step, 1000);
  std::printf(
      "spin: max |K/K0 - 1| %.2e, |(K + W)/K0 - 1| %.2e, centre of mass moved %.2e m, "
      "|dL|/|L| %.2e, at most %d solves per step\n",
      dk, de, dc, dl, max_solves);
  EXPECT_LT(dk, 0.01);  // kinetic energy: some is stored as centrifugal stretch
  EXPECT_LT(de, 1e-6);  // kinetic + strain (measured 7e-9)
  EXPECT_LT(dc, 1e-6);
  EXPECT_LT(dl, 1e-6);
}

// A rubber bar 0.4 x 0.05 x 0.1 m pinned along the line x = 0, z = 0.05 (it rotates
// about y), released horizontally under gravity: it swings down through 90 degrees and
// back up. Kinetic + strain + gravitational energy, -f_g . u for the constant gravity load.
void check_swinging_bar(double h, const std::string& extra) {
  const std::string yaml =
      "lattice: {h: " + std::to_string(h) + ", dims: [" + std::to_string(int(0.4 / h + 0.5)) +
      ", " + std::to_string(int(0.05 / h + 0.5)) + ", " + std::to_string(int(0.1 / h + 0.5)) +
      "]}\n"
      "materials: {rubber: {E: 1.0e6, nu: 0.3, rho: 1000}}\n"
      "geometry: [{add: {box: {min: [0, 0, 0], max: [0.4, 0.05, 0.1]}}}]\n"
      "boundary:\n"
      "  fixed: [{where: {box: {min: [-0.001, -0.01, 0.049], max: [0.001, 0.06, 0.051]}}}]\n"
      "  gravity: [0, 0, -9.81]\n"
      "analysis: {type: dynamic, formulation: corotational, dt: 0.005, steps: 240}\n"
      "solver: {type: direct}\n" +
      extra;
  Job job(PETSC_COMM_WORLD, yaml);
  job.initial_acceleration();
  Vec fg;
  VecDuplicate(job.state.u, &fg);
  assembly::assemble_loads(job.model.dm, job.model.layout, job.model.cells, job.model.boundary, 0.0,
                           1.0, fg);
  auto total = [&] {
    PetscScalar work;
    VecDot(fg, job.state.u, &work);
    return job.energy() - work;
  };
  // Scale: the potential energy the bar's centre of mass (at L/2) gives up in a quarter turn.
  const double m = 1000 * 0.4 * 0.05 * 0.1, drop = m * 9.81 * 0.2;
  const double e0 = total();
  double de = 0, lowest = 0;
  for (int n = 0; n < 240; ++n) {
    job.newmark_step();
    de = std::max(de, std::abs(total() - e0) / drop);
    PetscScalar work;
    VecDot(fg, job.state.u, &work);
    lowest = std::max(lowest, work / drop);
  }
  std::printf(
      "swing: gravity work at the lowest point %.3f x m g L/2, max |E - E0| %.2e x m g L/2\n",
      lowest, de);
  EXPECT_GT(lowest, 0.9);  // it did swing down through about 90 degrees
  EXPECT_LT(de, 0.01);
}

TEST(CorotationalEnergy, SwingingBarConservesTotalEnergy) {
  check_swinging_bar(0.05, "");
}

TEST(CorotationalEnergy, CompositeSwingingBarConservesTotalEnergy) {
  // Composite elements of level 1 (8 x 1 x 2 of them, h = 2.5 cm), one rotation each (their
  // mean deformation gradient's): the pin line (z = 5 cm) runs through composite vertices,
  // so it stays a pin.
  check_swinging_bar(0.025, "discretization: {type: composite, level: 1}\n");
}

// The step's energy terms balance for an energy-consistent scheme: what the loads (a ramp
// and gravity) and a support moving sinusoidally put in, less what Rayleigh damping takes
// out, is the change of kinetic + strain energy. Linear Newmark balances exactly for any
// data; the mid-point corotational step to second order in the step's rotation.
std::string driven_bar(const std::string& formulation, const std::string& mass) {
  return "lattice: {h: 0.05, dims: [8, 2, 2]}\n"
         "materials: {rubber: {E: 1.0e6, nu: 0.3, rho: 1000}}\n"
         "geometry: [{add: {box: {min: [0, 0, 0], max: [0.4, 0.1, 0.1]}}}]\n"
         "boundary:\n"
         "  fixed: [{where: {plane: {point: [0, 0, 0], normal: [1, 0, 0]}},\n"
         "           value: [0, {sine: {amplitude: 0.02, frequency: 3}}, 0]}]\n"
         "  traction: [{where: {plane: {point: [0.4, 0, 0], normal: [1, 0, 0]}},\n"
         "              value: [0, 0, -2.0e3], scale: {ramp: {value: 1, start: 0, end: 0.1}}}]\n"
         "  gravity: [0, 0, -9.81]\n"
         "analysis: {type: dynamic, formulation: " +
         formulation + ", dt: 0.005, steps: 100, rayleigh: [0.5, 0.002], mass: " + mass +
         "}\n"
         "solver: {type: direct}\n";
}

void expect_balanced(const std::string& yaml, double tol) {
  Job job(PETSC_COMM_WORLD, yaml);
  job.initial_acceleration();
  double created = 0, work = 0, support = 0, dissipated = 0, largest = 0;
  for (int n = 0; n < 100; ++n) {
    job.newmark_step();
    const auto& e = job.sim->last_step_energy();
    created += e.created();
    work += e.external_work;
    support += e.support_work;
    dissipated += e.dissipated;
    largest = std::max(largest, e.kinetic1 + e.strain1);
  }
  const double E = job.energy();
  std::printf("  loads %.4g J, supports %.4g J, damping %.4g J, now %.4g J: created %.2e J\n", work,
              support, dissipated, E, created);
  EXPECT_GT(std::abs(support), 0.1 * largest);  // every term matters
  EXPECT_GT(dissipated, 0.1 * largest);
  EXPECT_GT(std::abs(work), 0.1 * largest);
  EXPECT_LT(std::abs(created), tol * largest);
  EXPECT_NEAR(E, work + support - dissipated + created, 1e-9 * largest);
}

TEST(EnergyBalance, LinearNewmarkCreatesNoEnergy) {
  expect_balanced(driven_bar("linear", "consistent"), 1e-9);
}

TEST(EnergyBalance, LinearNewmarkOnCompositeElementsCreatesNoEnergy) {
  // The same on composite elements of level 1 (4 x 1 x 1 of them): the state stays in the
  // composite space and the step is its Galerkin projection, so the fine energies are the
  // composite ones and balance as exactly; the moving support is uniform over its face, so
  // the composite vertices on it move with it.
  expect_balanced(
      driven_bar("linear", "consistent") + "discretization: {type: composite, level: 1}\n", 1e-9);
  expect_balanced(driven_bar("linear", "lumped") + "discretization: {type: composite, level: 1}\n",
                  1e-9);
}

TEST(EnergyBalance, MidpointCorotationalStepNearlyBalances) {
  expect_balanced(driven_bar("corotational", "lumped"), 1e-4);  // measured 1.9e-5
  // Composite elements of level 1 with one rotation each.
  expect_balanced(
      driven_bar("corotational", "lumped") + "discretization: {type: composite, level: 1}\n", 1e-4);
}

TEST(EnergyBalance, CompositeMidpointForceOnEitherLevelGivesTheSameSteps) {
  // The composite mid-point force is computed on the composite level in every iteration
  // (analysis/composite_midpoint.hpp), or from the fine cells
  // (-hexcut_composite_midpoint false): the same steps to the iteration's tolerance, with
  // the same support work (du . fbar from the composite force) and energy balance.
  struct Run {
    std::vector<double> u;
    double support = 0, created = 0;
  };
  auto run = [](bool on) {
    Job job(PETSC_COMM_WORLD,
            driven_bar("corotational", "lumped") + "discretization: {type: composite, level: 1}\n",
            8, on ? nullptr : "-hexcut_composite_midpoint false");
    job.initial_acceleration();
    Run r;
    for (int n = 0; n < 60; ++n) {
      job.newmark_step();
      r.support += job.sim->last_step_energy().support_work;
      r.created += job.sim->last_step_energy().created();
    }
    PetscInt n;
    VecGetLocalSize(job.state.u, &n);
    const PetscScalar* a;
    VecGetArrayRead(job.state.u, &a);
    r.u.assign(a, a + n);
    VecRestoreArrayRead(job.state.u, &a);
    return r;
  };
  const Run fast = run(true), fine = run(false);
  double du = 0, umax = 0;
  for (std::size_t i = 0; i < fast.u.size(); ++i) {
    du = std::max(du, std::abs(fast.u[i] - fine.u[i]));
    umax = std::max(umax, std::abs(fine.u[i]));
  }
  std::printf(
      "composite / fine force: max |du| %.2e of %.3g m; support work %.6g / %.6g J; "
      "created %.2e / %.2e J\n",
      du, umax, fast.support, fine.support, fast.created, fine.created);
  EXPECT_LT(du, 1e-6 * umax);
  EXPECT_NEAR(fast.support, fine.support, 1e-4 * std::abs(fine.support));
  EXPECT_NEAR(fast.created, fine.created, 1e-3 * std::abs(fine.support));
}

// Lagged rotations on the spinning brick with 5 ms steps: the energy grows without bound
// (x 2e6 in 2.4 s); the energy check stops the run with a SolverError (exit 3) long before.
// (FreeSpinningBody... runs the iterated step through the same check.)
TEST(EnergyBalance, LaggedRotationsAreStopped) {
  std::string yaml = kSpinDeck;
  yaml.replace(yaml.find("dt: 0.001"), 9, "rotations: lagged, dt: 0.005");
  Job job(PETSC_COMM_WORLD, yaml);
  Probe probe(job);
  Eigen::Vector3d c0, L0;
  probe.rigid(&c0, &L0);
  probe.spin(2 * M_PI * Eigen::Vector3d(0.3, 0.2, 1.0).normalized(), c0);
  job.initial_acceleration();
  const double k0 = job.kinetic_energy(job.state);
  EXPECT_THROW(job.run(), SolverError);
  const double k = job.kinetic_energy(job.state);
  std::printf("  stopped at step %lld with K/K0 = %.3f\n", (long long)job.state.step, k / k0);
  EXPECT_LT(job.state.step, 1000);
  EXPECT_LT(k / k0, 1.2);
}

}  // namespace
}  // namespace hexcut::testing
