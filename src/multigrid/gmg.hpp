// hexcut's matrix-free geometric multigrid (doc/theory.md, "Geometric multigrid"), applied as the
// PETSc preconditioner type "hexcut" (multigrid/pc_hexcut.hpp).
//
// Level 0 is the simulation's own discretization, applied matrix-free from per-cell
// lambda, mu, rho and rotation (nothing 24x24 is stored per fine cell). Coarse levels
// come from hierarchy::build_hierarchy (components of 2x2x2 blocks) and store one
// Galerkin 24x24 block per coarse cell, A_C = sum_c W_c^T A_c W_c, packed symmetric
// (300 numbers). Transfer is trilinear
// (P, a PETSc MAIJ matrix; restriction = P^T), with the rows of prescribed fine DOFs
// zeroed so the hierarchy sees the constrained operator. Smoothers: 8-colour point-block
// Gauss-Seidel (colours by lattice parity, reversed after the coarse correction, so the
// V-cycle is symmetric) or Chebyshev on point-block Jacobi. The coarsest level is
// assembled and factored (Cholesky, MUMPS by default; options prefix -gmg_coarse_).
//
// The options (-gmg_*) are those of the PC type "hexcut" that applies it (multigrid/pc_hexcut.hpp,
// doc/user-guide.md "Solvers").
#pragma once

#include <petscksp.h>
#include <petscsf.h>

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "assembly/fine_cells.hpp"
#include "assembly/operator.hpp"
#include "hierarchy/hierarchy.hpp"
#include "lattice/lattice.hpp"
#include "multigrid/energy_interpolation.hpp"
#include "multigrid/fine_galerkin.hpp"
#include "multigrid/loop_cycle.hpp"
#include "multigrid/schwarz.hpp"
#include "multigrid/stored_cells.hpp"

