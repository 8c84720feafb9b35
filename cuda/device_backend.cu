#include <cuda_runtime.h>

#include <algorithm>
#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <stdexcept>
#include <type_traits>
#include <vector>

// The device side of device_kernels.hpp: launch wrappers around the host's functor bodies.
#include "backend/restriction.hpp"
#include "device_kernels.hpp"
#include "multigrid/stored_cell_kernels.hpp"

namespace hexcut::cuda {
namespace {

void check(cudaError_t e, const char* what) {
  if (e != cudaSuccess) throw std::runtime_error(std::string(what) + ": " + cudaGetErrorString(e));
}

/// A device array of n values of T, freed with it.
template <class T>
class DeviceArray {
 public:
  explicit DeviceArray(std::size_t n) : n_(n) {
    check(cudaMalloc(reinterpret_cast<void**>(&p_), n * sizeof(T) + 1), "cudaMalloc");
  }
  DeviceArray(const T* host, std::size_t n) : DeviceArray(n) {
    check(cudaMemcpy(p_, host, n * sizeof(T), cudaMemcpyHostToDevice), "cudaMemcpy to device");
  }
  ~DeviceArray() { cudaFree(p_); }
  DeviceArray(const DeviceArray&) = delete;
  DeviceArray& operator=(const DeviceArray&) = delete;
  void copy_to_host(T* host) const {
    check(cudaMemcpy(host, p_, n_ * sizeof(T), cudaMemcpyDeviceToHost), "cudaMemcpy to host");
  }
  T* get() const { return p_; }

