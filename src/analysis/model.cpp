#include "analysis/model.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "analysis/events.hpp"
#include "analysis/memory.hpp"
#include "assembly/initial_stress.hpp"
#include "common/errors.hpp"
#include "geometry/voxelize.hpp"

namespace hexcut::analysis {

namespace {

/// Young's moduli set by images (youngs_scale) must be usable: every filled cell whose
/// E came from an image gets E > 0 and finite, else an InputError at the image's deck
/// line with the number of such cells. Filled cells inside an image whose voxel is NaN
/// keep their material's E: reported as a warning with the count.
void check_image_youngs(const deck::Deck& deck, const geometry::VoxelGrid& grid,
                        const std::vector<std::int32_t>& touched,
                        std::vector<std::string>* warnings) {
  std::vector<const deck::GeometryStep*> images;
  std::vector<std::int32_t> image_step;  // per image: its position in deck.geometry
  for (std::size_t s = 0; s < deck.geometry.size(); ++s)
    if (deck.geometry[s].kind == deck::GeometryStep::Kind::image_youngs) {
      images.push_back(&deck.geometry[s]);
      image_step.push_back(std::int32_t(s));
    }
  if (images.empty() || grid.youngs.empty()) return;
  struct Tally {
    std::int64_t bad = 0, nan = 0;
    std::array<int, 3> example{};
    double value = 0.0;
  };
  std::vector<Tally> tally(images.size());
  const auto& spec = grid.spec;
  for (int k = 0; k < spec.dims[2]; ++k)
    for (int j = 0; j < spec.dims[1]; ++j)
      for (int i = 0; i < spec.dims[0]; ++i) {
        const auto c = spec.cell_index(i, j, k);
        if (grid.material[c] < 0) continue;
        const Eigen::Vector3d x = spec.cell_centre(i, j, k);
        // The image that decided this cell's E: the last one that covers its centre.
        for (std::size_t s = images.size(); s-- > 0;) {
          const auto box = images[s]->image->bounds();
          const double v = images[s]->image->sample(x);
          const bool inside =
              ((x - box.lo).array() >= 0.0).all() && ((x - box.hi).array() < 0.0).all();
          if (inside || !std::isnan(v)) {
            // A later operation that changed the cell decided its E (its material's).
            if (!touched.empty() && touched[c] > image_step[s]) break;
            auto& t = tally[s];
            // A calibrated image averages the voxels in the cell: what counts is the E it
            // gave the cell (NaN: none of its voxels had data), not the centre voxel.
            const bool no_data =
                images[s]->calibration ? std::isnan(grid.youngs[c]) : std::isnan(v);
            if (no_data) {
              ++t.nan;
            } else if (const double E = grid.youngs[c]; !(E > 0.0) || !std::isfinite(E)) {
              if (t.bad++ == 0) t.example = {i, j, k}, t.value = v;
            }
            break;
          }
        }
      }
  for (std::size_t s = 0; s < images.size(); ++s) {
    const auto& t = tally[s];
    if (t.bad > 0) {
      char msg[400];
      std::snprintf(msg, sizeof msg,
                    "image: Young's modulus from the image is <= 0 or not finite in %lld "
                    "filled cell(s), e.g. cell (%d, %d, %d): voxel %g gives %g Pa. Only E > 0 "
                    "can be simulated: remove those cells (threshold + material, or a "
                    "subtract), correct the image or set calibration.E_min",
                    (long long)t.bad, t.example[0], t.example[1], t.example[2], t.value,
                    grid.youngs[spec.cell_index(t.example[0], t.example[1], t.example[2])]);
      throw InputError(images[s]->where.prefix() + msg);
    }
    if (t.nan > 0 && warnings)
      warnings->push_back(images[s]->where.prefix() + "warning: " + std::to_string(t.nan) +
                          " filled cell(s) sample a NaN voxel of this image and keep their "
                          "material's E");
  }
}

}  // namespace

lattice::Lattice build_lattice(const deck::Deck& deck, std::vector<std::string>* warnings) {
  auto grid = geometry::make_empty_grid(deck.lattice);
  // Per cell the last geometry step that changed it (-1: none), once an image sets E: the
  // check below skips cells whose E a later operation reset.
  std::vector<std::int32_t> touched;
  for (std::size_t s = 0; s < deck.geometry.size(); ++s) {
    const auto& step = deck.geometry[s];
    if (step.kind == deck::GeometryStep::Kind::image_youngs) {
      if (step.calibration)
        geometry::apply_image_calibrated_youngs(grid, *step.image, *step.calibration);
      else
        geometry::apply_image_youngs(grid, *step.image, step.youngs_scale);
      if (touched.empty()) touched.assign(grid.material.size(), -1);
    }
    for (const auto& op : deck::membership_ops(step))
      geometry::apply(grid, op, touched.empty() ? nullptr : &touched, std::int32_t(s));
  }
  if (geometry::count_filled(grid) == 0)
    throw InputError(deck.geometry.front().where.prefix() +
                     "the geometry is empty: no cell centre of the lattice lies inside the body");
  check_image_youngs(deck, grid, touched, warnings);
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
  M->cells.initial_stress = assembly::initial_stress_of_cells(comm, deck, M->lattice, M->layout);
  M->boundary.initial_stress_load = assembly::initial_stress_load(
      deck, M->lattice, M->copies, M->layout, M->cells.initial_stress);
  PetscFunctionReturn(0);
}

}  // namespace

