#include "analysis/memory.hpp"

#include <petscsys.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>

#include "common/errors.hpp"
#include "common/petsc_check.hpp"

namespace hexcut::analysis {
namespace {

constexpr double kLibraries = 45e6;           // PETSc, MPI, HDF5 after initialization [B]
constexpr double kPerLatticeCell = 14.0;      // dense material grid + cell index + position index
constexpr double kPerImageCell = 8.0;         // dense Young's modulus grid of an image
constexpr double kReplicatedPerCell = 300.0;  // cells, links, vertex copies, partition

bool has_image_youngs(const deck::Deck& deck) {
  return std::any_of(deck.geometry.begin(), deck.geometry.end(), [](const auto& g) {
    return g.kind == deck::GeometryStep::Kind::image_youngs;
  });
}

/// Whether the multigrid will share its coarse Galerkin blocks (doc/theory.md, "Shared coarse
/// blocks"; multigrid/gmg.cpp decides it the same way): linear runs of hexahedra whose cells
/// have material kinds (no Young's modulus image), trilinear transfers, -gmg_shared_blocks
/// not false. Reads the options database (the deck's petsc_options are in it by now).
PetscErrorCode shares_coarse_blocks(const deck::Deck& deck, bool* shared) {
  PetscFunctionBeginUser;
  *shared = false;
  if (deck.analysis.formulation != deck::Analysis::Formulation::linear ||
      deck.discretization.type != deck::Discretization::Type::hexahedra || has_image_youngs(deck))
    PetscFunctionReturn(0);
  PetscBool on = PETSC_TRUE;
  char interpolation[32] = "trilinear";
  PetscCall(PetscOptionsGetBool(nullptr, nullptr, "-gmg_shared_blocks", &on, nullptr));
  PetscCall(PetscOptionsGetString(nullptr, nullptr, "-gmg_interpolation", interpolation,
                                  sizeof interpolation, nullptr));
  *shared = on && std::string(interpolation) == "trilinear";
  PetscFunctionReturn(0);
}

/// Distributed bytes per filled cell of the solver (operator, vectors, preconditioner),
/// for `cells` filled cells of a lattice of `dims` cells; `shared`: the multigrid shares
/// its coarse blocks.
double solver_bytes_per_cell(const deck::Solver& s, std::int64_t cells,
                             const std::array<int, 3>& dims, bool shared) {
  switch (s.type) {
    case deck::Solver::Type::gmg:
    case deck::Solver::Type::gmg_cycles:
      // With the 300 replicated bytes, peaks measured on the cantilever, libraries deducted
      // (doc/benchmarks.md, "Memory per DOF"): blocks shared (1300 per cell) 1198 at 466,560
      // cells and 1138 at 17,280,000; a block per coarse cell (1600) 1540 at 466,560 and
      // 1506 at 14,049,280. 1.8e3 before the output stopped being the peak.
      return shared ? 1.0e3 : 1.3e3;
    case deck::Solver::Type::cg_jacobi:
      return 3.7e3;
    case deck::Solver::Type::hypre:
    case deck::Solver::Type::gamg:
      return 9.5e3;
    case deck::Solver::Type::direct: {
      // Nested-dissection fill of a 3-D grid grows like n^(4/3): per cell like n^(1/3);
      // measured on cubes of 4096 and 13824 cells the exponent was nearer 1/4. A bar
      // (one side much longer) is cut across first, into cubes of its cross-section's
      // size, so its fill per cell is that of a cube with the middle side d: n is capped
      // at d^3. Measured peaks: 192 x 24 x 24 cells 3.96 GiB (estimate 4.0), 1280 x 16 x 16
      // 8.96 GiB (8.7); without the cap the estimates were 6.6 and 25.7 (doc/benchmarks.md).
      std::array<double, 3> d{double(dims[0]), double(dims[1]), double(dims[2])};
      std::sort(d.begin(), d.end());
      const double n = std::min(double(cells), d[1] * d[1] * d[1]);
      return 28e3 * std::pow(std::max(1.0, n / 4096.0), 0.25);
    }
  }
  return 9.5e3;
}

double gib(double bytes) {
  return bytes / (1024.0 * 1024.0 * 1024.0);
}

/// A number from /proc/meminfo [bytes], or 0.
double meminfo(const std::string& key) {
  std::ifstream in("/proc/meminfo");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind(key + ":", 0) == 0) return 1024.0 * std::stod(line.substr(key.size() + 1));
  return 0.0;
}

/// The cgroup (v2) memory limit minus what the cgroup uses [bytes], or 0 when unlimited.
double cgroup_room() {
  std::ifstream max("/sys/fs/cgroup/memory.max"), current("/sys/fs/cgroup/memory.current");
  std::string limit;
  double used = 0;
  if (!(max >> limit) || limit == "max" || !(current >> used)) return 0.0;
  return std::max(0.0, std::stod(limit) - used);
}

}  // namespace

