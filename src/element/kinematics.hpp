// Material parameters and centre-point kinematics of a Q1 cube (doc/theory.md, "Elements",
// "Corotation"). Symmetric tensors are 6 components in ParaView order (xx, yy, zz, xy, yz, xz) with
// tensor (not engineering) shear components; 3x3 matrices are row-major, M[3*i + j].
#pragma once

#include "element/host_device.hpp"
#include "element/reference.hpp"

namespace hexcut::element {

/// Lame parameters from Young's modulus and Poisson's ratio (nu < 1/2).
HEXCUT_HD inline void lame_from_young(double E, double nu, double* lambda, double* mu) {
  *lambda = E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu));
  *mu = E / (2.0 * (1.0 + nu));
}

/// Displacement gradient at the cell centre, G[3*i + j] = du_i/dX_j. At the centre every
/// trilinear shape function has gradient s_q/(4h), s_q the +-1 sign vector of corner q.
HEXCUT_HD inline void displacement_gradient_at_centre(const double* u24, double h, double G[9]) {
  for (int k = 0; k < 9; ++k) G[k] = 0.0;
  const double c = 0.25 / h;
  for (int q = 0; q < kCorners; ++q) {
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) G[3 * i + j] += c * u24[3 * q + i] * corner_sign(q, j);
    }
  }
}

/// Deformation gradient at the centre, F = I + (1/(4h)) sum_q u_q (x) s_q, row-major
/// F[3*i + j] = dx_i/dX_j.
HEXCUT_HD inline void deformation_gradient_at_centre(const double* u24, double h, double F[9]) {
  displacement_gradient_at_centre(u24, h, F);
  F[0] += 1.0;
  F[4] += 1.0;
  F[8] += 1.0;
}

/// Small strain at the cell centre, tensor components (xx, yy, zz, xy, yz, xz) with
/// eps_xy = 1/2 (du_x/dy + du_y/dx).
HEXCUT_HD inline void strain_at_centre(const double* u24, double h, double eps[6]) {
  double G[9];
  displacement_gradient_at_centre(u24, h, G);
  eps[0] = G[0];
  eps[1] = G[4];
  eps[2] = G[8];
  eps[3] = 0.5 * (G[1] + G[3]);
  eps[4] = 0.5 * (G[5] + G[7]);
  eps[5] = 0.5 * (G[2] + G[6]);
}

/// Isotropic Hooke's law on tensor components: sigma = lambda tr(eps) I + 2 mu eps.
HEXCUT_HD inline void hooke_stress(const double eps[6], double lambda, double mu, double sigma[6]) {
  const double lt = lambda * (eps[0] + eps[1] + eps[2]);
  for (int k = 0; k < 3; ++k) sigma[k] = lt + 2.0 * mu * eps[k];
  for (int k = 3; k < 6; ++k) sigma[k] = 2.0 * mu * eps[k];
}

/// out = R s R^T for a symmetric tensor s in ParaView order. out may alias s.
HEXCUT_HD inline void rotate_tensor(const double R[9], const double s[6], double out[6]) {
  const double S[9] = {s[0], s[3], s[5], s[3], s[1], s[4], s[5], s[4], s[2]};
  double RS[9];
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      RS[3 * i + j] = R[3 * i] * S[j] + R[3 * i + 1] * S[3 + j] + R[3 * i + 2] * S[6 + j];
    }
  }
  // Only the six independent entries of RS R^T are needed.
  const int ii[6] = {0, 1, 2, 0, 1, 0};
  const int jj[6] = {0, 1, 2, 1, 2, 2};
  for (int k = 0; k < 6; ++k) {
    const int i = ii[k], j = jj[k];
    out[k] = RS[3 * i] * R[3 * j] + RS[3 * i + 1] * R[3 * j + 1] + RS[3 * i + 2] * R[3 * j + 2];
  }
}

}  // namespace hexcut::element
