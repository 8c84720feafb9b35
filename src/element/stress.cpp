#include "element/stress.hpp"

#include <Eigen/Dense>
#include <cmath>

#include "element/corotation.hpp"
#include "element/kinematics.hpp"

namespace hexcut::element {

CellStress stress_fields(const double sigma[6]) {
  CellStress out{};
  for (int k = 0; k < 6; ++k) out.sigma[k] = sigma[k];
  out.von_mises = von_mises_stress(sigma);
  out.pressure = pressure(sigma);

  Eigen::Matrix3d s;
  s << sigma[0], sigma[3], sigma[5], sigma[3], sigma[1], sigma[4], sigma[5], sigma[4], sigma[2];
  // compute() (tridiagonal QR) rather than computeDirect(): the closed-form solver loses
  // digits in the directions when two principal stresses nearly coincide, and this runs
  // only at output time, so its cost does not matter.
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(s);
  // Eigen sorts ascending; the output is descending (most tensile first).
  Eigen::Vector3d dir[3];
  for (int i = 0; i < 3; ++i) {
    out.principal[i] = eig.eigenvalues()(2 - i);
    dir[i] = eig.eigenvectors().col(2 - i).normalized();
  }
  // Fix the sign freedom so output fields do not flicker between steps or ranks.
  for (int i = 0; i < 2; ++i) {
    Eigen::Index imax = 0;
    dir[i].cwiseAbs().maxCoeff(&imax);
    if (dir[i](imax) < 0.0) dir[i] = -dir[i];
  }
  // Right-handed frame; for distinct eigenvalues this only fixes the sign of the third
  // vector, for repeated ones any orthonormal completion is an eigenbasis as well.
  dir[2] = dir[0].cross(dir[1]).normalized();
  for (int i = 0; i < 3; ++i) {
    for (int d = 0; d < 3; ++d) out.directions[3 * i + d] = dir[i](d);
  }
  return out;
}

void recover_cell_stress(const double* u24, const double* x24_ref, const double R[9], double h,
                         double lambda, double mu, double sigma[6]) {
  double d[kElementDofs], eps[6];
  corotated_displacement(R, x24_ref, u24, d);
  strain_at_centre(d, h, eps);
  hooke_stress(eps, lambda, mu, sigma);
  rotate_tensor(R, sigma, sigma);
}

CellStress recover_stress(const double* u24, const double* x24_ref, const double R[9], double h,
                          double lambda, double mu) {
  double sig[6];
  recover_cell_stress(u24, x24_ref, R, h, lambda, mu, sig);
  return stress_fields(sig);
}

}  // namespace hexcut::element
