#include "analysis/composite_midpoint.hpp"

#include <algorithm>

#include "element/corotation.hpp"
#include "element/fine_cell.hpp"
#include "element/polar.hpp"

namespace hexcut::analysis {
namespace {

/// The interpolation of one fine cell from its composite element: W[8 q + a], the
/// weight of element corner a at the cell's corner q, for the cell at `offset` (in fine
/// cells, each in [0, s)) of an element s fine cells wide.
void element_weights(const std::array<int, 3>& offset, int s, double W[64]) {
  for (int q = 0; q < 8; ++q)
    for (int a = 0; a < 8; ++a) {
      double w = 1.0;
      for (int d = 0; d < 3; ++d) {
        const double xi = double(offset[d] + ((q >> d) & 1)) / s;
        w *= (a >> d) & 1 ? xi : 1.0 - xi;
      }
      W[8 * q + a] = w;
    }
}

/// B = W^T A W for a 24 x 24 A acting per component (W 8 x 8).
void project(const double* A, const double W[64], double* B) {
  double T[576];  // A W
  for (int r = 0; r < 24; ++r)
    for (int b = 0; b < 8; ++b)
      for (int j = 0; j < 3; ++j) {
        double t = 0.0;
        for (int p = 0; p < 8; ++p) t += A[24 * r + 3 * p + j] * W[8 * p + b];
        T[24 * r + 3 * b + j] = t;
      }
  for (int a = 0; a < 8; ++a)
    for (int i = 0; i < 3; ++i)
      for (int c = 0; c < 24; ++c) {
        double t = 0.0;
        for (int q = 0; q < 8; ++q) t += W[8 * q + a] * T[24 * (3 * q + i) + c];
        B[24 * (3 * a + i) + c] = t;
      }
}

/// The mu-weighted mean deformation gradient of element e at the corner values u24.
void mean_gradient(const CompositeElements& E, std::size_t e, const double* u24, double F[9]) {
  const double* g = &E.gradient[24 * e];
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      double t = i == j ? E.mu_sum[e] : 0.0;
      for (int a = 0; a < 8; ++a) t += u24[3 * a + i] * g[3 * a + j];
      F[3 * i + j] = t / E.mu_sum[e];
    }
}

}  // namespace

CompositeElements build_composite_elements(const multigrid::Multigrid& mg,
                                           const assembly::CellData& cells,
                                           const CompositeElements* previous) {
  const int l = mg.first_level(), s = 1 << l;
  const auto& fine = mg.level(0);
  const auto& lev = mg.level(l);
  const std::size_t n = lev.layout().cells.size();
  CompositeElements E;
  E.stiffness.assign(576 * n, 0.0);
  E.gram.assign(64 * n, 0.0);
  E.gradient.assign(24 * n, 0.0);
  E.mu_sum.assign(n, 0.0);
  E.corners.resize(24 * n);
  for (std::size_t e = 0; e < n; ++e) {
    const auto& p = lev.graph.ijk[lev.layout().cells[e]];
    for (int a = 0; a < 8; ++a) {
      const auto x = lev.graph.spec.vertex_position(p[0] + (a & 1), p[1] + ((a >> 1) & 1),
                                                    p[2] + ((a >> 2) & 1));
      for (int d = 0; d < 3; ++d) E.corners[24 * e + 3 * a + d] = x[d];
    }
  }
  E.keys = mg.composite_keys();
  // Elements a cut left whole: their sums are those of the previous topology.
  std::vector<char> copied(n, 0);
  if (previous) {
    const auto from = multigrid::match_composite_elements(previous->keys, E.keys);
    for (std::size_t e = 0; e < n; ++e) {
      if (from[e] < 0) continue;
      const auto k = std::size_t(from[e]);
      const auto& P = *previous;
      std::copy_n(&P.stiffness[576 * k], 576, &E.stiffness[576 * e]);
      std::copy_n(&P.gram[64 * k], 64, &E.gram[64 * e]);
      std::copy_n(&P.gradient[24 * k], 24, &E.gradient[24 * e]);
      E.mu_sum[e] = P.mu_sum[k];
      copied[e] = 1;
      ++E.carried;
    }
  }
  // Per offset of a fine cell in its element: W^T K_lambda W, W^T K_mu W, W^T W and
  // W^T g, computed for the offsets that occur (tables for all s^3 <= 512 offsets: 5 MiB).
  const auto& ref = element::reference_matrices();
  const std::size_t offsets = std::size_t(s) * s * s;
  std::vector<double> k_lambda(576 * offsets), k_mu(576 * offsets), gram(64 * offsets),
      grad(24 * offsets);
  std::vector<char> ready(offsets, 0);
  const double h = cells.h;
  const auto& ce = mg.composite_elements();
  for (std::size_t c = 0; c < ce.size(); ++c) {
    const auto e = std::size_t(ce[c]);
    if (copied[e]) continue;
    const auto& fp = fine.graph.ijk[fine.layout().cells[c]];
    const auto& cp = lev.graph.ijk[lev.layout().cells[e]];
    const std::array<int, 3> o{fp[0] - s * cp[0], fp[1] - s * cp[1], fp[2] - s * cp[2]};
    const std::size_t k = std::size_t(o[0] + s * (o[1] + s * o[2]));
    if (!ready[k]) {
      double W[64];
      element_weights(o, s, W);
      project(ref.k_lambda, W, &k_lambda[576 * k]);
      project(ref.k_mu, W, &k_mu[576 * k]);
      for (int a = 0; a < 8; ++a) {
        for (int b = 0; b < 8; ++b) {
          double t = 0.0;
          for (int q = 0; q < 8; ++q) t += W[8 * q + a] * W[8 * q + b];
          gram[64 * k + 8 * a + b] = t;
        }
        for (int j = 0; j < 3; ++j) {
          double t = 0.0;
          for (int q = 0; q < 8; ++q) t += W[8 * q + a] * element::corner_sign(q, j);
          grad[24 * k + 3 * a + j] = 0.25 * t / h;
        }
      }
      ready[k] = 1;
    }
    const double lh = h * cells.lambda[c], mh = h * cells.mu[c];
    double* K = &E.stiffness[576 * e];
    for (int i = 0; i < 576; ++i) K[i] += lh * k_lambda[576 * k + i] + mh * k_mu[576 * k + i];
    for (int i = 0; i < 64; ++i) E.gram[64 * e + i] += gram[64 * k + i];
    for (int i = 0; i < 24; ++i) E.gradient[24 * e + i] += cells.mu[c] * grad[24 * k + i];
    E.mu_sum[e] += cells.mu[c];
  }
  return E;
}

