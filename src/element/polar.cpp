#include <Eigen/Dense>
#include <cmath>

#include "element/corotation.hpp"

namespace hexcut::element {

void polar_rotation(const double F[9], double R[9]) {
  const Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>> f(F);
  Eigen::Map<Eigen::Matrix<double, 3, 3, Eigen::RowMajor>> r(R);
  // A zero (fully collapsed) or corrupted F carries no rotation information; identity
  // keeps the cell's operator the linear one instead of propagating NaNs into the solve.
  // Max-abs rather than norm(): squaring would underflow/overflow for |F| ~ 1e-200 / 1e200.
  const double scale = f.cwiseAbs().maxCoeff();
  if (!f.allFinite() || !(scale > 1e-300)) {
    r.setIdentity();
    return;
  }
  // Scale first so that tiny or huge F do not under/overflow inside the SVD; the rotation
  // factor is invariant under positive scaling.
  const Eigen::Matrix3d fs = f / scale;
  // JacobiSVD on a fixed 3x3 is accurate to round-off even for nearly singular F, which the
  // (faster) normal-equations eigen approach is not.
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(fs, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d u = svd.matrixU();
  const Eigen::Matrix3d& v = svd.matrixV();
  // Singular values come sorted descending, so column 2 belongs to the smallest one.
  // Flipping it (rather than any other) gives the proper rotation closest to F, and leaves
  // R^T F symmetric with the inversion carried by its smallest eigenvalue.
  if (u.determinant() * v.determinant() < 0.0) u.col(2) = -u.col(2);
  r = u * v.transpose();
}

}  // namespace hexcut::element
