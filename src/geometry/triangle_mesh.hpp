// Triangle surface meshes (OBJ, STL) and the solid they enclose.
#pragma once

#include <Eigen/Core>
#include <array>
#include <string>
#include <vector>

#include "geometry/shape.hpp"

namespace hexcut::geometry {

/// Indexed triangle mesh. Triangles are counter-clockwise seen from outside (outward
/// normals), the convention of OBJ and STL.
struct TriangleMesh {
  std::vector<Eigen::Vector3d> vertices;
  std::vector<std::array<int, 3>> triangles;  // 0-based vertex indices
};

/// Loads an OBJ (.obj) or STL (.stl, binary or ASCII) file, chosen by the extension
/// (case-insensitive). OBJ: `v` and `f` records (v, v/vt, v//vn, v/vt/vn; negative
/// indices are relative), polygons fan-triangulated, everything else ignored. STL:
/// binary when the size is exactly 84 + 50*n (even if the header starts with "solid"),
/// otherwise ASCII; identical vertex positions are merged so the mesh is indexed.
/// Throws hexcut::InputError ("path:line: message" where a line applies) for a missing
/// or unreadable file, bad syntax, an out-of-range index, or a mesh without triangles.
TriangleMesh load_triangle_mesh(const std::string& path);

/// v <- scale*v + translate. A negative scale mirrors the mesh; triangles are then
/// reversed so they stay outward-oriented. Throws std::invalid_argument for scale 0 or
/// non-finite arguments.
void transform(TriangleMesh& mesh, double scale, const Eigen::Vector3d& translate);

/// Bounding box of the vertices (of all vertices, referenced or not).
Aabb bounds(const TriangleMesh& mesh);

/// Enclosed volume by the divergence theorem, sum of v0·(v1×v2)/6; exact for a closed
/// outward-oriented mesh.
double enclosed_volume(const TriangleMesh& mesh);

/// Generalized winding number at p (Jacobson et al. 2013) by brute force over all
/// triangles: 1 inside a closed outward-oriented mesh, 0 outside, in between near holes.
/// Reference implementation for tests; make_mesh_solid() evaluates it hierarchically.
double winding_number(const TriangleMesh& mesh, const Eigen::Vector3d& p);

/// Solid bounded by a triangle mesh: inside where the generalized winding number is
/// >= 0.5, which tolerates small holes and cracks. Throws std::invalid_argument for an
/// empty mesh or an out-of-range index.
ShapePtr make_mesh_solid(TriangleMesh mesh);

}  // namespace hexcut::geometry
