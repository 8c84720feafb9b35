// Trilinear weights and the parity octant: the one definition the multigrid transfer
// (hierarchy, Galerkin kernels) and the surface's deformed positions share
// (doc/theory.md, "Geometric multigrid", "Transfer").
#pragma once

#include "element/host_device.hpp"

namespace hexcut::element {

/// Weight of cell corner q = a + 2b + 4c (x fastest) at local coordinates xi in [0,1]^3:
/// prod_d (xi_d if bit d of q else 1 - xi_d). The 8 weights sum to 1.
HEXCUT_HD inline double trilinear_weight(const double xi[3], int q) {
  double w = 1.0;
  for (int d = 0; d < 3; ++d) w *= ((q >> d) & 1) ? xi[d] : 1.0 - xi[d];
  return w;
}

/// Octant o = a + 2b + 4c of the cell or vertex at integer lattice position (i, j, k) in
/// its 2x2x2 block: the parity of each index. Also the vertex colour of the 8-colour
/// Gauss-Seidel sweep.
HEXCUT_HD inline int parity_octant(long long i, long long j, long long k) {
  return int((i & 1) + 2 * (j & 1) + 4 * (k & 1));
}

/// Trilinear weight of coarse corner j at fine corner i of the child in octant o: the
/// fine corner sits at xi_d = (o_d + i_d) / 2 in {0, 1/2, 1} of the coarse cell.
HEXCUT_HD inline double child_weight(int octant, int i, int j) {
  double xi[3];
  for (int d = 0; d < 3; ++d) xi[d] = 0.5 * double(((octant >> d) & 1) + ((i >> d) & 1));
  return trilinear_weight(xi, j);
}

/// Parity colour (0..7) of corner q of a cell at level position p: the colour of the
/// lattice vertex p + offset(q). The 8 corners of a cell have 8 different colours.
HEXCUT_HD inline int corner_colour(const int* p, int q) {
  return ((p[0] + (q & 1)) & 1) + 2 * ((p[1] + ((q >> 1) & 1)) & 1) +
         4 * ((p[2] + ((q >> 2) & 1)) & 1);
}

/// The corner of a cell at position p that has colour k.
HEXCUT_HD inline int corner_of_colour(const int* p, int k) {
  return ((k & 1) ^ (p[0] & 1)) + 2 * (((k >> 1) & 1) ^ (p[1] & 1)) +
         4 * (((k >> 2) & 1) ^ (p[2] & 1));
}

}  // namespace hexcut::element
