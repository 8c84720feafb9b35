// The stored cells' kernels (doc/theory.md, "Architecture"): functors over the local cells of a
// coarse level for the loop layer (backend/loop.hpp), on plain buffers: the cells' 8 local
// copies and their packed symmetric 24x24 blocks (300 numbers each).
#pragma once

#include <cstdint>

#include "element/fine_cell.hpp"
#include "element/host_device.hpp"
#include "element/trilinear.hpp"
#include "multigrid/kernels.hpp"

namespace hexcut::multigrid {

struct StoredCellData {
  const std::int32_t* corners = nullptr;  // 8 local copies per cell
  const double* packed = nullptr;         // kPackedSize per cell
};

/// y += A_e x_e at the cell's corners.
struct StoredApplyAdd {
  StoredCellData d;
  const double* x;
  double* y;
  HEXCUT_HD void operator()(std::int32_t e) const {
    const std::int32_t* corners = d.corners + 8 * std::int64_t(e);
    double xe[24], ye[24];
    element::gather_cell(x, corners, xe);
    for (int i = 0; i < 24; ++i) ye[i] = 0.0;
    packed_apply_add(d.packed + kPackedSize * std::int64_t(e), xe, ye);
    element::scatter_add_cell(ye, corners, y);
  }
};

/// y at the cell's corner of parity colour k += that corner's rows of A_e times x_e.
struct StoredColourRows {
  StoredCellData d;
  const int* position;  // 3 per cell: level position
  int colour;
  const double* x;
  double* y;
  HEXCUT_HD void operator()(std::int32_t e) const {
    const std::int32_t* corners = d.corners + 8 * std::int64_t(e);
    const int q = element::corner_of_colour(position + 3 * std::int64_t(e), colour);
    double xe[24], y3[3];
    element::gather_cell(x, corners, xe);
    packed_row_block(d.packed + kPackedSize * std::int64_t(e), q, xe, y3);
    for (int c = 0; c < 3; ++c) y[3 * corners[q] + c] += y3[c];
  }
};

/// diag += the 3x3 diagonal blocks of A_e at the cell's corners (9 per local copy).
struct StoredDiagonal {
  StoredCellData d;
  double* diag;
  HEXCUT_HD void operator()(std::int32_t e) const {
    const std::int32_t* corners = d.corners + 8 * std::int64_t(e);
    const double* P = d.packed + kPackedSize * std::int64_t(e);
    for (int q = 0; q < 8; ++q)
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
          diag[9 * corners[q] + 3 * i + j] += P[packed_index(3 * q + i, 3 * q + j)];
  }
};

}  // namespace hexcut::multigrid
