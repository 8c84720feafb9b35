// Results must not depend on the number of ranks: the same problem solved on all ranks
// of MPI_COMM_WORLD (2 under ctest) and on rank 0 alone gives the same displacement in
// canonical order, for every solver, and for a corotational dynamic run.
#include <array>
#include <cmath>
#include <map>

#include "common/mpi_gather.hpp"
#include "fixture.hpp"

namespace hexcut::testing {
namespace {

std::vector<double> solve_on(MPI_Comm comm, const std::string& yaml,
                             PetscInt* iterations = nullptr) {
  Job job(comm, yaml, 4);
  if (job.deck.analysis.type == deck::Analysis::Type::dynamic) {
    job.initial_acceleration();
    job.run();
  } else {
    job.run();
  }
  if (iterations) KSPGetIterationNumber(job.sim->ksp(), iterations);
  return job.canonical(job.state.u);
}

double relative_difference(const std::vector<double>& a, const std::vector<double>& b) {
  double num = 0, den = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    num = std::max(num, std::abs(a[i] - b[i]));
    den = std::max(den, std::abs(a[i]));
  }
  return num / den;
}

void compare(const std::string& yaml, double tol) {
  int size, rank;
  MPI_Comm_size(PETSC_COMM_WORLD, &size);
  MPI_Comm_rank(PETSC_COMM_WORLD, &rank);
  ASSERT_GE(size, 2) << "run this test with mpiexec -n 2";
  PetscInt its_parallel = 0, its_serial = 0;
  const auto parallel = solve_on(PETSC_COMM_WORLD, yaml, &its_parallel);
  MPI_Comm self;
  MPI_Comm_split(PETSC_COMM_WORLD, rank == 0 ? 0 : MPI_UNDEFINED, 0, &self);
  if (rank == 0) {
    const auto serial = solve_on(self, yaml, &its_serial);
    // hexcut's multigrid is the same algorithm on any number of ranks (the smoother's
    // set-up included), so it needs the same number of iterations.
    if (yaml.find("type: gmg") != std::string::npos) {
      EXPECT_EQ(its_serial, its_parallel);
    }
    ASSERT_EQ(serial.size(), parallel.size());
    const double diff = relative_difference(serial, parallel);
    std::printf("  max relative difference 1 vs %d ranks: %.2e\n", size, diff);
    EXPECT_LT(diff, tol);
    MPI_Comm_free(&self);
  }
  MPI_Barrier(PETSC_COMM_WORLD);
}

class EverySolver : public ::testing::TestWithParam<const char*> {};

TEST_P(EverySolver, TwoRanksEqualOneRank) {
  const std::string solver =
      std::string("{type: ") + GetParam() + ", rtol: 1.0e-11, max_iterations: 20000}";
  compare(cantilever_deck(0.025, "{type: static}", solver), 1e-10);
}

INSTANTIATE_TEST_SUITE_P(Solvers, EverySolver,
                         ::testing::Values("cg-jacobi", "hypre", "gamg", "direct", "gmg"));

TEST(Mpi, CorotationalDynamicTwoRanksEqualOneRank) {
  const std::string yaml =
      "lattice: {h: 0.025, dims: [40, 4, 4]}\n"
      "materials: {rubber: {E: 1.0e6, nu: 0.3, rho: 1000}}\n"
      "geometry: [{add: {box: {min: [0, 0, 0], max: [1.0, 0.1, 0.1]}}}]\n"
      "boundary:\n  fixed: [{where: {plane: {point: [0, 0, 0], normal: [1, 0, 0]}}}]\n"
      "  gravity: [0, 0, -9.81]\n"
      "analysis: {type: dynamic, formulation: corotational, dt: 0.01, steps: 20}\n"
      "solver: {type: gamg, rtol: 1.0e-12}\n";
  compare(yaml, 1e-10);
  // The same with the multigrid, rebuilt every step from the new rotations.
  std::string gmg = yaml;
  gmg.replace(gmg.find("type: gamg"), 10, "type: gmg");
  compare(gmg, 1e-10);
  // Composite elements of level 1, one rotation each, with the multigrid below them.
  compare(gmg + "discretization: {type: composite, level: 1}\n", 1e-10);
}

/// Composite element id of every cell, by canonical cell id (on every rank).
std::map<std::int64_t, double> composite_ids_on(MPI_Comm comm, const std::string& yaml) {
  Job job(comm, yaml, 4);
  const auto ids = job.sim->composite_element_ids();
  std::vector<std::array<double, 2>> mine(ids.size());
  for (std::size_t e = 0; e < ids.size(); ++e)
    mine[e] = {double(job.model.layout.cells[e]), ids[e]};
  std::map<std::int64_t, double> all;
  for (const auto& p : allgather(comm, mine)) all[std::int64_t(p[0])] = p[1];
  return all;
}

TEST(Mpi, CompositeElementIdsDoNotDependOnTheRanks) {
  // The output field composite_element: the same id for every cell on 1 and 2 ranks, on a
  // body whose blocks a hole splits into pieces.
  const std::string yaml =
      "lattice: {h: 0.1, dims: [16, 8, 8]}\n"
      "materials: {m: {E: 1000.0, nu: 0.3, rho: 1.0}}\n"
      "geometry:\n  - add: {box: {min: [0, 0, 0], max: [1.6, 0.8, 0.8]}}\n"
      "  - subtract: {box: {min: [0.1, -1, -1], max: [0.3, 2, 0.4]}}\n"
      "boundary:\n  fixed: [{where: {plane: {point: [0, 0, 0], normal: [1, 0, 0]}}}]\n"
      "analysis: {type: static}\nsolver: {type: direct}\n"
      "discretization: {type: composite, level: 2}\n";
  int rank;
  MPI_Comm_rank(PETSC_COMM_WORLD, &rank);
  const auto parallel = composite_ids_on(PETSC_COMM_WORLD, yaml);
  MPI_Comm self;
  MPI_Comm_split(PETSC_COMM_WORLD, rank == 0 ? 0 : MPI_UNDEFINED, 0, &self);
  if (rank == 0) {
    const auto serial = composite_ids_on(self, yaml);
    std::map<double, int> cells_per_id;
    for (const auto& [cell, id] : serial) ++cells_per_id[id];
    std::printf("  %zu cells, %zu composite elements\n", serial.size(), cells_per_id.size());
    EXPECT_EQ(serial, parallel);
    EXPECT_GT(cells_per_id.size(), std::size_t(4 * 2 * 2));  // the gap splits blocks
    MPI_Comm_free(&self);
  }
  MPI_Barrier(PETSC_COMM_WORLD);
}

class EveryCompositeSolver : public ::testing::TestWithParam<const char*> {};

TEST_P(EveryCompositeSolver, CompositeTwoRanksEqualOneRank) {
  // Composite elements of levels 1 and 2 (each inside one rank's super-blocks), static, and
  // a dynamic run with gravity; the composite system assembled (hypre, direct) or the
  // multigrid from the composite level down.
  const std::string solver =
      std::string("{type: ") + GetParam() + ", rtol: 1.0e-11, max_iterations: 20000}";
  for (int level : {1, 2}) {
    const std::string composite =
        "discretization: {type: composite, level: " + std::to_string(level) + "}\n";
    compare(cantilever_deck(0.025, "{type: static}", solver) + composite, 1e-9);
    std::string dynamic = cantilever_deck(0.025, "{type: dynamic, dt: 0.001, steps: 5}", solver);
    dynamic.insert(dynamic.find("analysis:"), "  gravity: [0, 0, -9.81]\n");
    compare(dynamic + composite, 1e-9);
  }
}

INSTANTIATE_TEST_SUITE_P(Solvers, EveryCompositeSolver,
                         ::testing::Values("hypre", "direct", "gmg"));

}  // namespace
}  // namespace hexcut::testing
