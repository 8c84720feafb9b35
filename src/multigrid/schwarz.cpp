#include "multigrid/schwarz.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <numeric>

#include "assembly/operator.hpp"

namespace hexcut::multigrid {

PetscErrorCode Schwarz::create(MPI_Comm comm, DM dm, const hierarchy::Level& fine,
                               const hierarchy::Level& coarse,
                               const std::vector<char>& coarse_selected,
                               const assembly::CellOperator& op, Vec mask, Schwarz* out) {
  PetscFunctionBeginUser;
  Schwarz& S = *out;
  S = Schwarz{};
  S.dm_ = dm;
  const auto& D = fine.layout();
  // The mask of every local DOF (ghosts too).
  std::vector<double> m;
  {
    Vec ml;
    PetscCall(DMGetLocalVector(dm, &ml));
    PetscCall(assembly::global_to_local(dm, mask, ml));
    const PetscScalar* a;
    PetscCall(VecGetArrayRead(ml, &a));
    m.assign(a, a + 3 * std::size_t(D.num_local()));
    PetscCall(VecRestoreArrayRead(ml, &a));
    PetscCall(DMRestoreLocalVector(dm, &ml));
  }
  // Local children of every selected coarse cell (children share their parent's rank).
  std::vector<std::int32_t> coarse_local(coarse.graph.num_cells(), -1);
  for (std::size_t C = 0; C < coarse.layout().cells.size(); ++C)
    coarse_local[coarse.layout().cells[C]] = std::int32_t(C);
  std::vector<std::vector<std::int32_t>> children(coarse.layout().cells.size());
  for (std::size_t e = 0; e < D.cells.size(); ++e) {
    const auto C = fine.parent[D.cells[e]];
    if (coarse_selected[C] && coarse_local[C] >= 0)
      children[coarse_local[C]].push_back(std::int32_t(e));
  }
  // Patch DOFs, in ascending global order (the submatrices' order).
  std::vector<IS> is;
  std::vector<PetscInt> global;
  for (const auto& ch : children) {
    if (ch.empty()) continue;
    std::vector<std::int32_t> copies;
    for (auto e : ch)
      for (auto v : D.cell_corners[e]) copies.push_back(v);
    std::sort(copies.begin(), copies.end());
    copies.erase(std::unique(copies.begin(), copies.end()), copies.end());
    std::vector<std::pair<PetscInt, std::int32_t>> dofs;
    for (auto v : copies)
      for (int c = 0; c < 3; ++c)
        if (m[3 * v + c] != 0.0) dofs.emplace_back(3 * D.global_block[D.copies[v]] + c, 3 * v + c);
    if (dofs.empty()) continue;
    std::sort(dofs.begin(), dofs.end());
    global.clear();
    for (const auto& [g, l] : dofs) {
      global.push_back(g);
      S.dof_.push_back(l);
    }
    S.offset_.push_back(std::int64_t(S.dof_.size()));
    IS one;
    PetscCall(ISCreateGeneral(PETSC_COMM_SELF, PetscInt(global.size()), global.data(),
                              PETSC_COPY_VALUES, &one));
    is.push_back(one);
  }
  // The principal submatrices of the assembled level operator, on every rank at once.
  Mat A;
  PetscCall(assembly::create_matrix(comm, fine.copies(), D, &A));
  PetscCall(assembly::assemble(op, mask, A));
  Mat* sub = nullptr;
  PetscCall(
      MatCreateSubMatrices(A, PetscInt(is.size()), is.data(), is.data(), MAT_INITIAL_MATRIX, &sub));
  for (std::size_t p = 0; p < is.size(); ++p) {
    const auto n = S.offset_[p + 1] - S.offset_[p];
    Eigen::MatrixXd Ap = Eigen::MatrixXd::Zero(n, n);
    for (PetscInt i = 0; i < n; ++i) {
      PetscInt nc;
      const PetscInt* cols;
      const PetscScalar* vals;
      PetscCall(MatGetRow(sub[p], i, &nc, &cols, &vals));
      for (PetscInt k = 0; k < nc; ++k) Ap(i, cols[k]) = vals[k];
      PetscCall(MatRestoreRow(sub[p], i, &nc, &cols, &vals));
    }
    // A coarse Galerkin operator may be singular (and so a patch of it), though consistent:
    // a shift of round-off size makes the factorization exist; the smoother is still
    // symmetric and positive.
    Eigen::LLT<Eigen::MatrixXd> llt(Ap);
    if (llt.info() != Eigen::Success) {
      const double shift = 1e-10 * Ap.diagonal().cwiseAbs().maxCoeff();
      Ap.diagonal().array() += shift;
      llt.compute(Ap);
      PetscCheck(llt.info() == Eigen::Success, PETSC_COMM_SELF, PETSC_ERR_MAT_CH_ZRPVT,
                 "gmg: a Schwarz patch matrix is not positive definite");
    }
    const Eigen::MatrixXd L = llt.matrixL();
    for (Eigen::Index i = 0; i < n; ++i)
      for (Eigen::Index j = 0; j <= i; ++j) S.factor_.push_back(L(i, j));
    S.factor_offset_.push_back(std::int64_t(S.factor_.size()));
  }
  PetscCall(MatDestroySubMatrices(PetscInt(is.size()), &sub));
  PetscCall(MatDestroy(&A));
  for (auto& one : is) PetscCall(ISDestroy(&one));
  // Owned DOFs in some patch of any rank (a patch may hold ghost copies).
  {
    Vec cl, cg;
    PetscCall(DMGetLocalVector(dm, &cl));
    PetscCall(DMGetGlobalVector(dm, &cg));
    PetscCall(VecSet(cl, 0.0));
    PetscScalar* a;
    PetscCall(VecGetArray(cl, &a));
    for (auto l : S.dof_) a[l] = 1.0;
    PetscCall(VecRestoreArray(cl, &a));
    PetscCall(VecSet(cg, 0.0));
    PetscCall(DMLocalToGlobalBegin(dm, cl, ADD_VALUES, cg));
    PetscCall(DMLocalToGlobalEnd(dm, cl, ADD_VALUES, cg));
    const PetscScalar* g;
    PetscCall(VecGetArrayRead(cg, &g));
    S.covered_.assign(3 * std::size_t(D.num_owned), 0);
    for (std::size_t i = 0; i < S.covered_.size(); ++i) S.covered_[i] = g[i] > 0.0;
    PetscCall(VecRestoreArrayRead(cg, &g));
    PetscCall(DMRestoreGlobalVector(dm, &cg));
    PetscCall(DMRestoreLocalVector(dm, &cl));
  }
  PetscFunctionReturn(0);
}

PetscErrorCode Schwarz::apply(Vec r, Vec z) const {
  PetscFunctionBeginUser;
  Vec rl, zl;
  PetscCall(DMGetLocalVector(dm_, &rl));
  PetscCall(DMGetLocalVector(dm_, &zl));
  PetscCall(assembly::global_to_local(dm_, r, rl));
  PetscCall(VecSet(zl, 0.0));
  const PetscScalar* ra;
  PetscScalar* za;
  PetscCall(VecGetArrayRead(rl, &ra));
  PetscCall(VecGetArray(zl, &za));
  Eigen::VectorXd y;
  for (std::size_t p = 0; p + 1 < offset_.size(); ++p) {
    const auto n = offset_[p + 1] - offset_[p];
    const std::int32_t* dofs = &dof_[offset_[p]];
    const double* L = &factor_[factor_offset_[p]];
    y.resize(n);
    // L y = r_p (forward, row i of L: a dot product), L^T y = y (backward, row i of L: an
    // axpy); packed lower rows, L(i, j) at i(i+1)/2 + j. Eigen's dot and axpy are vectorized
    // (a plain loop's dot product is not, and is latency-bound).
    using Row = Eigen::Map<const Eigen::VectorXd>;
    for (std::int64_t i = 0; i < n; ++i) {
      const double* Li = L + i * (i + 1) / 2;
      y[i] = (ra[dofs[i]] - Row(Li, i).dot(y.head(i))) / Li[i];
    }
    for (std::int64_t i = n - 1; i >= 0; --i) {
      const double* Li = L + i * (i + 1) / 2;
      y[i] /= Li[i];
      y.head(i) -= y[i] * Row(Li, i);
    }
    for (std::int64_t i = 0; i < n; ++i) za[dofs[i]] += y[i];
  }
  PetscCall(VecRestoreArray(zl, &za));
  PetscCall(VecRestoreArrayRead(rl, &ra));
  // The patch sums of every rank, on the owners; they replace z on the DOFs some patch covers.
  Vec zg;
  PetscCall(DMGetGlobalVector(dm_, &zg));
  PetscCall(VecSet(zg, 0.0));
  PetscCall(DMLocalToGlobalBegin(dm_, zl, ADD_VALUES, zg));
  PetscCall(DMLocalToGlobalEnd(dm_, zl, ADD_VALUES, zg));
  PetscCall(DMRestoreLocalVector(dm_, &rl));
  PetscCall(DMRestoreLocalVector(dm_, &zl));
  const PetscScalar* sums;
  PetscScalar* out;
  PetscCall(VecGetArrayRead(zg, &sums));
  PetscCall(VecGetArray(z, &out));
  for (std::size_t i = 0; i < covered_.size(); ++i)
    if (covered_[i]) out[i] = sums[i];
  PetscCall(VecRestoreArray(z, &out));
  PetscCall(VecRestoreArrayRead(zg, &sums));
  PetscCall(DMRestoreGlobalVector(dm_, &zg));
  PetscFunctionReturn(0);
}

}  // namespace hexcut::multigrid
