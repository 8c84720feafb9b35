// Coarse cells as a CellOperator (doc/theory.md, "Geometric multigrid", "Architecture"): one
// stored 24x24 block per cell, symmetric and packed (300 numbers), built by the Galerkin
// product A_C = sum_c W_c^T A_c W_c over the cell's children c in the finer level's operator,
// with W_c the trilinear weights of the child's octant. The multigrid's coarse levels are
// StoredCells; composite elements (a coarse level used as the simulation's discretization)
// will be too.
#pragma once

#include <cassert>
#include <cstdint>
#include <vector>

#include "assembly/cell_operator.hpp"
#include "multigrid/energy_interpolation.hpp"
#include "multigrid/stored_cell_kernels.hpp"

namespace hexcut::multigrid {

/// The children of each cell of a coarse level: local cells child[offset[C]..offset[C+1])
/// of the finer level (those on this rank; see StoredCells::galerkin for the others).
struct Children {
  std::vector<std::int32_t> offset, child;
};

/// A faster Galerkin product for some children (multigrid/fine_galerkin.hpp): add(e,
/// octant, A_parent) adds W^T A_e W of the finer level's cell e, W the trilinear weights of
/// `octant`, to the full 24x24 A_parent and returns true, or returns false to leave the
/// product to StoredCells::galerkin (which forms A_e).
class ChildGalerkin {
 public:
  virtual ~ChildGalerkin() = default;
  virtual bool add(std::size_t e, int octant, double* A_parent) const = 0;
};

/// How the blocks are stored: double, or float (-gmg_precision single; the products are
/// still formed in double, only the stored numbers are rounded: half the memory and the
/// memory traffic of the level's operator). In single precision a full rebuild is held in
/// double until round_to_single(), so that the next level's Galerkin product is formed
/// from the double blocks: rounding each level's input compounds (doc/theory.md, "Mixed
/// precision").
enum class Precision { double_, single };

/// Packed sum_c W_c^T A_c W_c over each group of `groups` (groups.offset.size() - 1 of them;
/// kPackedSize numbers each into `packed`): the trilinear Galerkin products of children whose
/// coarse cell is on another rank, formed on their own rank. `fast` as in
/// StoredCells::galerkin (may be null).
void children_products(const assembly::CellOperator& fine,
                       const assembly::CellPositions& fine_position, const Children& groups,
                       const ChildGalerkin* fast, double* packed);

class StoredCells final : public assembly::CellOperator {
 public:
  /// Zero blocks for the layout's local cells (single precision: none until galerkin()).
  explicit StoredCells(const topology::DofLayout& layout, Precision precision = Precision::double_);
  Precision precision() const { return precision_; }
  ~StoredCells() override;
  /// Bytes of the stored blocks (and of the cells' block numbers and the unpacked copies
  /// when blocks are shared).
  std::size_t bytes() const {
    return (blocks_ ? count_ * (holds_double_ ? sizeof(double) : sizeof(float)) : 0) +
           (slot_.size() + unpacked_.size() + unpacked_cells_.size() + packed_cells_.size()) *
               sizeof(std::int32_t) +
           full_double_.size() * sizeof(double) + full_single_.size() * sizeof(float);
  }

  /// Blocks shared by cells whose Galerkin products are equal by construction (doc/theory.md,
  /// "Shared coarse blocks"): `key` per local cell, -1 for a block of its own, k >= 0 for the
  /// one block of every cell with key k (the caller guarantees their products are the same
  /// numbers: unmasked, unrotated children of one material and density in the same octants,
  /// recursively, none on another rank: Multigrid::shared_block_keys).
  /// The next galerkin() forms each shared block once, from the first cell with its key. All
  /// keys -1 (or an empty key): a block per cell, as before any share(). Drops the blocks
  /// (galerkin() must rebuild every cell next). Not with set_block, rotate or rotate_block.
  void share(const std::vector<std::int32_t>& key);
  /// How many blocks are stored (the cells unless some share), and each cell's block
  /// (null: cell e's is block e).
  std::size_t num_blocks() const { return count_ / kPackedSize; }
  const std::int32_t* block_of() const { return slot_.empty() ? nullptr : slot_.data(); }
  /// How many blocks are also held unpacked for apply_add (24x24 each, in the stored type):
  /// those that at least kUnpackFrom cells share, so the copies cost at most 576 / 32 = 18
  /// numbers per cell; the product over an unpacked block that stays in cache is about
  /// twice as fast as over the packed one (doc/benchmarks.md, "Coarse blocks: packed storage
  /// and the product").
  std::size_t num_unpacked() const { return (full_double_.size() + full_single_.size()) / 576; }
  static constexpr std::size_t kUnpackFrom = 32;