 private:
  T* p_ = nullptr;
  std::size_t n_;
};

/// k(cell[i]) for i < n, one thread each: the cells of one colour.
template <class Kernel>
__global__ void for_each_of_colour(Kernel k, const std::int32_t* cell, std::int32_t n) {
  const std::int32_t i =
      std::int32_t(blockIdx.x) * std::int32_t(blockDim.x) + std::int32_t(threadIdx.x);
  if (i < n) k(cell[i]);
}

/// k over the cells of every colour of `cells`, one launch per colour (`order`: the device
/// copy of cells.colour_cell); no synchronization.
template <class Kernel>
void launch_colours(const Kernel& k, const std::int32_t* order, const CellArrays& cells) {
  constexpr int kThreads = 128;
  for (int c = 0; c < cells.num_colours; ++c) {
    const std::int32_t n = cells.colour_offset[c + 1] - cells.colour_offset[c];
    if (n == 0) continue;
    for_each_of_colour<<<(n + kThreads - 1) / kThreads, kThreads>>>(
        k, order + cells.colour_offset[c], n);
    check(cudaGetLastError(), "kernel launch");
  }
}

template <class T>
void apply(const T* packed, const CellArrays& cells, const double* x, double* y) {
  if (cells.num_cells == 0) return;
  const auto n_cells = std::size_t(cells.num_cells), values = 3 * std::size_t(cells.num_copies);
  const DeviceArray<T> P(packed, multigrid::kPackedSize * std::size_t(cells.num_blocks));
  const DeviceArray<std::int32_t> corners(cells.corners, 8 * n_cells);
  const DeviceArray<std::int32_t> block_of(cells.block_of, cells.block_of ? n_cells : 0);
  const DeviceArray<std::int32_t> order(cells.colour_cell,
                                        std::size_t(cells.colour_offset[cells.num_colours]));
  const DeviceArray<double> X(x, values);
  DeviceArray<double> Y(y, values);
  const backend::CellApplyAdd<multigrid::StoredCellOpsOf<T>> k{
      {P.get(), cells.block_of ? block_of.get() : nullptr}, corners.get(), X.get(), Y.get()};
  launch_colours(k, order.get(), cells);
  check(cudaDeviceSynchronize(), "kernel");
  Y.copy_to_host(y);
}

/// `host` (n values) uploaded into `slot`; the device pointer, or null for a null `host`.
template <class T>
T* upload(std::unique_ptr<DeviceArray<T>>* slot, const T* host, std::size_t n) {
  *slot = host ? std::make_unique<DeviceArray<T>>(host, n) : nullptr;
  return *slot ? (*slot)->get() : nullptr;
}

/// The fine cells' data on the device: FineCellData with device pointers, its arrays owned.
class DeviceFineCells {
 public:
  DeviceFineCells(const assembly::FineCellData& h, const FineTables& t, const CellArrays& cells)
      : d_(h) {
    const auto n = std::size_t(cells.num_cells);
    d_.corners = upload(&corners_, h.corners, 8 * n);
    d_.kind = upload(&kind_, h.kind, n);
    d_.kind_stiffness = upload(&kind_stiffness_, h.kind_stiffness, 576 * std::size_t(t.num_kinds));
    d_.own = upload(&own_, h.own, n);
    d_.own_stiffness =
        upload(&own_stiffness_, h.own ? h.own_stiffness : nullptr, 576 * std::size_t(t.num_own));
    d_.lambda = upload(&lambda_, h.lambda, n);
    d_.mu = upload(&mu_, h.mu, n);
    d_.rho = upload(&rho_, h.rho, n);
    d_.rotation = upload(&rotation_, h.rotation, 9 * n);
    d_.reference = upload(&reference_, h.reference, 1);
    d_.mask = upload(&mask_, h.mask, 3 * std::size_t(cells.num_copies));
    d_.cell_masked = upload(&cell_masked_, h.mask ? h.cell_masked : nullptr, n);
    d_.kind_stiffness_single =
        upload(&kind_single_, h.kind_stiffness_single, 576 * std::size_t(t.num_kinds));
    d_.reference_single = upload(&reference_single_, h.reference_single, 3 * 576);
    upload(&order_, cells.colour_cell, std::size_t(cells.colour_offset[cells.num_colours]));
  }
  /// y += A x, x and y device arrays of V (double or float), launched colour by colour (no
  /// synchronization).
  template <class V>
  void apply_add(const CellArrays& cells, const V* x, V* y) const {
    if (cells.num_cells == 0) return;
    if constexpr (std::is_same_v<V, float>) {
      if (d_.reference_single) {  // float arithmetic, as the host's FineCells on float vectors
        const backend::CellApplyAdd<assembly::FineCellOpsSingle, float> k{{d_}, d_.corners, x, y};
        launch_colours(k, order_->get(), cells);
        return;
      }
    }
    const backend::CellApplyAdd<assembly::FineCellOps, V> k{{d_}, d_.corners, x, y};
    launch_colours(k, order_->get(), cells);
  }
  /// The rows of the copies of parity colour k only (`position`: the cells' lattice positions
  /// on the device), launched cell colour by cell colour (no synchronization).
  template <class V>
  void apply_add_colour(const CellArrays& cells, const int* position, int k, const V* x,
                        V* y) const {
    if (cells.num_cells == 0) return;
    using Rows = backend::CellColourRows<assembly::FineCellOps, V>;
    launch_colours(Rows{{d_}, d_.corners, position, k, x, y}, order_->get(), cells);
  }

