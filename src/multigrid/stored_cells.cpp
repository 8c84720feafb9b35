#include "multigrid/stored_cells.hpp"

#include <algorithm>

#include "backend/loop.hpp"
#include "backend/restriction.hpp"
#include "element/corotation.hpp"
#include "multigrid/kernels.hpp"

namespace hexcut::multigrid {

StoredCells::StoredCells(const topology::DofLayout& layout, Precision precision)
    : CellOperator(layout), precision_(precision) {
  (precision == Precision::single ? single_.assign(kPackedSize * layout.cells.size(), 0.0f)
                                  : packed_.assign(kPackedSize * layout.cells.size(), 0.0));
}

std::int64_t StoredCells::galerkin(const assembly::CellOperator& fine,
                                   const assembly::CellPositions& fine_position,
                                   const Children& children, const std::vector<char>& fine_dirty,
                                   const InterpolationRows* rows) {
  // Each block is accumulated in full 24x24 form from its (at most 8) children, then
  // stored packed.
  const std::size_t n = num_cells();
  dirty_.assign(n, 0);
  std::int64_t rebuilt = 0;
  double child[576], parent[576], W[576];
  const bool general = rows && !rows->empty();
  const auto& fine_corners = fine.layout().cell_corners;
  const auto& parent_corners = layout().cell_corners;
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
      const int octant = element::parity_octant(p[0], p[1], p[2]);
      if (general && rows->touches(fine_corners[e].data())) {
        child_interpolation(*rows, fine_corners[e].data(), parent_corners[C].data(), octant, W);
        galerkin_accumulate_general(child, W, parent);
      } else {
        galerkin_accumulate(child, octant, parent);
      }
    }
    if (!mask_.empty()) {
      const auto& corners = parent_corners[C];
      for (int i = 0; i < 24; ++i)
        if (mask_[3 * std::size_t(corners[i / 3]) + i % 3] == 0.0)
          for (int j = 0; j < 24; ++j) parent[24 * i + j] = parent[24 * j + i] = 0.0;
    }
    if (precision_ == Precision::single)
      pack_symmetric(parent, &single_[kPackedSize * C]);
    else
      pack_symmetric(parent, &packed_[kPackedSize * C]);
  }
  return rebuilt;
}

void StoredCells::rotate(const std::vector<double>& dR) {
  const std::size_t n = num_cells();
  dirty_.assign(n, 1);
  for (std::size_t C = 0; C < n; ++C) rotate_block(C, &dR[9 * C]);
}

void StoredCells::rotate_block(std::size_t e, const double* R) {
  double A[576];
  unpack_symmetric(&packed_[kPackedSize * e], A);
  element::rotate_element_matrix(R, A, A);
  pack_symmetric(A, &packed_[kPackedSize * e]);
}

void StoredCells::set_block(std::size_t e, const double* packed) {
  std::copy_n(packed, kPackedSize, &packed_[kPackedSize * e]);
}

void StoredCells::apply_add(const double* x, double* y) const {
  const auto n = std::int64_t(num_cells());
  if (precision_ == Precision::single)
    backend::for_each(
        n, backend::CellApplyAdd<StoredCellOpsSingle>{{single_.data()}, corners(), x, y});
  else
    backend::for_each(n, backend::CellApplyAdd<StoredCellOps>{{packed_.data()}, corners(), x, y});
}

void StoredCells::apply_add_colour(const assembly::CellPositions& position, int k, const double* x,
                                   double* y) const {
  const int* p = position.empty() ? nullptr : position[0].data();
  const auto n = std::int64_t(num_cells());
  if (precision_ == Precision::single)
    backend::for_each(
        n, backend::CellColourRows<StoredCellOpsSingle>{{single_.data()}, corners(), p, k, x, y});
  else
    backend::for_each(
        n, backend::CellColourRows<StoredCellOps>{{packed_.data()}, corners(), p, k, x, y});
}

void StoredCells::add_diagonal_blocks(double* diag) const {
  const auto n = std::int64_t(num_cells());
  if (precision_ == Precision::single)
    backend::for_each(
        n, backend::CellDiagonal<StoredCellOpsSingle>{{single_.data()}, corners(), diag});
  else
    backend::for_each(n, backend::CellDiagonal<StoredCellOps>{{packed_.data()}, corners(), diag});
}

void StoredCells::cell_matrix(std::size_t e, double* A) const {
  if (precision_ == Precision::single)
    unpack_symmetric(&single_[kPackedSize * e], A);
  else
    unpack_symmetric(&packed_[kPackedSize * e], A);
}

}  // namespace hexcut::multigrid
