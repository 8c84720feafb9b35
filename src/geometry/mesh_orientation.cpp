// Orientation of a triangle mesh that bounds a solid (doc/theory.md, "Triangle-mesh
// solids"). The generalized winding number is signed: a reversed triangle subtracts its
// solid angle instead of adding it, so an inside-out cube has w = -1 inside, and a cube
// with one face f reversed has w = 1 - 2 Ω_f/4π inside (2/3 at the centre, below 1/2 near
// f) and up to 1 just outside f. Files get orientation wrong often (exporters,
// hand-written OBJ, STL whose normals disagree with the vertex order), so every solid is
// oriented here before it is used:
//  1. consistent orientation within each edge-connected piece (breadth-first search over
//     edges shared by exactly two triangles, which must run in opposite directions);
//  2. the sign of each piece by its signed volume (divergence theorem) about its area
//     centroid, which makes every closed piece outward; flat pieces bound nothing;
//  3. nesting: a piece inside an odd number of other pieces is a cavity and turns inward,
//     so an outer and an inner shell bound a hollow body (w = 1 - 1 = 0 in the cavity);
//  4. coincident copies of a triangle follow it.
// Sorting dominates: O(n log n) for n triangles.
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <numeric>
#include <stdexcept>
#include <string>
#include <tuple>
#include <utility>

#include "geometry/triangle_mesh.hpp"

namespace hexcut::geometry {
namespace {

// A piece whose |signed volume| is below this times its area^1.5 is a flat sheet. A
// closed plate of thickness t and side L has volume/area^1.5 ~ t/(2.8 L), so only plates
// thinner than ~1e-7 of their size count as sheets; round-off on a flat sheet of 10^6
// triangles stays below ~1e-10.
constexpr double kSheetVolume = 1e-8;
// Sample points per piece for the nesting test, and the winding numbers that count as
// clearly inside / clearly outside the other piece.
constexpr int kSamples = 32;
constexpr double kInside = 0.75, kOutside = 0.25;

std::string point_text(const Eigen::Vector3d& p) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "(%.6g, %.6g, %.6g)", p.x(), p.y(), p.z());
  return buf;
}

// Index of the first vertex at each vertex's position (equal coordinates).
std::vector<int> weld_positions(const std::vector<Eigen::Vector3d>& v) {
  const int nv = static_cast<int>(v.size());
  std::vector<int> order(nv);
  std::iota(order.begin(), order.end(), 0);
  const auto less = [&](int a, int b) {
    if (v[a].x() != v[b].x()) return v[a].x() < v[b].x();
    if (v[a].y() != v[b].y()) return v[a].y() < v[b].y();
    if (v[a].z() != v[b].z()) return v[a].z() < v[b].z();
    return a < b;
  };
  std::sort(order.begin(), order.end(), less);
  std::vector<int> canon(nv);
  for (int i = 0; i < nv; ++i) {
    const int a = order[i];
    canon[a] = (i > 0 && v[order[i - 1]] == v[a]) ? canon[order[i - 1]] : a;
  }
  return canon;
}

// Median-split tree over boxes, to find the boxes that contain a given box.
class BoxTree {
 public:
  explicit BoxTree(const std::vector<Eigen::AlignedBox3d>& boxes) : boxes_(boxes) {
    order_.resize(boxes.size());
    std::iota(order_.begin(), order_.end(), 0);
    if (!boxes.empty()) build(0, static_cast<int>(boxes.size()));
  }

  // Calls f(i) for every box i that contains `q`.
  template <class F>
  void containing(const Eigen::AlignedBox3d& q, F&& f) const {
    if (nodes_.empty()) return;
    std::vector<int> stack{0};
    while (!stack.empty()) {
      const Node& n = nodes_[stack.back()];
      stack.pop_back();
      if (!n.box.contains(q)) continue;
      if (n.left < 0) {
        for (int k = n.begin; k < n.end; ++k) {
          if (boxes_[order_[k]].contains(q)) f(order_[k]);
        }
      } else {
        stack.push_back(n.left);
        stack.push_back(n.right);
      }
    }
  }

