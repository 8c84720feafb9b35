// Hermite data of the outer boundary from the deck's geometry (doc/theory.md, "Surfaces (dual
// contouring)", "Boundary Hermite data"): the cells were classified by their centres, so the body's
// surface crosses each boundary face's centre-to-centre segment; geometry::find_crossing locates it
// on the same membership.
#include <algorithm>
#include <map>
#include <set>

#include "geometry/crossing.hpp"
#include "surface/surface.hpp"

namespace hexcut::surface {
const BoundaryCrossing* BoundaryHermite::find(std::int32_t cell, int face) const {
  const auto it = std::lower_bound(faces.begin(), faces.end(), std::make_pair(cell, face),
                                   [](const BoundaryCrossing& b, const std::pair<int, int>& key) {
                                     return std::make_pair(b.cell, b.face) < key;
                                   });
  return it != faces.end() && it->cell == cell && it->face == face ? &*it : nullptr;
}

BoundaryHermite boundary_hermite(const lattice::Lattice& L,
                                 const std::vector<geometry::GeometryOp>& ops) {
  return boundary_hermite(L, ops, 0, L.num_cells());
}

BoundaryHermite boundary_hermite(const lattice::Lattice& L,
                                 const std::vector<geometry::GeometryOp>& ops, std::int32_t first,
                                 std::int32_t last) {
  BoundaryHermite B;
  for (std::int32_t c = first; c < last; ++c) {
    const auto& p = L.ijk[c];
    const Eigen::Vector3d centre = L.spec.cell_centre(p[0], p[1], p[2]);
    for (int f = 0; f < 6; ++f) {
      const int axis = f / 2, step = f % 2 ? 1 : -1;
      std::array<int, 3> q = p;
      q[axis] += step;
      if (L.find(q[0], q[1], q[2]) >= 0) continue;
      const Eigen::Vector3d outside = centre + step * L.spec.h * Eigen::Vector3d::Unit(axis);
      if (const auto x = geometry::find_crossing(ops, centre, outside))
        B.faces.push_back({c, f, x->t, {x->normal.x(), x->normal.y(), x->normal.z()}});
    }
  }
  return B;  // cells ascending, faces ascending: sorted as find() needs
}

BoundaryHermite boundary_hermite(const lattice::Lattice& lattice, const deck::Deck& deck) {
  return boundary_hermite(lattice, deck::membership_ops(deck));
}

}  // namespace hexcut::surface
