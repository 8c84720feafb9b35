// The ghost exchange of one level of the loop-layer cycle (multigrid/loop_cycle.hpp; doc/theory.md,
// "The CUDA backend: the cycle on the loop layer") in the form both executors use: the owned
// copies that other ranks hold as ghosts (`send`), which the executor packs into a contiguous
// buffer with its own loop (PackCopies; on the device, a kernel), and a star forest between those
// packed buffers and the level vector's contiguous ghost region (3 values per copy). So the host
// runs the same plan the device does, and the device moves only the packed values and the ghost
// region across PCIe, not whole vectors.
#pragma once

#include <petscsf.h>

#include <cstdint>
#include <memory>
#include <vector>

#include "multigrid/loop_cycle.hpp"

namespace hexcut::multigrid {

class LevelHalo {
 public:
  /// The halo of `level` (its ghost_rank / ghost_index, from Multigrid::loop_levels), on
  /// `comm` (collective). Errors: PETSc's.
  static PetscErrorCode create(MPI_Comm comm, const LoopLevelArrays& level,
                               std::unique_ptr<LevelHalo>* out);
  ~LevelHalo();
  LevelHalo(const LevelHalo&) = delete;
  LevelHalo& operator=(const LevelHalo&) = delete;

  /// No rank has ghosts on this level: nothing to exchange (the same answer on every rank).
  bool empty() const { return sf_ == nullptr; }
  /// The owned copies (local indices) other ranks hold as ghosts, in the packed buffer's order.
  const std::vector<std::int32_t>& send() const { return send_; }
  std::int64_t num_ghosts() const { return num_ghosts_; }

  /// ghosts (3 values per ghost copy, the level vector's ghost region) = their owners' values
  /// from the owners' packed buffers (3 per send copy). S: double or float. Collective.
  template <class S>
  PetscErrorCode broadcast(const S* packed, S* ghosts) const;
  /// packed (3 per send copy) = the sum of the ghosts' values over the ranks holding them
  /// (zeroed first). Collective.
  template <class S>
  PetscErrorCode reduce(const S* ghosts, S* packed) const;

 private:
  LevelHalo() = default;
  PetscSF sf_ = nullptr;  // roots: packed values, leaves: ghost values
  std::vector<std::int32_t> send_;
  std::int64_t num_ghosts_ = 0;
};

}  // namespace hexcut::multigrid
