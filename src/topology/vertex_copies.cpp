#include "topology/vertex_copies.hpp"

#include <algorithm>
#include <numeric>

#include "topology/union_find.hpp"

namespace hexcut::topology {
namespace {

/// Cells grouped by position: cells_at(p) lists the cells at dense position p.
struct PositionIndex {
  std::vector<std::int32_t> offset, cells;
  PositionIndex(const CellGraph& G) {
    const auto n = G.spec.num_cells();
    offset.assign(n + 1, 0);
    for (const auto& p : G.ijk) ++offset[G.spec.cell_index(p[0], p[1], p[2]) + 1];
    for (std::int64_t i = 0; i < n; ++i) offset[i + 1] += offset[i];
    cells.resize(G.ijk.size());
    std::vector<std::int32_t> next(offset.begin(), offset.end() - 1);
    for (std::int32_t c = 0; c < G.num_cells(); ++c) {
      const auto& p = G.ijk[c];
      cells[next[G.spec.cell_index(p[0], p[1], p[2])]++] = c;
    }
  }
};

}  // namespace

VertexCopies build_vertex_copies(const CellGraph& G) {
  VertexCopies V;
  const std::int32_t n = G.num_cells();
  const auto& dims = G.spec.dims;
  const PositionIndex index(G);
  V.cell_corners.assign(n, {-1, -1, -1, -1, -1, -1, -1, -1});
  std::vector<std::int32_t> cells;  // cells around the current vertex
  std::vector<int> slot, copy_of_root;
  std::vector<std::int32_t> parent;  // union-find over the cells around one vertex (reused)
  for (std::int32_t c = 0; c < n; ++c) {
    for (int q = 0; q < 8; ++q) {
      if (V.cell_corners[c][q] >= 0) continue;
      const auto off = corner_offset(q);
      const int v[3] = {G.ijk[c][0] + off[0], G.ijk[c][1] + off[1], G.ijk[c][2] + off[2]};
      // The cells around vertex v: slot s = a + 2b + 4c holds the cells at position
      // v - 1 + (a,b,c), which touch v at their corner 7 - s.
      cells.clear();
      slot.clear();
      for (int s = 0; s < 8; ++s) {
        const auto o = corner_offset(s);
        const int p[3] = {v[0] - 1 + o[0], v[1] - 1 + o[1], v[2] - 1 + o[2]};
        if (p[0] < 0 || p[1] < 0 || p[2] < 0 || p[0] >= dims[0] || p[1] >= dims[1] ||
            p[2] >= dims[2])
          continue;
        const auto key = G.spec.cell_index(p[0], p[1], p[2]);
        for (auto i = index.offset[key]; i < index.offset[key + 1]; ++i) {
          cells.push_back(index.cells[i]);
          slot.push_back(s);
        }
      }
      // Components of these cells under the links among them. Two cells around v that
      // are linked share a face that contains v.
      const int m = int(cells.size());
      parent.resize(m);
      std::iota(parent.begin(), parent.end(), 0);
      for (int i = 0; i < m; ++i)
        for (auto l = G.link_offset[cells[i]]; l < G.link_offset[cells[i] + 1]; ++l) {
          const auto it = std::find(cells.begin(), cells.end(), G.link_target[l]);
          if (it == cells.end()) continue;
          unite(parent, i, std::int32_t(it - cells.begin()));
        }
      // One copy per component, numbered in order of the component's first cell.
      copy_of_root.assign(m, -1);
      for (int i = 0; i < m; ++i) {
        const int r = find_root(parent, i);
        if (copy_of_root[r] < 0) {
          copy_of_root[r] = V.num_copies++;
          V.vertex.push_back({v[0], v[1], v[2]});
        }
        V.cell_corners[cells[i]][7 - slot[i]] = copy_of_root[r];
      }
    }
  }
  V.first_cell.assign(V.num_copies, n);
  for (std::int32_t c = 0; c < n; ++c)
    for (int q = 0; q < 8; ++q)
      V.first_cell[V.cell_corners[c][q]] = std::min(V.first_cell[V.cell_corners[c][q]], c);
  return V;
}

VertexCopies build_vertex_copies(const lattice::Lattice& L) {
  return build_vertex_copies(graph_from_lattice(L));
}

}  // namespace hexcut::topology
