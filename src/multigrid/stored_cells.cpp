#include "multigrid/stored_cells.hpp"

#include <algorithm>
#include <cassert>
#include <cstdlib>
#include <cstring>
#include <new>

#include "backend/loop.hpp"
#include "backend/restriction.hpp"
#include "element/corotation.hpp"
#include "multigrid/kernels.hpp"

namespace hexcut::multigrid {

namespace {

/// Zeroed heap storage for `count` numbers of `bytes` each (never null, even for 0).
void* allocate_zeroed(std::size_t count, std::size_t bytes) {
  void* p = std::calloc(std::max<std::size_t>(count, 1), bytes);
  if (!p) throw std::bad_alloc();
  return p;
}

/// Adds fine cell e's trilinear Galerkin product W_o^T A_e W_o (octant o) to the 24x24
/// `parent`: from `fast` when it has it, else from the cell's matrix (`child`: 576 scratch).
void add_trilinear_child(const assembly::CellOperator& fine, std::size_t e, int octant,
                         const ChildGalerkin* fast, double* child, double* parent) {
  if (fast && fast->add(e, octant, parent)) return;
  fine.cell_matrix(e, child);
  galerkin_accumulate(child, octant, parent);
}

}  // namespace

StoredCells::StoredCells(const topology::DofLayout& layout, Precision precision)
    : CellOperator(layout), precision_(precision), count_(kPackedSize * layout.cells.size()) {
  // Single precision allocates at the first galerkin() (in double, rounded later): no
  // float buffer to free and reallocate at the set-up's peak.
  if (precision == Precision::double_) blocks_ = allocate_zeroed(count_, sizeof(double));
}

StoredCells::~StoredCells() {
  std::free(blocks_);
}

void StoredCells::share(const std::vector<std::int32_t>& key) {
  assert(key.empty() || key.size() == num_cells());
  slot_.clear();
  source_.clear();
  const std::size_t n = num_cells();
  std::size_t blocks = n;
  if (std::any_of(key.begin(), key.end(), [](std::int32_t k) { return k >= 0; })) {
    // A block per unshared cell and one per key, in order of first appearance.
    std::vector<std::int32_t> of_key;
    slot_.resize(n);
    for (std::size_t e = 0; e < n; ++e) {
      std::int32_t s;
      if (key[e] < 0) {
        s = std::int32_t(source_.size());
        source_.push_back(std::int32_t(e));
      } else {
        if (std::size_t(key[e]) >= of_key.size()) of_key.resize(std::size_t(key[e]) + 1, -1);
        auto& k = of_key[std::size_t(key[e])];
        if (k < 0) {
          k = std::int32_t(source_.size());
          source_.push_back(std::int32_t(e));
        }
        s = k;
      }
      slot_[e] = s;
    }
    blocks = source_.size();
  }
  std::free(blocks_);
  blocks_ = nullptr;
  count_ = kPackedSize * blocks;
  holds_double_ = true;
  if (precision_ == Precision::double_) blocks_ = allocate_zeroed(count_, sizeof(double));
  drop_unpacked_blocks();  // galerkin() forms the new blocks, and their unpacked copies
}

void StoredCells::drop_unpacked_blocks() {
  std::vector<std::int32_t>().swap(unpacked_);
  std::vector<std::int32_t>().swap(unpacked_cells_);
  std::vector<std::int32_t>().swap(packed_cells_);
  std::vector<double>().swap(full_double_);
  std::vector<float>().swap(full_single_);
}

void StoredCells::refresh_unpacked_blocks() {
  drop_unpacked_blocks();
  if (!blocks_ || slot_.empty()) return;
  std::vector<std::size_t> users(num_blocks(), 0);
  for (std::int32_t b : slot_) ++users[std::size_t(b)];
  std::vector<std::int32_t> unpacked(users.size(), -1);
  std::int32_t count = 0;
  for (std::size_t b = 0; b < users.size(); ++b)
    if (users[b] >= kUnpackFrom) unpacked[b] = count++;
  if (count == 0) return;
  unpacked_ = std::move(unpacked);
  for (std::size_t e = 0; e < slot_.size(); ++e)
    (unpacked_[std::size_t(slot_[e])] >= 0 ? unpacked_cells_ : packed_cells_)
        .push_back(std::int32_t(e));
  // In the stored type: a float block's unpacked numbers are the same floats.
  const auto unpack_into = [&](const auto* packed, auto& full) {
    full.resize(576 * std::size_t(count));
    double A[576];
    for (std::size_t b = 0; b < unpacked_.size(); ++b) {
      if (unpacked_[b] < 0) continue;
      unpack_symmetric(packed + kPackedSize * b, A);
      std::copy_n(A, 576, &full[576 * std::size_t(unpacked_[b])]);
    }
  };
  if (holds_double_)
    unpack_into(doubles(), full_double_);
  else
    unpack_into(floats(), full_single_);
}

std::int64_t StoredCells::galerkin(const assembly::CellOperator& fine,
                                   const assembly::CellPositions& fine_position,
                                   const Children& children, const std::vector<char>& fine_dirty,
                                   const InterpolationRows* rows, const ChildGalerkin* fast,
                                   const double* remote_sum) {
  // Each block is accumulated in full 24x24 form from its (at most 8) children, then
  // stored packed.
  const std::size_t n = num_cells();
  dirty_.assign(n, remote_sum ? 1 : 0);
  std::int64_t rebuilt = 0;
  for (std::size_t C = 0; C < n; ++C) {
    for (auto k = children.offset[C]; k < children.offset[C + 1]; ++k)
      if (fine_dirty[children.child[k]]) dirty_[C] = 1;
    rebuilt += dirty_[C];
  }
  // Single precision: a rebuild of every block is kept in double until round_to_single(),
  // so that the next level's Galerkin product (and the coarsest factorization) sees the
  // double blocks, not their rounding; a partial rebuild writes float directly (its clean
  // blocks exist only as floats by then).
  if (!blocks_ ||
      (precision_ == Precision::single && std::size_t(rebuilt) == n && !holds_double_)) {
    std::free(blocks_);  // every block is rebuilt from the finer level: none is read here
    blocks_ = nullptr;
    blocks_ = allocate_zeroed(count_, sizeof(double));
    holds_double_ = true;
  }
  double child[576], parent[576], W[576];
  const bool general = rows && !rows->empty();
  const auto& fine_corners = fine.layout().cell_corners;
  const auto& parent_corners = layout().cell_corners;
  for (std::size_t C = 0; C < n; ++C) {
    // A shared block is formed from its first cell, once.
    if (!dirty_[C] || (!slot_.empty() && std::size_t(source_[slot_[C]]) != C &&
                       dirty_[std::size_t(source_[slot_[C]])]))
      continue;
    std::fill(parent, parent + 576, 0.0);
    if (remote_sum) unpack_symmetric(remote_sum + kPackedSize * C, parent);
    for (auto k = children.offset[C]; k < children.offset[C + 1]; ++k) {
      const auto e = std::size_t(children.child[k]);
      const auto& p = fine_position[e];
      const int octant = element::parity_octant(p[0], p[1], p[2]);
      if (general && rows->touches(fine_corners[e].data())) {
        fine.cell_matrix(e, child);
        child_interpolation(*rows, fine_corners[e].data(), parent_corners[C].data(), octant, W);
        galerkin_accumulate_general(child, W, parent);
      } else {
        add_trilinear_child(fine, e, octant, fast, child, parent);
      }
    }
    if (!mask_.empty()) {
      const auto& corners = parent_corners[C];
      for (int i = 0; i < 24; ++i)
        if (mask_[3 * std::size_t(corners[i / 3]) + i % 3] == 0.0)
          for (int j = 0; j < 24; ++j) parent[24 * i + j] = parent[24 * j + i] = 0.0;
    }
    if (holds_double_)
      pack_symmetric(parent, doubles() + kPackedSize * slot(C));
    else
      pack_symmetric(parent, floats() + kPackedSize * slot(C));
  }
  refresh_unpacked_blocks();
  return rebuilt;
}

void children_products(const assembly::CellOperator& fine,
                       const assembly::CellPositions& fine_position, const Children& groups,
                       const ChildGalerkin* fast, double* packed) {
  double child[576], parent[576];
  for (std::size_t G = 0; G + 1 < groups.offset.size(); ++G) {
    std::fill(parent, parent + 576, 0.0);
    for (auto k = groups.offset[G]; k < groups.offset[G + 1]; ++k) {
      const auto e = std::size_t(groups.child[k]);
      const auto& p = fine_position[e];
      add_trilinear_child(fine, e, element::parity_octant(p[0], p[1], p[2]), fast, child, parent);
    }
    pack_symmetric(parent, packed + kPackedSize * G);
  }
}

void StoredCells::round_to_single() {
  if (precision_ != Precision::single || !holds_double_) return;
  // Float i goes to bytes [4i, 4i + 4), inside double i/2, which was read at step i/2 <= i;
  // double i (bytes [8i, 8i + 8)) is still intact when it is read. memcpy: no aliasing.
  auto* bytes = static_cast<unsigned char*>(blocks_);
  for (std::size_t i = 0; i < count_; ++i) {
    double v;
    std::memcpy(&v, bytes + sizeof(double) * i, sizeof v);
    const float f = float(v);
    std::memcpy(bytes + sizeof(float) * i, &f, sizeof f);
  }
  if (void* shrunk = std::realloc(blocks_, std::max<std::size_t>(count_, 1) * sizeof(float)))
    blocks_ = shrunk;  // else the larger buffer stays, holding the floats at its front
  holds_double_ = false;
  refresh_unpacked_blocks();
}

void StoredCells::rotate(const std::vector<double>& dR) {
  assert(slot_.empty());
  const std::size_t n = num_cells();
  dirty_.assign(n, 1);
  for (std::size_t C = 0; C < n; ++C) rotate_block(C, &dR[9 * C]);
}

void StoredCells::rotate_block(std::size_t e, const double* R) {
  assert(slot_.empty());
  double A[576];
  unpack_symmetric(doubles() + kPackedSize * e, A);
  element::rotate_element_matrix(R, A, A);
  pack_symmetric(A, doubles() + kPackedSize * e);
}

void StoredCells::set_block(std::size_t e, const double* packed) {
  assert(slot_.empty());
  std::copy_n(packed, kPackedSize, doubles() + kPackedSize * e);
}

template <class V>
void StoredCells::apply_add_on(const V* x, V* y) const {
  assert(blocks_ && "a single-precision level is used before its first galerkin()");
  const auto n = std::int64_t(num_cells());
  if (!unpacked_.empty()) {
    // Cells of the unpacked blocks, then the others: each loop runs one kernel body.
    if (const double* d = packed_double()) {
      backend::for_each_in(
          unpacked_cells_,
          backend::CellApplyAdd<UnpackedBlockOpsOf<double>, V>{
              {full_double_.data(), block_of(), unpacked_.data()}, corners(), x, y});
      backend::for_each_in(
          packed_cells_, backend::CellApplyAdd<StoredCellOps, V>{{d, block_of()}, corners(), x, y});
    } else {
      backend::for_each_in(
          unpacked_cells_,
          backend::CellApplyAdd<UnpackedBlockOpsOf<float>, V>{
              {full_single_.data(), block_of(), unpacked_.data()}, corners(), x, y});
      backend::for_each_in(packed_cells_, backend::CellApplyAdd<StoredCellOpsSingle, V>{
                                              {packed_single(), block_of()}, corners(), x, y});
    }
    return;
  }
  if (const double* d = packed_double())
    backend::for_each(n, backend::CellApplyAdd<StoredCellOps, V>{{d, block_of()}, corners(), x, y});
  else
    backend::for_each(n, backend::CellApplyAdd<StoredCellOpsSingle, V>{
                             {packed_single(), block_of()}, corners(), x, y});
}

void StoredCells::apply_add(const double* x, double* y) const {
  apply_add_on(x, y);
}

void StoredCells::apply_add(const float* x, float* y) const {
  apply_add_on(x, y);
}

template <class V>
void StoredCells::apply_add_colour_on(const assembly::CellPositions& position, int k, const V* x,
                                      V* y) const {
  assert(blocks_ && "a single-precision level is used before its first galerkin()");
  const int* p = position.empty() ? nullptr : position[0].data();
  const auto n = std::int64_t(num_cells());
  if (const double* d = packed_double())
    backend::for_each(
        n, backend::CellColourRows<StoredCellOps, V>{{d, block_of()}, corners(), p, k, x, y});
  else
    backend::for_each(n, backend::CellColourRows<StoredCellOpsSingle, V>{
                             {packed_single(), block_of()}, corners(), p, k, x, y});
}

void StoredCells::apply_add_colour(const assembly::CellPositions& position, int k, const double* x,
                                   double* y) const {
  apply_add_colour_on(position, k, x, y);
}

void StoredCells::apply_add_colour(const assembly::CellPositions& position, int k, const float* x,
                                   float* y) const {
  apply_add_colour_on(position, k, x, y);
}

void StoredCells::add_diagonal_blocks(double* diag) const {
  assert(blocks_ && "a single-precision level is used before its first galerkin()");
  const auto n = std::int64_t(num_cells());
  if (const double* d = packed_double())
    backend::for_each(n, backend::CellDiagonal<StoredCellOps>{{d, block_of()}, corners(), diag});
  else
    backend::for_each(n, backend::CellDiagonal<StoredCellOpsSingle>{
                             {packed_single(), block_of()}, corners(), diag});
}

void StoredCells::cell_matrix(std::size_t e, double* A) const {
  assert(blocks_ && "a single-precision level is used before its first galerkin()");
  if (const double* d = packed_double())
    unpack_symmetric(d + kPackedSize * slot(e), A);
  else
    unpack_symmetric(packed_single() + kPackedSize * slot(e), A);
}

}  // namespace hexcut::multigrid
