#include "assembly/fine_cells.hpp"

#include "backend/loop.hpp"
#include "backend/restriction.hpp"

namespace hexcut::assembly {

FineCells::FineCells(const topology::DofLayout& layout, const CellData& cells,
                     const OperatorWeights& w, bool cache)
    : CellOperator(layout), cells_(&cells), w_(w), cache_(cache) {
  if (!cache_) return;
  // The stiffness of cells without a kind (per-cell E), formed once here instead of at
  // every visit.
  const std::size_t n = num_cells();
  own_.assign(n, -1);
  std::size_t count = 0;
  for (std::size_t e = 0; e < n; ++e)
    if (cells.kind[e] < 0) own_[e] = std::int32_t(count++);
  own_stiffness_.resize(576 * count);
  for (std::size_t e = 0; e < n; ++e)
    if (own_[e] >= 0)
      element::cell_stiffness(element::reference_matrices(), cells.h, cells.lambda[e],
                              cells.mu[e], &own_stiffness_[576 * std::size_t(own_[e])]);
  // The float copies (2.3 KB per kind, 6.9 KB of reference): per kind, and the reference
  // matrices for the cells without
  // a kind (float arithmetic forms their stiffness from these, not from own_stiffness_).
  for (const auto& K : cells.kind_stiffness)
    kind_single_.insert(kind_single_.end(), K.begin(), K.end());
  const auto& ref = element::reference_matrices();
  for (const double* M : {ref.k_lambda, ref.k_mu, ref.mass})
    reference_single_.insert(reference_single_.end(), M, M + 576);
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

FineCellData FineCells::data() const {
  const CellData& C = *cells_;
  FineCellData d;
  d.corners = corners();
  d.kind = C.kind.data();
  d.kind_stiffness = C.kind_stiffness.empty() ? nullptr : C.kind_stiffness[0].data();
  d.own = cache_ ? own_.data() : nullptr;
  d.own_stiffness = own_stiffness_.data();
  d.lambda = C.lambda.data();
  d.mu = C.mu.data();
  d.rho = C.rho.data();
  d.rotation = C.identity_rotations ? nullptr : C.rotation.data();
  d.reference = &element::reference_matrices();
  d.h = C.h;
  d.w_stiffness = w_.stiffness;
  d.w_mass = w_.mass;
  d.lumped_mass = w_.lumped_mass;
  d.mask = mask_.empty() ? nullptr : mask_.data();
  d.cell_masked = cell_masked_.empty() ? nullptr : cell_masked_.data();
  d.kind_stiffness_single = kind_single_.empty() ? nullptr : kind_single_.data();
  d.reference_single = reference_single_.empty() ? nullptr : reference_single_.data();
  return d;
}

void FineCells::apply_add(const double* x, double* y) const {
  backend::for_each(std::int64_t(num_cells()),
                    backend::CellApplyAdd<FineCellOps>{{data()}, corners(), x, y});
}

void FineCells::apply_add(const float* x, float* y) const {
  const auto d = data();
  if (d.reference_single)
    backend::for_each(std::int64_t(num_cells()),
                      backend::CellApplyAdd<FineCellOpsSingle, float>{{d}, corners(), x, y});
  else
    backend::for_each(std::int64_t(num_cells()),
                      backend::CellApplyAdd<FineCellOps, float>{{d}, corners(), x, y});
}

void FineCells::apply_add_colour(const CellPositions& position, int k, const double* x,
                                 double* y) const {
  const int* p = position.empty() ? nullptr : position[0].data();
  backend::for_each(std::int64_t(num_cells()),
                    backend::CellColourRows<FineCellOps>{{data()}, corners(), p, k, x, y});
}

void FineCells::apply_add_colour(const CellPositions& position, int k, const float* x,
                                 float* y) const {
  const int* p = position.empty() ? nullptr : position[0].data();
  backend::for_each(std::int64_t(num_cells()),
                    backend::CellColourRows<FineCellOps, float>{{data()}, corners(), p, k, x, y});
}

void FineCells::add_diagonal_blocks(double* diag) const {
  backend::for_each(std::int64_t(num_cells()),
                    backend::CellDiagonal<FineCellOps>{{data()}, corners(), diag});
}

void FineCells::cell_matrix(std::size_t e, double* A) const {
  fine_cell_matrix(data(), std::int32_t(e), A);
}

}  // namespace hexcut::assembly
