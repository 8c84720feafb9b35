#include "multigrid/interpolation_region.hpp"

#include <algorithm>
#include <cstdint>

#include "element/trilinear.hpp"

namespace hexcut::multigrid {

using hierarchy::Level;

Region::~Region() {
  VecDestroy(&global);
  VecDestroy(&local);
  VecScatterDestroy(&scatter);
}

std::vector<char> corners_of_children(const Level& fine, const std::vector<char>& coarse_marked) {
  std::vector<char> in(std::size_t(fine.copies().num_copies), 0);
  for (std::int32_t c = 0; c < fine.graph.num_cells(); ++c)
    if (coarse_marked[std::size_t(fine.parent[c])])
      for (auto v : fine.copies().cell_corners[c]) in[std::size_t(v)] = 1;
  return in;
}

PetscErrorCode build_region(MPI_Comm comm, const Level& fine, const std::vector<char>& in,
                            PetscInt block, Region* R, std::int64_t* global_count) {
  PetscFunctionBeginUser;
  const auto& V = fine.copies();
  const auto& D = fine.layout();
  // Region copies in canonical order; global ids by (owner, canonical).
  std::vector<std::int32_t> canonical;  // region index -> canonical fine copy
  for (std::int32_t v = 0; v < V.num_copies; ++v)
    if (in[std::size_t(v)]) canonical.push_back(v);
  const std::int32_t n = std::int32_t(canonical.size());
  *global_count = n;
  auto& RL = R->layout;
  RL.rank = D.rank;
  RL.num_ranks = D.num_ranks;
  RL.num_global_copies = n;
  RL.owned_begin.assign(D.num_ranks + 1, 0);
  for (auto v : canonical) ++RL.owned_begin[fine.partition().copy_rank[v] + 1];
  for (int r = 0; r < D.num_ranks; ++r) RL.owned_begin[r + 1] += RL.owned_begin[r];
  RL.global_block.resize(n);
  std::vector<PetscInt> next(RL.owned_begin.begin(), RL.owned_begin.end() - 1);
  std::vector<std::int32_t> region_of(V.num_copies, -1);
  for (std::int32_t i = 0; i < n; ++i) {
    region_of[canonical[i]] = i;
    RL.global_block[i] = next[fine.partition().copy_rank[canonical[i]]]++;
  }
  // Local region copies in the fine layout's order: owned first, then ghosts.
  R->local_of.assign(D.num_local(), -1);
  for (std::int32_t i = 0; i < D.num_local(); ++i) {
    const auto r = region_of[D.copies[i]];
    if (r < 0) continue;
    R->local_of[i] = std::int32_t(RL.copies.size());
    R->fine_of.push_back(i);
    RL.copies.push_back(r);
    if (i < D.num_owned) ++RL.num_owned;
  }
  if (n > 0)
    PetscCall(topology::create_ghost_scatter(comm, RL, block, &R->global, &R->local, &R->scatter));
  PetscFunctionReturn(0);
}

PetscErrorCode to_local(const Region& R, Vec global) {
  PetscFunctionBeginUser;
  PetscCall(VecScatterBegin(R.scatter, global, R.local, INSERT_VALUES, SCATTER_FORWARD));
  PetscCall(VecScatterEnd(R.scatter, global, R.local, INSERT_VALUES, SCATTER_FORWARD));
  PetscFunctionReturn(0);
}

PetscErrorCode sum_to_owners(const Region& R, Vec global) {
  PetscFunctionBeginUser;
  PetscCall(VecSet(global, 0.0));
  PetscCall(VecScatterBegin(R.scatter, R.local, global, ADD_VALUES, SCATTER_REVERSE));
  PetscCall(VecScatterEnd(R.scatter, R.local, global, ADD_VALUES, SCATTER_REVERSE));
  PetscFunctionReturn(0);
}

PetscErrorCode row_patterns(const Level& fine, const Level& coarse, const Region& R,
                            std::vector<std::array<std::int32_t, kPatternSlots>>* pattern_out) {
  PetscFunctionBeginUser;
  const auto& D = fine.layout();
  const auto& DC = coarse.layout();
  const std::int32_t nr = R.layout.num_local();
  // Coarse canonical copy -> local coarse copy.
  std::vector<std::int32_t> coarse_local(coarse.copies().num_copies, -1);
  for (std::int32_t i = 0; i < DC.num_local(); ++i) coarse_local[DC.copies[i]] = i;
  // Over the whole, replicated level, so that owners and ghosts agree.
  auto& pattern = *pattern_out;
  pattern.assign(nr, {});
  std::vector<char> started(nr, 0);
  std::vector<std::int32_t> region_of_canonical(fine.copies().num_copies, -1);
  for (std::int32_t r = 0; r < nr; ++r) region_of_canonical[D.copies[R.fine_of[r]]] = r;
  for (std::int32_t c = 0; c < fine.graph.num_cells(); ++c) {
    const auto& pc = coarse.copies().cell_corners[fine.parent[c]];
    for (auto v : fine.copies().cell_corners[c]) {
      const auto r = region_of_canonical[v];
      if (r < 0) continue;
      auto& p = pattern[r];
      if (!started[r]) {
        std::copy(pc.begin(), pc.end(), p.begin());
        started[r] = 1;
        continue;
      }
      for (auto& J : p)
        if (J >= 0 && std::find(pc.begin(), pc.end(), J) == pc.end()) J = -1;
    }
  }
  for (auto& p : pattern) {
    std::sort(p.begin(), p.end(), [](std::int32_t a, std::int32_t b) {
      return (a < 0 ? INT32_MAX : a) < (b < 0 ? INT32_MAX : b);
    });
    for (auto& J : p) {
      if (J < 0) continue;
      J = coarse_local[J];
      PetscCheck(J >= 0, PETSC_COMM_SELF, PETSC_ERR_PLIB,
                 "gmg: a coarse copy of an interpolation pattern is not on this rank");
    }
  }
  PetscFunctionReturn(0);
}

PetscErrorCode region_cells(const Level& fine, const Level& coarse, const Region& R,
                            const std::vector<std::array<std::int32_t, kPatternSlots>>& pattern,
                            std::vector<RegionCell>* cells) {
  PetscFunctionBeginUser;
  const auto& D = fine.layout();
  const auto& DC = coarse.layout();
  std::vector<std::int32_t> coarse_cell_local(coarse.graph.num_cells(), -1);
  for (std::size_t C = 0; C < DC.cells.size(); ++C)
    coarse_cell_local[DC.cells[C]] = std::int32_t(C);
  cells->clear();
  for (std::size_t e = 0; e < D.cells.size(); ++e) {
    bool any = false;
    for (auto v : D.cell_corners[e]) any = any || R.local_of[v] >= 0;
    if (!any) continue;
    RegionCell rc;
    rc.e = std::int32_t(e);
    rc.parent = coarse_cell_local[fine.parent[D.cells[e]]];
    PetscCheck(rc.parent >= 0, PETSC_COMM_SELF, PETSC_ERR_PLIB, "gmg: a parent is not local");
    const auto& p = fine.graph.ijk[D.cells[e]];
    rc.octant = element::parity_octant(p[0], p[1], p[2]);
    const auto& pc = DC.cell_corners[rc.parent];
    for (int q = 0; q < 8; ++q) {
      rc.parent_corner[q].fill(-1);
      const auto r = R.local_of[D.cell_corners[e][q]];
      if (r < 0) continue;
      for (int k = 0; k < kPatternSlots && pattern[r][k] >= 0; ++k)
        for (int j = 0; j < 8; ++j)
          if (pc[j] == pattern[r][k]) rc.parent_corner[q][k] = std::int8_t(j);
    }
    cells->push_back(rc);
  }
  PetscFunctionReturn(0);
}

}  // namespace hexcut::multigrid
