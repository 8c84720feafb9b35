#include "multigrid/stored_cells.hpp"

#include <algorithm>

#include "multigrid/kernels.hpp"

namespace hexcut::multigrid {

StoredCells::StoredCells(const topology::DofLayout& layout)
    : CellOperator(layout), packed_(kPackedSize * layout.cells.size(), 0.0) {}

std::int64_t StoredCells::galerkin(const assembly::CellOperator& fine,
                                   const assembly::CellPositions& fine_position,
                                   const Children& children, const std::vector<char>& fine_dirty) {
  // Each block is accumulated in full 24x24 form from its (at most 8) children, then
  // stored packed.
  const std::size_t n = num_cells();
  dirty_.assign(n, 0);
  std::int64_t rebuilt = 0;
  double child[576], parent[576];
  for (std::size_t C = 0; C < n; ++C) {
    for (auto k = children.offset[C]; k < children.offset[C + 1]; ++k)
      if (fine_dirty[children.child[k]]) dirty_[C] = 1;
    if (!dirty_[C]) continue;
    ++rebuilt;
    std::fill(parent, parent + 576, 0.0);
    for (auto k = children.offset[C]; k < children.offset[C + 1]; ++k) {
      const auto e = std::size_t(children.child[k]);
      fine.cell_matrix(e, child);
      const auto& p = fine_position[e];
      galerkin_accumulate(child, element::parity_octant(p[0], p[1], p[2]), parent);
    }
    pack_symmetric(parent, &packed_[kPackedSize * C]);
  }
  return rebuilt;
}

void StoredCells::apply_add(const double* x, double* y) const {
  const auto& D = layout();
  double xe[24], ye[24];
  for (std::size_t e = 0; e < num_cells(); ++e) {
    element::gather_cell(x, D.cell_corners[e].data(), xe);
    std::fill(ye, ye + 24, 0.0);
    packed_apply_add(&packed_[kPackedSize * e], xe, ye);
    element::scatter_add_cell(ye, D.cell_corners[e].data(), y);
  }
}

void StoredCells::apply_add_colour(const assembly::CellPositions& position, int k,
                                   const double* x, double* y) const {
  const auto& D = layout();
  double xe[24], y3[3];
  for (std::size_t e = 0; e < num_cells(); ++e) {
    const auto& corners = D.cell_corners[e];
    const int q = corner_of_colour(position[e].data(), k);
    element::gather_cell(x, corners.data(), xe);
    packed_row_block(&packed_[kPackedSize * e], q, xe, y3);
    for (int c = 0; c < 3; ++c) y[3 * corners[q] + c] += y3[c];
  }
}

void StoredCells::add_diagonal_blocks(double* diag) const {
  const auto& D = layout();
  for (std::size_t e = 0; e < num_cells(); ++e) {
    const double* P = &packed_[kPackedSize * e];
    for (int q = 0; q < 8; ++q) {
      const auto v = D.cell_corners[e][q];
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) diag[9 * v + 3 * i + j] += P[packed_index(3 * q + i, 3 * q + j)];
    }
  }
}

void StoredCells::cell_matrix(std::size_t e, double* A) const {
  unpack_symmetric(&packed_[kPackedSize * e], A);
}

}  // namespace hexcut::multigrid