PetscErrorCode build_model(MPI_Comm comm, const deck::Deck& deck, int superblock, Model* M,
                           topology::PartitionMethod method, double repartition_imbalance) {
  PetscFunctionBeginUser;
  PetscMPIInt rank, size;
  PetscCallMPI(MPI_Comm_rank(comm, &rank));
  PetscCallMPI(MPI_Comm_size(comm, &size));
  PetscCall(require_memory(comm, deck, -1));  // before the dense lattice tables are allocated
  {
    const EventScope scope(events().voxelize);
    M->lattice = build_lattice(deck, &M->warnings);
    for (auto& w : assembly::initial_stress_warnings(deck, M->lattice)) M->warnings.push_back(w);
  }
  PetscCall(require_memory(comm, deck, M->lattice.num_cells()));
  const EventScope scope(events().topology);
  M->copies = topology::build_vertex_copies(M->lattice);
  // Composite elements of level l are cells of hierarchy level l, which must lie on one
  // rank: super-blocks of at least 2^l cells; 2^(l+2) by default, so that hexcut's multigrid
  // has two levels below the composite one (hierarchy/hierarchy.hpp).
  int min_superblock = 1;
  if (deck.discretization.type == deck::Discretization::Type::composite) {
    min_superblock = 1 << deck.discretization.level;
    superblock = std::max(superblock, 4 * min_superblock);
  }
  M->partition_method = method;
  M->min_superblock = min_superblock;
  M->repartition_imbalance = repartition_imbalance;
  M->partition = topology::partition_lattice(M->lattice, M->copies, size, superblock,
                                             min_superblock, method, comm);
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
  if (P.num_ranks > 1 && M->repartition_imbalance > 0) {
    // Every rank holds the same lattice and copies: the same decision and partition on all.
    // The new partition is kept only if it balances the DOFs better: a partitioner balances
    // super-blocks, and when the cut copies sit in a few of them it may do no better (then
    // moving the state would cost time and gain nothing).
    const double before = topology::partition_balance(P).copy_imbalance();
    if (before > M->repartition_imbalance) {
      auto Q = topology::partition_lattice(M->lattice, M->copies, P.num_ranks, P.superblock,
                                           M->min_superblock, M->partition_method, comm, true);
      const auto b = topology::partition_balance(Q);
      if (b.copy_imbalance() < before && b.empty_ranks == 0) {
        P = std::move(Q);
        ++M->repartitions;
      }
    }
  }
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
