// Link cutting (doc/theory.md, "Cutting"; Dick 2012, sec. 4.4.1): every connected link is the
// segment between the deformed centres of its two cells; a blade triangle that crosses it
// disconnects the cells. The Hermite data of the crossing (t, blade normal, cut id) are kept for
// the surfaces.
#pragma once

#include <Eigen/Core>
#include <optional>
#include <vector>

#include "cut/blade.hpp"
#include "cut/cell_tree.hpp"
#include "lattice/lattice.hpp"

namespace hexcut::cut {

/// Parameter s in [0, 1) where the segment p -> q crosses the triangle (closed: edges and
/// corners count, so a segment through the seam of two triangles is not missed), or
/// nullopt. A segment lying in the triangle's plane does not cross it.
std::optional<double> segment_crosses(const Eigen::Vector3d& p, const Eigen::Vector3d& q,
                                      const Triangle& tri);

/// The still-connected links that the triangles cross, with the cell centres of the
/// current configuration (one per cell) and a tree refitted to them. Each link appears
/// once, with the first triangle (in order) that crosses it. Deterministic: sorted by
/// (cell, dir).
std::vector<lattice::CutLink> find_crossed_links(const lattice::Lattice& lattice,
                                                 const CellTree& tree,
                                                 const std::vector<Eigen::Vector3d>& centres,
                                                 const std::vector<Triangle>& triangles,
                                                 int cut_id);

/// Clears the links and appends their Hermite data to lattice.cut_links.
void cut_links(lattice::Lattice& lattice, const std::vector<lattice::CutLink>& links);

}  // namespace hexcut::cut