namespace hexcut::multigrid {

enum class Smoother { gauss_seidel, chebyshev };

/// Where the cycle runs (-gmg_backend; doc/theory.md, "The CUDA backend"): host, the cycle on
/// PETSc vectors (every feature, any number of ranks); host_loop, the loop-layer cycle
/// (multigrid/loop_cycle.hpp) on the host, the CUDA backend's algorithm with the host's
/// bodies; cuda, the same on device 0 (one rank; builds with nvcc only).
enum class Backend { host, host_loop, cuda };

class Multigrid;
struct Options;

/// Why the loop-layer cycle (Backend::host_loop, cuda) cannot run with these options, or null:
/// it runs Chebyshev on point-block Jacobi or coloured block Gauss-Seidel, trilinear or
/// energy-minimizing interpolation (energy in double only), fine hexahedra (no composite
/// elements), on any number of ranks.
const char* loop_cycle_refusal(const Options& o);

/// A cycle run elsewhere than on PETSc vectors (Backend::host_loop, Backend::cuda): x = M^-1 b
/// on arrays of the first level's owned DOFs. Built after each update() of its Multigrid.
class CycleBackend {
 public:
  virtual ~CycleBackend() = default;
  virtual PetscErrorCode apply(const double* b, double* x) = 0;
};

/// Makes the CUDA backend's cycle for a Multigrid (after its update()). The application
/// installs it when hexcut is built with CUDA (cuda/device_backend.hpp, device_cycle); without
/// it, -gmg_backend cuda is refused.
using CycleBackendFactory = PetscErrorCode (*)(Multigrid& mg, std::unique_ptr<CycleBackend>* out);
/// How many devices the backend can use (0: none, with the reason in *why).
using DeviceCount = int (*)(std::string* why);
void set_device_cycle_factory(CycleBackendFactory factory, DeviceCount count);
CycleBackendFactory device_cycle_factory();
/// Devices the installed backend sees; 0 with the reason in *why (may be null) when none is
/// visible (the runtime's words) or no backend is installed (a build without nvcc).
int device_count(std::string* why);

/// Interpolation between levels (doc/theory.md, "Coarse spaces after cuts and on thin pieces").
/// smoothed: P <- (I - omega D^-1 A) P on the rows near irregular coarse cells; the levels
/// below the first smoothed transfer are then assembled sparse matrices (P^T A P).
enum class Interpolation { trilinear, energy, smoothed };

struct Options {
  hierarchy::HierarchyOptions hierarchy;
  // Chebyshev V(2,2) is the default: on one core it reaches 1e-8 on the 1.4M-DOF
  // cantilever in 10 iterations and half the time of Gauss-Seidel V(1,1) (13), whose
  // colour sweeps cost about two operator applications each (doc/benchmarks.md).
  Smoother smoother = Smoother::chebyshev;
  int presmooth = 2;
  int postsmooth = 2;
  double omega = 1.0;
  int cycle_gamma = 1;     // cycles on the next level per visit: 1 = V-cycle, 2 = W-cycle
  bool cycle_set = false;  // -gmg_cycle was given (callers may pick a default otherwise)
  // Partial rebuild (rotation-only updates): a Galerkin block is rebuilt when a
  // descendant's rotation moved by more than this since the block was built.
  double rebuild_tolerance = 0.0;
  // Rotations are cell-wise similarity transforms, so lambda_max(D^-1 A) drifts slowly:
  // rotation-only updates re-estimate it only every eig_every-th time.
  int eig_every = 10;
  // Energy-minimizing rows where coarse cells are irregular (cut, partial, material jump),
  // trilinear elsewhere; computed at each full rebuild, kept across rotation-only updates.
  Interpolation interpolation = Interpolation::trilinear;
  int energy_iterations = 4;
  int energy_from = 0;  // levels l >= energy_from get energy-minimized (or smoothed) rows
  // Smoothed interpolation: the rows smoothed are those of the corners of the children of
  // irregular coarse cells, grown by this many layers of cells (-1: every row).
  int smoothed_layers = 1;
  // Smoothed interpolation: how many transfers are smoothed, from the first with irregular
  // coarse cells down (-1: all). Each smoothed transfer widens the coarse stencil (27 points
  // -> 125 after one, ~729 after two), so deeper ones cost more than they gain.
  int smoothed_levels = 1;
  // Chebyshev preconditioner on levels >= schwarz_from (-1: none): additive Schwarz on the
  // patches of irregular coarse cells (multigrid/schwarz.hpp), point-block Jacobi elsewhere.
  int schwarz_from = -1;
  // Chebyshev degree on level l: presmooth (postsmooth) x degree_growth^l, at most 8, on levels
  // with irregular coarse cells (coarse levels are cheap: 1/8 of the work of the level above
  // per application); a solid block keeps presmooth (postsmooth) everywhere.
  double degree_growth = 1.0;
  bool view = false;
  // Coarse cells whose Galerkin blocks are equal by construction share one stored block
  // (StoredCells::share; doc/theory.md, "Shared coarse blocks"): linear runs of hexahedra with
  // trilinear transfers; false: a block per cell (for comparison).
  bool shared_blocks = true;
  // Mixed precision (-gmg_precision single): the Galerkin blocks of the levels below the
  // first are stored in float (products in double); the first level, whose operator is the
  // outer CG's, stays double, so CG still converges to its rtol in double.
  Precision precision = Precision::double_;
  Backend backend = Backend::host;
  // Composite elements (doc/theory.md, "Composite elements"; set by the simulation, not an
  // option): the cycle starts on this level, whose operator is the composite system: the
  // Galerkin blocks of the levels below with the rows and columns of fixed composite DOFs
  // (those that carry weight from a prescribed fine DOF) zeroed. Levels below it only carry
  // the Galerkin chain (trilinear interpolation, no smoothing).
  int first_level = 0;
  // false: the coarsest level is assembled but not factored (the composite system for
  // another solver: coarsest_matrix()).
  bool factor_coarsest = true;
  // Composite elements, rotation-only updates: rotate each stored composite block by the
  // change of its element's rotation, A_E <- dR^ A_E dR^T (Wu 2014, secs. 4.4.2-4.4.3:
  // composite matrices are cached and corotated per element), instead of the Galerkin
  // product of the rotated fine cells. Both are the same matrix (the fine cells of an
  // element share its rotation; doc/theory.md, "Composite elements"); taken only where no
  // composite vertex has some but not all of its components fixed.
  bool rotate_composite = true;
};

/// A composite element named by its fine cells: the smallest canonical id among them and
/// how many there are. Cuts only remove links, so each element after a cut holds a subset
/// of the fine cells of one element before it: equal keys mean the same fine cells.
struct CompositeKey {
  std::int32_t first_cell = -1, num_cells = 0;
  bool operator==(const CompositeKey& o) const {
    return first_cell == o.first_cell && num_cells == o.num_cells;
  }
};

/// For each key of `to`: the index of the same key in `from`, or -1.
std::vector<std::int32_t> match_composite_elements(const std::vector<CompositeKey>& from,
                                                   const std::vector<CompositeKey>& to);

/// The composite level's blocks as the last update() left them, per local composite
/// element (Multigrid::composite_blocks), to be carried over a cut to the elements it
/// leaves whole (Multigrid::carry_composite_blocks; doc/theory.md, "Composite elements").
struct CompositeBlocks {
  std::vector<CompositeKey> keys;
  std::vector<double> packed;            // kPackedSize each: the masked Galerkin block
  std::vector<double> rotation;          // 9 each (row-major): the rotation the block has
  std::vector<double> mask;              // 24 each: the composite mask of its corners' DOFs
  std::vector<std::int32_t> fine_fixed;  // each: prescribed DOFs at its fine cells' corners
  assembly::OperatorWeights weights;
};

class Multigrid {
 public:
  /// Builds the hierarchy for the model's lattice and distribution. `layout` and
  /// `fine_dm` are the simulation's DOF layout and DM (level 0). Level 0 refers to
  /// `copies`, `partition` and `layout` (not copied): they must outlive the Multigrid.
  Multigrid(MPI_Comm comm, const lattice::Lattice& lattice, const topology::VertexCopies& copies,
            const topology::Partition& partition, const topology::DofLayout& layout, DM fine_dm,
            const Options& options);
  ~Multigrid();
  Multigrid(const Multigrid&) = delete;
  Multigrid& operator=(const Multigrid&) = delete;

