#include "geometry/shape.hpp"

#include <stdexcept>

namespace hexcut::geometry {

Eigen::Vector3d Shape::outward_normal(const Eigen::Vector3d&) const {
  return Eigen::Vector3d::Zero();
}

std::optional<double> Shape::surface_crossing(const Eigen::Vector3d&,
                                              const Eigen::Vector3d&) const {
  return std::nullopt;
}

void Shape::classify_cells(const LatticeSpec& spec, const std::array<int, 3>& lo,
                           const std::array<int, 3>& hi, std::vector<std::uint8_t>& inside) const {
  const std::int64_t nx = std::max(0, hi[0] - lo[0]);
  const std::int64_t ny = std::max(0, hi[1] - lo[1]);
  const std::int64_t nz = std::max(0, hi[2] - lo[2]);
  inside.assign(nx * ny * nz, 0);
  std::int64_t c = 0;
  for (int k = lo[2]; k < hi[2]; ++k) {
    for (int j = lo[1]; j < hi[1]; ++j) {
      for (int i = lo[0]; i < hi[0]; ++i, ++c) {
        inside[c] = contains(spec.cell_centre(i, j, k)) ? 1 : 0;
      }
    }
  }
}

}  // namespace hexcut::geometry
