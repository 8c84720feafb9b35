#include "topology/partition.hpp"

#include <metis.h>

#include <algorithm>
#include <map>
#include <stdexcept>
#include <string>

namespace hexcut::topology {

Partition partition_lattice(const lattice::Lattice& L, const VertexCopies& V, int num_ranks,
                            int superblock, int min_superblock) {
  Partition P;
  P.num_ranks = num_ranks;
  const std::int32_t n = L.num_cells();
  P.cell_rank.assign(n, 0);
  if (num_ranks > 1) {
    int sb = superblock;
    std::map<std::int64_t, int> block_id;  // dense super-block index -> graph vertex
    std::vector<int> block_of_cell(n);
    std::array<std::int64_t, 3> nb{};
    for (;;) {
      block_id.clear();
      for (int d = 0; d < 3; ++d) nb[d] = (L.spec.dims[d] + sb - 1) / sb;
      for (std::int32_t c = 0; c < n; ++c) {
        const auto& p = L.ijk[c];
        const std::int64_t key = p[0] / sb + nb[0] * (p[1] / sb + nb[1] * std::int64_t(p[2] / sb));
        auto it = block_id.emplace(key, int(block_id.size())).first;
        block_of_cell[c] = it->second;
      }
      if (int(block_id.size()) >= 2 * num_ranks || sb <= std::max(1, min_superblock)) break;
      sb /= 2;
    }
    P.superblock = sb;
    const idx_t nblocks = idx_t(block_id.size());
    if (nblocks < num_ranks)
      throw std::runtime_error("cannot partition " + std::to_string(n) + " cells over " +
                               std::to_string(num_ranks) + " ranks: too few cells");
    // Super-block graph: face adjacency, vertex weight = material cells.
    std::vector<idx_t> weight(nblocks, 0);
    for (std::int32_t c = 0; c < n; ++c) ++weight[block_of_cell[c]];
    std::vector<std::vector<idx_t>> adj(nblocks);
    for (const auto& [key, id] : block_id) {
      const std::int64_t bi = key % nb[0], bj = (key / nb[0]) % nb[1], bk = key / (nb[0] * nb[1]);
      const std::int64_t b[3] = {bi, bj, bk};
      for (int d = 0; d < 3; ++d)
        for (int s = -1; s <= 1; s += 2) {
          std::int64_t q[3] = {b[0], b[1], b[2]};
          q[d] += s;
          if (q[d] < 0 || q[d] >= nb[d]) continue;
          auto it = block_id.find(q[0] + nb[0] * (q[1] + nb[1] * q[2]));
          if (it != block_id.end()) adj[id].push_back(it->second);
        }
    }
    std::vector<idx_t> xadj(nblocks + 1, 0), adjncy;
    for (idx_t b = 0; b < nblocks; ++b) {
      adjncy.insert(adjncy.end(), adj[b].begin(), adj[b].end());
      xadj[b + 1] = idx_t(adjncy.size());
    }
    idx_t ncon = 1, nparts = num_ranks, objval = 0, nv = nblocks;
    std::vector<idx_t> part(nblocks, 0);
    idx_t options[METIS_NOPTIONS];
    METIS_SetDefaultOptions(options);
    options[METIS_OPTION_SEED] = 1;  // deterministic on every rank
    const int status =
        METIS_PartGraphKway(&nv, &ncon, xadj.data(), adjncy.data(), weight.data(), nullptr, nullptr,
                            &nparts, nullptr, nullptr, options, &objval, part.data());
    if (status != METIS_OK) throw std::runtime_error("METIS_PartGraphKway failed");
    for (std::int32_t c = 0; c < n; ++c) P.cell_rank[c] = int(part[block_of_cell[c]]);
  }
  P.copy_rank.resize(V.num_copies);
  for (std::int32_t v = 0; v < V.num_copies; ++v) P.copy_rank[v] = P.cell_rank[V.first_cell[v]];
  return P;
}

}  // namespace hexcut::topology