  /// (Re)builds the levels' operators from the fine cell data and weights, with the
  /// given prescribed (owned, global) DOFs as identity rows. Call after each change of
  /// rotations or weights (every step of a corotational run). The first call, and any
  /// call with other weights or prescribed rows, rebuilds everything; otherwise only the
  /// rotations are compared with those the blocks were built from, and only the coarse
  /// cells above changed fine cells are rebuilt (their ancestors). Lambda, mu and rho
  /// are assumed unchanged between updates: call invalidate() after changing them.
  PetscErrorCode update(const assembly::CellData& cells, const assembly::OperatorWeights& w,
                        const std::vector<PetscInt>& constrained_rows);
  /// Makes the next update() rebuild everything.
  void invalidate() { built_ = false; }
  /// Composite runs: the blocks of the composite level after the last update() (empty
  /// before the first, or with first_level 0).
  CompositeBlocks composite_blocks() const;
  /// Composite runs after a cut: blocks of the previous topology (its composite_blocks()).
  /// The next full update() takes over the block of every element whose key, weights,
  /// corner mask and fine prescribed DOFs are the same (rotated by the change of its
  /// element's rotation; only where rotation commutes with the mask), instead of building
  /// it from its fine cells; the levels below the composite one are built as always.
  void carry_composite_blocks(CompositeBlocks blocks) { carried_ = std::move(blocks); }
  /// Composite elements (on this rank) whose blocks the last full update() carried over.
  std::int64_t carried_cells() const { return carried_cells_; }
  /// Per local composite element: its key (empty when the first level is 0).
  const std::vector<CompositeKey>& composite_keys() const { return composite_keys_; }
  /// What the energy-minimizing interpolation to level l did at the last full rebuild
  /// (rows = 0: trilinear; doc/theory.md, "Coarse spaces after cuts and on thin pieces").
  const EnergyStats& energy_stats(int l) const { return energy_stats_[l]; }
  /// Smoothed interpolation: the first level held as an assembled sparse matrix (P^T A P of
  /// the level above with the smoothed P); num_levels() when none is (every level keeps its
  /// matrix-free or 24x24-block operator).
  int assembled_from() const { return assembled_from_; }
  /// Smoothed interpolation to level l+1: the rows smoothed at the last full rebuild (on
  /// this rank, DOFs) and the damping omega = 4 / (3 lambda_max(D^-1 A_l)) (0: not smoothed).
  std::int64_t smoothed_rows(int l) const;
  double smoothing_omega(int l) const;
  /// Schwarz patches of level l's smoother on this rank (0: point-block Jacobi).
  std::int64_t schwarz_patches(int l) const;
  /// Cells of level l (on this rank) whose operator data the last update() rebuilt.
  std::int64_t rebuilt_cells(int l) const { return rebuilt_[l]; }

