// polar_rotation (one-sided Jacobi SVD on plain arrays, element/polar.hpp) against the
// Eigen JacobiSVD version it replaced, kept here as the reference.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <limits>
#include <random>

#include "element/polar.hpp"
#include "test_util.hpp"

namespace hexcut::element {
namespace {

using test::Mat3;

/// The former polar_rotation (src/element/polar.cpp up to this change).
Mat3 polar_eigen(const Mat3& f) {
  const double scale = f.cwiseAbs().maxCoeff();
  if (!f.allFinite() || !(scale > 1e-300)) return Mat3::Identity();
  const Eigen::Matrix3d fs = f / scale;
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(fs, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d u = svd.matrixU();
  const Eigen::Matrix3d& v = svd.matrixV();
  if (u.determinant() * v.determinant() < 0.0) u.col(2) = -u.col(2);
  return u * v.transpose();
}

Mat3 polar(const Mat3& F) {
  Mat3 R;
  polar_rotation(F.data(), R.data());
  return R;
}

double max_abs(const Mat3& M) { return M.cwiseAbs().maxCoeff(); }

void expect_proper_rotation(const Mat3& R) {
  EXPECT_LT(max_abs(R * R.transpose() - Mat3::Identity()), 1e-14);
  EXPECT_NEAR(R.determinant(), 1.0, 1e-14);
}

/// The rotation factor is determined by F to within a few eps / gap, the gap being
/// sigma2 + sigma3 for det F > 0 and sigma2 - sigma3 for det F < 0 (relative to sigma1).
double rotation_tolerance(const Mat3& F) {
  const Eigen::Vector3d s = Eigen::JacobiSVD<Eigen::Matrix3d>(F).singularValues();
  const double gap = (F.determinant() < 0 ? s(1) - s(2) : s(1) + s(2)) / s(0);
  return std::max(1e-13, 1e-14 / gap);
}

Mat3 diag(double a, double b, double c) { return Eigen::Vector3d(a, b, c).asDiagonal(); }

TEST(ElementPolarJacobi, MatchesEigenOnRandomF) {
  std::mt19937_64 rng(11);
  int inverted = 0;
  for (int t = 0; t < 2000; ++t) {
    const Mat3 F = test::random_matrix(rng);
    inverted += F.determinant() < 0;
    const Mat3 R = polar(F);
    expect_proper_rotation(R);
    EXPECT_LT(max_abs(R - polar_eigen(F)), rotation_tolerance(F)) << F;
  }
  EXPECT_GT(inverted, 500);
}

TEST(ElementPolarJacobi, RotationsAndStretchedRotations) {
  std::mt19937_64 rng(12);
  std::uniform_real_distribution<double> U(0.2, 3.0);
  for (int t = 0; t < 500; ++t) {
    const Mat3 Q = test::random_rotation(rng), P = test::random_rotation(rng);
    EXPECT_LT(max_abs(polar(Q) - Q), 1e-14);
    // F = Q P diag P^T: symmetric positive stretch, rotation factor Q.
    const Mat3 F = Q * P * diag(U(rng), U(rng), U(rng)) * P.transpose();
    const Mat3 R = polar(F);
    EXPECT_LT(max_abs(R - Q), 1e-13);
    EXPECT_LT(max_abs(R - polar_eigen(F)), 1e-13);
  }
}

TEST(ElementPolarJacobi, NearlySingularAndInverted) {
  // F = Q diag(1.7, 0.3, +-s3) P^T: the rotation factor is Q P^T for either sign (for
  // det F < 0 the flip of the smallest singular direction undoes the sign), down to
  // rank 2 (s3 = 0).
  std::mt19937_64 rng(13);
  for (double s3 : {1e-3, 1e-6, 1e-10, 1e-14, 1e-18, 0.0}) {
    for (double sign : {1.0, -1.0}) {
      for (int t = 0; t < 50; ++t) {
        const Mat3 Q = test::random_rotation(rng), P = test::random_rotation(rng);
        const Mat3 F = Q * diag(1.7, 0.3, sign * s3) * P.transpose();
        const Mat3 R = polar(F);
        expect_proper_rotation(R);
        EXPECT_LT(max_abs(R - Q * P.transpose()), 1e-13) << "s3 " << sign * s3;
        EXPECT_LT(max_abs(R - polar_eigen(F)), 1e-13) << "s3 " << sign * s3;
      }
    }
  }
}

TEST(ElementPolarJacobi, ExactRankTwoAndOne) {
  // Rank 2 in exact arithmetic (integer rows, third = 2 * second - first): R is unique.
  Mat3 F2;
  F2 << 1, 2, 3, 4, 5, 6, 7, 8, 9;
  expect_proper_rotation(polar(F2));
  EXPECT_LT(max_abs(polar(F2) - polar_eigen(F2)), 1e-13);
  Mat3 flat = diag(1.5, 0.7, 0.0);  // cell flattened onto a plane
  EXPECT_LT(max_abs(polar(flat) - Mat3::Identity()), 1e-15);
  // Rank 1: only the rotation of the one stretched direction is determined, R y = x
  // for F = x y^T; the rest must still be a proper rotation.
  std::mt19937_64 rng(14);
  std::normal_distribution<double> n(0.0, 1.0);
  for (int t = 0; t < 200; ++t) {
    Eigen::Vector3d x(n(rng), n(rng), n(rng)), y(n(rng), n(rng), n(rng));
    if (t == 0) x << 1, 2, 3, y << 4, 5, 6;  // exactly representable
    if (t == 1) x << 0, 0, 2, y << 0, 3, 0;  // axis-aligned (a1 exactly zero)
    const Mat3 F = x * y.transpose();
    const Mat3 R = polar(F);
    expect_proper_rotation(R);
    EXPECT_LT((R * y.normalized() - x.normalized()).cwiseAbs().maxCoeff(), 1e-13);
  }
}

TEST(ElementPolarJacobi, ScaleInvariance) {
  std::mt19937_64 rng(15);
  for (int t = 0; t < 100; ++t) {
    const Mat3 F = test::random_matrix(rng);
    const Mat3 R = polar(F);
    for (double s : {1e-200, 1e-300 * 4.0, 1e200, 1e300}) {
      const Mat3 Rs = polar(s * F);
      EXPECT_LT(max_abs(Rs - R), rotation_tolerance(F)) << s;
      EXPECT_LT(max_abs(Rs - polar_eigen(s * F)), rotation_tolerance(F)) << s;
    }
  }
}

TEST(ElementPolarJacobi, DegenerateFGivesIdentity) {
  const double inf = std::numeric_limits<double>::infinity();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (double bad : {nan, inf, -inf}) {
    for (int k = 0; k < 9; ++k) {
      Mat3 F = 2.0 * Mat3::Identity();
      F.data()[k] = bad;
      EXPECT_EQ(polar(F), Mat3::Identity());
      EXPECT_EQ(polar_eigen(F), Mat3::Identity());
    }
  }
  EXPECT_EQ(polar(Mat3::Zero()), Mat3::Identity());
  // At or below 1e-300 in every entry F counts as zero (both versions).
  const Mat3 tiny = 1e-300 * test::rotation_z(0.3);
  EXPECT_EQ(polar(tiny), Mat3::Identity());
  EXPECT_EQ(polar_eigen(tiny), Mat3::Identity());
  const Mat3 denormal = 1e-310 * Mat3::Identity();
  EXPECT_EQ(polar(denormal), Mat3::Identity());
}

}  // namespace
}  // namespace hexcut::element
