// Newmark time integration, beta = 1/4, gamma = 1/2 (average acceleration: unconditionally
// stable, no numerical damping), in the consistent form of doc/theory.md, "Dynamics: Newmark". With
// Rayleigh damping D = alpha1 M + alpha2 K one step solves A u^{n+1} = b with
//   A = a0 M + a1 D + K^
//   b = f + b^ + M (a0 u^n + a2 v^n + a^n) + D (a1 u^n + v^n)
// and then updates velocity and acceleration with newmark_update().
// (Dick 2012, eq. 2.97a, and Wu 2014, eq. 2.27, print the v^n term with a wrong power of dt;
// doc/references.md.)
#pragma once

#include "element/host_device.hpp"

namespace hexcut::element {

struct NewmarkCoefficients {
  double a0;  ///< 4/dt^2: M in A; M u^n in b; (u^{n+1} - u^n - dt v^n) in the acceleration
  double a1;  ///< 2/dt:   D in A; D u^n in b; (u^{n+1} - u^n) in the velocity
  double a2;  ///< 4/dt:   M v^n in b
};

HEXCUT_HD inline NewmarkCoefficients newmark_coefficients(double dt) {
  return NewmarkCoefficients{4.0 / (dt * dt), 2.0 / dt, 4.0 / dt};
}

/// The history vectors multiplied by M and D in the right-hand side:
/// mass_hist = a0 u + a2 v + a, damp_hist = a1 u + v (either output may be nullptr).
HEXCUT_HD inline void newmark_history(int n, double dt, const double* u, const double* v,
                                      const double* a, double* mass_hist, double* damp_hist) {
  const NewmarkCoefficients c = newmark_coefficients(dt);
  for (int i = 0; i < n; ++i) {
    if (mass_hist) mass_hist[i] = c.a0 * u[i] + c.a2 * v[i] + a[i];
    if (damp_hist) damp_hist[i] = c.a1 * u[i] + v[i];
  }
}

/// Velocity and acceleration after solving for u_new:
///   v_new = (2/dt)(u_new - u_old) - v_old,
///   a_new = (4/dt^2)(u_new - u_old - dt v_old) - a_old.
/// The outputs may alias v_old / a_old (each entry is read before it is written).
HEXCUT_HD inline void newmark_update(int n, double dt, const double* u_old, const double* v_old,
                                     const double* a_old, const double* u_new, double* v_new,
                                     double* a_new) {
  const NewmarkCoefficients c = newmark_coefficients(dt);
  for (int i = 0; i < n; ++i) {
    const double du = u_new[i] - u_old[i];
    const double vo = v_old[i], ao = a_old[i];
    v_new[i] = c.a1 * du - vo;
    a_new[i] = c.a0 * (du - dt * vo) - ao;
  }
}

}  // namespace hexcut::element
