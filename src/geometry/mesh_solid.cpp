// Inside test for triangle meshes by the generalized winding number (Jacobson, Kavan,
// Sorkine-Hornung 2013, "Robust inside-outside segmentation using generalized winding
// numbers"): w(p) = sum over triangles of the signed solid angle / 4π, 1 inside a
// closed outward-oriented mesh, 0 outside, and a smooth in-between value near holes,
// so inside = (w >= 0.5) still works for meshes with small holes or cracks. The sign of
// w follows the triangles' orientation, which make_mesh_solid() first makes consistent
// and outward (mesh_orientation.cpp).
//
// Speed comes from two layers:
//  1. Hierarchical evaluation of w (the paper's §3.3). A BVH over the triangles stores,
//     per node, a "cap": the node's open boundary edges fanned to one boundary vertex.
//     Patch + cap is a closed 2-cycle inside the node's box, whose winding number is 0
//     at any point outside the box, so there w(patch) = -w(reversed cap) exactly. Caps
//     have O(sqrt n) triangles against the node's n, and a closed node costs nothing.
//  2. classify_cells() evaluates w only where it can change between neighbouring cells:
//     "band" cells, whose box may touch a triangle (triangle AABB overlap plus a box-plane
//     test), and cells near open boundary loops (holes), where w varies smoothly. The
//     remaining cells form face-connected regions that no triangle touches; w is
//     continuous there and, away from holes, within a few percent of an integer, so it
//     cannot cross 0.5: one evaluation at a seed decides the whole region. A seed value
//     that is not near an integer (something unforeseen) makes that region fall back to
//     per-cell evaluation, so the shortcut can cost time but not correctness.
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>

#include "geometry/triangle_mesh.hpp"

namespace hexcut::geometry {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr int kLeafSize = 8;

using Tri = std::array<Eigen::Vector3d, 3>;

// Signed solid angle of triangle (a, b, c) seen from p, by the Van Oosterom–Strackee
// formula tan(Ω/2) = a·(b×c) / (|a||b||c| + (a·b)|c| + (b·c)|a| + (c·a)|b|), with a, b, c
// relative to p. Positive when p is behind the triangle (its normal (b-a)×(c-a) points
// away from p), so an interior point of a closed outward-oriented mesh sums to +4π.
inline double solid_angle(const Eigen::Vector3d& p, const Tri& t) {
  const Eigen::Vector3d a = t[0] - p, b = t[1] - p, c = t[2] - p;
  const double la = a.norm(), lb = b.norm(), lc = c.norm();
  const double num = a.dot(b.cross(c));
  const double den = la * lb * lc + a.dot(b) * lc + b.dot(c) * la + c.dot(a) * lb;
  return 2.0 * std::atan2(num, den);
}

// Does the segment a + s d, s in [0, 1], meet the box? (Slabs per axis.)
bool segment_meets_box(const Eigen::Vector3d& a, const Eigen::Vector3d& d,
                       const Eigen::AlignedBox3d& box) {
  double s0 = 0.0, s1 = 1.0;
  for (int k = 0; k < 3; ++k) {
    if (d[k] == 0.0) {
      if (a[k] < box.min()[k] || a[k] > box.max()[k]) return false;
      continue;
    }
    double lo = (box.min()[k] - a[k]) / d[k], hi = (box.max()[k] - a[k]) / d[k];
    if (lo > hi) std::swap(lo, hi);
    s0 = std::max(s0, lo);
    s1 = std::min(s1, hi);
    if (s0 > s1) return false;
  }
  return true;
}

// Parameter s in [0, 1] where the segment a + s d passes through triangle t (edges
// included), by Moller and Trumbore's barycentric solve; nullopt when it misses or lies in
// the triangle's plane.
std::optional<double> segment_triangle(const Eigen::Vector3d& a, const Eigen::Vector3d& d,
                                       const Tri& t) {
  const Eigen::Vector3d e1 = t[1] - t[0], e2 = t[2] - t[0];
  const Eigen::Vector3d q = d.cross(e2);
  const double det = e1.dot(q);
  if (!(std::abs(det) > 1e-300)) return std::nullopt;
  const Eigen::Vector3d r = a - t[0];
  const double u = r.dot(q) / det;
  if (u < 0.0 || u > 1.0) return std::nullopt;
  const Eigen::Vector3d w = r.cross(e1);
  const double v = d.dot(w) / det;
  if (v < 0.0 || u + v > 1.0) return std::nullopt;
  const double s = e2.dot(w) / det;
  if (s < 0.0 || s > 1.0) return std::nullopt;
  return s;
}

// Closest point to p on triangle t, by the Voronoi regions of its corners, edges and
// face (Ericson, "Real-Time Collision Detection", §5.1.5).
Eigen::Vector3d closest_point(const Eigen::Vector3d& p, const Tri& t) {
  const Eigen::Vector3d &a = t[0], &b = t[1], &c = t[2];
  const Eigen::Vector3d ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0.0 && d2 <= 0.0) return a;
  const Eigen::Vector3d bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0.0 && d4 <= d3) return b;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) return a + d1 / (d1 - d3) * ab;
  const Eigen::Vector3d cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0.0 && d5 <= d6) return c;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) return a + d2 / (d2 - d6) * ac;
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0)
    return b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b);
  const double denom = 1.0 / (va + vb + vc);
  return a + ab * (vb * denom) + ac * (vc * denom);
}

