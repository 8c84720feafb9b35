// Static checks against independent expectations: patch test, Timoshenko cantilever,
// vertex copies of edge-touching cells, and a rigid rotation in the corotational
// formulation.
#include <Eigen/Geometry>
#include <cmath>

#include "assembly/operator.hpp"
#include "element/element.hpp"
#include "element/stress.hpp"
#include "fixture.hpp"

namespace hexcut::testing {
namespace {

const char* kDirect = "{type: direct}";

// An affine displacement u = G x + c prescribed on the boundary of a body must be
// reproduced exactly inside: trilinear elements represent it, so the discrete
// solution is exact (the patch test).
TEST(Static, PatchTestReproducesAffineField) {
  // An L-shaped body, so the patch has re-entrant corners and several cell layers.
  const std::string yaml =
      "lattice: {h: 0.25, dims: [6, 5, 4]}\n"
      "materials: {m: {E: 1000.0, nu: 0.3, rho: 1}}\n"
      "geometry:\n  - add: {box: {min: [0, 0, 0], max: [1.5, 1.25, 1.0]}}\n"
      "  - subtract: {box: {min: [0.75, 0.75, -1], max: [2, 2, 2]}}\n"
      "boundary: {fixed: [{where: {all: true}}]}\n"
      "solver: {type: direct}\n";
  Job job(PETSC_COMM_WORLD, yaml);
  Eigen::Matrix3d G;
  G << 1e-3, 2e-3, -1e-3, 0.5e-3, -2e-3, 1.5e-3, 3e-3, 1e-3, 0.2e-3;
  const Eigen::Vector3d c(1e-3, -2e-3, 0.5e-3);
  auto affine = [&](const Eigen::Vector3d& x) {
    Eigen::Vector3d u = G * x + c;
    return u;
  };

  // Keep only vertices on the outer boundary: a copy is interior when all 8 cells
  // around its vertex exist.
  auto& cons = job.model.boundary.constraints;
  cons.rows.clear();
  cons.value.clear();
  cons.position.clear();
  std::vector<deck::Field> values;
  const auto& D = job.model.layout;
  const auto& L = job.model.lattice;
  std::vector<std::pair<PetscInt, double>> prescribed;
  for (std::int32_t i = 0; i < D.num_owned; ++i) {
    const auto v = D.copies[i];
    const auto& p = job.model.copies.vertex[v];
    int around = 0;
    for (int s = 0; s < 8; ++s)
      around += L.find(p[0] - 1 + (s & 1), p[1] - 1 + ((s >> 1) & 1), p[2] - 1 + (s >> 2)) >= 0;
    if (around == 8) continue;
    const auto u = affine(job.position(v));
    for (int d = 0; d < 3; ++d) prescribed.push_back({3 * (D.first_owned_block() + i) + d, u[d]});
  }
  values.resize(prescribed.size());
  for (std::size_t k = 0; k < prescribed.size(); ++k) {
    values[k].function.value = prescribed[k].second;
    cons.rows.push_back(prescribed[k].first);
    cons.position.push_back(Eigen::Vector3d::Zero());  // unused: the values are constants
  }
  for (auto& f : values) cons.value.push_back(&f);

  job.run();
  const auto u = job.canonical(job.state.u);
  double max_err = 0, max_u = 0;
  int interior = 0;
  for (std::int32_t v = 0; v < job.model.copies.num_copies; ++v) {
    const auto exact = affine(job.position(v));
    for (int d = 0; d < 3; ++d) {
      max_err = std::max(max_err, std::abs(u[3 * v + d] - exact[d]));
      max_u = std::max(max_u, std::abs(exact[d]));
    }
    const auto& p = job.model.copies.vertex[v];
    int around = 0;
    for (int s = 0; s < 8; ++s)
      around += L.find(p[0] - 1 + (s & 1), p[1] - 1 + ((s >> 1) & 1), p[2] - 1 + (s >> 2)) >= 0;
    interior += around == 8;
  }
  EXPECT_GT(interior, 10);
  EXPECT_LT(max_err / max_u, 1e-10);

  // The stress of an affine field is uniform: sigma = lambda tr(eps) I + 2 mu eps.
  analysis::CellStressFields f;
  check_petsc(analysis::compute_stress(job.model, false, job.state.u, &f), "stress");
  const double E = 1000.0, nu = 0.3, lambda = E * nu / ((1 + nu) * (1 - 2 * nu)),
               mu = E / (2 * (1 + nu));
  const Eigen::Matrix3d eps = 0.5 * (G + G.transpose());
  const Eigen::Matrix3d sigma = lambda * eps.trace() * Eigen::Matrix3d::Identity() + 2 * mu * eps;
  const double expected[6] = {sigma(0, 0), sigma(1, 1), sigma(2, 2),
                              sigma(0, 1), sigma(1, 2), sigma(0, 2)};
  for (std::size_t e = 0; e < f.energy_density.size(); ++e)
    for (int k = 0; k < 6; ++k) EXPECT_NEAR(f.sigma[6 * e + k], expected[k], 1e-10 * sigma.norm());
}

// Timoshenko beam: delta = P L^3/(3 E I) + P L/(kappa G A), kappa = 10(1+nu)/(12+11nu)
// for a rectangular section (Cowper). Q1 hexahedra are too stiff in bending on coarse
// grids; the tip deflection must approach the beam value from below as h -> 0.
TEST(Static, CantileverApproachesTimoshenko) {
  const double L = 1.0, b = 0.1, t = 0.1, P = 1000.0, E = 200e9, nu = 0.3;
  const double I = b * t * t * t / 12, A = b * t, G = E / (2 * (1 + nu));
  const double kappa = 10 * (1 + nu) / (12 + 11 * nu);
  const double delta = P * L * L * L / (3 * E * I) + P * L / (kappa * G * A);
  std::vector<double> errors;
  for (double h : {0.05, 0.025, 0.0125}) {
    Job job(PETSC_COMM_WORLD, cantilever_deck(h, "{type: static}", kDirect, L, b, t, P));
    job.run();
    const auto u = job.canonical(job.state.u);
    double sum = 0;
    int n = 0;
    for (std::int32_t v = 0; v < job.model.copies.num_copies; ++v)
      if (std::abs(job.position(v)[0] - L) < 1e-9) {
        sum += u[3 * v + 2];
        ++n;
      }
    const double tip = -sum / n;
    errors.push_back((delta - tip) / delta);
    if (errors.size() > 1) {
      EXPECT_LT(errors.back(), errors[errors.size() - 2])
          << "no convergence toward beam theory at h=" << h;
    }
  }
  EXPECT_GT(errors.back(), -0.01);
  EXPECT_LT(std::abs(errors.back()), 0.03)
      << "finest tip deflection off by " << 100 * errors.back() << "%";
}

// Two cubes that touch only along an edge must not share vertices: clamping one and
// pushing the other leaves the first exactly at rest.
TEST(Static, EdgeTouchingCubesMoveIndependently) {
  const std::string yaml =
      "lattice: {h: 0.5, dims: [4, 4, 2]}\n"
      "materials: {m: {E: 1000.0, nu: 0.3, rho: 1}}\n"
      "geometry:\n  - add: {box: {min: [0, 0, 0], max: [1, 1, 1]}}\n"
      "  - add: {box: {min: [1, 1, 0], max: [2, 2, 1]}}\n"
      "boundary:\n  fixed:\n    - where: {plane: {point: [0, 0, 0], normal: [1, 0, 0]}}\n"
      "    - where: {plane: {point: [2, 0, 0], normal: [1, 0, 0]}}\n"
      "  traction:\n    - where: {plane: {point: [0, 2, 0], normal: [0, 1, 0]}}\n"
      "      value: [0, 0, -10.0]\n"
      "solver: {type: direct}\n";
  Job job(PETSC_COMM_WORLD, yaml);
  // 2x2x2 cells per cube: 27 vertices each; the shared edge (x=1,y=1, 3 vertices) is duplicated.
  EXPECT_EQ(job.model.copies.num_copies, 54);
  job.run();
  const auto u = job.canonical(job.state.u);
  double first = 0, second = 0;
  for (std::int32_t v = 0; v < job.model.copies.num_copies; ++v) {
    const auto x = job.position(v);
    const bool in_second = job.model.copies.first_cell[v] >= 0 &&
                           job.model.lattice.ijk[job.model.copies.first_cell[v]][0] >= 2;
    const double m = Eigen::Vector3d(u[3 * v], u[3 * v + 1], u[3 * v + 2]).norm();
    (in_second ? second : first) = std::max(in_second ? second : first, m);
    (void)x;
  }
  EXPECT_GT(second, 1e-4);
  EXPECT_EQ(first, 0.0);
}

// Corotational formulation: a rigid rotation of the whole body by 90 degrees gives
// zero internal force (K^ u - b^ = 0) and zero stress; `extra`: more deck text (composite
// elements, whose fine cells share their element's rotation).
void check_rigid_rotation(const std::string& extra) {
  const std::string yaml =
      "lattice: {h: 0.1, origin: [0.3, -0.2, 0.1], dims: [6, 4, 3]}\n"
      "materials: {m: {E: 1.0e9, nu: 0.25, rho: 1000}}\n"
      "geometry:\n  - add: {sphere: {centre: [0.6, 0.0, 0.25], radius: 0.3}}\n"
      "boundary: {fixed: [{where: {all: true}}]}\n"
      "analysis: {type: static, formulation: corotational}\n"
      "solver: {type: direct}\n" +
      extra;
  Job job(PETSC_COMM_WORLD, yaml);
  const Eigen::Matrix3d R =
      Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  // u = (R - I) x about an arbitrary centre: a rigid motion.
  const Eigen::Vector3d centre(0.1, 0.2, -0.3);
  const auto& D = job.model.layout;
  PetscScalar* a;
  VecGetArray(job.state.u, &a);
  for (std::int32_t i = 0; i < D.num_owned; ++i) {
    const Eigen::Vector3d x = job.position(D.copies[i]) - centre;
    const Eigen::Vector3d u = R * x - x;
    for (int d = 0; d < 3; ++d) a[3 * i + d] = u[d];
  }
  VecRestoreArray(job.state.u, &a);
  // Rotations from the displacement, then f = K^ u - b^.
  Vec ul, f, b;
  DMGetLocalVector(job.model.dm, &ul);
  check_petsc(assembly::global_to_local(job.model.dm, job.state.u, ul), "g2l");
  const PetscScalar* ua;
  VecGetArrayRead(ul, &ua);
  assembly::update_rotations(D, ua, job.model.cells);
  VecRestoreArrayRead(ul, &ua);
  DMRestoreLocalVector(job.model.dm, &ul);
  for (std::size_t e = 0; e < D.cells.size(); ++e) {
    Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>> Re(
        &job.model.cells.rotation[9 * e]);
    EXPECT_LT((Re - R).norm(), 1e-12);
  }
  DMCreateGlobalVector(job.model.dm, &f);
  DMCreateGlobalVector(job.model.dm, &b);
  check_petsc(assembly::apply(job.model.dm, D, job.model.cells, {1.0, 0.0, true}, job.state.u, f),
              "apply");
  VecSet(b, 0.0);
  check_petsc(assembly::add_corotational_rhs(job.model.dm, D, job.model.cells, 1.0, b), "rhs");
  PetscReal nb, nf;
  VecNorm(b, NORM_2, &nb);
  VecAXPY(f, -1.0, b);
  VecNorm(f, NORM_2, &nf);
  EXPECT_GT(nb, 0.0);
  EXPECT_LT(nf / nb, 1e-10);  // K^ u alone is large; the corotational b^ cancels it
  analysis::CellStressFields s;
  check_petsc(analysis::compute_stress(job.model, true, job.state.u, &s), "stress");
  const double scale = 1.0e9 * 1.0;  // E times a unit strain
  for (double v : s.sigma) EXPECT_LT(std::abs(v), 1e-10 * scale);
  // The linear formulation sees a large spurious stress for the same motion.
  analysis::CellStressFields lin;
  check_petsc(analysis::compute_stress(job.model, false, job.state.u, &lin), "stress");
  double max_lin = 0;
  for (std::size_t e = 0; e < lin.energy_density.size(); ++e)
    max_lin = std::max(max_lin, element::von_mises_stress(&lin.sigma[6 * e]));
  EXPECT_GT(max_lin, 0.1 * scale);
  VecDestroy(&f);
  VecDestroy(&b);
}

TEST(Static, RigidRotationGivesNoForceAndNoStress) {
  check_rigid_rotation("");
}

TEST(Static, CompositeRigidRotationGivesNoForceAndNoStress) {
  for (int level : {1, 2})
    check_rigid_rotation("discretization: {type: composite, level: " + std::to_string(level) +
                         "}\n");
}

}  // namespace
}  // namespace hexcut::testing

