// Reference matrices of the trilinear (Q1) hexahedron on a cube (doc/theory.md, "Elements").
//
// Conventions shared by every stage:
//  - corner q = a + 2b + 4c for local offsets (a,b,c) in {0,1}^3 (x fastest); corner q
//    sits at h*(a,b,c) relative to the cell's minimum corner;
//  - element DOF index = 3*q + component (x,y,z interleaved), 24 DOFs per cell;
//  - 24x24 matrices are dense, row-major doubles (entry (i,j) at [24*i + j]).
#pragma once

#include "element/host_device.hpp"

namespace hexcut::element {

constexpr int kCorners = 8;
constexpr int kElementDofs = 24;
constexpr int kElementMatrixSize = kElementDofs * kElementDofs;  // 576

/// Matrices of the unit cube (h = 1), integrated with 2x2x2 Gauss points, which is exact
/// for the undistorted brick.
///  - k_lambda: from the energy 1/2*lambda*tr(eps)^2, i.e. 1/2 u^T (lambda*k_lambda) u;
///  - k_mu:     from the energy mu*eps:eps,          i.e. 1/2 u^T (mu*k_mu) u;
///  - mass:     consistent mass for rho = 1 (each displacement component separately;
///              the entries of one component sum to 1, the cell's mass).
/// A cell of edge h with Lame parameters (lambda, mu) and density rho has stiffness
/// h*(lambda*k_lambda + mu*k_mu) (stiffness scales with h: B ~ 1/h, volume ~ h^3), and mass
/// rho*h^3*mass (consistent) or rho*h^3/8 per corner (lumped). Keeping lambda and mu apart
/// lets every cell have its own Poisson ratio, not just its own Young's modulus.
struct ReferenceMatrices {
  double k_lambda[kElementMatrixSize];
  double k_mu[kElementMatrixSize];
  double mass[kElementMatrixSize];
};

/// The reference matrices, computed on first use (thread-safe) and then shared.
const ReferenceMatrices& reference_matrices();

/// Sign of corner q along axis d: -1 on the cell's low face, +1 on its high face.
HEXCUT_HD inline double corner_sign(int q, int d) {
  return ((q >> d) & 1) ? 1.0 : -1.0;
}

/// Reference corner positions h*(a,b,c) of a cell whose minimum corner is `origin`
/// (pass nullptr for the cell-local frame), as a 24-vector.
HEXCUT_HD inline void corner_positions(double h, const double* origin, double* x24) {
  for (int q = 0; q < kCorners; ++q) {
    for (int d = 0; d < 3; ++d) {
      x24[3 * q + d] = (origin ? origin[d] : 0.0) + h * double((q >> d) & 1);
    }
  }
}

/// Cell stiffness h*(lambda*K_lambda + mu*K_mu) into K (576 doubles).
HEXCUT_HD inline void cell_stiffness(const ReferenceMatrices& ref, double h, double lambda,
                                     double mu, double* K) {
  for (int i = 0; i < kElementMatrixSize; ++i) {
    K[i] = h * (lambda * ref.k_lambda[i] + mu * ref.k_mu[i]);
  }
}

}  // namespace hexcut::element