  /// One cycle (V or W, Options::cycle_gamma) from a zero guess: x = M^{-1} b (x is
  /// overwritten).
  PetscErrorCode cycle(Vec b, Vec x);
  /// y = A x with the constrained operator of the cycle's first level (the fine operator, or
  /// the composite system), matrix-free.
  PetscErrorCode apply_fine(Vec x, Vec y);
  /// A MATSHELL of that operator (owned by the Multigrid).
  Mat fine_operator() const { return shell_; }
  /// The level the cycle starts on (Options::first_level) and its DM.
  int first_level() const { return opt_.first_level; }
  /// Per local fine cell (level 0's layout order): the local index of its ancestor on the
  /// first level, its composite element (composite runs' rotation groups); empty when the
  /// first level is 0 (every cell its own).
  const std::vector<std::int32_t>& composite_elements() const { return composite_element_; }
  DM dm(int l) const;
  /// Prints levels, cells, DOFs, stored numbers and memory (-gmg_view).
  PetscErrorCode view(PetscViewer viewer) const;

  int num_levels() const { return int(levels_.size()); }
  const hierarchy::Level& level(int l) const { return levels_[l]; }
  /// The stored Galerkin blocks of level l >= 1 (after update()); has_stored_cells(l):
  /// whether level l has them (not where it is assembled: -gmg_interpolation smoothed).
  const StoredCells& stored_cells(int l) const;
  bool has_stored_cells(int l) const;
  /// The level position (lattice position at level 0) of each local cell of level l, in the
  /// layout's cell order: what backend::colour_cells and apply_add_colour take.
  const assembly::CellPositions& cell_positions(int l) const;
  /// Level l's operator applied to a level-l global vector (for tests).
  PetscErrorCode apply_level(int l, Vec x, Vec y);
  /// Interpolation from level l+1 to l (global, 3 DOFs per copy). The V-cycle uses
  /// diag(mask(l)) P: rows of prescribed (or dead) DOFs of level l are zeroed.
  Mat interpolation(int l) const;
  /// Level l's DOF mask: 1 free, 0 prescribed (level 0) or dead (no free fine DOF
  /// reaches it; an identity row on coarse levels).
  Vec mask(int l) const;
  /// Global vector of level l.
  PetscErrorCode create_vector(int l, Vec* v) const;
  /// The coarsest level's assembled matrix (masked Galerkin, identity rows where dead),
  /// and its solve x = A_c^+ b as the V-cycle does it (for tests).
  Mat coarsest_matrix() const { return coarse_matrix_; }
  PetscErrorCode solve_coarsest(Vec b, Vec x) { return KSPSolve(coarse_ksp_, b, x); }
  /// The same on arrays of the coarsest level's owned DOFs (the loop-layer cycle's executors).
  PetscErrorCode solve_coarsest(const double* b, double* x);
  /// Level l's per-cell operator: the fine cells on level 0, the stored Galerkin blocks below
  /// (null on assembled levels).
  const assembly::CellOperator* cell_operator(int l) const;
  /// The cycle's levels as plain arrays for the loop-layer cycle (multigrid/loop_cycle.hpp,
  /// the host and CUDA backends of issue 13), after update(): per level its mask, diagonal
  /// blocks, lambda_max, Chebyshev degrees and the transfer from the next level, in the
  /// layout's copy order (owned copies, then the layout's ghosts, then the coarse copies a
  /// transfer reaches beyond those; LoopLevelArrays::ghost_rank/ghost_index connect the ghosts
  /// to their owners). Refused (PETSC_ERR_SUP, with the reason) where that cycle is not the one
  /// cycle() runs: composite elements, Schwarz patches, smoothed interpolation, an assembled
  /// level.
  PetscErrorCode loop_levels(std::vector<LoopLevelArrays>* out) const;
  /// Options::cycle_gamma: 1 V-cycle, 2 W-cycle.
  int cycle_gamma() const { return opt_.cycle_gamma; }
  /// The communicator the hierarchy lives on.
  MPI_Comm comm() const { return comm_; }
  /// Options::precision: Precision::single, the coarse blocks in float (and, on the loop-layer
  /// backends, the cycle's vectors).
  Precision precision() const { return opt_.precision; }

