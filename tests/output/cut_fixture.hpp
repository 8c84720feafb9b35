// Test data for topology changes: a lattice mesh whose vertex copies can be split along a
// plane (what a cut does to the point table), and closed box surfaces, as full
// (rank-independent) tables plus per-rank slab views. Shared by the serial and 2-rank
// tests and by output_write_result_file --cuts; check_result_file.py --cuts checks files
// written from it without repeating the formulas (it checks geometric invariants).
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "output/result_writer.hpp"

namespace hexcut::output::testing {

/// Vertex (i, j, k) of an nx x ny x nz lattice is row i + (nx+1)(j + (ny+1)k); cell
/// (i, j, k) is row i + nx(j + ny k), corners in VTK_HEXAHEDRON order.
struct FullMesh {
  LatticeSpec lattice;
  std::int64_t num_points = 0;
  std::int64_t num_cells = 0;
  std::vector<double> points;  // num_points x 3
  std::vector<std::int64_t> cells;
  std::vector<std::int32_t> ijk, material;
  std::vector<double> youngs;
};

/// The lattice mesh; with 0 < split_at < nx, the vertices of the plane i = split_at get a
/// second copy (appended rows, in (j, k) order: row num_lattice_vertices + j + (ny+1)k)
/// used by the cells i >= split_at, as after a cut through that plane.
inline FullMesh lattice_mesh(const LatticeSpec& lattice, int split_at = 0) {
  const int nx = lattice.dims[0], ny = lattice.dims[1], nz = lattice.dims[2];
  const std::int64_t nv = std::int64_t(nx + 1) * (ny + 1) * (nz + 1);
  const bool split = split_at > 0 && split_at < nx;
  FullMesh m;
  m.lattice = lattice;
  m.num_points = nv + (split ? std::int64_t(ny + 1) * (nz + 1) : 0);
  m.num_cells = lattice.num_cells();
  for (std::int64_t p = 0; p < m.num_points; ++p) {
    int i = 0, j = 0, k = 0;
    if (p < nv) {
      i = int(p % (nx + 1));
      j = int(p / (nx + 1) % (ny + 1));
      k = int(p / (std::int64_t(nx + 1) * (ny + 1)));
    } else {
      i = split_at;
      j = int((p - nv) % (ny + 1));
      k = int((p - nv) / (ny + 1));
    }
    const auto x = lattice.vertex_position(i, j, k);
    m.points.insert(m.points.end(), {x.x(), x.y(), x.z()});
  }
  const auto vid = [&](int i, int j, int k, int cell_i) {
    if (split && i == split_at && cell_i >= split_at) return nv + j + std::int64_t(ny + 1) * k;
    return std::int64_t(i) + (nx + 1) * (std::int64_t(j) + (ny + 1) * std::int64_t(k));
  };
  for (std::int64_t c = 0; c < m.num_cells; ++c) {
    const int i = int(c % nx), j = int(c / nx % ny), k = int(c / (std::int64_t(nx) * ny));
    m.cells.insert(m.cells.end(),
                   {vid(i, j, k, i), vid(i + 1, j, k, i), vid(i + 1, j + 1, k, i),
                    vid(i, j + 1, k, i), vid(i, j, k + 1, i), vid(i + 1, j, k + 1, i),
                    vid(i + 1, j + 1, k + 1, i), vid(i, j + 1, k + 1, i)});
    m.ijk.insert(m.ijk.end(), {i, j, k});
    m.material.push_back(static_cast<std::int32_t>(c % 2));
    m.youngs.push_back(c % 2 == 0 ? 210e9 : 70e9);
  }
  return m;
}

/// Rows [s.row_offset, s.row_offset + s.local_rows) of a table with `cols` columns.
template <class T>
std::vector<T> rows(const std::vector<T>& table, const Slab& s, int cols) {
  return std::vector<T>(table.begin() + s.row_offset * cols,
                        table.begin() + (s.row_offset + s.local_rows) * cols);
}

/// This rank's slabs of a FullMesh, as MeshData (owns the slab copies).
struct MeshSlices {
  std::vector<double> points, youngs;
  std::vector<std::int64_t> cells;
  std::vector<std::int32_t> ijk, material;
  MeshData data;
  MeshSlices(const FullMesh& m, Slab p, Slab c) {
    p.global_rows = m.num_points;
    c.global_rows = m.num_cells;
    points = rows(m.points, p, 3);
    cells = rows(m.cells, c, 8);
    ijk = rows(m.ijk, c, 3);
    material = rows(m.material, c, 1);
    youngs = rows(m.youngs, c, 1);
    data.lattice = m.lattice;
    data.points = p;
    data.cells = c;
    data.positions = points.data();
    data.connectivity = cells.data();
    data.lattice_index = ijk.data();
    data.material = material.data();
    data.youngs_modulus = youngs.data();
  }
  MeshSlices(const MeshSlices&) = delete;
  MeshSlices& operator=(const MeshSlices&) = delete;
};

/// A box of whole cells, [i0, i1) x [0, ny) x [0, nz); cut_x_lo/hi: cut_id of its x- / x+
/// faces (every other face has cut_id 0).
struct Box {
  int i0 = 0, i1 = 0;
  std::int32_t cut_x_lo = 0, cut_x_hi = 0;
};

struct FullSurface {
  std::int64_t num_vertices = 0;
  std::int64_t num_triangles = 0;
  std::vector<double> positions;  // deformed: reference + offset
  std::vector<std::int32_t> owner_cell;
  std::vector<std::int64_t> triangles;
  std::vector<std::int32_t> cut_id;
};

/// The closed, outward-oriented surfaces of `boxes` (8 vertices and 12 triangles each),
/// moved by `offset`; each vertex is owned by the box's cell at that corner.
inline FullSurface box_surface(const LatticeSpec& lattice, const std::vector<Box>& boxes,
                               const std::array<double, 3>& offset) {
  const int ny = lattice.dims[1], nz = lattice.dims[2];
  // Corner c: x high when c & 1, y high when c & 2, z high when c & 4. Each face's quad
  // is counter-clockwise seen from outside.
  static const int kQuads[6][4] = {{0, 4, 6, 2}, {1, 3, 7, 5}, {0, 1, 5, 4},
                                   {2, 6, 7, 3}, {0, 2, 3, 1}, {4, 5, 7, 6}};
  FullSurface s;
  for (const Box& b : boxes) {
    const std::int64_t first = s.num_vertices;
    for (int c = 0; c < 8; ++c) {
      const int i = (c & 1) ? b.i1 : b.i0, j = (c & 2) ? ny : 0, k = (c & 4) ? nz : 0;
      const auto x = lattice.vertex_position(i, j, k);
      s.positions.insert(s.positions.end(),
                         {x.x() + offset[0], x.y() + offset[1], x.z() + offset[2]});
      s.owner_cell.push_back(static_cast<std::int32_t>(lattice.cell_index(
          (c & 1) ? b.i1 - 1 : b.i0, (c & 2) ? ny - 1 : 0, (c & 4) ? nz - 1 : 0)));
      ++s.num_vertices;
    }
    for (int f = 0; f < 6; ++f) {
      const int* q = kQuads[f];
      const std::int32_t cut = f == 0 ? b.cut_x_lo : (f == 1 ? b.cut_x_hi : 0);
      const int tri[2][3] = {{q[0], q[1], q[2]}, {q[0], q[2], q[3]}};
      for (const auto& t : tri) {
        s.triangles.insert(s.triangles.end(), {first + t[0], first + t[1], first + t[2]});
        s.cut_id.push_back(cut);
        ++s.num_triangles;
      }
    }
  }
  return s;
}

/// This rank's slabs of a FullSurface, as SurfaceData (owns the slab copies).
struct SurfaceSlices {
  std::vector<double> positions;
  std::vector<std::int32_t> owner_cell, cut_id;
  std::vector<std::int64_t> triangles;
  SurfaceData data;
  SurfaceSlices(const FullSurface& s, Slab v, Slab t) {
    v.global_rows = s.num_vertices;
    t.global_rows = s.num_triangles;
    positions = rows(s.positions, v, 3);
    owner_cell = rows(s.owner_cell, v, 1);
    triangles = rows(s.triangles, t, 3);
    cut_id = rows(s.cut_id, t, 1);
    data.vertices = v;
    data.faces = t;
    data.positions = positions.data();
    data.owner_cell = owner_cell.data();
    data.triangles = triangles.data();
    data.cut_id = cut_id.data();
  }
  SurfaceSlices(const SurfaceSlices&) = delete;
  SurfaceSlices& operator=(const SurfaceSlices&) = delete;
};

/// Even split of `global_rows` over `size` ranks (rank r's slab).
inline Slab even_slab(std::int64_t global_rows, int rank, int size) {
  Slab s;
  s.global_rows = global_rows;
  s.row_offset = global_rows * rank / size;
  s.local_rows = global_rows * (rank + 1) / size - s.row_offset;
  return s;
}

}  // namespace hexcut::output::testing