 private:
  struct Node {
    Eigen::AlignedBox3d box;
    int left = -1, right = -1, begin = 0, end = 0;
  };

  int build(int begin, int end) {
    const int id = static_cast<int>(nodes_.size());
    nodes_.emplace_back();
    Node n;
    n.begin = begin;
    n.end = end;
    Eigen::AlignedBox3d centres;
    for (int k = begin; k < end; ++k) {
      n.box.extend(boxes_[order_[k]]);
      centres.extend(boxes_[order_[k]].center());
    }
    int axis = 0;
    centres.sizes().maxCoeff(&axis);
    if (end - begin > 4 && centres.sizes()[axis] > 0.0) {
      const int mid = begin + (end - begin) / 2;
      std::nth_element(
          order_.begin() + begin, order_.begin() + mid, order_.begin() + end,
          [&](int a, int b) { return boxes_[a].center()[axis] < boxes_[b].center()[axis]; });
      n.left = build(begin, mid);
      n.right = build(mid, end);
    }
    nodes_[id] = n;
    return id;
  }

  const std::vector<Eigen::AlignedBox3d>& boxes_;
  std::vector<int> order_;
  std::vector<Node> nodes_;
};

// Coincident triangles (the same three positions): rep[t] is the first of t's group
// (t itself for the first), or -1 for a triangle with two corners at one position;
// same[t] says whether t runs round its corners in the same cyclic order as rep[t].
struct Copies {
  std::vector<int> rep;
  std::vector<std::uint8_t> same;
};

Copies find_copies(const std::vector<std::array<int, 3>>& tris, const std::vector<int>& canon) {
  const int nt = static_cast<int>(tris.size());
  Copies out{std::vector<int>(nt, -1), std::vector<std::uint8_t>(nt, 1)};
  std::vector<std::pair<std::array<int, 3>, int>> keyed;
  keyed.reserve(nt);
  for (int t = 0; t < nt; ++t) {
    std::array<int, 3> c = {canon[tris[t][0]], canon[tris[t][1]], canon[tris[t][2]]};
    if (c[0] == c[1] || c[1] == c[2] || c[2] == c[0]) continue;
    std::sort(c.begin(), c.end());
    keyed.emplace_back(c, t);
  }
  std::sort(keyed.begin(), keyed.end());
  // Cyclic order of the welded corners as +1 / -1 (an even or odd permutation of sorted).
  const auto parity = [&](int t) {
    const int a = canon[tris[t][0]], b = canon[tris[t][1]], c = canon[tris[t][2]];
    return ((a < b) + (b < c) + (c < a)) == 2 ? 1 : -1;
  };
  for (std::size_t i = 0; i < keyed.size();) {
    std::size_t j = i;
    const int r = keyed[i].second;
    for (; j < keyed.size() && keyed[j].first == keyed[i].first; ++j) {
      out.rep[keyed[j].second] = r;
      out.same[keyed[j].second] = parity(keyed[j].second) == parity(r);
    }
    i = j;
  }
  return out;
}

// Directed edges of the triangles that take part (first of each coincident group),
// sorted so that the triangles on one edge are adjacent: edge g is half[begin[g]] to
// half[begin[g + 1] - 1].
struct Edges {
  struct Half {
    int lo, hi;    // welded end points, lo < hi
    int tri;       // triangle
    bool forward;  // runs lo -> hi in the triangle as given
  };
  std::vector<Half> half;
  std::vector<int> begin;
  int count() const { return static_cast<int>(begin.size()) - 1; }
  int size(int g) const { return begin[g + 1] - begin[g]; }
};

