#include <Eigen/Dense>
#include <algorithm>
#include <vector>

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

/// theta with J theta = moment, or false where J is singular (points on a line).
bool moment_rotation(const Eigen::Matrix3d& J, const Vec3& moment, Vec3* theta) {
  const Eigen::LDLT<Eigen::Matrix3d> ldlt(J);
  if (ldlt.info() != Eigen::Success || !(ldlt.vectorD().minCoeff() > 1e-12 * J.trace()))
    return false;
  *theta = ldlt.solve(moment);
  return true;
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
  Vec3 theta;
  if (!moment_rotation(J, moment, &theta)) return;
  for (int q = 0; q < n; ++q) {
    const Vec3 t = theta.cross(corner(z, q) - c);
    for (int i = 0; i < 3; ++i) f[3 * q + i] -= t[i];
  }
}

void remove_moment_interpolated(int n, const double* z, const double* G, double* f) {
  // With z_q - c = sum_a w_qa (z~_a - c) (the weights of a corner sum to 1): the centroid
  // is sum_a m_a z~_a / sum m_a (m_a = sum_b G_ab, the corners' weight on node a), the
  // moment sum_a (z~_a - c) x f~_a, S = sum_q (z_q - c)(z_q - c)^T = sum_ab G_ab (z~_a -
  // c)(z~_b - c)^T, and the restricted correction sum_b G_ab theta x (z~_b - c).
  std::vector<double> m(std::size_t(n), 0.0);
  double total = 0.0;
  Vec3 c = Vec3::Zero();
  for (int a = 0; a < n; ++a) {
    for (int b = 0; b < n; ++b) m[std::size_t(a)] += G[std::size_t(n) * a + b];
    total += m[std::size_t(a)];
    c += m[std::size_t(a)] * corner(z, a);
  }
  if (!(total > 0.0)) return;
  c /= total;
  Vec3 moment = Vec3::Zero();
  Eigen::Matrix3d S = Eigen::Matrix3d::Zero();
  for (int a = 0; a < n; ++a) {
    const Vec3 za = corner(z, a) - c;
    moment += za.cross(corner(f, a));
    for (int b = 0; b < n; ++b)
      S += G[std::size_t(n) * a + b] * za * (corner(z, b) - c).transpose();
  }
  const Eigen::Matrix3d J = S.trace() * Eigen::Matrix3d::Identity() - S;
  Vec3 theta;
  if (!moment_rotation(J, moment, &theta)) return;
  for (int a = 0; a < n; ++a) {
    Vec3 t = Vec3::Zero();
    for (int b = 0; b < n; ++b) t += G[std::size_t(n) * a + b] * theta.cross(corner(z, b) - c);
    for (int i = 0; i < 3; ++i) f[3 * a + i] -= t[i];
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
