// Material cells and the face links between them (doc/theory.md, "Lattice, links and vertex
// copies"). Only material cells are stored; they are numbered in lattice order (x fastest), so face
// neighbours are near in memory. Links are the only thing a cut changes (src/cut).
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "common/lattice_spec.hpp"

namespace hexcut::lattice {

/// Link bits: cell connected to its +x, +y, +z face neighbour.
enum LinkBit : std::uint8_t { kLinkX = 1, kLinkY = 2, kLinkZ = 4 };

/// Hermite data of a link a blade has cut (doc/theory.md, "Cutting", "Surfaces (dual contouring)"):
/// the link from `cell` to its + neighbour in direction `dir` was crossed at parameter t along the
/// segment from this cell's centre to the neighbour's (both in the configuration at the time of the
/// cut), by a blade with unit normal `normal` (reference frame). Cut ids start at 1 (0 is the
/// original boundary in surface output).
struct CutLink {
  std::int32_t cell = -1;
  std::int32_t dir = 0;
  double t = 0.5;
  std::array<double, 3> normal{0.0, 0.0, 0.0};
  std::int32_t cut_id = 0;
};

struct Lattice {
  LatticeSpec spec;
  std::vector<std::array<std::int32_t, 3>> ijk;  // per cell: lattice index
  std::vector<std::int32_t> material;            // per cell: material id
  std::vector<double> youngs;                    // per cell: E [Pa]
  std::vector<double> poisson;                   // per cell: nu [-]
  std::vector<double> density;                   // per cell: rho [kg/m^3]
  std::vector<std::uint8_t> links;               // per cell: LinkBit mask
  std::vector<std::int32_t> cell_at;             // dense lattice index -> cell, -1 = empty
  std::vector<CutLink> cut_links;                // links cleared by cuts, in cutting order

  std::int32_t num_cells() const { return std::int32_t(ijk.size()); }
  /// Cell at (i,j,k), or -1 when empty or outside the lattice.
  std::int32_t find(int i, int j, int k) const {
    if (i < 0 || j < 0 || k < 0 || i >= spec.dims[0] || j >= spec.dims[1] || k >= spec.dims[2])
      return -1;
    return cell_at[spec.cell_index(i, j, k)];
  }
  /// Cell c's face neighbour on the + side in direction d (0,1,2), or -1 when empty or
  /// outside the lattice.
  std::int32_t neighbour(std::int32_t c, int d) const {
    const auto& p = ijk[c];
    return find(p[0] + (d == 0), p[1] + (d == 1), p[2] + (d == 2));
  }
  /// Is cell c linked to its face neighbour in direction d (0,1,2) on the + side?
  bool linked(std::int32_t c, int d) const { return links[c] & (1u << d); }
};

/// Per-material properties used to fill the per-cell arrays.
struct MaterialProperties {
  double youngs_modulus, poisson_ratio, density;
};

/// Builds cells and links from a dense material grid (-1 = empty). `youngs_override`
/// is empty or dense with NaN meaning "use the material's E". Every pair of face
/// neighbours starts linked.
Lattice build_lattice(const LatticeSpec& spec, const std::vector<std::int16_t>& dense_material,
                      const std::vector<double>& youngs_override,
                      const std::vector<MaterialProperties>& materials);

}  // namespace hexcut::lattice