Edges find_edges(const std::vector<std::array<int, 3>>& tris, const std::vector<int>& canon,
                 const Copies& copies) {
  Edges edges;
  edges.half.reserve(3 * tris.size());
  for (int t = 0; t < static_cast<int>(tris.size()); ++t) {
    if (copies.rep[t] != t) continue;
    for (int e = 0; e < 3; ++e) {
      const int a = canon[tris[t][e]], b = canon[tris[t][(e + 1) % 3]];
      edges.half.push_back({std::min(a, b), std::max(a, b), t, a < b});
    }
  }
  auto& half = edges.half;
  std::sort(half.begin(), half.end(), [](const Edges::Half& x, const Edges::Half& y) {
    return std::tie(x.lo, x.hi, x.tri) < std::tie(y.lo, y.hi, y.tri);
  });
  for (std::size_t i = 0; i < half.size(); ++i) {
    if (i == 0 || half[i].lo != half[i - 1].lo || half[i].hi != half[i - 1].hi) {
      edges.begin.push_back(static_cast<int>(i));
    }
  }
  edges.begin.push_back(static_cast<int>(half.size()));
  return edges;
}

// Triangles grouped into pieces: piece[t] (-1 for triangles that take no part) and the
// triangles of piece p, tris[begin[p]] to tris[begin[p + 1] - 1], in triangle order.
struct Pieces {
  std::vector<int> piece, begin, tris;
  int count() const { return static_cast<int>(begin.size()) - 1; }
};

std::string edge_text(const TriangleMesh& mesh, int a, int b) {
  return point_text(mesh.vertices[a]) + " - " + point_text(mesh.vertices[b]);
}

// Step 1: pieces through edges of exactly two triangles, and reversed[t] for each
// triangle t so that the two run every such edge in opposite directions. Throws
// std::invalid_argument when a piece is one-sided.
Pieces orient_pieces(const TriangleMesh& mesh, const std::vector<int>& canon, const Copies& copies,
                     const Edges& edges, std::vector<std::uint8_t>& reversed) {
  const int nt = static_cast<int>(mesh.triangles.size());
  struct Link {
    int tri;
    bool same;  // both triangles run the edge the same way, as given
  };
  std::vector<int> link_begin(nt + 1, 0);
  for (int g = 0; g < edges.count(); ++g) {
    if (edges.size(g) != 2) continue;
    ++link_begin[edges.half[edges.begin[g]].tri + 1];
    ++link_begin[edges.half[edges.begin[g] + 1].tri + 1];
  }
  std::partial_sum(link_begin.begin(), link_begin.end(), link_begin.begin());
  std::vector<Link> links(link_begin[nt]);
  std::vector<int> fill(link_begin.begin(), link_begin.end() - 1);
  for (int g = 0; g < edges.count(); ++g) {
    if (edges.size(g) != 2) continue;
    const auto &x = edges.half[edges.begin[g]], &y = edges.half[edges.begin[g] + 1];
    links[fill[x.tri]++] = {y.tri, x.forward == y.forward};
    links[fill[y.tri]++] = {x.tri, x.forward == y.forward};
  }

  Pieces pieces;
  pieces.piece.assign(nt, -1);
  reversed.assign(nt, 0);
  int count = 0;
  std::vector<int> queue;
  for (int t0 = 0; t0 < nt; ++t0) {
    if (copies.rep[t0] != t0 || pieces.piece[t0] >= 0) continue;
    const int id = count++;
    pieces.piece[t0] = id;
    queue.assign(1, t0);
    for (std::size_t q = 0; q < queue.size(); ++q) {
      const int t = queue[q];
      for (int k = link_begin[t]; k < link_begin[t + 1]; ++k) {
        const auto [u, same] = links[k];
        const std::uint8_t want = reversed[t] ^ std::uint8_t(same);
        if (pieces.piece[u] < 0) {
          pieces.piece[u] = id;
          reversed[u] = want;
          queue.push_back(u);
          continue;
        }
        if (reversed[u] == want) continue;
        const auto& ft = mesh.triangles[t];
        const auto& fu = mesh.triangles[u];
        int a = 0, b = 0;  // the shared edge, for the message
        for (int e = 0; e < 3; ++e) {
          const int p = canon[ft[e]], r = canon[ft[(e + 1) % 3]];
          for (int f = 0; f < 3; ++f) {
            const int s = canon[fu[f]], w = canon[fu[(f + 1) % 3]];
            if ((p == s && r == w) || (p == w && r == s)) a = p, b = r;
          }
        }
        throw std::invalid_argument(
            "the mesh cannot be oriented: it is one-sided (like a Moebius strip); going "
            "round it reverses the side at the edge " +
            edge_text(mesh, a, b));
      }
    }
  }

  pieces.begin.assign(count + 1, 0);
  for (int t = 0; t < nt; ++t) {
    if (pieces.piece[t] >= 0) ++pieces.begin[pieces.piece[t] + 1];
  }
  std::partial_sum(pieces.begin.begin(), pieces.begin.end(), pieces.begin.begin());
  pieces.tris.resize(pieces.begin[count]);
  fill.assign(pieces.begin.begin(), pieces.begin.end() - 1);
  for (int t = 0; t < nt; ++t) {
    if (pieces.piece[t] >= 0) pieces.tris[fill[pieces.piece[t]]++] = t;
  }
  return pieces;
}

