// Dual contouring on the link grid (Wu 2014, sec. 4.3.2; doc/theory.md, "Surfaces (dual
// contouring)"). The primal grid is the graph of cell centres and links; its dual cells are the
// cubes around lattice vertices, and a face between two cells is the dual of their link. The vertex
// copies already are the material components of each dual cell, so a surface vertex is a vertex
// copy, and a face's quad joins the copies at its 4 lattice vertices.
#include "surface/surface.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <limits>

namespace hexcut::surface {
namespace {

// Singular values of the QEF's matrix below this fraction of the largest are dropped
// (Ju et al. 2002): directions along which the Hermite planes barely constrain the
// vertex (a flat or gently curved patch) keep the mass point's coordinate instead of
// following round-off or curvature to the edge of the dual cell.
constexpr double kTruncation = 0.1;

// One side of a face: the material cell `cell` bounded at its face (axis, step), with the
// face's Hermite data. Both sides of a cut share `face` (and the data).
struct Side {
  std::int32_t cell;
  int axis, step;  // step = +1 or -1: the face's outward direction from this cell
  std::int32_t face;
  std::int32_t cut_id;
  Eigen::Vector3d point, normal;
};

// The 4 corners (hexcut numbering) of a cell's face (axis, step), counter-clockwise seen
// from outside the cell: (0,0), (1,0), (1,1), (0,1) in the face's axes u = axis+1,
// w = axis+2 turn positively about e_u x e_w = e_axis, and are reversed for step < 0.
std::array<int, 4> face_corners(int axis, int step) {
  static constexpr int kUw[4][2] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
  std::array<int, 4> q;
  for (int i = 0; i < 4; ++i) {
    const auto& uw = kUw[step > 0 ? i : 3 - i];
    std::array<int, 3> off;
    off[axis] = step > 0 ? 1 : 0;
    off[(axis + 1) % 3] = uw[0];
    off[(axis + 2) % 3] = uw[1];
    q[i] = off[0] + 2 * off[1] + 4 * off[2];
  }
  return q;
}

// Quadratic error sum_i (n_i . (x - p_i))^2 of one surface vertex, in coordinates
// relative to its lattice vertex (the dual cell's centre) for conditioning.
struct Qef {
  Eigen::Matrix3d ata = Eigen::Matrix3d::Zero();
  Eigen::Vector3d atb = Eigen::Vector3d::Zero();
  Eigen::Vector3d point_sum = Eigen::Vector3d::Zero();
  int count = 0;
  std::int32_t last_face = -1;  // both sides of a cut may reach the same copy: count once

  void add(std::int32_t face, const Eigen::Vector3d& p, const Eigen::Vector3d& n) {
    if (face == last_face) return;
    last_face = face;
    ata += n * n.transpose();
    atb += n * n.dot(p);
    point_sum += p;
    ++count;
  }

