// The Stanford bunny (input/meshes/bunny.obj): a real scanned closed mesh.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>

#include "geometry/triangle_mesh.hpp"
#include "geometry/voxelize.hpp"

namespace hg = hexcut::geometry;
using Eigen::Vector3d;

namespace {

// Lattice of edge h over the mesh bounds plus a margin of two cells, with an origin
// offset so no cell centre lines up with mesh vertices by accident.
hexcut::LatticeSpec lattice_around(const hg::Aabb& b, double h) {
  hexcut::LatticeSpec spec;
  spec.h = h;
  spec.origin = b.lo - Vector3d(2.013, 1.987, 2.031) * h;
  for (int a = 0; a < 3; ++a) {
    spec.dims[a] = static_cast<int>(std::ceil((b.hi[a] - spec.origin[a]) / h)) + 2;
  }
  return spec;
}

const hg::TriangleMesh& bunny() {
  static const hg::TriangleMesh mesh = hg::load_triangle_mesh(HEXCUT_BUNNY_OBJ);
  return mesh;
}

}  // namespace

TEST(GeometryBunny, Loads) {
  EXPECT_EQ(bunny().vertices.size(), 1839u);
  EXPECT_EQ(bunny().triangles.size(), 3674u);
  const auto b = hg::bounds(bunny());
  EXPECT_NEAR(b.lo.y(), 0.0, 0.01);
  EXPECT_NEAR(b.hi.y(), 9.65, 0.01);
  EXPECT_GT(hg::enclosed_volume(bunny()), 0.0);
}

TEST(GeometryBunny, VoxelVolumeMatchesEnclosedVolume) {
  const double h = 0.1;
  const auto solid = hg::make_mesh_solid(bunny());
  hg::VoxelGrid grid = hg::make_empty_grid(lattice_around(solid->bounds(), h));
  hg::apply(grid, {hg::OpMode::add, solid, 0});
  const double voxel_volume = double(hg::count_filled(grid)) * h * h * h;
  const double mesh_volume = hg::enclosed_volume(bunny());
  std::printf("bunny: enclosed volume %.4f, voxel volume %.4f (h = %g)\n", mesh_volume,
              voxel_volume, h);
  EXPECT_NEAR(voxel_volume / mesh_volume, 1.0, 0.02);
}

TEST(GeometryBunny, FastClassifyEqualsBruteForce) {
  const auto solid = hg::make_mesh_solid(bunny());
  const auto spec = lattice_around(solid->bounds(), 0.45);
  std::vector<std::uint8_t> fast;
  solid->classify_cells(spec, {0, 0, 0}, spec.dims, fast);
  int inside = 0, mismatches = 0;
  for (int k = 0; k < spec.dims[2]; ++k) {
    for (int j = 0; j < spec.dims[1]; ++j) {
      for (int i = 0; i < spec.dims[0]; ++i) {
        const Vector3d p = spec.cell_centre(i, j, k);
        const double w = hg::winding_number(bunny(), p);
        const bool f = fast[spec.cell_index(i, j, k)];
        inside += f;
        // Near w = 0.5 round-off may decide either way; elsewhere the fast cell path
        // and the hierarchical point query must both agree with brute force.
        if (std::abs(w - 0.5) < 1e-6) continue;
        if (f != (w >= 0.5)) ++mismatches;
        EXPECT_EQ(solid->contains(p), w >= 0.5) << "w = " << w;
      }
    }
  }
  EXPECT_EQ(mismatches, 0);
  EXPECT_GT(inside, 100);
}

TEST(GeometryBunny, MillionCellTiming) {
  const auto t0 = std::chrono::steady_clock::now();
  const auto solid = hg::make_mesh_solid(bunny());
  const auto b = solid->bounds();
  const double h = std::cbrt((b.hi - b.lo).prod() / 1.0e6);
  hg::VoxelGrid grid = hg::make_empty_grid(lattice_around(b, h));
  hg::apply(grid, {hg::OpMode::add, solid, 0});
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const double volume = double(hg::count_filled(grid)) * h * h * h;
  std::printf("bunny: %lld cells (h = %.4f), %lld filled, voxelized in %.3f s\n",
              static_cast<long long>(grid.spec.num_cells()), h,
              static_cast<long long>(hg::count_filled(grid)), seconds);
  EXPECT_NEAR(volume / hg::enclosed_volume(bunny()), 1.0, 0.02);
#ifdef NDEBUG
  EXPECT_LT(seconds, 10.0);
#endif
}

TEST(GeometryBunny, OrientationLeavesItAndRestoresIt) {
  // The file is outward and consistent: orientation changes nothing, so the bunny
  // voxelizes exactly as before. Inside-out or with random triangles reversed, it comes
  // back to the file's orientation, triangle by triangle, and to the same cells.
  hg::TriangleMesh m = bunny();
  const auto t0 = std::chrono::steady_clock::now();
  const auto r = hg::orient_solid(m);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::printf("bunny: orient_solid on %zu triangles in %.4f s\n", m.triangles.size(), seconds);
  EXPECT_EQ(r.pieces, 1);
  EXPECT_EQ(r.flipped, 0);
  EXPECT_EQ(r.cavities + r.sheets + r.walls + r.removed, 0);
  EXPECT_EQ(m.triangles, bunny().triangles);

  const auto spec = lattice_around(hg::bounds(bunny()), 0.2);
  const auto cells = [&](const hg::TriangleMesh& mesh) {
    hg::VoxelGrid grid = hg::make_empty_grid(spec);
    hg::apply(grid, {hg::OpMode::add, hg::make_mesh_solid(mesh), 0});
    return grid.material;
  };
  const auto want = cells(bunny());
  hg::TriangleMesh inside_out = bunny();
  for (auto& t : inside_out.triangles) std::swap(t[1], t[2]);
  hg::TriangleMesh mixed = bunny();
  for (std::size_t t = 0; t < mixed.triangles.size(); t += 3) {
    std::swap(mixed.triangles[t][1], mixed.triangles[t][2]);
  }
  EXPECT_TRUE(cells(inside_out) == want);
  EXPECT_TRUE(cells(mixed) == want);
  for (hg::TriangleMesh* mesh : {&inside_out, &mixed}) {
    hg::orient_solid(*mesh);
    EXPECT_EQ(mesh->triangles, bunny().triangles);
  }
}
