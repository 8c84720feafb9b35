// The mid-point corotational cell force (doc/theory.md "Mid-point corotational step"):
// no resultant and no moment about the mid-point configuration, no work in a rigid step,
// a discrete energy balance to second order in the step's rotation, the linear force for
// small displacements, and the gradient of the corotational strain energy as the step
// shrinks.
#include <gtest/gtest.h>

#include <cmath>

#include "element/element.hpp"
#include "test_util.hpp"

namespace hexcut::element {
namespace {

using test::Mat24;
using test::Mat3;
using test::Vec24;

using test::cell_K;
using test::kH;

Vec24 corners() {
  Vec24 x;
  corner_positions(kH, nullptr, x.data());
  return x;
}

// Displacement that rotates the cell by R about corner 0 on top of the deformation e
// (corner displacements of the unrotated cell): x + u = R (x + e).
Vec24 rotated(const Mat3& R, const Vec24& e) {
  const Vec24 x = corners();
  Vec24 u;
  for (int q = 0; q < 8; ++q)
    u.segment<3>(3 * q) = R * (x.segment<3>(3 * q) + e.segment<3>(3 * q)) - x.segment<3>(3 * q);
  return u;
}

Vec24 random_vector(std::mt19937_64& rng, double scale) {
  std::uniform_real_distribution<double> U(-scale, scale);
  Vec24 v;
  for (int k = 0; k < 24; ++k) v[k] = U(rng);
  return v;
}

// Strain energy 1/2 d^T K d with R the polar rotation of u.
double energy(const Mat24& K, const Vec24& u) {
  double F[9], R[9];
  Vec24 d;
  deformation_gradient_at_centre(u.data(), kH, F);
  polar_rotation(F, R);
  corotated_displacement(R, corners().data(), u.data(), d.data());
  return 0.5 * d.dot(K * d);
}

struct Result {
  Vec24 f;
  MidpointForce info;
};

Result force(const Mat24& K, const Vec24& u0, const Vec24& u1) {
  Result r;
  Vec24 d0;
  current_corotated_displacement(kH, corners().data(), u0.data(), d0.data());
  r.info =
      midpoint_force(K.data(), kH, corners().data(), d0.data(), u0.data(), u1.data(), r.f.data());
  return r;
}

Eigen::Vector3d moment_about_midpoint(const Vec24& f, const Vec24& u0, const Vec24& u1) {
  const Vec24 x = corners() + 0.5 * (u0 + u1);
  Eigen::Vector3d m = Eigen::Vector3d::Zero();
  for (int q = 0; q < 8; ++q)
    m += Eigen::Vector3d(x.segment<3>(3 * q)).cross(Eigen::Vector3d(f.segment<3>(3 * q)));
  return m;
}

TEST(Midpoint, NoResultantNoMoment) {
  std::mt19937_64 rng(5);
  const Mat24 K = cell_K();
  for (int trial = 0; trial < 50; ++trial) {
    // Large rotations (random), strains of a few per cent, steps of any size.
    const Vec24 u0 = rotated(test::random_rotation(rng), random_vector(rng, 0.02 * kH));
    const Vec24 u1 = rotated(test::random_rotation(rng), random_vector(rng, 0.02 * kH));
    const auto r = force(K, u0, u1);
    EXPECT_NEAR(r.info.energy0, energy(K, u0), 1e-13 * energy(K, u0));
    EXPECT_NEAR(r.info.energy1, energy(K, u1), 1e-13 * energy(K, u1));
    Eigen::Vector3d resultant = Eigen::Vector3d::Zero();
    for (int q = 0; q < 8; ++q) resultant += r.f.segment<3>(3 * q);
    EXPECT_LT(resultant.norm(), 1e-13 * r.f.norm());
    EXPECT_LT(moment_about_midpoint(r.f, u0, u1).norm(), 1e-13 * r.f.norm() * kH);
  }
}

// f . (u1 - u0) = W1 - W0 up to a defect of second order in the step's rotation theta
// (the straight-line mid-point of a rotated cell is shrunk by cos(theta/2)) times the
// change of d, plus third-order terms in the change of d: |defect| / |f||d1 - d0| is
// about theta^2/8 and falls by 100 when theta falls by 10.
TEST(Midpoint, EnergyBalanceToSecondOrderInTheStepRotation) {
  std::mt19937_64 rng(8);
  const Mat24 K = cell_K();
  double previous = 0;
  for (double theta : {0.2, 0.02}) {
    double worst = 0;
    for (int trial = 0; trial < 20; ++trial) {
      const Mat3 R0 = test::random_rotation(rng);
      const Vec24 e0 = random_vector(rng, 0.02 * kH), de = random_vector(rng, 1e-4 * kH);
      const Eigen::Vector3d axis = Eigen::Vector3d::Random().normalized();
      const Mat3 step = Eigen::AngleAxisd(theta, axis).toRotationMatrix();
      const Vec24 u0 = rotated(R0, e0), u1 = rotated(step * R0, e0 + de);
      const auto r = force(K, u0, u1);
      const double defect = r.f.dot(u1 - u0) - (r.info.energy1 - r.info.energy0);
      worst = std::max(worst, std::abs(defect) / (r.f.norm() * de.norm()));
    }
    std::printf("step rotation %.2f: |f . du - dW| / (|f| |dd|) <= %.2e (theta^2/8 = %.2e)\n",
                theta, worst, theta * theta / 8);
    EXPECT_LT(worst, theta * theta / 4);
    if (previous > 0) {
      EXPECT_LT(worst, previous / 30);
    }
    previous = worst;
  }
}

// Small displacements: R ~ I and f -> K (u0 + u1)/2, the linear (trapezoidal) force.
TEST(Midpoint, SmallDisplacementsGiveTheLinearForce) {
  std::mt19937_64 rng(9);
  const Mat24 K = cell_K();
  for (double size : {1e-3, 1e-4}) {
    const Vec24 u0 = random_vector(rng, size * kH), u1 = random_vector(rng, size * kH);
    const auto r = force(K, u0, u1);
    const Vec24 linear = K * (0.5 * (u0 + u1));
    const double err = (r.f - linear).norm() / linear.norm();
    std::printf("displacements %.0e h: |f - K ubar| / |K ubar| = %.2e\n", size, err);
    EXPECT_LT(err, 10 * size);  // first order in the displacement gradient
  }
}

TEST(Midpoint, RigidStepOfADeformedCellDoesNoWork) {
  std::mt19937_64 rng(6);
  const Mat24 K = cell_K();
  const Vec24 e = random_vector(rng, 0.02 * kH);
  const Mat3 R0 = test::random_rotation(rng);
  const Mat3 step = test::rotation_z(0.3);
  const Vec24 u0 = rotated(R0, e), u1 = rotated(step * R0, e);
  const auto r = force(K, u0, u1);
  EXPECT_NEAR(r.info.energy1, r.info.energy0, 1e-13 * r.info.energy0);
  EXPECT_LT(std::abs(r.f.dot(u1 - u0)), 1e-13 * r.f.norm() * (u1 - u0).norm());
  // The force is that of the deformed cell, rotated with it (about as large as K e).
  EXPECT_NEAR(r.f.norm(), (K * e).norm(), 0.05 * (K * e).norm());
}

// As the step shrinks, the force tends to the gradient of W (central differences) up to
// O(strain^2) relative; the plain corotational force R^ K d, which is not a gradient,
// differs from it at O(strain) (the moment of K d about the deformed corners).
TEST(Midpoint, TendsToTheEnergyGradient) {
  std::mt19937_64 rng(7);
  const Mat24 K = cell_K();
  for (double strain : {0.01, 0.05}) {
    const Vec24 u = rotated(test::random_rotation(rng), random_vector(rng, strain * kH));
    Vec24 grad;
    const double eps = 1e-6 * kH;
    for (int k = 0; k < 24; ++k) {
      Vec24 up = u, um = u;
      up[k] += eps;
      um[k] -= eps;
      grad[k] = (energy(K, up) - energy(K, um)) / (2 * eps);
    }
    const Vec24 du = random_vector(rng, 1e-7 * kH);
    const auto r = force(K, u - du, u + du);
    double F[9], R[9];
    Vec24 plain;
    deformation_gradient_at_centre(u.data(), kH, F);
    polar_rotation(F, R);
    element_force(R, K.data(), corners().data(), u.data(), plain.data());
    const double err = (r.f - grad).norm() / grad.norm();
    const double err_plain = (plain - grad).norm() / grad.norm();
    std::printf("strain %.2f: |f - grad W|/|grad W| = %.2e (mid-point), %.2e (R K d)\n", strain,
                err, err_plain);
    EXPECT_LT(err, 0.3 * strain * strain);
    EXPECT_GT(err_plain, 0.05 * strain);
  }
}

}  // namespace
}  // namespace hexcut::element
