// Generalized winding number inside test: closed and holed meshes, and the fast
// classify_cells path against brute-force evaluation.
#include <gtest/gtest.h>

#include <cmath>

#include "geometry/triangle_mesh.hpp"
#include "test_util.hpp"

namespace hg = hexcut::geometry;
using Eigen::Vector3d;

namespace {

hexcut::LatticeSpec test_lattice() {
  hexcut::LatticeSpec spec;
  spec.origin = Vector3d(-0.31, -0.29, -0.33);
  spec.h = 0.07;
  spec.dims = {24, 25, 23};
  return spec;
}

// classify_cells over the whole lattice (and over an interior sub-box) must equal
// w >= 0.5 evaluated by brute force, except where w is within 1e-6 of the threshold.
void expect_classify_matches_brute_force(const hg::TriangleMesh& mesh) {
  const auto solid = hg::make_mesh_solid(mesh);
  const auto spec = test_lattice();
  std::vector<std::uint8_t> fast, sub;
  solid->classify_cells(spec, {0, 0, 0}, spec.dims, fast);
  const std::array<int, 3> slo{3, 5, 2}, shi{20, 17, 21};
  solid->classify_cells(spec, slo, shi, sub);
  ASSERT_EQ(fast.size(), std::size_t(spec.num_cells()));
  int inside = 0, mismatches = 0;
  for (int k = 0; k < spec.dims[2]; ++k) {
    for (int j = 0; j < spec.dims[1]; ++j) {
      for (int i = 0; i < spec.dims[0]; ++i) {
        const Vector3d p = spec.cell_centre(i, j, k);
        const double w = hg::winding_number(mesh, p);
        const bool f = fast[spec.cell_index(i, j, k)];
        inside += f;
        if (f != (w >= 0.5) && std::abs(w - 0.5) >= 1e-6) {
          ++mismatches;
          ADD_FAILURE() << "cell " << i << " " << j << " " << k << " w=" << w;
        }
        EXPECT_EQ(solid->contains(p), f) << i << " " << j << " " << k;
        if (i >= slo[0] && i < shi[0] && j >= slo[1] && j < shi[1] && k >= slo[2] && k < shi[2]) {
          const auto s =
              (i - slo[0]) + (shi[0] - slo[0]) * ((j - slo[1]) + (shi[1] - slo[1]) * (k - slo[2]));
          EXPECT_EQ(sub[s], f) << i << " " << j << " " << k;
        }
      }
    }
  }
  EXPECT_EQ(mismatches, 0);
  EXPECT_GT(inside, 0);
}

}  // namespace

TEST(GeometryWinding, ClosedCube) {
  const auto cube = hg::test::cube_mesh(0.0, 1.0);
  EXPECT_NEAR(hg::winding_number(cube, Vector3d(0.5, 0.5, 0.5)), 1.0, 1e-12);
  EXPECT_NEAR(hg::winding_number(cube, Vector3d(0.01, 0.98, 0.3)), 1.0, 1e-12);
  EXPECT_NEAR(hg::winding_number(cube, Vector3d(1.01, 0.5, 0.5)), 0.0, 1e-12);
  EXPECT_NEAR(hg::winding_number(cube, Vector3d(-3, 7, 2)), 0.0, 1e-12);
  const auto solid = hg::make_mesh_solid(cube);
  EXPECT_TRUE(solid->contains(Vector3d(0.5, 0.5, 0.5)));
  EXPECT_TRUE(solid->contains(Vector3d(0.999, 0.001, 0.5)));
  EXPECT_FALSE(solid->contains(Vector3d(1.001, 0.5, 0.5)));
  EXPECT_FALSE(solid->contains(Vector3d(0.5, -0.2, 0.5)));
  EXPECT_FALSE(solid->contains(Vector3d(10, 10, 10)));
  EXPECT_EQ(solid->bounds().lo, Vector3d::Zero());
  EXPECT_EQ(solid->bounds().hi, Vector3d::Ones());
}

TEST(GeometryWinding, CubeWithOneTriangleRemoved) {
  auto cube = hg::test::cube_mesh(0.0, 1.0);
  cube.triangles.erase(cube.triangles.begin() + 3);
  // The centre sees each face at 4π/6; half a face is missing.
  EXPECT_NEAR(hg::winding_number(cube, Vector3d(0.5, 0.5, 0.5)), 1.0 - 1.0 / 12.0, 1e-12);
  const auto solid = hg::make_mesh_solid(cube);
  EXPECT_TRUE(solid->contains(Vector3d(0.5, 0.5, 0.5)));
  EXPECT_TRUE(solid->contains(Vector3d(0.2, 0.7, 0.4)));
  EXPECT_FALSE(solid->contains(Vector3d(5, 0.5, 0.5)));
  EXPECT_FALSE(solid->contains(Vector3d(0.5, 0.5, -4)));
  EXPECT_FALSE(solid->contains(Vector3d(0.5, 0.5, 8)));
  expect_classify_matches_brute_force(cube);
}

TEST(GeometryWinding, ClosedTessellatedCubeClassifiesExactly) {
  const auto cube = hg::test::tessellated_cube(8);
  EXPECT_NEAR(hg::enclosed_volume(cube), 1.0, 1e-12);
  expect_classify_matches_brute_force(cube);
  // All cells with centre strictly inside [0,1]^3 and no others.
  const auto spec = test_lattice();
  std::vector<std::uint8_t> in;
  hg::make_mesh_solid(cube)->classify_cells(spec, {0, 0, 0}, spec.dims, in);
  for (int k = 0; k < spec.dims[2]; ++k) {
    for (int j = 0; j < spec.dims[1]; ++j) {
      for (int i = 0; i < spec.dims[0]; ++i) {
        const Vector3d p = spec.cell_centre(i, j, k);
        const bool expected = (p.array() > 0.0).all() && (p.array() < 1.0).all();
        ASSERT_EQ(bool(in[spec.cell_index(i, j, k)]), expected) << i << " " << j << " " << k;
      }
    }
  }
}

TEST(GeometryWinding, HolesInTessellatedCube) {
  // A 3x3-quad hole in one face, and separately a whole face removed (an open box).
  const int n = 8;
  auto holed = hg::test::tessellated_cube(n);
  auto open_box = holed;
  // Face (a=0, side=0) holds triangles [0, 2n^2); quad (u,v) is triangles 2(u+nv), +1.
  std::vector<std::array<int, 3>> kept;
  for (std::size_t t = 0; t < holed.triangles.size(); ++t) {
    const int quad = static_cast<int>(t / 2);
    const int u = quad % n, v = quad / n;
    const bool in_hole = quad < n * n && u >= 3 && u < 6 && v >= 2 && v < 5;
    if (!in_hole) kept.push_back(holed.triangles[t]);
  }
  holed.triangles = kept;
  EXPECT_EQ(holed.triangles.size(), std::size_t(12 * n * n - 18));
  open_box.triangles.erase(open_box.triangles.begin(), open_box.triangles.begin() + 2 * n * n);

  EXPECT_TRUE(hg::make_mesh_solid(holed)->contains(Vector3d(0.5, 0.5, 0.5)));
  expect_classify_matches_brute_force(holed);
  expect_classify_matches_brute_force(open_box);
}

TEST(GeometryWinding, InvalidMesh) {
  EXPECT_THROW(hg::make_mesh_solid(hg::TriangleMesh{}), std::invalid_argument);
  auto cube = hg::test::cube_mesh(0, 1);
  cube.triangles[4][1] = 8;
  EXPECT_THROW(hg::make_mesh_solid(cube), std::invalid_argument);
}
