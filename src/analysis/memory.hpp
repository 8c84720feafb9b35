// The memory a job needs, estimated before it allocates, so that a job too large for the
// machine stops at once with the estimate (exit 2) instead of dying of std::bad_alloc
// minutes later (doc/user-guide.md, "Memory").
#pragma once

#include <petscsys.h>

#include <cstdint>
#include <string>

#include "deck/deck.hpp"

namespace hexcut::analysis {

/// Bytes one rank needs for a job of `lattice_cells` lattice cells of which
/// `material_cells` are filled, on `ranks` ranks. Every rank holds the lattice
/// description (14 B per lattice cell, +8 B when an image sets Young's moduli, ~300 B
/// per filled cell); the operator, vectors and solver are shared out (per filled cell:
/// gmg 1.3 kB, 1.0 kB when its coarse blocks are shared (`shared_blocks`), cg-jacobi 3.7 kB,
/// hypre and gamg 9.5 kB, direct 28 kB x (n/4096)^(1/4) for the fill of the Cholesky factor, n =
/// min(cells, d^3) with d the lattice's middle side (a bar's nested dissection cuts it into cubes
/// of its cross-section); corotational dynamic composite runs of level l
/// + 300 B + 5.6 kB / 8^l); 45 MB for the libraries. The figures were
/// measured (peak resident memory of hexcut runs on solid boxes, doc/user-guide.md);
/// they are good to about 30% for solid bodies.
double estimate_bytes_per_rank(const deck::Deck& deck, std::int64_t lattice_cells,
                               std::int64_t material_cells, int ranks, bool shared_blocks);

/// Memory this node can give the job [bytes]: MemAvailable of /proc/meminfo, capped by
/// the cgroup's limit (batch systems), or -hexcut_memory_available GiB when given;
/// 0 = unknown or check disabled (-hexcut_memory_available 0). Throws InputError when
/// -hexcut_memory_available is not a number >= 0.
PetscErrorCode available_bytes_on_node(double* bytes);

/// Throws InputError when the ranks on some node would need more than that node has
/// (whether the multigrid shares its coarse blocks read from the options database; a bad
/// -gmg_shared_blocks value is an "invalid PETSc option"):
/// `material_cells` < 0 checks the lattice alone (before voxelization). Collective.
PetscErrorCode require_memory(MPI_Comm comm, const deck::Deck& deck, std::int64_t material_cells);

}  // namespace hexcut::analysis
