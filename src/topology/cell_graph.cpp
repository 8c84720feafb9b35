#include "topology/cell_graph.hpp"

#include <algorithm>

namespace hexcut::topology {

void set_links(CellGraph& G, std::vector<std::array<std::int32_t, 2>> pairs) {
  const std::int32_t n = G.num_cells();
  G.link_offset.assign(n + 1, 0);
  for (const auto& p : pairs) {
    ++G.link_offset[p[0] + 1];
    ++G.link_offset[p[1] + 1];
  }
  for (std::int32_t c = 0; c < n; ++c) G.link_offset[c + 1] += G.link_offset[c];
  G.link_target.assign(G.link_offset[n], -1);
  std::vector<std::int32_t> next(G.link_offset.begin(), G.link_offset.end() - 1);
  for (const auto& p : pairs) {
    G.link_target[next[p[0]]++] = p[1];
    G.link_target[next[p[1]]++] = p[0];
  }
  for (std::int32_t c = 0; c < n; ++c)
    std::sort(G.link_target.begin() + G.link_offset[c],
              G.link_target.begin() + G.link_offset[c + 1]);
}

CellGraph graph_from_lattice(const lattice::Lattice& L) {
  CellGraph G;
  G.spec = L.spec;
  G.ijk = L.ijk;
  std::vector<std::array<std::int32_t, 2>> pairs;
  for (std::int32_t c = 0; c < L.num_cells(); ++c)
    for (int d = 0; d < 3; ++d)
      if (L.linked(c, d)) {
        auto q = L.ijk[c];
        ++q[d];
        pairs.push_back({c, L.find(q[0], q[1], q[2])});
      }
  set_links(G, std::move(pairs));
  return G;
}

}  // namespace hexcut::topology