 private:
  assembly::FineCellData d_;
  std::unique_ptr<DeviceArray<std::int32_t>> corners_, kind_, own_, order_;
  std::unique_ptr<DeviceArray<double>> kind_stiffness_, own_stiffness_, lambda_, mu_, rho_,
      rotation_, mask_;
  std::unique_ptr<DeviceArray<element::ReferenceMatrices>> reference_;
  std::unique_ptr<DeviceArray<char>> cell_masked_;
  std::unique_ptr<DeviceArray<float>> kind_single_, reference_single_;
};

/// A level's packed Galerkin blocks on the device (double or float), its cells and colours.
class DeviceStoredCells {
 public:
  DeviceStoredCells(const double* pd, const float* ps, const CellArrays& cells)
      : cells_(cells), offsets_(cells.colour_offset, cells.colour_offset + cells.num_colours + 1) {
    cells_.colour_offset = offsets_.data();  // read at every launch: held here, not borrowed
    const auto n = std::size_t(cells.num_cells);
    const auto values = multigrid::kPackedSize * std::size_t(cells.num_blocks);
    packed_double_ = upload(&pd_, pd, values);
    packed_single_ = upload(&ps_, pd ? nullptr : ps, values);
    corners_ = upload(&c_, cells.corners, 8 * n);
    block_of_ = upload(&b_, cells.block_of, n);
    order_ = upload(&o_, cells.colour_cell, std::size_t(cells.colour_offset[cells.num_colours]));
  }
  /// y += A x, x and y device arrays of V (double or float; no synchronization).
  template <class V>
  void apply_add(const V* x, V* y) const {
    if (cells_.num_cells == 0) return;
    if (packed_double_)
      launch_colours(
          backend::CellApplyAdd<multigrid::StoredCellOps, V>{
              {packed_double_, block_of_}, corners_, x, y},
          order_, cells_);
    else  // float blocks, double products (as the host's StoredCells, on any vectors)
      launch_colours(
          backend::CellApplyAdd<multigrid::StoredCellOpsSingle, V>{
              {packed_single_, block_of_}, corners_, x, y},
          order_, cells_);
  }
  /// The rows of the copies of parity colour k only (`position`: the cells' level positions on
  /// the device; no synchronization).
  template <class V>
  void apply_add_colour(const int* position, int k, const V* x, V* y) const {
    if (cells_.num_cells == 0) return;
    if (packed_double_)
      launch_colours(
          backend::CellColourRows<multigrid::StoredCellOps, V>{
              {packed_double_, block_of_}, corners_, position, k, x, y},
          order_, cells_);
    else
      launch_colours(
          backend::CellColourRows<multigrid::StoredCellOpsSingle, V>{
              {packed_single_, block_of_}, corners_, position, k, x, y},
          order_, cells_);
  }

