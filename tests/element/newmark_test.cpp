#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "element/element.hpp"

namespace hexcut::element {
namespace {

// One step of m u'' + c u' + k u = 0 with the formulas of doc/theory.md, "Dynamics: Newmark"
// (D = c):
//   A = a0 m + a1 c + k,  b = m (a0 u + a2 v + a) + c (a1 u + v).
struct Oscillator {
  double m, c, k;
  double u, v, a;
  void step(double dt) {
    const NewmarkCoefficients co = newmark_coefficients(dt);
    double mh = 0, dh = 0;
    newmark_history(1, dt, &u, &v, &a, &mh, &dh);
    const double A = co.a0 * m + co.a1 * c + k;
    const double u_new = (m * mh + c * dh) / A;
    newmark_update(1, dt, &u, &v, &a, &u_new, &v, &a);  // in place
    u = u_new;
  }
  double energy() const { return 0.5 * m * v * v + 0.5 * k * u * u; }
};

TEST(ElementNewmark, Coefficients) {
  const NewmarkCoefficients c = newmark_coefficients(0.5);
  EXPECT_DOUBLE_EQ(c.a0, 16.0);
  EXPECT_DOUBLE_EQ(c.a1, 4.0);
  EXPECT_DOUBLE_EQ(c.a2, 8.0);
  // Update against hand-computed numbers: dt = 0.5, du = 0.25, v = 1, a = 2.
  const double uo[2] = {1.0, 0.0}, vo[2] = {1.0, 0.0}, ao[2] = {2.0, 0.0}, un[2] = {1.25, 0.0};
  double vn[2], an[2];
  newmark_update(2, 0.5, uo, vo, ao, un, vn, an);
  EXPECT_DOUBLE_EQ(vn[0], 4.0 * 0.25 - 1.0);
  EXPECT_DOUBLE_EQ(an[0], 16.0 * (0.25 - 0.5) - 2.0);
  EXPECT_EQ(vn[1], 0.0);
  EXPECT_EQ(an[1], 0.0);
}

TEST(ElementNewmark, UndampedOscillatorConservesEnergyAndPeriod) {
  const double m = 2.0, k = 5.0;
  const double omega = std::sqrt(k / m), T = 2.0 * M_PI / omega;
  const double dt = T / 100.0;
  Oscillator o{m, 0.0, k, 1.0, 0.0, -k / m};
  const double e0 = o.energy();
  // Average acceleration is the trapezoidal rule: for u0 = 1, v0 = 0 the discrete solution
  // is exactly cos(n theta) with theta = 2 atan(omega dt / 2) (period elongation, no decay).
  const double theta = 2.0 * std::atan(0.5 * omega * dt);
  std::vector<double> up_crossings;
  double u_prev = o.u;
  double max_de = 0.0, max_du = 0.0;
  for (int n = 1; n <= 1000; ++n) {
    o.step(dt);
    max_de = std::max(max_de, std::abs(o.energy() - e0) / e0);
    max_du = std::max(max_du, std::abs(o.u - std::cos(n * theta)));
    if (u_prev < 0.0 && o.u >= 0.0) {  // interpolate the upward zero crossing
      up_crossings.push_back(dt * (n - 1 + u_prev / (u_prev - o.u)));
    }
    u_prev = o.u;
  }
  EXPECT_LT(max_de, 1e-12);
  EXPECT_LT(max_du, 1e-10);
  ASSERT_GE(up_crossings.size(), 9u);
  const double period =
      (up_crossings.back() - up_crossings.front()) / double(up_crossings.size() - 1);
  const double discrete_period = 2.0 * M_PI * dt / theta;
  EXPECT_NEAR(period, discrete_period, 1e-6 * T);
  // Known elongation ~ (omega dt)^2 / 12 = 3.3e-4 for dt = T/100: longer, within 1%.
  EXPECT_GT(period, T);
  EXPECT_NEAR(period / T - 1.0, std::pow(omega * dt, 2) / 12.0, 1e-5);
  EXPECT_LT(std::abs(period - T), 0.01 * T);
}

TEST(ElementNewmark, DampedOscillatorDiscreteEnergyBalance) {
  // With damping c the trapezoidal rule satisfies exactly
  //   E_{n+1} - E_n = -c dt/4 (v_n + v_{n+1})^2,
  // which checks the damping terms of A and b (an error in a1 or in D's history breaks it).
  const double m = 1.5, c = 0.3, k = 40.0, dt = 0.01;
  Oscillator o{m, c, k, 0.2, -1.0, 0.0};
  o.a = (-k * o.u - c * o.v) / m;
  for (int n = 0; n < 500; ++n) {
    const double e_old = o.energy(), v_old = o.v;
    o.step(dt);
    const double dissipated = 0.25 * c * dt * (v_old + o.v) * (v_old + o.v);
    EXPECT_NEAR(o.energy() - e_old, -dissipated, 1e-13 * e_old) << n;
    // The equation of motion holds at every step (acceleration is consistent).
    EXPECT_NEAR(m * o.a + c * o.v + k * o.u, 0.0, 1e-10 * k);
  }
}

}  // namespace
}  // namespace hexcut::element