  // Minimiser by truncated eigen-decomposition of A^T A (whose eigenvalues are the
  // squared singular values of A), regularised toward the mass point: the minimum-norm
  // correction of the mean of the p_i. Clipped to the dual cell [-half, half]^3.
  Eigen::Vector3d solve(double half) const {
    const Eigen::Vector3d mass = point_sum / count;
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(ata);
    const Eigen::Vector3d& lambda = eig.eigenvalues();  // ascending
    const double cutoff = kTruncation * kTruncation * lambda[2];
    const Eigen::Vector3d residual = atb - ata * mass;
    Eigen::Vector3d x = mass;
    for (int i = 0; i < 3; ++i) {
      if (!(lambda[i] > cutoff) || !(lambda[i] > 0.0)) continue;
      const auto u = eig.eigenvectors().col(i);
      x += u * (u.dot(residual) / lambda[i]);
    }
    return x.cwiseMax(-half).cwiseMin(half);
  }
};

// Every unlinked face of every material cell, one Side per material side: a cut link
// gives two (its data from lattice.cut_links; a link cleared without an entry gets the
// face centre, the axis normal and cut id 0), a face against an empty or outside
// neighbour one (its data from `boundary`, or the face centre and axis normal).
std::vector<Side> collect_sides(const lattice::Lattice& L, const BoundaryHermite* boundary) {
  // (cell, dir) -> first CutLink: a link is cleared once, so later duplicates are stale.
  std::vector<std::pair<std::int64_t, std::int32_t>> cut_of;
  for (std::int32_t i = 0; i < std::int32_t(L.cut_links.size()); ++i)
    cut_of.push_back({3 * std::int64_t(L.cut_links[i].cell) + L.cut_links[i].dir, i});
  std::stable_sort(cut_of.begin(), cut_of.end(),
                   [](const auto& a, const auto& b) { return a.first < b.first; });
  const auto find_cut = [&](std::int32_t c, int dir) -> const lattice::CutLink* {
    const std::int64_t key = 3 * std::int64_t(c) + dir;
    const auto it = std::lower_bound(cut_of.begin(), cut_of.end(), key,
                                     [](const auto& e, std::int64_t k) { return e.first < k; });
    return it != cut_of.end() && it->first == key ? &L.cut_links[it->second] : nullptr;
  };

  const double h = L.spec.h;
  std::vector<Side> sides;
  std::int32_t face = 0;
  for (std::int32_t c = 0; c < L.num_cells(); ++c) {
    const auto& ijk = L.ijk[c];
    const Eigen::Vector3d centre = L.spec.cell_centre(ijk[0], ijk[1], ijk[2]);
    for (int axis = 0; axis < 3; ++axis) {
      const Eigen::Vector3d e = Eigen::Vector3d::Unit(axis);
      for (int step : {-1, 1}) {
        std::array<int, 3> q = ijk;
        q[axis] += step;
        const std::int32_t nb = L.find(q[0], q[1], q[2]);
        if (nb >= 0) {
          // Two material cells: linked, or a cut, which the - cell of the pair emits.
          if (step < 0 || L.linked(c, axis)) continue;
          const lattice::CutLink* cut = find_cut(c, axis);
          const double t = cut ? cut->t : 0.5;
          const Eigen::Vector3d n =
              cut ? Eigen::Vector3d(cut->normal[0], cut->normal[1], cut->normal[2]) : e;
          const Eigen::Vector3d p = centre + t * h * e;
          const std::int32_t id = cut ? cut->cut_id : 0;
          sides.push_back({c, axis, 1, face, id, p, n});
          sides.push_back({nb, axis, -1, face, id, p, n});
        } else {
          const BoundaryCrossing* b =
              boundary ? boundary->find(c, face_index(axis, step > 0)) : nullptr;
          const double t = b ? b->t : 0.5;
          const Eigen::Vector3d n = b ? Eigen::Vector3d(b->normal[0], b->normal[1], b->normal[2])
                                      : Eigen::Vector3d(step * e);
          sides.push_back({c, axis, step, face, 0, centre + step * t * h * e, n});
        }
        ++face;
      }
    }
  }
  return sides;
}

// The cell of copy v's component that the surface vertex at x follows: one whose box
// contains x, else the nearest (by distance to the box); the lowest-numbered on ties.
std::int32_t owning_cell(const lattice::Lattice& L, const topology::VertexCopies& V, std::int32_t v,
                         const Eigen::Vector3d& x) {
  const auto& vertex = V.vertex[v];
  std::int32_t best_cell = -1;
  double best = std::numeric_limits<double>::infinity();
  for (int s = 0; s < 8; ++s) {
    // The cell at vertex - 1 + offset(s) touches the vertex at its corner 7 - s.
    const auto o = topology::corner_offset(s);
    const std::int32_t c = L.find(vertex[0] - 1 + o[0], vertex[1] - 1 + o[1], vertex[2] - 1 + o[2]);
    if (c < 0 || V.cell_corners[c][7 - s] != v) continue;
    const auto& ijk = L.ijk[c];
    const Eigen::Vector3d lo = L.spec.vertex_position(ijk[0], ijk[1], ijk[2]);
    const Eigen::Vector3d hi = lo + Eigen::Vector3d::Constant(L.spec.h);
    const double d = (x - x.cwiseMax(lo).cwiseMin(hi)).squaredNorm();
    if (d < best || (d == best && c < best_cell)) {
      best = d;
      best_cell = c;
    }
  }
  return best_cell;
}

}  // namespace

Surface build_surface(const lattice::Lattice& L, const topology::VertexCopies& V,
                      const BoundaryHermite* boundary) {
  const double h = L.spec.h;
  const std::vector<Side> sides = collect_sides(L, boundary);

  // Surface vertices: the copies some side touches, numbered in copy order.
  std::vector<std::int32_t> vertex_of(V.num_copies, -1);
  for (const auto& s : sides)
    for (int q : face_corners(s.axis, s.step)) vertex_of[V.cell_corners[s.cell][q]] = 0;
  Surface S;
  for (std::int32_t v = 0; v < V.num_copies; ++v) {
    if (vertex_of[v] < 0) continue;
    vertex_of[v] = std::int32_t(S.copy.size());
    S.copy.push_back(v);
  }

  // Each side's Hermite datum enters the QEF of the copies at its 4 corners: those are
  // exactly the components of the dual cells whose edge (the link) the face is dual to.
  std::vector<Qef> qef(S.copy.size());
  const auto lattice_vertex = [&](std::int32_t v) {
    return L.spec.vertex_position(V.vertex[v][0], V.vertex[v][1], V.vertex[v][2]);
  };
  for (const auto& s : sides) {
    for (int q : face_corners(s.axis, s.step)) {
      const std::int32_t v = V.cell_corners[s.cell][q];
      qef[vertex_of[v]].add(s.face, s.point - lattice_vertex(v), s.normal);
    }
  }

  const std::size_t n = S.copy.size();
  S.position.resize(n);
  S.cell.resize(n);
  S.local.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d x = lattice_vertex(S.copy[i]) + qef[i].solve(0.5 * h);
    const std::int32_t c = owning_cell(L, V, S.copy[i], x);
    const auto& ijk = L.ijk[c];
    // Not clamped to [0,1]: a vertex outside its cell extrapolates, which keeps the
    // reference position exact and moves it with the cell's affine part.
    const Eigen::Vector3d local = (x - L.spec.vertex_position(ijk[0], ijk[1], ijk[2])) / h;
    S.position[i] = {x.x(), x.y(), x.z()};
    S.cell[i] = c;
    S.local[i] = {local.x(), local.y(), local.z()};
  }

  // One quad per side, split along its shorter diagonal (the better-shaped pair).
  const auto pos = [&](std::int32_t i) {
    return Eigen::Vector3d(S.position[i][0], S.position[i][1], S.position[i][2]);
  };
  S.triangles.reserve(2 * sides.size());
  S.cut_id.reserve(2 * sides.size());
  for (const auto& s : sides) {
    std::array<std::int32_t, 4> w;
    const auto corners = face_corners(s.axis, s.step);
    for (int i = 0; i < 4; ++i) w[i] = vertex_of[V.cell_corners[s.cell][corners[i]]];
    if ((pos(w[0]) - pos(w[2])).squaredNorm() <= (pos(w[1]) - pos(w[3])).squaredNorm()) {
      S.triangles.push_back({w[0], w[1], w[2]});
      S.triangles.push_back({w[0], w[2], w[3]});
    } else {
      S.triangles.push_back({w[0], w[1], w[3]});
      S.triangles.push_back({w[1], w[2], w[3]});
    }
    S.cut_id.insert(S.cut_id.end(), 2, s.cut_id);
  }
  return S;
}

}  // namespace hexcut::surface
