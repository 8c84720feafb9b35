#include "multigrid/energy_interpolation.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <map>

#include "element/trilinear.hpp"
#include "multigrid/interpolation_region.hpp"

namespace hexcut::multigrid {

using hierarchy::Level;

bool InterpolationRows::touches(const std::int32_t* fine_corners) const {
  if (coarse.empty()) return false;
  for (int q = 0; q < 8; ++q)
    if (row_of[fine_corners[q]] >= 0) return true;
  return false;
}

void child_interpolation(const InterpolationRows& rows, const std::int32_t* fine_corners,
                         const std::int32_t* parent_corners, int octant, double* W) {
  std::fill(W, W + 576, 0.0);
  for (int q = 0; q < 8; ++q) {
    const auto r = rows.row_of.empty() ? -1 : rows.row_of[fine_corners[q]];
    if (r < 0) {
      for (int j = 0; j < 8; ++j) {
        const double w = element::child_weight(octant, q, j);
        for (int a = 0; a < 3; ++a) W[24 * (3 * q + a) + 3 * j + a] = w;
      }
      continue;
    }
    const auto& pattern = rows.coarse[r];
    const double* blocks = &rows.block[72 * std::size_t(r)];
    for (int k = 0; k < 8 && pattern[k] >= 0; ++k) {
      int j = 0;
      while (j < 8 && parent_corners[j] != pattern[k]) ++j;
      // The pattern is a subset of every incident parent's corners (energy_interpolation).
      if (j == 8) continue;
      for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) W[24 * (3 * q + a) + 3 * j + b] = blocks[9 * k + 3 * a + b];
    }
  }
}

std::vector<char> irregular_cells(const Level& fine, const Level& coarse,
                                  const std::vector<char>& fine_irregular,
                                  const std::vector<double>& youngs,
                                  const std::vector<double>& poisson) {
  const std::int32_t nf = fine.graph.num_cells(), nc = coarse.graph.num_cells();
  std::vector<int> children(nc, 0), links(nc, 0);
  std::vector<char> irregular(nc, 0);
  std::vector<std::int32_t> first_child(nc, -1);
  for (std::int32_t c = 0; c < nf; ++c) {
    const auto C = fine.parent[c];
    ++children[C];
    if (!fine_irregular.empty() && fine_irregular[c]) irregular[C] = 1;
    if (!youngs.empty()) {
      if (first_child[C] < 0) {
        first_child[C] = c;
      } else if (youngs[c] != youngs[first_child[C]] || poisson[c] != poisson[first_child[C]]) {
        irregular[C] = 1;
      }
    }
    for (auto l = fine.graph.link_offset[c]; l < fine.graph.link_offset[c + 1]; ++l)
      if (fine.parent[fine.graph.link_target[l]] == C) ++links[C];  // each link twice
  }
  for (std::int32_t C = 0; C < nc; ++C)
    if (children[C] < 8 || links[C] < 24) irregular[C] = 1;
  return irregular;
}

namespace {

constexpr int kSlots = kPatternSlots;
constexpr int kRow = 9 * kSlots;  // numbers per fine copy: 8 3x3 blocks

/// What one row of the minimization needs: the rigid-mode projector data of its pattern.
struct RowConstraint {
  int slots = 0;
  double B[3 * kSlots][6];  // rigid modes at the pattern's coarse copies, relative to the row
  double Ginv[6][6];        // (B^T B)^+
};

/// x (3 rows of 24: slot k, column b) <- x - (x B) G^+ B^T on each DOF row, zero where masked.
void project_row(const RowConstraint& c, const double* mask3, double* x) {
  const int m = 3 * c.slots;
  for (int a = 0; a < 3; ++a) {
    double* r = x + 24 * a;
    if (mask3[a] == 0.0) {
      std::fill(r, r + 24, 0.0);
      continue;
    }
    double xb[6] = {0, 0, 0, 0, 0, 0}, y[6] = {0, 0, 0, 0, 0, 0};
    for (int i = 0; i < m; ++i)
      for (int k = 0; k < 6; ++k) xb[k] += r[i] * c.B[i][k];
    for (int k = 0; k < 6; ++k)
      for (int l = 0; l < 6; ++l) y[k] += xb[l] * c.Ginv[l][k];
    for (int i = 0; i < m; ++i)
      for (int k = 0; k < 6; ++k) r[i] -= y[k] * c.B[i][k];
    std::fill(r + m, r + 24, 0.0);
  }
}

// A row is stored as 3 DOF rows of 24 (slot k, coarse component b at 3k + b): the blocks of
// InterpolationRows are slot-major (9k + 3a + b); these convert.
inline double& at(double* row, int a, int k, int b) {
  return row[24 * a + 3 * k + b];
}

}  // namespace

