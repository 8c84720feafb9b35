// Small helpers shared by the element tests.
#pragma once

#include <Eigen/Dense>
#include <random>

#include "element/element.hpp"

namespace hexcut::element::test {

using Mat24 = Eigen::Matrix<double, 24, 24, Eigen::RowMajor>;
using Vec24 = Eigen::Matrix<double, 24, 1>;
using Mat3 = Eigen::Matrix<double, 3, 3, Eigen::RowMajor>;

/// The test cell of the corotation tests: edge kH (m), Lame parameters kLambda, kMu (Pa).
constexpr double kH = 0.5, kLambda = 3.0, kMu = 1.7;

/// Stiffness matrix of the test cell (24 x 24, row-major).
inline Mat24 cell_K() {
  Mat24 K;
  cell_stiffness(reference_matrices(), kH, kLambda, kMu, K.data());
  return K;
}

inline Eigen::Map<const Mat24> as_mat24(const double* p) {
  return Eigen::Map<const Mat24>(p);
}

/// Uniformly distributed random rotation (normalized Gaussian quaternion).
inline Mat3 random_rotation(std::mt19937_64& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  Eigen::Quaterniond q(n(rng), n(rng), n(rng), n(rng));
  q.normalize();
  return q.toRotationMatrix();
}

/// A 3x3 matrix of independent standard normal entries (det < 0 half of the time).
inline Mat3 random_matrix(std::mt19937_64& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  Mat3 F;
  for (int k = 0; k < 9; ++k) F.data()[k] = n(rng);
  return F;
}

inline Mat3 rotation_z(double angle) {
  return Eigen::AngleAxisd(angle, Eigen::Vector3d::UnitZ()).toRotationMatrix();
}

/// Corner values of the affine map x -> G x + c at the corners of a cell.
inline Vec24 affine_field(const Mat3& G, const Eigen::Vector3d& c, const Vec24& x) {
  Vec24 u;
  for (int q = 0; q < 8; ++q) u.segment<3>(3 * q) = G * x.segment<3>(3 * q) + c;
  return u;
}

}  // namespace hexcut::element::test