// A twist can also pass through an edge of three or more triangles, which step 1 does
// not cross: a piece with exactly two triangles on such an edge must run it in opposite
// directions too. Throws std::invalid_argument otherwise.
void check_nonmanifold_edges(const TriangleMesh& mesh, const Edges& edges, const Pieces& pieces,
                             const std::vector<std::uint8_t>& reversed) {
  std::vector<std::pair<int, int>> runs;  // (piece, +1 forward / -1 backward)
  for (int g = 0; g < edges.count(); ++g) {
    if (edges.size(g) < 3) continue;
    runs.clear();
    for (int i = edges.begin[g]; i < edges.begin[g + 1]; ++i) {
      const auto& h = edges.half[i];
      runs.emplace_back(pieces.piece[h.tri], h.forward != bool(reversed[h.tri]) ? 1 : -1);
    }
    std::sort(runs.begin(), runs.end());
    for (std::size_t i = 0; i < runs.size();) {
      std::size_t j = i;
      int net = 0;
      for (; j < runs.size() && runs[j].first == runs[i].first; ++j) net += runs[j].second;
      if (j - i == 2 && net != 0) {
        const auto& h = edges.half[edges.begin[g]];
        throw std::invalid_argument(
            "the mesh cannot be oriented: at the edge " + edge_text(mesh, h.lo, h.hi) +
            ", shared by " + std::to_string(edges.size(g)) +
            " triangles, the two triangles of one connected piece run the edge the same way "
            "however the piece is turned (a one-sided surface)");
      }
      i = j;
    }
  }
}

