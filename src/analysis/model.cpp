#include "analysis/model.hpp"

#include "common/errors.hpp"
#include "geometry/voxelize.hpp"

namespace hexcut::analysis {

lattice::Lattice build_lattice(const deck::Deck& deck) {
  auto grid = geometry::make_empty_grid(deck.lattice);
  for (const auto& step : deck.geometry) {
    if (step.kind == deck::GeometryStep::Kind::image_youngs)
      geometry::apply_image_youngs(grid, *step.image, step.youngs_scale);
    for (const auto& op : deck::membership_ops(step)) geometry::apply(grid, op);
  }
  if (geometry::count_filled(grid) == 0)
    throw InputError(deck.geometry.front().where.prefix() +
                     "the geometry is empty: no cell centre of the lattice lies inside the body");
  std::vector<lattice::MaterialProperties> props;
  for (const auto& m : deck.materials)
    props.push_back({m.youngs_modulus, m.poisson_ratio, m.density});
  return lattice::build_lattice(grid.spec, grid.material, grid.youngs, props);
}

namespace {

/// Everything that follows from the copies and the partition.
PetscErrorCode build_distributed_data(MPI_Comm comm, const deck::Deck& deck, int rank, Model* M) {
  PetscFunctionBeginUser;
  M->layout = topology::build_dof_layout(M->copies, M->partition, rank);
  PetscCall(topology::create_dm(comm, M->layout, &M->dm));
  PetscCall(
      assembly::reference_positions(M->dm, M->lattice, M->copies, M->layout, &M->coordinates));
  M->cells = assembly::make_cell_data(M->lattice, M->layout);
  M->boundary = assembly::resolve_boundary(comm, deck, M->lattice, M->copies, M->layout);
  PetscFunctionReturn(0);
}

}  // namespace

PetscErrorCode build_model(MPI_Comm comm, const deck::Deck& deck, int superblock, Model* M) {
  PetscFunctionBeginUser;
  PetscMPIInt rank, size;
  PetscCallMPI(MPI_Comm_rank(comm, &rank));
  PetscCallMPI(MPI_Comm_size(comm, &size));
  M->lattice = build_lattice(deck);
  M->copies = topology::build_vertex_copies(M->lattice);
  M->partition = topology::partition_lattice(M->lattice, M->copies, size, superblock);
  PetscCall(build_distributed_data(comm, deck, rank, M));
  PetscFunctionReturn(0);
}

PetscErrorCode rebuild_topology(MPI_Comm comm, const deck::Deck& deck, Model* M) {
  PetscFunctionBeginUser;
  PetscMPIInt rank;
  PetscCallMPI(MPI_Comm_rank(comm, &rank));
  M->copies = topology::build_vertex_copies(M->lattice);
  auto& P = M->partition;
  P.copy_rank.resize(M->copies.num_copies);
  for (std::int32_t v = 0; v < M->copies.num_copies; ++v)
    P.copy_rank[v] = P.cell_rank[M->copies.first_cell[v]];
  PetscCall(build_distributed_data(comm, deck, rank, M));
  PetscFunctionReturn(0);
}

PetscErrorCode destroy_model(Model* M) {
  PetscFunctionBeginUser;
  PetscCall(VecDestroy(&M->coordinates));
  PetscCall(DMDestroy(&M->dm));
  PetscFunctionReturn(0);
}

}  // namespace hexcut::analysis
