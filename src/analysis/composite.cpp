#include "analysis/composite.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

namespace hexcut::analysis {
namespace {

/// Global vectors of levels 0..l borrowed from the multigrid's DMs for a scope.
class LevelVectors {
 public:
  explicit LevelVectors(const multigrid::Multigrid& mg) : mg_(mg), v_(mg.first_level() + 1) {}
  ~LevelVectors() {
    for (std::size_t k = 0; k < v_.size(); ++k)
      if (v_[k]) DMRestoreGlobalVector(mg_.dm(int(k)), &v_[k]);
  }
  LevelVectors(const LevelVectors&) = delete;
  LevelVectors& operator=(const LevelVectors&) = delete;
  /// Borrows the vectors of levels first..last (inclusive).
  PetscErrorCode get(int first, int last) {
    PetscFunctionBeginUser;
    for (int k = first; k <= last; ++k)
      if (!v_[k]) PetscCall(DMGetGlobalVector(mg_.dm(k), &v_[k]));
    PetscFunctionReturn(0);
  }
  Vec operator[](int k) const { return v_[k]; }

 private:
  const multigrid::Multigrid& mg_;
  std::vector<Vec> v_;
};

}  // namespace

PetscErrorCode restrict_composite(multigrid::Multigrid& mg, Vec fine, Vec composite) {
  PetscFunctionBeginUser;
  const int l = mg.first_level();
  if (l == 0) {
    PetscCall(VecCopy(fine, composite));
    PetscFunctionReturn(0);
  }
  LevelVectors v(mg);
  PetscCall(v.get(1, l - 1));
  Vec from = fine;
  for (int k = 0; k < l; ++k) {
    Vec to = k + 1 == l ? composite : v[k + 1];
    PetscCall(MatMultTranspose(mg.interpolation(k), from, to));
    from = to;
  }
  PetscFunctionReturn(0);
}

PetscErrorCode prolong_composite(multigrid::Multigrid& mg, Vec composite, Vec fine) {
  PetscFunctionBeginUser;
  const int l = mg.first_level();
  if (l == 0) {
    PetscCall(VecCopy(composite, fine));
    PetscFunctionReturn(0);
  }
  LevelVectors v(mg);
  PetscCall(v.get(1, l - 1));
  Vec from = composite;
  for (int k = l - 1; k >= 0; --k) {
    Vec to = k == 0 ? fine : v[k];
    PetscCall(MatMult(mg.interpolation(k), from, to));
    from = to;
  }
  PetscFunctionReturn(0);
}

PetscErrorCode composite_interpolation_matrix(const multigrid::Multigrid& mg, Mat* I) {
  PetscFunctionBeginUser;
  const int l = mg.first_level();
  PetscCheck(l >= 1, PETSC_COMM_SELF, PETSC_ERR_ARG_WRONG,
             "composite level 0 has no interpolation");
  *I = nullptr;
  for (int k = 0; k < l; ++k) {
    Mat Pk;
    PetscCall(MatConvert(mg.interpolation(k), MATAIJ, MAT_INITIAL_MATRIX, &Pk));
    if (!*I) {
      *I = Pk;
    } else {
      Mat IP;
      PetscCall(MatMatMult(*I, Pk, MAT_INITIAL_MATRIX, PETSC_DEFAULT, &IP));
      PetscCall(MatDestroy(I));
      PetscCall(MatDestroy(&Pk));
      *I = IP;
    }
  }
  PetscFunctionReturn(0);
}

CompositePreimage::~CompositePreimage() {
  KSPDestroy(&ksp_);
  MatDestroy(&gram_);
  MatDestroy(&I_);
}

PetscErrorCode CompositePreimage::solve(Vec x, Vec xc, double* misfit) {
  PetscFunctionBeginUser;
  if (!ksp_) {
    PetscCall(composite_interpolation_matrix(mg_, &I_));
    PetscCall(MatTransposeMatMult(I_, I_, MAT_INITIAL_MATRIX, PETSC_DEFAULT, &gram_));
    PetscCall(MatSetOption(gram_, MAT_SPD, PETSC_TRUE));
    PetscCall(MatSetOptionsPrefix(gram_, "hexcut_preimage_"));
    PetscCall(KSPCreate(PetscObjectComm((PetscObject)gram_), &ksp_));
    PetscCall(KSPSetOptionsPrefix(ksp_, "hexcut_preimage_"));
    PetscCall(KSPSetOperators(ksp_, gram_, gram_));
    PetscCall(KSPSetType(ksp_, KSPPREONLY));
    PC pc;
    PetscCall(KSPGetPC(ksp_, &pc));
    PetscCall(PCSetType(pc, PCCHOLESKY));
    PetscCall(PCFactorSetMatSolverType(pc, MATSOLVERMUMPS));
    PetscCall(KSPSetUp(ksp_));
  }
  Vec rhs, back;
  PetscCall(VecDuplicate(xc, &rhs));
  PetscCall(VecDuplicate(x, &back));
  PetscCall(MatMultTranspose(I_, x, rhs));
  PetscCall(KSPSolve(ksp_, rhs, xc));
  PetscCall(MatMult(I_, xc, back));
  PetscCall(VecAXPY(back, -1.0, x));
  PetscReal d = 0;
  PetscCall(VecNorm(back, NORM_INFINITY, &d));
  *misfit = d;
  PetscCall(VecDestroy(&back));
  PetscCall(VecDestroy(&rhs));
  PetscFunctionReturn(0);
}

PetscErrorCode composite_prescribed(multigrid::Multigrid& mg, Vec values, Vec g) {
  PetscFunctionBeginUser;
  const int l = mg.first_level();
  Vec m0 = mg.mask(0), mc = mg.mask(l);
  Vec prescribed, t, num;
  PetscCall(DMGetGlobalVector(mg.dm(0), &prescribed));
  PetscCall(DMGetGlobalVector(mg.dm(0), &t));
  PetscCall(DMGetGlobalVector(mg.dm(l), &num));
  // g~ = I^T (g on prescribed DOFs) / I^T (1 on prescribed DOFs) on the fixed composite DOFs.
  PetscCall(VecSet(prescribed, 1.0));
  PetscCall(VecAXPY(prescribed, -1.0, m0));
  PetscCall(VecPointwiseMult(t, prescribed, values));
  PetscCall(restrict_composite(mg, t, num));
  PetscCall(restrict_composite(mg, prescribed, g));
  {
    PetscInt n;
    const PetscScalar *m, *nu;
    PetscScalar* de;
    PetscCall(VecGetLocalSize(num, &n));
    PetscCall(VecGetArrayRead(mc, &m));
    PetscCall(VecGetArrayRead(num, &nu));
    PetscCall(VecGetArray(g, &de));  // the denominator becomes g~ (0 on free DOFs)
    for (PetscInt i = 0; i < n; ++i) de[i] = m[i] == 0.0 && de[i] > 0.0 ? nu[i] / de[i] : 0.0;
    PetscCall(VecRestoreArray(g, &de));
    PetscCall(VecRestoreArrayRead(num, &nu));
    PetscCall(VecRestoreArrayRead(mc, &m));
  }
  PetscCall(DMRestoreGlobalVector(mg.dm(l), &num));
  PetscCall(DMRestoreGlobalVector(mg.dm(0), &t));
  PetscCall(DMRestoreGlobalVector(mg.dm(0), &prescribed));
  PetscFunctionReturn(0);
}

PetscErrorCode composite_rhs(multigrid::Multigrid& mg, Vec b, Vec bc, Vec uc, double* deviation) {
  PetscFunctionBeginUser;
  const int l = mg.first_level();
  Vec m0 = mg.mask(0), mc = mg.mask(l);
  DM d0 = mg.dm(0), dc = mg.dm(l);
  Vec prescribed, t, lift, g;
  PetscCall(DMGetGlobalVector(d0, &prescribed));
  PetscCall(DMGetGlobalVector(d0, &t));
  PetscCall(DMGetGlobalVector(d0, &lift));
  PetscCall(DMGetGlobalVector(dc, &g));
  PetscCall(composite_prescribed(mg, b, g));
  PetscCall(VecSet(prescribed, 1.0));
  PetscCall(VecAXPY(prescribed, -1.0, m0));
  PetscReal gmax = 0.0;
  PetscCall(VecNorm(g, NORM_INFINITY, &gmax));
  // The lifting u_L = I g~ and the fine residual of the free rows b - A u_L.
  PetscCall(prolong_composite(mg, g, lift));
  if (deviation) {
    PetscCall(VecPointwiseMult(t, prescribed, b));
    PetscReal bmax = 0.0, dmax = 0.0;
    PetscCall(VecNorm(t, NORM_INFINITY, &bmax));
    PetscCall(VecAXPY(t, -1.0, lift));
    PetscCall(VecPointwiseMult(t, t, prescribed));
    PetscCall(VecNorm(t, NORM_INFINITY, &dmax));
    *deviation = bmax > 0.0 ? dmax / bmax : 0.0;
  }
  if (gmax > 0.0) {
    PetscCall(mg.apply_level(0, lift, t));
    PetscCall(VecAYPX(t, -1.0, b));
  } else {
    PetscCall(VecCopy(b, t));
  }
  PetscCall(VecPointwiseMult(t, t, m0));
  PetscCall(restrict_composite(mg, t, bc));
  // Identity rows on the fixed composite DOFs: bc = uc = g~ there.
  {
    PetscInt n;
    const PetscScalar *m, *ga;
    PetscScalar *ba, *ua;
    PetscCall(VecGetLocalSize(bc, &n));
    PetscCall(VecGetArrayRead(mc, &m));
    PetscCall(VecGetArrayRead(g, &ga));
    PetscCall(VecGetArray(bc, &ba));
    PetscCall(VecGetArray(uc, &ua));
    for (PetscInt i = 0; i < n; ++i)
      if (m[i] == 0.0) ba[i] = ua[i] = ga[i];
    PetscCall(VecRestoreArray(uc, &ua));
    PetscCall(VecRestoreArray(bc, &ba));
    PetscCall(VecRestoreArrayRead(g, &ga));
    PetscCall(VecRestoreArrayRead(mc, &m));
  }
  PetscCall(DMRestoreGlobalVector(dc, &g));
  PetscCall(DMRestoreGlobalVector(d0, &lift));
  PetscCall(DMRestoreGlobalVector(d0, &t));
  PetscCall(DMRestoreGlobalVector(d0, &prescribed));
  PetscFunctionReturn(0);
}

PetscErrorCode composite_norm(multigrid::Multigrid& mg, Vec r, PetscReal* norm, Vec add) {
  PetscFunctionBeginUser;
  const int l = mg.first_level();
  Vec t, c;
  PetscCall(DMGetGlobalVector(mg.dm(0), &t));
  PetscCall(DMGetGlobalVector(mg.dm(l), &c));
  PetscCall(VecPointwiseMult(t, r, mg.mask(0)));
  PetscCall(restrict_composite(mg, t, c));
  if (add) PetscCall(VecAXPY(c, 1.0, add));
  PetscCall(VecPointwiseMult(c, c, mg.mask(l)));
  PetscCall(VecNorm(c, NORM_2, norm));
  PetscCall(DMRestoreGlobalVector(mg.dm(l), &c));
  PetscCall(DMRestoreGlobalVector(mg.dm(0), &t));
  PetscFunctionReturn(0);
}

PetscErrorCode composite_positions(const multigrid::Multigrid& mg, Vec* x) {
  PetscFunctionBeginUser;
  const auto& lev = mg.level(mg.first_level());
  const auto& D = lev.layout();
  PetscCall(DMCreateGlobalVector(mg.dm(mg.first_level()), x));
  PetscScalar* a;
  PetscCall(VecGetArray(*x, &a));
  for (std::int32_t i = 0; i < D.num_owned; ++i) {
    const auto& v = lev.copies().vertex[D.copies[i]];
    const Eigen::Vector3d p = lev.graph.spec.vertex_position(v[0], v[1], v[2]);
    for (int d = 0; d < 3; ++d) a[3 * i + d] = p[d];
  }
  PetscCall(VecRestoreArray(*x, &a));
  PetscFunctionReturn(0);
}

PetscErrorCode check_composite_supports(MPI_Comm comm, multigrid::Multigrid& mg,
                                        const deck::Deck& deck, PetscInt* clamped_out,
                                        PetscInt* prescribed_out) {
  PetscFunctionBeginUser;
  // A fine DOF is held fixed by the composite model when I (composite free mask) is 0 there.
  Vec free;
  PetscCall(DMGetGlobalVector(mg.dm(0), &free));
  PetscCall(prolong_composite(mg, mg.mask(mg.first_level()), free));
  PetscInt n;
  const PetscScalar *f, *m;
  PetscCall(VecGetLocalSize(free, &n));
  PetscCall(VecGetArrayRead(free, &f));
  PetscCall(VecGetArrayRead(mg.mask(0), &m));
  PetscInt counts[2] = {0, 0};
  for (PetscInt i = 0; i < n; ++i) {
    counts[0] += f[i] == 0.0;
    counts[1] += m[i] == 0.0;
  }
  PetscCall(VecRestoreArrayRead(mg.mask(0), &m));
  PetscCall(VecRestoreArrayRead(free, &f));
  PetscCall(DMRestoreGlobalVector(mg.dm(0), &free));
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, counts, 2, MPIU_INT, MPI_SUM, comm));
  if (clamped_out) *clamped_out = counts[0];
  if (prescribed_out) *prescribed_out = counts[1];
  if (counts[1] > 0 && counts[0] > 2 * counts[1]) {
    const auto& w = deck.discretization.where;
    char msg[512];
    std::snprintf(msg, sizeof msg,
                  "%swarning: composite elements of level %d hold %lld fine DOFs fixed where the "
                  "supports prescribe %lld (%.1fx): a support on a region smaller than a "
                  "composite element clamps the whole element (doc/user-guide.md, "
                  "\"Discretization\")\n",
                  w.prefix().c_str(), mg.first_level(), (long long)counts[0], (long long)counts[1],
                  double(counts[0]) / double(counts[1]));
    // Once per run, not again for each topology a cut makes (unless the numbers change).
    static std::string last;
    if (last != msg) PetscCall(PetscPrintf(comm, "%s", msg));
    last = msg;
  }
  PetscFunctionReturn(0);
}

}  // namespace hexcut::analysis
