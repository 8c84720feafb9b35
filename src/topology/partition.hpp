// Distribution of cells and vertex copies over MPI ranks (doc/theory.md, "Parallel layout"). The
// lattice is cut into super-blocks of `superblock` cells per side and whole super-blocks go to
// ranks, so up to log2(superblock)+1 levels of a multigrid hierarchy the children of every coarse
// cell lie on one rank (deeper levels sum their children's products across ranks). Three methods
// assign them (-hexcut_partition; doc/benchmarks.md, "Partitioning"): METIS k-way on the
// super-block face-adjacency graph weighted by material cell count (the default), PT-Scotch on the
// same graph through PETSc's MatPartitioning, distributed over the ranks, or a Hilbert
// space-filling curve through the super-blocks cut into pieces of equal cell count. A vertex copy
// is owned by the owner of its lowest-numbered incident cell. Every rank ends with the same
// partition.
#pragma once

#include <mpi.h>

#include <cstdint>
#include <string>
#include <vector>

#include "lattice/lattice.hpp"
#include "topology/vertex_copies.hpp"

namespace hexcut::topology {

enum class PartitionMethod { metis, ptscotch, sfc };

/// "metis", "ptscotch", "sfc".
const char* method_name(PartitionMethod m);

struct Partition {
  int num_ranks = 1;
  int superblock = 8;          // cells per super-block side actually used
  std::vector<int> cell_rank;  // per cell
  std::vector<int> copy_rank;  // per vertex copy
};

/// `superblock` is a power of two; it is halved while there are fewer than 2 occupied
/// super-blocks per rank, but not below `min_superblock` (composite elements of level l need
/// 2^l: a composite element must lie on one rank). PT-Scotch partitions the super-block graph
/// distributed over `comm` (collective on it; any size, the result is gathered on every rank);
/// METIS and the curve compute it on every rank alike. Throws InputError when there are fewer
/// super-blocks than ranks. `balance_copies` (after cuts, which add vertex copies but no cells):
/// the vertex copies each super-block owns are balanced too, as METIS's second constraint, or
/// added to the cell counts for PT-Scotch and the curve (one weight each).
Partition partition_lattice(const lattice::Lattice& lattice, const VertexCopies& copies,
                            int num_ranks, int superblock, int min_superblock = 1,
                            PartitionMethod method = PartitionMethod::metis,
                            MPI_Comm comm = MPI_COMM_SELF, bool balance_copies = false);

/// How a partition balances the work: the most cells and owned vertex copies (DOFs / 3) on a
/// rank against the mean, and the ranks without a cell. Counts only (O(cells + copies), no
/// sort), for the decisions after a cut.
struct PartitionBalance {
  std::int64_t max_cells = 0, max_copies = 0;
  std::int64_t empty_ranks = 0;  // ranks without a cell (a body of few super-blocks)
  double mean_cells = 0, mean_copies = 0;
  double cell_imbalance() const { return double(max_cells) / mean_cells; }  // max/mean >= 1
  double copy_imbalance() const { return double(max_copies) / mean_copies; }
};
PartitionBalance partition_balance(const Partition& partition);

/// What a partition costs: its balance, and its communication: the face links between cells
/// of different ranks (each once) and the ghost copies of each rank (copies at its cells'
/// corners that another rank owns: what its halo exchange moves).
struct PartitionStats : PartitionBalance {
  std::int64_t cut_links = 0, ghosts = 0, max_ghosts = 0;
};
PartitionStats partition_stats(const lattice::Lattice& lattice, const VertexCopies& copies,
                               const Partition& partition);

/// Position of super-block (x, y, z) of a 2^bits-sided grid along a 3D Hilbert curve
/// (Skilling 2004, "Programming the Hilbert curve"; doc/references.md): consecutive keys are
/// face neighbours.
std::uint64_t hilbert_key(std::uint32_t x, std::uint32_t y, std::uint32_t z, int bits);

}  // namespace hexcut::topology
