// The CUDA backend's operators (issue 13; doc/theory.md, "Kernel bodies for a CUDA
// backend"): the stored cells' and the fine cells' y += A x on the device, with the same
// functor bodies the host runs (backend::CellApplyAdd over multigrid::StoredCellOpsOf<T>
// and assembly::FineCellOps), launched one colour of backend::colour_cells at a time so
// that no two threads of a launch scatter into the same vertex copy.
#pragma once

#include <algorithm>
#include <memory>
#include <stdexcept>
#include <vector>

#include "assembly/fine_cells.hpp"
#include "backend/loop.hpp"
#include "device_kernels.hpp"
#include "multigrid/gmg.hpp"
#include "multigrid/halo.hpp"
#include "multigrid/stored_cells.hpp"

namespace hexcut::cuda {

/// y += A x for the stored cells A (in the precision they are held in now) on device 0; x, y:
/// 3 values per local copy of A's layout (host arrays, copied in and out once per call).
/// `colours`: backend::colour_cells of A's cells' level positions. Throws
/// std::runtime_error with the CUDA runtime's message when a call fails.
/// The stored cells `A` as the device functions take them, with `colours` (colour_cells of
/// their level positions; both must outlive the result).
inline CellArrays stored_cell_arrays(const multigrid::StoredCells& A,
                                     const backend::CellColours& colours) {
  return CellArrays{std::int64_t(A.num_cells()),  A.corners(),         colours.num_colours(),
                    colours.offset.data(),        colours.cell.data(), A.layout().num_local(),
                    std::int64_t(A.num_blocks()), A.block_of()};
}

inline void stored_apply_add(const multigrid::StoredCells& A, const backend::CellColours& colours,
                             const double* x, double* y) {
  const CellArrays cells = stored_cell_arrays(A, colours);
  if (A.packed_double())
    packed_apply_add(A.packed_double(), cells, x, y);
  else
    packed_apply_add(A.packed_single(), cells, x, y);
}

/// The fine cells `A` as the device functions take them: their cells and colours, and the
/// lengths of their shared tables (the largest kind and own-stiffness index + 1).
inline CellArrays fine_cell_arrays(const assembly::FineCells& A,
                                   const backend::CellColours& colours, FineTables* tables) {
  const auto d = A.data();
  const auto n = std::ptrdiff_t(A.num_cells());
  tables->num_kinds = n ? 1 + *std::max_element(d.kind, d.kind + n) : 0;
  tables->num_own = d.own && n ? 1 + *std::max_element(d.own, d.own + n) : 0;
  return CellArrays{std::int64_t(n),
                    A.corners(),
                    colours.num_colours(),
                    colours.offset.data(),
                    colours.cell.data(),
                    A.layout().num_local(),
                    0,
                    nullptr};
}

/// y += A x for the fine cells A (their current weights, rotations and mask) on device 0;
/// x, y: 3 values per local copy of A's layout (host arrays, copied in and out once per
/// call). `colours`: backend::colour_cells of the cells' lattice positions. Throws
/// std::runtime_error with the CUDA runtime's message when a call fails.
inline void fine_apply_add(const assembly::FineCells& A, const backend::CellColours& colours,
                           const double* x, double* y) {
  FineTables tables;
  const auto cells = fine_cell_arrays(A, colours, &tables);
  fine_apply_add(A.data(), tables, cells, x, y);
}

/// -gmg_backend cuda (multigrid::Backend::cuda): the cycle of a Multigrid on this rank's device
/// (select_device: node rank mod the node's devices; DeviceCycle over Multigrid::loop_levels),
/// made after each of its update()s; with -gmg_precision single its vectors are float (the
/// single-precision V-cycle). On more ranks each level's ghosts go through its LevelHalo: the
/// packed send copies and the ghost region are copied to the host and exchanged there.
class MultigridDeviceCycle : public multigrid::CycleBackend {
 public:
  /// Errors: those of Multigrid::loop_levels (PETSC_ERR_SUP with the reason where the loop-
  /// layer cycle does not apply), PETSC_ERR_LIB with the CUDA runtime's message (also when no
  /// device is visible: Multigrid::update checks multigrid::device_count first).
  static PetscErrorCode create(multigrid::Multigrid& mg,
                               std::unique_ptr<multigrid::CycleBackend>* out) {
    PetscFunctionBeginUser;
    std::unique_ptr<MultigridDeviceCycle> c(new MultigridDeviceCycle(mg));
    PetscCall(mg.loop_levels(&c->arrays_));
    const int L = mg.num_levels();
    c->halos_.resize(L);
    for (int l = 0; l < L; ++l)
      PetscCall(multigrid::LevelHalo::create(mg.comm(), c->arrays_[l], &c->halos_[l]));
    MPI_Comm node;
    PetscCallMPI(MPI_Comm_split_type(mg.comm(), MPI_COMM_TYPE_SHARED, 0, MPI_INFO_NULL, &node));
    PetscMPIInt node_rank;
    PetscCallMPI(MPI_Comm_rank(node, &node_rank));
    PetscCallMPI(MPI_Comm_free(&node));
    try {  // the uploads and host containers below throw; PETSc errors stay codes
      select_device(node_rank);
      std::vector<DeviceCycleLevel> levels(L);
      c->colours_.resize(L);
      for (int l = 0; l < L; ++l) {
        auto& d = levels[l];
        d.loop = c->arrays_[l].view;
        const auto& h = *c->halos_[l];
        d.halo = !h.empty();
        d.halo_send = h.send().data();
        d.halo_num_send = std::int64_t(h.send().size());
        if (l + 1 == L) continue;  // the coarsest level is solved on the host
        c->colours_[l] = backend::colour_cells(mg.cell_positions(l));
        d.position = mg.cell_positions(l).empty() ? nullptr : mg.cell_positions(l)[0].data();
        if (l == 0) {
          const auto* fine = dynamic_cast<const assembly::FineCells*>(mg.cell_operator(0));
          PetscCheck(fine, PETSC_COMM_SELF, PETSC_ERR_PLIB, "gmg: level 0 has no fine cells");
          c->fine_data_ = fine->data();
          d.cells = fine_cell_arrays(*fine, c->colours_[0], &d.tables);
          d.fine = &c->fine_data_;
        } else {
          const auto& A = mg.stored_cells(l);
          d.cells = stored_cell_arrays(A, c->colours_[l]);
          d.packed_double = A.packed_double();
          d.packed_single = A.packed_single();
        }
      }
      auto* self = c.get();
      const bool single = mg.precision() == multigrid::Precision::single;
      // The halo's MPI part. Collective: after an error every rank still takes part (the first
      // error is kept for apply()), so that no rank waits on one that stopped.
      DeviceHaloExchange halo;
      halo.broadcast = [self, single](int l, const void* packed, void* ghosts) {
        const auto& h = *self->halos_[std::size_t(l)];
        self->keep(
            single ? h.broadcast(static_cast<const float*>(packed), static_cast<float*>(ghosts))
                   : h.broadcast(static_cast<const double*>(packed), static_cast<double*>(ghosts)));
      };
      halo.reduce = [self, single](int l, const void* ghosts, void* packed) {
        const auto& h = *self->halos_[std::size_t(l)];
        self->keep(
            single ? h.reduce(static_cast<const float*>(ghosts), static_cast<float*>(packed))
                   : h.reduce(static_cast<const double*>(ghosts), static_cast<double*>(packed)));
      };
      c->cycle_ = std::make_unique<DeviceCycle>(
          levels, mg.cycle_gamma(), single,
          [self](const double* b, double* x) { self->keep(self->mg_.solve_coarsest(b, x)); },
          std::move(halo));
    } catch (const std::exception& e) {
      SETERRQ(PETSC_COMM_SELF, PETSC_ERR_LIB, "-gmg_backend cuda: %s", e.what());
    }
    *out = std::move(c);
    PetscFunctionReturn(0);
  }
  PetscErrorCode apply(const double* b, double* x) override {
    PetscFunctionBeginUser;
    error_ = 0;
    try {
      cycle_->apply(b, x);
    } catch (const std::exception& e) {
      SETERRQ(PETSC_COMM_SELF, PETSC_ERR_LIB, "-gmg_backend cuda: %s", e.what());
    }
    PetscCall(error_);
    PetscFunctionReturn(0);
  }
  /// Median seconds of `repeat` device cycles (DeviceCycle::time_cycle).
  double time_cycle(int repeat) { return cycle_->time_cycle(repeat); }

 private:
  explicit MultigridDeviceCycle(multigrid::Multigrid& mg) : mg_(mg) {}
  multigrid::Multigrid& mg_;
  std::vector<multigrid::LoopLevelArrays> arrays_;
  std::vector<backend::CellColours> colours_;
  assembly::FineCellData fine_data_;
  std::vector<std::unique_ptr<multigrid::LevelHalo>> halos_;
  std::unique_ptr<DeviceCycle> cycle_;
  // The first PETSc error of the coarsest solve or a halo exchange during apply().
  PetscErrorCode error_ = 0;
  void keep(PetscErrorCode e) {
    if (!error_) error_ = e;
  }
};

/// The factory hexcut installs with multigrid::set_device_cycle_factory (with device_count).
inline PetscErrorCode device_cycle(multigrid::Multigrid& mg,
                                   std::unique_ptr<multigrid::CycleBackend>* out) {
  return MultigridDeviceCycle::create(mg, out);
}

}  // namespace hexcut::cuda
