#include "element/reference.hpp"

#include <cmath>

namespace hexcut::element {
namespace {

// Trilinear shape function of corner q and its gradient at xi in the unit cube.
void shape(int q, const double xi[3], double* n, double grad[3]) {
  double f[3], df[3];
  for (int d = 0; d < 3; ++d) {
    const bool high = (q >> d) & 1;
    f[d] = high ? xi[d] : 1.0 - xi[d];
    df[d] = high ? 1.0 : -1.0;
  }
  *n = f[0] * f[1] * f[2];
  grad[0] = df[0] * f[1] * f[2];
  grad[1] = f[0] * df[1] * f[2];
  grad[2] = f[0] * f[1] * df[2];
}

ReferenceMatrices compute_reference_matrices() {
  ReferenceMatrices m{};
  // 2-point Gauss rule on [0,1]: the integrands are at most quadratic per axis, so the
  // product rule is exact for the brick (both stiffness and consistent mass).
  const double g = 0.5 / std::sqrt(3.0);
  const double pts[2] = {0.5 - g, 0.5 + g};
  const double w = 1.0 / 8.0;
  for (int gp = 0; gp < 8; ++gp) {
    const double xi[3] = {pts[gp & 1], pts[(gp >> 1) & 1], pts[(gp >> 2) & 1]};
    double n[kCorners], dn[kCorners][3];
    for (int q = 0; q < kCorners; ++q) shape(q, xi, &n[q], dn[q]);
    for (int q = 0; q < kCorners; ++q) {
      for (int r = 0; r < kCorners; ++r) {
        for (int i = 0; i < 3; ++i) {
          for (int k = 0; k < 3; ++k) {
            const int row = 3 * q + i, col = 3 * r + k;
            // tr(eps) = sum_q grad N_q . u_q, so the lambda part couples component i of q
            // with component k of r through dN_q/dx_i * dN_r/dx_k.
            m.k_lambda[kElementDofs * row + col] += w * dn[q][i] * dn[r][k];
            // 2*eps:eps = grad u : grad u + grad u : grad u^T.
            double kmu = dn[q][k] * dn[r][i];
            if (i == k) {
              for (int j = 0; j < 3; ++j) kmu += dn[q][j] * dn[r][j];
            }
            m.k_mu[kElementDofs * row + col] += w * kmu;
            if (i == k) m.mass[kElementDofs * row + col] += w * n[q] * n[r];
          }
        }
      }
    }
  }
  return m;
}

}  // namespace

const ReferenceMatrices& reference_matrices() {
  static const ReferenceMatrices matrices = compute_reference_matrices();
  return matrices;
}

}  // namespace hexcut::element
