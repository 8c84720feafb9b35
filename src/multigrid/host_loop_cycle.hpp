// The loop-layer cycle (multigrid/loop_cycle.hpp) on the host backend (issue 13): the
// executor whose for_each is backend::for_each and whose cells are the Multigrid's own
// (assembly::FineCells on level 0, StoredCells below), with the coarsest level solved by the
// Multigrid's factorization. It is the reference the CUDA backend is tested against
// (tests/cuda/device_test.cpp), and it is itself tested against Multigrid::cycle
// (tests/multigrid/multigrid_test.cpp, "LoopCycle"): the same cycle to round-off.
//
// HostLoopCycleOf<float> (HostLoopCycleSingle) is the single-precision V-cycle of mixed
// precision (-gmg_backend host_loop -gmg_precision single; doc/theory.md, "Mixed precision"):
// every level's work vectors in float, the outer CG in double.
//
// On more ranks each level's vectors hold the rank's owned copies and its ghosts
// (LoopLevel::num_local), and exchange()/accumulate() are each level's LevelHalo
// (multigrid/halo.hpp: the owners' send copies packed, a star forest between the packed
// buffers and the ghost region), the plan the device executor runs too, so the cycle is
// Multigrid::cycle's on any number of ranks.
#pragma once

#include <petscsys.h>

#include <array>
#include <memory>
#include <vector>

#include "backend/loop.hpp"
#include "multigrid/gmg.hpp"
#include "multigrid/halo.hpp"
#include "multigrid/loop_cycle.hpp"

namespace hexcut::multigrid {

template <class S>
class HostLoopCycleOf : public CycleBackend {
 public:
  using Scalar = S;  // the work vectors' type: double or float

  /// The cycle of `mg` (after its update(); it must outlive this). Errors: those of
  /// Multigrid::loop_levels (PETSC_ERR_SUP where the loop-layer cycle does not apply).
  static PetscErrorCode create(Multigrid& mg, std::unique_ptr<HostLoopCycleOf>* out);
  HostLoopCycleOf(const HostLoopCycleOf&) = delete;
  HostLoopCycleOf& operator=(const HostLoopCycleOf&) = delete;

  /// x = M^-1 b, one cycle from zero; b, x: 3 values per owned copy of level 0 (in double:
  /// a float cycle rounds b once on entry).
  PetscErrorCode apply(const double* b, double* x) override;

  // The executor of loop::cycle_level.
  int num_levels() const { return int(levels_.size()); }
  int gamma() const { return mg_.cycle_gamma(); }
  const LoopLevel& level(int l) const { return levels_[l].view; }
  S* b(int l) { return work_[l][0].data(); }
  S* x(int l) { return work_[l][1].data(); }
  S* r(int l) { return work_[l][2].data(); }
  S* dir(int l) { return work_[l][3].data(); }
  template <class Kernel>
  void for_each(std::int64_t n, const Kernel& k) {
    backend::for_each(n, k);
  }
  void apply_add(int l, const S* x, S* y) { mg_.cell_operator(l)->apply_add(x, y); }
  void apply_add_colour(int l, int k, const S* x, S* y) {
    mg_.cell_operator(l)->apply_add_colour(mg_.cell_positions(l), k, x, y);
  }
  void solve_coarsest(const S* b, S* x);
  void exchange(int l, S* x);
  void accumulate(int l, S* y);

 private:
  explicit HostLoopCycleOf(Multigrid& mg) : mg_(mg) {}
  Multigrid& mg_;
  std::vector<LoopLevelArrays> levels_;
  std::vector<std::array<std::vector<S>, 4>> work_;  // b, x, r, dir per level
  std::vector<double> coarse_b_, coarse_x_;          // float: the coarsest solve's, in double
  // float: each level's data in float (LoopLevel's twins: diagonal blocks, mask, prolongation
  // and restriction weights); the double copies are released.
  std::vector<std::array<std::vector<float>, 4>> single_;
  std::vector<std::unique_ptr<LevelHalo>> halos_;          // per level
  std::vector<std::vector<S>> packed_;                     // per level: 3 per send copy
  // The first PETSc error of solve_coarsest, exchange or accumulate (the executor interface
  // has no error channel), returned by apply().
  PetscErrorCode error_ = 0;
  void keep(PetscErrorCode e) {
    if (!error_) error_ = e;
  }
};

using HostLoopCycle = HostLoopCycleOf<double>;
using HostLoopCycleSingle = HostLoopCycleOf<float>;

/// The host backend's cycle for `mg` in its precision (Precision::single: HostLoopCycleSingle),
/// what Multigrid::update makes for -gmg_backend host_loop. Errors: those of create().
PetscErrorCode host_loop_cycle(Multigrid& mg, Precision precision,
                               std::unique_ptr<CycleBackend>* out);

}  // namespace hexcut::multigrid