// Step 3: for each piece of `solids` (outward, volume[p] > 0), the number of solids it
// lies inside: the other's box contains its box, the other's volume is larger, and at
// up to kSamples triangle centroids of the piece the other's winding number is > kInside
// at more than half and < kOutside at none.
std::vector<int> nesting_depth(const TriangleMesh& mesh, const Pieces& pieces,
                               const std::vector<int>& solids, const std::vector<double>& volume,
                               const std::vector<Eigen::AlignedBox3d>& box) {
  const auto& tris = mesh.triangles;
  const auto centroid = [&](int t) {
    return (mesh.vertices[tris[t][0]] + mesh.vertices[tris[t][1]] + mesh.vertices[tris[t][2]]) /
           3.0;
  };
  std::vector<Eigen::AlignedBox3d> solid_box;
  for (int p : solids) solid_box.push_back(box[p]);
  const BoxTree tree(solid_box);
  std::vector<std::pair<int, int>> candidates;  // (container, piece)
  for (int p : solids) {
    tree.containing(box[p], [&](int k) {
      const int b = solids[k];
      if (b != p && volume[b] > volume[p]) candidates.emplace_back(b, p);
    });
  }
  std::sort(candidates.begin(), candidates.end());

  std::vector<int> depth(pieces.count(), 0);
  std::vector<int> local(mesh.vertices.size(), -1);
  for (std::size_t i = 0; i < candidates.size();) {
    // All pieces that may lie in container b: their samples, then b's winding number.
    const int b = candidates[i].first;
    std::size_t j = i;
    std::vector<Eigen::Vector3d> points;
    std::vector<std::size_t> first;  // first sample of each candidate in `points`
    for (; j < candidates.size() && candidates[j].first == b; ++j) {
      const int p = candidates[j].second;
      first.push_back(points.size());
      const int n = pieces.begin[p + 1] - pieces.begin[p];
      const int s = std::min(n, kSamples);
      for (int k = 0; k < s; ++k) {
        points.push_back(centroid(pieces.tris[pieces.begin[p] + int((k + 0.5) * n / s)]));
      }
    }
    first.push_back(points.size());
    TriangleMesh container;
    for (int k = pieces.begin[b]; k < pieces.begin[b + 1]; ++k) {
      std::array<int, 3> f;
      for (int c = 0; c < 3; ++c) {
        const int v = tris[pieces.tris[k]][c];
        if (local[v] < 0) {
          local[v] = static_cast<int>(container.vertices.size());
          container.vertices.push_back(mesh.vertices[v]);
        }
        f[c] = local[v];
      }
      container.triangles.push_back(f);
    }
    for (int k = pieces.begin[b]; k < pieces.begin[b + 1]; ++k) {
      for (int v : tris[pieces.tris[k]]) local[v] = -1;
    }
    const std::vector<double> w = winding_numbers(container, points);
    for (std::size_t c = 0; c + i < j; ++c) {
      int in = 0, out = 0;
      for (std::size_t s = first[c]; s < first[c + 1]; ++s) {
        in += w[s] > kInside;
        out += w[s] < kOutside;
      }
      const auto n = static_cast<int>(first[c + 1] - first[c]);
      if (out == 0 && 2 * in > n) ++depth[candidates[i + c].second];
    }
    i = j;
  }
  return depth;
}

}  // namespace

