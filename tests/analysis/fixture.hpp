// Test support: a model built from deck text, with the solver and state it needs.
#pragma once

#include <gtest/gtest.h>
#include <petscksp.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "analysis/cutting.hpp"
#include "analysis/driver.hpp"
#include "analysis/model.hpp"
#include "analysis/result_output.hpp"
#include "analysis/simulation.hpp"
#include "common/petsc_check.hpp"
#include "deck/deck.hpp"
#include "solve/linear_solver.hpp"
#include "topology/dof_layout.hpp"

/// Calls a PetscErrorCode function through the app's error boundary
/// (throw_on_petsc_error): a solver failure throws SolverError, an input error InputError,
/// and any other error a std::runtime_error naming the call.
#define HEXCUT_CALL(call) ::hexcut::check_petsc((call), #call)

namespace hexcut::testing {

/// Deck + model + simulation + state on a communicator. The deck's solver options are
/// put into the options database, so use one solver type per process at a time or
/// clear the options between (PetscOptionsClear is called by the constructor).
struct Job {
  MPI_Comm comm;
  deck::Deck deck;
  analysis::Model model;
  std::unique_ptr<analysis::Simulation> sim;
  analysis::State state;

  /// `options`: PETSc options for this job (e.g. "-gmg_levels 3"), set after clearing.
  Job(MPI_Comm comm_, const std::string& yaml, int superblock = 8, const char* options = nullptr)
      : comm(comm_) {
    deck = deck::parse_deck(yaml, "test.yaml");
    HEXCUT_CALL(PetscOptionsClear(nullptr));
    if (options) HEXCUT_CALL(PetscOptionsInsertString(nullptr, options));
    HEXCUT_CALL(solve::insert_deck_options(deck.solver));
    HEXCUT_CALL(analysis::build_model(comm, deck, superblock, &model));
    HEXCUT_CALL(analysis::Simulation::create(comm, model, deck, &sim));
    HEXCUT_CALL(analysis::create_state(model.dm, &state));
  }
  /// Takes the analysis' steps from the current state with analysis::Driver, as the app
  /// does (without output; cuts at t = 0 and the initial acceleration are the caller's, as
  /// Driver::prepare and Driver::begin do them in the app).
  void run(const analysis::DriverHooks& hooks = {}) {
    HEXCUT_CALL(analysis::Driver(comm, deck, model, state, sim, hooks).run());
  }
  /// The Simulation's steps and energies of the state, through the boundary.
  void initial_acceleration() { HEXCUT_CALL(sim->initial_acceleration(state)); }
  void newmark_step() { HEXCUT_CALL(sim->newmark_step(state)); }
  double kinetic_energy(const analysis::State& s) const {
    double e = 0;
    HEXCUT_CALL(sim->kinetic_energy(s, &e));
    return e;
  }
  double elastic_energy(const analysis::State& s) const {
    double e = 0;
    HEXCUT_CALL(sim->elastic_energy(s, &e));
    return e;
  }
  /// Applies every cut of the deck, whatever its time, to the current state and rebuilds
  /// the simulation on the cut topology (composite runs: with `carry`, the old
  /// simulation's composite_carry(); may be null). Returns the number of links cut.
  std::int64_t cut_all(analysis::CompositeCarry* carry = nullptr) {
    analysis::Cutter cutter(deck, model.lattice);
    analysis::CutReport r;
    HEXCUT_CALL(analysis::apply_due_cuts(comm, deck, cutter, 1e300, &model, &state, &r));
    sim.reset();
    HEXCUT_CALL(analysis::Simulation::create(comm, model, deck, &sim, carry));
    return std::int64_t(r.links);
  }
  /// Kinetic + strain energy of the job's state.
  double energy() const { return kinetic_energy(state) + elastic_energy(state); }

  ~Job() {
    analysis::destroy_state(&state);
    sim.reset();
    analysis::destroy_model(&model);
  }

  /// The displacement in canonical copy order, on every rank.
  std::vector<double> canonical(Vec v) const {
    const auto& D = model.layout;
    topology::NaturalScatter ns;
    MPI_Comm comm = PetscObjectComm((PetscObject)v);
    HEXCUT_CALL(topology::create_natural_scatter(
        comm, D.num_global_copies,
        std::vector<std::int32_t>(D.copies.begin(), D.copies.begin() + D.num_owned),
        D.first_owned_block(), 3, &ns));
    HEXCUT_CALL(VecScatterBegin(ns.scatter, v, ns.natural, INSERT_VALUES, SCATTER_FORWARD));
    HEXCUT_CALL(VecScatterEnd(ns.scatter, v, ns.natural, INSERT_VALUES, SCATTER_FORWARD));
    VecScatter all;
    Vec seq;
    HEXCUT_CALL(VecScatterCreateToAll(ns.natural, &all, &seq));
    HEXCUT_CALL(VecScatterBegin(all, ns.natural, seq, INSERT_VALUES, SCATTER_FORWARD));
    HEXCUT_CALL(VecScatterEnd(all, ns.natural, seq, INSERT_VALUES, SCATTER_FORWARD));
    const PetscScalar* a;
    PetscInt n;
    VecGetLocalSize(seq, &n);
    VecGetArrayRead(seq, &a);
    std::vector<double> out(a, a + n);
    VecRestoreArrayRead(seq, &a);
    VecScatterDestroy(&all);
    VecDestroy(&seq);
    topology::destroy_natural_scatter(&ns);
    return out;
  }

