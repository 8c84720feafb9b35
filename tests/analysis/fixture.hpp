// Test support: a model built from deck text, with the solver and state it needs.
#pragma once

#include <gtest/gtest.h>
#include <petscksp.h>

#include <memory>
#include <string>
#include <vector>

#include "analysis/driver.hpp"
#include "analysis/model.hpp"
#include "analysis/result_output.hpp"
#include "analysis/simulation.hpp"
#include "common/petsc_check.hpp"
#include "deck/deck.hpp"
#include "solve/linear_solver.hpp"
#include "topology/dof_layout.hpp"

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
    check_petsc(PetscOptionsClear(nullptr), "PetscOptionsClear");
    if (options)
      check_petsc(PetscOptionsInsertString(nullptr, options), "PetscOptionsInsertString");
    check_petsc(solve::insert_deck_options(deck.solver), "insert_deck_options");
    check_petsc(analysis::build_model(comm, deck, superblock, &model), "build_model");
    sim = std::make_unique<analysis::Simulation>(comm, model, deck);
    check_petsc(analysis::create_state(model.dm, &state), "create_state");
  }
  /// Takes the analysis' steps from the current state with analysis::Driver, as the app
  /// does (without output; cuts at t = 0 and the initial acceleration are the caller's, as
  /// Driver::prepare and Driver::begin do them in the app).
  void run(const analysis::DriverHooks& hooks = {}) {
    analysis::Driver(comm, deck, model, state, sim, hooks).run();
  }

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
    check_petsc(topology::create_natural_scatter(
                    comm, D.num_global_copies,
                    std::vector<std::int32_t>(D.copies.begin(), D.copies.begin() + D.num_owned),
                    D.first_owned_block(), 3, &ns),
                "natural scatter");
    check_petsc(VecScatterBegin(ns.scatter, v, ns.natural, INSERT_VALUES, SCATTER_FORWARD),
                "scatter");
    check_petsc(VecScatterEnd(ns.scatter, v, ns.natural, INSERT_VALUES, SCATTER_FORWARD),
                "scatter");
    VecScatter all;
    Vec seq;
    check_petsc(VecScatterCreateToAll(ns.natural, &all, &seq), "to all");
    check_petsc(VecScatterBegin(all, ns.natural, seq, INSERT_VALUES, SCATTER_FORWARD), "scatter");
    check_petsc(VecScatterEnd(all, ns.natural, seq, INSERT_VALUES, SCATTER_FORWARD), "scatter");
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
