// The CUDA backend's operators on plain arrays (issue 13): what device_backend.cu compiles
// with nvcc, kept free of the host classes (and of Eigen, which nvcc warns about). Callers
// use device_backend.hpp.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "assembly/fine_cell_kernels.hpp"
#include "multigrid/loop_cycle.hpp"

namespace hexcut::cuda {

/// CUDA devices this process can use; 0 when there is none or no driver, with the
/// runtime's reason in *why (may be null).
int device_count(std::string* why);

/// Makes device (node_rank mod device_count) this process's device: one GPU per MPI rank on a
/// node with as many GPUs as ranks, ranks sharing them round-robin otherwise. Returns the device
/// number; throws std::runtime_error with the CUDA runtime's message when that fails.
int select_device(int node_rank);

/// The cells and colours of one level, as plain arrays (host memory).
struct CellArrays {
  std::int64_t num_cells = 0;
  const std::int32_t* corners = nullptr;  // 8 local copies per cell
  int num_colours = 0;
  const std::int32_t* colour_offset = nullptr;  // num_colours + 1
  const std::int32_t* colour_cell = nullptr;    // the cells, colour by colour
  std::int64_t num_copies = 0;                  // local copies: x, y hold 3 each
  std::int64_t num_blocks = 0;                  // stored blocks (num_cells unless shared)
  const std::int32_t* block_of = nullptr;       // per cell: its block; null: block e
};

/// y += A x on device 0 for packed symmetric 24x24 blocks (multigrid::kPackedSize per
/// block, double or float; cell e's is block_of[e], or e), one colour at a time; x, y host arrays,
/// copied in and out. Throws std::runtime_error with the CUDA runtime's message when a call fails.
void packed_apply_add(const double* packed, const CellArrays& cells, const double* x, double* y);
void packed_apply_add(const float* packed, const CellArrays& cells, const double* x, double* y);

/// Lengths of the shared tables of an assembly::FineCellData (the per-cell arrays have
/// CellArrays::num_cells entries, the mask 3 per copy).
struct FineTables {
  std::int64_t num_kinds = 0;  // kind_stiffness: 576 numbers each
  std::int64_t num_own = 0;    // own_stiffness: 576 numbers each
};

/// y += A x on device 0 for the fine cells `d` (host pointers; assembly::FineCellOps, the
/// host backend's body), one colour of `cells` at a time; cells.num_blocks and block_of
/// unused. x, y: host arrays, copied in and out. Throws std::runtime_error on a CUDA error.
void fine_apply_add(const assembly::FineCellData& d, const FineTables& tables,
                    const CellArrays& cells, const double* x, double* y);

/// The corotational rotation update on device 0 (assembly::CellRotation, the host's body):
/// R (9 per cell) from u (3 per local copy, `num_copies`) for `num_cells` cells of size h
/// with 8 corners each; host arrays, copied in and out. Throws std::runtime_error on a CUDA
/// error.
void cell_rotations(const std::int32_t* corners, std::int64_t num_cells, std::int64_t num_copies,
                    const double* u, double h, double* R);

/// One level of the device cycle, host memory: the loop-layer arrays (mask, diagonal blocks,
/// transfer from the next level; multigrid::Multigrid::loop_levels) and the level's cells:
/// the fine cells on level 0 (`fine`, `tables`), packed Galerkin blocks below (double or
/// float, with cells.num_blocks and cells.block_of); the coarsest level needs neither.
struct DeviceCycleLevel {
  multigrid::LoopLevel loop;
  CellArrays cells;
  const assembly::FineCellData* fine = nullptr;
  FineTables tables;
  const double* packed_double = nullptr;
  const float* packed_single = nullptr;
  const int* position = nullptr;  // 3 per cell: lattice or level position (Gauss-Seidel)
  // On more ranks, the level's halo (multigrid::LevelHalo): whether any rank has ghosts here
  // (then every rank takes part in each exchange), its send copies (host memory) and its ghost
  // copies (loop.num_local - loop.num_copies of them, the vectors' contiguous tail).
  bool halo = false;
  const std::int32_t* halo_send = nullptr;
  std::int64_t halo_num_send = 0;
};

/// The MPI side of the device cycle's ghost exchange, on host buffers (multigrid::LevelHalo):
/// broadcast(l, packed, ghosts) sets the ghosts' values (3 per ghost copy) to their owners'
/// packed ones (3 per send copy); reduce(l, ghosts, packed) sets packed to the sum of the
/// ghosts' values over the ranks that hold them. The values are the cycle's type (double, or
/// float with `single`). Collective over the ranks; unused (may be empty) on one rank.
struct DeviceHaloExchange {
  std::function<void(int l, const void* packed, void* ghosts)> broadcast;
  std::function<void(int l, const void* ghosts, void* packed)> reduce;
};

/// The multigrid cycle (multigrid::loop::cycle_level, the host's algorithm and bodies) with
/// every level resident on this process's device (device 0 unless select_device chose
/// another): smoothing, residuals and transfers on the device, the coarsest level solved by
/// `solve_coarsest` on the host (b copied down, x copied up: the
/// coarsest level is small, and the host's sparse factorization is what the host cycle uses
/// too). Built once per set-up (uploads everything); each apply copies b in and x out.
/// `single`: every level's work vectors in float (the single-precision V-cycle of mixed
/// precision, as multigrid::HostLoopCycleSingle on the host: float level data, the fine cells'
/// products in float, the vector operations in double from float loads with one rounding per
/// store; b rounded once on entry, the coarsest solve through double arrays).
/// Throws std::runtime_error with the CUDA runtime's message when a call fails.
class DeviceCycle {
 public:
  DeviceCycle(const std::vector<DeviceCycleLevel>& levels, int gamma, bool single,
              std::function<void(const double* b, double* x)> solve_coarsest,
              DeviceHaloExchange halo = {});
  ~DeviceCycle();
  DeviceCycle(const DeviceCycle&) = delete;
  DeviceCycle& operator=(const DeviceCycle&) = delete;
  /// x = M^-1 b (one cycle from zero); b, x: host arrays of level 0's owned DOFs.
  void apply(const double* b, double* x);
  /// The median time of `repeat` cycles with b already on the device [s] (benchmarks).
  double time_cycle(int repeat);

 private:
  struct Executor;
  std::unique_ptr<Executor> ex_;
};

/// Device timings for the benchmarks (scripts/bench/operator_throughput.cpp), everything
/// resident on device 0: the median of `repeat` fine applications y += A x (all colours, after
/// one warm-up) [s], with double and with float vectors (the single-precision V-cycle's), and
/// the bandwidth of a copy kernel y = x over `copy_bytes` per array [bytes/s: bytes read +
/// written over the median time], the STREAM-like reference.
struct DeviceTiming {
  double fine_apply_seconds = 0;
  double fine_apply_single_seconds = 0;
  double copy_bandwidth = 0;
  std::string device;  // the device's name
};
DeviceTiming time_fine_apply(const assembly::FineCellData& d, const FineTables& tables,
                             const CellArrays& cells, int repeat, std::size_t copy_bytes);

}  // namespace hexcut::cuda
