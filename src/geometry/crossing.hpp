// Where a segment leaves the body that a list of geometry operations builds, and the body's outward
// normal there: the Hermite data of the outer boundary for the surfaces (doc/theory.md, "Surfaces
// (dual contouring)"). Membership is the one voxelize.hpp's apply() gives cell centres, so the
// crossing lies between a material cell's centre and its empty neighbour's centre.
#pragma once

#include <Eigen/Core>
#include <optional>
#include <vector>

#include "geometry/voxelize.hpp"

namespace hexcut::geometry {

/// Is p inside the body after applying `ops` in order to an empty lattice? The last add or
/// subtract whose shape contains p decides (assign changes a material, not membership).
bool inside_after(const std::vector<GeometryOp>& ops, const Eigen::Vector3d& p);

struct Crossing {
  double t = 0.5;                                    // inside + t * (outside - inside)
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();  // unit, pointing out of the body
};

/// The boundary crossing on the segment from `inside` to `outside`: the exact intersection
/// with the deciding shape's surface where the shape offers one (Shape::surface_crossing:
/// triangle meshes) and membership flips across it, else by bisection on inside_after()
/// (`iterations` halvings: 30 resolve 1e-9 of the segment). The normal is
/// the outward normal (Shape::outward_normal) of the operation whose surface is crossed:
/// an add's shape as is, a subtract's reversed. Where that shape has none (images), the
/// segment's direction. nullopt when `inside` is not inside or `outside` not outside.
std::optional<Crossing> find_crossing(const std::vector<GeometryOp>& ops,
                                      const Eigen::Vector3d& inside, const Eigen::Vector3d& outside,
                                      int iterations = 30);

}  // namespace hexcut::geometry
