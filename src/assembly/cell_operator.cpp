#include "assembly/cell_operator.hpp"

#include "assembly/operator.hpp"

namespace hexcut::assembly {

PetscErrorCode apply(DM dm, const CellOperator& op, Vec x, Vec y, Vec identity_mask) {
  PetscFunctionBeginUser;
  Vec xl, yl;
  PetscCall(DMGetLocalVector(dm, &xl));
  PetscCall(DMGetLocalVector(dm, &yl));
  PetscCall(global_to_local(dm, x, xl));
  PetscCall(VecSet(yl, 0.0));
  const PetscScalar* xa;
  PetscScalar* ya;
  PetscCall(VecGetArrayRead(xl, &xa));
  PetscCall(VecGetArray(yl, &ya));
  op.apply_add(xa, ya);
  PetscCall(VecRestoreArrayRead(xl, &xa));
  PetscCall(VecRestoreArray(yl, &ya));
  PetscCall(VecSet(y, 0.0));
  PetscCall(DMLocalToGlobalBegin(dm, yl, ADD_VALUES, y));
  PetscCall(DMLocalToGlobalEnd(dm, yl, ADD_VALUES, y));
  PetscCall(DMRestoreLocalVector(dm, &xl));
  PetscCall(DMRestoreLocalVector(dm, &yl));
  if (identity_mask) {
    const PetscScalar *m, *xg;
    PetscScalar* yg;
    PetscInt n;
    PetscCall(VecGetLocalSize(y, &n));
    PetscCall(VecGetArrayRead(identity_mask, &m));
    PetscCall(VecGetArrayRead(x, &xg));
    PetscCall(VecGetArray(y, &yg));
    for (PetscInt i = 0; i < n; ++i)
      if (m[i] == 0.0) yg[i] += xg[i];
    PetscCall(VecRestoreArray(y, &yg));
    PetscCall(VecRestoreArrayRead(x, &xg));
    PetscCall(VecRestoreArrayRead(identity_mask, &m));
  }
  PetscFunctionReturn(0);
}

PetscErrorCode assemble(const CellOperator& op, Vec identity_mask, Mat A) {
  PetscFunctionBeginUser;
  const auto& D = op.layout();
  PetscCall(MatZeroEntries(A));
  double Ae[576];
  PetscInt idx[8];
  for (std::size_t e = 0; e < op.num_cells(); ++e) {
    op.cell_matrix(e, Ae);
    for (int q = 0; q < 8; ++q) idx[q] = D.global_block[D.copies[D.cell_corners[e][q]]];
    PetscCall(MatSetValuesBlocked(A, 8, idx, 8, idx, Ae, ADD_VALUES));
  }
  if (identity_mask) {
    PetscInt lo, n;
    const PetscScalar* m;
    PetscCall(VecGetOwnershipRange(identity_mask, &lo, nullptr));
    PetscCall(VecGetLocalSize(identity_mask, &n));
    PetscCall(VecGetArrayRead(identity_mask, &m));
    for (PetscInt i = 0; i < n; ++i)
      if (m[i] == 0.0) PetscCall(MatSetValue(A, lo + i, lo + i, 1.0, ADD_VALUES));
    PetscCall(VecRestoreArrayRead(identity_mask, &m));
  }
  PetscCall(MatAssemblyBegin(A, MAT_FINAL_ASSEMBLY));
  PetscCall(MatAssemblyEnd(A, MAT_FINAL_ASSEMBLY));
  PetscFunctionReturn(0);
}

}  // namespace hexcut::assembly
