#include "hierarchy/hierarchy.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <type_traits>

#include "element/trilinear.hpp"
#include "topology/union_find.hpp"

namespace hexcut::hierarchy {
namespace {

int octant_of(const std::array<std::int32_t, 3>& p) {
  return element::parity_octant(p[0], p[1], p[2]);
}

}  // namespace

double transfer_weight(int octant, int fine_corner, int coarse_corner) {
  return element::child_weight(octant, fine_corner, coarse_corner);
}

topology::CellGraph coarsen(const topology::CellGraph& fine, Coarsening mode,
                            std::vector<std::int32_t>* parent) {
  const std::int32_t n = fine.num_cells();
  topology::CellGraph coarse;
  coarse.spec = fine.spec;
  coarse.spec.h = 2 * fine.spec.h;
  for (int d = 0; d < 3; ++d) coarse.spec.dims[d] = (fine.spec.dims[d] + 1) / 2;
  auto block_key = [&](std::int32_t c) {
    const auto& p = fine.ijk[c];
    return coarse.spec.cell_index(p[0] / 2, p[1] / 2, p[2] / 2);
  };
  // Union cells of one block: linked ones (components) or all of them (naive).
  auto root = topology::make_union_find(n);
  if (mode == Coarsening::components) {
    for (std::int32_t c = 0; c < n; ++c)
      for (auto l = fine.link_offset[c]; l < fine.link_offset[c + 1]; ++l) {
        const auto b = fine.link_target[l];
        if (block_key(b) == block_key(c)) topology::unite(root, c, b);
      }
  } else {
    std::map<std::int64_t, std::int32_t> first;
    for (std::int32_t c = 0; c < n; ++c) {
      topology::unite(root, c, first.emplace(block_key(c), c).first->second);
    }
  }
  // Coarse cells in order of (block, lowest child): deterministic, rank-independent.
  std::vector<std::int32_t> roots;
  for (std::int32_t c = 0; c < n; ++c)
    if (topology::find_root(root, c) == c) roots.push_back(c);
  std::stable_sort(roots.begin(), roots.end(),
                   [&](std::int32_t a, std::int32_t b) { return block_key(a) < block_key(b); });
  std::vector<std::int32_t> coarse_of_root(n, -1);
  for (std::size_t i = 0; i < roots.size(); ++i) {
    coarse_of_root[roots[i]] = std::int32_t(i);
    const auto& p = fine.ijk[roots[i]];
    coarse.ijk.push_back({p[0] / 2, p[1] / 2, p[2] / 2});
  }
  parent->resize(n);
  for (std::int32_t c = 0; c < n; ++c) (*parent)[c] = coarse_of_root[topology::find_root(root, c)];
  // Coarse links: any fine link between different coarse cells.
  std::vector<std::array<std::int32_t, 2>> pairs;
  for (std::int32_t c = 0; c < n; ++c)
    for (auto l = fine.link_offset[c]; l < fine.link_offset[c + 1]; ++l) {
      const auto a = (*parent)[c], b = (*parent)[fine.link_target[l]];
      if (a < b) pairs.push_back({a, b});
    }
  std::sort(pairs.begin(), pairs.end());
  pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
  topology::set_links(coarse, std::move(pairs));
  return coarse;
}

double duplication(const topology::CellGraph& g) {
  if (g.num_cells() == 0) return 0.0;
  std::vector<std::int64_t> at(std::size_t(g.num_cells()));
  for (std::int32_t c = 0; c < g.num_cells(); ++c)
    at[std::size_t(c)] = g.spec.cell_index(g.ijk[c][0], g.ijk[c][1], g.ijk[c][2]);
  std::sort(at.begin(), at.end());
  const auto positions = std::unique(at.begin(), at.end()) - at.begin();
  return double(g.num_cells()) / double(positions) - 1.0;
}

std::vector<Level> build_hierarchy(topology::CellGraph fine, const topology::VertexCopies& copies,
                                   const topology::Partition& partition,
                                   const topology::DofLayout& layout, const HierarchyOptions& opt) {
  const int rank = layout.rank;
  std::vector<Level> levels(1);
  levels[0].graph = std::move(fine);
  // The simulation's, not owned: an empty deleter.
  const auto borrowed = [](const auto& x) {
    return std::shared_ptr<const std::decay_t<decltype(x)>>(&x, [](const auto*) {});
  };
  levels[0].copies_ptr = borrowed(copies);
  levels[0].partition_ptr = borrowed(partition);
  levels[0].layout_ptr = borrowed(layout);
  levels[0].ranks = partition.num_ranks;
  while (opt.levels == 0 || int(levels.size()) < opt.levels) {
    const auto& f = levels.back();
    const bool enough = int(levels.size()) >= opt.min_levels;
    if (opt.levels == 0 && enough && 3 * std::int64_t(f.copies().num_copies) <= opt.coarse_dofs)
      break;
    // A lattice of one cell coarsens to itself: no deeper level exists.
    const auto& dims = f.graph.spec.dims;
    if (dims[0] <= 1 && dims[1] <= 1 && dims[2] <= 1) break;
    Level c;
    c.graph = coarsen(f.graph, opt.mode, &levels.back().parent);
    if (opt.levels == 0 && enough && c.graph.num_cells() == f.graph.num_cells()) break;
    // Two levels at least: one level is a direct solve of the fine system.
    const auto level_dofs = 3 * std::int64_t(f.copies().num_copies);
    if (opt.levels == 0 && enough && levels.size() >= 2 && opt.max_duplication >= 0 &&
        level_dofs <= opt.duplication_dofs &&
        double(level_dofs) <= opt.duplication_share * 3.0 * double(copies.num_copies) &&
        duplication(c.graph) > opt.max_duplication)
      break;
    // Gathered onto fewer ranks when the level gets small (never a level below min_levels).
    c.ranks = f.ranks;
    if (opt.gather_cells > 0 && std::int64_t(levels.size()) >= opt.min_levels &&
        c.graph.num_cells() < opt.gather_cells * f.ranks)
      c.ranks = int(std::clamp<std::int64_t>(c.graph.num_cells() / opt.gather_cells, 1, f.ranks));
    auto cc = std::make_shared<topology::VertexCopies>(topology::build_vertex_copies(c.graph));
    auto cp = std::make_shared<topology::Partition>();
    cp->num_ranks = partition.num_ranks;
    cp->superblock = std::max(1, f.partition().superblock / 2);
    // Each coarse cell on the rank of its lowest-numbered child, folded onto c.ranks ranks.
    cp->cell_rank.assign(c.graph.num_cells(), -1);
    const auto& par = levels.back().parent;
    for (std::int32_t e = 0; e < f.graph.num_cells(); ++e) {
      const int r = int(std::int64_t(f.partition().cell_rank[e]) * c.ranks / f.ranks);
      auto& owner = cp->cell_rank[par[e]];
      if (owner < 0) owner = r;
      c.remote_children |= owner != f.partition().cell_rank[e];
    }
    cp->copy_rank.resize(cc->num_copies);
    for (std::int32_t v = 0; v < cc->num_copies; ++v)
      cp->copy_rank[v] = cp->cell_rank[cc->first_cell[v]];
    c.layout_ptr =
        std::make_shared<const topology::DofLayout>(topology::build_dof_layout(*cc, *cp, rank));
    c.copies_ptr = std::move(cc);
    c.partition_ptr = std::move(cp);
    levels.push_back(std::move(c));
  }
  return levels;
}

namespace {

/// Weights that incident cell `cell` of fine copy `copy` (at corner q) gives.
void weights_from_cell(const Level& fine, const Level& coarse, std::int32_t cell, int q,
                       std::array<std::int32_t, 8>* ids, std::array<double, 8>* w) {
  const int o = octant_of(fine.graph.ijk[cell]);
  const auto C = fine.parent[cell];
  for (int j = 0; j < 8; ++j) {
    (*ids)[j] = coarse.copies().cell_corners[C][j];
    (*w)[j] = transfer_weight(o, q, j);
  }
}

}  // namespace

Interpolation interpolation(const Level& fine, const Level& coarse, int rank) {
  Interpolation I;
  // Corner of each copy in its first cell.
  for (std::int32_t v = 0; v < fine.copies().num_copies; ++v) {
    if (fine.partition().copy_rank[v] != rank) continue;
    const auto cell = fine.copies().first_cell[v];
    int q = 0;
    while (fine.copies().cell_corners[cell][q] != v) ++q;
    std::array<std::int32_t, 8> ids;
    std::array<double, 8> w;
    weights_from_cell(fine, coarse, cell, q, &ids, &w);
    // Drop zero weights: a fine vertex at a coarse vertex has one weight 1.
    std::array<std::int32_t, 8> keep_ids;
    std::array<double, 8> keep_w;
    keep_ids.fill(-1);
    keep_w.fill(0.0);
    int k = 0;
    for (int j = 0; j < 8; ++j)
      if (w[j] != 0.0) {
        keep_ids[k] = ids[j];
        keep_w[k++] = w[j];
      }
    I.fine.push_back(v);
    I.coarse.push_back(keep_ids);
    I.weight.push_back(keep_w);
  }
  return I;
}

double interpolation_mismatch(const Level& fine, const Level& coarse) {
  // For every copy, compare the weight map (coarse copy -> weight) of every incident cell
  // with the one of its first cell.
  std::vector<std::map<std::int32_t, double>> reference(fine.copies().num_copies);
  std::vector<char> have(fine.copies().num_copies, 0);
  double worst = 0.0;
  for (std::int32_t c = 0; c < fine.graph.num_cells(); ++c)
    for (int q = 0; q < 8; ++q) {
      const auto v = fine.copies().cell_corners[c][q];
      std::array<std::int32_t, 8> ids;
      std::array<double, 8> w;
      weights_from_cell(fine, coarse, c, q, &ids, &w);
      std::map<std::int32_t, double> m;
      for (int j = 0; j < 8; ++j)
        if (w[j] != 0.0) m[ids[j]] += w[j];
      if (!have[v]) {
        reference[v] = m;
        have[v] = 1;
        continue;
      }
      std::map<std::int32_t, double> diff = reference[v];
      for (const auto& [id, x] : m) diff[id] -= x;
      for (const auto& [id, x] : diff) worst = std::max(worst, std::abs(x));
    }
  return worst;
}

}  // namespace hexcut::hierarchy
