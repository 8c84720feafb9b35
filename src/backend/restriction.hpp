// Element restriction around a per-cell operator (doc/theory.md, "Architecture"): the kernels
// that gather a cell's 24 values from its 8 vertex copies, let the cell's operator act, and
// scatter the result back, as libCEED splits an operator into restriction and qfunction. A
// `Cell` (FineCellOps, StoredCellOps) provides, all HEXCUT_HD, for local cell e:
//   void apply_add(e, corners, xe, ye) const     ye += A_e xe (xe may be overwritten)
//   void row_block(e, corners, q, xe, y3) const  y3 = rows of corner q of A_e times xe
//   void diagonal_block(e, corners, q, D) const  D = 3x3 diagonal block of corner q
// `corners` are the cell's 8 local copies. The functors run under backend::for_each.
#pragma once

#include <cstdint>
#include <type_traits>

#include "element/fine_cell.hpp"
#include "element/host_device.hpp"
#include "element/trilinear.hpp"

namespace hexcut::backend {

/// The type a Cell's apply_add works in: Cell::Arith where it declares one (float for
/// assembly::FineCellOpsSingle), double otherwise.
template <class Cell, class = void>
struct CellArith {
  using type = double;
};
template <class Cell>
struct CellArith<Cell, std::void_t<typename Cell::Arith>> {
  using type = typename Cell::Arith;
};

/// y += A x: each cell's contribution at its corners. V: the vectors' type (double, or float
/// for the loop-layer cycle in single precision); the cell's 24 values are gathered into and
/// scattered from its arithmetic's type (CellArith).
template <class Cell, class V = double>
struct CellApplyAdd {
  Cell cell;
  const std::int32_t* corners;  // 8 per cell
  const V* x;
  V* y;
  HEXCUT_HD void operator()(std::int32_t e) const {
    using A = typename CellArith<Cell>::type;
    const std::int32_t* c = corners + 8 * std::int64_t(e);
    A xe[24], ye[24];
    element::gather_cell(x, c, xe);
    for (int i = 0; i < 24; ++i) ye[i] = A(0);
    cell.apply_add(e, c, xe, ye);
    element::scatter_add_cell(ye, c, y);
  }
};

/// y at each cell's corner of parity colour k += that corner's rows of A_e times x_e. V: the
/// vectors' type (as CellApplyAdd's: the 24 values gathered into double, the 3 rows added
/// rounded to V).
template <class Cell, class V = double>
struct CellColourRows {
  Cell cell;
  const std::int32_t* corners;  // 8 per cell
  const int* position;          // 3 per cell: lattice or level position
  int colour;
  const V* x;
  V* y;
  HEXCUT_HD void operator()(std::int32_t e) const {
    const std::int32_t* c = corners + 8 * std::int64_t(e);
    const int q = element::corner_of_colour(position + 3 * std::int64_t(e), colour);
    double xe[24], y3[3];
    element::gather_cell(x, c, xe);
    cell.row_block(e, c, q, xe, y3);
    for (int i = 0; i < 3; ++i) y[3 * std::int64_t(c[q]) + i] += V(y3[i]);
  }
};

/// diag += the 3x3 diagonal blocks of every A_e at its corners (9 per local copy).
template <class Cell>
struct CellDiagonal {
  Cell cell;
  const std::int32_t* corners;  // 8 per cell
  double* diag;
  HEXCUT_HD void operator()(std::int32_t e) const {
    const std::int32_t* c = corners + 8 * std::int64_t(e);
    double block[9];
    for (int q = 0; q < 8; ++q) {
      cell.diagonal_block(e, c, q, block);
      for (int k = 0; k < 9; ++k) diag[9 * c[q] + k] += block[k];
    }
  }
};

}  // namespace hexcut::backend
