// The Cartesian lattice every stage shares (doc/theory.md, "Lattice, links and vertex copies"):
// nx*ny*nz cubic cells of edge h; cell (i,j,k) covers origin + h*[i,i+1]x[j,j+1]x[k,k+1].
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>

namespace hexcut {

struct LatticeSpec {
  Eigen::Vector3d origin{0.0, 0.0, 0.0};
  double h = 1.0;                    // cell edge [m]
  std::array<int, 3> dims{0, 0, 0};  // cells per axis

  std::int64_t num_cells() const { return std::int64_t(dims[0]) * dims[1] * dims[2]; }
  /// Dense cell index, x fastest.
  std::int64_t cell_index(int i, int j, int k) const {
    return i + std::int64_t(dims[0]) * (j + std::int64_t(dims[1]) * k);
  }
  Eigen::Vector3d cell_centre(int i, int j, int k) const {
    return origin + h * Eigen::Vector3d(i + 0.5, j + 0.5, k + 0.5);
  }
  Eigen::Vector3d vertex_position(int i, int j, int k) const {
    return origin + h * Eigen::Vector3d(i, j, k);
  }
};

}  // namespace hexcut