void check_mesh(const TriangleMesh& mesh) {
  if (mesh.triangles.empty()) throw std::invalid_argument("mesh solid: mesh has no triangles");
  check_mesh_indices(mesh);
}

using Edge = std::pair<int, int>;  // directed

// Net directed edges of a set of edges: (a,b) and (b,a) cancel. What remains is the open
// boundary of the patch (empty for a closed patch). Sorted, so the result is deterministic.
std::vector<Edge> cancel_edges(const std::vector<Edge>& edges) {
  std::vector<std::pair<std::pair<int, int>, int>> keyed;
  keyed.reserve(edges.size());
  for (const auto& [a, b] : edges) {
    if (a == b) continue;
    keyed.push_back(a < b ? std::make_pair(std::make_pair(a, b), 1)
                          : std::make_pair(std::make_pair(b, a), -1));
  }
  std::sort(keyed.begin(), keyed.end());
  std::vector<Edge> out;
  for (std::size_t i = 0; i < keyed.size();) {
    std::size_t j = i;
    int count = 0;
    while (j < keyed.size() && keyed[j].first == keyed[i].first) count += keyed[j++].second;
    const auto [lo, hi] = keyed[i].first;
    for (int c = 0; c < std::abs(count); ++c)
      out.push_back(count > 0 ? Edge{lo, hi} : Edge{hi, lo});
    i = j;
  }
  return out;
}

class UnionFind {
 public:
  explicit UnionFind(int n) : parent_(n) { std::iota(parent_.begin(), parent_.end(), 0); }
  int find(int x) {
    while (parent_[x] != x) x = parent_[x] = parent_[parent_[x]];
    return x;
  }
  void unite(int a, int b) { parent_[find(a)] = find(b); }

 private:
  std::vector<int> parent_;
};

class MeshSolid final : public Shape {
 public:
  explicit MeshSolid(TriangleMesh mesh) : mesh_(std::move(mesh)) {
    check_mesh(mesh_);
    const int n = static_cast<int>(mesh_.triangles.size());
    std::vector<int> order(n);
    std::iota(order.begin(), order.end(), 0);
    std::vector<Eigen::Vector3d> centroid(n);
    for (int t = 0; t < n; ++t) centroid[t] = tri(t)[0] / 3 + tri(t)[1] / 3 + tri(t)[2] / 3;
    std::vector<Edge> root_boundary;
    build(order, centroid, 0, n, root_boundary);
    tris_.reserve(n);
    for (int t : order) tris_.push_back(tri(t));
    find_hole_zones(root_boundary);
    bounds_ = geometry::bounds(mesh_);
  }

  bool contains(const Eigen::Vector3d& p) const override { return winding(p) >= 0.5; }

  Aabb bounds() const override { return bounds_; }