PetscErrorCode composite_midpoint_force(multigrid::Multigrid& mg, const CompositeElements& E,
                                        Vec u0c, Vec u1c, Vec fc, assembly::CellData& cells,
                                        double energy[2]) {
  PetscFunctionBeginUser;
  const int l = mg.first_level();
  DM dm = mg.dm(l);
  const auto& D = mg.level(l).layout();
  const std::size_t n = D.cells.size();
  assembly::LocalValues a0, a1;
  PetscCall(a0.get(dm, u0c));
  PetscCall(a1.get(dm, u1c));
  Vec fl;
  PetscCall(DMGetLocalVector(dm, &fl));
  PetscCall(VecSet(fl, 0.0));
  PetscScalar* fa;
  PetscCall(VecGetArray(fl, &fa));
  std::vector<double> Rm(9 * n);
  energy[0] = energy[1] = 0.0;
  for (std::size_t e = 0; e < n; ++e) {
    double v0[24], v1[24], vm[24], F[9], R0[9], R1[9], x[24], d0[24], d1[24], Kd0[24], Kd1[24],
        f[24], z[24];
    element::gather_cell(a0.data(), D.cell_corners[e].data(), v0);
    element::gather_cell(a1.data(), D.cell_corners[e].data(), v1);
    for (int k = 0; k < 24; ++k) vm[k] = 0.5 * (v0[k] + v1[k]);
    mean_gradient(E, e, v0, F);
    element::polar_rotation(F, R0);
    mean_gradient(E, e, v1, F);
    element::polar_rotation(F, R1);
    mean_gradient(E, e, vm, F);
    element::polar_rotation(F, &Rm[9 * e]);
    // Element-local reference corners: d = R^T (x + u) - x differs from the fine cells'
    // (each relative to its own corner) by a translation per cell, which K annihilates.
    const double* X = &E.corners[24 * e];
    for (int k = 0; k < 24; ++k) x[k] = X[k] - X[k % 3];
    element::corotated_displacement(R0, x, v0, d0);
    element::corotated_displacement(R1, x, v1, d1);
    const double* K = &E.stiffness[576 * e];
    element::element_matvec(K, d0, Kd0);
    element::element_matvec(K, d1, Kd1);
    for (int k = 0; k < 24; ++k) {
      energy[0] += 0.5 * d0[k] * Kd0[k];
      energy[1] += 0.5 * d1[k] * Kd1[k];
      Kd0[k] = 0.5 * (Kd0[k] + Kd1[k]);
      z[k] = X[k] + vm[k];
    }
    element::rotate_blocks(&Rm[9 * e], Kd0, f);
    element::remove_moment_interpolated(8, z, &E.gram[64 * e], f);
    element::scatter_add_cell(f, D.cell_corners[e].data(), fa);
  }
  PetscCall(VecRestoreArray(fl, &fa));
  PetscCall(VecSet(fc, 0.0));
  PetscCall(DMLocalToGlobalBegin(dm, fl, ADD_VALUES, fc));
  PetscCall(DMLocalToGlobalEnd(dm, fl, ADD_VALUES, fc));
  PetscCall(DMRestoreLocalVector(dm, &fl));
  // Every fine cell turns with its element's mid-point rotation (the operator reads them).
  cells.identity_rotations = false;
  const auto& ce = mg.composite_elements();
  cells.rotation.resize(9 * ce.size());
  for (std::size_t c = 0; c < ce.size(); ++c)
    std::copy_n(&Rm[9 * std::size_t(ce[c])], 9, &cells.rotation[9 * c]);
  PetscFunctionReturn(0);
}

}  // namespace hexcut::analysis
