// hexcut's geometric multigrid against independent references: the assembled matrix
// (matrix-free apply), PETSc's MatPtAP (Galerkin coarse blocks), interpolation
// consistency, V-cycle symmetry, and convergence of GMG-CG. Runs on 1 or 2 ranks.
#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <map>
#include <set>

#include "../analysis/fixture.hpp"
#include "assembly/boundary.hpp"
#include "backend/loop.hpp"
#include "backend/restriction.hpp"
#include "element/reference.hpp"
#include "multigrid/gmg.hpp"
#include "multigrid/host_loop_cycle.hpp"

namespace hexcut::testing {
namespace {

const std::string kBlock =
    holed_block_body() +
    "boundary:\n  fixed:\n    - where: {plane: {point: [0, 0, 0], normal: [1, 0, 0]}}\n"
    "    - where: {plane: {point: [1.2, 0, 0], normal: [1, 0, 0]}}\n      components: [y]\n"
    "  traction:\n    - where: {plane: {point: [1.2, 0, 0], normal: [1, 0, 0]}}\n      value: [0, "
    "0, -10.0]\n"
    "analysis: {type: static, formulation: corotational}\n"
    "solver: {type: gmg, rtol: 1.0e-10}\n";

/// kBlock with the linear formulation (no rotations stored).
std::string linear_block() {
  std::string yaml = kBlock;
  return yaml.replace(yaml.find("corotational"), 12, "linear");
}

/// A cube of n^3 cells clamped at the bottom, pushed sideways on top (static, linear).
std::string cube_deck(int n) {
  return "lattice: {h: " + std::to_string(1.0 / n) + ", dims: [" + std::to_string(n) + ", " +
         std::to_string(n) + ", " + std::to_string(n) + "]}\n" +
         "materials: {m: {E: 1.0, nu: 0.3, rho: 1}}\n"
         "geometry: [{add: {box: {min: [0, 0, 0], max: [1, 1, 1]}}}]\n"
         "boundary:\n  fixed: [{where: {plane: {point: [0, 0, 0], normal: [0, 0, 1]}}}]\n"
         "  traction: [{where: {plane: {point: [0, 0, 1], normal: [0, 0, 1]}}, value: [0.01, 0, "
         "-0.01]}]\n"
         "solver: {type: gmg, rtol: 1.0e-8}\n";
}

/// Random (deterministic) rotations: rotations of a smooth displacement field.
void set_rotations(Job& job) {
  const auto& D = job.model.layout;
  PetscScalar* a;
  VecGetArray(job.state.u, &a);
  for (std::int32_t i = 0; i < D.num_owned; ++i) {
    const auto x = job.position(D.copies[i]);
    a[3 * i] = 0.3 * std::sin(3 * x[1]) * x[0];
    a[3 * i + 1] = 0.2 * std::cos(2 * x[0]) * x[2];
    a[3 * i + 2] = 0.4 * x[0] * x[0];
  }
  VecRestoreArray(job.state.u, &a);
  Vec ul;
  DMGetLocalVector(job.model.dm, &ul);
  assembly::global_to_local(job.model.dm, job.state.u, ul);
  const PetscScalar* ua;
  VecGetArrayRead(ul, &ua);
  assembly::update_rotations(D, ua, job.model.cells);
  VecRestoreArrayRead(ul, &ua);
  DMRestoreLocalVector(job.model.dm, &ul);
}

void fill(Vec v, double phase) {
  PetscInt lo, n;
  VecGetOwnershipRange(v, &lo, nullptr);
  VecGetLocalSize(v, &n);
  PetscScalar* a;
  VecGetArray(v, &a);
  for (PetscInt i = 0; i < n; ++i) a[i] = std::sin(0.37 * double(lo + i) + phase) + 0.1;
  VecRestoreArray(v, &a);
}

/// max |a - b| / max |a| (fixture.hpp).
double rel_diff(Vec a, Vec b) {
  return rel_max_difference(a, b);
}

struct Operators {
  Job job;
  Mat A = nullptr;  // assembled, constrained
  assembly::OperatorWeights w;
  Operators(const std::string& yaml, assembly::OperatorWeights weights,
            const char* options = "-gmg_levels 3", int superblock = 8)
      : job(PETSC_COMM_WORLD, yaml, superblock, options), w(weights) {
    set_rotations(job);
    check_petsc(assembly::create_matrix(PETSC_COMM_WORLD, job.model.copies, job.model.layout, &A),
                "create");
    HEXCUT_CALL(assembly::assemble_constrained_matrix(
        job.model.dm, job.model.layout, job.model.cells, w, job.model.boundary.constraints, A));
    job.sim->multigrid()->update(job.model.cells, w, job.model.boundary.constraints.rows);
  }
  ~Operators() { MatDestroy(&A); }
};

/// Relative difference between the multigrid's matrix-free fine operator and the
/// assembled matrix on a fixed vector.
double matrix_free_difference(Operators& ops) {
  Vec x, y_mf, y_as;
  MatCreateVecs(ops.A, &x, &y_mf);
  VecDuplicate(y_mf, &y_as);
  fill(x, 0.3);
  MatMult(ops.A, x, y_as);
  ops.job.sim->multigrid()->apply_fine(x, y_mf);
  const double d = rel_diff(y_as, y_mf);
  for (Vec* v : {&x, &y_mf, &y_as}) VecDestroy(v);
  return d;
}

class EveryWeighting : public ::testing::TestWithParam<int> {};

const assembly::OperatorWeights kWeights[3] = {
    {1.0, 0.0, true}, {1.7, 40.0, true}, {1.2, 25.0, false}};

TEST_P(EveryWeighting, MatrixFreeApplyEqualsAssembledMatrix) {
  Operators ops(kBlock, kWeights[GetParam()]);
  EXPECT_LT(matrix_free_difference(ops), 1e-12);
}

TEST_P(EveryWeighting, ConstrainedMatrixIsTheEliminationOfTheAssembledOperator) {
  // The masked assembly (assembly::assemble_constrained_matrix, the multigrid's Dirichlet
  // mask) gives the matrix that symmetric elimination of the assembled operator gives
  // (MatZeroRowsColumns, 1 on the diagonal): the same nonzero pattern, the same values bit
  // for bit, ghost DOFs of a rank included.
  Operators ops(kBlock, kWeights[GetParam()]);
  const auto& M = ops.job.model;
  Mat B;
  HEXCUT_CALL(assembly::create_matrix(PETSC_COMM_WORLD, M.copies, M.layout, &B));
  HEXCUT_CALL(assembly::assemble_matrix(M.layout, M.cells, ops.w, B));
  const auto& rows = M.boundary.constraints.rows;
  HEXCUT_CALL(MatZeroRowsColumns(B, PetscInt(rows.size()), rows.data(), 1.0, nullptr, nullptr));
  PetscInt lo, hi;
  MatGetOwnershipRange(B, &lo, &hi);
  std::int64_t differ = 0, entries = 0;
  for (PetscInt r = lo; r < hi; ++r) {
    PetscInt na, nb;
    const PetscInt *ca, *cb;
    const PetscScalar *va, *vb;
    MatGetRow(ops.A, r, &na, &ca, &va);
    MatGetRow(B, r, &nb, &cb, &vb);
    entries += nb;
    if (na != nb || !std::equal(ca, ca + na, cb) ||
        std::memcmp(va, vb, sizeof(PetscScalar) * std::size_t(na)) != 0)
      ++differ;
    MatRestoreRow(B, r, &nb, &cb, &vb);
    MatRestoreRow(ops.A, r, &na, &ca, &va);
  }
  MatDestroy(&B);
  EXPECT_GT(entries, 0);
  EXPECT_EQ(differ, 0) << "rows that differ of " << hi - lo;
}

INSTANTIATE_TEST_SUITE_P(Weights, EveryWeighting, ::testing::Values(0, 1, 2));

/// Largest relative difference, over levels 1 and 2, between the multigrid's level operator
/// and the Galerkin product P^T A P of the level below (level 0: `A`, the assembled
/// constrained fine matrix) with the V-cycle's transfer (prescribed or dead rows of P
/// zeroed), on a vector.
double galerkin_mismatch(multigrid::Multigrid* mg, Mat A) {
  std::vector<Mat> owned;
  double worst = 0.0;
  for (int l = 0; l < 2; ++l) {
    Mat P, Ac;
    MatConvert(mg->interpolation(l), MATAIJ, MAT_INITIAL_MATRIX, &P);
    MatDiagonalScale(P, mg->mask(l), nullptr);
    MatPtAP(A, P, MAT_INITIAL_MATRIX, 2.0, &Ac);
    Vec x, y_ref, y_mg;
    mg->create_vector(l + 1, &x);
    VecDuplicate(x, &y_ref);
    VecDuplicate(x, &y_mg);
    fill(x, 1.1 * (l + 1));
    MatMult(Ac, x, y_ref);
    mg->apply_level(l + 1, x, y_mg);
    worst = std::max(worst, rel_diff(y_ref, y_mg));
    for (Vec* v : {&x, &y_ref, &y_mg}) VecDestroy(v);
    MatDestroy(&P);
    owned.push_back(Ac);
    A = Ac;
  }
  for (Mat& m : owned) MatDestroy(&m);
  return worst;
}

TEST(Multigrid, GalerkinBlocksEqualPtAP) {
  // For the trilinear transfer and for the energy-minimizing one (kBlock has a hole and a
  // material jump: irregular coarse cells, general 24x24 W per child there).
  // Smoothed: levels 1 and 2 are assembled from the fine cells (P^T A P with the smoothed P),
  // which this compares with the test's own assembled fine matrix.
  // Rotated cells (Operators sets rotations), so level 1's blocks are the rotated products
  // of multigrid/fine_galerkin.hpp where no DOF is prescribed; with the trilinear transfer
  // every weighting (stiffness only, lumped and consistent mass).
  for (const auto& w : kWeights) {
    Operators ops(kBlock, w, "-gmg_levels 3");
    EXPECT_LT(galerkin_mismatch(ops.job.sim->multigrid(), ops.A), 1e-12)
        << "trilinear, w_K " << w.stiffness << ", w_M " << w.mass
        << (w.lumped_mass ? " lumped" : "");
  }
  for (const char* interpolation :
       {"trilinear", "energy", "smoothed", "smoothed -gmg_smoothed_levels -1"}) {
    const std::string options = std::string("-gmg_levels 3 -gmg_interpolation ") + interpolation;
    Operators ops(kBlock, {1.3, 10.0, false}, options.c_str());
    auto* mg = ops.job.sim->multigrid();
    ASSERT_GE(mg->num_levels(), 3);
    if (std::string(interpolation) == "energy") {
      ASSERT_GT(mg->energy_stats(0).rows, 0);
    }
    if (std::string(interpolation).find("smoothed") == 0) {
      ASSERT_EQ(mg->assembled_from(), 1);
      ASSERT_GT(mg->smoothing_omega(0), 0.0);
    }
    EXPECT_LT(galerkin_mismatch(mg, ops.A), 1e-12) << interpolation;
  }
}

TEST(Multigrid, SharedBlocksAreTheBlocksEachCellWouldHave) {
  // Linear runs: coarse cells whose children have one block key (one material and density,
  // no prescribed DOF, recursively) and fill the same octants share one stored block, formed
  // once. kBlock has a hole, a material jump, a clamped and a roller face, so some coarse
  // cells share and others keep their own. Each cell's block must be exactly the one it has
  // without sharing, for every weighting (with mass the two densities differ too), and
  // still P^T A P. Variants: a blade between the children of the coarse cells at
  // x = 0.2..0.4 that stops half-way through them (their children's corners are split
  // copies; the block does not see them); super-blocks of 1 cell, so that on 2 ranks coarse
  // cells have children on the other rank (their products arrive summed: such a cell must
  // keep its own block).
  const std::string blade =
      "cuts:\n  - blade: {polygon: [[0.3, -0.1, -0.1], [0.3, 0.1, -0.1], [0.3, 0.1, 0.9], "
      "[0.3, -0.1, 0.9]]}\n";
  struct Case {
    bool cut;
    int superblock;
  };
  for (const auto& w : kWeights)
    for (const Case c : {Case{false, 8}, Case{true, 8}, Case{false, 1}}) {
      const std::string yaml = linear_block() + (c.cut ? blade : "");
      const std::string what = std::string("w_M ") + std::to_string(w.mass) +
                               (c.cut ? ", cut" : "") + ", super-block " +
                               std::to_string(c.superblock);
      // One job after the other: a job's options stay in PETSc's database, and the cut
      // makes a new Simulation, which reads them.
      auto make = [&](const char* options) {
        auto j = std::make_unique<Job>(PETSC_COMM_WORLD, yaml, c.superblock, options);
        if (c.cut) {
          EXPECT_GT(j->cut_all(), 0);
        }
        j->sim->multigrid()->update(j->model.cells, w, j->model.boundary.constraints.rows);
        return j;
      };
      auto shared_job = make("-gmg_levels 3");
      auto own_job = make("-gmg_levels 3 -gmg_shared_blocks false");
      Job& shared = *shared_job;
      auto* mg = shared.sim->multigrid();
      ASSERT_EQ(mg->num_levels(), 3);
      int size;
      MPI_Comm_size(PETSC_COMM_WORLD, &size);
      if (c.superblock == 1 && size > 1) {
        EXPECT_TRUE(mg->level(1).remote_children) << what;
      }
      for (int l = 1; l < 3; ++l) {
        const auto& A = mg->stored_cells(l);
        const auto& B = own_job->sim->multigrid()->stored_cells(l);
        ASSERT_EQ(A.num_cells(), B.num_cells());
        EXPECT_EQ(B.num_blocks(), B.num_cells());
        double count[3] = {double(A.num_blocks()), double(A.num_cells()), 0.0}, a[576], b[576];
        for (std::size_t e = 0; e < A.num_cells(); ++e) {
          A.cell_matrix(e, a);
          B.cell_matrix(e, b);
          for (int i = 0; i < 576; ++i) count[2] = std::max(count[2], std::abs(a[i] - b[i]));
        }
        MPI_Allreduce(MPI_IN_PLACE, count, 2, MPI_DOUBLE, MPI_SUM, PETSC_COMM_WORLD);
        if (l == 1) {
          EXPECT_LE(count[0], count[1] / 2) << what << ": level 1, too few cells share";
        }
        EXPECT_GT(count[0], 2.0) << what << ": level " << l << ", cells that differ share";
        EXPECT_EQ(count[2], 0.0) << what << ": level " << l;
      }
      Mat K;
      check_petsc(
          assembly::create_matrix(PETSC_COMM_WORLD, shared.model.copies, shared.model.layout, &K),
          "create");
      HEXCUT_CALL(assembly::assemble_constrained_matrix(shared.model.dm, shared.model.layout,
                                                        shared.model.cells, w,
                                                        shared.model.boundary.constraints, K));
      EXPECT_LT(galerkin_mismatch(mg, K), 1e-12) << what;
      MatDestroy(&K);
    }
}

TEST(Multigrid, UnpackedSharedBlocksApplyLikeThePackedOnes) {
  // Blocks that many cells share (an uncut homogeneous cube: on level 1 all but the clamped
  // layer share one) are applied from unpacked copies, the others from their packed
  // storage, cell by cell; the sum must be the product of the packed blocks a block per cell
  // gives, to round-off, in both precisions (single: the same rounded numbers), on every
  // level.
  for (const char* precision : {"double", "single"}) {
    const std::string common = std::string("-gmg_levels 3 -gmg_precision ") + precision;
    const assembly::OperatorWeights w{1.0, 0.0, true};
    auto make = [&](const std::string& options) {
      auto j = std::make_unique<Job>(PETSC_COMM_WORLD, cube_deck(32), 8, options.c_str());
      j->sim->multigrid()->update(j->model.cells, w, j->model.boundary.constraints.rows);
      return j;
    };
    auto shared_job = make(common);
    auto own_job = make(common + " -gmg_shared_blocks false");
    auto* shared = shared_job->sim->multigrid();
    auto* own = own_job->sim->multigrid();
    ASSERT_EQ(shared->num_levels(), 3);
    for (int l = 1; l < 3; ++l) {
      const auto& A = shared->stored_cells(l);
      const auto& B = own->stored_cells(l);
      EXPECT_EQ(B.num_unpacked(), 0u) << precision << ", level " << l;
      if (l == 1) {
        // The clamped bottom layer's cells keep blocks of their own (packed); the rest
        // share one, unpacked (per rank: a rank away from the bottom has only that one).
        double count[2] = {double(A.num_unpacked()), double(A.num_blocks())};
        MPI_Allreduce(MPI_IN_PLACE, count, 2, MPI_DOUBLE, MPI_SUM, PETSC_COMM_WORLD);
        EXPECT_GT(count[0], 0.0) << precision << ": " << count[1] << " blocks";
        EXPECT_LT(count[0], count[1]) << precision;
      }
      Vec x, ya, yb;
      shared->create_vector(l, &x);
      VecDuplicate(x, &ya);
      VecDuplicate(x, &yb);
      fill(x, 0.3 * l);
      HEXCUT_CALL(shared->apply_level(l, x, ya));
      HEXCUT_CALL(own->apply_level(l, x, yb));
      EXPECT_LT(rel_diff(ya, yb), 1e-14) << precision << ", level " << l;
      for (Vec* v : {&x, &ya, &yb}) VecDestroy(v);
    }
  }
}

TEST(Multigrid, ChildrenOnOtherRanksAndGatheredLevelsStayGalerkin) {
  // Super-blocks of 1 and 2 cells: on 2 ranks, levels 1 and 2 have coarse cells whose
  // children are on both ranks (their products are summed on the coarse cell's rank), and
  // -gmg_gather_cells 100000 gathers every coarse level onto rank 0. The blocks must still
  // be P^T A P, and the depth no longer depends on the super-block (it used to be capped at
  // log2(super-block) + 1 levels).
  int size;
  MPI_Comm_size(PETSC_COMM_WORLD, &size);
  bool remote_seen = false;  // (whether a level straddles the ranks depends on the partition)
  for (int superblock : {1, 2})
    for (const char* gather : {"0", "100000"}) {
      const std::string options = std::string("-gmg_levels 3 -gmg_gather_cells ") + gather;
      Operators ops(kBlock, {1.3, 10.0, false}, options.c_str(), superblock);
      auto* mg = ops.job.sim->multigrid();
      ASSERT_EQ(mg->num_levels(), 3);
      if (size > 1) {
        remote_seen |= mg->level(1).remote_children || mg->level(2).remote_children;
        EXPECT_EQ(mg->level(1).ranks, std::string(gather) == "0" ? size : 1);
      }
      EXPECT_LT(galerkin_mismatch(mg, ops.A), 1e-12)
          << "super-block " << superblock << ", gather " << gather;
    }
  if (size > 1) {
    EXPECT_TRUE(remote_seen) << "no level had children on another rank";
  }
}

/// Turns the rotation of every local cell with x-origin in [x_min, x_max) by `angle` about z;
/// returns the canonical ids of the turned cells.
std::vector<std::int32_t> turn_cells(Job& job, double x_min, double x_max, double angle) {
  auto& cells = job.model.cells;
  const Eigen::Matrix3d turn =
      Eigen::AngleAxisd(angle, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  std::vector<std::int32_t> turned;
  for (std::size_t e = 0; e < job.model.layout.cells.size(); ++e) {
    if (cells.origin[e][0] < x_min || cells.origin[e][0] >= x_max) continue;
    Eigen::Map<Eigen::Matrix<double, 3, 3, Eigen::RowMajor>> R(&cells.rotation[9 * e]);
    R = (turn * R).eval();
    turned.push_back(job.model.layout.cells[e]);
  }
  return turned;
}

/// Level l's operator applied to a fixed vector (caller destroys the result).
Vec level_apply(multigrid::Multigrid* mg, int l) {
  Vec x, y;
  mg->create_vector(l, &x);
  VecDuplicate(x, &y);
  fill(x, 0.7 * l);
  mg->apply_level(l, x, y);
  VecDestroy(&x);
  return y;
}

TEST(Multigrid, PartialRebuildTouchesOnlyAncestorsAndEqualsFullRebuild) {
  // Trilinear transfer: a full rebuild recomputes an energy-minimizing one from the turned
  // operator, so partial and full rebuilds differ by design there; the next test checks
  // that partial rebuilds with the energy-minimizing transfer stay Galerkin.
  const assembly::OperatorWeights w{1.3, 10.0, false};
  Operators ops(kBlock, w, "-gmg_levels 3 -gmg_interpolation trilinear");
  auto* mg = ops.job.sim->multigrid();
  ASSERT_EQ(mg->num_levels(), 3);
  for (int l = 0; l < 3; ++l)
    EXPECT_EQ(mg->rebuilt_cells(l), std::int64_t(mg->level(l).layout().cells.size()))
        << "first update: all";
  // Turn a slab of cells; the ancestors of exactly those are rebuilt.
  // Cells 3..5 along x (h = 0.1): blocks [2,3] and [4,5] of level 1 get some turned
  // children, not all, and not always their first one.
  const auto turned = turn_cells(ops.job, 0.25, 0.55, 0.1);
  std::set<std::int32_t> parents1, parents2;
  for (auto c : turned) parents1.insert(mg->level(0).parent[c]);
  for (auto c : parents1) parents2.insert(mg->level(1).parent[c]);
  mg->update(ops.job.model.cells, w, ops.job.model.boundary.constraints.rows);
  EXPECT_EQ(mg->rebuilt_cells(0), std::int64_t(turned.size()));
  EXPECT_EQ(mg->rebuilt_cells(1), std::int64_t(parents1.size()));
  EXPECT_EQ(mg->rebuilt_cells(2), std::int64_t(parents2.size()));
  std::int64_t n1 = std::int64_t(mg->level(1).layout().cells.size()),
               total_turned = std::int64_t(turned.size());
  MPI_Allreduce(MPI_IN_PLACE, &n1, 1, MPI_INT64_T, MPI_SUM, PETSC_COMM_WORLD);
  MPI_Allreduce(MPI_IN_PLACE, &total_turned, 1, MPI_INT64_T, MPI_SUM, PETSC_COMM_WORLD);
  std::int64_t r1 = mg->rebuilt_cells(1);
  MPI_Allreduce(MPI_IN_PLACE, &r1, 1, MPI_INT64_T, MPI_SUM, PETSC_COMM_WORLD);
  ASSERT_GT(total_turned, 0);
  EXPECT_LT(r1, n1 / 2) << "a partial rebuild";
  // Every level equals a full rebuild from the same cell data.
  std::vector<Vec> partial(3);
  for (int l = 0; l < 3; ++l) partial[l] = level_apply(mg, l);
  mg->invalidate();
  mg->update(ops.job.model.cells, w, ops.job.model.boundary.constraints.rows);
  EXPECT_EQ(mg->rebuilt_cells(1), std::int64_t(mg->level(1).layout().cells.size()));
  for (int l = 0; l < 3; ++l) {
    Vec full = level_apply(mg, l);
    EXPECT_LT(rel_diff(partial[l], full), 1e-14) << "level " << l;
    VecDestroy(&full);
  }
  for (Vec& v : partial) VecDestroy(&v);
}

TEST(Multigrid, RotationOnlyUpdateKeepsTheEnergyInterpolationAndStaysGalerkin) {
  // The energy-minimizing rows are computed at full rebuilds and kept across rotation-only
  // updates; the partially rebuilt coarse blocks are then P^T A P with that same P and the
  // turned fine operator.
  const assembly::OperatorWeights w{1.3, 10.0, false};
  Operators ops(kBlock, w, "-gmg_levels 3 -gmg_interpolation energy");
  auto* mg = ops.job.sim->multigrid();
  ASSERT_GT(mg->energy_stats(0).rows, 0);
  Mat P_before;
  MatConvert(mg->interpolation(0), MATAIJ, MAT_INITIAL_MATRIX, &P_before);
  turn_cells(ops.job, 0.25, 0.55, 0.3);
  mg->update(ops.job.model.cells, w, ops.job.model.boundary.constraints.rows);
  EXPECT_LT(mg->rebuilt_cells(0), std::int64_t(mg->level(0).layout().cells.size()));
  Mat P_after;
  MatConvert(mg->interpolation(0), MATAIJ, MAT_INITIAL_MATRIX, &P_after);
  PetscBool same;
  MatEqual(P_before, P_after, &same);
  EXPECT_TRUE(same) << "rotation-only update: the interpolation is kept";
  HEXCUT_CALL(assembly::assemble_constrained_matrix(ops.job.model.dm, ops.job.model.layout,
                                                    ops.job.model.cells, w,
                                                    ops.job.model.boundary.constraints, ops.A));
  EXPECT_LT(galerkin_mismatch(mg, ops.A), 1e-12);
  MatDestroy(&P_before);
  MatDestroy(&P_after);
}

/// The rigid mode m (0-2: translation along e_m, 3-5: linearized rotation about e_{m-3}
/// through the origin) at the owned copies of level l, positions in level-0 lattice units.
Vec rigid_mode(multigrid::Multigrid* mg, int l, int m) {
  Vec v;
  mg->create_vector(l, &v);
  const auto& lev = mg->level(l);
  const double s = double(1 << l);
  PetscScalar* a;
  VecGetArray(v, &a);
  for (std::int32_t i = 0; i < lev.layout().num_owned; ++i) {
    const auto& p = lev.copies().vertex[lev.layout().copies[i]];
    const double x[3] = {s * p[0], s * p[1], s * p[2]};
    double u[3] = {0, 0, 0};
    if (m < 3) {
      u[m] = 1.0;
    } else {
      const int k = m - 3;  // u = e_k x x
      u[(k + 1) % 3] = -x[(k + 2) % 3];
      u[(k + 2) % 3] = x[(k + 1) % 3];
    }
    for (int d = 0; d < 3; ++d) a[3 * i + d] = u[d];
  }
  VecRestoreArray(v, &a);
  return v;
}

TEST(Multigrid, EnergyInterpolationKeepsRigidModesAndLowersTheEnergy) {
  // P B_c = B_f on the free rows of every level (the constraint of the minimization), and
  // the minimized rows have less energy than the trilinear ones they start from.
  Operators ops(kBlock, {1.0, 0.0, true}, "-gmg_levels 3 -gmg_interpolation energy");
  auto* mg = ops.job.sim->multigrid();
  for (int l = 0; l + 1 < mg->num_levels(); ++l) {
    const auto& st = mg->energy_stats(l);
    ASSERT_GT(st.rows, 0) << "level " << l;
    EXPECT_LT(st.energy_after, st.energy_before) << "level " << l;
    std::printf("level %d: %lld rows, energy %.6g -> %.6g in %d iterations\n", l,
                (long long)st.rows, st.energy_before, st.energy_after, st.iterations);
    for (int m = 0; m < 6; ++m) {
      Vec c = rigid_mode(mg, l + 1, m), f = rigid_mode(mg, l, m), Pc;
      VecDuplicate(f, &Pc);
      MatMult(mg->interpolation(l), c, Pc);
      VecAXPY(Pc, -1.0, f);
      VecPointwiseMult(Pc, Pc, mg->mask(l));
      PetscReal err, ref;
      VecNorm(Pc, NORM_INFINITY, &err);
      VecNorm(f, NORM_INFINITY, &ref);
      EXPECT_LT(err, 1e-11 * ref) << "level " << l << " mode " << m;
      for (Vec* v : {&c, &f, &Pc}) VecDestroy(v);
    }
  }
}

/// The rows of an AIJ matrix owned here, as (column -> value) maps.
std::vector<std::map<PetscInt, double>> owned_rows(Mat M) {
  PetscInt lo, hi;
  MatGetOwnershipRange(M, &lo, &hi);
  std::vector<std::map<PetscInt, double>> rows(std::size_t(hi - lo));
  for (PetscInt r = lo; r < hi; ++r) {
    PetscInt n;
    const PetscInt* c;
    const PetscScalar* v;
    MatGetRow(M, r, &n, &c, &v);
    for (PetscInt k = 0; k < n; ++k)
      if (v[k] != 0.0) rows[std::size_t(r - lo)][c[k]] = v[k];
    MatRestoreRow(M, r, &n, &c, &v);
  }
  return rows;
}

/// max over the entries of |a - b|, over max |b|.
double row_difference(const std::map<PetscInt, double>& a, const std::map<PetscInt, double>& b) {
  double d = 0.0;
  for (const auto& [c, v] : a) {
    const auto it = b.find(c);
    d = std::max(d, std::abs(v - (it == b.end() ? 0.0 : it->second)));
  }
  for (const auto& [c, v] : b)
    if (!a.count(c)) d = std::max(d, std::abs(v));
  return d;
}

TEST(Multigrid, SmoothedInterpolationIsDampedJacobiOnTheTrilinearOne) {
  // P_s = (I - omega D^-1 A) diag(mask) P_t on the smoothed rows, P_t elsewhere, with A the
  // test's own assembled constrained fine matrix, D its 3x3 diagonal blocks (PETSc's
  // MatInvertBlockDiagonal), P_t the trilinear transfer of a second multigrid of the same
  // body, and omega = 4 / (3 lambda_max) below 2 / lambda_max (a true power iteration's).
  // Every row smoothed (-gmg_smoothed_layers -1): P_s is that product on all rows; by default
  // only rows near irregular coarse cells, and each of those lowers the energy of P.
  const assembly::OperatorWeights w{1.0, 0.0, true};
  Operators tri(kBlock, w, "-gmg_levels 3");
  Mat Pt;
  MatConvert(tri.job.sim->multigrid()->interpolation(0), MATAIJ, MAT_INITIAL_MATRIX, &Pt);
  MatDiagonalScale(Pt, tri.job.sim->multigrid()->mask(0), nullptr);
  // D^-1 A P_t, assembled by the test.
  MatSetBlockSize(tri.A, 3);
  const PetscScalar* blocks;
  MatInvertBlockDiagonal(tri.A, &blocks);
  PetscInt lo, hi;
  MatGetOwnershipRange(tri.A, &lo, &hi);
  Mat Dm;
  MatCreateAIJ(PETSC_COMM_WORLD, hi - lo, hi - lo, PETSC_DETERMINE, PETSC_DETERMINE, 3, nullptr, 0,
               nullptr, &Dm);
  for (PetscInt b = lo / 3; b < hi / 3; ++b) {
    const PetscInt idx[3] = {3 * b, 3 * b + 1, 3 * b + 2};
    // PETSc's blocks are column-major; D^-1 of a symmetric block is symmetric anyway.
    double row_major[9];
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) row_major[3 * i + j] = blocks[9 * (b - lo / 3) + 3 * j + i];
    MatSetValues(Dm, 3, idx, 3, idx, row_major, INSERT_VALUES);
  }
  MatAssemblyBegin(Dm, MAT_FINAL_ASSEMBLY);
  MatAssemblyEnd(Dm, MAT_FINAL_ASSEMBLY);
  Mat DAP;
  MatMatMatMult(Dm, tri.A, Pt, MAT_INITIAL_MATRIX, PETSC_DEFAULT, &DAP);
  // lambda_max(D^-1 A) by 300 power iterations.
  Vec v, Av, z;
  MatCreateVecs(tri.A, &v, &Av);
  VecDuplicate(v, &z);
  fill(v, 0.4);
  double lambda = 0.0;
  for (int it = 0; it < 300; ++it) {
    PetscReal nv;
    VecNormalize(v, &nv);
    MatMult(tri.A, v, Av);
    MatMult(Dm, Av, z);
    VecDot(v, z, &lambda);  // Rayleigh quotient in the D-inner product would be exact; this
    VecCopy(z, v);          // approaches lambda_max from below as well
  }
  for (Vec* x : {&v, &Av, &z}) VecDestroy(x);
  const auto rows_t = owned_rows(Pt), rows_dap = owned_rows(DAP);
  for (const char* layers : {"-1", "1"}) {
    const std::string options =
        std::string("-gmg_levels 3 -gmg_interpolation smoothed -gmg_smoothed_layers ") + layers;
    Operators sm(kBlock, w, options.c_str());
    auto* mg = sm.job.sim->multigrid();
    const double omega = mg->smoothing_omega(0);
    EXPECT_GT(omega, 0.0);
    EXPECT_LT(omega, 2.0 / lambda) << "lambda_max " << lambda;
    EXPECT_GT(omega, 1.0 / lambda) << "lambda_max " << lambda;
    const auto rows_s = owned_rows(mg->interpolation(0));
    ASSERT_EQ(rows_s.size(), rows_t.size());
    std::int64_t smoothed = 0, neither = 0, changed = 0;
    for (std::size_t r = 0; r < rows_s.size(); ++r) {
      auto expect = rows_t[r];
      for (const auto& [c, x] : rows_dap[r]) expect[c] -= omega * x;
      const bool is_smoothed = row_difference(rows_s[r], expect) < 1e-12;
      const bool is_trilinear = row_difference(rows_s[r], rows_t[r]) < 1e-14;
      smoothed += is_smoothed;
      neither += !is_smoothed && !is_trilinear;
      changed += !is_trilinear;
    }
    std::int64_t counts[4] = {smoothed, neither, changed, mg->smoothed_rows(0)};
    std::int64_t n = std::int64_t(rows_s.size());
    MPI_Allreduce(MPI_IN_PLACE, counts, 4, MPI_INT64_T, MPI_SUM, PETSC_COMM_WORLD);
    MPI_Allreduce(MPI_IN_PLACE, &n, 1, MPI_INT64_T, MPI_SUM, PETSC_COMM_WORLD);
    std::printf(
        "layers %s: omega %.4f (2/lambda_max %.4f); %lld of %lld rows changed, %lld "
        "smoothed rows reported\n",
        layers, omega, 2.0 / lambda, (long long)counts[2], (long long)n, (long long)counts[3]);
    EXPECT_EQ(counts[1], 0) << "rows neither trilinear nor smoothed";
    EXPECT_GT(counts[2], 0);
    EXPECT_LE(counts[2], counts[3]);
    if (std::string(layers) == "-1") {
      EXPECT_EQ(counts[0], n);
    } else {
      EXPECT_LT(counts[3], n) << "only rows near irregular coarse cells";
    }
    // Jacobi smoothing with omega < 2 / lambda_max lowers trace(P^T A P).
    Mat Et, Es, Ps;
    MatConvert(mg->interpolation(0), MATAIJ, MAT_INITIAL_MATRIX, &Ps);
    MatPtAP(tri.A, Pt, MAT_INITIAL_MATRIX, 2.0, &Et);
    MatPtAP(tri.A, Ps, MAT_INITIAL_MATRIX, 2.0, &Es);
    PetscScalar et, es;
    MatGetTrace(Et, &et);
    MatGetTrace(Es, &es);
    EXPECT_LT(es, et);
    for (Mat* M : {&Et, &Es, &Ps}) MatDestroy(M);
  }
  for (Mat* M : {&Pt, &Dm, &DAP}) MatDestroy(M);
}

TEST(Multigrid, RebuildToleranceKeepsCoarseBlocksButNotTheFineOperator) {
  const assembly::OperatorWeights w{1.0, 5.0, true};
  Operators ops(kBlock, w, "-gmg_levels 3 -gmg_rebuild_tol 0.5");
  auto* mg = ops.job.sim->multigrid();
  turn_cells(ops.job, -1.0, 0.25, 0.1);  // entries move by < 0.1
  mg->update(ops.job.model.cells, w, ops.job.model.boundary.constraints.rows);
  EXPECT_EQ(mg->rebuilt_cells(1), 0);
  EXPECT_EQ(mg->rebuilt_cells(2), 0);
  // The fine operator is the current one: equal to the matrix assembled now.
  HEXCUT_CALL(assembly::assemble_constrained_matrix(ops.job.model.dm, ops.job.model.layout,
                                                    ops.job.model.cells, w,
                                                    ops.job.model.boundary.constraints, ops.A));
  EXPECT_LT(matrix_free_difference(ops), 1e-12);
}

TEST(Multigrid, InterpolationIsConsistentForEveryIncidentCell) {
  // A body with a hole through it and a slab one cell thick (yaml), and three columns
  // touching only along edges (yaml2), where coarse cells share positions and vertex
  // copies are duplicated. (yaml's thin box [0.8, 1.6] x [0.8, 0.8001] holds no cell
  // centre and its blocks stay connected: no shared positions there.)
  const std::string yaml =
      "lattice: {h: 0.1, dims: [16, 8, 8]}\n"
      "materials: {m: {E: 1.0, nu: 0.3, rho: 1}}\n"
      "geometry:\n  - add: {box: {min: [0, 0, 0], max: [0.8, 0.8, 0.8]}}\n"
      "  - subtract: {box: {min: [0.1, 0.1, -1], max: [0.3, 0.3, 2]}}\n"
      "  - add: {box: {min: [0.8, 0.8, 0], max: [1.6, 0.8001, 0.8]}}\n"
      "  - add: {box: {min: [0.8, 0, 0], max: [1.6, 0.1, 0.8]}}\n"
      "  - subtract: {box: {min: [0.75, 0.35, 0.35], max: [0.85, 0.45, 0.45]}}\n"
      "boundary: {fixed: [{where: {plane: {point: [0, 0, 0], normal: [1, 0, 0]}}}]}\n"
      "solver: {type: gmg}\n";
  const std::string yaml2 =
      "lattice: {h: 0.1, dims: [8, 8, 4]}\n"
      "materials: {m: {E: 1.0, nu: 0.3, rho: 1}}\n"
      "geometry:\n  - add: {box: {min: [0, 0, 0], max: [0.3, 0.3, 0.4]}}\n"
      "  - add: {box: {min: [0.3, 0.3, 0], max: [0.5, 0.5, 0.4]}}\n"
      "  - add: {box: {min: [0.5, 0.5, 0], max: [0.8, 0.8, 0.4]}}\n"
      "boundary: {fixed: [{where: {plane: {point: [0, 0, 0], normal: [1, 0, 0]}}}]}\n"
      "solver: {type: gmg}\n";
  // Positions of a level held by more than one cell, and the cells at them.
  auto shared_positions = [](const hierarchy::Level& lev) {
    std::map<std::int64_t, int> cells_at;
    for (const auto& p : lev.graph.ijk) ++cells_at[lev.graph.spec.cell_index(p[0], p[1], p[2])];
    std::array<int, 2> n{0, 0};
    for (const auto& [key, count] : cells_at)
      if (count > 1) n = {n[0] + 1, n[1] + count};
    return n;
  };
  for (const auto* y : {&yaml, &yaml2}) {
    Job job(PETSC_COMM_WORLD, *y, 8, "-gmg_levels 4");
    auto* mg = job.sim->multigrid();
    // 4 levels on 1 rank; 3 on 2, whose partition halves the super-block (max depth).
    ASSERT_GE(mg->num_levels(), 3);
    for (int l = 0; l + 1 < mg->num_levels(); ++l) {
      EXPECT_EQ(hierarchy::interpolation_mismatch(mg->level(l), mg->level(l + 1)), 0.0)
          << "level " << l;
    }
    EXPECT_EQ(shared_positions(mg->level(0))[0], 0);
    if (y == &yaml2) {
      // Three square columns (cells i, j in 0-2, 3-4, 5-7, all k) touching along the
      // edges x = y = 0.3 and x = y = 0.5. Level 1 (2x2x2 blocks): blocks (1,1) and
      // (2,2) hold one cell of each of two columns, in both block layers: 4 positions,
      // 8 cells. Level 2: blocks (0,0) (columns 1 and 2) and (1,1) (columns 2 and 3):
      // 2 positions, 4 cells. Level 3, one block: the three columns, 1 position, 3 cells.
      const std::array<std::array<int, 2>, 4> expected{{{0, 0}, {4, 8}, {2, 4}, {1, 3}}};
      for (int l = 0; l < mg->num_levels(); ++l)
        EXPECT_EQ(shared_positions(mg->level(l)), expected[l]) << l;
    }
  }
}

TEST(Multigrid, VCycleIsSymmetric) {
  // kBlock's hole and material jump make irregular coarse cells: with -gmg_schwarz_from 1
  // Chebyshev runs on Schwarz patches on level 1 (with growing degree and the energy-
  // minimizing interpolation), with 0 on level 0 too; by default nowhere.
  for (const char* smoother :
       {"gs", "chebyshev", "chebyshev -gmg_cycle w", "gs -gmg_cycle w",
        "chebyshev -gmg_schwarz_from 1 -gmg_degree_growth 2 -gmg_interpolation energy",
        "chebyshev -gmg_schwarz_from 0 -gmg_interpolation energy",
        "chebyshev -gmg_interpolation smoothed -gmg_smoothed_levels -1"}) {
    const std::string options =
        std::string("-gmg_levels 3 -gmg_presmooth 2 -gmg_postsmooth 2 -gmg_smoother ") + smoother;
    Operators ops(kBlock, {1.0, 3.0, true}, options.c_str());
    ASSERT_EQ(ops.job.sim->multigrid()->num_levels(), 3);
    auto* mg = ops.job.sim->multigrid();
    const std::string s = smoother;
    if (s.find("chebyshev") != std::string::npos) {
      std::int64_t patches[2] = {mg->schwarz_patches(0), mg->schwarz_patches(1)};
      MPI_Allreduce(MPI_IN_PLACE, patches, 2, MPI_INT64_T, MPI_SUM, PETSC_COMM_WORLD);
      EXPECT_EQ(patches[0] > 0, s.find("from 0") != std::string::npos) << smoother;
      EXPECT_EQ(patches[1] > 0, s.find("from") != std::string::npos) << smoother;
    }
    Vec x, y, Mx, My;
    MatCreateVecs(ops.A, &x, &y);
    VecDuplicate(x, &Mx);
    VecDuplicate(x, &My);
    fill(x, 0.1);
    fill(y, 2.9);
    mg->cycle(x, Mx);
    mg->cycle(y, My);
    PetscScalar a, b;
    VecDot(x, My, &a);
    VecDot(Mx, y, &b);
    EXPECT_LT(std::abs(a - b) / std::abs(a), 1e-10) << smoother;
    // And it is positive: <x, M^-1 x> > 0.
    PetscScalar c;
    VecDot(x, Mx, &c);
    EXPECT_GT(c, 0.0) << smoother;
    for (Vec* v : {&x, &y, &Mx, &My}) VecDestroy(v);
  }
}

TEST(Multigrid, SchwarzPatchSolveInvertsTheOperatorOnItsPatch) {
  // M r = sum_p R_p^T A_pp^-1 R_p r (multigrid/schwarz.hpp). Take one patch: the 27 copies of
  // the 8 children of one coarse cell, none prescribed. A vector x that is non-zero only on
  // the patch's centre copy has r = A x inside the patch (the centre's neighbours are the
  // patch), so R_p r = A_pp x_p and M r must give x back exactly: a wrong factor, a wrong
  // DOF map or a missing ghost row fails it. The reference is the assembled matrix alone.
  Operators ops(kBlock, {1.0, 3.0, true});
  auto* mg = ops.job.sim->multigrid();
  const auto& fine = mg->level(0);
  const auto& coarse = mg->level(1);
  const auto& D = fine.layout();
  Vec mask = mg->mask(0);
  // The mask in canonical copy order on every rank, to pick the same patch everywhere.
  const auto free = ops.job.canonical(mask);
  std::vector<std::vector<std::int32_t>> children(coarse.graph.num_cells());
  for (std::int32_t e = 0; e < fine.graph.num_cells(); ++e) children[fine.parent[e]].push_back(e);
  std::int32_t chosen = -1, centre = -1;
  for (std::int32_t C = 0; C < coarse.graph.num_cells() && chosen < 0; ++C) {
    if (children[C].size() != 8) continue;
    std::set<std::int32_t> copies;
    std::map<std::int32_t, int> seen;
    for (auto e : children[C])
      for (auto v : fine.copies().cell_corners[e]) {
        copies.insert(v);
        ++seen[v];
      }
    bool all_free = copies.size() == 27;
    for (auto v : copies)
      for (int c = 0; c < 3; ++c) all_free = all_free && free[3 * v + c] != 0.0;
    if (!all_free) continue;
    chosen = C;
    for (const auto& [v, n] : seen)
      if (n == 8) centre = v;
  }
  ASSERT_GE(chosen, 0);
  ASSERT_GE(centre, 0);
  std::vector<char> selected(coarse.graph.num_cells(), 0);
  selected[chosen] = 1;
  assembly::FineCells op(D, ops.job.model.cells, ops.w);
  multigrid::Schwarz schwarz;
  HEXCUT_CALL(multigrid::Schwarz::create(PETSC_COMM_WORLD, ops.job.model.dm, fine, coarse, selected,
                                         op, mask, &schwarz));
  std::int64_t patches = schwarz.num_patches();
  MPI_Allreduce(MPI_IN_PLACE, &patches, 1, MPI_INT64_T, MPI_SUM, PETSC_COMM_WORLD);
  EXPECT_EQ(patches, 1);
  Vec x, r, z;
  MatCreateVecs(ops.A, &x, &r);
  VecDuplicate(x, &z);
  VecSet(x, 0.0);
  const PetscInt row = 3 * D.global_block[centre];
  PetscInt lo, hi;
  VecGetOwnershipRange(x, &lo, &hi);
  if (row >= lo && row < hi) {
    const PetscScalar v[3] = {0.7, -1.3, 0.4};
    const PetscInt rows[3] = {row, row + 1, row + 2};
    VecSetValues(x, 3, rows, v, INSERT_VALUES);
  }
  VecAssemblyBegin(x);
  VecAssemblyEnd(x);
  MatMult(ops.A, x, r);
  VecSet(z, 0.0);
  HEXCUT_CALL(schwarz.apply(r, z));
  EXPECT_LT(rel_diff(x, z), 1e-12);
  for (Vec* v : {&x, &r, &z}) VecDestroy(v);
}

/// The Stanford bunny (input/meshes/bunny.obj), 10 cm tall, glued at its base, of cells h
/// and Poisson's ratio nu (deck numbers), optionally under gravity; solver gmg to 1e-8.
std::string bunny_deck(const std::string& h, const std::string& nu, bool gravity) {
  return "lattice: {bounds: [[-0.051, 0.0, -0.039], [0.051, 0.098, 0.039]], h: " + h + "}\n" +
         "materials: {tissue: {E: 1.0e5, nu: " + nu + ", rho: 1050}}\n" +
         "geometry: [{add: {mesh: {file: " HEXCUT_SOURCE_DIR
         "/input/meshes/bunny.obj, scale: 0.01}}}]\n"
         "boundary:\n  fixed: [{where: {half_space: {point: [0, 0.003, 0], normal: [0, 1, "
         "0]}}}]\n" +
         (gravity ? "  gravity: [0, -9.81, 0]\n" : "") + "solver: {type: gmg, rtol: 1.0e-8}\n";
}

TEST(Multigrid, CoarsestSolveIsExactWhenTheCoarseLevelIsSingular) {
  // bunny.yaml's body and support with the operator of its dynamic steps (dt 5 ms, mass
  // weight 4/dt^2), 3 levels: the masked Galerkin coarse matrix (2814 DOFs) has three
  // zero eigenvalues, from two coarse copies near the support whose columns of P differ
  // only on prescribed fine DOFs. The system is consistent for right-hand sides in its
  // range, which is where the V-cycle's restricted residuals lie, but a factorization
  // that divides by round-off pivots returned solutions of 1e12 times the right-hand
  // side with a relative residual of 1e-3, and on 2 ranks, at random, NaN or an
  // indefinite preconditioner; here, without it (-gmg_coarse_mat_mumps_icntl_24 0),
  // |x| / |r| = 2.5e7. With null-pivot detection it is exact on the range.
  const std::string yaml = bunny_deck("0.002", "0.45", false);
  const double dt = 0.005;
  Operators ops(yaml, {1.0, 4.0 / (dt * dt), true}, "-gmg_levels 3");
  auto* mg = ops.job.sim->multigrid();
  ASSERT_EQ(mg->num_levels(), 3);
  Vec r, b, x, res;
  mg->create_vector(2, &r);
  for (Vec* v : {&b, &x, &res}) VecDuplicate(r, v);
  fill(r, 0.7);
  // b in the range up to a perturbation of 1e-12 relative: the V-cycle's restricted
  // residuals are in the range only up to round-off.
  MatMult(mg->coarsest_matrix(), r, b);
  PetscReal nb0;
  VecNorm(b, NORM_INFINITY, &nb0);
  fill(res, 1.9);
  VecAXPY(b, 1e-12 * nb0, res);
  ASSERT_EQ(mg->solve_coarsest(b, x), 0);
  MatMult(mg->coarsest_matrix(), x, res);
  VecAXPY(res, -1.0, b);
  PetscReal nr, nb, nx, ny;
  VecNorm(res, NORM_2, &nr);
  VecNorm(b, NORM_2, &nb);
  VecNorm(x, NORM_2, &nx);
  VecNorm(r, NORM_2, &ny);
  std::printf("coarsest solve: relative residual %.2e, |x| / |r| %.2e\n", nr / nb, nx / ny);
  EXPECT_LT(nr / nb, 1e-10);
  EXPECT_LT(nx, 2 * ny);  // no huge null-space component
  for (Vec* v : {&r, &b, &x, &res}) VecDestroy(v);
}

/// GMG-CG iterations to rtol 1e-8 for cube_deck(n).
PetscInt cube_iterations(int n, const char* extra = nullptr) {
  Job job(PETSC_COMM_WORLD, cube_deck(n), 16, extra);
  job.run();
  PetscInt its;
  KSPGetIterationNumber(job.sim->ksp(), &its);
  return its;
}

TEST(Multigrid, CubeConvergenceIsIndependentOfResolution) {
  const PetscInt i16 = cube_iterations(16), i32 = cube_iterations(32), i64 = cube_iterations(64);
  std::printf("GMG-CG iterations to 1e-8: 16^3 %d, 32^3 %d, 64^3 %d\n", int(i16), int(i32),
              int(i64));
  EXPECT_LE(i32, 15);
  EXPECT_LE(i64 - i16, 3);
  // The Gauss-Seidel smoother, V(1,1), meets the same bounds.
  const char* gs = "-gmg_smoother gs -gmg_presmooth 1 -gmg_postsmooth 1";
  const PetscInt g16 = cube_iterations(16, gs), g32 = cube_iterations(32, gs);
  std::printf("Gauss-Seidel V(1,1): 16^3 %d, 32^3 %d\n", int(g16), int(g32));
  EXPECT_LE(g32, 15);
  EXPECT_LE(g32 - g16, 3);
}

PetscInt static_iterations(const std::string& yaml, int superblock = 8,
                           const char* options = nullptr) {
  Job job(PETSC_COMM_WORLD, yaml, superblock, options);
  job.run();
  PetscInt its;
  KSPGetIterationNumber(job.sim->ksp(), &its);
  return its;
}

TEST(Multigrid, IterationsDoNotDependOnSuperBlockOrGathering) {
  // The same hierarchy whatever the distribution: the same CG iterations (automatic depth).
  const PetscInt reference = static_iterations(kBlock, 8);
  EXPECT_EQ(static_iterations(kBlock, 1), reference);
  EXPECT_EQ(static_iterations(kBlock, 2), reference);
  EXPECT_EQ(static_iterations(kBlock, 8, "-gmg_gather_cells 100000"), reference);
}

TEST(Multigrid, BunnyConvergesWithin25Iterations) {
  // The Stanford bunny, 10 cm tall, ~112k cells, glued at its base, under gravity.
  const std::string yaml = bunny_deck("0.0012", "0.3", true);
  Job job(PETSC_COMM_WORLD, yaml);
  ASSERT_GE(job.model.lattice.num_cells(), 100000);
  job.run();
  PetscInt its;
  KSPGetIterationNumber(job.sim->ksp(), &its);
  std::printf("bunny: %d cells, %d GMG-CG iterations\n", int(job.model.lattice.num_cells()),
              int(its));
  EXPECT_LE(its, 25);
}

/// Static GMG-CG to rtol 1e-8 with `options`: iterations, the solution and the coarsest
/// level's matrix (owned by the caller). `cut`: the deck's cuts applied first.
struct SolveResult {
  PetscInt iterations = 0;
  std::vector<double> u;
  Mat coarsest = nullptr;
  int levels = 0;
  std::vector<double> duplication;   // per level (hierarchy::duplication)
  std::vector<std::int64_t> copies;  // per level: vertex copies (3 DOFs each)
  // Levels 1..L-2 (not the coarsest): the packed blocks as the level applies them, in the
  // precision it holds them in after the set-up (float rounding widened to double).
  std::vector<std::vector<double>> blocks;
  std::vector<bool> float_blocks;
};
SolveResult solve_static(const std::string& yaml, const char* options, bool cut = false) {
  Job job(PETSC_COMM_WORLD, yaml, 8, options);
  if (cut) {
    EXPECT_GT(job.cut_all(), 0);
  }
  job.run();
  SolveResult s;
  KSPGetIterationNumber(job.sim->ksp(), &s.iterations);
  s.u = job.canonical(job.state.u);
  MatDuplicate(job.sim->multigrid()->coarsest_matrix(), MAT_COPY_VALUES, &s.coarsest);
  s.levels = job.sim->multigrid()->num_levels();
  for (int l = 0; l < s.levels; ++l) {
    s.duplication.push_back(hexcut::hierarchy::duplication(job.sim->multigrid()->level(l).graph));
    s.copies.push_back(job.sim->multigrid()->level(l).copies().num_copies);
  }
  for (int l = 1; l + 1 < s.levels && job.sim->multigrid()->has_stored_cells(l); ++l) {
    // Cell by cell (cells may share a block: StoredCells::block_of).
    const auto& A = job.sim->multigrid()->stored_cells(l);
    s.float_blocks.push_back(!A.packed_double());
    std::vector<double> blocks;
    for (std::size_t e = 0; e < A.num_cells(); ++e) {
      const std::size_t b = multigrid::kPackedSize * (A.block_of() ? A.block_of()[e] : e);
      if (A.packed_double())
        blocks.insert(blocks.end(), A.packed_double() + b,
                      A.packed_double() + b + multigrid::kPackedSize);
      else
        blocks.insert(blocks.end(), A.packed_single() + b,
                      A.packed_single() + b + multigrid::kPackedSize);
    }
    s.blocks.push_back(std::move(blocks));
  }
  return s;
}

/// The cases of issue 13's mixed-precision tests: the cantilever, the bunny, a cube cut into
/// rods and a slender bar (1280 x 4 x 4 cells, ||A|| ||x|| / ||b|| = 6e10), static, gmg to
/// rtol 1e-8.
struct PrecisionCase {
  const char* name;
  std::string yaml;
  bool cut;
};
std::vector<PrecisionCase> mixed_precision_cases() {
  const std::string bunny = bunny_deck("0.002", "0.3", true);
  std::string rods =
      "lattice: {h: 0.0625, dims: [16, 16, 16]}\n"
      "materials: {m: {E: 1.0e6, nu: 0.3, rho: 1000}}\n"
      "geometry: [{add: {box: {min: [0, 0, 0], max: [1, 1, 1]}}}]\n"
      "boundary:\n  fixed: [{where: {plane: {point: [0, 0, 0], normal: [0, 0, 1]}}}]\n"
      "  gravity: [0.3, 0.2, -9.81]\n"
      "solver: {type: gmg, rtol: 1.0e-8}\ncuts:\n";
  for (double c : {0.3125, 0.5625, 0.8125}) {
    const std::string a = std::to_string(c);
    rods += "  - blade: {polygon: [[" + a + ", -0.1, 0.5], [" + a + ", 1.1, 0.5], [" + a +
            ", 1.1, 1.1], [" + a + ", -0.1, 1.1]]}\n";
    rods += "  - blade: {polygon: [[-0.1, " + a + ", 0.5], [1.1, " + a + ", 0.5], [1.1, " + a +
            ", 1.1], [-0.1, " + a + ", 1.1]]}\n";
  }
  return {
      {"cantilever", cantilever_deck(0.0125, "{type: static}", "{type: gmg, rtol: 1.0e-8}"), false},
      {"bunny", bunny, false},
      {"cube cut into rods", rods, true},
      {"slender bar",
       cantilever_deck(0.0125, "{type: static}", "{type: gmg, rtol: 1.0e-8}", 16.0, 0.05, 0.05),
       false}};
}

TEST(Multigrid, SinglePrecisionCoarseLevelsKeepTheIterationsAndTheSolution) {
  // -gmg_precision single stores the coarse levels' Galerkin blocks in float, each the
  // rounding of the double run's block (the Galerkin chain is formed in double: every
  // level's float blocks equal the double run's rounded, bit for bit), and factors the
  // coarsest matrix from double blocks (equal to the double run's). CG in double still
  // reaches rtol 1e-8 with at most 2 more iterations, and the solutions agree to the
  // tolerance, on mixed_precision_cases(); on the slender bar a chain of rounded levels took
  // 40 iterations against 23 and a coarsest matrix factored from float blocks made the
  // preconditioner indefinite (doc/theory.md, "Mixed precision").
  for (const auto& c : mixed_precision_cases()) {
    auto d = solve_static(c.yaml, nullptr, c.cut);
    auto s = solve_static(c.yaml, "-gmg_precision single", c.cut);
    double du = 0, nu = 0;
    for (std::size_t i = 0; i < d.u.size(); ++i)
      du = std::max(du, std::abs(d.u[i] - s.u[i])), nu = std::max(nu, std::abs(d.u[i]));
    PetscReal na, nd;
    MatNorm(d.coarsest, NORM_FROBENIUS, &na);
    MatAXPY(s.coarsest, -1.0, d.coarsest, DIFFERENT_NONZERO_PATTERN);
    MatNorm(s.coarsest, NORM_FROBENIUS, &nd);
    std::printf(
        "%s (%d levels): iterations double %d, single %d; solutions differ by %.1e (relative); "
        "coarsest "
        "matrices by %.1e\n",
        c.name, s.levels, int(d.iterations), int(s.iterations), du / nu, nd / na);
    EXPECT_LE(s.iterations, d.iterations + 2) << c.name;
    EXPECT_LT(du / nu, 1e-6) << c.name;
    EXPECT_LT(nd / na, 1e-14) << c.name;  // factored from the double chain
    ASSERT_EQ(s.blocks.size(), d.blocks.size()) << c.name;
    // Every level but the first and the coarsest is float: none in a 2-level hierarchy
    // (the rods: the depth rule for cut bodies stops at level 1).
    EXPECT_EQ(s.blocks.size(), std::size_t(std::max(0, s.levels - 2))) << c.name;
    for (std::size_t k = 0; k < s.blocks.size(); ++k) {
      EXPECT_TRUE(s.float_blocks[k] && !d.float_blocks[k]) << c.name << " level " << k + 1;
      ASSERT_EQ(s.blocks[k].size(), d.blocks[k].size());
      std::size_t unequal = 0, changed = 0;
      for (std::size_t i = 0; i < s.blocks[k].size(); ++i) {
        unequal += s.blocks[k][i] != double(float(d.blocks[k][i]));
        changed += s.blocks[k][i] != d.blocks[k][i];
      }
      EXPECT_EQ(unequal, 0u) << c.name << " level " << k + 1 << ": not the double chain rounded";
      EXPECT_GT(changed, s.blocks[k].size() / 2) << c.name << " level " << k + 1 << ": not float";
    }
    MatDestroy(&d.coarsest);
    MatDestroy(&s.coarsest);
  }
}

TEST(Multigrid, FloatVCycleKeepsTheIterationsAndTheSolution) {
  // -gmg_backend host_loop -gmg_precision single: the whole cycle in float (every level's
  // vectors and level data, the fine cells' products in float arithmetic), CG and its
  // residual in double. Issue 13: rtol 1e-8 reached with at most 2 more iterations than the
  // double cycle, solutions equal to the tolerance, on the same cases as the float blocks,
  // on 1 and 2 ranks.
  for (const auto& c : mixed_precision_cases()) {
    auto d = solve_static(c.yaml, nullptr, c.cut);
    auto s = solve_static(c.yaml, "-gmg_backend host_loop -gmg_precision single", c.cut);
    ASSERT_EQ(d.u.size(), s.u.size());
    const auto du = max_difference(d.u.data(), s.u.data(), d.u.size());
    std::printf("%s (%d levels): iterations double %d, float cycle %d; solutions differ by %.1e\n",
                c.name, s.levels, int(d.iterations), int(s.iterations), du.relative());
    EXPECT_LE(s.iterations, d.iterations + 2) << c.name;
    // The slender bar's solutions are determined only to its round-off floor: a true relative
    // residual of 4.6e-6 in double (doc/benchmarks.md, "Slender bars"; measured 1.4e-6 apart).
    const bool bar = std::string(c.name) == "slender bar";
    EXPECT_LT(du.relative(), bar ? 1e-5 : 1e-6) << c.name;
    MatDestroy(&d.coarsest);
    MatDestroy(&s.coarsest);
  }
}

/// A 16^3 unit cube clamped at its base under gravity; `cuts`: vertical blades every 3 cells
/// from the top down to mid-height, aligned with the lattice or turned by 20 degrees about
/// the vertical (the case family of scripts/bench/coarse_spaces.py).
std::string blade_grid_cube(bool cuts, double angle_deg) {
  const int n = 16;
  std::string y =
      "lattice: {h: 0.0625, dims: [16, 16, 16]}\n"
      "materials: {m: {E: 1.0e6, nu: 0.3, rho: 1000}}\n"
      "geometry: [{add: {box: {min: [0, 0, 0], max: [1, 1, 1]}}}]\n"
      "boundary:\n  fixed: [{where: {plane: {point: [0, 0, 0], normal: [0, 0, 1]}}}]\n"
      "  gravity: [0, 0, -9.81]\n"
      "solver: {type: gmg, rtol: 1.0e-8}\n";
  if (!cuts) return y;
  y += "cuts:\n";
  const double a = angle_deg * M_PI / 180.0, ca = std::cos(a), sa = std::sin(a);
  for (double p = 3.3 / n; p < 1.0; p += 3.0 / n)
    for (int d = 0; d < 2; ++d) {
      y += "  - blade: {polygon: [";
      const double sz[4][2] = {{-0.3, 0.5}, {1.3, 0.5}, {1.3, 1.1}, {-0.3, 1.1}};
      for (int k = 0; k < 4; ++k) {
        const double x = (d == 0 ? p : sz[k][0]) - 0.5, yy = (d == 0 ? sz[k][0] : p) - 0.5;
        char buf[96];
        std::snprintf(buf, sizeof buf, "%s[%.6f, %.6f, %.1f]", k ? ", " : "",
                      0.5 + ca * x - sa * yy, 0.5 + sa * x + ca * yy, sz[k][1]);
        y += buf;
      }
      y += "]}\n";
    }
  return y;
}

/// x = M^-1 b by a backend's cycle (HostLoopCycle, HostLoopCycleSingle), on b's owned values.
std::vector<double> backend_cycle(multigrid::CycleBackend& cycle, Vec b) {
  PetscInt n;
  VecGetLocalSize(b, &n);
  std::vector<double> x(n);
  const PetscScalar* ba;
  VecGetArrayRead(b, &ba);
  HEXCUT_CALL(cycle.apply(ba, x.data()));
  VecRestoreArrayRead(b, &ba);
  return x;
}

TEST(Multigrid, LoopCycleOnTheHostIsTheCycle) {
  // The cycle written once over an executor (multigrid/loop_cycle.hpp: what the CUDA backend
  // runs) on the host backend equals Multigrid::cycle, the PETSc-vector cycle, to round-off
  // (the transfers sum in another order): V and W, Chebyshev and Gauss-Seidel, trilinear and
  // energy-minimizing transfers, double and float coarse blocks, the holed
  // two-material corotated block and the cut 3-cell blade grid (coarse cells of several
  // pieces, dead coarse DOFs). On 2 ranks (multigrid_mpi_test) the same, through the
  // executor's ghost exchange: each rank compares its owned values.
  struct Case {
    std::string yaml;
    const char* options;
    bool cut;
    int superblock;
    // Round-off is what the two cycles may differ by, times what the cycle itself amplifies
    // it by: ~1 except on the energy rows of the two-material block, where Multigrid::cycle
    // answers a 1e-15 relative change of b with 1.1e-12 (measured): there 1e3 x the bounds.
    double amplification = 1.0;
  };
  const Case cases[] = {
      {kBlock, "-gmg_levels 3", false, 8},
      {kBlock, "-gmg_levels 3 -gmg_cycle w -gmg_precision single", false, 8},
      {kBlock, "-gmg_levels 3 -gmg_presmooth 3 -gmg_postsmooth 1", false, 8},
      {blade_grid_cube(true, 20.0), "-gmg_levels 4 -gmg_cycle w", true, 8},
      // Super-blocks of one cell: on 2 ranks coarse cells have children on other ranks, so a
      // transfer reaches coarse copies beyond the coarse cells' ghosts.
      {kBlock, "-gmg_levels 3 -gmg_precision single", false, 1},
      // Coloured block Gauss-Seidel (forward before, backward after the coarse correction).
      {kBlock, "-gmg_levels 3 -gmg_smoother gs", false, 8},
      {kBlock, "-gmg_levels 3 -gmg_smoother gs -gmg_presmooth 2 -gmg_omega 0.9", false, 1},
      {blade_grid_cube(true, 20.0), "-gmg_levels 4 -gmg_cycle w -gmg_smoother gs", true, 8},
      // Energy-minimizing rows (3x3 blocks): around the two materials' interface, and after
      // the cut (irregular coarse cells).
      {kBlock, "-gmg_levels 3 -gmg_interpolation energy", false, 8, 1e3},
      {blade_grid_cube(true, 20.0), "-gmg_levels 4 -gmg_cycle w -gmg_interpolation energy", true,
       8},
  };
  for (const auto& c : cases) {
    Job job(PETSC_COMM_WORLD, c.yaml, c.superblock, c.options);
    if (c.cut) {
      EXPECT_GT(job.cut_all(), 0);
    }
    set_rotations(job);
    auto& mg = *job.sim->multigrid();
    HEXCUT_CALL(mg.update(job.model.cells, {1.0, 0.0, true}, job.model.boundary.constraints.rows));
    std::unique_ptr<multigrid::HostLoopCycle> loop;
    HEXCUT_CALL(multigrid::HostLoopCycle::create(mg, &loop));
    if (c.superblock == 1) {  // on more ranks, a transfer reaches copies beyond the ghosts
      std::int64_t extra = 0;
      for (int l = 0; l < loop->num_levels(); ++l)
        extra += loop->level(l).num_local - mg.level(l).layout().num_local();
      MPI_Allreduce(MPI_IN_PLACE, &extra, 1, MPI_INT64_T, MPI_SUM, PETSC_COMM_WORLD);
      PetscMPIInt ranks;
      MPI_Comm_size(PETSC_COMM_WORLD, &ranks);
      if (ranks > 1) {
        EXPECT_GT(extra, 0) << c.options << ": no coarse copies beyond the ghosts";
      }
    }
    if (std::strstr(c.options, "energy")) {  // the case has block rows, not only weights
      bool blocks = false;
      for (int l = 0; l + 1 < loop->num_levels(); ++l) blocks |= loop->level(l).weight_block == 9;
      EXPECT_TRUE(blocks) << c.options << ": no energy rows";
    }
    Vec b, x;
    HEXCUT_CALL(mg.create_vector(0, &b));
    VecDuplicate(b, &x);
    fill(b, 0.7);
    HEXCUT_CALL(mg.cycle(b, x));
    const auto y = backend_cycle(*loop, b);
    const PetscScalar* xa;
    VecGetArrayRead(x, &xa);
    const auto d = max_difference(xa, y.data(), y.size());
    VecRestoreArrayRead(x, &xa);
    std::printf("%s%s: %d levels, max |loop - cycle| / max |cycle| = %.1e\n", c.options,
                c.cut ? " (cut)" : "", mg.num_levels(), d.relative());
    EXPECT_GT(d.magnitude, 0.0);
    EXPECT_LT(d.relative(), 1e-12 * c.amplification) << c.options;
    // The same cycle on float vectors: float's rounding (2^-24 = 6e-8 per operation, grown
    // by the cycle's contraction), neither double's round-off nor a different cycle.
    std::unique_ptr<multigrid::HostLoopCycleSingle> single;
    HEXCUT_CALL(multigrid::HostLoopCycleSingle::create(mg, &single));
    const auto ys = backend_cycle(*single, b);
    const auto ds = max_difference(y.data(), ys.data(), y.size());
    std::printf("  in float: max |float - double| / max |double| = %.1e\n", ds.relative());
    EXPECT_GT(ds.relative(), 1e-9) << c.options << ": not float";
    EXPECT_LT(ds.relative(), 1e-5 * c.amplification) << c.options;
    VecDestroy(&b);
    VecDestroy(&x);
  }
  {
    // Chosen as options, Multigrid::cycle runs the float cycle: float's distance from the
    // double loop cycle (a double cycle behind the options would be 1e-16 from it).
    Job job(PETSC_COMM_WORLD, kBlock, 8,
            "-gmg_levels 3 -gmg_backend host_loop -gmg_precision single");
    auto& mg = *job.sim->multigrid();
    HEXCUT_CALL(mg.update(job.model.cells, {1.0, 0.0, true}, job.model.boundary.constraints.rows));
    Vec b, x;
    HEXCUT_CALL(mg.create_vector(0, &b));
    VecDuplicate(b, &x);
    fill(b, 0.7);
    HEXCUT_CALL(mg.cycle(b, x));
    std::unique_ptr<multigrid::HostLoopCycle> loop;
    HEXCUT_CALL(multigrid::HostLoopCycle::create(mg, &loop));
    const auto y = backend_cycle(*loop, b);
    const PetscScalar* xa;
    VecGetArrayRead(x, &xa);
    const auto d = max_difference(y.data(), xa, y.size());
    VecRestoreArrayRead(x, &xa);
    std::printf("-gmg_backend host_loop -gmg_precision single: %.1e from the double loop cycle\n",
                d.relative());
    EXPECT_GT(d.relative(), 1e-9) << "the options did not select the float cycle";
    EXPECT_LT(d.relative(), 1e-5);
    VecDestroy(&b);
    VecDestroy(&x);
  }
  // What it does not run yet is named.
  Job job(PETSC_COMM_WORLD, kBlock, 8, "-gmg_levels 3 -gmg_schwarz_from 1");
  auto& mg = *job.sim->multigrid();
  HEXCUT_CALL(mg.update(job.model.cells, {1.0, 0.0, true}, job.model.boundary.constraints.rows));
  std::unique_ptr<multigrid::HostLoopCycle> loop;
  PetscPushErrorHandler(PetscReturnErrorHandler, nullptr);
  const PetscErrorCode ierr = multigrid::HostLoopCycle::create(mg, &loop);
  PetscPopErrorHandler();
  EXPECT_EQ(ierr, PETSC_ERR_SUP);
}

TEST(Multigrid, HostLoopBackendSolvesLikeTheHostCycle) {
  // -gmg_backend host_loop (the CUDA backend's cycle on the host) through whole static solves,
  // chosen like any option: the same CG iterations and displacements as the default backend,
  // on the uncut cube and the cut blade grid (W-cycle, the default after cuts), with Chebyshev
  // and with Gauss-Seidel, on 1 and 2 ranks.
  for (const std::string smoother : {"", " -gmg_smoother gs"})
    for (bool cut : {false, true}) {
      auto host =
          solve_static(blade_grid_cube(cut, 20.0), ("-gmg_levels 3" + smoother).c_str(), cut);
      auto loop = solve_static(blade_grid_cube(cut, 20.0),
                               ("-gmg_levels 3 -gmg_backend host_loop" + smoother).c_str(), cut);
      ASSERT_EQ(host.u.size(), loop.u.size());
      const auto d = max_difference(host.u.data(), loop.u.data(), host.u.size());
      std::printf("%s%s: %d / %d iterations, max |du| / max |u| = %.1e\n", cut ? "cut" : "uncut",
                  smoother.c_str(), int(host.iterations), int(loop.iterations), d.relative());
      EXPECT_EQ(host.iterations, loop.iterations);
      EXPECT_GT(d.magnitude, 0.0);
      EXPECT_LT(d.relative(), 1e-10);
      MatDestroy(&host.coarsest);
      MatDestroy(&loop.coarsest);
    }
}

TEST(Multigrid, SmoothedInterpolationKeepsCutBladeGridsWithinOneAndAHalfTimesTheUncutCube) {
  // Issue 10's goal on the blade grids: CG iterations <= 1.5 x the uncut cube's. At the full
  // depth (the duplication rule off) the W-cycle with trilinear interpolation misses it (16
  // and 15 against 8, measured), the W-cycle with the smoothed transfer to level 1 meets it
  // (10 and 10); the solutions agree.
  const char* full = "-gmg_cycle w -gmg_max_duplication -1";
  auto uncut = solve_static(blade_grid_cube(false, 0), full);
  auto uncut_s = solve_static(blade_grid_cube(false, 0),
                              "-gmg_cycle w -gmg_max_duplication -1 -gmg_interpolation smoothed");
  EXPECT_EQ(uncut_s.iterations, uncut.iterations) << "no irregular coarse cell: nothing changes";
  for (double angle : {0.0, 20.0}) {
    auto tri = solve_static(blade_grid_cube(true, angle), full, true);
    auto sm =
        solve_static(blade_grid_cube(true, angle),
                     "-gmg_cycle w -gmg_max_duplication -1 -gmg_interpolation smoothed", true);
    double du = 0, nu = 0;
    for (std::size_t i = 0; i < tri.u.size(); ++i)
      du = std::max(du, std::abs(tri.u[i] - sm.u[i])), nu = std::max(nu, std::abs(tri.u[i]));
    std::printf(
        "blades turned %.0f deg: W-cycle iterations uncut %d, trilinear %d, smoothed %d; "
        "solutions differ by %.1e\n",
        angle, int(uncut.iterations), int(tri.iterations), int(sm.iterations), du / nu);
    EXPECT_GT(tri.iterations, 1.5 * double(uncut.iterations)) << "the case is hard";
    EXPECT_LE(sm.iterations, 1.5 * double(uncut.iterations)) << angle;
    EXPECT_LT(du / nu, 1e-6);
    MatDestroy(&tri.coarsest);
    MatDestroy(&sm.coarsest);
  }
  MatDestroy(&uncut.coarsest);
  MatDestroy(&uncut_s.coarsest);
}

TEST(Multigrid, DuplicationRuleStopsWhereCoarseCellsOutgrowThePieces) {
  // The automatic depth's duplication stop (hierarchy::duplication: coarse cells per occupied
  // block, less one): 0 on every level of the solid cube, which keeps its depth; on the
  // 3-cell blade grids it passes level 1 (2-cell cells, narrower than the pieces) and stops
  // before level 2 (> 0.5: seen with the rule off), and the CG iterations drop from the full
  // depth's 16 and 15 to 12 and 13 (measured at 16^3, against the solid cube's 8: 1.5x and
  // 1.6x; issue 10's 1.5x is met on the aligned grid only). The solutions agree. The stop is
  // allowed at level 1 here (-gmg_duplication_share 1); the default's share keeps it off
  // level 1 (the next test).
  auto uncut = solve_static(blade_grid_cube(false, 0), nullptr);
  auto uncut_full = solve_static(blade_grid_cube(false, 0), "-gmg_max_duplication -1");
  EXPECT_EQ(uncut.levels, uncut_full.levels);
  for (double d : uncut_full.duplication) EXPECT_EQ(d, 0.0);
  for (double angle : {0.0, 20.0}) {
    auto rule = solve_static(blade_grid_cube(true, angle), "-gmg_duplication_share 1", true);
    auto full = solve_static(blade_grid_cube(true, angle), "-gmg_max_duplication -1", true);
    ASSERT_GE(full.levels, 3);
    std::printf("blades turned %.0f deg: duplication per level", angle);
    for (double d : full.duplication) std::printf(" %.2f", d);
    std::printf("; levels %d (rule) / %d (full); iterations %d / %d, uncut %d\n", rule.levels,
                full.levels, int(rule.iterations), int(full.iterations), int(uncut.iterations));
    EXPECT_LE(full.duplication[1], 0.5);
    EXPECT_GT(full.duplication[2], 0.5);
    EXPECT_EQ(rule.levels, 2);
    EXPECT_LE(rule.iterations, (angle == 0 ? 1.5 : 1.65) * double(uncut.iterations)) << angle;
    EXPECT_LE(rule.iterations, full.iterations - 2) << angle;
    EXPECT_GT(full.iterations, 1.5 * double(uncut.iterations)) << "the case is hard";
    double du = 0, nu = 0;
    for (std::size_t i = 0; i < rule.u.size(); ++i)
      du = std::max(du, std::abs(rule.u[i] - full.u[i])), nu = std::max(nu, std::abs(rule.u[i]));
    EXPECT_LT(du / nu, 1e-6);
    MatDestroy(&rule.coarsest);
    MatDestroy(&full.coarsest);
  }
  MatDestroy(&uncut.coarsest);
  MatDestroy(&uncut_full.coarsest);
}

TEST(Multigrid, DuplicationRuleStopsOnlyAtLevelsOfATenthOfTheFineDofs) {
  // The duplication stop's share (-gmg_duplication_share, default 0.1): the level it stops at
  // is factored, and a level 1 (1/8 of the fine DOFs or more) costs more to factor than the
  // iterations a deeper hierarchy adds (doc/benchmarks.md, "The duplication rule's share").
  // On the 16^3 3-cell blade grid with the automatic depth's floor lowered to 500 DOFs (so
  // that the full depth has 4 levels, as on larger bodies), the default passes the level-2
  // duplication (level 1 is over the share) and stops before level 3 (level 2 is under it);
  // share 1 stops before level 2, as the rule did before it had a share.
  const std::string deck = blade_grid_cube(true, 20.0);
  auto dofs = [](const SolveResult& s, int l) { return 3.0 * double(s.copies[l]); };
  auto rule = solve_static(deck, "-gmg_coarse_dofs 500", true);
  auto level1 = solve_static(deck, "-gmg_coarse_dofs 500 -gmg_duplication_share 1", true);
  auto full = solve_static(deck, "-gmg_coarse_dofs 500 -gmg_max_duplication -1", true);
  ASSERT_GE(full.levels, 4);
  std::printf(
      "levels %d / %d / %d (share 0.1 / share 1 / no stop); level 1, 2 DOFs over the "
      "fine: %.3f, %.3f; duplication %.2f, %.2f, %.2f; iterations %d / %d / %d\n",
      rule.levels, level1.levels, full.levels, dofs(full, 1) / dofs(full, 0),
      dofs(full, 2) / dofs(full, 0), full.duplication[1], full.duplication[2], full.duplication[3],
      int(rule.iterations), int(level1.iterations), int(full.iterations));
  EXPECT_GT(dofs(full, 1), 0.1 * dofs(full, 0));
  EXPECT_LE(dofs(full, 2), 0.1 * dofs(full, 0));
  EXPECT_GT(full.duplication[2], 0.5);
  EXPECT_GT(full.duplication[3], 0.5);
  EXPECT_EQ(level1.levels, 2);
  EXPECT_EQ(rule.levels, 3);
  EXPECT_LT(rule.iterations, full.iterations);
  double du = 0, nu = 0;
  for (std::size_t i = 0; i < rule.u.size(); ++i)
    du = std::max(du, std::abs(rule.u[i] - full.u[i])), nu = std::max(nu, std::abs(rule.u[i]));
  EXPECT_LT(du / nu, 1e-6);
  for (auto* s : {&rule, &level1, &full}) MatDestroy(&s->coarsest);
}

TEST(Multigrid, BarsTouchingAlongAnEdgeConvergeLikeOneBar) {
  // Two bars that share only an edge get separate vertex copies along it, and the
  // component hierarchy keeps them apart on every level.
  auto deck = [](const std::string& bodies) {
    return "lattice: {h: 0.025, dims: [40, 8, 8]}\n"
           "materials: {m: {E: 1.0e6, nu: 0.3, rho: 1}}\n"
           "geometry:\n" +
           bodies +
           "boundary:\n  fixed: [{where: {plane: {point: [0, 0, 0], normal: [1, 0, 0]}}}]\n"
           "  gravity: [0, 0, -9.81]\n"
           "solver: {type: gmg, rtol: 1.0e-8}\n";
  };
  const auto one =
      static_iterations(deck("  - add: {box: {min: [0, 0, 0], max: [1, 0.1, 0.1]}}\n"));
  const auto two =
      static_iterations(deck("  - add: {box: {min: [0, 0, 0], max: [1, 0.1, 0.1]}}\n"
                             "  - add: {box: {min: [0, 0.1, 0.1], max: [1, 0.2, 0.2]}}\n"));
  std::printf("one bar %d iterations, two edge-touching bars %d\n", int(one), int(two));
  EXPECT_LE(two, one + 2);
}

// The loop layer's cell colours (backend::colour_cells): a concurrent backend scatters the
// cells of one colour at once, so no two of them may share a vertex copy, on every level.
// Parity alone (8 colours) is not enough on coarse levels: two pieces of one 2x2x2 block
// sit at one position and can share copies through a neighbour. Here cells (2,2,2) and
// (3,3,2) touch only along an edge inside their block and are joined below it through
// (2,2,1), (2,3,1), (3,3,1): their coarse cells share a position and copies.
TEST(Multigrid, CellColoursShareNoVertexCopyOnAnyLevel) {
  auto cell = [](int i, int j, int k) {
    return "  - add: {box: {min: [" + std::to_string(i) + ", " + std::to_string(j) + ", " +
           std::to_string(k) + "], max: [" + std::to_string(i + 1) + ", " + std::to_string(j + 1) +
           ", " + std::to_string(k + 1) + "]}}\n";
  };
  const std::string joined_below =
      "lattice: {h: 1.0, dims: [4, 4, 4]}\n"
      "materials: {m: {E: 1.0, nu: 0.3, rho: 1}}\n"
      "geometry:\n" +
      cell(2, 2, 2) + cell(3, 3, 2) + cell(2, 2, 1) + cell(2, 3, 1) + cell(3, 3, 1) +
      "boundary: {fixed: [{where: {plane: {point: [0, 0, 1], normal: [0, 0, 1]}}}]}\n"
      "solver: {type: gmg}\n";
  const std::string holes =
      "lattice: {h: 0.1, dims: [8, 8, 8]}\n"
      "materials: {m: {E: 1.0, nu: 0.3, rho: 1}}\n"
      "geometry:\n  - add: {box: {min: [0, 0, 0], max: [0.8, 0.8, 0.8]}}\n"
      "  - subtract: {box: {min: [0.1, 0.0, 0.1], max: [0.2, 0.8, 0.7]}}\n"
      "  - subtract: {box: {min: [0.5, 0.1, 0.0], max: [0.6, 0.7, 0.8]}}\n"
      "boundary: {fixed: [{where: {plane: {point: [0, 0, 0], normal: [1, 0, 0]}}}]}\n"
      "solver: {type: gmg}\n";
  // Largest number of cells of one colour that share a copy (1: conflict-free).
  auto worst_sharing = [](const topology::DofLayout& D, const backend::CellColours& c) {
    int worst = 0;
    for (int k = 0; k < c.num_colours(); ++k) {
      std::map<std::int32_t, int> users;
      for (auto i = c.offset[k]; i < c.offset[k + 1]; ++i)
        for (auto v : D.cell_corners[c.cell[i]]) worst = std::max(worst, ++users[v]);
    }
    return worst;
  };
  for (const auto* y : {&joined_below, &holes}) {
    Job job(PETSC_COMM_WORLD, *y, 8, "-gmg_levels 2");
    auto* mg = job.sim->multigrid();
    int ranks;
    MPI_Comm_size(PETSC_COMM_WORLD, &ranks);
    // On 2 ranks the small lattice's partition may leave room for one level only.
    if (ranks == 1) {
      ASSERT_EQ(mg->num_levels(), 2);
    }
    for (int l = 0; l < mg->num_levels(); ++l) {
      const auto& lev = mg->level(l);
      std::vector<std::array<int, 3>> pos, parity_only;
      for (auto c : lev.layout().cells)
        pos.push_back({lev.graph.ijk[c][0], lev.graph.ijk[c][1], lev.graph.ijk[c][2]});
      const auto colours = backend::colour_cells(pos);
      EXPECT_EQ(worst_sharing(lev.layout(), colours), pos.empty() ? 0 : 1) << "level " << l;
      std::size_t total = 0;
      for (int k = 0; k < colours.num_colours(); ++k)
        total += colours.offset[k + 1] - colours.offset[k];
      EXPECT_EQ(total, pos.size());
      if (l == 0) {
        EXPECT_LE(colours.num_colours(), 8);
      }
      if (y == &joined_below && l == 1 && !pos.empty()) {
        // Parity alone would put the two pieces at block (1,1,1) in one colour.
        backend::CellColours parity;
        parity.offset.assign(9, 0);
        for (const auto& p : pos) ++parity.offset[element::parity_octant(p[0], p[1], p[2]) + 1];
        for (int k = 0; k < 8; ++k) parity.offset[k + 1] += parity.offset[k];
        parity.cell.resize(pos.size());
        std::vector<std::int32_t> next(parity.offset.begin(), parity.offset.end() - 1);
        for (std::size_t e = 0; e < pos.size(); ++e)
          parity.cell[next[element::parity_octant(pos[e][0], pos[e][1], pos[e][2])]++] =
              std::int32_t(e);
        // On several ranks the two pieces may live on different ranks (a coarse cell goes
        // with its lowest-numbered child); where both are local the rule must still hold.
        const int parity_sharing = worst_sharing(lev.layout(), parity);
        if (ranks == 1) {
          EXPECT_EQ(parity_sharing, 2);
        }
        if (parity_sharing == 2) {
          EXPECT_GT(colours.num_colours(), 8);
        }
      }
    }
  }
}

// Cells without a shared stiffness kind (per-cell E from an image: more distinct values
// than kinds) are applied as h (lambda K_lambda + mu K_mu) from the two reference matrices,
// never formed per visit (the loop layer's device-sized kernels), and formed once per update
// in the multigrid. Every path must agree with the same cells given one kind each, whose
// stiffness element::cell_stiffness forms: the assembled matrix, assembly::apply and the
// multigrid's fine operator, with rotations and mass.
TEST(Multigrid, CellsWithoutAKindMatchTheirFormedStiffness) {
  const assembly::OperatorWeights w{1.3, 40.0, false};
  Job job(PETSC_COMM_WORLD, kBlock, 8, "-gmg_levels 3");
  set_rotations(job);
  auto& C = job.model.cells;
  for (std::size_t e = 0; e < C.lambda.size(); ++e) {  // distinct values per cell
    C.lambda[e] *= 1.0 + 0.37 * std::sin(0.1 * double(e));
    C.mu[e] *= 1.0 + 0.21 * std::cos(0.13 * double(e));
  }
  assembly::CellData formed = C;  // the reference: one kind per cell, formed here
  formed.kind.resize(C.lambda.size());
  formed.kind_stiffness.resize(C.lambda.size());
  for (std::size_t e = 0; e < C.lambda.size(); ++e) {
    formed.kind[e] = std::int32_t(e);
    element::cell_stiffness(element::reference_matrices(), C.h, C.lambda[e], C.mu[e],
                            formed.kind_stiffness[e].data());
  }
  C.kind.assign(C.lambda.size(), -1);
  C.kind_stiffness.clear();
  DM dm = job.model.dm;
  Vec x, y_ref, y;
  DMCreateGlobalVector(dm, &x);
  VecDuplicate(x, &y_ref);
  VecDuplicate(x, &y);
  fill(x, 0.7);
  const auto& D = job.model.layout;
  check_petsc(assembly::apply(dm, D, formed, w, x, y_ref), "apply formed");
  check_petsc(assembly::apply(dm, D, C, w, x, y), "apply");
  EXPECT_LT(rel_diff(y_ref, y), 1e-13) << "assembly::apply";
  Mat A;
  check_petsc(assembly::create_matrix(PETSC_COMM_WORLD, job.model.copies, D, &A), "create");
  check_petsc(assembly::assemble_matrix(D, C, w, A), "assemble");
  MatMult(A, x, y);
  EXPECT_LT(rel_diff(y_ref, y), 1e-13) << "assembled";
  // The multigrid's fine operator is the constrained one: compare on free DOFs only.
  auto* mg = job.sim->multigrid();
  check_petsc(mg->update(C, w, job.model.boundary.constraints.rows), "update");
  HEXCUT_CALL(
      assembly::assemble_constrained_matrix(dm, D, formed, w, job.model.boundary.constraints, A));
  MatMult(A, x, y_ref);
  check_petsc(mg->apply_fine(x, y), "apply_fine");
  EXPECT_LT(rel_diff(y_ref, y), 1e-13) << "multigrid fine operator";
  // Level 1 from cells without a kind: h (lambda G_lambda + mu G_mu), rotated.
  EXPECT_LT(galerkin_mismatch(mg, A), 1e-12) << "Galerkin blocks";
  MatDestroy(&A);
  VecDestroy(&x);
  VecDestroy(&y);
  VecDestroy(&y_ref);
}

TEST(Multigrid, FineCellsOnFloatVectorsApplyTheOperatorInFloat) {
  // The float V-cycle's fine operator (FineCells::apply_add on float vectors: float copies of
  // the kinds' stiffness and of the reference matrices, float arithmetic) against the double
  // one, on the corotated holed two-material block with a mask, cells with and without a kind
  // (the latter from K_lambda and K_mu), lumped and consistent mass (a weight where the mass
  // dominates): float's accuracy (2^-24 per operation over 24-term sums), nothing more.
  Job job(PETSC_COMM_WORLD, kBlock, 8, "-gmg_levels 3");
  set_rotations(job);
  auto& C = job.model.cells;
  for (std::size_t e = 0; e < C.lambda.size(); e += 3) C.kind[e] = -1;  // every third cell
  const auto& D = job.model.layout;
  std::vector<double> mask(3 * std::size_t(D.num_local()), 1.0);
  for (std::size_t k = 0; k < mask.size(); k += 7) mask[k] = 0.0;
  const std::size_t n = 3 * std::size_t(D.num_local());
  std::vector<double> x(n), yd(n, 0.0);
  std::vector<float> xs(n), ys(n, 0.0f);
  for (std::size_t i = 0; i < n; ++i)
    x[i] = double(xs[i] = float(std::sin(0.37 * double(i)) + 0.1));
  for (const assembly::OperatorWeights& w :
       {assembly::OperatorWeights{1.0, 0.0, true}, assembly::OperatorWeights{1.7, 40.0, true},
        assembly::OperatorWeights{1e-3, 25.0, false}}) {
    assembly::FineCells op(D, C, w, true);
    op.set_mask(mask);
    ASSERT_NE(op.data().reference_single, nullptr) << "no float copies: double arithmetic";
    std::fill(yd.begin(), yd.end(), 0.0);
    std::fill(ys.begin(), ys.end(), 0.0f);
    op.apply_add(x.data(), yd.data());
    op.apply_add(xs.data(), ys.data());
    std::vector<double> y(ys.begin(), ys.end());
    const auto d = max_difference(yd.data(), y.data(), n);
    // The same float vectors through the double-arithmetic body: float arithmetic rounds
    // differently, so the two differ (by less than float's accuracy).
    std::vector<float> yds(n, 0.0f);
    backend::for_each(std::int64_t(op.num_cells()),
                      backend::CellApplyAdd<assembly::FineCellOps, float>{
                          {op.data()}, op.corners(), xs.data(), yds.data()});
    std::vector<double> y2(yds.begin(), yds.end());
    const double arithmetic = max_difference(y2.data(), y.data(), n).relative();
    std::printf(
        "w_K %g, w_M %.0f, %s mass: max |y_float - y_double| / max |y_double| = %.1e "
        "(from double arithmetic on the same float vectors: %.1e)\n",
        w.stiffness, w.mass, w.lumped_mass ? "lumped" : "consistent", d.relative(), arithmetic);
    EXPECT_GT(d.magnitude, 0.0);
    EXPECT_LT(d.relative(), 1e-5);
    EXPECT_GT(arithmetic, 0.0) << "float vectors do not use float arithmetic";
  }
}

TEST(Multigrid, LinearRunsStoreNoRotationsAndTheCycleWorksInTheCallersVectors) {
  // A linear run keeps no per-cell rotations (72 bytes per cell) and its operators are
  // still those of R = I: the multigrid's fine operator equals the constrained assembled
  // matrix, and its coarse blocks stay P^T A P.
  const std::string linear = linear_block();
  const assembly::OperatorWeights w{1.0, 3.0, true};
  Job job(PETSC_COMM_WORLD, linear, 8, "-gmg_levels 3");
  auto& C = job.model.cells;
  assembly::set_identity_rotations(C);
  EXPECT_TRUE(C.identity_rotations);
  EXPECT_TRUE(C.rotation.empty());
  auto* mg = job.sim->multigrid();
  check_petsc(mg->update(C, w, job.model.boundary.constraints.rows), "update");
  Mat A;
  check_petsc(assembly::create_matrix(PETSC_COMM_WORLD, job.model.copies, job.model.layout, &A),
              "create");
  HEXCUT_CALL(assembly::assemble_constrained_matrix(job.model.dm, job.model.layout, C, w,
                                                    job.model.boundary.constraints, A));
  Vec x, y, y_ref, b0, Mb, Mb2;
  MatCreateVecs(A, &x, &y);
  for (Vec* v : {&y_ref, &b0, &Mb, &Mb2}) VecDuplicate(x, v);
  fill(x, 0.4);
  MatMult(A, x, y_ref);
  check_petsc(mg->apply_fine(x, y), "apply_fine");
  EXPECT_LT(rel_diff(y_ref, y), 1e-13) << "fine operator with R = I";
  EXPECT_LT(galerkin_mismatch(mg, A), 1e-12);
  // A rotation-only update with nothing stored rebuilds nothing.
  check_petsc(mg->update(C, w, job.model.boundary.constraints.rows), "update");
  EXPECT_EQ(mg->rebuilt_cells(1), 0);
  // The cycle runs in the caller's arrays: b is left as it was, and two cycles of the same
  // b give the same x bit for bit (nothing of the first stays in the second).
  VecCopy(x, b0);
  VecSet(Mb, 1e300);  // x is overwritten, whatever it held
  check_petsc(mg->cycle(x, Mb), "cycle");
  check_petsc(mg->cycle(x, Mb2), "cycle");
  EXPECT_EQ(rel_diff(b0, x), 0.0) << "b untouched";
  EXPECT_EQ(rel_diff(Mb, Mb2), 0.0);
  PetscScalar c;
  VecDot(x, Mb, &c);
  EXPECT_GT(c, 0.0);
  for (Vec* v : {&x, &y, &y_ref, &b0, &Mb, &Mb2}) VecDestroy(v);
  MatDestroy(&A);
}

TEST(Multigrid, AnIndefinitePreconditionerIsNamedAndSinglePrecisionIsBlamedOnlyWhenSet) {
  // CG stops with DIVERGED_INDEFINITE_PC when <r, M^-1 r> < 0; the message says what that
  // means, and with -gmg_precision single (which can make a coarse level indefinite on a
  // large slender body; doc/theory.md, "Mixed precision") that double is the remedy. Here
  // the operator and the multigrid are built from negated moduli: M^-1 is negative definite.
  const std::string linear = linear_block();
  for (const char* precision : {"double", "single"}) {
    const std::string options = std::string("-gmg_levels 3 -gmg_precision ") + precision;
    Job job(PETSC_COMM_WORLD, linear, 8, options.c_str());
    auto& C = job.model.cells;
    assembly::set_identity_rotations(C);
    for (std::size_t e = 0; e < C.lambda.size(); ++e) C.lambda[e] *= -1.0, C.mu[e] *= -1.0;
    for (auto& K : C.kind_stiffness)
      for (double& k : K) k = -k;
    auto* mg = job.sim->multigrid();
    check_petsc(mg->update(C, {1.0, 0.0, true}, job.model.boundary.constraints.rows), "update");
    KSP ksp = job.sim->ksp();
    KSPSetOperators(ksp, mg->fine_operator(), mg->fine_operator());
    Vec b, x;
    MatCreateVecs(mg->fine_operator(), &x, &b);
    fill(b, 0.2);
    VecSet(x, 0.0);
    solve::SolveRecord record;
    PetscPushErrorHandler(PetscReturnErrorHandler, nullptr);
    const PetscErrorCode ierr = solve::solve(ksp, b, x, &record);
    PetscPopErrorHandler();
    EXPECT_EQ(ierr, PETSC_ERR_NOT_CONVERGED) << precision;
    EXPECT_EQ(record.reason, KSP_DIVERGED_INDEFINITE_PC) << precision;
    char* message = nullptr;
    PetscErrorMessage(ierr, nullptr, &message);
    const std::string m = message ? message : "";
    EXPECT_NE(m.find("DIVERGED_INDEFINITE_PC"), std::string::npos) << m;
    EXPECT_NE(m.find("not positive definite"), std::string::npos) << m;
    EXPECT_EQ(m.find("-gmg_precision double") != std::string::npos,
              std::string(precision) == "single")
        << m;
    VecDestroy(&b);
    VecDestroy(&x);
  }
}

}  // namespace
}  // namespace hexcut::testing