 private:
  struct LevelData;
  // loop_levels' transfer from level l+1: the trilinear MAIJ's scalar weights, or the energy
  // rows' 3x3 blocks; coarse_local maps a coarse global block to its local copy.
  PetscErrorCode scalar_prolongation(int l, PetscInt coarse_begin,
                                     const std::function<std::int32_t(PetscInt)>& coarse_local,
                                     LoopLevelArrays* a) const;
  PetscErrorCode block_prolongation(int l,
                                    const std::function<std::int32_t(PetscInt)>& coarse_local,
                                    LoopLevelArrays* a) const;
  PetscErrorCode apply_level_impl(int l, Vec x, Vec y);
  PetscErrorCode smooth(int l, Vec b, Vec x, int sweeps, bool reverse);
  PetscErrorCode gauss_seidel(int l, Vec b, Vec x, bool reverse);
  PetscErrorCode chebyshev(int l, Vec b, Vec x, int degree);
  PetscErrorCode cycle_level(int l, bool zero_guess);
  PetscErrorCode build_diagonal(int l);
  void mark_dirty_fine_cells(const assembly::CellData& cells, bool full);
  // Per local cell of level l >= 1, the key of the block it shares (StoredCells::share), or
  // -1, from `below`, the keys of level l-1 (level 0, fine_block_keys: the fine cells'
  // material kind and density, where the cell is unmasked; the caller checks that sharing
  // applies at all: trilinear transfers, no rotations, hexahedra).
  std::vector<std::int32_t> shared_block_keys(int l, const std::vector<std::int32_t>& below) const;
  std::vector<std::int32_t> fine_block_keys(const assembly::CellData& cells) const;
  PetscErrorCode build(const lattice::Lattice& lattice, const topology::VertexCopies& copies,
                       const topology::Partition& partition, const topology::DofLayout& layout,
                       DM fine_dm);
  PetscErrorCode estimate_lambda_max(int l);
  PetscErrorCode build_coarsest();
  PetscErrorCode build_interpolation(int l);
  /// Levels with remote children: groups this rank's children of level l's cells on other
  /// ranks (`remote`: (coarse cell, local child of level l-1) pairs) and builds the star forest
  /// that sums their products into the owners' blocks.
  PetscErrorCode build_remote_groups(int l,
                                     std::vector<std::pair<std::int32_t, std::int32_t>> remote);
  /// Those groups' Galerkin products summed onto their coarse cells' ranks: kPackedSize per
  /// local cell of level l in *sum (collective).
  PetscErrorCode remote_products(int l, const ChildGalerkin* fast, std::vector<double>* sum);
  /// Smoothed interpolation: levels >= assembled_from_ as P^T A P of the level above, from the
  /// assembled operator of level assembled_from_ - 1 down, and the coarsest solver.
  PetscErrorCode build_smoothed_chain();
  /// The smoothing rows' point-block Jacobi D^-1 of level l as a sparse matrix (rows outside
  /// the smoothed set empty).
  PetscErrorCode smoothing_jacobi(int l, Mat* Dinv);
  /// diag_inv and mask of an assembled level from its matrix, with identity rows made where
  /// no fine DOF reaches (dead DOFs).
  PetscErrorCode assembled_diagonal(int l);
  PetscErrorCode build_composite_mask();
  /// The carried blocks that apply (carry_composite_blocks) copied into the composite
  /// level; (*carried)[C] = 1 for those elements.
  PetscErrorCode take_carried_blocks(const assembly::CellData& cells, std::vector<char>* carried);
  /// The rotation element C's block is built at: its fine cells' (identity when there are
  /// no rotations).
  const double* element_rotation(const assembly::CellData& cells, std::size_t C) const;
  /// Rotation-only update of the composite level by rotating its blocks; false in *done
  /// when it does not apply (then the Galerkin chain rebuilds them).
  PetscErrorCode rotate_composite_blocks(const assembly::CellData& cells, bool* done);
  bool has_irregular_parents(int l) const;  // some cell of level l+1 is irregular
  bool uses_schwarz(int l) const;
  PetscErrorCode build_schwarz(int l);
  PetscErrorCode precondition(int l, Vec r, Vec z);
  int degree(int l, int sweeps) const;

