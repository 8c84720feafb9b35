#include <cuda_runtime.h>

#include <algorithm>
#include <cstdint>
#include <memory>
#include <stdexcept>
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
  constexpr int kThreads = 128;
  for (int c = 0; c < cells.num_colours; ++c) {
    const std::int32_t n = cells.colour_offset[c + 1] - cells.colour_offset[c];
    if (n == 0) continue;
    for_each_of_colour<<<(n + kThreads - 1) / kThreads, kThreads>>>(
        k, order.get() + cells.colour_offset[c], n);
    check(cudaGetLastError(), "kernel launch");
  }
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
    upload(&order_, cells.colour_cell, std::size_t(cells.colour_offset[cells.num_colours]));
  }
  /// y += A x, x and y device arrays, launched colour by colour (no synchronization).
  void apply_add(const CellArrays& cells, const double* x, double* y) const {
    const backend::CellApplyAdd<assembly::FineCellOps> k{{d_}, d_.corners, x, y};
    constexpr int kThreads = 128;
    for (int c = 0; c < cells.num_colours; ++c) {
      const std::int32_t n = cells.colour_offset[c + 1] - cells.colour_offset[c];
      if (n == 0) continue;
      for_each_of_colour<<<(n + kThreads - 1) / kThreads, kThreads>>>(
          k, order_->get() + cells.colour_offset[c], n);
      check(cudaGetLastError(), "kernel launch");
    }
  }

 private:
  assembly::FineCellData d_;
  std::unique_ptr<DeviceArray<std::int32_t>> corners_, kind_, own_, order_;
  std::unique_ptr<DeviceArray<double>> kind_stiffness_, own_stiffness_, lambda_, mu_, rho_,
      rotation_, mask_;
  std::unique_ptr<DeviceArray<element::ReferenceMatrices>> reference_;
  std::unique_ptr<DeviceArray<char>> cell_masked_;
};

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