  /// Rebuilds the block of every cell with a child marked in `fine_dirty` from `fine`'s
  /// cell matrices; `fine_position` (the children's level positions) gives each child's
  /// octant. The interpolation is trilinear, except for children with a corner in `rows`
  /// (energy-minimizing rows; may be null), whose 24x24 W_c comes from them
  /// (child_interpolation). `fast` (may be null) forms the trilinear products of the
  /// children it can. Marks the rebuilt cells in dirty() and returns how many there were.
  ///
  /// Levels with remote children (hierarchy::Level::remote_children): `remote_sum` holds,
  /// kPackedSize per local cell, the products of its children on other ranks already summed
  /// (children_products() there, reduced here); every block is then rebuilt from its local
  /// children plus that sum.
  std::int64_t galerkin(const assembly::CellOperator& fine,
                        const assembly::CellPositions& fine_position, const Children& children,
                        const std::vector<char>& fine_dirty,
                        const InterpolationRows* rows = nullptr,
                        const ChildGalerkin* fast = nullptr, const double* remote_sum = nullptr);
  /// Single precision: the blocks a full galerkin() left in double are rounded to float
  /// and the double copy freed (call it once the next level is built); a no-op otherwise.
  /// Every action uses the double blocks while they are held; the rounding is done in
  /// place (each float over the front of the doubles already read) and the buffer shrunk.
  void round_to_single();
  /// Per local cell: rebuilt by the last galerkin() (or rotated by rotate()).
  const std::vector<char>& dirty() const { return dirty_; }
  /// Marks every cell in dirty() (their blocks are new to the level below).
  void mark_all_dirty() { dirty_.assign(num_cells(), 1); }
  /// All packed blocks, kPackedSize per block (num_blocks(), block_of()): double (null once rounded
  /// to single) and float (null in double; stale while the double blocks are held), for a device
  /// backend's copy: use the double blocks when they are not null.
  const double* packed_double() const {
    return holds_double_ ? static_cast<const double*>(blocks_) : nullptr;
  }
  const float* packed_single() const {
    return holds_double_ ? nullptr : static_cast<const float*>(blocks_);
  }
  /// Cell e's packed block (kPackedSize numbers), and replacing it. Double precision only
  /// (the composite level), like rotate() and rotate_block().
  const double* block(std::size_t e) const {
    assert(packed_double() && slot_.empty());
    return packed_double() + kPackedSize * e;
  }
  void set_block(std::size_t e, const double* packed);
  /// A_e <- R^ A_e R^T for every local cell e, R = dR[9 e..] (row-major 3x3 per cell); marks
  /// all cells in dirty().
  void rotate(const std::vector<double>& dR);
  /// A_e <- R^ A_e R^T for cell e only (R row-major 3x3); dirty() unchanged.
  void rotate_block(std::size_t e, const double* R);
  /// Dirichlet mask (1 free, 0 fixed; 3 values per local copy, owned and ghosts): galerkin()
  /// zeroes the rows and columns of fixed DOFs in the blocks it builds, D A_C D with
  /// D = diag(mask) (composite elements). Empty: none.
  void set_mask(std::vector<double> mask_local) { mask_ = std::move(mask_local); }

  void apply_add(const double* x, double* y) const override;
  void apply_add(const float* x, float* y) const override;
  void apply_add_colour(const assembly::CellPositions& position, int k, const double* x,
                        double* y) const override;
  void apply_add_colour(const assembly::CellPositions& position, int k, const float* x,
                        float* y) const override;
  void add_diagonal_blocks(double* diag) const override;
  void cell_matrix(std::size_t e, double* A) const override;

 private:
  /// Both apply_add's: V the vectors' type.
  template <class V>
  void apply_add_on(const V* x, V* y) const;
  /// Both apply_add_colour's.
  template <class V>
  void apply_add_colour_on(const assembly::CellPositions& position, int k, const V* x, V* y) const;
  Precision precision_;
  /// The double blocks (set_block, rotate_block: the composite level, always double).
  double* doubles() {
    assert(holds_double_ && blocks_);
    return static_cast<double*>(blocks_);
  }
  float* floats() {
    assert(!holds_double_ && blocks_);
    return static_cast<float*>(blocks_);
  }

  std::size_t slot(std::size_t e) const { return slot_.empty() ? e : std::size_t(slot_[e]); }
  /// Unpacks the blocks num_unpacked() counts into full_double_ or full_single_ (the stored
  /// type), and frees the copies where none qualifies; after every change of the blocks.
  void refresh_unpacked_blocks();
  /// Frees the unpacked copies and their cell lists (the blocks are about to be re-formed).
  void drop_unpacked_blocks();

  // The packed blocks, kPackedSize per block (count_ numbers), as doubles or floats:
  // one malloc'd buffer, so that round_to_single() rounds in place and shrinks it
  // (realloc) instead of holding both copies at the set-up's peak.
  void* blocks_ = nullptr;
  std::size_t count_ = 0;
  bool holds_double_ = true;
  std::vector<char> dirty_;
  std::vector<double> mask_;
  std::vector<std::int32_t> slot_;      // per cell: its block (empty: cell e's is block e)
  std::vector<std::int32_t> source_;    // per block: the cell whose product forms it
  std::vector<std::int32_t> unpacked_;  // per block: its unpacked copy, or -1 (empty: none)
  // With unpacked copies: the cells applied from them, and the others (packed), in order.
  std::vector<std::int32_t> unpacked_cells_, packed_cells_;
  std::vector<double> full_double_;  // the unpacked copies, 576 each
  std::vector<float> full_single_;
};

}  // namespace hexcut::multigrid
