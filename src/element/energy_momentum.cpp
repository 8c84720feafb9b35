#include <Eigen/Dense>
#include <cmath>

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

/// Infinitesimal rotation theta that best carries the moment m of forces about the
/// centroid of the points z (centroid-relative): J theta = m, J = sum(|z|^2 I - z z^T).
/// A degenerate cell (all corners on a line) has a singular J; it gets theta = 0.
Vec3 rotation_for_moment(const Vec3 z[kCorners], const Vec3& m) {
  Eigen::Matrix3d J = Eigen::Matrix3d::Zero();
  for (int q = 0; q < kCorners; ++q)
    J += z[q].squaredNorm() * Eigen::Matrix3d::Identity() - z[q] * z[q].transpose();
  const Eigen::LDLT<Eigen::Matrix3d> ldlt(J);
  if (ldlt.info() != Eigen::Success || !(ldlt.vectorD().minCoeff() > 1e-12 * J.trace()))
    return Vec3::Zero();
  return ldlt.solve(m);
}

}  // namespace

ConservingForce conserving_force(const double* K, double h, const double* x24, const double* u0,
                                 const double* u1, double* f24) {
  ConservingForce out;
  double um[kElementDofs], F[9], R0[9], R1[9], d0[kElementDofs], d1[kElementDofs];
  for (int k = 0; k < kElementDofs; ++k) um[k] = 0.5 * (u0[k] + u1[k]);
  deformation_gradient_at_centre(u0, h, F);
  polar_rotation(F, R0);
  deformation_gradient_at_centre(u1, h, F);
  polar_rotation(F, R1);
  deformation_gradient_at_centre(um, h, F);
  polar_rotation(F, out.rotation);
  corotated_displacement(R0, x24, u0, d0);
  corotated_displacement(R1, x24, u1, d1);

  // W1 - W0 = (d1 - d0)^T K (d0 + d1)/2 exactly (K symmetric); this form keeps its
  // accuracy when the two energies are close.
  double dbar[kElementDofs], dd[kElementDofs], Kd[kElementDofs];
  for (int k = 0; k < kElementDofs; ++k) {
    dbar[k] = 0.5 * (d0[k] + d1[k]);
    dd[k] = d1[k] - d0[k];
  }
  element_matvec(K, d0, Kd);
  out.energy0 = 0.5 * dot24(d0, Kd);
  element_matvec(K, d1, Kd);
  out.energy1 = 0.5 * dot24(d1, Kd);
  element_matvec(K, dbar, Kd);
  const double dW = dot24(dd, Kd);

  // Mid-point force R_m K dbar, with its moment about the mid-point corners removed.
  rotate_blocks(out.rotation, Kd, f24);
  Vec3 z[kCorners], c = Vec3::Zero();
  for (int q = 0; q < kCorners; ++q) {
    z[q] = corner(x24, q) - corner(x24, 0) + corner(um, q);
    c += z[q] / kCorners;
  }
  Vec3 moment = Vec3::Zero(), turn = Vec3::Zero();
  Vec3 dx[kCorners], shift = Vec3::Zero();
  for (int q = 0; q < kCorners; ++q) {
    z[q] -= c;
    dx[q] = corner(u1, q) - corner(u0, q);
    shift += dx[q] / kCorners;
    moment += z[q].cross(corner(f24, q));
    turn += z[q].cross(dx[q]);
  }
  const Vec3 theta = rotation_for_moment(z, moment);
  const Vec3 omega = rotation_for_moment(z, turn);
  // g: the step with its rigid part (translation + infinitesimal rotation of the mid-point
  // configuration) removed, i.e. its projection onto the deformation modes.
  double g[kElementDofs], step[kElementDofs];
  for (int q = 0; q < kCorners; ++q) {
    const Vec3 fq = corner(f24, q) - theta.cross(z[q]);
    const Vec3 gq = dx[q] - shift - omega.cross(z[q]);
    for (int i = 0; i < 3; ++i) {
      f24[3 * q + i] = fq[i];
      g[3 * q + i] = gq[i];
      step[3 * q + i] = dx[q][i];
    }
  }
  // Discrete-gradient correction along g: afterwards f . (u1 - u0) = W1 - W0 exactly.
  const double gg = dot24(g, g);
  const double defect = dW - dot24(f24, step);
  const double dnorm = std::sqrt(dot24(d0, d0) + dot24(d1, d1));
  out.corrected = gg > 0.0 && std::sqrt(gg) > 1e-12 * dnorm;
  if (out.corrected) {
    const double s = defect / gg;
    for (int k = 0; k < kElementDofs; ++k) f24[k] += s * g[k];
  }
  return out;
}

}  // namespace hexcut::element
