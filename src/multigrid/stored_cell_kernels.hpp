// The stored cells' per-cell operator (doc/theory.md, "Architecture") for the restriction
// kernels of backend/restriction.hpp, on a plain buffer: the packed symmetric 24x24 block of
// each cell (300 numbers), or of each group of cells that share one; and, for the product
// alone, the few shared blocks unpacked (576 numbers each).
#pragma once

#include <cstdint>

#include "element/host_device.hpp"
#include "multigrid/kernels.hpp"

namespace hexcut::multigrid {

/// The stored cells' per-cell operator for backend/restriction.hpp's kernels; T: the
/// stored type (double, or float for -gmg_precision single). `slot` (may be null: cell e's
/// block is block e) maps each cell to its block: cells that share one (StoredCells::share)
/// map to the same.
template <class T>
struct StoredCellOpsOf {
  const T* packed;                     // kPackedSize per block
  const std::int32_t* slot = nullptr;  // per cell: its block, or null
  HEXCUT_HD const T* block(std::int32_t e) const {
    return packed + kPackedSize * std::int64_t(slot ? slot[e] : e);
  }
  HEXCUT_HD void apply_add(std::int32_t e, const std::int32_t*, double* xe, double* ye) const {
    packed_apply_add(block(e), xe, ye);
  }
  HEXCUT_HD void row_block(std::int32_t e, const std::int32_t*, int q, double* xe,
                           double* y3) const {
    packed_row_block(block(e), q, xe, y3);
  }
  HEXCUT_HD void diagonal_block(std::int32_t e, const std::int32_t*, int q, double* D) const {
    const T* P = block(e);
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) D[3 * i + j] = double(P[packed_index(3 * q + i, 3 * q + j)]);
  }
};
using StoredCellOps = StoredCellOpsOf<double>;
using StoredCellOpsSingle = StoredCellOpsOf<float>;

/// The product alone (backend::CellApplyAdd) for cells whose block many cells share and is
/// also held unpacked (StoredCells::num_unpacked): block b's copy is full[576 unpacked[b]..]
/// (row-major), applied as the fine cells' stiffness is (element::symmetric_apply_add: rows
/// in order, 24 accumulators), which the packed columns cannot match where a block stays in
/// cache. Run over those cells only (backend::for_each_in); the row and diagonal blocks read
/// the packed ones.
template <class T>
struct UnpackedBlockOpsOf {
  const T* full;                 // 576 per unpacked block
  const std::int32_t* slot;      // per cell: its block
  const std::int32_t* unpacked;  // per block: its copy in full (>= 0 for these cells)
  HEXCUT_HD void apply_add(std::int32_t e, const std::int32_t*, double* xe, double* ye) const {
    element::symmetric_apply_add(full + 576 * std::int64_t(unpacked[slot[e]]), 1.0, xe, ye);
  }
};

}  // namespace hexcut::multigrid
