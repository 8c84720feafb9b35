// DOF numbering and the rank-local view of the topology (doc/theory.md, "Parallel layout"). Three
// DOFs per vertex copy, interleaved (x,y,z), block size 3. PETSc's global numbering puts each
// rank's owned copies in one contiguous range (rank order, then canonical order within a rank). The
// local numbering is owned copies first, then ghosts.
//
// The layout is exposed as a DMShell: global and local vectors and the ghost scatter,
// so KSP monitors and viewers work on hexcut's vectors. A "natural" scatter maps the
// PETSc order to the canonical (rank-independent) order used by the output files.
#pragma once

#include <petscdm.h>
#include <petscdmshell.h>
#include <petscvec.h>

#include <array>
#include <cstdint>
#include <vector>

#include "lattice/lattice.hpp"
#include "topology/partition.hpp"
#include "topology/vertex_copies.hpp"

namespace hexcut::topology {

struct DofLayout {
  int rank = 0, num_ranks = 1;
  std::int32_t num_global_copies = 0;
  std::vector<PetscInt> global_block;  // per canonical copy: PETSc global block index
  std::vector<PetscInt> owned_begin;   // per rank (+1): first global block of each rank
  std::vector<std::int32_t> cells;     // local cells (canonical ids), ascending
  std::vector<std::int32_t> copies;    // local copies (canonical ids): owned, then ghosts
  std::int32_t num_owned = 0;
  std::vector<std::array<std::int32_t, 8>> cell_corners;  // per local cell: local copy ids

  std::int32_t num_local() const { return std::int32_t(copies.size()); }
  PetscInt first_owned_block() const { return owned_begin[rank]; }
};

DofLayout build_dof_layout(const VertexCopies& copies, const Partition& partition, int rank);

/// Ghost exchange for `bs` values per copy: a global vector (owned copies), a local
/// sequential vector (owned + ghosts) and the scatter global -> local (use it with
/// SCATTER_REVERSE and ADD_VALUES to sum local contributions into their owners).
PetscErrorCode create_ghost_scatter(MPI_Comm comm, const DofLayout& layout, PetscInt bs,
                                    Vec* global, Vec* local, VecScatter* global_to_local);

/// A DMShell over the layout: global vectors (owned DOFs, bs 3), local vectors
/// (owned + ghost DOFs), and global<->local scatters (local->global adds).
PetscErrorCode create_dm(MPI_Comm comm, const DofLayout& layout, DM* dm);

/// Scatter from a PETSc-ordered vector with `block` entries per copy to the canonical
/// ("natural") order, split evenly over ranks as contiguous row slabs for output.
struct NaturalScatter {
  VecScatter scatter = nullptr;
  Vec natural = nullptr;   // canonical order, contiguous slab per rank
  PetscInt row_begin = 0;  // first canonical row of this rank's slab
  PetscInt rows = 0;       // rows in this rank's slab
  PetscInt block = 1;
};

/// For entities numbered canonically 0..n_global-1, of which this rank holds the
/// listed ones (`canonical[i]` sits at PETSc-ordered position `petsc_begin + i`).
PetscErrorCode create_natural_scatter(MPI_Comm comm, PetscInt n_global,
                                      const std::vector<std::int32_t>& canonical,
                                      PetscInt petsc_begin, PetscInt block, NaturalScatter* out);
PetscErrorCode destroy_natural_scatter(NaturalScatter* s);

}  // namespace hexcut::topology
