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
using test::kLambda;
using test::kMu;

Mat24 block_diag(const Mat3& R) {
  Mat24 Rh = Mat24::Zero();
  for (int q = 0; q < 8; ++q) Rh.block<3, 3>(3 * q, 3 * q) = R;
  return Rh;
}

Vec24 cell_corners(const double* origin) {
  Vec24 x;
  corner_positions(kH, origin, x.data());
  return x;
}

// Rotation of the cell from its displacement, as the per-step pipeline does it.
Mat3 rotation_of(const Vec24& u) {
  Mat3 F, R;
  deformation_gradient_at_centre(u.data(), kH, F.data());
  polar_rotation(F.data(), R.data());
  return R;
}

TEST(ElementCorotation, RotateElementMatrixMatchesDenseProduct) {
  std::mt19937_64 rng(11);
  const Mat3 R = test::random_rotation(rng);
  const Mat24 K = cell_K();
  Mat24 out;
  rotate_element_matrix(R.data(), K.data(), out.data());
  const Mat24 expect = block_diag(R) * K * block_diag(R).transpose();
  EXPECT_LT((out - expect).cwiseAbs().maxCoeff(), 1e-14 * K.cwiseAbs().maxCoeff());
  // In place works too.
  Mat24 inplace = K;
  rotate_element_matrix(R.data(), inplace.data(), inplace.data());
  EXPECT_EQ(inplace, out);
}

TEST(ElementCorotation, RhsAndForceMatchDenseFormulas) {
  std::mt19937_64 rng(12);
  std::uniform_real_distribution<double> U(-0.1, 0.1);
  const Mat3 R = test::random_rotation(rng);
  const Mat24 K = cell_K();
  const Mat24 Rh = block_diag(R);
  const double origin[3] = {1.0, 2.0, 3.0};
  const Vec24 x = cell_corners(origin);
  Vec24 u;
  for (int k = 0; k < 24; ++k) u(k) = U(rng);

  Vec24 b, f;
  corotational_rhs(R.data(), K.data(), x.data(), b.data());
  element_force(R.data(), K.data(), x.data(), u.data(), f.data());
  const Vec24 b_expect = -Rh * K * (Rh.transpose() * x - x);
  const Vec24 f_expect = Rh * K * (Rh.transpose() * (x + u) - x);
  const double scale = K.cwiseAbs().maxCoeff() * x.cwiseAbs().maxCoeff();
  EXPECT_LT((b - b_expect).cwiseAbs().maxCoeff(), 1e-14 * scale);
  EXPECT_LT((f - f_expect).cwiseAbs().maxCoeff(), 1e-14 * scale);
  // The force is the system's A_e u - b_e.
  Mat24 A;
  rotate_element_matrix(R.data(), K.data(), A.data());
  EXPECT_LT((A * u - b - f).cwiseAbs().maxCoeff(), 1e-14 * scale);
  // A translation of the reference frame changes nothing.
  const Vec24 x_local = cell_corners(nullptr);
  Vec24 b_local, f_local;
  corotational_rhs(R.data(), K.data(), x_local.data(), b_local.data());
  element_force(R.data(), K.data(), x_local.data(), u.data(), f_local.data());
  EXPECT_LT((b_local - b).cwiseAbs().maxCoeff(), 1e-14 * scale);
  EXPECT_LT((f_local - f).cwiseAbs().maxCoeff(), 1e-14 * scale);
}

