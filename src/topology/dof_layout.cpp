#include "topology/dof_layout.hpp"

#include <algorithm>
#include <unordered_map>

namespace hexcut::topology {

DofLayout build_dof_layout(const VertexCopies& V, const Partition& P, int rank) {
  DofLayout D;
  D.rank = rank;
  D.num_ranks = P.num_ranks;
  D.num_global_copies = V.num_copies;
  std::vector<PetscInt> count(P.num_ranks, 0);
  for (std::int32_t v = 0; v < V.num_copies; ++v) ++count[P.copy_rank[v]];
  D.owned_begin.assign(P.num_ranks + 1, 0);
  for (int r = 0; r < P.num_ranks; ++r) D.owned_begin[r + 1] = D.owned_begin[r] + count[r];
  D.global_block.resize(V.num_copies);
  std::vector<PetscInt> next(D.owned_begin.begin(), D.owned_begin.end() - 1);
  for (std::int32_t v = 0; v < V.num_copies; ++v) {
    const int r = P.copy_rank[v];
    D.global_block[v] = next[r]++;
    if (r == rank) D.copies.push_back(v);
  }
  D.num_owned = std::int32_t(D.copies.size());

  for (std::int32_t c = 0; c < std::int32_t(P.cell_rank.size()); ++c)
    if (P.cell_rank[c] == rank) D.cells.push_back(c);
  std::unordered_map<std::int32_t, std::int32_t> local_of;
  local_of.reserve(D.copies.size() * 2);
  for (std::int32_t i = 0; i < D.num_owned; ++i) local_of[D.copies[i]] = i;
  std::vector<std::int32_t> ghosts;
  for (std::int32_t c : D.cells)
    for (std::int32_t v : V.cell_corners[c])
      if (P.copy_rank[v] != rank && !local_of.count(v)) {
        local_of[v] = -1;
        ghosts.push_back(v);
      }
  std::sort(ghosts.begin(), ghosts.end());
  for (std::int32_t v : ghosts) {
    local_of[v] = std::int32_t(D.copies.size());
    D.copies.push_back(v);
  }
  D.cell_corners.resize(D.cells.size());
  for (size_t i = 0; i < D.cells.size(); ++i)
    for (int q = 0; q < 8; ++q) D.cell_corners[i][q] = local_of.at(V.cell_corners[D.cells[i]][q]);
  return D;
}

PetscErrorCode create_ghost_scatter(MPI_Comm comm, const DofLayout& D, PetscInt bs, Vec* global,
                                    Vec* local, VecScatter* g2l) {
  PetscFunctionBeginUser;
  PetscCall(VecCreateMPI(comm, bs * D.num_owned, PETSC_DETERMINE, global));
  PetscCall(VecSetBlockSize(*global, bs));
  PetscCall(VecCreateSeq(PETSC_COMM_SELF, bs * D.num_local(), local));
  PetscCall(VecSetBlockSize(*local, bs));
  std::vector<PetscInt> gidx(D.num_local());
  for (std::int32_t i = 0; i < D.num_local(); ++i) gidx[i] = D.global_block[D.copies[i]];
  IS is_global, is_local;
  PetscCall(ISCreateBlock(PETSC_COMM_SELF, bs, D.num_local(), gidx.data(), PETSC_COPY_VALUES,
                          &is_global));
  PetscCall(ISCreateStride(PETSC_COMM_SELF, bs * D.num_local(), 0, 1, &is_local));
  PetscCall(VecScatterCreate(*global, is_global, *local, is_local, g2l));
  PetscCall(ISDestroy(&is_global));
  PetscCall(ISDestroy(&is_local));
  PetscFunctionReturn(0);
}

PetscErrorCode create_dm(MPI_Comm comm, const DofLayout& D, DM* dm) {
  PetscFunctionBeginUser;
  Vec global, local;
  VecScatter g2l, l2g;
  PetscCall(create_ghost_scatter(comm, D, 3, &global, &local, &g2l));
  // DMShell's local-to-global runs its scatter forward: build the reverse direction.
  std::vector<PetscInt> gidx(D.num_local());
  for (std::int32_t i = 0; i < D.num_local(); ++i) gidx[i] = D.global_block[D.copies[i]];
  IS is_global, is_local;
  PetscCall(
      ISCreateBlock(PETSC_COMM_SELF, 3, D.num_local(), gidx.data(), PETSC_COPY_VALUES, &is_global));
  PetscCall(ISCreateStride(PETSC_COMM_SELF, 3 * D.num_local(), 0, 1, &is_local));
  PetscCall(VecScatterCreate(local, is_local, global, is_global, &l2g));
  PetscCall(ISDestroy(&is_global));
  PetscCall(ISDestroy(&is_local));

  PetscCall(DMShellCreate(comm, dm));
  PetscCall(DMShellSetGlobalVector(*dm, global));
  PetscCall(DMShellSetLocalVector(*dm, local));
  PetscCall(DMShellSetGlobalToLocalVecScatter(*dm, g2l));
  PetscCall(DMShellSetLocalToGlobalVecScatter(*dm, l2g));
  PetscCall(PetscObjectSetName((PetscObject)*dm, "hexcut-dofs"));
  PetscCall(DMSetUp(*dm));
  PetscCall(VecScatterDestroy(&g2l));
  PetscCall(VecScatterDestroy(&l2g));
  PetscCall(VecDestroy(&global));
  PetscCall(VecDestroy(&local));
  PetscFunctionReturn(0);
}

PetscErrorCode create_natural_scatter(MPI_Comm comm, PetscInt n_global,
                                      const std::vector<std::int32_t>& canonical,
                                      PetscInt petsc_begin, PetscInt block, NaturalScatter* out) {
  PetscFunctionBeginUser;
  const PetscInt n = PetscInt(canonical.size());
  Vec petsc_order;
  PetscCall(VecCreateMPIWithArray(comm, block, block * n, PETSC_DETERMINE, nullptr, &petsc_order));
  // The natural vector: canonical rows split evenly over ranks, `block` values per row.
  PetscInt rows = PETSC_DECIDE;
  PetscCall(PetscSplitOwnership(comm, &rows, &n_global));
  PetscCall(VecCreateMPI(comm, block * rows, PETSC_DETERMINE, &out->natural));
  PetscCall(VecSetBlockSize(out->natural, block));
  PetscInt lo, hi;
  PetscCall(VecGetOwnershipRange(out->natural, &lo, &hi));
  out->row_begin = lo / block;
  out->rows = rows;
  out->block = block;
  std::vector<PetscInt> from(n), to(n);
  for (PetscInt i = 0; i < n; ++i) {
    from[i] = petsc_begin + i;
    to[i] = canonical[i];
  }
  IS is_from, is_to;
  PetscCall(ISCreateBlock(comm, block, n, from.data(), PETSC_COPY_VALUES, &is_from));
  PetscCall(ISCreateBlock(comm, block, n, to.data(), PETSC_COPY_VALUES, &is_to));
  PetscCall(VecScatterCreate(petsc_order, is_from, out->natural, is_to, &out->scatter));
  PetscCall(ISDestroy(&is_from));
  PetscCall(ISDestroy(&is_to));
  PetscCall(VecDestroy(&petsc_order));
  PetscFunctionReturn(0);
}

PetscErrorCode destroy_natural_scatter(NaturalScatter* s) {
  PetscFunctionBeginUser;
  PetscCall(VecScatterDestroy(&s->scatter));
  PetscCall(VecDestroy(&s->natural));
  PetscFunctionReturn(0);
}

}  // namespace hexcut::topology