double estimate_bytes_per_rank(const deck::Deck& deck, std::int64_t lattice_cells,
                               std::int64_t material_cells, int ranks, bool shared_blocks) {
  const bool image_youngs = has_image_youngs(deck);
  double bytes =
      kLibraries + (kPerLatticeCell + (image_youngs ? kPerImageCell : 0.0)) * double(lattice_cells);
  if (material_cells > 0) {
    double distributed =
        solver_bytes_per_cell(deck.solver, material_cells, deck.lattice.dims, shared_blocks);
    // Corotational dynamic runs on composite elements of level l add each element's own
    // data (a 24x24 stiffness, its Gram matrix and gradients: 5.6 kB per element, one per
    // 8^l cells) and the preimage's AIJ interpolation (~300 B per cell): measured 1.1 kB
    // per cell at level 1 and 0.4 kB at level 2 on the bunny (doc/benchmarks.md).
    if (deck.discretization.type == deck::Discretization::Type::composite &&
        deck.discretization.level > 0 &&
        deck.analysis.formulation == deck::Analysis::Formulation::corotational &&
        deck.analysis.type == deck::Analysis::Type::dynamic)
      distributed += 300.0 + 5600.0 / std::pow(8.0, deck.discretization.level);
    bytes += kReplicatedPerCell * double(material_cells) +
             distributed * double(material_cells) / double(std::max(ranks, 1));
  }
  return bytes;
}

PetscErrorCode available_bytes_on_node(double* bytes) {
  PetscFunctionBeginUser;
  char buf[64] = "";
  PetscBool set = PETSC_FALSE;
  PetscCall(
      PetscOptionsGetString(nullptr, nullptr, "-hexcut_memory_available", buf, sizeof buf, &set));
  if (set) {
    char* end = nullptr;
    const double g = std::strtod(buf, &end);
    if (*buf == '\0' || *end != '\0' || !(g >= 0))
      throw InputError(std::string("-hexcut_memory_available must be a number of GiB >= 0, got '") +
                       buf + "'");
    *bytes = g * 1024.0 * 1024.0 * 1024.0;
    PetscFunctionReturn(0);
  }
  double avail = meminfo("MemAvailable");
  if (const double room = cgroup_room(); room > 0) avail = avail > 0 ? std::min(avail, room) : room;
  *bytes = avail;
  PetscFunctionReturn(0);
}

PetscErrorCode require_memory(MPI_Comm comm, const deck::Deck& deck, std::int64_t material_cells) {
  PetscFunctionBeginUser;
  int size, node_size, node_rank;
  MPI_Comm_size(comm, &size);
  MPI_Comm node;
  MPI_Comm_split_type(comm, MPI_COMM_TYPE_SHARED, 0, MPI_INFO_NULL, &node);
  MPI_Comm_size(node, &node_size);
  MPI_Comm_rank(node, &node_rank);
  MPI_Comm_free(&node);
  bool shared_blocks = false;
  PetscCall(parse_petsc_options(comm, [&] { return shares_coarse_blocks(deck, &shared_blocks); }));
  const double per_rank =
      estimate_bytes_per_rank(deck, deck.lattice.num_cells(), material_cells, size, shared_blocks);
  // Each node's first rank compares its node's need with what the node has.
  double worst[3] = {0.0, 0.0, 0.0};  // need / available, need, available
  if (node_rank == 0) {
    double avail = 0.0;
    PetscCall(available_bytes_on_node(&avail));
    const double need = per_rank * node_size;
    if (avail > 0) worst[0] = need / avail, worst[1] = need, worst[2] = avail;
  }
  struct {
    double ratio;
    int rank;
  } mine{worst[0], 0}, max;
  MPI_Comm_rank(comm, &mine.rank);
  MPI_Allreduce(&mine, &max, 1, MPI_DOUBLE_INT, MPI_MAXLOC, comm);
  MPI_Bcast(worst, 3, MPI_DOUBLE, max.rank, comm);
  if (max.ratio <= 1.0) PetscFunctionReturn(0);
  char msg[600];
  if (material_cells < 0)
    std::snprintf(msg, sizeof msg,
                  "the lattice of %lld cells needs about %.3g GiB per rank before the body is "
                  "even voxelized (every rank holds the lattice), %.3g GiB on a node with %d "
                  "rank(s) that has %.3g GiB available: use a coarser h or a smaller lattice "
                  "(doc/user-guide.md, \"Memory\"; -hexcut_memory_available GiB overrides what "
                  "hexcut assumes the node has, 0 skips this check)",
                  (long long)deck.lattice.num_cells(), gib(per_rank), gib(worst[1]),
                  int(worst[1] / per_rank + 0.5), gib(worst[2]));
  else
    std::snprintf(msg, sizeof msg,
                  "this job (%lld cells, solver %s, %d rank(s)) needs about %.3g GiB per rank, "
                  "%.3g GiB on a node with %d rank(s) that has %.3g GiB available: use more "
                  "nodes, a leaner solver (gmg) or a coarser h (doc/user-guide.md, \"Memory\"; "
                  "-hexcut_memory_available GiB overrides what hexcut assumes the node has, 0 "
                  "skips this check)",
                  (long long)material_cells, deck::to_string(deck.solver.type), size, gib(per_rank),
                  gib(worst[1]), int(worst[1] / per_rank + 0.5), gib(worst[2]));
  throw InputError((material_cells < 0 ? deck.lattice_where.prefix() : deck.path + ":1: ") + msg);
}

}  // namespace hexcut::analysis
