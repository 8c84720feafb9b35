#include <Eigen/Dense>
#include <algorithm>

#include "element/corotation.hpp"
#include "element/kinematics.hpp"

namespace hexcut::element {
namespace {

using Vec3 = Eigen::Vector3d;

Vec3 corner(const double* v24, int q) {
  return Vec3(v24[3 * q], v24[3 * q + 1], v24[3 * q + 2]);
}

double dot24(const double* a, const double* b) {
  double s = 0.0;
  for (int k = 0; k < kElementDofs; ++k) s += a[k] * b[k];
  return s;
}

}  // namespace

void remove_moment(int n, const double* z, double* f) {
  // Subtract the infinitesimal rotation theta x z (centroid-relative) with J theta = moment,
  // J = sum (|z|^2 I - z z^T), which has the same moment and no resultant.
  Vec3 c = Vec3::Zero();
  for (int q = 0; q < n; ++q) c += corner(z, q) / n;
  Vec3 moment = Vec3::Zero();
  Eigen::Matrix3d J = Eigen::Matrix3d::Zero();
  for (int q = 0; q < n; ++q) {
    const Vec3 zq = corner(z, q) - c;
    moment += zq.cross(corner(f, q));
    J += zq.squaredNorm() * Eigen::Matrix3d::Identity() - zq * zq.transpose();
  }
  // Points on a line have a singular J; they keep their (tiny) moment.
  const Eigen::LDLT<Eigen::Matrix3d> ldlt(J);
  if (ldlt.info() != Eigen::Success || !(ldlt.vectorD().minCoeff() > 1e-12 * J.trace())) return;
  const Vec3 theta = ldlt.solve(moment);
  for (int q = 0; q < n; ++q) {
    const Vec3 t = theta.cross(corner(z, q) - c);
    for (int i = 0; i < 3; ++i) f[3 * q + i] -= t[i];
  }
}

MidpointForce midpoint_force(const double* K, double h, const double* x24, const double* d0,
                             const double* u0, const double* u1, double* f24, const double* R1,
                             const double* Rm, bool remove_moment_here) {
  MidpointForce out;
  double um[kElementDofs], F[9], d1[kElementDofs];
  for (int k = 0; k < kElementDofs; ++k) um[k] = 0.5 * (u0[k] + u1[k]);
  if (R1)
    corotated_displacement(R1, x24, u1, d1);
  else
    current_corotated_displacement(h, x24, u1, d1);
  if (Rm) {
    std::copy(Rm, Rm + 9, out.rotation);
  } else {
    deformation_gradient_at_centre(um, h, F);
    polar_rotation(F, out.rotation);
  }
  double Kd0[kElementDofs], Kd1[kElementDofs];
  element_matvec(K, d0, Kd0);
  element_matvec(K, d1, Kd1);
  out.energy0 = 0.5 * dot24(d0, Kd0);
  out.energy1 = 0.5 * dot24(d1, Kd1);
  for (int k = 0; k < kElementDofs; ++k) Kd0[k] = 0.5 * (Kd0[k] + Kd1[k]);  // K dbar
  rotate_blocks(out.rotation, Kd0, f24);

  if (!remove_moment_here) return out;
  // Remove the moment of R_m K dbar about the mid-point corners z.
  double z[kElementDofs];
  for (int q = 0; q < kCorners; ++q)
    for (int i = 0; i < 3; ++i) z[3 * q + i] = x24[3 * q + i] - x24[i] + um[3 * q + i];
  remove_moment(kCorners, z, f24);
  return out;
}

}  // namespace hexcut::element
