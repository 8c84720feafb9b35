// An AABB tree over the lattice's cells for blade queries (doc/theory.md, "Cutting"). Each cell's
// box covers its link segments: its centre and the centres of the + neighbours it is linked to, in
// the deformed configuration. The tree's shape is built once from the reference centres; refit()
// only recomputes the boxes bottom-up, which stays a good tree while cells move moderately relative
// to each other.
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <vector>

#include "lattice/lattice.hpp"

namespace hexcut::cut {

class CellTree {
 public:
  /// Builds the tree over all cells of the lattice at their reference centres.
  explicit CellTree(const lattice::Lattice& lattice);
  /// Recomputes every box from the cell centres (one per cell, in cell order).
  void refit(const lattice::Lattice& lattice, const std::vector<Eigen::Vector3d>& centres);
  /// Calls visit(cell) for every cell whose box meets `box`.
  template <class Visit>
  void query(const Eigen::AlignedBox3d& box, Visit&& visit) const;

 private:
  struct Node {
    Eigen::AlignedBox3d box;
    std::int32_t left = -1, right = -1;  // children (internal nodes)
    std::int32_t begin = 0, end = 0;     // range of order_ (leaves)
  };
  std::int32_t build(std::vector<Eigen::Vector3d>& centres, std::int32_t begin, std::int32_t end);
  std::vector<Node> nodes_;
  std::vector<std::int32_t> order_;  // cells, grouped by leaf
};

template <class Visit>
void CellTree::query(const Eigen::AlignedBox3d& box, Visit&& visit) const {
  if (nodes_.empty()) return;
  std::int32_t stack[128];
  int top = 0;
  stack[top++] = 0;
  while (top > 0) {
    const Node& n = nodes_[stack[--top]];
    if (!n.box.intersects(box)) continue;
    if (n.left < 0) {
      for (auto k = n.begin; k < n.end; ++k) visit(order_[k]);
    } else {
      stack[top++] = n.left;
      stack[top++] = n.right;
    }
  }
}

}  // namespace hexcut::cut
