// Pressures and expression-valued supports and loads against independent expectations:
// a thick-walled cylinder under internal pressure (Lamé), the resultant and moment of a
// pressure on a closed staircase body and on a hemisphere, a traction linear in x against
// its analytic resultant and moment, expression supports at the vertices, and a pressure
// that reaches the faces a cut opens.
#include <cmath>
#include <cstdio>

#include "analysis/cutting.hpp"
#include "assembly/boundary.hpp"
#include "common/errors.hpp"
#include "fixture.hpp"

namespace hexcut::testing {
namespace {

std::string num(double v) {
  char b[40];
  std::snprintf(b, sizeof b, "%.17g", v);
  return b;
}

/// The external force vector at time t (load factor 1), in canonical copy order.
std::vector<double> loads(Job& job, double t) {
  Vec f;
  VecDuplicate(job.state.u, &f);
  check_petsc(assembly::assemble_loads(job.model.dm, job.model.layout, job.model.cells,
                                       job.model.boundary, t, 1.0, f),
              "assemble_loads");
  auto out = job.canonical(f);
  VecDestroy(&f);
  return out;
}

struct Resultant {
  Eigen::Vector3d force{0, 0, 0};   // [N]
  Eigen::Vector3d moment{0, 0, 0};  // about `about` [N m]
};

/// Sum of the nodal forces and of their moments (forces at the reference vertices)
/// over the copies for which `keep(copy)` holds.
template <class Keep>
Resultant resultant(const Job& job, const std::vector<double>& f, const Eigen::Vector3d& about,
                    Keep keep) {
  Resultant r;
  for (std::int32_t v = 0; v < job.model.copies.num_copies; ++v) {
    if (!keep(v)) continue;
    const Eigen::Vector3d fv(&f[3 * v]);
    r.force += fv;
    r.moment += (job.position(v) - about).cross(fv);
  }
  return r;
}

Resultant resultant(const Job& job, const std::vector<double>& f,
                    const Eigen::Vector3d& about = Eigen::Vector3d::Zero()) {
  return resultant(job, f, about, [](std::int32_t) { return true; });
}

// ---------------------------------------------------------------- Lamé

/// Relative L2 error over the vertices of the radial displacement of a thick-walled
/// cylinder (inner radius a = 1, outer b = 2) under internal pressure p, plane strain,
/// with `n` cells through the wall, against Lamé's
///   u_r(r) = p a^2 / (E (b^2 - a^2)) ((1 + nu)(1 - 2 nu) r + (1 + nu) b^2 / r).
/// The full ring is one cell thick with u_z = 0 at every vertex (exact plane strain:
/// the z-independent discrete field with u_z = 0 is the solution), u_x = 0 on x = 0 and
/// u_y = 0 on y = 0 (symmetry planes of the exact solution; no rigid modes left).
double lame_error(int n) {
  const double a = 1.0, b = 2.0, E = 1.0e9, nu = 0.3, p = 1.0e6, h = (b - a) / n;
  // The inner staircase faces have centres within h/2 of r = a; the outer ones are near
  // r = b. The selector's cylinder spans only the face centres at z = h/2 of the lateral
  // faces, not the faces of the end planes z = 0 and z = h.
  const std::string yaml =
      "lattice: {h: " + num(h) + ", bounds: [[" + num(-b) + ", " + num(-b) + ", 0], [" + num(b) +
      ", " + num(b) + ", " + num(h) +
      "]]}\n"
      "materials: {m: {E: " +
      num(E) + ", nu: " + num(nu) +
      ", rho: 1}}\n"
      "geometry:\n"
      "  - add: {cylinder: {start: [0, 0, -1], end: [0, 0, 1], radius: " +
      num(b) +
      "}}\n"
      "  - subtract: {cylinder: {start: [0, 0, -1], end: [0, 0, 1], radius: " +
      num(a) +
      "}}\n"
      "boundary:\n"
      "  fixed:\n"
      "    - {where: {all: true}, components: [z]}\n"
      "    - {where: {plane: {point: [0, 0, 0], normal: [1, 0, 0]}}, components: [x]}\n"
      "    - {where: {plane: {point: [0, 0, 0], normal: [0, 1, 0]}}, components: [y]}\n"
      "  pressure:\n"
      "    - where: {cylinder: {start: [0, 0, " +
      num(0.25 * h) + "], end: [0, 0, " + num(0.75 * h) + "], radius: " + num(a + 0.75 * h) +
      "}}\n"
      "      value: " +
      num(p) +
      "\n"
      "solver: {type: gmg, rtol: 1.0e-10}\n";
  Job job(PETSC_COMM_WORLD, yaml);
  // The pressure's resultant on the closed inner staircase vanishes, and only inner
  // faces are loaded: the x-force on the half ring x > 0 is -p times its projection,
  // 2a p (exactly for the staircase: the projection of the hole is 2a wide when a/h is
  // an integer).
  const auto f = loads(job, 1.0);
  const auto all = resultant(job, f);
  EXPECT_LT(all.force.norm(), 1e-9 * p * a * h);
  const auto right = resultant(job, f, Eigen::Vector3d::Zero(),
                               [&](std::int32_t v) { return job.position(v).x() > 1e-9; });
  EXPECT_NEAR(right.force.x(), 2 * a * h * p, 1e-9 * p * a * h);

  job.run();
  const auto u = job.canonical(job.state.u);
  const double k = p * a * a / (E * (b * b - a * a));
  double err2 = 0, ref2 = 0, uz = 0;
  for (std::int32_t v = 0; v < job.model.copies.num_copies; ++v) {
    const Eigen::Vector3d x = job.position(v);
    const double r = std::hypot(x.x(), x.y());
    const double exact = k * ((1 + nu) * (1 - 2 * nu) * r + (1 + nu) * b * b / r);
    const double ur = (u[3 * v] * x.x() + u[3 * v + 1] * x.y()) / r;
    err2 += (ur - exact) * (ur - exact);
    ref2 += exact * exact;
    uz = std::max(uz, std::abs(u[3 * v + 2]));
  }
  EXPECT_EQ(uz, 0.0);
  return std::sqrt(err2 / ref2);
}

TEST(Loads, LameCylinderUnderInternalPressure) {
  std::vector<double> errors;
  for (int n : {8, 16, 32}) {
    errors.push_back(lame_error(n));
    std::printf("Lame: %2d cells through the wall: relative L2 error of u_r = %.4f\n", n,
                errors.back());
  }
  EXPECT_LT(errors[2], 0.03);
  EXPECT_LT(errors[1], errors[0]);
  EXPECT_LT(errors[2], errors[1]);
}

// ---------------------------------------------------------------- resultants

TEST(Loads, UniformPressureOnAClosedStaircaseHasNoResultantNorMoment) {
  // A voxelized ball: sum of -p n dA over a closed surface is 0, and so is the sum of
  // x × (-p n dA) (the divergence of x × e_i vanishes), whatever the staircase.
  const double p = 3.0e5, h = 0.1;
  const std::string yaml =
      "lattice: {h: 0.1, bounds: [[-0.6, -0.6, -0.6], [0.6, 0.6, 0.6]]}\n"
      "materials: {m: {E: 1.0e9, nu: 0.3, rho: 1}}\n"
      "geometry: [{add: {sphere: {centre: [0.03, -0.02, 0.01], radius: 0.52}}}]\n"
      "boundary:\n"
      "  fixed: [{where: {sphere: {centre: [0, 0, 0], radius: 0.1}}}]\n"
      "  pressure: [{where: {all: true}, value: " +
      num(p) + "}]\n";
  Job job(PETSC_COMM_WORLD, yaml);
  const auto f = loads(job, 1.0);
  const auto r = resultant(job, f, Eigen::Vector3d(0.3, 0.2, -0.1));
  double total = 0;  // sum of |f|: the scale of the cancellation
  for (double v : f) total += std::abs(v);
  EXPECT_GT(total, p * h * h * 100);
  EXPECT_LT(r.force.norm(), 1e-13 * total);
  EXPECT_LT(r.moment.norm(), 1e-13 * total);
}

TEST(Loads, PressureOnAHemisphereEqualsPressureTimesProjectedArea) {
  // The lower half of a ball, pressure on the curved staircase only (face centres below
  // z = -h/4, so not the flat top at z = 0): the resultant pushes up with p times the
  // projected area, which for the staircase is exactly the top layer of cells
  // (counted here from the cell centres), and within a few percent p π R^2.
  const double p = 2.0e5, h = 0.05, R = 0.5;
  const std::string yaml =
      "lattice: {h: 0.05, bounds: [[-0.6, -0.6, -0.6], [0.6, 0.6, 0]]}\n"
      "materials: {m: {E: 1.0e9, nu: 0.3, rho: 1}}\n"
      "geometry: [{add: {sphere: {centre: [0, 0, 0], radius: 0.5}}}]\n"
      "boundary:\n"
      "  fixed: [{where: {plane: {point: [0, 0, 0], normal: [0, 0, 1]}}}]\n"
      "  pressure:\n"
      "    - where: {half_space: {point: [0, 0, -0.0125], normal: [0, 0, 1]}}\n"
      "      value: " +
      num(p) + "\n";
  Job job(PETSC_COMM_WORLD, yaml);
  int top_cells = 0;
  for (int i = 0; i < 24; ++i)
    for (int j = 0; j < 24; ++j) {
      const double x = -0.6 + (i + 0.5) * h, y = -0.6 + (j + 0.5) * h, z = -0.5 * h;
      top_cells += x * x + y * y + z * z <= R * R;
    }
  const auto r = resultant(job, loads(job, 1.0));
  const double expected = p * top_cells * h * h;
  std::printf("hemisphere: resultant %.6g N up, p x staircase projection %.6g N, p pi R^2 %.6g N\n",
              r.force.z(), expected, p * M_PI * R * R);
  EXPECT_NEAR(r.force.z(), expected, 1e-12 * expected);
  EXPECT_LT(std::hypot(r.force.x(), r.force.y()), 1e-12 * expected);
  EXPECT_NEAR(r.force.z(), p * M_PI * R * R, 0.03 * p * M_PI * R * R);
}

/// A box [0, 0.8] x [0, 0.4] x [0, 0.2] with h = 0.1, clamped at x = 0, and `boundary`
/// lines appended.
std::string box_deck(const std::string& boundary) {
  return "lattice: {h: 0.1, dims: [8, 4, 2]}\n"
         "materials: {m: {E: 1.0e9, nu: 0.3, rho: 1}}\n"
         "geometry: [{add: {box: {min: [0, 0, 0], max: [0.8, 0.4, 0.2]}}}]\n"
         "boundary:\n"
         "  fixed: [{where: {plane: {point: [0, 0, 0], normal: [1, 0, 0]}}}]\n" +
         boundary;
}

TEST(Loads, TractionLinearInXHasTheAnalyticResultantAndMoment) {
  // t_z = c0 + c1 x on the top face z = 0.2 (L = 0.8 by W = 0.4), times t (the
  // expression) and a ramp scale: at t = 0.5 the ramp is 0.25, so
  // F_z = 0.5 * 0.25 * W (c0 L + c1 L^2 / 2), and the moment about the origin is
  // M_x = 0.125 * ∫ y t_z dA = 0.125 (W^2 / 2)(c0 L + c1 L^2 / 2),
  // M_y = -0.125 ∫ x t_z dA = -0.125 W (c0 L^2 / 2 + c1 L^3 / 3).
  // Consistent nodal loads reproduce both for a field linear on each face.
  const double c0 = 1500.0, c1 = -4000.0, L = 0.8, W = 0.4;
  Job job(PETSC_COMM_WORLD,
          box_deck("  traction:\n"
                   "    - where: {plane: {point: [0, 0, 0.2], normal: [0, 0, 1]}}\n"
                   "      value: [0, 0, '(" +
                   num(c0) + " + (" + num(c1) +
                   ") * x) * t']\n"
                   "      scale: {ramp: {value: 1, start: 0.25, end: 1.25}}\n"));
  const auto r = resultant(job, loads(job, 0.5));
  const double s = 0.5 * 0.25;
  const Eigen::Vector3d F(0, 0, s * W * (c0 * L + c1 * L * L / 2));
  const Eigen::Vector3d M(s * W * W / 2 * (c0 * L + c1 * L * L / 2),
                          -s * W * (c0 * L * L / 2 + c1 * L * L * L / 3), 0);
  EXPECT_LT((r.force - F).norm(), 1e-12 * F.norm());
  EXPECT_LT((r.moment - M).norm(), 1e-12 * M.norm());
}

TEST(Loads, ConstantExpressionsGiveTheUniformLoads) {
  // The same constant traction and pressure, once as numbers (t h^2/4 per face corner)
  // and once as expressions (2x2 Gauss points, fixed in time or varying with t): the
  // load vectors agree to round-off, and the pressure on the end face x = 0.8 gives
  // -p A in x.
  const std::string numbers =
      "  traction: [{where: {plane: {point: [0, 0, 0.2], normal: [0, 0, 1]}}, value: [100, "
      "-200, 300]}]\n"
      "  pressure: [{where: {plane: {point: [0.8, 0, 0], normal: [1, 0, 0]}}, value: 5000}]\n";
  const std::string expressions =
      "  traction: [{where: {plane: {point: [0, 0, 0.2], normal: [0, 0, 1]}}, value: ['100 + "
      "0*x', '-200 + 0*t', 300]}]\n"
      "  pressure: [{where: {plane: {point: [0.8, 0, 0], normal: [1, 0, 0]}}, value: '5000 + "
      "0*y'}]\n";
  Job uniform(PETSC_COMM_WORLD, box_deck(numbers));
  Job expr(PETSC_COMM_WORLD, box_deck(expressions));
  const auto f0 = loads(uniform, 1.0), f1 = loads(expr, 1.0);
  ASSERT_EQ(f0.size(), f1.size());
  double diff = 0, norm = 0;
  for (std::size_t i = 0; i < f0.size(); ++i) {
    diff = std::max(diff, std::abs(f0[i] - f1[i]));
    norm = std::max(norm, std::abs(f0[i]));
  }
  EXPECT_LT(diff, 1e-14 * norm);
  // Uniform: t h^2 / 4 at each face corner; (0.4, 0.4, 0.2) is a corner of two top faces.
  for (std::int32_t v = 0; v < uniform.model.copies.num_copies; ++v)
    if ((uniform.position(v) - Eigen::Vector3d(0.4, 0.4, 0.2)).norm() < 1e-9) {
      EXPECT_DOUBLE_EQ(f0[3 * v + 0], 2 * 100 * 0.01 / 4);
      EXPECT_DOUBLE_EQ(f0[3 * v + 1], 2 * -200 * 0.01 / 4);
      EXPECT_DOUBLE_EQ(f0[3 * v + 2], 2 * 300 * 0.01 / 4);
    }
  const auto r = resultant(uniform, f0);
  EXPECT_NEAR(r.force.x(), 100 * 0.32 - 5000 * 0.08, 1e-10);
}

TEST(Loads, ExpressionSupportsArePrescribedAtTheVertices) {
  // Every vertex prescribed: the static solution is the prescribed field at t = 1.
  // Components: an expression of x, y; a time function; an expression of z and t.
  Job job(PETSC_COMM_WORLD,
          "lattice: {h: 0.1, dims: [4, 3, 2]}\n"
          "materials: {m: {E: 1.0e9, nu: 0.3, rho: 1}}\n"
          "geometry: [{add: {box: {min: [0, 0, 0], max: [0.4, 0.3, 0.2]}}}]\n"
          "boundary:\n"
          "  fixed:\n"
          "    - where: {all: true}\n"
          "      value: ['1e-3 * x * y + 2e-4', {ramp: {value: -3.0e-4, end: 2}}, "
          "'sin(_pi * z) * 1e-3 * t^2']\n"
          "solver: {type: direct}\n");
  job.run();
  const auto u = job.canonical(job.state.u);
  double worst = 0;
  for (std::int32_t v = 0; v < job.model.copies.num_copies; ++v) {
    const Eigen::Vector3d x = job.position(v);
    const Eigen::Vector3d exact(1e-3 * x.x() * x.y() + 2e-4, -1.5e-4,
                                std::sin(M_PI * x.z()) * 1e-3);
    worst = std::max(worst, (Eigen::Vector3d(&u[3 * v]) - exact).norm());
  }
  EXPECT_LT(worst, 1e-15);
}

// ---------------------------------------------------------------- after a cut

TEST(Loads, PressureReachesTheFacesACutOpens) {
  // A bar [0, 1] x [0, 0.1] x [0, 0.1], pressure p on the boundary faces with centres in
  // 0.45 <= x <= 0.55. Before the cut at x = 0.5 those are lateral faces only: no force
  // along x on either half. After it, the cut faces are boundary faces too: the left
  // piece is pushed by -p A along x, the right one by +p A (A = 0.01 m^2).
  const double p = 1.0e4, A = 0.01;
  const std::string yaml =
      "lattice: {h: 0.05, dims: [20, 2, 2]}\n"
      "materials: {m: {E: 1.0e6, nu: 0.3, rho: 1000}}\n"
      "geometry: [{add: {box: {min: [0, 0, 0], max: [1, 0.1, 0.1]}}}]\n"
      "boundary:\n"
      "  fixed: [{where: {plane: {point: [0, 0, 0], normal: [1, 0, 0]}}}]\n"
      "  pressure:\n"
      "    - where: {box: {min: [0.45, -1, -1], max: [0.55, 1, 1]}}\n"
      "      value: " +
      num(p) +
      "\n"
      "solver: {type: cg-jacobi}\n"
      "cuts:\n"
      "  - blade: {polygon: [[0.5, -1, -1], [0.5, 2, -1], [0.5, 2, 2], [0.5, -1, 2]]}\n";
  Job job(PETSC_COMM_WORLD, yaml);
  auto halves = [&]() {
    const auto f = loads(job, 1.0);
    const auto& L = job.model.lattice;
    const auto left = [&](std::int32_t v) {
      return L.spec.cell_centre(L.ijk[job.model.copies.first_cell[v]][0], 0, 0).x() < 0.5;
    };
    return std::pair{resultant(job, f, {}, left).force,
                     resultant(job, f, {}, [&](std::int32_t v) { return !left(v); }).force};
  };
  const auto [left0, right0] = halves();
  EXPECT_LT(std::abs(left0.x()) + std::abs(right0.x()), 1e-12 * p * A);
  EXPECT_LT((left0 + right0).norm(), 1e-12 * p * A);
  analysis::Cutter cutter(job.deck, job.model.lattice);
  analysis::CutReport cut;
  HEXCUT_CALL(analysis::apply_due_cuts(PETSC_COMM_WORLD, job.deck, cutter, 0.0, &job.model,
                                       &job.state, &cut));
  ASSERT_EQ(cut.links, 4);
  const auto [left1, right1] = halves();
  EXPECT_NEAR(left1.x(), -p * A, 1e-12 * p * A);
  EXPECT_NEAR(right1.x(), p * A, 1e-12 * p * A);
  EXPECT_LT(std::hypot(left1.y(), left1.z()), 1e-12 * p * A);
}

}  // namespace
}  // namespace hexcut::testing