namespace hexcut::testing {
namespace {

TEST(Static, CentrifugalLoadResultantIsMassTimesOmegaSquaredTimesCentroidDistance) {
  // A box off the spin axis: the resultant of rho omega^2 r is m omega^2 r_centroid
  // (perpendicular part), whatever the discretization, because r is linear in x.
  const std::string yaml =
      "lattice: {h: 0.05, dims: [8, 4, 6]}\n"
      "materials: {m: {E: 1.0e6, nu: 0.3, rho: 900}}\n"
      "geometry: [{add: {box: {min: [0, 0, 0], max: [0.4, 0.2, 0.3]}}}]\n"
      "boundary:\n  fixed: [{where: {plane: {point: [0, 0, 0], normal: [1, 0, 0]}}}]\n"
      "  centrifugal: {point: [-0.1, 0.05, 0], axis: [0, 0, 2], omega: 30}\n";
  Job job(PETSC_COMM_WORLD, yaml);
  Vec f;
  VecDuplicate(job.state.u, &f);
  check_petsc(assembly::assemble_loads(job.model.dm, job.model.layout, job.model.cells,
                                       job.model.boundary, 0.0, 1.0, f),
              "assemble_loads");
  const Eigen::Vector3d sum = component_sums(f);
  VecDestroy(&f);
  const double mass = 900 * 0.4 * 0.2 * 0.3, w2 = 900.0;
  const Eigen::Vector3d expected = mass * w2 * Eigen::Vector3d(0.2 + 0.1, 0.1 - 0.05, 0.0);
  EXPECT_LT((sum - expected).norm(), 1e-12 * expected.norm());
}

}  // namespace
}  // namespace hexcut::testing
