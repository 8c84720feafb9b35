// Solid shapes for voxelization (doc/theory.md, "Voxelization"): anything that can answer "is this
// point inside?". Cells are classified by their centre, so a shape is sampled, never integrated.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include "common/lattice_spec.hpp"

namespace hexcut::geometry {

/// Axis-aligned bounding box. Unbounded shapes use +-infinity on the open sides.
struct Aabb {
  Eigen::Vector3d lo;
  Eigen::Vector3d hi;

  bool is_finite() const { return lo.allFinite() && hi.allFinite(); }
};

class Shape {
 public:
  virtual ~Shape() = default;

  /// Point membership; points on the surface count as inside.
  virtual bool contains(const Eigen::Vector3d& p) const = 0;

  /// Box that contains every inside point (may be infinite, see Aabb).
  virtual Aabb bounds() const = 0;

  /// Unit outward normal of the surface near p (p is meant to lie on or close to the surface): the
  /// Hermite normal of the outer boundary (doc/theory.md, "Surfaces (dual contouring)",
  /// geometry/crossing). Zero when the shape has no normal to offer (the default, e.g. voxel
  /// images).
  virtual Eigen::Vector3d outward_normal(const Eigen::Vector3d& p) const;
  /// Where the segment from a to b crosses the shape's surface, as s in [0, 1] (the point
  /// a + s (b - a)), for shapes that can compute it exactly and find exactly one crossing
  /// there; nullopt otherwise (the default: no such test, or none or several crossings).
  /// geometry/crossing uses it instead of bisecting; it checks the answer by membership.
  virtual std::optional<double> surface_crossing(const Eigen::Vector3d& a,
                                                 const Eigen::Vector3d& b) const;

  /// Classifies the cells of the half-open index box [lo, hi) of `spec` by their centre:
  /// inside[(i-lo0) + nx*((j-lo1) + ny*(k-lo2))] = contains(cell centre), with
  /// nx = hi0-lo0, ny = hi1-lo1. `inside` is resized to the box size. The default
  /// loops contains(); shapes with a faster bulk test override it.
  virtual void classify_cells(const LatticeSpec& spec, const std::array<int, 3>& lo,
                              const std::array<int, 3>& hi,
                              std::vector<std::uint8_t>& inside) const;
};

using ShapePtr = std::shared_ptr<const Shape>;

/// Closed box [lo, hi]; requires lo < hi componentwise.
ShapePtr make_box(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi);

/// Closed ball |p - centre| <= radius; requires radius > 0.
ShapePtr make_sphere(const Eigen::Vector3d& centre, double radius);

/// Finite cylinder with flat caps, axis from p0 to p1; requires p0 != p1, radius > 0.
ShapePtr make_cylinder(const Eigen::Vector3d& p0, const Eigen::Vector3d& p1, double radius);

/// Half-space (p - point)·normal <= 0, i.e. the normal points out of the solid.
/// Requires a nonzero normal (it need not be unit length).
ShapePtr make_half_space(const Eigen::Vector3d& point, const Eigen::Vector3d& normal);

/// Slab |(p - point)·n| <= half_thickness with n = normal/|normal|; a thin slab selects
/// the points of a plane (boundary conditions). Requires half_thickness >= 0.
ShapePtr make_slab(const Eigen::Vector3d& point, const Eigen::Vector3d& normal,
                   double half_thickness);

}  // namespace hexcut::geometry
