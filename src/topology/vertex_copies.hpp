// Vertex copies (doc/theory.md, "Lattice, links and vertex copies"; the virtual-node idea,
// Jerabkova 2007, sec. 3.1; doc/references.md). Around each lattice vertex the up-to-8 incident
// cells are grouped into connected components using only the links among those 8 cells; each
// component gets its own copy (3 DOFs). Uncut solid gives one copy per vertex; cells meeting only
// at an edge or a corner, or separated by a cut, get separate copies. This module is the one place
// topology is derived from links: the cut stage (src/cut) changes links and calls it again.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "lattice/lattice.hpp"
#include "topology/cell_graph.hpp"

namespace hexcut::topology {

/// Corner q of a cell sits at local offset (q&1, (q>>1)&1, (q>>2)&1): x fastest.
inline std::array<int, 3> corner_offset(int q) {
  return {q & 1, (q >> 1) & 1, (q >> 2) & 1};
}

/// VTK_HEXAHEDRON corner order expressed in hexcut's corner numbering.
inline constexpr std::array<int, 8> kVtkHexOrder{0, 1, 3, 2, 4, 5, 7, 6};

struct VertexCopies {
  std::int32_t num_copies = 0;
  std::vector<std::array<std::int32_t, 8>> cell_corners;  // per cell: copy at each corner
  std::vector<std::array<std::int32_t, 3>> vertex;        // per copy: lattice vertex (i,j,k)
  std::vector<std::int32_t> first_cell;                   // per copy: lowest-numbered incident cell
};

/// Builds vertex copies from a level's cells and links (several cells may share a
/// position on coarse levels). The numbering is a pure
/// function of the lattice (cells are visited in order), so it does not depend on the
/// number of MPI ranks: it is the "canonical" point order of the output files.
VertexCopies build_vertex_copies(const CellGraph& graph);
VertexCopies build_vertex_copies(const lattice::Lattice& lattice);

}  // namespace hexcut::topology