SolidOrientation orient_solid(TriangleMesh& mesh) {
  check_mesh_indices(mesh);
  auto& tris = mesh.triangles;
  const int nt = static_cast<int>(tris.size());
  const std::vector<int> canon = weld_positions(mesh.vertices);
  const Copies copies = find_copies(tris, canon);
  const Edges edges = find_edges(tris, canon, copies);

  // 1. Consistent orientation within each piece.
  std::vector<std::uint8_t> reversed;
  const Pieces pieces = orient_pieces(mesh, canon, copies, edges, reversed);
  check_nonmanifold_edges(mesh, edges, pieces, reversed);
  for (int t = 0; t < nt; ++t) {
    if (reversed[t]) std::swap(tris[t][1], tris[t][2]);
  }
  const int np = pieces.count();
  const auto corner = [&](int t, int k) -> const Eigen::Vector3d& {
    return mesh.vertices[tris[t][k]];
  };
  const auto turn_piece = [&](int p) {
    for (int k = pieces.begin[p]; k < pieces.begin[p + 1]; ++k) {
      const int t = pieces.tris[k];
      std::swap(tris[t][1], tris[t][2]);
      reversed[t] ^= 1;
    }
  };

  // 2. Signed volume of each piece about its area centroid (the centroid keeps a flat
  // sheet at volume 0 and makes the volume of a piece with a hole depend little on the
  // reference point; that of a closed piece does not depend on it at all).
  enum class Kind : std::uint8_t { solid, sheet, wall };
  std::vector<Kind> kind(np, Kind::solid);
  std::vector<double> volume(np, 0.0);
  std::vector<Eigen::AlignedBox3d> box(np);
  for (int p = 0; p < np; ++p) {
    double area = 0.0;
    Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
    for (int k = pieces.begin[p]; k < pieces.begin[p + 1]; ++k) {
      const int t = pieces.tris[k];
      const double a =
          0.5 * (corner(t, 1) - corner(t, 0)).cross(corner(t, 2) - corner(t, 0)).norm();
      area += a;
      centroid += a / 3.0 * (corner(t, 0) + corner(t, 1) + corner(t, 2));
      for (int c = 0; c < 3; ++c) box[p].extend(corner(t, c));
    }
    if (area > 0.0) {
      centroid /= area;
      double six_v = 0.0;
      for (int k = pieces.begin[p]; k < pieces.begin[p + 1]; ++k) {
        const int t = pieces.tris[k];
        const Eigen::Vector3d a = corner(t, 0) - centroid, b = corner(t, 1) - centroid,
                              c = corner(t, 2) - centroid;
        six_v += a.dot(b.cross(c));
      }
      volume[p] = six_v / 6.0;
    }
    if (!(std::abs(volume[p]) > kSheetVolume * area * std::sqrt(area))) {
      kind[p] = Kind::sheet;
    } else if (volume[p] < 0.0) {
      turn_piece(p);
      volume[p] = -volume[p];
    }
  }
  // A flat piece whose every edge is inside it or shared by three or more triangles is
  // a wall between two parts of the body (two boxes side by side, each closed by the
  // face they share): it bounds nothing, and left in, its sign, which nothing decides,
  // would add or take up to 1/2 next to it. Walls are left out. A sheet, with a free
  // edge (of one triangle), adds less than 1/2 anywhere off it: alone it moves no point
  // across 1/2, and it stays as given.
  std::vector<std::uint8_t> free_edge(np, 0);
  for (int g = 0; g < edges.count(); ++g) {
    if (edges.size(g) == 1) free_edge[pieces.piece[edges.half[edges.begin[g]].tri]] = 1;
  }
  for (int p = 0; p < np; ++p) {
    if (kind[p] == Kind::sheet && !free_edge[p]) kind[p] = Kind::wall;
  }

  // 3. Nesting: a solid piece inside an odd number of others is a cavity.
  SolidOrientation report;
  report.pieces = np;
  std::vector<int> solids;
  for (int p = 0; p < np; ++p) {
    if (kind[p] == Kind::solid) solids.push_back(p);
  }
  const std::vector<int> depth = nesting_depth(mesh, pieces, solids, volume, box);
  for (int p : solids) {
    if (depth[p] % 2 == 1) {
      turn_piece(p);
      ++report.cavities;
    }
  }

  // 4. Copies of a triangle of a solid piece run like it (a face or a shell given twice
  // counts twice, like two overlapping bodies); copies of a sheet's triangle alternate,
  // so that they cancel in pairs (a sheet bounds nothing); walls go with their copies.
  std::vector<int> seen(nt, 0);  // copies met so far, per first triangle
  std::vector<std::uint8_t> keep(nt, 1);
  for (int t = 0; t < nt; ++t) {
    const int r = copies.rep[t];
    if (r < 0) continue;
    const Kind k = kind[pieces.piece[r]];
    if (k == Kind::wall) {
      keep[t] = 0;
      continue;
    }
    if (r == t) continue;
    const bool opposite = k == Kind::sheet && ++seen[r] % 2 == 1;
    // Reversed when its cyclic order, as given, differs from r's now (or should not).
    if (reversed[r] ^ std::uint8_t(!copies.same[t]) ^ std::uint8_t(opposite)) {
      std::swap(tris[t][1], tris[t][2]);
      reversed[t] = 1;
    }
  }
  for (int p = 0; p < np; ++p) {
    report.sheets += kind[p] == Kind::sheet;
    report.walls += kind[p] == Kind::wall;
  }
  std::size_t kept = 0;
  for (int t = 0; t < nt; ++t) {
    if (!keep[t]) continue;
    report.flipped += reversed[t];
    tris[kept++] = tris[t];
  }
  report.removed = nt - static_cast<int>(kept);
  tris.resize(kept);
  return report;
}

}  // namespace hexcut::geometry
