#include "assembly/fine_cells.hpp"

#include <algorithm>

#include "element/element.hpp"
#include "element/trilinear.hpp"

namespace hexcut::assembly {

FineCells::FineCells(const topology::DofLayout& layout, const CellData& cells,
                     const OperatorWeights& w, bool cache)
    : CellOperator(layout), cells_(&cells), w_(w), cache_(cache) {
  set_weights(w);
}

void FineCells::set_weights(const OperatorWeights& w) {
  w_ = w;
  if (!cache_) return;
  const std::size_t n = num_cells();
  views_.resize(n);
  std::size_t own = 0;
  for (std::size_t e = 0; e < n; ++e) own += cells_->kind[e] < 0;
  own_stiffness_.clear();
  own_stiffness_.resize(own);
  own = 0;
  for (std::size_t e = 0; e < n; ++e) {
    double* buffer = cells_->kind[e] < 0 ? own_stiffness_[own++].data() : nullptr;
    views_[e] = fine_cell_view(*cells_, e, w_, buffer);
  }
}

void FineCells::set_mask(std::vector<double> mask_local) {
  mask_ = std::move(mask_local);
  cell_masked_.clear();
  if (mask_.empty()) return;
  const auto& D = layout();
  cell_masked_.assign(num_cells(), 0);
  for (std::size_t e = 0; e < num_cells(); ++e)
    for (auto v : D.cell_corners[e])
      for (int c = 0; c < 3; ++c)
        if (mask_[3 * v + c] == 0.0) cell_masked_[e] = 1;
}

element::FineCell FineCells::view(std::size_t e, double* buffer) const {
  return cache_ ? views_[e] : fine_cell_view(*cells_, e, w_, buffer);
}

void FineCells::apply_add(const double* x, double* y) const {
  const auto& D = layout();
  double buffer[element::kElementMatrixSize], xe[24], ye[24];
  for (std::size_t e = 0; e < num_cells(); ++e) {
    const auto& corners = D.cell_corners[e];
    element::gather_cell(x, corners.data(), xe);
    std::fill(ye, ye + 24, 0.0);
    if (masked(e)) {
      // Masked DOFs: x enters as 0 and y stays 0, the rows and columns of A_e zeroed.
      for (int q = 0; q < 8; ++q)
        for (int k = 0; k < 3; ++k) xe[3 * q + k] *= mask_[3 * corners[q] + k];
      element::fine_cell_apply_add(view(e, buffer), xe, ye);
      for (int q = 0; q < 8; ++q)
        for (int k = 0; k < 3; ++k) ye[3 * q + k] *= mask_[3 * corners[q] + k];
    } else {
      element::fine_cell_apply_add(view(e, buffer), xe, ye);
    }
    element::scatter_add_cell(ye, corners.data(), y);
  }
}

void FineCells::apply_add_colour(const CellPositions& position, int k, const double* x,
                                 double* y) const {
  const auto& D = layout();
  double buffer[element::kElementMatrixSize], xe[24], y3[3];
  for (std::size_t e = 0; e < num_cells(); ++e) {
    const auto& corners = D.cell_corners[e];
    const int q = element::corner_of_colour(position[e].data(), k);
    element::gather_cell(x, corners.data(), xe);
    if (masked(e)) {
      for (int p = 0; p < 8; ++p)
        for (int c = 0; c < 3; ++c) xe[3 * p + c] *= mask_[3 * corners[p] + c];
      element::fine_row_block(view(e, buffer), q, xe, y3);
      for (int c = 0; c < 3; ++c) y3[c] *= mask_[3 * corners[q] + c];
    } else {
      element::fine_row_block(view(e, buffer), q, xe, y3);
    }
    for (int c = 0; c < 3; ++c) y[3 * corners[q] + c] += y3[c];
  }
}

void FineCells::add_diagonal_blocks(double* diag) const {
  const auto& D = layout();
  double buffer[element::kElementMatrixSize], block[9];
  for (std::size_t e = 0; e < num_cells(); ++e) {
    const auto cell = view(e, buffer);
    for (int q = 0; q < 8; ++q) {
      const auto v = D.cell_corners[e][q];
      element::fine_diagonal_block(cell, q, block);
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) {
          double a = block[3 * i + j];
          if (!mask_.empty()) a *= mask_[3 * v + i] * mask_[3 * v + j];
          diag[9 * v + 3 * i + j] += a;
        }
    }
  }
}

void FineCells::cell_matrix(std::size_t e, double* A) const {
  cell_operator(*cells_, e, w_, A);
  if (!masked(e)) return;
  double m[24];
  element::gather_cell(mask_.data(), layout().cell_corners[e].data(), m);
  for (int r = 0; r < 24; ++r)
    for (int c = 0; c < 24; ++c) A[24 * r + c] *= m[r] * m[c];
}

}  // namespace hexcut::assembly
