// Cell stress recovery at the centre and derived fields (doc/theory.md, "Stress").
#pragma once

#include <cmath>

namespace hexcut::element {

/// Stress of one cell and the fields derived from it. Tensors are in ParaView order
/// (xx, yy, zz, xy, yz, xz), tensor (not engineering) shear components.
struct CellStress {
  double sigma[6];      ///< Cauchy stress in the world frame
  double von_mises;     ///< sqrt(3/2 s:s), s the deviator
  double pressure;      ///< hydrostatic pressure -tr(sigma)/3 (positive = compression)
  double principal[3];  ///< principal stresses, descending (positive = tension)
  /// Principal directions, one per row: directions[3*i + d] is component d of the unit
  /// eigenvector of principal[i]. The rows are orthonormal and right-handed
  /// (row2 = row0 x row1); rows 0 and 1 have their largest-magnitude component positive,
  /// so the (otherwise arbitrary) signs are reproducible.
  double directions[9];
};

/// Stress at the centre of a cell: eps_loc = strain_at_centre(R^T (x + u) - x),
/// sigma_loc = lambda tr(eps_loc) I + 2 mu eps_loc, sigma = R sigma_loc R^T, plus the
/// derived fields. u24: corner displacements; x24_ref: reference corner positions (any
/// frame that differs by a translation); R: the cell's rotation (row-major; identity for
/// linear elasticity).
CellStress recover_stress(const double* u24, const double* x24_ref, const double R[9], double h,
                          double lambda, double mu);

/// The stress tensor alone of recover_stress (6 values, ParaView order, into `sigma`), for
/// callers that derive the other fields later (stress_fields) or not at all.
void recover_cell_stress(const double* u24, const double* x24_ref, const double R[9], double h,
                         double lambda, double mu, double sigma[6]);

/// Derived fields (von Mises, pressure, principal values and directions) of a given stress
/// tensor; the result's sigma is a copy of the input.
CellStress stress_fields(const double sigma[6]);

/// Hydrostatic pressure -tr(s)/3 of a tensor in ParaView order (positive = compression).
inline double pressure(const double s[6]) {
  return -(s[0] + s[1] + s[2]) / 3.0;
}

/// von Mises equivalent stress of a symmetric tensor in ParaView order.
inline double von_mises_stress(const double s[6]) {
  const double a = s[0] - s[1], b = s[1] - s[2], c = s[2] - s[0];
  const double j2x6 = a * a + b * b + c * c + 6.0 * (s[3] * s[3] + s[4] * s[4] + s[5] * s[5]);
  return j2x6 > 0.0 ? std::sqrt(0.5 * j2x6) : 0.0;
}

/// Strain-energy density W = 1/2 sigma : epsilon [J/m^3 = Pa] of an isotropic linear
/// material (Lame lambda, mu [Pa]) at stress s (ParaView order), from the compliance
/// epsilon = (sigma - lambda/(3 lambda + 2 mu) tr(sigma) I) / (2 mu): rotation-invariant,
/// so the same for the corotated stress.
inline double strain_energy_density(const double s[6], double lambda, double mu) {
  const double tr = s[0] + s[1] + s[2];
  const double ss =
      s[0] * s[0] + s[1] * s[1] + s[2] * s[2] + 2.0 * (s[3] * s[3] + s[4] * s[4] + s[5] * s[5]);
  return (ss - lambda / (3.0 * lambda + 2.0 * mu) * tr * tr) / (4.0 * mu);
}

}  // namespace hexcut::element
