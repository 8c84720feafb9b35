#include "cut/link_cut.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <map>

namespace hexcut::cut {

std::optional<double> segment_crosses(const Eigen::Vector3d& p, const Eigen::Vector3d& q,
                                      const Triangle& tri) {
  // Moller-Trumbore on the segment, with a scale-aware tolerance on the barycentric
  // bounds so that shared triangle edges are closed.
  const Eigen::Vector3d d = q - p, e1 = tri.b - tri.a, e2 = tri.c - tri.a;
  const Eigen::Vector3d h = d.cross(e2);
  const double det = e1.dot(h);
  const double scale = e1.norm() * e2.norm() * d.norm();
  if (std::abs(det) <= 1e-12 * scale) return std::nullopt;  // parallel or degenerate
  const double inv = 1.0 / det;
  const Eigen::Vector3d s = p - tri.a;
  const double u = s.dot(h) * inv;
  constexpr double eps = 1e-12;
  if (u < -eps || u > 1.0 + eps) return std::nullopt;
  const Eigen::Vector3d qv = s.cross(e1);
  const double v = d.dot(qv) * inv;
  if (v < -eps || u + v > 1.0 + eps) return std::nullopt;
  const double t = e2.dot(qv) * inv;
  // Half-open [0, 1): a blade through a cell centre cuts one of its two links, not both.
  if (t < 0.0 || t >= 1.0) return std::nullopt;
  return t;
}

std::vector<lattice::CutLink> find_crossed_links(const lattice::Lattice& lattice,
                                                 const CellTree& tree,
                                                 const std::vector<Eigen::Vector3d>& centres,
                                                 const std::vector<Triangle>& triangles,
                                                 int cut_id) {
  std::map<std::pair<std::int32_t, int>, lattice::CutLink> hits;  // (cell, dir) -> first hit
  for (const auto& tri : triangles) {
    const Eigen::Vector3d normal = tri.normal();
    if (normal.squaredNorm() == 0) continue;  // degenerate triangle: crosses nothing
    Eigen::AlignedBox3d box(tri.a);
    box.extend(tri.b);
    box.extend(tri.c);
    tree.query(box, [&](std::int32_t c) {
      for (int d = 0; d < 3; ++d) {
        if (!lattice.linked(c, d) || hits.count({c, d})) continue;
        const auto nb = lattice.neighbour(c, d);
        if (nb < 0) continue;
        if (const auto t = segment_crosses(centres[c], centres[nb], tri))
          hits[{c, d}] = {c, d, *t, {normal.x(), normal.y(), normal.z()}, cut_id};
      }
    });
  }
  std::vector<lattice::CutLink> out;
  out.reserve(hits.size());
  for (const auto& kv : hits) out.push_back(kv.second);
  return out;
}

void cut_links(lattice::Lattice& lattice, const std::vector<lattice::CutLink>& links) {
  for (const auto& l : links) {
    lattice.links[l.cell] &= std::uint8_t(~(1u << l.dir));
    lattice.cut_links.push_back(l);
  }
}

}  // namespace hexcut::cut
