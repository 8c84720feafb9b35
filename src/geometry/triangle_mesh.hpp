// Triangle surface meshes (OBJ, STL) and the solid they enclose.
#pragma once

#include <Eigen/Core>
#include <array>
#include <string>
#include <vector>

#include "geometry/shape.hpp"

namespace hexcut::geometry {

/// Indexed triangle mesh. Triangles are counter-clockwise seen from outside (outward
/// normals), the convention of OBJ and STL; files often break it, so meshes used as
/// solids go through orient_solid() (make_mesh_solid() does it).
struct TriangleMesh {
  std::vector<Eigen::Vector3d> vertices;
  std::vector<std::array<int, 3>> triangles;  // 0-based vertex indices
};

/// Loads an OBJ (.obj) or STL (.stl, binary or ASCII) file, chosen by the extension
/// (case-insensitive). OBJ: `v` and `f` records (v, v/vt, v//vn, v/vt/vn; negative
/// indices are relative), polygons fan-triangulated, everything else ignored. STL:
/// binary when the size is exactly 84 + 50*n (even if the header starts with "solid"),
/// otherwise ASCII; identical vertex positions are merged so the mesh is indexed. STL
/// facet normals are ignored: triangles keep the file's vertex order, and meshes used as
/// solids are oriented afterwards (orient_solid).
/// Throws hexcut::InputError ("path:line: message" where a line applies) for a missing
/// or unreadable file, bad syntax, an out-of-range index, or a mesh without triangles.
TriangleMesh load_triangle_mesh(const std::string& path);

/// v <- rotation (scale v) + translate: scaled about the file's origin, then turned about
/// it, then moved. A negative scale mirrors the mesh; triangles are then reversed so they
/// stay outward-oriented. `rotation` must be proper orthogonal (R^T R = I to 1e-9,
/// det R = 1). Throws std::invalid_argument for scale 0, a rotation that is not one, or
/// non-finite arguments.
void transform(TriangleMesh& mesh, double scale, const Eigen::Vector3d& translate,
               const Eigen::Matrix3d& rotation = Eigen::Matrix3d::Identity());

/// Checks what every use of a mesh relies on: each triangle's vertex indices lie in
/// [0, vertices.size()) and every vertex is finite. Throws std::invalid_argument naming
/// the first offending triangle (0-based) otherwise.
void check_mesh_indices(const TriangleMesh& mesh);

/// Bounding box of the vertices (of all vertices, referenced or not).
Aabb bounds(const TriangleMesh& mesh);

/// Enclosed volume by the divergence theorem, sum of v0·(v1×v2)/6; exact for a closed
/// outward-oriented mesh.
double enclosed_volume(const TriangleMesh& mesh);

/// Generalized winding number at p (Jacobson et al. 2013) by brute force over all
/// triangles: 1 inside a closed outward-oriented mesh, 0 outside, in between near holes.
/// Reference implementation for tests; make_mesh_solid() evaluates it hierarchically.
double winding_number(const TriangleMesh& mesh, const Eigen::Vector3d& p);

/// The same winding number at many points, of the mesh as given (no orientation),
/// evaluated hierarchically as make_mesh_solid() does: equal to winding_number() up to
/// round-off, in O(n log n) for the tree plus about O(log n) per point away from holes.
/// Throws std::invalid_argument like make_mesh_solid().
std::vector<double> winding_numbers(const TriangleMesh& mesh,
                                    const std::vector<Eigen::Vector3d>& points);

/// What orient_solid() found and did.
struct SolidOrientation {
  int pieces = 0;    // edge-connected pieces (see orient_solid)
  int cavities = 0;  // solid pieces inside an odd number of others, now oriented inward
  int sheets = 0;    // flat pieces with a free edge, left as given
  int walls = 0;     // flat pieces between other pieces, removed
  int flipped = 0;   // triangles whose vertex order was reversed
  int removed = 0;   // triangles removed (those of walls)
};

/// Orients a mesh that bounds a solid so that the generalized winding number is 1 in
/// the solid and 0 outside, whatever the orientation each triangle was given in
/// (doc/theory.md, "Triangle-mesh solids"):
///  1. Vertices at equal positions are one vertex (OBJ files often repeat them).
///     Triangles on the same three positions are copies of the first of them and take no
///     part until step 4; triangles with two corners at one position stay as given.
///     A piece is a set of triangles connected through edges that exactly two triangles
///     share; across each such edge the two are made to run in opposite directions
///     (breadth-first search). An edge of one triangle (a hole) or of three or more (two
///     bodies touching along an edge, an inner wall) does not connect pieces.
///  2. Each piece is turned so that its signed volume about its area centroid is
///     positive. A piece with |volume| <= 1e-8 area^1.5 is flat and bounds nothing: a
///     sheet (it has an edge of one triangle) stays as given, since alone it moves w by
///     less than 1/2; a wall (all its edges inside it or shared with other pieces, e.g.
///     the face between two boxes side by side) is removed.
///  3. A piece lies inside another when its box lies in the other's box, its volume is
///     smaller, and at its sample points (up to 32 triangle centroids) the other's
///     winding number is > 0.75 at more than half and < 0.25 at none (a piece that
///     crosses the other's surface is not inside it: the two are united). A piece
///     inside an odd number of others is a cavity and is reversed.
///  4. Copies of a triangle of a solid piece run like it; copies of a sheet's triangle
///     alternate, so that pairs cancel.
/// O(n log n) for n triangles. Throws std::invalid_argument for an out-of-range index, a
/// non-finite vertex, or a piece that cannot be oriented: a one-sided surface (Möbius
/// strip, Klein bottle), also when the twist passes through an edge shared by more than
/// two triangles; the message names the edge by its end points.
SolidOrientation orient_solid(TriangleMesh& mesh);

/// Solid bounded by a triangle mesh: the mesh is first oriented by orient_solid(), so
/// the orientation of its triangles does not matter; then inside where the generalized
/// winding number is >= 0.5, which tolerates small holes and cracks. Throws
/// std::invalid_argument for an empty mesh, an out-of-range index, or a mesh that
/// orient_solid() rejects.
ShapePtr make_mesh_solid(TriangleMesh mesh);

}  // namespace hexcut::geometry
