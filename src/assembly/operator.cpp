#include "assembly/operator.hpp"

#include <algorithm>
#include <map>

#include "assembly/fine_cells.hpp"
#include "backend/loop.hpp"
#include "element/element.hpp"

namespace hexcut::assembly {
namespace {

constexpr double kIdentity[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};

}  // namespace

const double* cell_stiffness(const CellData& cells, std::size_t e, double* buffer) {
  if (cells.kind[e] >= 0) return cells.kind_stiffness[cells.kind[e]].data();
  element::cell_stiffness(element::reference_matrices(), cells.h, cells.lambda[e], cells.mu[e],
                          buffer);
  return buffer;
}

CellData make_cell_data(const lattice::Lattice& L, const topology::DofLayout& D) {
  CellData C;
  C.h = L.spec.h;
  const std::size_t n = D.cells.size();
  C.lambda.resize(n);
  C.mu.resize(n);
  C.rho.resize(n);
  C.origin.resize(n);
  for (std::size_t e = 0; e < n; ++e) {
    const auto c = D.cells[e];
    element::lame_from_young(L.youngs[c], L.poisson[c], &C.lambda[e], &C.mu[e]);
    C.rho[e] = L.density[c];
    for (int d = 0; d < 3; ++d) C.origin[e][d] = L.spec.origin[d] + L.spec.h * L.ijk[c][d];
  }
  // Shared stiffness per distinct (lambda, mu), up to a limit that keeps it small.
  constexpr std::size_t kMaxKinds = 256;
  std::map<std::pair<double, double>, std::int32_t> kinds;
  C.kind.assign(n, -1);
  for (std::size_t e = 0; e < n && kinds.size() <= kMaxKinds; ++e)
    kinds.emplace(std::make_pair(C.lambda[e], C.mu[e]), std::int32_t(kinds.size()));
  if (kinds.size() <= kMaxKinds) {
    C.kind_stiffness.resize(kinds.size());
    for (const auto& [lm, id] : kinds)
      element::cell_stiffness(element::reference_matrices(), C.h, lm.first, lm.second,
                              C.kind_stiffness[id].data());
    for (std::size_t e = 0; e < n; ++e) C.kind[e] = kinds.at({C.lambda[e], C.mu[e]});
  }
  set_identity_rotations(C);
  return C;
}

void set_identity_rotations(CellData& C) {
  // Nothing stored: 72 bytes per cell (about 24 per DOF) that a linear run never reads.
  C.identity_rotations = true;
  std::vector<double>().swap(C.rotation);
}

void cell_rotations(const topology::DofLayout& D, const CellData& C, const double* u_local,
                    double* R) {
  const std::size_t n = D.cells.size();
  if (C.rotation_group.empty()) {
    // The loop layer's body, the one the CUDA backend launches (cuda::cell_rotations).
    if (n)
      backend::for_each(std::int64_t(n), CellRotation{D.cell_corners[0].data(), u_local, C.h, R});
    return;
  }
  // The mean of F over the group's cells weighted by their shear modulus (the polar factor
  // of the sum is that of the mean): in a homogeneous group the volume average (the cells
  // are of equal volume; Wu 2014, eq. 4.7); where a group mixes a stiff and a soft material
  // the rotation follows the stiff part, which carries the force (doc/theory.md,
  // "Composite elements").
  std::vector<double> sum(9 * std::size_t(C.num_rotation_groups), 0.0), group_R(sum.size());
  for (std::size_t e = 0; e < n; ++e) {
    double u24[24], F[9];
    element::gather_cell(u_local, D.cell_corners[e].data(), u24);
    element::deformation_gradient_at_centre(u24, C.h, F);
    for (int k = 0; k < 9; ++k) sum[9 * std::size_t(C.rotation_group[e]) + k] += C.mu[e] * F[k];
  }
  for (std::int32_t g = 0; g < C.num_rotation_groups; ++g)
    element::polar_rotation(&sum[9 * std::size_t(g)], &group_R[9 * std::size_t(g)]);
  for (std::size_t e = 0; e < n; ++e)
    std::copy_n(&group_R[9 * std::size_t(C.rotation_group[e])], 9, &R[9 * e]);
}

void update_rotations(const topology::DofLayout& D, const double* u_local, CellData& C) {
  C.identity_rotations = false;
  C.rotation.resize(9 * D.cells.size());
  cell_rotations(D, C, u_local, C.rotation.data());
}

double strain_energy_local(const topology::DofLayout& D, const CellData& C, const double* u,
                           const double* rotations) {
  double buffer[element::kElementMatrixSize], x24[24], u24[24], d[24], Kd[24];
  element::corner_positions(C.h, nullptr, x24);
  double w = 0.0;
  for (std::size_t e = 0; e < D.cells.size(); ++e) {
    element::gather_cell(u, D.cell_corners[e].data(), u24);
    const double* R = rotations ? &rotations[9 * e] : kIdentity;
    element::corotated_displacement(R, x24, u24, d);
    element::element_matvec(cell_stiffness(C, e, buffer), d, Kd);
    for (int i = 0; i < 24; ++i) w += 0.5 * d[i] * Kd[i];
  }
  return w;
}

PetscErrorCode create_matrix(MPI_Comm comm, const topology::VertexCopies& V,
                             const topology::DofLayout& D, Mat* A) {
  PetscFunctionBeginUser;
  // Neighbour copies of each owned copy: all corners of all its incident cells. Every
  // rank has the whole (replicated) lattice, so cells of other ranks are visible too.
  const PetscInt first = D.first_owned_block();
  std::vector<std::vector<PetscInt>> neighbours(D.num_owned);
  for (std::size_t c = 0; c < V.cell_corners.size(); ++c) {
    for (int q = 0; q < 8; ++q) {
      const PetscInt row = D.global_block[V.cell_corners[c][q]] - first;
      if (row < 0 || row >= D.num_owned) continue;
      for (int p = 0; p < 8; ++p) neighbours[row].push_back(D.global_block[V.cell_corners[c][p]]);
    }
  }
  std::vector<PetscInt> d_nnz(D.num_owned), o_nnz(D.num_owned);
  const PetscInt last = first + D.num_owned;
  for (PetscInt r = 0; r < D.num_owned; ++r) {
    auto& nb = neighbours[r];
    std::sort(nb.begin(), nb.end());
    nb.erase(std::unique(nb.begin(), nb.end()), nb.end());
    d_nnz[r] =
        std::count_if(nb.begin(), nb.end(), [&](PetscInt g) { return g >= first && g < last; });
    o_nnz[r] = PetscInt(nb.size()) - d_nnz[r];
    std::vector<PetscInt>().swap(nb);
  }
  PetscCall(MatCreate(comm, A));
  PetscCall(MatSetSizes(*A, 3 * D.num_owned, 3 * D.num_owned, PETSC_DETERMINE, PETSC_DETERMINE));
  PetscCall(MatSetType(*A, MATAIJ));
  PetscCall(MatSetBlockSize(*A, 3));
  PetscCall(MatXAIJSetPreallocation(*A, 3, d_nnz.data(), o_nnz.data(), nullptr, nullptr));
  PetscCall(MatSetOption(*A, MAT_SYMMETRIC, PETSC_TRUE));
  PetscCall(MatSetOption(*A, MAT_SYMMETRY_ETERNAL, PETSC_TRUE));
  PetscCall(MatSetOption(*A, MAT_NEW_NONZERO_ALLOCATION_ERR, PETSC_TRUE));
  PetscCall(MatSetOption(*A, MAT_IGNORE_ZERO_ENTRIES, PETSC_FALSE));
  PetscCall(MatSetOption(*A, MAT_KEEP_NONZERO_PATTERN, PETSC_TRUE));
  PetscFunctionReturn(0);
}

PetscErrorCode assemble_matrix(const topology::DofLayout& D, const CellData& C,
                               const OperatorWeights& w, Mat A) {
  return assemble(FineCells(D, C, w), nullptr, A);
}

PetscErrorCode global_to_local(DM dm, Vec global, Vec local) {
  PetscFunctionBeginUser;
  PetscCall(DMGlobalToLocalBegin(dm, global, INSERT_VALUES, local));
  PetscCall(DMGlobalToLocalEnd(dm, global, INSERT_VALUES, local));
  PetscFunctionReturn(0);
}

PetscErrorCode apply(DM dm, const topology::DofLayout& D, const CellData& C,
                     const OperatorWeights& w, Vec x, Vec y) {
  return apply(dm, FineCells(D, C, w), x, y);
}

PetscErrorCode add_corotational_rhs(DM dm, const topology::DofLayout& D, const CellData& C,
                                    double stiffness_weight, Vec b) {
  PetscFunctionBeginUser;
  if (C.identity_rotations) PetscFunctionReturn(0);  // R = I: nothing to add
  Vec bl;
  PetscCall(DMGetLocalVector(dm, &bl));
  PetscCall(VecSet(bl, 0.0));
  PetscScalar* ba;
  PetscCall(VecGetArray(bl, &ba));
  double buffer[element::kElementMatrixSize], x24[24], be[24];
  element::corner_positions(C.h, nullptr, x24);
  for (std::size_t e = 0; e < D.cells.size(); ++e) {
    const double* K = cell_stiffness(C, e, buffer);
    element::corotational_rhs(&C.rotation[9 * e], K, x24, be);
    element::scatter_add_cell(be, D.cell_corners[e].data(), ba, stiffness_weight);
  }
  PetscCall(VecRestoreArray(bl, &ba));
  PetscCall(DMLocalToGlobalBegin(dm, bl, ADD_VALUES, b));
  PetscCall(DMLocalToGlobalEnd(dm, bl, ADD_VALUES, b));
  PetscCall(DMRestoreLocalVector(dm, &bl));
  PetscFunctionReturn(0);
}

PetscErrorCode corotated_displacements(DM dm, const topology::DofLayout& D, const CellData& C,
                                       Vec u, std::vector<double>* d) {
  PetscFunctionBeginUser;
  Vec ul;
  PetscCall(DMGetLocalVector(dm, &ul));
  PetscCall(global_to_local(dm, u, ul));
  const PetscScalar* a;
  PetscCall(VecGetArrayRead(ul, &a));
  double x24[24], u24[24];
  element::corner_positions(C.h, nullptr, x24);
  d->resize(24 * D.cells.size());
  std::vector<double> R(9 * D.cells.size());
  cell_rotations(D, C, a, R.data());
  for (std::size_t e = 0; e < D.cells.size(); ++e) {
    element::gather_cell(a, D.cell_corners[e].data(), u24);
    element::corotated_displacement(&R[9 * e], x24, u24, &(*d)[24 * e]);
  }
  PetscCall(VecRestoreArrayRead(ul, &a));
  PetscCall(DMRestoreLocalVector(dm, &ul));
  PetscFunctionReturn(0);
}

PetscErrorCode assemble_midpoint_force(DM dm, const topology::DofLayout& D, CellData& C,
                                       const std::vector<double>& d0, Vec u0, Vec u1, Vec f,
                                       double energy[2]) {
  PetscFunctionBeginUser;
  Vec l0, l1, fl;
  PetscCall(DMGetLocalVector(dm, &l0));
  PetscCall(DMGetLocalVector(dm, &l1));
  PetscCall(DMGetLocalVector(dm, &fl));
  PetscCall(global_to_local(dm, u0, l0));
  PetscCall(global_to_local(dm, u1, l1));
  PetscCall(VecSet(fl, 0.0));
  const PetscScalar *a0, *a1;
  PetscScalar* fa;
  PetscCall(VecGetArrayRead(l0, &a0));
  PetscCall(VecGetArrayRead(l1, &a1));
  PetscCall(VecGetArray(fl, &fa));
  double buffer[element::kElementMatrixSize], x24[24], v0[24], v1[24], fe[24];
  element::corner_positions(C.h, nullptr, x24);
  energy[0] = energy[1] = 0.0;
  C.identity_rotations = false;
  C.rotation.resize(9 * D.cells.size());
  // Rotation groups: the rotations at u1 and at the mid-point are the groups' (each cell's
  // own are computed inside midpoint_force otherwise).
  std::vector<double> R1, Rm;
  if (!C.rotation_group.empty()) {
    const std::size_t nl = 3 * std::size_t(D.num_local());
    std::vector<double> um(nl);
    for (std::size_t i = 0; i < nl; ++i) um[i] = 0.5 * (a0[i] + a1[i]);
    R1.resize(9 * D.cells.size());
    Rm.resize(R1.size());
    cell_rotations(D, C, a1, R1.data());
    cell_rotations(D, C, um.data(), Rm.data());
  }
  // Groups: the forces of all cells first, then the moment of each group's forces about
  // its mid-point configuration is removed (element::remove_moment) before they are added.
  const bool groups = !C.rotation_group.empty();
  std::vector<double> group_f, group_z;
  std::vector<std::int64_t> group_start;
  if (groups) {
    group_start.assign(std::size_t(C.num_rotation_groups) + 1, 0);
    for (auto g : C.rotation_group) ++group_start[std::size_t(g) + 1];
    for (std::size_t g = 0; g < std::size_t(C.num_rotation_groups); ++g)
      group_start[g + 1] += group_start[g];
    group_f.resize(24 * D.cells.size());
    group_z.resize(24 * D.cells.size());
  }
  std::vector<std::int64_t> next(group_start.begin(), group_start.end());
  std::vector<std::int64_t> slot(groups ? D.cells.size() : 0);
  for (std::size_t e = 0; e < D.cells.size(); ++e) {
    element::gather_cell(a0, D.cell_corners[e].data(), v0);
    element::gather_cell(a1, D.cell_corners[e].data(), v1);
    const auto r = element::midpoint_force(cell_stiffness(C, e, buffer), C.h, x24, &d0[24 * e], v0,
                                           v1, fe, groups ? &R1[9 * e] : nullptr,
                                           groups ? &Rm[9 * e] : nullptr, !groups);
    if (groups) {
      // This cell's corners and forces in its group's arrays (mid-point positions).
      slot[e] = next[std::size_t(C.rotation_group[e])]++;
      for (int k = 0; k < 24; ++k) {
        group_f[24 * slot[e] + k] = fe[k];
        group_z[24 * slot[e] + k] = C.origin[e][k % 3] + x24[k] + 0.5 * (v0[k] + v1[k]);
      }
    }
    std::copy(r.rotation, r.rotation + 9, &C.rotation[9 * e]);
    energy[0] += r.energy0;
    energy[1] += r.energy1;
    if (!groups) element::scatter_add_cell(fe, D.cell_corners[e].data(), fa);
  }
  if (groups) {
    for (std::size_t g = 0; g < std::size_t(C.num_rotation_groups); ++g) {
      const auto b = group_start[g], n = group_start[g + 1] - b;
      if (n > 0) element::remove_moment(int(8 * n), &group_z[24 * b], &group_f[24 * b]);
    }
    for (std::size_t e = 0; e < D.cells.size(); ++e)
      element::scatter_add_cell(&group_f[24 * slot[e]], D.cell_corners[e].data(), fa);
  }
  PetscCall(VecRestoreArray(fl, &fa));
  PetscCall(VecRestoreArrayRead(l1, &a1));
  PetscCall(VecRestoreArrayRead(l0, &a0));
  PetscCall(VecSet(f, 0.0));
  PetscCall(DMLocalToGlobalBegin(dm, fl, ADD_VALUES, f));
  PetscCall(DMLocalToGlobalEnd(dm, fl, ADD_VALUES, f));
  PetscCall(DMRestoreLocalVector(dm, &fl));
  PetscCall(DMRestoreLocalVector(dm, &l1));
  PetscCall(DMRestoreLocalVector(dm, &l0));
  PetscFunctionReturn(0);
}

PetscErrorCode reference_positions(DM dm, const lattice::Lattice& L,
                                   const topology::VertexCopies& V, const topology::DofLayout& D,
                                   Vec* x) {
  PetscFunctionBeginUser;
  PetscCall(DMCreateGlobalVector(dm, x));
  PetscScalar* a;
  PetscCall(VecGetArray(*x, &a));
  for (std::int32_t i = 0; i < D.num_owned; ++i) {
    const auto& v = V.vertex[D.copies[i]];
    for (int d = 0; d < 3; ++d) a[3 * i + d] = L.spec.origin[d] + L.spec.h * v[d];
  }
  PetscCall(VecRestoreArray(*x, &a));
  PetscFunctionReturn(0);
}

}  // namespace hexcut::assembly
