#include <gtest/gtest.h>

#include <cmath>

#include "element/element.hpp"
#include "test_util.hpp"

namespace hexcut::element {
namespace {

using test::Mat3;
using test::Vec24;

constexpr double kH = 2.0;
const double kIdentity[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};

Vec24 affine(const Mat3& G, const Vec24& x) {
  return test::affine_field(G, Eigen::Vector3d(0.01, -0.02, 0.03), x);
}

Vec24 corners() {
  Vec24 x;
  const double origin[3] = {4.0, 6.0, -2.0};
  corner_positions(kH, origin, x.data());
  return x;
}

TEST(ElementStrain, UniaxialStrain) {
  const double eps0 = 2e-3;
  Mat3 G = Mat3::Zero();
  G(0, 0) = eps0;
  const Vec24 x = corners();
  const Vec24 u = affine(G, x);
  double eps[6];
  strain_at_centre(u.data(), kH, eps);
  const double expect[6] = {eps0, 0, 0, 0, 0, 0};
  for (int k = 0; k < 6; ++k) EXPECT_NEAR(eps[k], expect[k], 1e-16) << k;

  const double lambda = 5.0, mu = 3.0;
  const CellStress s = recover_stress(u.data(), x.data(), kIdentity, kH, lambda, mu);
  const double sig[6] = {(lambda + 2 * mu) * eps0, lambda * eps0, lambda * eps0, 0, 0, 0};
  for (int k = 0; k < 6; ++k) EXPECT_NEAR(s.sigma[k], sig[k], 1e-14) << k;
  EXPECT_NEAR(s.pressure, -(lambda + 2 * mu / 3.0) * eps0, 1e-14);
}

TEST(ElementStrain, ShearComponentOrder) {
  // Each simple shear u_i = g X_j must land in the ParaView slot of (i,j): xy=3, yz=4, xz=5,
  // with tensor shear eps_ij = g/2 and stress sigma_ij = mu g.
  const int slot[3][3] = {{0, 3, 5}, {3, 1, 4}, {5, 4, 2}};
  const double g = 1e-3, lambda = 2.0, mu = 7.0;
  const Vec24 x = corners();
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      if (i == j) continue;
      Mat3 G = Mat3::Zero();
      G(i, j) = g;
      const Vec24 u = affine(G, x);
      double eps[6];
      strain_at_centre(u.data(), kH, eps);
      const CellStress s = recover_stress(u.data(), x.data(), kIdentity, kH, lambda, mu);
      for (int k = 0; k < 6; ++k) {
        EXPECT_NEAR(eps[k], k == slot[i][j] ? 0.5 * g : 0.0, 1e-17) << i << j << k;
        EXPECT_NEAR(s.sigma[k], k == slot[i][j] ? mu * g : 0.0, 1e-11 * mu * g) << i << j << k;
      }
      // (x + u) - x costs ~1e-16 * h absolute in d, i.e. ~1e-13 relative to this strain.
      // Pure shear: von Mises = sqrt(3) tau, principal stresses +tau, 0, -tau.
      EXPECT_NEAR(s.von_mises, std::sqrt(3.0) * mu * g, 1e-11 * mu * g);
      EXPECT_NEAR(s.principal[0], mu * g, 1e-11 * mu * g);
      EXPECT_NEAR(s.principal[1], 0.0, 1e-11 * mu * g);
      EXPECT_NEAR(s.principal[2], -mu * g, 1e-11 * mu * g);
    }
  }
}

TEST(ElementStrain, DeformationGradientLayout) {
  // F[3*i + j] = dx_i/dX_j for u = G X.
  Mat3 G;
  G << 1, 2, 3, 4, 5, 6, 7, 8, 9;
  G *= 0.01;
  const Vec24 u = affine(G, corners());
  double F[9];
  deformation_gradient_at_centre(u.data(), kH, F);
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) EXPECT_NEAR(F[3 * i + j], (i == j) + G(i, j), 1e-15);
  }
}

TEST(ElementStrain, CentreStrainOfNonAffineField) {
  // Hourglass mode u_x = s_y s_z (corner signs): zero strain at the centre, which is why
  // centre strain alone cannot be used as the element energy.
  Vec24 u = Vec24::Zero();
  for (int q = 0; q < 8; ++q) u(3 * q) = corner_sign(q, 1) * corner_sign(q, 2);
  double eps[6];
  strain_at_centre(u.data(), kH, eps);
  for (double e : eps) EXPECT_EQ(e, 0.0);
}

