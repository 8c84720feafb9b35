#include "cut/blade.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>

namespace hexcut::cut {

Eigen::Vector3d Triangle::normal() const {
  const Eigen::Vector3d n = (b - a).cross(c - a);
  const double len = n.norm();
  return len > 0 ? Eigen::Vector3d(n / len) : Eigen::Vector3d::Zero();
}

namespace {

/// The two triangles of the quad p0 p1 q1 q0 (p: edge at one position, q: at the next).
void add_quad(const Eigen::Vector3d& p0, const Eigen::Vector3d& p1, const Eigen::Vector3d& q1,
              const Eigen::Vector3d& q0, std::vector<Triangle>* out) {
  out->push_back({p0, p1, q1});
  out->push_back({p0, q1, q0});
}

std::vector<Triangle> cylinder_triangles(const deck::Blade& b) {
  // The side of the cylinder only (a stamp cuts along its wall), as `segments` quads.
  const Eigen::Vector3d axis = (b.end - b.start).normalized();
  const Eigen::Vector3d helper =
      std::abs(axis.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
  const Eigen::Vector3d e1 = axis.cross(helper).normalized(), e2 = axis.cross(e1);
  std::vector<Triangle> out;
  for (int s = 0; s < b.segments; ++s) {
    const double a0 = 2.0 * M_PI * s / b.segments, a1 = 2.0 * M_PI * (s + 1) / b.segments;
    const Eigen::Vector3d r0 = b.radius * (std::cos(a0) * e1 + std::sin(a0) * e2);
    const Eigen::Vector3d r1 = b.radius * (std::cos(a1) * e1 + std::sin(a1) * e2);
    add_quad(b.start + r0, b.start + r1, b.end + r1, b.end + r0, &out);
  }
  return out;
}

std::vector<Triangle> scalpel_segment(const deck::Blade& b, std::size_t k) {
  std::vector<Triangle> out;
  add_quad(b.edge[0] + b.path[k], b.edge[1] + b.path[k], b.edge[1] + b.path[k + 1],
           b.edge[0] + b.path[k + 1], &out);
  return out;
}

}  // namespace

std::vector<Triangle> blade_triangles(const deck::Blade& b) {
  std::vector<Triangle> out;
  switch (b.kind) {
    case deck::Blade::Kind::mesh:
      for (const auto& t : b.mesh.triangles)
        out.push_back({b.mesh.vertices[t[0]], b.mesh.vertices[t[1]], b.mesh.vertices[t[2]]});
      break;
    case deck::Blade::Kind::polygon:
      // Planar and convex (checked by the deck): a fan from the first corner covers it.
      for (std::size_t i = 1; i + 1 < b.polygon.size(); ++i)
        out.push_back({b.polygon[0], b.polygon[i], b.polygon[i + 1]});
      break;
    case deck::Blade::Kind::scalpel:
      for (std::size_t k = 0; k + 1 < b.path.size(); ++k) {
        auto q = scalpel_segment(b, k);
        out.insert(out.end(), q.begin(), q.end());
      }
      break;
    case deck::Blade::Kind::cylinder:
      out = cylinder_triangles(b);
      break;
  }
  return out;
}

std::vector<CutEvent> cut_schedule(const std::vector<deck::Cut>& cuts) {
  std::vector<CutEvent> events;
  for (std::size_t i = 0; i < cuts.size(); ++i) {
    const auto& c = cuts[i];
    const int id = int(i) + 1;
    if (c.swept) {
      const std::size_t n = c.blade.path.size();
      for (std::size_t k = 0; k + 1 < n; ++k) {
        const double t =
            c.window_begin + double(k + 1) * (c.window_end - c.window_begin) / double(n - 1);
        events.push_back({t, id, scalpel_segment(c.blade, k)});
      }
    } else {
      events.push_back({c.time, id, blade_triangles(c.blade)});
    }
  }
  std::stable_sort(events.begin(), events.end(),
                   [](const CutEvent& a, const CutEvent& b) { return a.time < b.time; });
  return events;
}

}  // namespace hexcut::cut
