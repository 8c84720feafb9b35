#include "topology/vertex_copies.hpp"

#include <algorithm>

namespace hexcut::topology {
namespace {

int find_root(std::array<int, 8>& parent, int a) {
  while (parent[a] != a) a = parent[a] = parent[parent[a]];
  return a;
}

}  // namespace

VertexCopies build_vertex_copies(const lattice::Lattice& L) {
  VertexCopies V;
  const std::int32_t n = L.num_cells();
  V.cell_corners.assign(n, {-1, -1, -1, -1, -1, -1, -1, -1});
  for (std::int32_t c = 0; c < n; ++c) {
    for (int q = 0; q < 8; ++q) {
      if (V.cell_corners[c][q] >= 0) continue;
      const auto off = corner_offset(q);
      const int vi = L.ijk[c][0] + off[0], vj = L.ijk[c][1] + off[1], vk = L.ijk[c][2] + off[2];
      // The 8 cells around vertex v: slot s = a + 2b + 4c holds cell (v - 1 + (a,b,c)),
      // which touches v at its corner 7 - s.
      std::array<std::int32_t, 8> cells;
      std::array<int, 8> parent;
      for (int s = 0; s < 8; ++s) {
        const auto o = corner_offset(s);
        cells[s] = L.find(vi - 1 + o[0], vj - 1 + o[1], vk - 1 + o[2]);
        parent[s] = s;
      }
      // Union slots joined by a link between the two cells (slots differ in one bit d,
      // the lower slot's cell owns the +d link).
      for (int s = 0; s < 8; ++s) {
        if (cells[s] < 0) continue;
        for (int d = 0; d < 3; ++d) {
          if (s & (1 << d)) continue;
          const int t = s | (1 << d);
          if (cells[t] >= 0 && L.linked(cells[s], d)) {
            const int rs = find_root(parent, s), rt = find_root(parent, t);
            if (rs != rt) parent[std::max(rs, rt)] = std::min(rs, rt);
          }
        }
      }
      // One copy per component, numbered by the lowest slot of the component (stable).
      std::array<std::int32_t, 8> copy_of_root;
      copy_of_root.fill(-1);
      for (int s = 0; s < 8; ++s) {
        if (cells[s] < 0) continue;
        const int r = find_root(parent, s);
        if (copy_of_root[r] < 0) {
          copy_of_root[r] = V.num_copies++;
          V.vertex.push_back({vi, vj, vk});
        }
        V.cell_corners[cells[s]][7 - s] = copy_of_root[r];
      }
    }
  }
  V.first_cell.assign(V.num_copies, n);
  for (std::int32_t c = 0; c < n; ++c)
    for (int q = 0; q < 8; ++q)
      V.first_cell[V.cell_corners[c][q]] = std::min(V.first_cell[V.cell_corners[c][q]], c);
  return V;
}

}  // namespace hexcut::topology