PetscErrorCode energy_interpolation(MPI_Comm comm, const Level& fine, const Level& coarse,
                                    const std::vector<char>& coarse_irregular,
                                    const assembly::CellOperator& op,
                                    const std::vector<double>& diag_inv, Vec mask, int iterations,
                                    InterpolationRows* rows, EnergyStats* stats) {
  PetscFunctionBeginUser;
  *stats = EnergyStats{};
  *rows = InterpolationRows{};
  Region R;
  std::int64_t global_count = 0;
  PetscCall(build_region(comm, fine, corners_of_children(fine, coarse_irregular), kRow, &R,
                         &global_count));
  stats->rows = global_count;
  if (global_count == 0) PetscFunctionReturn(0);
  const auto& D = fine.layout();
  const auto& DC = coarse.layout();
  const std::int32_t nr = R.layout.num_local(), nr_owned = R.layout.num_owned;

  std::vector<std::array<std::int32_t, kSlots>> pattern;
  PetscCall(row_patterns(fine, coarse, R, &pattern));
  // Coarse canonical copy -> local coarse copy.
  std::vector<std::int32_t> coarse_local(coarse.copies().num_copies, -1);
  for (std::int32_t i = 0; i < DC.num_local(); ++i) coarse_local[DC.copies[i]] = i;

  // The trilinear start: the weights of each copy's first incident cell, in its pattern.
  std::vector<double> P0(std::size_t(kRow) * nr, 0.0);
  for (std::int32_t r = 0; r < nr; ++r) {
    const auto v = D.copies[R.fine_of[r]];
    const auto cell = fine.copies().first_cell[v];
    int q = 0;
    while (fine.copies().cell_corners[cell][q] != v) ++q;
    const auto& p = fine.graph.ijk[cell];
    const int o = element::parity_octant(p[0], p[1], p[2]);
    const auto& pc = coarse.copies().cell_corners[fine.parent[cell]];
    for (int j = 0; j < 8; ++j) {
      const double w = element::child_weight(o, q, j);
      if (w == 0.0) continue;
      const auto J = coarse_local[pc[j]];
      int k = 0;
      while (k < kSlots && pattern[r][k] != J) ++k;
      PetscCheck(k < kSlots, PETSC_COMM_SELF, PETSC_ERR_PLIB,
                 "gmg: a trilinear weight lies outside the cell pattern");
      for (int a = 0; a < 3; ++a) at(&P0[kRow * std::size_t(r)], a, k, a) = w;
    }
  }

  // Rigid-mode constraints of the owned rows, positions relative to the row's copy (in
  // fine-level lattice units; a common scale does not change the constraint).
  std::vector<RowConstraint> constraint(nr_owned);
  std::map<std::vector<int>, Eigen::Matrix<double, 6, 6>> pseudo_inverses;
  for (std::int32_t r = 0; r < nr_owned; ++r) {
    auto& c = constraint[r];
    const auto& xf = fine.copies().vertex[D.copies[R.fine_of[r]]];
    for (int k = 0; k < kSlots && pattern[r][k] >= 0; ++k) {
      const auto& xc = coarse.copies().vertex[DC.copies[pattern[r][k]]];
      const double y[3] = {2.0 * xc[0] - xf[0], 2.0 * xc[1] - xf[1], 2.0 * xc[2] - xf[2]};
      for (int b = 0; b < 3; ++b) {
        double* B = c.B[3 * k + b];
        for (int m = 0; m < 6; ++m) B[m] = 0.0;
        B[b] = 1.0;
        // rotation about axis e_m: u = e_m x y
        const double e_cross_y[3][3] = {{0.0, -y[2], y[1]}, {y[2], 0.0, -y[0]}, {-y[1], y[0], 0.0}};
        for (int m = 0; m < 3; ++m) B[3 + m] = e_cross_y[m][b];
      }
      c.slots = k + 1;
    }
    // G^+ depends only on the pattern's offsets (small integers): a few shapes in all.
    // B's rotation columns hold +-y: (e_1 x y)_0 = y_2, (e_2 x y)_1 = y_0, (e_0 x y)_2 = y_1.
    std::vector<int> key{c.slots};
    for (int k = 0; k < c.slots; ++k) {
      key.push_back(int(std::lround(c.B[3 * k + 1][3 + 2])));
      key.push_back(int(std::lround(c.B[3 * k + 2][3 + 0])));
      key.push_back(int(std::lround(c.B[3 * k + 0][3 + 1])));
    }
    auto found = pseudo_inverses.find(key);
    if (found == pseudo_inverses.end()) {
      Eigen::Matrix<double, 6, 6> G = Eigen::Matrix<double, 6, 6>::Zero();
      for (int i = 0; i < 3 * c.slots; ++i)
        for (int k = 0; k < 6; ++k)
          for (int l = 0; l < 6; ++l) G(k, l) += c.B[i][k] * c.B[i][l];
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 6, 6>> eig(G);
      const auto& ev = eig.eigenvalues();
      const double tol = 1e-10 * std::max(1.0, ev.cwiseAbs().maxCoeff());
      Eigen::Matrix<double, 6, 6> Gi = Eigen::Matrix<double, 6, 6>::Zero();
      for (int k = 0; k < 6; ++k)
        if (ev(k) > tol)
          Gi += (1.0 / ev(k)) * eig.eigenvectors().col(k) * eig.eigenvectors().col(k).transpose();
      found = pseudo_inverses.emplace(key, Gi).first;
    }
    for (int k = 0; k < 6; ++k)
      for (int l = 0; l < 6; ++l) c.Ginv[k][l] = found->second(k, l);
  }

  std::vector<RegionCell> cells;
  PetscCall(region_cells(fine, coarse, R, pattern, &cells));

  // y = Pi_pattern(A Y) on the owned rows: per cell, W from Y's rows (and trilinear weights
  // at corners outside the region when `with_trilinear`), A_e W, kept on the pattern.
  std::vector<double> Ae(576), W(576), acc;
  auto apply = [&](Vec Yg, bool with_trilinear, Vec out) -> PetscErrorCode {
    PetscFunctionBeginUser;
    PetscCall(to_local(R, Yg));
    const PetscScalar* y;
    PetscCall(VecGetArrayRead(R.local, &y));
    acc.assign(std::size_t(kRow) * nr, 0.0);
    for (const auto& rc : cells) {
      std::fill(W.begin(), W.end(), 0.0);
      const auto* fc = D.cell_corners[rc.e].data();
      for (int q = 0; q < 8; ++q) {
        const auto r = R.local_of[fc[q]];
        if (r < 0) {
          if (!with_trilinear) continue;
          for (int j = 0; j < 8; ++j) {
            const double w = element::child_weight(rc.octant, q, j);
            for (int a = 0; a < 3; ++a) W[24 * (3 * q + a) + 3 * j + a] = w;
          }
          continue;
        }
        const double* row = y + std::size_t(kRow) * r;
        for (int k = 0; k < kSlots; ++k) {
          const int j = rc.parent_corner[q][k];
          if (j < 0) continue;
          for (int a = 0; a < 3; ++a)
            for (int b = 0; b < 3; ++b) W[24 * (3 * q + a) + 3 * j + b] = row[24 * a + 3 * k + b];
        }
      }
      op.cell_matrix(std::size_t(rc.e), Ae.data());
      // Rows q of A_e W for the region corners only (the rows kept), each a fixed-size
      // 3x24 by 24x24 product (set-up only; host code).
      using M24 = Eigen::Matrix<double, 24, 24, Eigen::RowMajor>;
      using M3 = Eigen::Matrix<double, 3, 24, Eigen::RowMajor>;
      const Eigen::Map<const M24> Wm(W.data());
      for (int q = 0; q < 8; ++q) {
        const auto r = R.local_of[fc[q]];
        if (r < 0) continue;
        const M3 Tq = Eigen::Map<const M3>(&Ae[72 * q]) * Wm;
        double* row = &acc[std::size_t(kRow) * r];
        for (int k = 0; k < kSlots; ++k) {
          const int j = rc.parent_corner[q][k];
          if (j < 0) continue;
          for (int a = 0; a < 3; ++a)
            for (int b = 0; b < 3; ++b) row[24 * a + 3 * k + b] += Tq(a, 3 * j + b);
        }
      }
    }
    PetscCall(VecRestoreArrayRead(R.local, &y));
    PetscScalar* l;
    PetscCall(VecGetArray(R.local, &l));
    std::copy(acc.begin(), acc.end(), l);
    PetscCall(VecRestoreArray(R.local, &l));
    PetscCall(sum_to_owners(R, out));
    PetscFunctionReturn(0);
  };

  const PetscScalar* m;
  PetscCall(VecGetArrayRead(mask, &m));
  std::vector<double> mask_owned(3 * std::size_t(nr_owned));
  for (std::int32_t r = 0; r < nr_owned; ++r)
    for (int a = 0; a < 3; ++a) mask_owned[3 * r + a] = m[3 * R.fine_of[r] + a];
  PetscCall(VecRestoreArrayRead(mask, &m));
  auto project = [&](Vec v) -> PetscErrorCode {
    PetscFunctionBeginUser;
    PetscScalar* x;
    PetscCall(VecGetArray(v, &x));
    for (std::int32_t r = 0; r < nr_owned; ++r)
      project_row(constraint[r], &mask_owned[3 * r], x + std::size_t(kRow) * r);
    PetscCall(VecRestoreArray(v, &x));
    PetscFunctionReturn(0);
  };
  // z = D^-1 x: the 3x3 diagonal block of the row's copy acts on its 3 DOF rows.
  auto precondition = [&](Vec x, Vec z) -> PetscErrorCode {
    PetscFunctionBeginUser;
    const PetscScalar* xa;
    PetscScalar* za;
    PetscCall(VecGetArrayRead(x, &xa));
    PetscCall(VecGetArray(z, &za));
    for (std::int32_t r = 0; r < nr_owned; ++r) {
      const double* Di = &diag_inv[9 * std::size_t(R.fine_of[r])];
      const double* xr = xa + std::size_t(kRow) * r;
      double* zr = za + std::size_t(kRow) * r;
      for (int a = 0; a < 3; ++a)
        for (int i = 0; i < 24; ++i)
          zr[24 * a + i] =
              Di[3 * a] * xr[i] + Di[3 * a + 1] * xr[24 + i] + Di[3 * a + 2] * xr[48 + i];
    }
    PetscCall(VecRestoreArray(z, &za));
    PetscCall(VecRestoreArrayRead(x, &xa));
    PetscFunctionReturn(0);
  };

  // Jacobi-preconditioned CG on trace(P^T A P) over the corrections X (P = P0 + X) that keep
  // the pattern, the rigid modes and the masked rows (Olson, Schroder, Tuminaro 2011, sec. 3).
  Vec P, Xr, Z, Dir, AD;
  PetscCall(VecDuplicate(R.global, &P));
  PetscCall(VecDuplicate(R.global, &Xr));
  PetscCall(VecDuplicate(R.global, &Z));
  PetscCall(VecDuplicate(R.global, &Dir));
  PetscCall(VecDuplicate(R.global, &AD));
  {
    PetscScalar* p;
    PetscCall(VecGetArray(P, &p));
    std::copy(P0.begin(), P0.begin() + std::ptrdiff_t(kRow) * nr_owned, p);
    PetscCall(VecRestoreArray(P, &p));
  }
  // The energy of the rows' columns within the region is trace(P^T A P) restricted to the
  // region rows: <P, Pi(A P)> before projection is the gradient's pairing.
  PetscCall(apply(P, true, Xr));  // Xr = A P on the pattern (not yet projected)
  {
    PetscScalar e;
    PetscCall(VecDot(P, Xr, &e));
    stats->energy_before = e;
  }
  PetscCall(VecScale(Xr, -1.0));
  PetscCall(project(Xr));  // residual R = -Pi(A P)
  PetscCall(precondition(Xr, Z));
  PetscCall(project(Z));
  PetscCall(VecCopy(Z, Dir));
  PetscScalar rz;
  PetscCall(VecDot(Xr, Z, &rz));
  for (int it = 0; it < iterations && rz > 0.0; ++it) {
    PetscCall(apply(Dir, false, AD));
    PetscCall(project(AD));
    PetscScalar dAd;
    PetscCall(VecDot(Dir, AD, &dAd));
    if (!(dAd > 0.0)) break;
    const double alpha = rz / dAd;
    PetscCall(VecAXPY(P, alpha, Dir));
    PetscCall(VecAXPY(Xr, -alpha, AD));
    PetscCall(precondition(Xr, Z));
    PetscCall(project(Z));
    PetscScalar rz_new;
    PetscCall(VecDot(Xr, Z, &rz_new));
    PetscCall(VecAYPX(Dir, rz_new / rz, Z));
    rz = rz_new;
    stats->iterations = it + 1;
  }
  PetscCall(apply(P, true, AD));
  {
    PetscScalar e;
    PetscCall(VecDot(P, AD, &e));
    stats->energy_after = e;
  }

  // The rows of every local region copy (owners' values to the ghosts).
  PetscCall(to_local(R, P));
  rows->row_of.assign(D.num_local(), -1);
  rows->coarse.assign(nr, {});
  rows->block.assign(std::size_t(kRow) * nr, 0.0);
  const PetscScalar* pl;
  PetscCall(VecGetArrayRead(R.local, &pl));
  for (std::int32_t r = 0; r < nr; ++r) {
    rows->row_of[R.fine_of[r]] = r;
    rows->coarse[r] = pattern[r];
    const double* row = pl + std::size_t(kRow) * r;
    double* blk = &rows->block[std::size_t(kRow) * r];
    for (int k = 0; k < kSlots; ++k)
      for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) blk[9 * k + 3 * a + b] = row[24 * a + 3 * k + b];
  }
  PetscCall(VecRestoreArrayRead(R.local, &pl));
  PetscCall(VecDestroy(&P));
  PetscCall(VecDestroy(&Xr));
  PetscCall(VecDestroy(&Z));
  PetscCall(VecDestroy(&Dir));
  PetscCall(VecDestroy(&AD));
  PetscFunctionReturn(0);
}