  double winding(const Eigen::Vector3d& p) const {
    double sum = 0.0;
    int stack[128];
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
      const Node& node = nodes_[stack[--top]];
      if (node.has_cap && !node.box.contains(p)) {
        for (int c = node.cap_begin; c < node.cap_end; ++c) sum += solid_angle(p, caps_[c]);
      } else if (node.left < 0) {
        for (int t = node.begin; t < node.end; ++t) sum += solid_angle(p, tris_[t]);
      } else {
        stack[top++] = node.left;
        stack[top++] = node.right;
      }
    }
    return sum / (4.0 * kPi);
  }

  void classify_cells(const LatticeSpec& spec, const std::array<int, 3>& lo,
                      const std::array<int, 3>& hi,
                      std::vector<std::uint8_t>& inside) const override;

  // The triangles the segment a-b passes through, by a BVH descent pruned by the segment's
  // slab test against the node boxes, and the Moller-Trumbore test per triangle (Ericson,
  // "Real-Time Collision Detection", sec. 5.3.6). One hit: its parameter; none or several
  // (a sliver thinner than the segment, a hole, a hit on a shared edge counted twice):
  // nullopt, and the caller keeps bisecting.
  std::optional<double> surface_crossing(const Eigen::Vector3d& a,
                                         const Eigen::Vector3d& b) const override {
    const Eigen::Vector3d d = b - a;
    std::optional<double> hit;
    int hits = 0;
    int stack[128];
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
      const Node& node = nodes_[stack[--top]];
      if (!segment_meets_box(a, d, node.box)) continue;
      if (node.left >= 0) {
        stack[top++] = node.left;
        stack[top++] = node.right;
        continue;
      }
      for (int t = node.begin; t < node.end; ++t) {
        const auto s = segment_triangle(a, d, tris_[t]);
        if (!s) continue;
        if (++hits > 1) return std::nullopt;
        hit = s;
      }
    }
    return hit;
  }

  // Normal of the nearest non-degenerate triangle (triangles are outward-oriented),
  // found by a best-first descent of the BVH pruned by box distance.
  Eigen::Vector3d outward_normal(const Eigen::Vector3d& p) const override {
    double best = std::numeric_limits<double>::infinity();
    Eigen::Vector3d normal = Eigen::Vector3d::Zero();
    int stack[128];
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
      const Node& node = nodes_[stack[--top]];
      if (node.box.squaredExteriorDistance(p) >= best) continue;
      if (node.left < 0) {
        for (int t = node.begin; t < node.end; ++t) {
          const Tri& tri = tris_[t];
          const Eigen::Vector3d n = (tri[1] - tri[0]).cross(tri[2] - tri[0]);
          if (!(n.squaredNorm() > 0.0)) continue;
          const double d = (closest_point(p, tri) - p).squaredNorm();
          if (d < best) {
            best = d;
            normal = n.normalized();
          }
        }
        continue;
      }
      // Visit the nearer child first (pushed last) so that `best` shrinks early.
      const double dl = nodes_[node.left].box.squaredExteriorDistance(p);
      const double dr = nodes_[node.right].box.squaredExteriorDistance(p);
      stack[top++] = dl < dr ? node.right : node.left;
      stack[top++] = dl < dr ? node.left : node.right;
    }
    return normal;
  }

 private:
  struct Node {
    Eigen::AlignedBox3d box;
    int begin = 0, end = 0;     // range in tris_
    int left = -1, right = -1;  // children; -1 for a leaf
    int cap_begin = 0, cap_end = 0;
    bool has_cap = false;  // cap cheaper than the triangles (may be empty: closed)
  };

  Tri tri(int t) const {
    const auto& f = mesh_.triangles[t];
    return {mesh_.vertices[f[0]], mesh_.vertices[f[1]], mesh_.vertices[f[2]]};
  }

  // Builds the subtree over order[begin, end) (median split on the longest centroid
  // axis) and returns its open boundary edges in `boundary`. Returns the node index.
  int build(std::vector<int>& order, const std::vector<Eigen::Vector3d>& centroid, int begin,
            int end, std::vector<Edge>& boundary) {
    const int id = static_cast<int>(nodes_.size());
    nodes_.emplace_back();
    Eigen::AlignedBox3d box, cbox;
    for (int i = begin; i < end; ++i) {
      for (const auto& v : tri(order[i])) box.extend(v);
      cbox.extend(centroid[order[i]]);
    }
    Node node;
    node.box = box;
    node.begin = begin;
    node.end = end;
    const Eigen::Vector3d ext = cbox.sizes();
    int axis = 0;
    if (ext[1] > ext[axis]) axis = 1;
    if (ext[2] > ext[axis]) axis = 2;
    std::vector<Edge> edges;
    if (end - begin <= kLeafSize || !(ext[axis] > 0.0)) {
      for (int i = begin; i < end; ++i) {
        const auto& f = mesh_.triangles[order[i]];
        edges.insert(edges.end(), {{f[0], f[1]}, {f[1], f[2]}, {f[2], f[0]}});
      }
    } else {
      const int mid = begin + (end - begin) / 2;
      std::nth_element(order.begin() + begin, order.begin() + mid, order.begin() + end,
                       [&](int a, int b) { return centroid[a][axis] < centroid[b][axis]; });
      std::vector<Edge> lb, rb;
      node.left = build(order, centroid, begin, mid, lb);
      node.right = build(order, centroid, mid, end, rb);
      edges = std::move(lb);
      edges.insert(edges.end(), rb.begin(), rb.end());
    }
    boundary = cancel_edges(edges);
    // Cap: boundary edges (a,b) fanned to c as triangles (c,a,b), skipping degenerate
    // ones. Worth storing only when it is smaller than the patch itself.
    if (boundary.size() < static_cast<std::size_t>(end - begin)) {
      node.has_cap = true;
      node.cap_begin = static_cast<int>(caps_.size());
      if (!boundary.empty()) {
        const int c = boundary.front().first;
        for (const auto& [a, b] : boundary) {
          if (a == c || b == c) continue;
          caps_.push_back({mesh_.vertices[c], mesh_.vertices[a], mesh_.vertices[b]});
        }
      }
      node.cap_end = static_cast<int>(caps_.size());
    }
    nodes_[id] = node;
    return id;
  }

  // Boxes around the mesh's open boundary loops, inflated by twice their diagonal. A hole
  // of diameter d seen from distance r subtends about d²/(16 r²) of w, so outside these
  // zones w stays within ~0.02 of an integer and the region shortcut is safe.
  void find_hole_zones(const std::vector<Edge>& boundary) {
    if (boundary.empty()) return;
    UnionFind uf(static_cast<int>(mesh_.vertices.size()));
    for (const auto& [a, b] : boundary) uf.unite(a, b);
    std::vector<int> zone_of(mesh_.vertices.size(), -1);
    std::vector<Eigen::AlignedBox3d> boxes;
    for (const auto& [a, b] : boundary) {
      for (int v : {a, b}) {
        const int r = uf.find(v);
        if (zone_of[r] < 0) {
          zone_of[r] = static_cast<int>(boxes.size());
          boxes.emplace_back();
        }
        boxes[zone_of[r]].extend(mesh_.vertices[v]);
      }
    }
    for (const auto& b : boxes) {
      const Eigen::Vector3d pad = Eigen::Vector3d::Constant(2.0 * b.diagonal().norm());
      hole_zones_.push_back({b.min() - pad, b.max() + pad});
    }
  }

  TriangleMesh mesh_;
  std::vector<Node> nodes_;
  std::vector<Tri> tris_;  // in BVH order
  std::vector<Tri> caps_;
  std::vector<Aabb> hole_zones_;
  Aabb bounds_;
};

