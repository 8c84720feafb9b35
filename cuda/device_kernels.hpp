// The CUDA backend's operators on plain arrays (issue 13): what device_backend.cu compiles
// with nvcc, kept free of the host classes (and of Eigen, which nvcc warns about). Callers
// use device_backend.hpp.
#pragma once

#include <cstdint>
#include <string>

namespace hexcut::cuda {

/// CUDA devices this process can use; 0 when there is none or no driver, with the
/// runtime's reason in *why (may be null).
int device_count(std::string* why);

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

}  // namespace hexcut::cuda