PetscErrorCode interpolation_matrix(MPI_Comm comm, const Level& fine, const Level& coarse,
                                    const InterpolationRows& rows, Mat* P) {
  PetscFunctionBeginUser;
  const auto& D = fine.layout();
  const auto& DC = coarse.layout();
  const auto I = hierarchy::interpolation(fine, coarse, D.rank);  // trilinear, owned copies
  std::vector<std::int32_t> local_of(fine.copies().num_copies, -1);
  for (std::int32_t i = 0; i < D.num_owned; ++i) local_of[D.copies[i]] = i;
  const PetscInt first = DC.first_owned_block(), last = first + DC.num_owned;
  std::vector<PetscInt> d_nnz(D.num_owned, 0), o_nnz(D.num_owned, 0);
  // Block columns of each owned row.
  std::vector<std::array<PetscInt, 8>> cols(D.num_owned);
  std::vector<int> count(D.num_owned, 0);
  for (std::size_t i = 0; i < I.fine.size(); ++i) {
    const auto f = local_of[I.fine[i]];
    const auto r = rows.row_of.empty() ? -1 : rows.row_of[f];
    int n = 0;
    if (r >= 0) {
      for (int k = 0; k < 8 && rows.coarse[r][k] >= 0; ++k)
        cols[f][n++] = DC.global_block[DC.copies[rows.coarse[r][k]]];
    } else {
      for (int j = 0; j < 8 && I.coarse[i][j] >= 0; ++j)
        cols[f][n++] = DC.global_block[I.coarse[i][j]];
    }
    count[f] = n;
    for (int k = 0; k < n; ++k) (cols[f][k] >= first && cols[f][k] < last ? d_nnz : o_nnz)[f]++;
  }
  PetscCall(MatCreateBAIJ(comm, 3, 3 * D.num_owned, 3 * DC.num_owned, PETSC_DETERMINE,
                          PETSC_DETERMINE, 0, d_nnz.data(), 0, o_nnz.data(), P));
  for (std::size_t i = 0; i < I.fine.size(); ++i) {
    const auto f = local_of[I.fine[i]];
    const PetscInt row = D.global_block[I.fine[i]];
    const auto r = rows.row_of.empty() ? -1 : rows.row_of[f];
    for (int k = 0; k < count[f]; ++k) {
      double blk[9] = {0, 0, 0, 0, 0, 0, 0, 0, 0};
      if (r >= 0) {
        std::copy_n(&rows.block[72 * std::size_t(r) + 9 * k], 9, blk);
      } else {
        blk[0] = blk[4] = blk[8] = I.weight[i][k];
      }
      PetscCall(MatSetValuesBlocked(*P, 1, &row, 1, &cols[f][k], blk, INSERT_VALUES));
    }
  }
  PetscCall(MatAssemblyBegin(*P, MAT_FINAL_ASSEMBLY));
  PetscCall(MatAssemblyEnd(*P, MAT_FINAL_ASSEMBLY));
  PetscFunctionReturn(0);
}

}  // namespace hexcut::multigrid
