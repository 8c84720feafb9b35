// Manufactured solution on the unit cube: u*_i = c_i sin(pi x) sin(pi y) sin(pi z)
// vanishes on the boundary; the body force f = -div sigma(u*) is integrated here with
// 3x3x3 Gauss points and trilinear shape functions written independently of
// src/element. Q1 elements must converge with order 2 in L2 and order 1 in the energy
// norm.
#include <cmath>

#include "analysis/composite.hpp"
#include "assembly/boundary.hpp"
#include "fixture.hpp"

namespace hexcut::testing {
namespace {

const double kPi = M_PI;
const double kC[3] = {1.0, -0.5, 0.75};
const double kE = 1.0, kNu = 0.3;
const double kLambda = kE * kNu / ((1 + kNu) * (1 - 2 * kNu)), kMu = kE / (2 * (1 + kNu));

Eigen::Vector3d exact(const Eigen::Vector3d& x) {
  const double g = std::sin(kPi * x[0]) * std::sin(kPi * x[1]) * std::sin(kPi * x[2]);
  return Eigen::Vector3d(kC[0], kC[1], kC[2]) * g;
}

Eigen::Matrix3d exact_gradient(const Eigen::Vector3d& x) {  // (grad u)_ij = du_i/dx_j
  const Eigen::Vector3d s(std::sin(kPi * x[0]), std::sin(kPi * x[1]), std::sin(kPi * x[2]));
  const Eigen::Vector3d c(std::cos(kPi * x[0]), std::cos(kPi * x[1]), std::cos(kPi * x[2]));
  const Eigen::Vector3d dg(kPi * c[0] * s[1] * s[2], kPi * s[0] * c[1] * s[2],
                           kPi * s[0] * s[1] * c[2]);
  return Eigen::Vector3d(kC[0], kC[1], kC[2]) * dg.transpose();
}

Eigen::Vector3d body_force(const Eigen::Vector3d& x) {
  const Eigen::Vector3d s(std::sin(kPi * x[0]), std::sin(kPi * x[1]), std::sin(kPi * x[2]));
  const Eigen::Vector3d c(std::cos(kPi * x[0]), std::cos(kPi * x[1]), std::cos(kPi * x[2]));
  const double g = s[0] * s[1] * s[2];
  Eigen::Matrix3d H;  // Hessian of g
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      if (i == j) {
        H(i, j) = -kPi * kPi * g;
      } else {
        const int k = 3 - i - j;
        H(i, j) = kPi * kPi * c[i] * c[j] * s[k];
      }
    }
  const Eigen::Vector3d cv(kC[0], kC[1], kC[2]);
  // f = -(lambda + mu) grad(div u) - mu laplace(u); laplace(g) = -3 pi^2 g.
  return -(kLambda + kMu) * (H * cv) - kMu * cv * (-3 * kPi * kPi * g);
}

struct Errors {
  double l2, energy;
};

/// Errors of the hexahedra on an n^3 lattice (level 0) or of composite elements of `level`.
Errors solve_and_measure(int n, int level = 0) {
  const double h = 1.0 / n;
  const std::string yaml =
      "lattice: {h: " + std::to_string(h) + ", dims: [" + std::to_string(n) + ", " +
      std::to_string(n) + ", " + std::to_string(n) + "]}\n" +
      "materials: {m: {E: 1.0, nu: 0.3, rho: 1}}\n"
      "geometry: [{add: {box: {min: [0, 0, 0], max: [1, 1, 1]}}}]\n"
      "boundary:\n  fixed:\n"
      "    - where: {plane: {point: [0, 0, 0], normal: [1, 0, 0]}}\n"
      "    - where: {plane: {point: [1, 0, 0], normal: [1, 0, 0]}}\n"
      "    - where: {plane: {point: [0, 0, 0], normal: [0, 1, 0]}}\n"
      "    - where: {plane: {point: [0, 1, 0], normal: [0, 1, 0]}}\n"
      "    - where: {plane: {point: [0, 0, 0], normal: [0, 0, 1]}}\n"
      "    - where: {plane: {point: [0, 0, 1], normal: [0, 0, 1]}}\n"
      "solver: {type: direct}\n" +
      (level > 0 ? "discretization: {type: composite, level: " + std::to_string(level) + "}\n"
                 : std::string());
  Job job(PETSC_COMM_WORLD, yaml);
  auto& M = job.model;
  const auto& D = M.layout;
  // Gauss rule on [0,1] with 3 points.
  const double gp[3] = {0.5 - 0.5 * std::sqrt(0.6), 0.5, 0.5 + 0.5 * std::sqrt(0.6)};
  const double gw[3] = {5.0 / 18, 8.0 / 18, 5.0 / 18};
  auto shape = [](int q, const Eigen::Vector3d& xi, double* N, Eigen::Vector3d* dN) {
    double v[3], dv[3];
    for (int d = 0; d < 3; ++d) {
      const int a = (q >> d) & 1;
      v[d] = a ? xi[d] : 1 - xi[d];
      dv[d] = a ? 1.0 : -1.0;
    }
    *N = v[0] * v[1] * v[2];
    *dN = Eigen::Vector3d(dv[0] * v[1] * v[2], v[0] * dv[1] * v[2], v[0] * v[1] * dv[2]);
  };
  // Load vector.
  Vec bl, b;
  DMGetLocalVector(M.dm, &bl);
  DMCreateGlobalVector(M.dm, &b);
  VecSet(bl, 0.0);
  PetscScalar* ba;
  VecGetArray(bl, &ba);
  for (std::size_t e = 0; e < D.cells.size(); ++e) {
    const Eigen::Vector3d x0(M.cells.origin[e][0], M.cells.origin[e][1], M.cells.origin[e][2]);
    for (int i = 0; i < 27; ++i) {
      const Eigen::Vector3d xi(gp[i % 3], gp[(i / 3) % 3], gp[i / 9]);
      const double w = gw[i % 3] * gw[(i / 3) % 3] * gw[i / 9] * h * h * h;
      const Eigen::Vector3d f = body_force(x0 + h * xi);
      for (int q = 0; q < 8; ++q) {
        double N;
        Eigen::Vector3d dN;
        shape(q, xi, &N, &dN);
        for (int d = 0; d < 3; ++d) ba[3 * D.cell_corners[e][q] + d] += w * N * f[d];
      }
    }
  }
  VecRestoreArray(bl, &ba);
  VecSet(b, 0.0);
  DMLocalToGlobalBegin(M.dm, bl, ADD_VALUES, b);
  DMLocalToGlobalEnd(M.dm, bl, ADD_VALUES, b);
  DMRestoreLocalVector(M.dm, &bl);
  // Operator and solve (homogeneous Dirichlet).
  Mat A;
  KSP ksp;
  check_petsc(assembly::create_matrix(PETSC_COMM_WORLD, M.copies, D, &A), "create_matrix");
  HEXCUT_CALL(assembly::assemble_constrained_matrix(M.dm, D, M.cells, {1.0, 0.0, true},
                                                    M.boundary.constraints, A));
  check_petsc(assembly::constrain_rhs(M.dm, D, M.cells, {1.0, 0.0, true}, M.boundary.constraints,
                                      0.0, 1.0, b),
              "rhs");
  solve::SolveRecord record;
  if (level == 0) {
    check_petsc(solve::create_solver(PETSC_COMM_WORLD, M.dm, job.deck.solver, &ksp), "ksp");
    check_petsc(solve::set_operator(ksp, job.deck.solver, A, M.coordinates), "operator");
    HEXCUT_CALL(solve::solve(ksp, b, job.state.u, &record));
  } else {
    // The composite system (analysis/composite.hpp) with the same fine load vector.
    auto* mg = job.sim->multigrid();
    HEXCUT_CALL(mg->update(M.cells, {1.0, 0.0, true}, M.boundary.constraints.rows));
    Vec bc, uc, xc;
    DMCreateGlobalVector(mg->dm(level), &bc);
    VecDuplicate(bc, &uc);
    VecSet(uc, 0.0);
    HEXCUT_CALL(analysis::composite_rhs(*mg, b, bc, uc));
    HEXCUT_CALL(analysis::composite_positions(*mg, &xc));
    check_petsc(solve::create_solver(PETSC_COMM_WORLD, mg->dm(level), job.deck.solver, &ksp),
                "ksp");
    check_petsc(solve::set_operator(ksp, job.deck.solver, mg->coarsest_matrix(), xc), "operator");
    HEXCUT_CALL(solve::solve(ksp, bc, uc, &record));
    HEXCUT_CALL(analysis::prolong_composite(*mg, uc, job.state.u));
    for (Vec* v : {&bc, &uc, &xc}) VecDestroy(v);
  }
  // Errors by 3x3x3 quadrature of the local cells.
  Vec ul;
  DMGetLocalVector(M.dm, &ul);
  check_petsc(assembly::global_to_local(M.dm, job.state.u, ul), "g2l");
  const PetscScalar* ua;
  VecGetArrayRead(ul, &ua);
  double l2 = 0, en = 0;
  for (std::size_t e = 0; e < D.cells.size(); ++e) {
    const Eigen::Vector3d x0(M.cells.origin[e][0], M.cells.origin[e][1], M.cells.origin[e][2]);
    for (int i = 0; i < 27; ++i) {
      const Eigen::Vector3d xi(gp[i % 3], gp[(i / 3) % 3], gp[i / 9]);
      const double w = gw[i % 3] * gw[(i / 3) % 3] * gw[i / 9] * h * h * h;
      Eigen::Vector3d uh = Eigen::Vector3d::Zero();
      Eigen::Matrix3d Gh = Eigen::Matrix3d::Zero();
      for (int q = 0; q < 8; ++q) {
        double N;
        Eigen::Vector3d dN;
        shape(q, xi, &N, &dN);
        const Eigen::Vector3d uq(ua[3 * D.cell_corners[e][q]], ua[3 * D.cell_corners[e][q] + 1],
                                 ua[3 * D.cell_corners[e][q] + 2]);
        uh += N * uq;
        Gh += uq * (dN / h).transpose();
      }
      const Eigen::Vector3d x = x0 + h * xi;
      l2 += w * (uh - exact(x)).squaredNorm();
      const Eigen::Matrix3d de =
          0.5 * ((Gh - exact_gradient(x)) + (Gh - exact_gradient(x)).transpose());
      en += w * (kLambda * de.trace() * de.trace() + 2 * kMu * (de.array() * de.array()).sum());
    }
  }
  VecRestoreArrayRead(ul, &ua);
  DMRestoreLocalVector(M.dm, &ul);
  MPI_Allreduce(MPI_IN_PLACE, &l2, 1, MPI_DOUBLE, MPI_SUM, PETSC_COMM_WORLD);
  MPI_Allreduce(MPI_IN_PLACE, &en, 1, MPI_DOUBLE, MPI_SUM, PETSC_COMM_WORLD);
  KSPDestroy(&ksp);
  MatDestroy(&A);
  VecDestroy(&b);
  return {std::sqrt(l2), std::sqrt(en)};
}

TEST(Manufactured, ConvergesWithOptimalOrders) {
  std::vector<Errors> err;
  for (int n : {4, 8, 16}) err.push_back(solve_and_measure(n));
  for (std::size_t k = 1; k < err.size(); ++k) {
    const double l2_order = std::log2(err[k - 1].l2 / err[k].l2);
    const double energy_order = std::log2(err[k - 1].energy / err[k].energy);
    std::printf("refinement %zu: L2 %.3e (order %.3f)  energy %.3e (order %.3f)\n", k, err[k].l2,
                l2_order, err[k].energy, energy_order);
    if (k == err.size() - 1) {
      EXPECT_GE(l2_order, 1.9);
      EXPECT_GE(energy_order, 0.9);
    }
  }
}

TEST(Manufactured, CompositeElementsConvergeWithTheOrdersOfTheirSize) {
  // With the composite level fixed, refining h refines the composite elements too (size
  // 2^l h). On the cube the composite space of level l is the Q1 space of size 2^l h and its
  // Galerkin matrices are exactly that space's (the fine integration is exact for it), so
  // the orders are those of Q1, and the errors at fine h are those of the hexahedra at
  // 2^l h: the same numbers up to quadrature (the load and the error integrals take the
  // 3-point Gauss rule per fine cell here, per composite-sized cell there), a second check of
  // the composite path.
  const Errors q1 = solve_and_measure(8);
  for (int level : {1, 2}) {
    std::vector<Errors> err;
    for (int n : {16, 32}) err.push_back(solve_and_measure(n, level));
    if (level == 1) {
      EXPECT_NEAR(err[0].l2, q1.l2, 1e-3 * q1.l2);
      EXPECT_NEAR(err[0].energy, q1.energy, 1e-3 * q1.energy);
    }
    const double l2_order = std::log2(err[0].l2 / err[1].l2);
    const double energy_order = std::log2(err[0].energy / err[1].energy);
    std::printf(
        "composite level %d, n 16 -> 32: L2 %.3e -> %.3e (order %.3f), energy %.3e -> "
        "%.3e (order %.3f)\n",
        level, err[0].l2, err[1].l2, l2_order, err[0].energy, err[1].energy, energy_order);
    EXPECT_GE(l2_order, level == 1 ? 1.9 : 1.8);
    EXPECT_GE(energy_order, 0.9);
  }
}

}  // namespace
}  // namespace hexcut::testing
