// galerkin_accumulate (multigrid/kernels.hpp) against a plain W^T A W, and the packed
// symmetric storage of the coarse blocks against the full matrix it stands for.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "multigrid/kernels.hpp"

namespace hexcut::multigrid {
namespace {

/// P += W^T A W with W = kron(w, I3), w(i, j) = child_weight(octant, i, j), all 24x24
/// row-major, by the definition.
void reference_accumulate(const double* A, int octant, double* P) {
  std::vector<double> W(576, 0.0), WtA(576, 0.0);
  for (int i = 0; i < 8; ++i)
    for (int j = 0; j < 8; ++j)
      for (int d = 0; d < 3; ++d)
        W[24 * (3 * i + d) + 3 * j + d] = element::child_weight(octant, i, j);
  for (int r = 0; r < 24; ++r)
    for (int c = 0; c < 24; ++c)
      for (int k = 0; k < 24; ++k) WtA[24 * r + c] += W[24 * k + r] * A[24 * k + c];
  for (int r = 0; r < 24; ++r)
    for (int c = 0; c < 24; ++c) {
      double s = 0.0;
      for (int k = 0; k < 24; ++k) s += WtA[24 * r + k] * W[24 * k + c];
      P[24 * r + c] += s;
    }
}

TEST(GalerkinKernel, EqualsWtAWForEveryOctant) {
  std::mt19937_64 rng(21);
  std::uniform_real_distribution<double> U(-1.0, 1.0);
  for (int trial = 0; trial < 20; ++trial) {
    for (int octant = 0; octant < 8; ++octant) {
      // Symmetric A (the multigrid's) and, every fourth trial, a general one.
      const bool symmetric = trial % 4 != 3;
      double A[576], P[576], Pref[576];
      for (int r = 0; r < 24; ++r)
        for (int c = 0; c < 24; ++c) A[24 * r + c] = symmetric && c < r ? A[24 * c + r] : U(rng);
      for (int k = 0; k < 576; ++k) P[k] = Pref[k] = U(rng);  // accumulates onto P
      galerkin_accumulate(A, octant, P);
      reference_accumulate(A, octant, Pref);
      double err = 0.0;
      for (int k = 0; k < 576; ++k) err = std::max(err, std::abs(P[k] - Pref[k]));
      EXPECT_LT(err, 1e-14) << "octant " << octant << (symmetric ? "" : ", general A");
    }
  }
}

TEST(GalerkinKernel, RotatedBlockIsTheProductOfTheRotatedCell) {
  // W^T (R^ K R^T) W = R^ (W^T K W) R^T, R^ = diag(R, ..., R): rotated_block_add on the
  // unrotated product against the definition on the rotated matrix.
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> U(-1.0, 1.0);
  for (int octant = 0; octant < 8; ++octant) {
    double K[576], G[576] = {0}, RK[576], P[576], Pref[576], R[9];
    for (int r = 0; r < 24; ++r)
      for (int c = 0; c < 24; ++c) K[24 * r + c] = c < r ? K[24 * c + r] : U(rng);
    // A rotation from a random unit quaternion.
    double q[4], n = 0.0;
    for (double& x : q) {
      x = U(rng);
      n += x * x;
    }
    for (double& x : q) x /= std::sqrt(n);
    const double a = q[0], b = q[1], c = q[2], d = q[3];
    const double Rq[9] = {a * a + b * b - c * c - d * d, 2 * (b * c - a * d),
                          2 * (b * d + a * c),           2 * (b * c + a * d),
                          a * a - b * b + c * c - d * d, 2 * (c * d - a * b),
                          2 * (b * d - a * c),           2 * (c * d + a * b),
                          a * a - b * b - c * c + d * d};
    std::copy(Rq, Rq + 9, R);
    for (int P_ = 0; P_ < 8; ++P_)  // RK = R^ K R^T, block by block
      for (int Q = 0; Q < 8; ++Q)
        for (int i = 0; i < 3; ++i)
          for (int j = 0; j < 3; ++j) {
            double s = 0.0;
            for (int k = 0; k < 3; ++k)
              for (int l = 0; l < 3; ++l)
                s += R[3 * i + k] * K[24 * (3 * P_ + k) + 3 * Q + l] * R[3 * j + l];
            RK[24 * (3 * P_ + i) + 3 * Q + j] = s;
          }
    for (int k = 0; k < 576; ++k) P[k] = Pref[k] = U(rng);  // accumulates onto P
    reference_accumulate(RK, octant, Pref);
    galerkin_accumulate(K, octant, G);
    rotated_block_add(G, R, 1.0, P);
    double err = 0.0;
    for (int k = 0; k < 576; ++k) err = std::max(err, std::abs(P[k] - Pref[k]));
    EXPECT_LT(err, 1e-13) << "octant " << octant;
  }
}

TEST(GalerkinKernel, ReflectedWeights) {
  // The identity galerkin_accumulate relies on: the weights of octant o are those of
  // octant 0 with both corner indices reflected, and octant 0's weight of fine corner k
  // to coarse corner K is 2^-|k| when K's bits are a subset of k's, else 0.
  for (int o = 0; o < 8; ++o)
    for (int i = 0; i < 8; ++i)
      for (int j = 0; j < 8; ++j)
        EXPECT_EQ(element::child_weight(o, i, j), element::child_weight(0, i ^ o, j ^ o));
  for (int k = 0; k < 8; ++k)
    for (int K = 0; K < 8; ++K) {
      const int bits = (k & 1) + ((k >> 1) & 1) + ((k >> 2) & 1);
      EXPECT_EQ(element::child_weight(0, k, K), (K & ~k) ? 0.0 : std::ldexp(1.0, -bits));
    }
}

TEST(PackedBlocks, IndexIsABijectionOntoTheUpperTriangle) {
  // LAPACK's upper packed order: column by column, rows 0..c of column c.
  std::vector<int> seen(kPackedSize, 0);
  for (int c = 0; c < 24; ++c)
    for (int r = 0; r <= c; ++r) {
      const int k = packed_index(r, c);
      ASSERT_GE(k, 0);
      ASSERT_LT(k, kPackedSize);
      EXPECT_EQ(k, r + c * (c + 1) / 2);
      EXPECT_EQ(packed_index(c, r), k) << "symmetric";
      ++seen[k];
    }
  for (int k = 0; k < kPackedSize; ++k) EXPECT_EQ(seen[k], 1) << "entry " << k;
}

template <class T>
void expect_packed_apply_is_the_symmetric_product(double tolerance) {
  std::mt19937_64 rng(8);
  std::uniform_real_distribution<double> U(-1.0, 1.0);
  for (int trial = 0; trial < 20; ++trial) {
    double A[576], x[24], y[24], yref[24], back[576];
    for (int r = 0; r < 24; ++r)
      for (int c = 0; c < 24; ++c) A[24 * r + c] = c < r ? A[24 * c + r] : U(rng);
    T P[kPackedSize];
    pack_symmetric(A, P);
    unpack_symmetric(P, back);
    // The matrix the packed numbers stand for: A rounded to T, symmetric.
    for (int k = 0; k < 576; ++k) {
      EXPECT_EQ(back[k], double(T(A[k])));
      A[k] = back[k];
    }
    for (int i = 0; i < 24; ++i) x[i] = U(rng), y[i] = yref[i] = U(rng);  // accumulates
    packed_apply_add(P, x, y);
    for (int r = 0; r < 24; ++r)
      for (int c = 0; c < 24; ++c) yref[r] += A[24 * r + c] * x[c];
    double err = 0.0;
    for (int i = 0; i < 24; ++i) err = std::max(err, std::abs(y[i] - yref[i]));
    EXPECT_LT(err, tolerance) << "trial " << trial;
    // Rows of one corner, as the Gauss-Seidel colours read them.
    for (int q = 0; q < 8; ++q) {
      double y3[3];
      packed_row_block(P, q, x, y3);
      for (int e = 0; e < 3; ++e) {
        double s = 0.0;
        for (int c = 0; c < 24; ++c) s += A[24 * (3 * q + e) + c] * x[c];
        EXPECT_NEAR(y3[e], s, tolerance) << "corner " << q;
      }
    }
  }
}

TEST(PackedBlocks, ApplyIsTheSymmetricProductInDoubleAndFloat) {
  // The arithmetic is double in both: only the stored numbers differ, so the float blocks'
  // product is that of the rounded matrix to double round-off.
  expect_packed_apply_is_the_symmetric_product<double>(1e-14);
  expect_packed_apply_is_the_symmetric_product<float>(1e-14);
}

}  // namespace
}  // namespace hexcut::multigrid