void check_principal(const CellStress& s) {
  Mat3 S;
  S << s.sigma[0], s.sigma[3], s.sigma[5], s.sigma[3], s.sigma[1], s.sigma[4], s.sigma[5],
      s.sigma[4], s.sigma[2];
  const double scale = S.norm();
  EXPECT_GE(s.principal[0], s.principal[1]);
  EXPECT_GE(s.principal[1], s.principal[2]);
  Mat3 D;  // rows = directions
  for (int k = 0; k < 9; ++k) D.data()[k] = s.directions[k];
  EXPECT_LT((D * D.transpose() - Mat3::Identity()).cwiseAbs().maxCoeff(), 1e-14);
  EXPECT_NEAR(D.determinant(), 1.0, 1e-14);
  for (int i = 0; i < 3; ++i) {
    const Eigen::Vector3d d = D.row(i).transpose();
    EXPECT_LT((S * d - s.principal[i] * d).norm(), 1e-13 * scale) << i;
  }
  EXPECT_NEAR(s.principal[0] + s.principal[1] + s.principal[2], S.trace(), 1e-13 * scale);
  EXPECT_NEAR(s.pressure, -S.trace() / 3.0, 1e-15 * scale);
}

TEST(ElementStress, PrincipalValuesAndDirections) {
  std::mt19937_64 rng(21);
  std::uniform_real_distribution<double> U(-100.0, 100.0);
  for (int t = 0; t < 200; ++t) {
    double sig[6];
    for (double& v : sig) v = U(rng);
    check_principal(stress_fields(sig));
  }
  // Repeated eigenvalues (uniaxial, hydrostatic) still give an orthonormal right-handed set.
  const double uni[6] = {0, 0, -5, 0, 0, 0};
  check_principal(stress_fields(uni));
  const double hyd[6] = {-3, -3, -3, 0, 0, 0};
  check_principal(stress_fields(hyd));
}

TEST(ElementStress, VonMisesAndPressure) {
  const double tension[6] = {250.0, 0, 0, 0, 0, 0};
  EXPECT_NEAR(stress_fields(tension).von_mises, 250.0, 1e-12);
  const double compression[6] = {0, 0, -40.0, 0, 0, 0};
  const CellStress c = stress_fields(compression);
  EXPECT_NEAR(c.von_mises, 40.0, 1e-12);
  EXPECT_NEAR(c.pressure, 40.0 / 3.0, 1e-12);
  EXPECT_NEAR(c.principal[0], 0.0, 1e-15);
  EXPECT_NEAR(c.principal[2], -40.0, 1e-12);
  EXPECT_NEAR(std::abs(c.directions[8]), 1.0, 1e-15);  // most compressive along z
  const double hydro[6] = {-7.0, -7.0, -7.0, 0, 0, 0};
  const CellStress h = stress_fields(hydro);
  EXPECT_EQ(h.von_mises, 0.0);
  EXPECT_NEAR(h.pressure, 7.0, 1e-15);
  // Rotating a stress state leaves von Mises, pressure and principal values unchanged.
  std::mt19937_64 rng(22);
  const Mat3 Q = test::random_rotation(rng);
  const double s[6] = {10, -4, 3, 2, -1, 5};
  double rs[6];
  rotate_tensor(Q.data(), s, rs);
  const CellStress a = stress_fields(s), b = stress_fields(rs);
  EXPECT_NEAR(a.von_mises, b.von_mises, 1e-12);
  EXPECT_NEAR(a.pressure, b.pressure, 1e-13);
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(a.principal[i], b.principal[i], 1e-12);
}

}  // namespace
}  // namespace hexcut::element

namespace hexcut::element {
namespace {

TEST(ElementStress, StrainEnergyDensityIsHalfStressTimesStrain) {
  // Uniaxial stress s: W = s^2 / (2E); pure shear t: W = t^2 / (2G); and for a general
  // tensor W = 1/2 sigma:epsilon with epsilon from Hooke's law written out (E, nu form),
  // unchanged by a rotation of the tensor.
  const double E = 2.0e9, nu = 0.3, lambda = E * nu / ((1 + nu) * (1 - 2 * nu)),
               mu = E / (2 * (1 + nu));
  const double uni[6] = {5.0e6, 0, 0, 0, 0, 0}, shear[6] = {0, 0, 0, 3.0e6, 0, 0};
  EXPECT_NEAR(strain_energy_density(uni, lambda, mu), 25e12 / (2 * E), 1e-12 * 25e12 / E);
  EXPECT_NEAR(strain_energy_density(shear, lambda, mu), 9e12 / (2 * mu), 1e-12 * 9e12 / mu);
  const double s[6] = {3e6, -1e6, 2e6, 0.5e6, -0.7e6, 1.1e6};  // xx yy zz xy yz xz
  const double S[3][3] = {{s[0], s[3], s[5]}, {s[3], s[1], s[4]}, {s[5], s[4], s[2]}};
  const double tr = s[0] + s[1] + s[2];
  double W = 0;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      const double eps = ((1 + nu) * S[i][j] - (i == j ? nu * tr : 0.0)) / E;
      W += 0.5 * S[i][j] * eps;
    }
  EXPECT_NEAR(strain_energy_density(s, lambda, mu), W, 1e-12 * W);
  // Rotated by 90 degrees about z: x -> y, y -> -x.
  const double r[6] = {s[1], s[0], s[2], -s[3], s[5], -s[4]};
  EXPECT_NEAR(strain_energy_density(r, lambda, mu), W, 1e-12 * W);
}

}  // namespace
}  // namespace hexcut::element
