// The loop layer (doc/theory.md, "Architecture", "Kernel bodies for a CUDA backend"): a kernel
// is a functor k(i) over the cells (or vertex copies) 0..n-1 whose data are plain pointers into
// buffers the backend owns, structure of arrays, with a HEXCUT_HD call operator. The host
// backend below runs it in a plain loop; a CUDA backend (issue 13) launches the same functor,
// one thread per index, over the cells of one colour at a time (colour_cells) so that the
// scatter of a cell's contributions into shared vertex copies never races. On the host the
// loop is serial: the scatter cannot race, and cell order keeps the vertex data in cache.
// Models: MFEM's mfem::forall, libCEED's qfunctions.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

namespace hexcut::backend {

/// Host backend: k(i) for i = 0..n-1, in order.
template <class Kernel>
inline void for_each(std::int64_t n, const Kernel& k) {
  for (std::int64_t i = 0; i < n; ++i) k(std::int32_t(i));
}

/// Host backend: k(cells[i]) for i in order (a subset of the cells, e.g. those one
/// per-cell operator serves).
template <class Kernel>
inline void for_each_in(const std::vector<std::int32_t>& cells, const Kernel& k) {
  for (const std::int32_t e : cells) k(e);
}

/// Cells grouped into colours such that no two cells of one colour share a vertex copy:
/// colour c holds cell[offset[c] .. offset[c+1]).
struct CellColours {
  std::vector<std::int32_t> offset;  // num_colours() + 1
  std::vector<std::int32_t> cell;
  int num_colours() const { return int(offset.size()) - 1; }
};

/// Colours of cells at lattice (or level) positions: the parity octant of the position
/// (cells of one octant are at least two cells apart, so share no vertex), times the
/// index of the cell among those at the same position (several cells of a coarse level
/// may sit at one position, the pieces of a 2x2x2 block, and they may share copies). At
/// most 8 x (largest number of cells at one position) colours; 8 on a fine lattice.
CellColours colour_cells(const std::vector<std::array<int, 3>>& position);

/// The host backend over the cells of colour c (what a device backend launches per colour).
template <class Kernel>
inline void for_each_of_colour(const CellColours& colours, int c, const Kernel& k) {
  for (auto i = colours.offset[c]; i < colours.offset[c + 1]; ++i) k(colours.cell[i]);
}

}  // namespace hexcut::backend