 private:
  CellArrays cells_;  // its colour_offset points into offsets_ (the others are not read again)
  std::vector<std::int32_t> offsets_;
  std::unique_ptr<DeviceArray<double>> pd_;
  std::unique_ptr<DeviceArray<float>> ps_;
  std::unique_ptr<DeviceArray<std::int32_t>> c_, b_, o_;
  const double* packed_double_ = nullptr;
  const float* packed_single_ = nullptr;
  const std::int32_t *corners_ = nullptr, *block_of_ = nullptr, *order_ = nullptr;
};

/// k(i) for i < n, one thread each.
template <class Kernel>
__global__ void for_each_index(Kernel k, std::int64_t n) {
  const std::int64_t i = std::int64_t(blockIdx.x) * blockDim.x + threadIdx.x;
  if (i < n) k(std::int32_t(i));
}

/// for_each_index over 0..n-1 (nothing for n = 0); no synchronization.
template <class Kernel>
void launch_index(std::int64_t n, const Kernel& k) {
  if (n == 0) return;
  constexpr int kThreads = 256;
  for_each_index<<<unsigned((n + kThreads - 1) / kThreads), kThreads>>>(k, n);
  check(cudaGetLastError(), "kernel launch");
}

__global__ void copy_kernel(const double* x, double* y, std::size_t n) {
  const std::size_t i = std::size_t(blockIdx.x) * blockDim.x + threadIdx.x;
  if (i < n) y[i] = x[i];
}

/// The median of `repeat` timings of f() (after one warm-up) [s], with CUDA events.
template <class F>
double median_seconds(int repeat, const F& f) {
  cudaEvent_t a, b;
  check(cudaEventCreate(&a), "cudaEventCreate");
  check(cudaEventCreate(&b), "cudaEventCreate");
  f();
  std::vector<double> t;
  for (int i = 0; i < std::max(repeat, 1); ++i) {
    check(cudaEventRecord(a), "cudaEventRecord");
    f();
    check(cudaEventRecord(b), "cudaEventRecord");
    check(cudaEventSynchronize(b), "cudaEventSynchronize");
    float ms = 0;
    check(cudaEventElapsedTime(&ms, a, b), "cudaEventElapsedTime");
    t.push_back(1e-3 * double(ms));
  }
  cudaEventDestroy(a);
  cudaEventDestroy(b);
  std::sort(t.begin(), t.end());
  return t[t.size() / 2];
}

}  // namespace

/// The device cycle behind DeviceCycle, whatever the work vectors' type.
struct DeviceCycle::Executor {
  virtual ~Executor() = default;
  virtual void apply(const double* b, double* x) = 0;
  virtual double time_cycle(int repeat) = 0;
  template <class S>
  struct Of;
};

/// The executor of multigrid::loop::cycle_level on the device (multigrid/loop_cycle.hpp), with
/// work vectors of type S: double, or float for the single-precision V-cycle (then its level
/// data, diagonal blocks, masks and weights, are rounded to float on upload, as on the host).
template <class S>
struct DeviceCycle::Executor::Of final : DeviceCycle::Executor {
  std::vector<multigrid::LoopLevel> levels;  // device pointers
  std::vector<CellArrays> cells;             // level 0: colour_offset points into offsets0
  std::vector<std::int32_t> offsets0;
  std::vector<std::unique_ptr<DeviceArray<double>>> doubles;
  std::vector<std::unique_ptr<DeviceArray<float>>> floats;
  std::vector<std::unique_ptr<DeviceArray<std::int32_t>>> ints;
  std::vector<std::unique_ptr<DeviceArray<S>>> vectors;
  std::unique_ptr<DeviceFineCells> fine;
  std::vector<std::unique_ptr<DeviceStoredCells>> stored;  // per level (null on 0 and the last)
  std::vector<std::array<S*, 4>> work;                     // b, x, r, dir per level
  std::vector<const int*> positions;                       // per level: 3 per cell (GS)
  // Per level on more ranks: the halo's send copies and packed values on the device, and the
  // host buffers the MPI exchange works on (DeviceHaloExchange).
  struct Halo {
    bool on = false;
    std::int64_t num_send = 0, num_ghosts = 0;
    const std::int32_t* send = nullptr;
    S* packed = nullptr;
    std::vector<S> host_packed, host_ghosts;
  };
  std::vector<Halo> halos;
  DeviceHaloExchange halo_exchange;
  int gamma_ = 1;
  std::function<void(const double*, double*)> coarse;
  std::vector<S> coarse_s;                 // the coarsest level's b, then x, as on the device
  std::vector<double> coarse_b, coarse_x;  // the same in double, for the host factorization
  std::vector<S> host_b;                   // level 0's b (float: b rounded once on entry)

  Of(const std::vector<DeviceCycleLevel>& levels, int gamma,
     std::function<void(const double* b, double* x)> solve_coarsest, DeviceHaloExchange halo);

  /// upload() into a new slot of `owner`.
  template <class T>
  T* up(std::vector<std::unique_ptr<DeviceArray<T>>>* owner, const T* host, std::size_t n) {
    owner->emplace_back();
    return upload(&owner->back(), host, n);
  }
  S* zeros(std::size_t n) {
    vectors.push_back(std::make_unique<DeviceArray<S>>(n));
    check(cudaMemset(vectors.back()->get(), 0, n * sizeof(S)), "cudaMemset");
    return vectors.back()->get();
  }

