// Rotation factor of the polar decomposition of a cell's deformation gradient (doc/theory.md,
// "Corotation"), on plain arrays so that a CUDA backend runs the same body (HEXCUT_HD).
#pragma once

#include <cmath>

#include "element/host_device.hpp"

namespace hexcut::element {

/// Rotation factor R of the polar decomposition F = R S, always a proper rotation
/// (det R = +1). For det F <= 0 (inverted or flattened cell) the singular direction of
/// the smallest singular value is flipped, i.e. R = U diag(1,1,-1) V^T from the SVD
/// F = U Sigma V^T; this is the rotation closest to F among proper rotations. Returns the
/// identity when F is (numerically) zero or not finite. F and R are row-major.
///
/// The SVD is a one-sided Jacobi SVD (Hestenes 1958): plane rotations V applied to the
/// columns of F until they are mutually orthogonal, F V = U Sigma. Each rotation is
/// computed from its own two columns, which keeps small singular values and their
/// directions accurate (Demmel & Veselic 1992), as Eigen's two-sided JacobiSVD (used
/// before) does, unlike the eigenvectors of F^T F once the two smallest singular values
/// are small. R is then assembled from the two largest singular pairs only,
///   R = u1 v1^T + u2 v2^T + (u1 x u2)(v1 x v2)^T,
/// which is U V^T with the third pair's sign chosen so that det R = +1: for det F > 0 that
/// is U V^T itself, for det F < 0 the flipped smallest direction, and the third left
/// vector (inaccurate when sigma3 is tiny, undefined when it is zero) is never needed.
HEXCUT_HD inline void polar_rotation(const double F[9], double R[9]) {
  // A zero (fully collapsed) or corrupted F carries no rotation information; identity
  // keeps the cell's operator the linear one instead of propagating NaNs into the solve.
  // Max-abs rather than a norm: squaring would underflow/overflow for |F| ~ 1e-200 / 1e200.
  double scale = 0.0;
  bool finite = true;
  for (int k = 0; k < 9; ++k) {
    finite = finite && std::isfinite(F[k]);
    scale = std::fabs(F[k]) > scale ? std::fabs(F[k]) : scale;
  }
  if (!finite || !(scale > 1e-300)) {
    for (int k = 0; k < 9; ++k) R[k] = (k % 4 == 0) ? 1.0 : 0.0;
    return;
  }
  // a[j] = column j of F / scale (scaling first keeps tiny or huge F from under- or
  // overflowing; the rotation factor is invariant under positive scaling); v[j] = column
  // j of V.
  double a[3][3], v[3][3];
  for (int j = 0; j < 3; ++j)
    for (int i = 0; i < 3; ++i) {
      a[j][i] = F[3 * i + j] / scale;
      v[j][i] = i == j ? 1.0 : 0.0;
    }
  // Cyclic sweeps over the column pairs until no pair is further from orthogonal than
  // round-off (3x3 converges quadratically, in 3 to 6 sweeps).
  constexpr double kTolerance = 4.0 * 2.220446049250313e-16;
  for (int sweep = 0; sweep < 20; ++sweep) {
    bool rotated = false;
    for (int p = 0; p < 2; ++p)
      for (int q = p + 1; q < 3; ++q) {
        double alpha = 0.0, beta = 0.0, gamma = 0.0;
        for (int i = 0; i < 3; ++i) {
          alpha += a[p][i] * a[p][i];
          beta += a[q][i] * a[q][i];
          gamma += a[p][i] * a[q][i];
        }
        if (!(std::fabs(gamma) > kTolerance * std::sqrt(alpha) * std::sqrt(beta))) continue;
        rotated = true;
        // The smaller root t = tan(theta) of t^2 + 2 zeta t - 1 = 0 makes the rotated
        // columns orthogonal; for huge zeta (one column negligible), t = 1 / (2 zeta).
        const double zeta = (beta - alpha) / (2.0 * gamma);
        const double t = std::fabs(zeta) > 1e150
                             ? 0.5 / zeta
                             : (zeta >= 0.0 ? 1.0 : -1.0) /
                                   (std::fabs(zeta) + std::sqrt(1.0 + zeta * zeta));
        const double c = 1.0 / std::sqrt(1.0 + t * t), s = c * t;
        for (int i = 0; i < 3; ++i) {
          const double ap = a[p][i], aq = a[q][i], vp = v[p][i], vq = v[q][i];
          a[p][i] = c * ap - s * aq;
          a[q][i] = s * ap + c * aq;
          v[p][i] = c * vp - s * vq;
          v[q][i] = s * vp + c * vq;
        }
      }
    if (!rotated) break;
  }
  // Sort the columns by decreasing norm (singular value), as the SVD orders them.
  double n2[3];
  for (int j = 0; j < 3; ++j) n2[j] = a[j][0] * a[j][0] + a[j][1] * a[j][1] + a[j][2] * a[j][2];
  for (int pass = 0; pass < 3; ++pass) {
    const int j = pass == 1 ? 1 : 0;  // compare-and-swap (0,1), (1,2), (0,1)
    if (n2[j] < n2[j + 1]) {
      double x = n2[j];
      n2[j] = n2[j + 1];
      n2[j + 1] = x;
      for (int i = 0; i < 3; ++i) {
        x = a[j][i];
        a[j][i] = a[j + 1][i];
        a[j + 1][i] = x;
        x = v[j][i];
        v[j][i] = v[j + 1][i];
        v[j + 1][i] = x;
      }
    }
  }
  // u0 = a0 / |a0| (|a0|^2 >= 1/3: F / scale has an entry of magnitude 1); u1 = a1 made
  // orthogonal to u0 once more and normalized. When a1 vanishes (rank-1 F, up to round-off
  // far below any cell's deformation), any unit vector orthogonal to u0 serves: the
  // rotation about u0 is not determined by F.
  double u[2][3];
  const double n0 = std::sqrt(n2[0]);
  for (int i = 0; i < 3; ++i) u[0][i] = a[0][i] / n0;
  const double d = u[0][0] * a[1][0] + u[0][1] * a[1][1] + u[0][2] * a[1][2];
  for (int i = 0; i < 3; ++i) u[1][i] = a[1][i] - d * u[0][i];
  double n1 = std::sqrt(u[1][0] * u[1][0] + u[1][1] * u[1][1] + u[1][2] * u[1][2]);
  if (!(n1 > 1e-150)) {
    // e = the axis along which u0 is smallest; u1 = e x u0 / |e x u0|.
    const double b0 = std::fabs(u[0][0]), b1 = std::fabs(u[0][1]), b2 = std::fabs(u[0][2]);
    const int k = b0 <= b1 ? (b0 <= b2 ? 0 : 2) : (b1 <= b2 ? 1 : 2);
    const int k1 = (k + 1) % 3, k2 = (k + 2) % 3;
    u[1][k] = 0.0;
    u[1][k1] = -u[0][k2];
    u[1][k2] = u[0][k1];
    n1 = std::sqrt(u[1][k1] * u[1][k1] + u[1][k2] * u[1][k2]);
  }
  for (int i = 0; i < 3; ++i) u[1][i] /= n1;
  // Third columns: u2 = u0 x u1, v2 = v0 x v1 (proper frames), then R = U V^T.
  double u2[3], v2[3];
  for (int i = 0; i < 3; ++i) {
    const int i1 = (i + 1) % 3, i2 = (i + 2) % 3;
    u2[i] = u[0][i1] * u[1][i2] - u[0][i2] * u[1][i1];
    v2[i] = v[0][i1] * v[1][i2] - v[0][i2] * v[1][i1];
  }
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      R[3 * i + j] = u[0][i] * v[0][j] + u[1][i] * v[1][j] + u2[i] * v2[j];
}

}  // namespace hexcut::element