// Inclusive range of cells (clipped to [lo, hi)) along one axis whose closed extent
// [o + h*i, o + h*(i+1)] meets [a, b]. Empty when first > last.
std::pair<int, int> cell_range(double a, double b, double o, double h, int lo, int hi) {
  const double first = std::ceil((a - o) / h - 1.0);
  const double last = std::floor((b - o) / h);
  return {static_cast<int>(std::clamp(first, double(lo), double(hi))),
          static_cast<int>(std::clamp(last, double(lo) - 1.0, double(hi) - 1.0))};
}

void MeshSolid::classify_cells(const LatticeSpec& spec, const std::array<int, 3>& lo,
                               const std::array<int, 3>& hi,
                               std::vector<std::uint8_t>& inside) const {
  const std::int64_t nx = std::max(0, hi[0] - lo[0]);
  const std::int64_t ny = std::max(0, hi[1] - lo[1]);
  const std::int64_t nz = std::max(0, hi[2] - lo[2]);
  const std::int64_t n = nx * ny * nz;
  inside.assign(n, 0);
  if (n == 0) return;
  const double h = spec.h;
  const auto index = [&](int i, int j, int k) {
    return (i - lo[0]) + nx * ((j - lo[1]) + ny * std::int64_t(k - lo[2]));
  };

  enum : std::uint8_t { kFree = 0, kBand = 1, kDone = 2 };
  std::vector<std::uint8_t> state(n, kFree);

  // Band: cells whose box, dilated by eps against round-off, may touch a triangle.
  const double eps = 1e-3 * h;
  const double half = 0.5 * h + eps;
  for (const auto& t : tris_) {
    const Eigen::Vector3d tlo = t[0].cwiseMin(t[1]).cwiseMin(t[2]).array() - eps;
    const Eigen::Vector3d thi = t[0].cwiseMax(t[1]).cwiseMax(t[2]).array() + eps;
    std::array<std::pair<int, int>, 3> r;
    bool empty = false;
    for (int a = 0; a < 3; ++a) {
      r[a] = cell_range(tlo[a], thi[a], spec.origin[a], h, lo[a], hi[a]);
      empty |= r[a].first > r[a].second;
    }
    if (empty) continue;
    // A large tilted triangle has a large AABB; the box-plane test keeps only the cells
    // its plane passes through.
    const Eigen::Vector3d normal = (t[1] - t[0]).cross(t[2] - t[0]);
    const double nlen = normal.norm();
    const Eigen::Vector3d un =
        nlen > 0.0 ? Eigen::Vector3d(normal / nlen) : Eigen::Vector3d::Zero();
    const double reach = half * un.cwiseAbs().sum();
    for (int k = r[2].first; k <= r[2].second; ++k) {
      for (int j = r[1].first; j <= r[1].second; ++j) {
        for (int i = r[0].first; i <= r[0].second; ++i) {
          const std::int64_t c = index(i, j, k);
          if (state[c] == kBand) continue;
          if (nlen > 0.0 && std::abs(un.dot(spec.cell_centre(i, j, k) - t[0])) > reach) continue;
          state[c] = kBand;
        }
      }
    }
  }
  for (const auto& z : hole_zones_) {
    std::array<std::pair<int, int>, 3> r;
    for (int a = 0; a < 3; ++a)
      r[a] = cell_range(z.lo[a], z.hi[a], spec.origin[a], h, lo[a], hi[a]);
    for (int k = r[2].first; k <= r[2].second; ++k) {
      for (int j = r[1].first; j <= r[1].second; ++j) {
        for (int i = r[0].first; i <= r[0].second; ++i) state[index(i, j, k)] = kBand;
      }
    }
  }

  std::vector<std::int64_t> stack;
  for (int k = lo[2]; k < hi[2]; ++k) {
    for (int j = lo[1]; j < hi[1]; ++j) {
      for (int i = lo[0]; i < hi[0]; ++i) {
        const std::int64_t c = index(i, j, k);
        if (state[c] == kBand) {
          inside[c] = winding(spec.cell_centre(i, j, k)) >= 0.5;
          state[c] = kDone;
          continue;
        }
        if (state[c] != kFree) continue;
        // New region: flood it (6-connected) from this seed.
        const double w = winding(spec.cell_centre(i, j, k));
        const bool settled = std::abs(w - std::round(w)) < 0.25;
        const std::uint8_t seed_inside = w >= 0.5;
        state[c] = kDone;
        stack.assign(1, c);
        while (!stack.empty()) {
          const std::int64_t q = stack.back();
          stack.pop_back();
          const int qi = lo[0] + static_cast<int>(q % nx);
          const int qj = lo[1] + static_cast<int>((q / nx) % ny);
          const int qk = lo[2] + static_cast<int>(q / (nx * ny));
          inside[q] = settled ? seed_inside : winding(spec.cell_centre(qi, qj, qk)) >= 0.5;
          const auto visit = [&](bool ok, std::int64_t nb) {
            if (ok && state[nb] == kFree) {
              state[nb] = kDone;
              stack.push_back(nb);
            }
          };
          visit(qi > lo[0], q - 1);
          visit(qi + 1 < hi[0], q + 1);
          visit(qj > lo[1], q - nx);
          visit(qj + 1 < hi[1], q + nx);
          visit(qk > lo[2], q - nx * ny);
          visit(qk + 1 < hi[2], q + nx * ny);
        }
      }
    }
  }
}

}  // namespace

double winding_number(const TriangleMesh& mesh, const Eigen::Vector3d& p) {
  double sum = 0.0;
  for (const auto& f : mesh.triangles) {
    sum += solid_angle(p, {mesh.vertices.at(f[0]), mesh.vertices.at(f[1]), mesh.vertices.at(f[2])});
  }
  return sum / (4.0 * kPi);
}

std::vector<double> winding_numbers(const TriangleMesh& mesh,
                                    const std::vector<Eigen::Vector3d>& points) {
  const MeshSolid solid(mesh);
  std::vector<double> w(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) w[i] = solid.winding(points[i]);
  return w;
}

ShapePtr make_mesh_solid(TriangleMesh mesh) {
  // Orientation first: the winding number is signed, and outward_normal() relies on
  // outward triangles too (triangle_mesh.hpp, orient_solid).
  orient_solid(mesh);
  return std::make_shared<MeshSolid>(std::move(mesh));
}

}  // namespace hexcut::geometry