  /// Reference position of canonical copy v.
  Eigen::Vector3d position(std::int32_t v) const {
    const auto& L = model.lattice;
    const auto& p = model.copies.vertex[v];
    return L.spec.origin + L.spec.h * Eigen::Vector3d(p[0], p[1], p[2]);
  }
};

/// max |a - b| / max |a| over two global vectors of the same layout.
inline double rel_max_difference(Vec a, Vec b) {
  Vec d;
  VecDuplicate(a, &d);
  VecWAXPY(d, -1.0, a, b);
  PetscReal nd, na;
  VecNorm(d, NORM_INFINITY, &nd);
  VecNorm(a, NORM_INFINITY, &na);
  VecDestroy(&d);
  return nd / na;
}

/// max |a_i - b_i| and max |a_i| over n values of two arrays.
struct MaxDifference {
  double difference = 0, magnitude = 0;
  double relative() const { return difference / magnitude; }
};
inline MaxDifference max_difference(const double* a, const double* b, std::size_t n) {
  MaxDifference d;
  for (std::size_t i = 0; i < n; ++i) {
    d.difference = std::max(d.difference, std::abs(a[i] - b[i]));
    d.magnitude = std::max(d.magnitude, std::abs(a[i]));
  }
  return d;
}

/// Sum over all DOFs of a global vector, per component (x, y, z): a resultant force or
/// a total momentum.
inline Eigen::Vector3d component_sums(Vec v) {
  PetscInt n;
  VecGetLocalSize(v, &n);
  const PetscScalar* a;
  VecGetArrayRead(v, &a);
  double sum[3] = {0, 0, 0};
  for (PetscInt i = 0; i < n; ++i) sum[i % 3] += a[i];
  VecRestoreArrayRead(v, &a);
  MPI_Allreduce(MPI_IN_PLACE, sum, 3, MPI_DOUBLE, MPI_SUM, PetscObjectComm((PetscObject)v));
  return {sum[0], sum[1], sum[2]};
}

/// The lattice, materials and geometry of a 1.2 m x 0.8 m x 0.8 m block (12 x 8 x 8 cells)
/// with a spherical hole and a part 5x stiffer (x > 0.8 m): partly filled and cut-up
/// coarse cells, and a material jump, for the multigrid and composite tests.
inline std::string holed_block_body() {
  return "lattice: {h: 0.1, dims: [12, 8, 8]}\n"
         "materials: {a: {E: 1000.0, nu: 0.3, rho: 2.0}, b: {E: 5000.0, nu: 0.2, rho: 1.0}}\n"
         "geometry:\n  - add: {box: {min: [0, 0, 0], max: [1.2, 0.8, 0.8]}}\n    material: a\n"
         "  - subtract: {sphere: {centre: [0.6, 0.4, 0.4], radius: 0.25}}\n"
         "  - assign: {box: {min: [0.8, 0, 0], max: [1.2, 0.8, 0.8]}}\n    material: b\n";
}

/// A bar [0,L]x[0,b]x[0,t] clamped at x = 0 with a downward end traction of resultant P.
inline std::string cantilever_deck(double h, const std::string& analysis, const std::string& solver,
                                   double L = 1.0, double b = 0.1, double t = 0.1,
                                   double P = 1000.0) {
  const int nx = int(std::lround(L / h)), ny = int(std::lround(b / h)),
            nz = int(std::lround(t / h));
  return "lattice: {h: " + std::to_string(h) + ", dims: [" + std::to_string(nx) + ", " +
         std::to_string(ny) + ", " + std::to_string(nz) + "]}\n" +
         "materials: {steel: {E: 200.0e9, nu: 0.3, rho: 7800}}\n"
         "geometry:\n  - add: {box: {min: [0, 0, 0], max: [" +
         std::to_string(L) + ", " + std::to_string(b) + ", " + std::to_string(t) + "]}}\n" +
         "boundary:\n  fixed:\n    - where: {plane: {point: [0, 0, 0], normal: [1, 0, 0]}}\n"
         "  traction:\n    - where: {plane: {point: [" +
         std::to_string(L) +
         ", 0, 0], normal: [1, 0, 0]}}\n"
         "      value: [0, 0, " +
         std::to_string(-P / (b * t)) + "]\n" + "analysis: " + analysis + "\n" +
         "solver: " + solver + "\n";
}

}  // namespace hexcut::testing
