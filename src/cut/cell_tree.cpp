#include "cut/cell_tree.hpp"

#include <algorithm>

namespace hexcut::cut {
namespace {
constexpr std::int32_t kLeafSize = 8;
}

CellTree::CellTree(const lattice::Lattice& lattice) {
  const auto n = lattice.num_cells();
  order_.resize(n);
  std::vector<Eigen::Vector3d> centres(n);
  for (std::int32_t c = 0; c < n; ++c) {
    order_[c] = c;
    const auto& p = lattice.ijk[c];
    centres[c] = lattice.spec.cell_centre(p[0], p[1], p[2]);
  }
  if (n > 0) {
    nodes_.reserve(2 * (n / kLeafSize + 1));
    build(centres, 0, n);
    refit(lattice, centres);
  }
}

std::int32_t CellTree::build(std::vector<Eigen::Vector3d>& centres, std::int32_t begin,
                             std::int32_t end) {
  // Median split along the longest side of the centres' box: balanced, depth ~log2(n/8),
  // far below the query stack's 128 entries.
  const auto id = std::int32_t(nodes_.size());
  nodes_.push_back({});
  nodes_[id].begin = begin;
  nodes_[id].end = end;
  if (end - begin <= kLeafSize) return id;
  Eigen::AlignedBox3d box;
  for (auto k = begin; k < end; ++k) box.extend(centres[order_[k]]);
  int axis;
  box.sizes().maxCoeff(&axis);
  const auto mid = begin + (end - begin) / 2;
  std::nth_element(
      order_.begin() + begin, order_.begin() + mid, order_.begin() + end,
      [&](std::int32_t a, std::int32_t b) { return centres[a][axis] < centres[b][axis]; });
  const auto left = build(centres, begin, mid);
  const auto right = build(centres, mid, end);
  nodes_[id].left = left;
  nodes_[id].right = right;
  return id;
}

void CellTree::refit(const lattice::Lattice& lattice, const std::vector<Eigen::Vector3d>& centres) {
  // Children are created after their parent, so a reverse sweep visits children first.
  for (auto id = std::int32_t(nodes_.size()) - 1; id >= 0; --id) {
    Node& n = nodes_[id];
    n.box.setEmpty();
    if (n.left >= 0) {
      n.box.extend(nodes_[n.left].box);
      n.box.extend(nodes_[n.right].box);
      continue;
    }
    for (auto k = n.begin; k < n.end; ++k) {
      const auto c = order_[k];
      n.box.extend(centres[c]);
      for (int d = 0; d < 3; ++d) {
        if (!lattice.linked(c, d)) continue;
        const auto nb = lattice.neighbour(c, d);
        if (nb >= 0) n.box.extend(centres[nb]);
      }
    }
  }
}

}  // namespace hexcut::cut
