// Distribution of cells and vertex copies over MPI ranks (doc/theory.md, "Parallel layout"). The
// lattice is cut into super-blocks of `superblock` cells per side and whole super-blocks go to
// ranks (METIS k-way on the super-block face-adjacency graph, weighted by material cell count), so
// every coarse cell of a multigrid hierarchy up to log2(superblock)+1 levels lies on one rank. A
// vertex copy is owned by the owner of its lowest-numbered incident cell. Every rank computes the
// same partition from the same lattice.
#pragma once

#include <cstdint>
#include <vector>

#include "lattice/lattice.hpp"
#include "topology/vertex_copies.hpp"

namespace hexcut::topology {

struct Partition {
  int num_ranks = 1;
  int superblock = 8;          // cells per super-block side actually used
  std::vector<int> cell_rank;  // per cell
  std::vector<int> copy_rank;  // per vertex copy
};

/// `superblock` is a power of two; it is halved while there are fewer than 2 occupied
/// super-blocks per rank, but not below `min_superblock` (composite elements of level l need
/// 2^l: a composite element must lie on one rank). Throws std::runtime_error if the body
/// cannot be split.
Partition partition_lattice(const lattice::Lattice& lattice, const VertexCopies& copies,
                            int num_ranks, int superblock, int min_superblock = 1);

}  // namespace hexcut::topology