// Rigid motion x -> Q x + c of a cell: zero force and zero stress.
void check_rigid_motion(const Mat3& Q, const Eigen::Vector3d& c, const double* origin) {
  const Mat24 K = cell_K();
  const Vec24 x = cell_corners(origin);
  const Vec24 u = test::affine_field(Q - Mat3::Identity(), c, x);
  const Mat3 R = rotation_of(u);
  EXPECT_LT((R - Q).cwiseAbs().maxCoeff(), 1e-12);
  Vec24 f;
  element_force(R.data(), K.data(), x.data(), u.data(), f.data());
  // Relative to |K| h (the force of a unit-strain deformation).
  EXPECT_LT(f.cwiseAbs().maxCoeff(), 1e-10 * K.cwiseAbs().maxCoeff() * kH);
  const CellStress s = recover_stress(u.data(), x.data(), R.data(), kH, kLambda, kMu);
  for (double v : s.sigma) EXPECT_LT(std::abs(v), 1e-10 * kMu);
  EXPECT_LT(s.von_mises, 1e-10 * kMu);
  // The linear (unrotated) operator would see a large spurious force instead.
  Vec24 f_lin;
  const Mat3 I = Mat3::Identity();
  element_force(I.data(), K.data(), x.data(), u.data(), f_lin.data());
  EXPECT_GT(f_lin.cwiseAbs().maxCoeff(), 0.1 * K.cwiseAbs().maxCoeff() * kH);
}

TEST(ElementCorotation, RigidRotation90AboutZ) {
  const double origin[3] = {2.0, -1.0, 4.0};
  check_rigid_motion(test::rotation_z(M_PI / 2), Eigen::Vector3d::Zero(), origin);
  check_rigid_motion(test::rotation_z(M_PI / 2), Eigen::Vector3d(0.3, -0.2, 5.0), nullptr);
}

TEST(ElementCorotation, RandomRigidRotations) {
  std::mt19937_64 rng(13);
  std::uniform_real_distribution<double> U(-5.0, 5.0);
  for (int t = 0; t < 20; ++t) {
    const double origin[3] = {U(rng), U(rng), U(rng)};
    check_rigid_motion(test::random_rotation(rng), Eigen::Vector3d(U(rng), U(rng), U(rng)), origin);
  }
}

TEST(ElementCorotation, RotatedUniaxialStretchGivesRotatedStress) {
  std::mt19937_64 rng(14);
  const double eps0 = 1e-3;
  const Mat3 S = Eigen::Vector3d(1.0 + eps0, 1.0, 1.0).asDiagonal();
  // Unrotated stress of uniaxial strain eps0 along x.
  const Mat3 sigma_loc = Eigen::Vector3d(kLambda + 2 * kMu, kLambda, kLambda).asDiagonal() * eps0;
  for (int t = 0; t < 10; ++t) {
    const Mat3 Q = t == 0 ? Mat3(test::rotation_z(M_PI / 2)) : test::random_rotation(rng);
    const double origin[3] = {1.0, 1.0, -2.0};
    const Vec24 x = cell_corners(origin);
    const Vec24 u = test::affine_field(Q * S - Mat3::Identity(), Eigen::Vector3d(0.1, 0, 0), x);
    const Mat3 R = rotation_of(u);
    EXPECT_LT((R - Q).cwiseAbs().maxCoeff(), 1e-12);
    const CellStress s = recover_stress(u.data(), x.data(), R.data(), kH, kLambda, kMu);
    const Mat3 expect = Q * sigma_loc * Q.transpose();
    const double got[9] = {s.sigma[0], s.sigma[3], s.sigma[5], s.sigma[3], s.sigma[1],
                           s.sigma[4], s.sigma[5], s.sigma[4], s.sigma[2]};
    for (int k = 0; k < 9; ++k) EXPECT_NEAR(got[k], expect.data()[k], 1e-12) << k;
    // The stress is frame-indifferent: principal values do not depend on Q.
    EXPECT_NEAR(s.principal[0], (kLambda + 2 * kMu) * eps0, 1e-12);
    EXPECT_NEAR(s.principal[1], kLambda * eps0, 1e-12);
    EXPECT_NEAR(s.principal[2], kLambda * eps0, 1e-12);
    // Its tensile direction is the rotated x axis (up to sign).
    const Eigen::Vector3d d0(s.directions[0], s.directions[1], s.directions[2]);
    EXPECT_NEAR(std::abs(d0.dot(Q.col(0))), 1.0, 1e-9);
  }
}

}  // namespace
}  // namespace hexcut::element
