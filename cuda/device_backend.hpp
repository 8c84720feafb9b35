// The CUDA backend's operators (issue 13; doc/theory.md, "Kernel bodies for a CUDA
// backend"): the stored cells' and the fine cells' y += A x on the device, with the same
// functor bodies the host runs (backend::CellApplyAdd over multigrid::StoredCellOpsOf<T>
// and assembly::FineCellOps), launched one colour of backend::colour_cells at a time so
// that no two threads of a launch scatter into the same vertex copy.
#pragma once

#include <algorithm>

#include "assembly/fine_cells.hpp"
#include "backend/loop.hpp"
#include "device_kernels.hpp"
#include "multigrid/stored_cells.hpp"

namespace hexcut::cuda {

/// y += A x for the stored cells A (in the precision they are held in now) on device 0; x, y:
/// 3 values per local copy of A's layout (host arrays, copied in and out once per call).
/// `colours`: backend::colour_cells of A's cells' level positions. Throws
/// std::runtime_error with the CUDA runtime's message when a call fails.
inline void stored_apply_add(const multigrid::StoredCells& A, const backend::CellColours& colours,
                             const double* x, double* y) {
  const CellArrays cells{std::int64_t(A.num_cells()),  A.corners(),         colours.num_colours(),
                         colours.offset.data(),        colours.cell.data(), A.layout().num_local(),
                         std::int64_t(A.num_blocks()), A.block_of()};
  if (A.packed_double())
    packed_apply_add(A.packed_double(), cells, x, y);
  else
    packed_apply_add(A.packed_single(), cells, x, y);
}

/// The fine cells `A` as the device functions take them: their cells and colours, and the
/// lengths of their shared tables (the largest kind and own-stiffness index + 1).
inline CellArrays fine_cell_arrays(const assembly::FineCells& A,
                                   const backend::CellColours& colours, FineTables* tables) {
  const auto d = A.data();
  const auto n = std::ptrdiff_t(A.num_cells());
  tables->num_kinds = n ? 1 + *std::max_element(d.kind, d.kind + n) : 0;
  tables->num_own = d.own && n ? 1 + *std::max_element(d.own, d.own + n) : 0;
  return CellArrays{std::int64_t(n),
                    A.corners(),
                    colours.num_colours(),
                    colours.offset.data(),
                    colours.cell.data(),
                    A.layout().num_local(),
                    0,
                    nullptr};
}

/// y += A x for the fine cells A (their current weights, rotations and mask) on device 0;
/// x, y: 3 values per local copy of A's layout (host arrays, copied in and out once per
/// call). `colours`: backend::colour_cells of the cells' lattice positions. Throws
/// std::runtime_error with the CUDA runtime's message when a call fails.
inline void fine_apply_add(const assembly::FineCells& A, const backend::CellColours& colours,
                           const double* x, double* y) {
  FineTables tables;
  const auto cells = fine_cell_arrays(A, colours, &tables);
  fine_apply_add(A.data(), tables, cells, x, y);
}

}  // namespace hexcut::cuda