  MPI_Comm comm_;
  Options opt_;
  std::vector<hierarchy::Level> levels_;
  std::vector<std::unique_ptr<LevelData>> data_;
  const assembly::CellData* fine_cells_ = nullptr;
  std::unique_ptr<assembly::FineCells> fine_op_;  // level 0's operator
  FineGalerkinTables fine_tables_;                // level 1's products, made with fine_op_
  assembly::OperatorWeights weights_;
  bool built_ = false;
  std::vector<double> built_rotation_;  // level 0: rotation each cell's parent block saw
  std::vector<PetscInt> built_rows_;
  int updates_since_estimate_ = 0;
  std::vector<std::int64_t> rebuilt_;
  std::vector<std::vector<char>> irregular_;  // per level l >= 1: its irregular cells (canonical)
  std::vector<InterpolationRows> rows_;       // per level l < L-1: energy-minimized rows to it
  std::vector<EnergyStats> energy_stats_;
  int assembled_from_ = 0;              // smoothed interpolation: first assembled level (L: none)
  std::vector<double> composite_mask_;  // first level > 0: per local DOF, 0 fixed
  std::vector<std::int32_t> composite_element_;     // per local fine cell: its first-level cell
  std::vector<std::int32_t> composite_fine_cell_;   // per local composite element: a fine cell
  std::vector<double> composite_rotation_;          // per element: rotation its block has
  std::vector<CompositeKey> composite_keys_;        // per local composite element
  std::vector<std::int32_t> composite_fine_fixed_;  // per element: CompositeBlocks::fine_fixed
  CompositeBlocks carried_;                         // carry_composite_blocks, until update()
  std::int64_t carried_cells_ = 0;
  // Per local fine cell: the Galerkin blocks between it and its composite element were not
  // built (the element's block was carried over a cut): the next Galerkin update of the
  // element rebuilds all of it (mark_dirty_fine_cells).
  std::vector<char> chain_missing_;
  bool rotatable_ = false;  // every composite vertex fixed in all components or none
  Mat shell_ = nullptr;
  std::unique_ptr<CycleBackend> backend_cycle_;  // Backend::host_loop, cuda: rebuilt by update()
  KSP coarse_ksp_ = nullptr;
  Mat coarse_matrix_ = nullptr;
  PetscLogEvent ev_setup_ = 0, ev_apply_ = 0, ev_smooth_ = 0, ev_interp_ = 0, ev_schwarz_ = 0;
};

}  // namespace hexcut::multigrid
