// Cut and boundary surfaces by dual contouring on the link grid (Wu 2014, sec. 4.3.2;
// doc/theory.md, "Surfaces (dual contouring)"). Every face between a material cell and something it
// is not linked to (an empty or outside neighbour, or a cell across a cut) becomes a quad whose
// corners are the surface vertices of the vertex copies at the face's 4 lattice vertices. A surface
// vertex minimises the quadratic error of the Hermite data (crossing point and normal) of the faces
// around its copy, so it sits on the cut or the body's surface rather than on the voxel staircase.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "deck/deck.hpp"
#include "geometry/voxelize.hpp"
#include "lattice/lattice.hpp"
#include "topology/vertex_copies.hpp"

namespace hexcut::surface {

/// A triangle mesh in the reference configuration. Vertex v moves with the displacement
/// interpolated trilinearly at local[v] from the 8 corner copies of cell[v].
struct Surface {
  std::vector<std::array<double, 3>> position;         // reference position [m] per vertex
  std::vector<std::int32_t> cell;                      // owning lattice cell per vertex
  std::vector<std::array<double, 3>> local;            // trilinear coordinates in that cell
  std::vector<std::int32_t> copy;                      // vertex copy (topology) per vertex
  std::vector<std::array<std::int32_t, 3>> triangles;  // counter-clockwise seen from outside
  std::vector<std::int32_t> cut_id;                    // per triangle: 0 = outer boundary
};

/// Face f of a cell: axis f/2, on the + side when f is odd.
inline int face_index(int axis, bool plus) {
  return 2 * axis + (plus ? 1 : 0);
}

/// Hermite data of one boundary face (a material cell against an empty or outside
/// neighbour): the body's surface crosses the segment from the cell's centre to the
/// neighbour's centre at fraction t, with unit outward normal `normal`.
struct BoundaryCrossing {
  std::int32_t cell = -1;
  std::int32_t face = 0;  // face_index()
  double t = 0.5;
  std::array<double, 3> normal{0.0, 0.0, 0.0};
};

/// The boundary faces' Hermite data, sorted by (cell, face). Cuts do not change which
/// faces are boundary faces, so one table serves every later surface.
struct BoundaryHermite {
  std::vector<BoundaryCrossing> faces;
  /// The entry of (cell, face), or null when the table has none.
  const BoundaryCrossing* find(std::int32_t cell, int face) const;
};

/// Hermite data of every boundary face of `lattice` whose crossing find_crossing() finds
/// for the body `ops` builds (a face whose cell centre the ops do not count as inside,
/// e.g. a lattice edited by hand, gets no entry and falls back to the face itself).
BoundaryHermite boundary_hermite(const lattice::Lattice& lattice,
                                 const std::vector<geometry::GeometryOp>& ops);
/// The same for the cells [first, last) only (to split the work over ranks: the tables of
/// consecutive ranges concatenate in order).
BoundaryHermite boundary_hermite(const lattice::Lattice& lattice,
                                 const std::vector<geometry::GeometryOp>& ops, std::int32_t first,
                                 std::int32_t last);

/// The same for the deck's geometry steps (the body analysis::build_lattice voxelizes).
BoundaryHermite boundary_hermite(const lattice::Lattice& lattice, const deck::Deck& deck);

/// Builds the cut surfaces (cut_id of the lattice's CutLinks, one quad on each side of a
/// cut link) and the outer boundary (cut_id 0, one quad per boundary face) of `lattice`,
/// whose vertex copies are `copies` (topology::build_vertex_copies of the current links).
/// `boundary` supplies the boundary faces' Hermite data; faces without an entry (or all,
/// when it is null) use the face centre and the axis normal, which gives the staircase.
Surface build_surface(const lattice::Lattice& lattice, const topology::VertexCopies& copies,
                      const BoundaryHermite* boundary = nullptr);

}  // namespace hexcut::surface
