#include <gtest/gtest.h>

#include <cmath>

#include "element/element.hpp"
#include "test_util.hpp"

namespace hexcut::element {
namespace {

using test::Mat3;

Mat3 polar(const Mat3& F) {
  Mat3 R;
  polar_rotation(F.data(), R.data());
  return R;
}

void expect_proper_rotation(const Mat3& R, double tol = 1e-13) {
  EXPECT_LT((R * R.transpose() - Mat3::Identity()).cwiseAbs().maxCoeff(), tol);
  EXPECT_NEAR(R.determinant(), 1.0, tol);
}

Mat3 random_spd(std::mt19937_64& rng, double lo, double hi) {
  std::uniform_real_distribution<double> U(lo, hi);
  const Mat3 Q = test::random_rotation(rng);
  return Q * Eigen::Vector3d(U(rng), U(rng), U(rng)).asDiagonal() * Q.transpose();
}

TEST(ElementPolar, RecoversRandomRotations) {
  std::mt19937_64 rng(1);
  for (int t = 0; t < 200; ++t) {
    const Mat3 Q = test::random_rotation(rng);
    EXPECT_LT((polar(Q) - Q).cwiseAbs().maxCoeff(), 1e-12);
    // F = Q S with S symmetric positive definite: the rotation factor is Q.
    const Mat3 F = Q * random_spd(rng, 0.2, 3.0);
    EXPECT_LT((polar(F) - Q).cwiseAbs().maxCoeff(), 1e-12);
  }
  // The exact 90 degree rotation used by the corotation tests.
  const Mat3 Rz = test::rotation_z(M_PI / 2);
  EXPECT_LT((polar(Rz) - Rz).cwiseAbs().maxCoeff(), 1e-15);
}

TEST(ElementPolar, PureStretchGivesIdentity) {
  std::mt19937_64 rng(2);
  for (int t = 0; t < 50; ++t) {
    EXPECT_LT((polar(random_spd(rng, 0.1, 5.0)) - Mat3::Identity()).cwiseAbs().maxCoeff(), 1e-12);
  }
  const Mat3 D = Eigen::Vector3d(2.0, 0.5, 1.0).asDiagonal();
  EXPECT_LT((polar(D) - Mat3::Identity()).cwiseAbs().maxCoeff(), 1e-15);
}

TEST(ElementPolar, ProperRotationForRandomAndInvertedF) {
  std::mt19937_64 rng(3);
  std::normal_distribution<double> n(0.0, 1.0);
  int inverted = 0;
  for (int t = 0; t < 500; ++t) {
    Mat3 F;
    for (int k = 0; k < 9; ++k) F.data()[k] = n(rng);
    if (F.determinant() < 0) ++inverted;
    const Mat3 R = polar(F);
    expect_proper_rotation(R);
    // R^T F is symmetric; if F is inverted, exactly its smallest-magnitude eigenvalue is
    // negative (the flipped singular direction), otherwise all are positive.
    const Mat3 S = R.transpose() * F;
    EXPECT_LT((S - S.transpose()).cwiseAbs().maxCoeff(), 1e-12 * F.norm());
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(0.5 * (S + S.transpose()));
    const Eigen::Vector3d ev = eig.eigenvalues();
    int negatives = 0;
    double min_abs = 1e300, neg_abs = 0;
    for (int i = 0; i < 3; ++i) {
      min_abs = std::min(min_abs, std::abs(ev(i)));
      if (ev(i) < 0) {
        ++negatives;
        neg_abs = -ev(i);
      }
    }
    EXPECT_EQ(negatives, F.determinant() < 0 ? 1 : 0);
    if (negatives == 1) {
      EXPECT_DOUBLE_EQ(neg_abs, min_abs);
    }
  }
  EXPECT_GT(inverted, 100);  // the sample really covered inverted cells
}

TEST(ElementPolar, InvertedCellFlipsSmallestDirection) {
  // A cell pushed through itself along z (thinnest direction): no rotation happened.
  const Mat3 F1 = Eigen::Vector3d(1.0, 1.2, -0.5).asDiagonal();
  EXPECT_LT((polar(F1) - Mat3::Identity()).cwiseAbs().maxCoeff(), 1e-15);
  // Same, rotated by Q: the rotation factor is Q.
  std::mt19937_64 rng(4);
  const Mat3 Q = test::random_rotation(rng);
  EXPECT_LT((polar(Q * F1) - Q).cwiseAbs().maxCoeff(), 1e-12);
  // Inversion along x, where x is the smallest stretch.
  const Mat3 F2 = Eigen::Vector3d(-0.1, 2.0, 3.0).asDiagonal();
  EXPECT_LT((polar(Q * F2) - Q).cwiseAbs().maxCoeff(), 1e-12);
  // Point reflection: all singular values equal, any answer must still be a rotation.
  expect_proper_rotation(polar(-Mat3::Identity()));
}

TEST(ElementPolar, DegenerateF) {
  EXPECT_EQ(polar(Mat3::Zero()), Mat3::Identity());
  Mat3 nan_f = Mat3::Identity();
  nan_f(1, 2) = std::nan("");
  EXPECT_EQ(polar(nan_f), Mat3::Identity());
  // Tiny and huge scales do not matter.
  std::mt19937_64 rng(5);
  const Mat3 Q = test::random_rotation(rng);
  EXPECT_LT((polar(1e-200 * Q) - Q).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_LT((polar(1e200 * Q) - Q).cwiseAbs().maxCoeff(), 1e-12);
  // Cell flattened onto a plane (rank 2) and onto a line (rank 1): still proper rotations,
  // and for the plane the in-plane rotation is recovered.
  const Mat3 flat = Q * Eigen::Vector3d(1.5, 0.7, 0.0).asDiagonal();
  const Mat3 Rf = polar(flat);
  expect_proper_rotation(Rf);
  EXPECT_LT((Rf - Q).cwiseAbs().maxCoeff(), 1e-12);
  expect_proper_rotation(polar(Q * Eigen::Vector3d(0.0, 2.0, 0.0).asDiagonal()));
}

TEST(ElementPolar, FromCornerDisplacements) {
  // u = (Q - I) X at the corners gives F = Q at the centre, whatever the cell position.
  std::mt19937_64 rng(6);
  const Mat3 Q = test::random_rotation(rng);
  test::Vec24 x;
  const double origin[3] = {10.0, -4.0, 2.0};
  corner_positions(0.25, origin, x.data());
  const test::Vec24 u = test::affine_field(Q - Mat3::Identity(), Eigen::Vector3d(1, 2, 3), x);
  Mat3 F;
  deformation_gradient_at_centre(u.data(), 0.25, F.data());
  EXPECT_LT((F - Q).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_LT((polar(F) - Q).cwiseAbs().maxCoeff(), 1e-12);
}

}  // namespace
}  // namespace hexcut::element
