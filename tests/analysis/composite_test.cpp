// Composite elements (doc/theory.md, "Composite elements") against independent references:
// level 0 is the fine model; the composite stiffness and mass are MatPtAP of the assembled
// fine matrices with the composite interpolation (fixed columns removed); the composite mass
// weighs the body; affine fields are interpolated exactly, through cuts; uniaxial tension on
// roller supports is reproduced exactly (its solution is affine, so it lies in every
// composite space); with the level fixed, refining h converges to a manufactured solution
// (analysis_manufactured_test); energy balance (analysis_energy_test); a cut bar
// (cut_test); 1 rank = 2 ranks (analysis_mpi_test); the mid-point force computed on the
// composite level is I^T of the fine grouped one.
#include "analysis/composite.hpp"

#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <map>

#include "analysis/composite_midpoint.hpp"
#include "assembly/boundary.hpp"
#include "element/kinematics.hpp"
#include "fixture.hpp"

namespace hexcut::testing {
namespace {

/// A block with a spherical hole and a stiffer part, clamped at x = 0 and on rollers
/// (y) at x = 1.2, loaded at x = 1.2, and cut from the top to half depth at x = 0.5.
std::string holed_block(const std::string& analysis, bool supports = true, bool cut = true) {
  std::string s = holed_block_body();
  if (supports)
    s += "boundary:\n  fixed:\n    - where: {plane: {point: [0, 0, 0], normal: [1, 0, 0]}}\n"
         "    - where: {plane: {point: [1.2, 0, 0], normal: [1, 0, 0]}}\n      components: [y]\n"
         "  traction:\n    - where: {plane: {point: [1.2, 0, 0], normal: [1, 0, 0]}}\n"
         "      value: [0, 0, -10.0]\n";
  if (cut)
    s += "cuts:\n  - blade: {polygon: [[0.5, -1, 0.4], [0.5, 2, 0.4], [0.5, 2, 2], [0.5, -1, 2]]}\n"
         "    time: 0\n";
  return s + "analysis: " + analysis + "\n";
}

/// The composite interpolation as an AIJ matrix (analysis::composite_interpolation_matrix).
Mat composite_interpolation(const multigrid::Multigrid& mg) {
  Mat I;
  HEXCUT_CALL(analysis::composite_interpolation_matrix(mg, &I));
  return I;
}

/// ||A - B||_F / ||A||_F.
double matrix_difference(Mat A, Mat B) {
  Mat D;
  MatDuplicate(A, MAT_COPY_VALUES, &D);
  MatAXPY(D, -1.0, B, DIFFERENT_NONZERO_PATTERN);
  PetscReal nd, na;
  MatNorm(D, NORM_FROBENIUS, &nd);
  MatNorm(A, NORM_FROBENIUS, &na);
  MatDestroy(&D);
  return nd / na;
}

/// The composite matrix of `job` (solver direct: the assembled, unfactored composite
/// level) for weights w, against I_f^T A I_f + diag(fixed) from the assembled fine matrix.
double galerkin_difference(Job& job, const assembly::OperatorWeights& w) {
  auto* mg = job.sim->multigrid();
  const auto& rows = job.model.boundary.constraints.rows;
  HEXCUT_CALL(mg->update(job.model.cells, w, rows));
  Mat C = mg->coarsest_matrix();
  Mat A;
  HEXCUT_CALL(assembly::create_matrix(PETSC_COMM_WORLD, job.model.copies, job.model.layout, &A));
  HEXCUT_CALL(assembly::assemble_constrained_matrix(job.model.dm, job.model.layout, job.model.cells,
                                                    w, job.model.boundary.constraints, A));
  Mat I = composite_interpolation(*mg);
  Vec mc = mg->mask(mg->first_level()), fixed;
  VecDuplicate(mc, &fixed);
  VecSet(fixed, 1.0);
  VecAXPY(fixed, -1.0, mc);
  MatDiagonalScale(I, nullptr, mc);  // the fixed composite columns removed
  Mat R;
  MatPtAP(A, I, MAT_INITIAL_MATRIX, 2.0, &R);
  MatSetOption(R, MAT_NEW_NONZERO_ALLOCATION_ERR, PETSC_FALSE);
  MatDiagonalSet(R, fixed, ADD_VALUES);
  const double d = matrix_difference(C, R);
  for (Mat* m : {&A, &I, &R}) MatDestroy(m);
  VecDestroy(&fixed);
  return d;
}

/// Rotations of the job's local cells from the displacement u(x) of every local copy (x its
/// reference position), as a corotational step sets them (assembly::update_rotations);
/// returns that displacement (3 per local copy).
template <class Field>
std::vector<double> rotate_cells_by(Job& job, const Field& u_of_x) {
  const auto& D = job.model.layout;
  std::vector<double> a(3 * std::size_t(D.num_local()));
  for (std::int32_t i = 0; i < D.num_local(); ++i) {
    const Eigen::Vector3d u = u_of_x(job.position(D.copies[i]));
    for (int d = 0; d < 3; ++d) a[3 * i + d] = u[d];
  }
  assembly::update_rotations(D, a.data(), job.model.cells);
  return a;
}

/// Cell rotations of a twist about a tilted axis through the origin, growing along x
/// (angle * x rad): every composite element turns differently.
void twist_cells(Job& job, double angle) {
  rotate_cells_by(job, [angle](const Eigen::Vector3d& x) {
    const Eigen::Matrix3d R =
        Eigen::AngleAxisd(angle * x[0], Eigen::Vector3d(0.2, 1, 0.3).normalized())
            .toRotationMatrix();
    return Eigen::Vector3d(R * x - x);
  });
}

TEST(Composite, LevelZeroIsTheFineModel) {
  // The composite path (restriction, fixed values, lifting, prolongation) at level 0 is
  // the identity: the same displacement as the hexahedra to round-off, with the direct
  // solver, also for a prescribed non-zero displacement.
  for (const char* support : {"", "      value: [0.001, 0, -0.002]\n"}) {
    std::string deck = cantilever_deck(0.025, "{type: static}", "{type: direct}");
    const std::string clamp = "normal: [1, 0, 0]}}\n";
    deck.insert(deck.find(clamp) + clamp.size(), support);
    Job fine(PETSC_COMM_WORLD, deck);
    fine.run();
    Job level0(PETSC_COMM_WORLD, deck + "discretization: {type: composite, level: 0}\n");
    ASSERT_TRUE(level0.sim->composite());
    level0.run();
    const auto a = fine.canonical(fine.state.u), b = level0.canonical(level0.state.u);
    double d = 0, s = 0;
    for (std::size_t i = 0; i < a.size(); ++i) {
      d = std::max(d, std::abs(a[i] - b[i]));
      s = std::max(s, std::abs(a[i]));
    }
    EXPECT_LT(d, 1e-12 * s) << support;
  }
}

TEST(Composite, StiffnessAndMassAreTheGalerkinProductsOfTheFineMatrices) {
  // K~ = I_f^T K I_f and M~ = I_f^T M I_f (consistent and lumped fine mass; also with the
  // Newmark weights of a step) from PETSc's MatPtAP of the assembled fine matrices, on a
  // body with a hole, a material jump, a cut that ends inside it, a clamp and a roller.
  for (int level : {1, 2}) {
    const std::string deck =
        holed_block("{type: dynamic, dt: 0.01, steps: 1}") + "solver: {type: direct}\n" +
        "discretization: {type: composite, level: " + std::to_string(level) + "}\n";
    Job job(PETSC_COMM_WORLD, deck);
    ASSERT_GT(job.cut_all(), 0);
    for (const assembly::OperatorWeights& w :
         {assembly::OperatorWeights{1.0, 0.0, true}, assembly::OperatorWeights{0.0, 1.0, false},
          assembly::OperatorWeights{0.0, 1.0, true}, assembly::OperatorWeights{1.2, 400.0, true}}) {
      const double d = galerkin_difference(job, w);
      std::printf("level %d, weights (%g, %g, %s): |C - I^T A I| / |C| = %.2e\n", level,
                  w.stiffness, w.mass, w.lumped_mass ? "lumped" : "consistent", d);
      EXPECT_LT(d, 1e-12);
    }
  }
}

TEST(Composite, MassWeighsTheBody) {
  // A translation t on every composite copy interpolates to t on every fine copy, so
  // t^T M~ t = m |t|^2 with m the body's mass (sum of rho h^3 over its cells).
  for (int level : {1, 2, 3}) {
    const std::string deck = holed_block("{type: dynamic, dt: 0.01, steps: 1}", false, false) +
                             "solver: {type: direct}\ndiscretization: {type: composite, level: " +
                             std::to_string(level) + "}\n";
    Job job(PETSC_COMM_WORLD, deck);
    double mass = 0;
    const auto& L = job.model.lattice;
    for (std::int32_t c = 0; c < L.num_cells(); ++c)
      mass += job.deck.materials[L.material[c]].density * std::pow(L.spec.h, 3);
    for (bool lumped : {false, true}) {
      auto* mg = job.sim->multigrid();
      HEXCUT_CALL(mg->update(job.model.cells, {0.0, 1.0, lumped}, {}));
      Mat C = mg->coarsest_matrix();
      Vec t, Ct;
      MatCreateVecs(C, &t, &Ct);
      for (int d = 0; d < 3; ++d) {
        PetscInt lo, hi;
        VecGetOwnershipRange(t, &lo, &hi);
        PetscScalar* a;
        VecGetArray(t, &a);
        for (PetscInt i = lo; i < hi; ++i) a[i - lo] = i % 3 == d ? 1.0 : 0.0;
        VecRestoreArray(t, &a);
        MatMult(C, t, Ct);
        PetscScalar m;
        VecDot(t, Ct, &m);
        EXPECT_NEAR(m, mass, 1e-12 * mass) << "level " << level << " component " << d;
      }
      VecDestroy(&t);
      VecDestroy(&Ct);
    }
  }
}

TEST(Composite, AffineFieldsAreInterpolatedExactlyThroughCuts) {
  // Each piece's composite copies carry the affine field at their positions; I gives it
  // back at every fine copy, on both sides of the cut and around the hole.
  for (int level : {1, 2, 3}) {
    const std::string deck = holed_block("{type: static}") + "solver: {type: direct}\n" +
                             "discretization: {type: composite, level: " + std::to_string(level) +
                             "}\n";
    Job job(PETSC_COMM_WORLD, deck);
    ASSERT_GT(job.cut_all(), 0);
    auto* mg = job.sim->multigrid();
    const Eigen::Matrix3d G =
        (Eigen::Matrix3d() << 0.1, -0.3, 0.2, 0.05, 0.4, -0.1, 0.3, 0.0, -0.2).finished();
    const Eigen::Vector3d c(0.01, -0.02, 0.03);
    auto affine = [&](Vec positions, Vec out) {
      PetscInt n;
      VecGetLocalSize(positions, &n);
      const PetscScalar* x;
      PetscScalar* u;
      VecGetArrayRead(positions, &x);
      VecGetArray(out, &u);
      for (PetscInt i = 0; i < n / 3; ++i) {
        const Eigen::Vector3d v = G * Eigen::Vector3d(x[3 * i], x[3 * i + 1], x[3 * i + 2]) + c;
        for (int d = 0; d < 3; ++d) u[3 * i + d] = v[d];
      }
      VecRestoreArray(out, &u);
      VecRestoreArrayRead(positions, &x);
    };
    Vec xc, uc, u, exact;
    HEXCUT_CALL(analysis::composite_positions(*mg, &xc));
    VecDuplicate(xc, &uc);
    affine(xc, uc);
    DMCreateGlobalVector(job.model.dm, &u);
    VecDuplicate(u, &exact);
    HEXCUT_CALL(analysis::prolong_composite(*mg, uc, u));
    affine(job.model.coordinates, exact);
    EXPECT_LT(rel_max_difference(exact, u), 1e-14) << "level " << level;
    for (Vec* v : {&xc, &uc, &u, &exact}) VecDestroy(v);
  }
}

TEST(Composite, UniaxialTensionOnRollersIsExact) {
  // sigma_xx = s on x = L, rollers on x = 0, y = 0, z = 0: u = (s/E) (x, -nu y, -nu z),
  // affine, so every composite level reproduces it; through the composite loads (the
  // traction restricted), the fixation propagation and the Galerkin stiffness.
  const double E = 1000.0, nu = 0.3, s = 5.0;
  const std::string base =
      "lattice: {h: 0.05, dims: [16, 8, 8]}\n"
      "materials: {m: {E: 1000.0, nu: 0.3, rho: 1.0}}\n"
      "geometry: [{add: {box: {min: [0, 0, 0], max: [0.8, 0.4, 0.4]}}}]\n"
      "boundary:\n  fixed:\n"
      "    - {where: {plane: {point: [0, 0, 0], normal: [1, 0, 0]}}, components: [x]}\n"
      "    - {where: {plane: {point: [0, 0, 0], normal: [0, 1, 0]}}, components: [y]}\n"
      "    - {where: {plane: {point: [0, 0, 0], normal: [0, 0, 1]}}, components: [z]}\n"
      "  traction:\n    - {where: {plane: {point: [0.8, 0, 0], normal: [1, 0, 0]}}, value: [5.0, "
      "0, 0]}\n"
      "analysis: {type: static}\n";
  for (const char* solver : {"{type: direct}", "{type: gmg, rtol: 1.0e-12}"})
    for (int level : {1, 2, 3}) {
      Job job(PETSC_COMM_WORLD,
              base + "solver: " + solver +
                  "\ndiscretization: {type: composite, level: " + std::to_string(level) + "}\n");
      job.run();
      Vec exact;
      VecDuplicate(job.state.u, &exact);
      PetscInt n;
      VecGetLocalSize(exact, &n);
      const PetscScalar* x;
      PetscScalar* u;
      VecGetArrayRead(job.model.coordinates, &x);
      VecGetArray(exact, &u);
      for (PetscInt i = 0; i < n / 3; ++i) {
        u[3 * i] = s / E * x[3 * i];
        u[3 * i + 1] = -nu * s / E * x[3 * i + 1];
        u[3 * i + 2] = -nu * s / E * x[3 * i + 2];
      }
      VecRestoreArray(exact, &u);
      VecRestoreArrayRead(job.model.coordinates, &x);
      const double d = rel_max_difference(exact, job.state.u);
      std::printf("%s, level %d: max |u - u_exact| / max |u_exact| = %.2e\n", solver, level, d);
      EXPECT_LT(d, 1e-9) << solver << " level " << level;
      VecDestroy(&exact);
    }
}

/// ||I x~ - x||_inf / ||x||_inf for the least-squares x~ (analysis::CompositePreimage): 0
/// when the fine vector x lies in the composite space.
double distance_from_composite_space(multigrid::Multigrid& mg, Vec x) {
  analysis::CompositePreimage preimage(mg);
  Vec xc;
  HEXCUT_CALL(DMCreateGlobalVector(mg.dm(mg.first_level()), &xc));
  double misfit = 0.0;
  HEXCUT_CALL(preimage.solve(x, xc, &misfit));
  VecDestroy(&xc);
  PetscReal n = 0;
  VecNorm(x, NORM_INFINITY, &n);
  return n > 0 ? misfit / n : misfit;
}

TEST(Composite, StateStaysInTheCompositeSpaceThroughALateCut) {
  // The state lives on the fine copies as u = I u~. A cut splits fine copies (with their
  // state) and composite elements into pieces, each inside an old element, so the old field
  // is still I_new u~_new with every new composite copy taking its old copy's value (Wu's
  // rule; analysis/composite.hpp): u, v and a stay in the new composite space.
  const std::string deck =
      "lattice: {h: 0.025, dims: [40, 4, 4]}\n"
      "materials: {m: {E: 2.0e5, nu: 0.3, rho: 1000}}\n"
      "geometry: [{add: {box: {min: [0, 0, 0], max: [1.0, 0.1, 0.1]}}}]\n"
      "boundary:\n  fixed: [{where: {plane: {point: [0, 0, 0], normal: [1, 0, 0]}}}]\n"
      "  gravity: [0, 0, -9.81]\n"
      "cuts:\n  - blade: {polygon: [[0.335, -1, 0.05], [0.335, 2, 0.05], [0.335, 2, 2], [0.335, "
      "-1, "
      "2]]}\n    time: 0.01\n"
      "analysis: {type: dynamic, dt: 0.002, steps: 10}\n"
      "solver: {type: gmg, rtol: 1.0e-12}\n"
      "discretization: {type: composite, level: 2}\n";
  Job job(PETSC_COMM_WORLD, deck);
  double worst = 0.0;
  int checked = 0;
  analysis::DriverHooks hooks;
  hooks.on_step = [&](const analysis::State& s) {
    if (s.time < 0.011) return;
    for (Vec v : {s.u, s.v, s.a})
      worst = std::max(worst, distance_from_composite_space(*job.sim->multigrid(), v));
    ++checked;
  };
  analysis::Driver driver(PETSC_COMM_WORLD, job.deck, job.model, job.state, job.sim, hooks);
  HEXCUT_CALL(driver.begin());
  HEXCUT_CALL(driver.run());
  std::printf("after the cut (%d steps): largest distance of u, v, a from range(I): %.2e\n",
              checked, worst);
  EXPECT_GE(checked, 4);
  EXPECT_FALSE(job.model.lattice.cut_links.empty());
  EXPECT_LT(worst, 1e-10);
}

TEST(Composite, FineCellsShareTheirElementsRotation) {
  // Corotational composite runs: the rotation of every fine cell is that of its composite
  // element, the polar factor of the mean centre deformation gradient of the element's fine
  // cells (Wu 2014, eq. 4.7), here for a bending-and-twisting field of large rotations.
  for (int level : {1, 2}) {
    Job job(PETSC_COMM_WORLD,
            cantilever_deck(0.025, "{type: static, formulation: corotational}", "{type: direct}") +
                "discretization: {type: composite, level: " + std::to_string(level) + "}\n");
    const auto& D = job.model.layout;
    auto& cells = job.model.cells;
    ASSERT_EQ(cells.rotation_group.size(), D.cells.size());
    const auto a = rotate_cells_by(job, [](const Eigen::Vector3d& x) {
      const Eigen::Matrix3d R =
          Eigen::AngleAxisd(1.2 * x[0], Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(0.8 * x[0], Eigen::Vector3d::UnitX()).toRotationMatrix();
      return Eigen::Vector3d(R * x - x + Eigen::Vector3d(0.01 * x[1], 0, 0.02 * x[2]));
    });
    // Independently: sum F per element, polar factor by Eigen's SVD (U V^T).
    std::map<std::int32_t, Eigen::Matrix3d> sum;
    for (std::size_t e = 0; e < D.cells.size(); ++e) {
      double u24[24], F[9];
      element::gather_cell(a.data(), D.cell_corners[e].data(), u24);
      element::deformation_gradient_at_centre(u24, cells.h, F);
      Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>> Fm(F);
      auto it = sum.emplace(cells.rotation_group[e], Eigen::Matrix3d::Zero()).first;
      it->second += Fm;
    }
    double worst = 0;
    for (std::size_t e = 0; e < D.cells.size(); ++e) {
      Eigen::JacobiSVD<Eigen::Matrix3d> svd(sum[cells.rotation_group[e]],
                                            Eigen::ComputeFullU | Eigen::ComputeFullV);
      const Eigen::Matrix3d Rg = svd.matrixU() * svd.matrixV().transpose();
      Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>> Re(&cells.rotation[9 * e]);
      worst = std::max(worst, (Re - Rg).norm());
    }
    EXPECT_EQ(sum.size(), job.sim->multigrid()->level(level).layout().cells.size());
    EXPECT_LT(worst, 1e-10) << "level " << level;
  }
}

TEST(Composite, RotatedBlocksAreTheGalerkinProductsOfTheRotatedFineCells) {
  // After a full build at one set of element rotations, a rotation-only update rotates the
  // stored composite blocks by each element's change of rotation (multigrid::Options::
  // rotate_composite) without touching a fine cell; the result must be the Galerkin
  // product of the fine matrix assembled with the new rotations (fine cells of an element
  // share its rotation), with the Newmark weights (the mass is rotation-invariant).
  for (int level : {1, 2}) {
    std::string deck = holed_block(
                           "{type: dynamic, formulation: corotational, dt: 0.01, "
                           "steps: 1}",
                           true, false) +
                       "solver: {type: direct}\ndiscretization: {type: composite, level: " +
                       std::to_string(level) + "}\n";
    // A clamp only (all components): a roller fixes some components of a vertex, which
    // rotation does not commute with (such runs rebuild by Galerkin products).
    deck.replace(deck.find("      components: [y]\n"), 22, "");
    Job job(PETSC_COMM_WORLD, deck);
    const assembly::OperatorWeights w{1.3, 250.0, true};
    twist_cells(job, 0.4);
    EXPECT_LT(galerkin_difference(job, w), 1e-12);
    twist_cells(job, 1.1);
    double d = galerkin_difference(job, w);
    twist_cells(job, 1.7);  // a second rotation-only update, from the rotated blocks
    d = std::max(d, galerkin_difference(job, w));
    auto* mg = job.sim->multigrid();
    std::printf("level %d: rotated blocks vs Galerkin of the rotated fine cells: %.2e\n", level, d);
    EXPECT_EQ(mg->rebuilt_cells(0), 0);  // no fine cell was visited
    EXPECT_EQ(mg->rebuilt_cells(level), std::int64_t(mg->level(level).layout().cells.size()));
    EXPECT_LT(d, 1e-12);
  }
}

/// Per local composite element of `job`: the canonical ids of its fine cells, in order.
std::vector<std::vector<std::int32_t>> element_cell_sets(Job& job) {
  const auto& mg = *job.sim->multigrid();
  std::vector<std::vector<std::int32_t>> sets(mg.level(mg.first_level()).layout().cells.size());
  const auto& element = mg.composite_elements();
  for (std::size_t e = 0; e < element.size(); ++e)
    sets[std::size_t(element[e])].push_back(job.model.layout.cells[e]);
  for (auto& s : sets) std::sort(s.begin(), s.end());
  return sets;
}

TEST(Composite, CutsRebuildOnlyTheElementsTheyChange) {
  // After a cut, an element whose fine cells are those of an element before it keeps its
  // block (rotated by its change of rotation) and its mid-point data (Simulation::
  // composite_carry): the elements re-assembled are exactly those whose fine-cell set is
  // new (counted here from the fine cells, as sets), the composite matrix is still the
  // Galerkin product of the cut fine matrix at the new rotations, and the mid-point data
  // equal a build from scratch. With -hexcut_composite_carry false every element is built.
  // With a roller support (blocks that cannot be rotated) a kept block must be at the same
  // rotation, and the next rotation update rebuilds its whole Galerkin chain.
  enum Mode { carry, no_carry, roller };
  for (int level : {1, 2})
    for (Mode mode : {carry, no_carry, roller}) {
      std::string deck =
          holed_block("{type: dynamic, formulation: corotational, dt: 0.01, steps: 1}") +
          "solver: {type: direct}\ndiscretization: {type: composite, level: " +
          std::to_string(level) + "}\n";
      if (mode != roller) deck.replace(deck.find("      components: [y]\n"), 22, "");
      Job job(PETSC_COMM_WORLD, deck);
      const assembly::OperatorWeights w{1.3, 250.0, true};
      twist_cells(job, 0.4);
      EXPECT_LT(galerkin_difference(job, w), 1e-12);
      const auto before = element_cell_sets(job);
      analysis::CompositeCarry kept = job.sim->composite_carry();
      const auto old_elements =
          analysis::build_composite_elements(*job.sim->multigrid(), job.model.cells);
      if (mode == no_carry) PetscOptionsSetValue(nullptr, "-hexcut_composite_carry", "false");
      ASSERT_GT(job.cut_all(&kept), 0);
      PetscOptionsClearValue(nullptr, "-hexcut_composite_carry");
      auto* mg = job.sim->multigrid();
      const auto after = element_cell_sets(job);
      std::int64_t changed = 0;
      for (const auto& s : after)
        changed += std::find(before.begin(), before.end(), s) == before.end();
      const auto total = std::int64_t(after.size());
      // The elements turned since their blocks were built (roller: not yet).
      twist_cells(job, mode == roller ? 0.4 : 1.1);
      double d = galerkin_difference(job, w);
      const auto rebuilt = mg->rebuilt_cells(level), carried = mg->carried_cells();
      if (mode == roller) {
        twist_cells(job, 1.1);  // a rotation update: Galerkin products, the kept chains included
        d = std::max(d, galerkin_difference(job, w));
      }
      const auto E = analysis::build_composite_elements(*mg, job.model.cells, &old_elements);
      const auto fresh = analysis::build_composite_elements(*mg, job.model.cells);
      double worst = 0.0, size = 0.0;
      for (auto [a, b] : {std::pair{&E.stiffness, &fresh.stiffness},
                          {&E.gram, &fresh.gram},
                          {&E.gradient, &fresh.gradient},
                          {&E.mu_sum, &fresh.mu_sum}}) {
        ASSERT_EQ(a->size(), b->size());
        for (std::size_t k = 0; k < a->size(); ++k) {
          worst = std::max(worst, std::abs((*a)[k] - (*b)[k]));
          size = std::max(size, std::abs((*b)[k]));
        }
      }
      std::printf(
          "level %d, %s: %lld of %lld elements changed by the cut; re-assembled %lld, carried "
          "%lld (mid-point data %lld); Galerkin difference %.1e, data difference %.1e\n",
          level,
          mode == carry      ? "carry"
          : mode == no_carry ? "no carry"
                             : "roller",
          (long long)changed, (long long)total, (long long)rebuilt, (long long)carried,
          (long long)E.carried, d, worst / size);
      EXPECT_GT(changed, 0);
      EXPECT_LT(changed, total);
      EXPECT_EQ(rebuilt, mode == no_carry ? total : changed);
      EXPECT_EQ(carried, mode == no_carry ? 0 : total - changed);
      EXPECT_EQ(E.carried, total - changed);
      EXPECT_LT(d, 1e-12);
      EXPECT_LT(worst, 1e-13 * size);
    }
}

TEST(Composite, KeptElementsGiveTheSameRun) {
  // A whole corotational dynamic run with a cut between steps (the driver's path:
  // Driver::follow_topology carries the elements over) gives the same displacement as the
  // run that rebuilds every element after the cut, to the solver's tolerance.
  // (Clamped only: with a roller, a block is kept only at an unchanged rotation.)
  std::string deck =
      holed_block("{type: dynamic, formulation: corotational, dt: 0.01, steps: 4}") +
      "solver: {type: gmg, rtol: 1.0e-11}\ndiscretization: {type: composite, level: 1}\n";
  deck.replace(deck.find("    time: 0\n"), 11, "    time: 0.015\n");
  const std::string roller =
      "    - where: {plane: {point: [1.2, 0, 0], normal: [1, 0, 0]}}\n      components: [y]\n";
  deck.replace(deck.find(roller), roller.size(), "");  // a cantilever: rotatable blocks
  std::vector<double> u[2];
  for (int reuse : {1, 0}) {
    Job job(PETSC_COMM_WORLD, deck, 8, reuse ? nullptr : "-hexcut_composite_carry false");
    std::int64_t carried = 0;
    analysis::DriverHooks hooks;
    hooks.on_step = [&](const analysis::State&) {
      carried += job.sim->multigrid()->carried_cells();
    };
    job.run(hooks);
    EXPECT_EQ(carried > 0, reuse == 1);
    EXPECT_FALSE(job.model.lattice.cut_links.empty());
    u[reuse] = job.canonical(job.state.u);
  }
  ASSERT_EQ(u[0].size(), u[1].size());
  const auto d = max_difference(u[0].data(), u[1].data(), u[0].size());
  std::printf("kept elements vs all rebuilt: max |du| / max |u| = %.1e (max |u| %.3g m)\n",
              d.relative(), d.magnitude);
  EXPECT_GT(d.magnitude, 0.0);
  EXPECT_LT(d.relative(), 1e-8);
}

/// Momentum of the composite system, sum over composite DOFs of M~ v~ (M~ = I^T M I, the
/// consistent mass) per direction, for the composite velocity v~ [kg m/s].
Eigen::Vector3d composite_momentum(Job& job, Vec vc) {
  auto& mg = *job.sim->multigrid();
  Vec v, Mv, r;
  HEXCUT_CALL(DMCreateGlobalVector(job.model.dm, &v));
  VecDuplicate(v, &Mv);
  VecDuplicate(vc, &r);
  HEXCUT_CALL(analysis::prolong_composite(mg, vc, v));
  HEXCUT_CALL(
      assembly::apply(job.model.dm, job.model.layout, job.model.cells, {0.0, 1.0, false}, v, Mv));
  HEXCUT_CALL(analysis::restrict_composite(mg, Mv, r));
  Eigen::Vector3d p;
  for (int d = 0; d < 3; ++d) VecStrideSum(r, d, &p[d]);
  for (Vec* x : {&v, &Mv, &r}) VecDestroy(x);
  return p;
}

TEST(Composite, CutsKeepTheCompositeMomentum) {
  // A cut splits composite copies; each new copy takes the value of the copy it split from
  // (the fine state is unchanged and the composite one is its preimage), so the composite
  // momentum sum(I^T M I v~) is the same before and after the cut, for a spinning and
  // translating body on a free, holed, two-material block.
  for (int level : {1, 2}) {
    Job job(PETSC_COMM_WORLD, holed_block("{type: dynamic, dt: 0.01, steps: 1}", false) +
                                  "solver: {type: direct}\ndiscretization: {type: composite, "
                                  "level: " +
                                  std::to_string(level) + "}\n");
    auto& mg0 = *job.sim->multigrid();
    Vec x, vc;
    HEXCUT_CALL(analysis::composite_positions(mg0, &x));
    VecDuplicate(x, &vc);
    PetscInt n;
    VecGetLocalSize(x, &n);
    const PetscScalar* xa;
    PetscScalar* va;
    VecGetArrayRead(x, &xa);
    VecGetArray(vc, &va);
    for (PetscInt i = 0; i < n; i += 3) {  // v = w x (x - c) + v0 + a non-rigid part
      const Eigen::Vector3d p(xa[i], xa[i + 1], xa[i + 2]);
      const Eigen::Vector3d v = Eigen::Vector3d(0.3, -1.0, 2.0).cross(p) +
                                Eigen::Vector3d(0.5, 0.1, -0.2) +
                                Eigen::Vector3d(0.2 * p[1] * p[2], 0, std::sin(3 * p[0]));
      for (int d = 0; d < 3; ++d) va[i + d] = v[d];
    }
    VecRestoreArray(vc, &va);
    VecRestoreArrayRead(x, &xa);
    const Eigen::Vector3d before = composite_momentum(job, vc);
    HEXCUT_CALL(analysis::prolong_composite(mg0, vc, job.state.v));
    for (Vec* v : {&x, &vc}) VecDestroy(v);
    const auto copies = job.sim->multigrid()->level(level).layout().num_owned;
    ASSERT_GT(job.cut_all(), 0);
    auto& mg = *job.sim->multigrid();
    HEXCUT_CALL(DMCreateGlobalVector(mg.dm(level), &vc));
    analysis::CompositePreimage preimage(mg);
    double misfit = 1.0;
    HEXCUT_CALL(preimage.solve(job.state.v, vc, &misfit));
    const Eigen::Vector3d after = composite_momentum(job, vc);
    VecDestroy(&vc);
    std::printf(
        "level %d: composite copies %d -> %d; momentum before [%.15g %.15g %.15g], after "
        "[%.15g %.15g %.15g]; preimage misfit %.1e\n",
        level, int(copies), int(mg.level(level).layout().num_owned), before.x(), before.y(),
        before.z(), after.x(), after.y(), after.z(), misfit);
    EXPECT_GT(mg.level(level).layout().num_owned, copies);
    EXPECT_LT(misfit, 1e-12);
    EXPECT_LT((after - before).norm(), 1e-12 * before.norm());
  }
}

TEST(Composite, MidpointForceOnTheCompositeLevelIsTheRestrictedFineForce) {
  // For u0 = I u0~ and u1 = I u1~, the mid-point force from the composite elements' own data
  // (analysis/composite_midpoint.hpp) equals I^T of the fine force with the elements as
  // rotation groups (assembly::assemble_midpoint_force: fine cells, per-group rotations and
  // moment removal over all corners of a group), with the same strain energies and
  // rotations; on a holed, cut, two-material body whose elements are partly filled, under
  // large rotations (a bend and a twist of up to 1.4 rad).
  for (int level : {1, 2}) {
    const std::string deck = holed_block(
                                 "{type: dynamic, formulation: corotational, dt: 0.01, "
                                 "steps: 1}") +
                             "solver: {type: direct}\n" +
                             "discretization: {type: composite, level: " + std::to_string(level) +
                             "}\n";
    Job job(PETSC_COMM_WORLD, deck);
    ASSERT_GT(job.cut_all(), 0);
    auto& mg = *job.sim->multigrid();
    DM dc = mg.dm(level);
    Vec x, u0c, u1c, fc, fref, u0, u1, f;
    HEXCUT_CALL(analysis::composite_positions(mg, &x));
    for (Vec* v : {&u0c, &u1c, &fc, &fref}) HEXCUT_CALL(DMCreateGlobalVector(dc, v));
    for (Vec* v : {&u0, &u1, &f}) HEXCUT_CALL(DMCreateGlobalVector(job.model.dm, v));
    PetscInt n;
    VecGetLocalSize(x, &n);
    const PetscScalar* xa;
    PetscScalar *a0, *a1;
    VecGetArrayRead(x, &xa);
    VecGetArray(u0c, &a0);
    VecGetArray(u1c, &a1);
    for (PetscInt i = 0; i < n; i += 3) {
      const Eigen::Vector3d p(xa[i], xa[i + 1], xa[i + 2]);
      const Eigen::Matrix3d R0 = Eigen::AngleAxisd(0.6 * p[0], Eigen::Vector3d::UnitY()).matrix();
      const Eigen::Matrix3d R1 = Eigen::AngleAxisd(1.1 * p[0], Eigen::Vector3d::UnitY()) *
                                 Eigen::AngleAxisd(0.5 * p[0], Eigen::Vector3d::UnitX()).matrix();
      const Eigen::Vector3d s(0.01 * std::sin(7 * p[1]), 0.02 * p[2] * p[0], -0.01 * p[1]);
      const Eigen::Vector3d v0 = R0 * p - p + s, v1 = R1 * p - p + 2 * s;
      for (int d = 0; d < 3; ++d) a0[i + d] = v0[d], a1[i + d] = v1[d];
    }
    VecRestoreArray(u1c, &a1);
    VecRestoreArray(u0c, &a0);
    VecRestoreArrayRead(x, &xa);
    HEXCUT_CALL(analysis::prolong_composite(mg, u0c, u0));
    HEXCUT_CALL(analysis::prolong_composite(mg, u1c, u1));
    // The fine grouped force, restricted.
    auto& cells = job.model.cells;
    ASSERT_FALSE(cells.rotation_group.empty());
    std::vector<double> d0;
    double e_fine[2], e_comp[2];
    HEXCUT_CALL(assembly::corotated_displacements(job.model.dm, job.model.layout, cells, u0, &d0));
    HEXCUT_CALL(assembly::assemble_midpoint_force(job.model.dm, job.model.layout, cells, d0, u0, u1,
                                                  f, e_fine));
    HEXCUT_CALL(analysis::restrict_composite(mg, f, fref));
    const std::vector<double> fine_rotations = cells.rotation;
    std::fill(cells.rotation.begin(), cells.rotation.end(), 0.0);
    const auto E = analysis::build_composite_elements(mg, cells);
    HEXCUT_CALL(analysis::composite_midpoint_force(mg, E, u0c, u1c, fc, cells, e_comp));
    PetscReal nref, nd;
    VecNorm(fref, NORM_2, &nref);
    VecAXPY(fc, -1.0, fref);
    VecNorm(fc, NORM_2, &nd);
    double rot = 0.0;
    for (std::size_t k = 0; k < fine_rotations.size(); ++k)
      rot = std::max(rot, std::abs(fine_rotations[k] - cells.rotation[k]));
    std::printf(
        "level %d: |f~ - I^T f| / |I^T f| = %.2e (|I^T f| = %.3g N), energies %.6g %.6g J "
        "(fine %.6g %.6g), rotations differ by %.1e\n",
        level, nd / nref, nref, e_comp[0], e_comp[1], e_fine[0], e_fine[1], rot);
    EXPECT_GT(nref, 0.0);
    EXPECT_LT(nd / nref, 1e-11);
    EXPECT_NEAR(e_comp[0], e_fine[0], 1e-11 * e_fine[0]);
    EXPECT_NEAR(e_comp[1], e_fine[1], 1e-11 * e_fine[1]);
    EXPECT_LT(rot, 1e-12);
    for (Vec* v : {&x, &u0c, &u1c, &fc, &fref, &u0, &u1, &f}) VecDestroy(v);
  }
}

TEST(Composite, PreimageRecoversTheCompositeValues) {
  // For x = I x~ (any x~), CompositePreimage returns x~ to round-off, on a holed, cut,
  // two-material body at levels 1, 2 and 3; a fine field outside range(I) is reported by
  // its misfit.
  for (int level : {1, 2, 3}) {
    const std::string deck =
        holed_block("{type: dynamic, dt: 0.01, steps: 1}") + "solver: {type: direct}\n" +
        "discretization: {type: composite, level: " + std::to_string(level) + "}\n";
    Job job(PETSC_COMM_WORLD, deck);
    ASSERT_GT(job.cut_all(), 0);
    auto& mg = *job.sim->multigrid();
    Vec xc, back, x;
    HEXCUT_CALL(DMCreateGlobalVector(mg.dm(level), &xc));
    HEXCUT_CALL(VecDuplicate(xc, &back));
    HEXCUT_CALL(DMCreateGlobalVector(job.model.dm, &x));
    PetscRandom rnd;
    PetscRandomCreate(PETSC_COMM_WORLD, &rnd);
    VecSetRandom(xc, rnd);
    HEXCUT_CALL(analysis::prolong_composite(mg, xc, x));
    analysis::CompositePreimage preimage(mg);
    double misfit = 1.0, rough = 0.0;
    HEXCUT_CALL(preimage.solve(x, back, &misfit));
    VecAXPY(back, -1.0, xc);
    PetscReal d, n;
    VecNorm(back, NORM_INFINITY, &d);
    VecNorm(xc, NORM_INFINITY, &n);
    VecSetRandom(x, rnd);  // a fine field that no composite one interpolates
    HEXCUT_CALL(preimage.solve(x, back, &rough));
    PetscRandomDestroy(&rnd);
    std::printf(
        "level %d: |x~ - preimage(I x~)| / |x~| = %.1e, misfit %.1e; random fine field: "
        "misfit %.2f\n",
        level, d / n, misfit, rough);
    EXPECT_LT(d / n, 1e-11);
    EXPECT_LT(misfit, 1e-12);
    EXPECT_GT(rough, 0.1);
    for (Vec* v : {&xc, &back, &x}) VecDestroy(v);
  }
}

TEST(Composite, FixationPropagationAndDeckErrors) {
  // The clamp of the cantilever's end face (5 x 5 fine vertices) stays that face at every
  // level; a support at one fine vertex inside composite element E fixes E's 8 corners
  // and so clamps all of E's fine vertices: (2^l + 1)^3 of them, less those on the face.
  const std::string base = cantilever_deck(0.025, "{type: static}", "{type: direct}");
  const std::string clamp = "normal: [1, 0, 0]}}\n";
  for (int level : {1, 2})
    for (bool point : {false, true}) {
      std::string deck = base;
      if (point)
        deck.insert(deck.find(clamp) + clamp.size(),
                    "    - where: {sphere: {centre: [0.025, 0.025, 0.025], radius: 0.001}}\n");
      Job job(PETSC_COMM_WORLD,
              deck + "discretization: {type: composite, level: " + std::to_string(level) + "}\n");
      job.run();
      PetscInt clamped = 0, prescribed = 0;
      HEXCUT_CALL(analysis::check_composite_supports(PETSC_COMM_WORLD, *job.sim->multigrid(),
                                                     job.deck, &clamped, &prescribed));
      const int side = (1 << level) + 1;
      EXPECT_EQ(prescribed, 3 * (25 + point));
      EXPECT_EQ(clamped, 3 * (25 + (point ? side * side * side - side * side : 0)))
          << "level " << level;
    }
  const std::string deck = base;
  EXPECT_THROW(deck::parse_deck(deck + "discretization: {type: composite}\n", "d.yaml"),
               InputError);
  EXPECT_THROW(deck::parse_deck(deck + "discretization: {type: composite, level: 4}\n", "d.yaml"),
               InputError);
  EXPECT_THROW(deck::parse_deck(deck + "discretization: {type: hexahedra, level: 1}\n", "d.yaml"),
               InputError);
}

}  // namespace
}  // namespace hexcut::testing
