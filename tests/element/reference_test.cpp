#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "element/element.hpp"
#include "test_util.hpp"

namespace hexcut::element {
namespace {

using test::Mat24;
using test::Mat3;
using test::Vec24;

struct LameCase {
  double lambda, mu;
};

std::vector<LameCase> lame_cases() {
  double l = 0, m = 0;
  lame_from_young(200e9, 0.3, &l, &m);
  return {{1.0, 1.0}, {0.0, 1.0}, {100.0, 1.0}, {l, m}, {2.5, 0.01}};
}

Mat24 stiffness(double h, double lambda, double mu) {
  Mat24 K;
  cell_stiffness(reference_matrices(), h, lambda, mu, K.data());
  return K;
}

TEST(ElementReference, KnownDiagonalEntries) {
  // Unit cube, corner 0: int (dN/dx)^2 = int (1-y)^2 (1-z)^2 = 1/9 and int N^2 = 1/27.
  // K_mu diagonal = sum_j int (dN/dx_j)^2 + int (dN/dx_i)^2 = 3/9 + 1/9.
  const auto& ref = reference_matrices();
  for (int d = 0; d < 24; ++d) {
    EXPECT_NEAR(ref.k_lambda[25 * d], 1.0 / 9.0, 1e-15);
    EXPECT_NEAR(ref.k_mu[25 * d], 4.0 / 9.0, 1e-15);
    EXPECT_NEAR(ref.mass[25 * d], 1.0 / 27.0, 1e-15);
  }
}

TEST(ElementReference, Symmetric) {
  const auto& ref = reference_matrices();
  for (const double* m : {ref.k_lambda, ref.k_mu, ref.mass}) {
    const Mat24 a = test::as_mat24(m);
    EXPECT_LT((a - a.transpose()).cwiseAbs().maxCoeff(), 1e-15 * a.cwiseAbs().maxCoeff());
  }
}

TEST(ElementReference, StiffnessPsdWithSixRigidModes) {
  for (const auto& c : lame_cases()) {
    SCOPED_TRACE("lambda=" + std::to_string(c.lambda) + " mu=" + std::to_string(c.mu));
    const Mat24 K = stiffness(1.0, c.lambda, c.mu);
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 24, 24>> eig(K);
    const auto& ev = eig.eigenvalues();  // ascending
    const double top = ev(23);
    ASSERT_GT(top, 0.0);
    EXPECT_GT(ev(0), -1e-12 * top);
    EXPECT_LT(std::abs(ev(5)), 1e-12 * top) << "fewer than 6 zero eigenvalues";
    // Smallest deformation-mode eigenvalue is of order mu, so relative to top it is
    // ~mu/(lambda+2mu): generous floor, still far above round-off.
    EXPECT_GT(ev(6), 1e-6 * top) << "more than 6 zero eigenvalues";
    // Row sums vanish: rigid translations carry no force.
    EXPECT_LT(K.rowwise().sum().cwiseAbs().maxCoeff(), 1e-13 * top);
  }
}

TEST(ElementReference, RigidModesInNullSpace) {
  Vec24 x;
  const double origin[3] = {3.0, -2.0, 7.5};
  corner_positions(0.5, origin, x.data());
  for (const auto& c : lame_cases()) {
    const Mat24 K = stiffness(0.5, c.lambda, c.mu);
    const double scale = K.cwiseAbs().maxCoeff() * 10.0;  // |x| ~ 10
    for (int d = 0; d < 3; ++d) {
      Vec24 t = Vec24::Zero();
      for (int q = 0; q < 8; ++q) t(3 * q + d) = 1.0;
      EXPECT_LT((K * t).cwiseAbs().maxCoeff(), 1e-13 * scale);
      // Infinitesimal rotation about axis d: u = e_d x X (skew-symmetric affine field).
      Mat3 W = Mat3::Zero();
      const int a = (d + 1) % 3, b = (d + 2) % 3;
      W(b, a) = 1.0;
      W(a, b) = -1.0;
      const Vec24 r = test::affine_field(W, Eigen::Vector3d::Zero(), x);
      EXPECT_LT((K * r).cwiseAbs().maxCoeff(), 1e-13 * scale);
    }
  }
}

TEST(ElementReference, MassTotalsAndPositiveDefinite) {
  const Mat24 M = test::as_mat24(reference_matrices().mass);
  for (int c = 0; c < 3; ++c) {
    Vec24 t = Vec24::Zero();
    for (int q = 0; q < 8; ++q) t(3 * q + c) = 1.0;
    EXPECT_NEAR(t.dot(M * t), 1.0, 1e-14);  // rho = 1, h = 1: unit mass
  }
  EXPECT_NEAR(M.sum(), 3.0, 1e-13);  // one unit per displacement component
  // The Q1 mass is a Kronecker product of 1D masses [1/3 1/6; 1/6 1/3] (eigenvalues
  // 1/2 and 1/6), so its spectrum lies in [1/216, 1/8].
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 24, 24>> eig(M);
  EXPECT_NEAR(eig.eigenvalues()(0), 1.0 / 216.0, 1e-15);
  EXPECT_NEAR(eig.eigenvalues()(23), 1.0 / 8.0, 1e-15);
}

// Independent stiffness of a cube of edge h: 3x3x3 Gauss in physical coordinates with the
// fourth-order tensor C_ijkl = lambda d_ij d_kl + mu (d_ik d_jl + d_il d_jk).
Mat24 independent_stiffness(double h, double lambda, double mu) {
  const double p[3] = {0.5 - 0.5 * std::sqrt(0.6), 0.5, 0.5 + 0.5 * std::sqrt(0.6)};
  const double w[3] = {5.0 / 18.0, 8.0 / 18.0, 5.0 / 18.0};
  auto delta = [](int a, int b) { return a == b ? 1.0 : 0.0; };
  Mat24 K = Mat24::Zero();
  for (int gi = 0; gi < 27; ++gi) {
    const int g[3] = {gi % 3, (gi / 3) % 3, gi / 9};
    const double X[3] = {h * p[g[0]], h * p[g[1]], h * p[g[2]]};
    const double wt = w[g[0]] * w[g[1]] * w[g[2]] * h * h * h;
    double dN[8][3];
    for (int q = 0; q < 8; ++q) {
      double f[3], df[3];
      for (int d = 0; d < 3; ++d) {
        const bool hi = (q >> d) & 1;
        f[d] = hi ? X[d] / h : 1.0 - X[d] / h;
        df[d] = hi ? 1.0 / h : -1.0 / h;
      }
      dN[q][0] = df[0] * f[1] * f[2];
      dN[q][1] = f[0] * df[1] * f[2];
      dN[q][2] = f[0] * f[1] * df[2];
    }
    for (int q = 0; q < 8; ++q)
      for (int r = 0; r < 8; ++r)
        for (int i = 0; i < 3; ++i)
          for (int k = 0; k < 3; ++k)
            for (int j = 0; j < 3; ++j)
              for (int l = 0; l < 3; ++l) {
                const double C = lambda * delta(i, j) * delta(k, l) +
                                 mu * (delta(i, k) * delta(j, l) + delta(i, l) * delta(j, k));
                K(3 * q + i, 3 * r + k) += wt * C * dN[q][j] * dN[r][l];
              }
  }
  return K;
}

TEST(ElementReference, ScalesLinearlyWithEdge) {
  for (const auto& c : lame_cases()) {
    for (double h : {1.0, 2.0, 0.125}) {
      const Mat24 expect = independent_stiffness(h, c.lambda, c.mu);
      const Mat24 got = stiffness(h, c.lambda, c.mu);
      EXPECT_LT((got - expect).cwiseAbs().maxCoeff(), 1e-13 * expect.cwiseAbs().maxCoeff())
          << "h=" << h << " lambda=" << c.lambda << " mu=" << c.mu;
    }
  }
}

TEST(ElementReference, AffineFieldEnergyMatchesAnalytic) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> U(-1.0, 1.0);
  for (double h : {1.0, 0.3, 2.0}) {
    Vec24 x;
    const double origin[3] = {1.0, 2.0, -3.0};
    corner_positions(h, origin, x.data());
    for (int trial = 0; trial < 5; ++trial) {
      Mat3 G;
      for (int k = 0; k < 9; ++k) G.data()[k] = U(rng);
      const Vec24 u = test::affine_field(G, Eigen::Vector3d(U(rng), U(rng), U(rng)), x);
      const Mat3 eps = 0.5 * (G + G.transpose());
      for (const auto& c : lame_cases()) {
        const Mat24 K = stiffness(h, c.lambda, c.mu);
        const double energy = 0.5 * u.dot(K * u);
        const double tr = eps.trace();
        const double expect =
            h * h * h * (0.5 * c.lambda * tr * tr + c.mu * eps.cwiseProduct(eps).sum());
        EXPECT_NEAR(energy, expect, 1e-12 * std::abs(expect));
      }
    }
  }
}

TEST(ElementReference, LameFromYoung) {
  double l = 0, m = 0;
  lame_from_young(210.0, 0.25, &l, &m);
  EXPECT_NEAR(l, 84.0, 1e-12);  // 210*0.25/(1.25*0.5)
  EXPECT_NEAR(m, 84.0, 1e-12);  // 210/2.5
  lame_from_young(3.0, 0.0, &l, &m);
  EXPECT_EQ(l, 0.0);
  EXPECT_NEAR(m, 1.5, 1e-15);
}

}  // namespace
}  // namespace hexcut::element
