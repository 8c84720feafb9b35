#include <cuda_runtime.h>

#include <cstdint>
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

}  // namespace

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
