// Setup of the discrete model, stage by stage (doc/theory.md, "Pipeline"): deck -> voxel grid ->
// lattice (cells, links) -> vertex copies -> partition -> DOF layout + DM -> cell data and boundary
// data. Every rank builds the same lattice and topology (they are small integer arrays) and keeps
// the operator data of its own cells only.
#pragma once

#include <petscdm.h>

#include "assembly/boundary.hpp"
#include "assembly/operator.hpp"
#include "deck/deck.hpp"
#include "lattice/lattice.hpp"
#include "topology/dof_layout.hpp"
#include "topology/partition.hpp"
#include "topology/vertex_copies.hpp"

namespace hexcut::analysis {

struct Model {
  lattice::Lattice lattice;
  topology::VertexCopies copies;
  topology::Partition partition;
  topology::DofLayout layout;
  DM dm = nullptr;            // global/local vectors and ghost exchange
  Vec coordinates = nullptr;  // owned reference positions (bs 3)
  assembly::CellData cells;   // operator data of the local cells
  assembly::Boundary boundary;
  std::vector<std::string> warnings;  // "file:line: warning: ..." found while building
  // How the partition is made, kept for re-partitioning after cuts (build_model's arguments).
  topology::PartitionMethod partition_method = topology::PartitionMethod::metis;
  int min_superblock = 1;
  // After a cut, the super-blocks are re-partitioned (cells and vertex copies balanced) when
  // the owned DOFs' max/mean over ranks exceeds this; 0: never (-hexcut_repartition).
  double repartition_imbalance = 0;
  int repartitions = 0;  // how often that happened (the cells changed ranks)
};

/// Voxelizes the deck's geometry. Throws InputError (with the deck line) when the body
/// is empty, or when an image gives some filled cell a Young's modulus <= 0 or not
/// finite. Appends warnings (NaN voxels under filled cells) to `warnings` when given.
lattice::Lattice build_lattice(const deck::Deck& deck,
                               std::vector<std::string>* warnings = nullptr);

/// Builds the whole model on `comm`. `superblock` = cells per super-block side, `method` how
/// super-blocks are assigned to ranks (topology/partition.hpp), `repartition_imbalance` as
/// Model::repartition_imbalance.
PetscErrorCode build_model(MPI_Comm comm, const deck::Deck& deck, int superblock, Model* model,
                           topology::PartitionMethod method = topology::PartitionMethod::metis,
                           double repartition_imbalance = 0);
PetscErrorCode destroy_model(Model* model);

/// After the lattice's links changed (a cut): rebuilds vertex copies, DOF layout, DM,
/// reference positions, cell data and boundary data. The cells keep their ranks (their
/// super-blocks do not move) unless the DOFs' imbalance (max/mean over ranks) exceeds
/// model->repartition_imbalance: then the super-blocks are partitioned again, balancing cells
/// and copies, and the new partition is kept (model->repartitions grows) only if its DOF
/// imbalance is lower and no rank is left without cells. A new copy goes to the rank of its
/// lowest-numbered cell.
/// model->dm and model->coordinates must have been released (or handed over) before.
PetscErrorCode rebuild_topology(MPI_Comm comm, const deck::Deck& deck, Model* model);

}  // namespace hexcut::analysis