  // The executor of loop::cycle_level.
  using Scalar = S;
  int num_levels() const { return int(levels.size()); }
  int gamma() const { return gamma_; }
  const multigrid::LoopLevel& level(int l) const { return levels[l]; }
  S* b(int l) { return work[l][0]; }
  S* x(int l) { return work[l][1]; }
  S* r(int l) { return work[l][2]; }
  S* dir(int l) { return work[l][3]; }
  template <class Kernel>
  void for_each(std::int64_t n, const Kernel& k) {
    launch_index(n, k);
  }
  void apply_add(int l, const S* xd, S* yd) {
    if (l == 0)
      fine->apply_add(cells[0], xd, yd);
    else
      stored[l]->apply_add(xd, yd);
  }
  void apply_add_colour(int l, int k, const S* xd, S* yd) {
    if (l == 0)
      fine->apply_add_colour(cells[0], positions[0], k, xd, yd);
    else
      stored[l]->apply_add_colour(positions[l], k, xd, yd);
  }
  // The ghost exchange (multigrid/halo.hpp's plan): the send copies packed on the device, the
  // packed values and the ghost region across PCIe, the MPI part on the host.
  void exchange(int l, S* xd) {
    Halo& h = halos[l];
    if (!h.on) return;
    launch_index(h.num_send, multigrid::PackCopies<S>{h.send, xd, h.packed});
    check(cudaMemcpy(h.host_packed.data(), h.packed, 3 * h.num_send * sizeof(S),
                     cudaMemcpyDeviceToHost),
          "cudaMemcpy to host");
    halo_exchange.broadcast(l, h.host_packed.data(), h.host_ghosts.data());
    check(cudaMemcpy(xd + 3 * levels[l].num_copies, h.host_ghosts.data(),
                     3 * h.num_ghosts * sizeof(S), cudaMemcpyHostToDevice),
          "cudaMemcpy to device");
  }
  void accumulate(int l, S* yd) {
    Halo& h = halos[l];
    if (!h.on) return;
    check(cudaMemcpy(h.host_ghosts.data(), yd + 3 * levels[l].num_copies,
                     3 * h.num_ghosts * sizeof(S), cudaMemcpyDeviceToHost),
          "cudaMemcpy to host");
    halo_exchange.reduce(l, h.host_ghosts.data(), h.host_packed.data());
    check(cudaMemcpy(h.packed, h.host_packed.data(), 3 * h.num_send * sizeof(S),
                     cudaMemcpyHostToDevice),
          "cudaMemcpy to device");
    launch_index(h.num_send, multigrid::AddCopies<S>{h.send, h.packed, yd});
  }
  void solve_coarsest(const S* bd, S* xd) {
    const auto n = coarse_s.size();
    check(cudaMemcpy(coarse_s.data(), bd, n * sizeof(S), cudaMemcpyDeviceToHost),
          "cudaMemcpy to host");
    if constexpr (std::is_same_v<S, double>) {
      coarse(coarse_s.data(), coarse_x.data());
      std::copy(coarse_x.begin(), coarse_x.end(), coarse_s.begin());
    } else {  // the factorization is double's: the coarsest vectors pass through double
      std::copy(coarse_s.begin(), coarse_s.end(), coarse_b.begin());
      coarse(coarse_b.data(), coarse_x.data());
      std::copy(coarse_x.begin(), coarse_x.end(), coarse_s.begin());
    }
    check(cudaMemcpy(xd, coarse_s.data(), n * sizeof(S), cudaMemcpyHostToDevice),
          "cudaMemcpy to device");
  }

