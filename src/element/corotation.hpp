// Corotational element operators (doc/theory.md, "Corotation"; Dick 2012, ch. 2, sec. 2.2.5, eqs.
// 2.89-2.92; doc/references.md).
//
// A cell with rotation R (polar factor of its centre deformation gradient) contributes
//   A_e = R^ K R^T   and   b_e = -R^ K (R^T x - x)
// to the system A u = f + b, where R^ = diag(R, ..., R) (8 blocks), K the cell stiffness
// and x the cell's reference corner positions. Because K annihilates rigid translations,
// x may be given in any frame that differs by a translation (global coordinates or the
// cell-local h*(a,b,c)); the results are the same.
//
// All 3x3 matrices are row-major (R[3*i + j]); 24-vectors and 24x24 matrices follow the
// element DOF numbering of reference.hpp.
#pragma once

#include "element/host_device.hpp"
#include "element/kinematics.hpp"  // deformation_gradient_at_centre
#include "element/polar.hpp"       // polar_rotation
#include "element/reference.hpp"

namespace hexcut::element {

/// out = R^T v per corner (local frame from world frame). out may alias v.
HEXCUT_HD inline void rotate_blocks_transposed(const double R[9], const double* v24,
                                               double* out24) {
  for (int q = 0; q < kCorners; ++q) {
    const double a = v24[3 * q], b = v24[3 * q + 1], c = v24[3 * q + 2];
    for (int i = 0; i < 3; ++i) out24[3 * q + i] = R[i] * a + R[3 + i] * b + R[6 + i] * c;
  }
}

/// out = R v per corner (world frame from local frame). out may alias v.
HEXCUT_HD inline void rotate_blocks(const double R[9], const double* v24, double* out24) {
  for (int q = 0; q < kCorners; ++q) {
    const double a = v24[3 * q], b = v24[3 * q + 1], c = v24[3 * q + 2];
    for (int i = 0; i < 3; ++i) {
      out24[3 * q + i] = R[3 * i] * a + R[3 * i + 1] * b + R[3 * i + 2] * c;
    }
  }
}

/// y = K v for a 24x24 row-major K.
HEXCUT_HD inline void element_matvec(const double* K, const double* v24, double* y24) {
  for (int i = 0; i < kElementDofs; ++i) {
    double s = 0.0;
    for (int j = 0; j < kElementDofs; ++j) s += K[kElementDofs * i + j] * v24[j];
    y24[i] = s;
  }
}

/// RKRt = R^ K R^T (24x24, row-major). RKRt may alias K: each 3x3 block is copied first.
HEXCUT_HD inline void rotate_element_matrix(const double R[9], const double* K, double* RKRt) {
  for (int a = 0; a < kCorners; ++a) {
    for (int b = 0; b < kCorners; ++b) {
      double blk[9], t[9];
      for (int k = 0; k < 3; ++k) {
        for (int l = 0; l < 3; ++l) blk[3 * k + l] = K[kElementDofs * (3 * a + k) + 3 * b + l];
      }
      for (int i = 0; i < 3; ++i) {  // t = R blk
        for (int l = 0; l < 3; ++l) {
          t[3 * i + l] = R[3 * i] * blk[l] + R[3 * i + 1] * blk[3 + l] + R[3 * i + 2] * blk[6 + l];
        }
      }
      for (int i = 0; i < 3; ++i) {  // out = t R^T
        for (int j = 0; j < 3; ++j) {
          RKRt[kElementDofs * (3 * a + i) + 3 * b + j] =
              t[3 * i] * R[3 * j] + t[3 * i + 1] * R[3 * j + 1] + t[3 * i + 2] * R[3 * j + 2];
        }
      }
    }
  }
}

/// Corotated (local-frame) displacement d = R^T (x + u) - x: the cell's deformation with
/// its rotation removed. u may be nullptr (u = 0). Positions are taken relative to corner
/// 0, so d is this up to a rigid translation, which K and the strain ignore; this avoids
/// the cancellation that (x + u) - x suffers when x is a global coordinate far from 0.
HEXCUT_HD inline void corotated_displacement(const double R[9], const double* x24,
                                             const double* u24, double* d24) {
  double y[kElementDofs];
  for (int k = 0; k < kElementDofs; ++k) {
    const double xl = x24[k] - x24[k % 3];
    y[k] = xl + (u24 ? u24[k] : 0.0);
  }
  rotate_blocks_transposed(R, y, d24);
  for (int k = 0; k < kElementDofs; ++k) d24[k] -= x24[k] - x24[k % 3];
}

/// Corotational right-hand side contribution b_e = -R^ K (R^T x - x).
HEXCUT_HD inline void corotational_rhs(const double R[9], const double* K, const double* x24_ref,
                                       double* b24) {
  double d[kElementDofs], t[kElementDofs];
  corotated_displacement(R, x24_ref, nullptr, d);
  element_matvec(K, d, t);
  rotate_blocks(R, t, b24);
  for (int k = 0; k < kElementDofs; ++k) b24[k] = -b24[k];
}

/// Corotational internal (elastic) force f_e = R^ K (R^T (x + u) - x) = A_e u - b_e.
/// It vanishes for any rigid motion whose rotation is R.
HEXCUT_HD inline void element_force(const double R[9], const double* K, const double* x24,
                                    const double* u24, double* f24) {
  double d[kElementDofs], t[kElementDofs];
  corotated_displacement(R, x24, u24, d);
  element_matvec(K, d, t);
  rotate_blocks(R, t, f24);
}

/// d = R^T (x + u) - x with R the polar rotation of the cell's own centre deformation
/// gradient (as corotated_displacement; h: cell edge [m]).
HEXCUT_HD inline void current_corotated_displacement(double h, const double* x24, const double* u24,
                                                     double* d24) {
  double F[9], R[9];
  deformation_gradient_at_centre(u24, h, F);
  polar_rotation(F, R);
  corotated_displacement(R, x24, u24, d24);
}

/// What midpoint_force() found besides the force.
struct MidpointForce {
  double energy0 = 0.0, energy1 = 0.0;               ///< strain energy 1/2 d^T K d at u0 and u1 [J]
  double rotation[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};  ///< R_m of the mid-point (u0 + u1)/2
};

/// Mean internal force of one cell over a time step from u0 to u1 (doc/theory.md
/// "Mid-point corotational step"; the mid-point form of Crisfield, Galvanetto & Jelenic
/// 1997):
///   f = R_m^ K dbar - theta x z,   dbar = (d(u0) + d(u1))/2,
/// d = R^T (x + u) - x with R the polar rotation of each end, R_m that of the mid-point
/// configuration, and theta x z the infinitesimal rotation of the mid-point corners z
/// (centroid-relative) with the moment of R_m^ K dbar: f has neither resultant nor moment
/// about the mid-point configuration, so the mid-point rule conserves linear and angular
/// momentum, and a rigid step (which moves the mid-point corners by an infinitesimal
/// rotation) does no work. f . (u1 - u0) equals W(u1) - W(u0), W = 1/2 d^T K d, up to
/// terms of second order in the step's rotation times its change of d (not exactly).
/// K: 24x24 cell stiffness; h: cell edge [m]; x24: reference corners (cell-local);
/// d0: the corotated displacement at u0 (current_corotated_displacement, which a step
/// computes once); u0, u1: corner displacements [m]; f24: the force [N]. R1, Rm: the
/// rotations at u1 and at the mid-point when they are given (a composite element's, shared
/// by its cells); null: the polar factors of this cell's own deformation gradients.
/// remove_moment_here = false leaves the moment in f24: a composite element removes it
/// from the forces of all its cells together (remove_moment), since its cells rotate with
/// the element's rotation, not their own.
MidpointForce midpoint_force(const double* K, double h, const double* x24, const double* d0,
                             const double* u0, const double* u1, double* f24,
                             const double* R1 = nullptr, const double* Rm = nullptr,
                             bool remove_moment_here = true);

/// Subtracts from the forces f (3 per point) at the n points z (3 per point, any origin)
/// the infinitesimal rotation theta x (z - c) about their centroid c with the same moment
/// about c: the result has the resultant of f and no moment (points on a line: unchanged).
void remove_moment(int n, const double* z, double* f);

/// remove_moment() for the points of cells interpolated from n nodes: the fine corners
/// z_q = sum_a w_qa z~_a carry the forces whose restriction to the nodes is f~_a =
/// sum_q w_qa f_q, and G = sum_q w_q w_q^T (n x n, row-major; the Gram matrix of the
/// weights over all corners) holds all that the moment, the centroid and the inertia of
/// the corners need. On return f~ is the restriction of remove_moment() applied to the
/// corners (exact; doc/theory.md, "Composite elements"). z: node positions (3 per node),
/// f: node forces (3 per node).
void remove_moment_interpolated(int n, const double* z, const double* G, double* f);

}  // namespace hexcut::element
