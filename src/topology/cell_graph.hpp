// Cells of one lattice level and the face links between them (doc/theory.md, "Lattice, links and
// vertex copies", "Geometric multigrid"). On the simulation lattice every position holds at most
// one cell; on coarse multigrid levels several cells (connected components of one 2x2x2 block) may
// share a position, so links are explicit neighbour lists rather than bits.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "common/lattice_spec.hpp"
#include "lattice/lattice.hpp"

namespace hexcut::topology {

struct CellGraph {
  LatticeSpec spec;                              // this level's lattice
  std::vector<std::array<std::int32_t, 3>> ijk;  // per cell: position
  std::vector<std::int32_t> link_offset;         // CSR over cells (size n+1)
  std::vector<std::int32_t> link_target;         // linked face neighbours, both directions
  // (The multigrid frees both once its hierarchy is built, unless its energy-minimizing
  // interpolation reads them again: hierarchy levels may have empty links.)

  std::int32_t num_cells() const { return std::int32_t(ijk.size()); }
};

/// The simulation level: cell ids are the lattice's, links from its link bits.
CellGraph graph_from_lattice(const lattice::Lattice& lattice);

/// Builds CSR links from a list of linked pairs (each pair once, any order).
void set_links(CellGraph& graph, std::vector<std::array<std::int32_t, 2>> pairs);

}  // namespace hexcut::topology