  void apply(const double* bh, double* xh) override {
    const auto n = host_b.size();
    std::copy(bh, bh + n, host_b.begin());
    check(cudaMemcpy(b(0), host_b.data(), n * sizeof(S), cudaMemcpyHostToDevice),
          "cudaMemcpy to device");
    multigrid::loop::cycle_level(*this, 0, true);
    check(cudaMemcpy(host_b.data(), x(0), n * sizeof(S), cudaMemcpyDeviceToHost),
          "cudaMemcpy to host");
    std::copy(host_b.begin(), host_b.end(), xh);
  }
  double time_cycle(int repeat) override {
    return median_seconds(repeat, [&] { multigrid::loop::cycle_level(*this, 0, true); });
  }
};

template <class S>
DeviceCycle::Executor::Of<S>::Of(const std::vector<DeviceCycleLevel>& in, int gamma,
                                 std::function<void(const double* b, double* x)> solve_coarsest,
                                 DeviceHaloExchange halo) {
  const int L = int(in.size());
  gamma_ = gamma;
  coarse = std::move(solve_coarsest);
  halo_exchange = std::move(halo);
  halos.resize(L);
  levels.resize(L);
  cells.resize(L);
  stored.resize(L);
  work.resize(L);
  positions.assign(L, nullptr);
  for (int l = 0; l < L; ++l) {
    const auto& h = in[l].loop;
    auto& d = levels[l];
    d = h;
    const auto n = std::size_t(h.num_copies);
    // The level data in the vectors' type (float: the LoopLevel's float twins, rounded here).
    const auto level_array = [&](const double* host, std::size_t count, const double** dbl,
                                 const float** flt) {
      *dbl = nullptr;
      *flt = nullptr;
      if constexpr (std::is_same_v<S, float>) {
        if (!host) return;
        const std::vector<float> rounded(host, host + count);
        *flt = up(&floats, rounded.data(), count);
      } else {
        *dbl = up(&doubles, host, count);
      }
    };
    level_array(h.mask, 3 * n, &d.mask, &d.mask_single);
    level_array(h.diag_inv, 9 * n, &d.diag_inv, &d.diag_inv_single);
    d.colour_copy = up(&ints, h.colour_copy, std::size_t(h.colour_begin[8]));
    if (l + 1 < L) {
      d.prolong_coarse = up(&ints, h.prolong_coarse, 8 * n);
      const auto block = std::size_t(h.weight_block);
      level_array(h.prolong_weight, 8 * block * n, &d.prolong_weight, &d.prolong_weight_single);
      const auto nc = std::size_t(h.num_coarse);
      const auto nr = std::size_t(h.restrict_offset[nc]);
      d.restrict_offset = up(&ints, h.restrict_offset, nc + 1);
      d.restrict_fine = up(&ints, h.restrict_fine, nr);
      level_array(h.restrict_weight, block * nr, &d.restrict_weight, &d.restrict_weight_single);
      cells[l] = in[l].cells;
      positions[l] = up(&ints, in[l].position, 3 * std::size_t(in[l].cells.num_cells));
      if (l == 0) {
        const auto& c = in[0].cells;
        offsets0.assign(c.colour_offset, c.colour_offset + c.num_colours + 1);
        fine = std::make_unique<DeviceFineCells>(*in[0].fine, in[0].tables, c);
        cells[0].colour_offset = offsets0.data();
      } else
        stored[l] =
            std::make_unique<DeviceStoredCells>(in[l].packed_double, in[l].packed_single, cells[l]);
    }
    for (auto& w : work[l]) w = zeros(3 * std::size_t(h.num_local));
    if (in[l].halo) {
      if (!halo_exchange.broadcast || !halo_exchange.reduce)
        throw std::runtime_error("DeviceCycle: a level with a halo, and no exchange given");
      Halo& g = halos[l];
      g.on = true;
      g.num_send = in[l].halo_num_send;
      g.num_ghosts = h.num_local - h.num_copies;
      g.send = up(&ints, in[l].halo_send, std::size_t(g.num_send));
      g.packed = zeros(3 * std::size_t(g.num_send));
      g.host_packed.assign(3 * std::size_t(g.num_send), S(0));
      g.host_ghosts.assign(3 * std::size_t(g.num_ghosts), S(0));
    }
  }
  const auto nc = 3 * std::size_t(in[L - 1].loop.num_copies);
  coarse_s.assign(nc, S(0));
  coarse_b.assign(nc, 0.0);
  coarse_x.assign(nc, 0.0);
  host_b.assign(3 * std::size_t(in[0].loop.num_copies), S(0));
}

DeviceCycle::DeviceCycle(const std::vector<DeviceCycleLevel>& levels, int gamma, bool single,
                         std::function<void(const double* b, double* x)> solve_coarsest,
                         DeviceHaloExchange halo) {
  const int L = int(levels.size());
  if (L < 1 || (L > 1 && !levels[0].fine))
    throw std::runtime_error("DeviceCycle: needs a level, and fine cells on level 0 above others");
  if (single)
    ex_ = std::make_unique<Executor::Of<float>>(levels, gamma, std::move(solve_coarsest),
                                                std::move(halo));
  else
    ex_ = std::make_unique<Executor::Of<double>>(levels, gamma, std::move(solve_coarsest),
                                                 std::move(halo));
}

DeviceCycle::~DeviceCycle() = default;

void DeviceCycle::apply(const double* b, double* x) {
  ex_->apply(b, x);
}

double DeviceCycle::time_cycle(int repeat) {
  return ex_->time_cycle(repeat);
}

void cell_rotations(const std::int32_t* corners, std::int64_t num_cells, std::int64_t num_copies,
                    const double* u, double h, double* R) {
  if (num_cells == 0) return;
  const DeviceArray<std::int32_t> c(corners, 8 * std::size_t(num_cells));
  const DeviceArray<double> U(u, 3 * std::size_t(num_copies));
  DeviceArray<double> Rd(9 * std::size_t(num_cells));
  launch_index(num_cells, assembly::CellRotation{c.get(), U.get(), h, Rd.get()});
  check(cudaDeviceSynchronize(), "kernel");
  Rd.copy_to_host(R);
}

void fine_apply_add(const assembly::FineCellData& d, const FineTables& tables,
                    const CellArrays& cells, const double* x, double* y) {
  if (cells.num_cells == 0) return;
  const auto values = 3 * std::size_t(cells.num_copies);
  const DeviceFineCells A(d, tables, cells);
  const DeviceArray<double> X(x, values);
  DeviceArray<double> Y(y, values);
  A.apply_add(cells, X.get(), Y.get());
  check(cudaDeviceSynchronize(), "kernel");
  Y.copy_to_host(y);
}

DeviceTiming time_fine_apply(const assembly::FineCellData& d, const FineTables& tables,
                             const CellArrays& cells, int repeat, std::size_t copy_bytes) {
  DeviceTiming t;
  cudaDeviceProp prop;
  check(cudaGetDeviceProperties(&prop, 0), "cudaGetDeviceProperties");
  t.device = prop.name;
  const auto values = 3 * std::size_t(cells.num_copies);
  const std::vector<double> ones(values, 1.0);
  const DeviceFineCells A(d, tables, cells);
  const DeviceArray<double> X(ones.data(), values);
  DeviceArray<double> Y(ones.data(), values);
  t.fine_apply_seconds = median_seconds(repeat, [&] { A.apply_add(cells, X.get(), Y.get()); });
  const std::vector<float> ones_single(values, 1.0f);
  const DeviceArray<float> Xs(ones_single.data(), values);
  DeviceArray<float> Ys(ones_single.data(), values);
  t.fine_apply_single_seconds =
      median_seconds(repeat, [&] { A.apply_add(cells, Xs.get(), Ys.get()); });
  const std::size_t n = copy_bytes / sizeof(double);
  const DeviceArray<double> cx(n);
  DeviceArray<double> cy(n);
  check(cudaMemset(cx.get(), 0, n * sizeof(double)), "cudaMemset");
  constexpr int kThreads = 256;
  const double s = median_seconds(repeat, [&] {
    copy_kernel<<<unsigned((n + kThreads - 1) / kThreads), kThreads>>>(cx.get(), cy.get(), n);
    check(cudaGetLastError(), "kernel launch");
  });
  t.copy_bandwidth = 2.0 * double(n * sizeof(double)) / s;
  return t;
}

int select_device(int node_rank) {
  int n = 0;
  check(cudaGetDeviceCount(&n), "cudaGetDeviceCount");
  if (n == 0) throw std::runtime_error("no CUDA device");
  const int device = node_rank % n;
  check(cudaSetDevice(device), "cudaSetDevice");
  return device;
}

int device_count(std::string* why) {
  int n = 0;
  const cudaError_t e = cudaGetDeviceCount(&n);
  if (e != cudaSuccess) {
    if (why) *why = cudaGetErrorString(e);
    cudaGetLastError();  // clear the error
    return 0;
  }
  if (n == 0 && why) *why = "no CUDA device";
  return n;
}

void packed_apply_add(const double* packed, const CellArrays& cells, const double* x, double* y) {
  apply(packed, cells, x, y);
}

void packed_apply_add(const float* packed, const CellArrays& cells, const double* x, double* y) {
  apply(packed, cells, x, y);
}

}  // namespace hexcut::cuda
