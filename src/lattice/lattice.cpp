#include "lattice/lattice.hpp"

#include <cmath>

namespace hexcut::lattice {

Lattice build_lattice(const LatticeSpec& spec, const std::vector<std::int16_t>& dense_material,
                      const std::vector<double>& youngs_override,
                      const std::vector<MaterialProperties>& materials) {
  Lattice L;
  L.spec = spec;
  L.cell_at.assign(dense_material.size(), -1);
  const auto [nx, ny, nz] = spec.dims;
  for (int k = 0; k < nz; ++k)
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i) {
        const auto dense = spec.cell_index(i, j, k);
        const int m = dense_material[dense];
        if (m < 0) continue;
        L.cell_at[dense] = L.num_cells();
        L.ijk.push_back({i, j, k});
        L.material.push_back(m);
        double E = materials[m].youngs_modulus;
        if (!youngs_override.empty() && !std::isnan(youngs_override[dense]))
          E = youngs_override[dense];
        L.youngs.push_back(E);
        L.poisson.push_back(materials[m].poisson_ratio);
        L.density.push_back(materials[m].density);
      }
  L.links.assign(L.ijk.size(), 0);
  for (std::int32_t c = 0; c < L.num_cells(); ++c) {
    const auto& p = L.ijk[c];
    for (int d = 0; d < 3; ++d) {
      std::array<int, 3> q{p[0], p[1], p[2]};
      ++q[d];
      if (L.find(q[0], q[1], q[2]) >= 0) L.links[c] |= std::uint8_t(1u << d);
    }
  }
  return L;
}

}  // namespace hexcut::lattice
