// Boundary crossings and outward normals of geometry operation lists (geometry/crossing):
// the Hermite data of the outer surface.
#include "geometry/crossing.hpp"

#include <gtest/gtest.h>

#include <cmath>

#include "geometry/triangle_mesh.hpp"

namespace hexcut::geometry {
namespace {

using V = Eigen::Vector3d;

void expect_near(const V& a, const V& b, double tol) {
  EXPECT_LT((a - b).norm(), tol) << "got (" << a.transpose() << "), want (" << b.transpose() << ")";
}

TEST(Crossing, SphereGivesTheAnalyticPointAndRadialNormal) {
  const V c(0.1, -0.2, 0.3);
  const std::vector<GeometryOp> ops{{OpMode::add, make_sphere(c, 1.0), 0}};
  const V a = c + V(0.5, 0.2, 0.0), b = c + V(1.5, 0.2, 0.0);
  const auto x = find_crossing(ops, a, b);
  ASSERT_TRUE(x);
  // |a + t (b - a) - c| = 1 along x: 0.5 + t = sqrt(1 - 0.04).
  EXPECT_NEAR(x->t, std::sqrt(0.96) - 0.5, 1e-8);
  const V p = a + x->t * (b - a);
  expect_near(x->normal, (p - c).normalized(), 1e-8);
  EXPECT_FALSE(find_crossing(ops, b, a));  // "inside" must be inside
  EXPECT_FALSE(find_crossing(ops, a, a));  // and "outside" outside
}

TEST(Crossing, SubtractedShapeGivesTheReversedNormal) {
  // A box with a spherical cavity: leaving the material into the cavity, the body's
  // outward normal points into the cavity, towards the sphere's centre.
  const V c(0.5, 0.5, 0.5);
  const std::vector<GeometryOp> ops{{OpMode::add, make_box(V::Zero(), V::Ones()), 0},
                                    {OpMode::subtract, make_sphere(c, 0.25), 0},
                                    {OpMode::assign, make_sphere(c, 0.4), 1}};  // ignored
  EXPECT_TRUE(inside_after(ops, V(0.5, 0.5, 0.1)));
  EXPECT_FALSE(inside_after(ops, c));
  EXPECT_FALSE(inside_after(ops, V(1.5, 0.5, 0.5)));
  const auto x = find_crossing(ops, V(0.5, 0.5, 0.1), c);
  ASSERT_TRUE(x);
  EXPECT_NEAR(x->t, 0.15 / 0.4, 1e-8);
  expect_near(x->normal, V(0, 0, 1), 1e-8);
  // Leaving through the box's face instead: the box's normal.
  const auto y = find_crossing(ops, V(0.9, 0.2, 0.5), V(1.2, 0.2, 0.5));
  ASSERT_TRUE(y);
  EXPECT_NEAR(y->t, 1.0 / 3.0, 1e-8);
  expect_near(y->normal, V(1, 0, 0), 1e-12);
}

TEST(Crossing, UnionUsesTheShapeThatIsLeft) {
  // A box and a later, overlapping sphere: from inside the sphere's part outwards the
  // sphere's surface is crossed, even though the box was added first.
  const std::vector<GeometryOp> ops{{OpMode::add, make_box(V::Zero(), V::Ones()), 0},
                                    {OpMode::add, make_sphere(V(1, 0.5, 0.5), 0.3), 0}};
  const auto x = find_crossing(ops, V(1.1, 0.5, 0.5), V(1.5, 0.5, 0.5));
  ASSERT_TRUE(x);
  EXPECT_NEAR(x->t, 0.2 / 0.4, 1e-8);
  expect_near(x->normal, V(1, 0, 0), 1e-8);
}

TEST(Crossing, PrimitiveNormals) {
  const auto cyl = make_cylinder(V(0, 0, 0), V(0, 0, 2), 0.5);
  expect_near(cyl->outward_normal(V(0.3, 0.4, 1.0)), V(0.6, 0.8, 0), 1e-12);  // mantle
  expect_near(cyl->outward_normal(V(0.1, 0.0, 1.95)), V(0, 0, 1), 1e-12);     // near top cap
  expect_near(cyl->outward_normal(V(0.1, 0.0, -0.1)), V(0, 0, -1), 1e-12);    // below bottom
  expect_near(cyl->outward_normal(V(0.6, 0.0, 2.1)), V(1, 0, 1).normalized(), 1e-12);  // rim
  const auto box = make_box(V::Zero(), V(2, 1, 1));
  expect_near(box->outward_normal(V(1.0, 0.5, 0.95)), V(0, 0, 1), 1e-12);
  expect_near(box->outward_normal(V(2.1, 1.1, 0.5)), V(1, 1, 0).normalized(), 1e-12);
  expect_near(make_half_space(V::Zero(), V(0, 2, 0))->outward_normal(V(5, 5, 5)), V(0, 1, 0),
              1e-12);
  const auto slab = make_slab(V::Zero(), V(0, 0, 1), 0.1);
  expect_near(slab->outward_normal(V(0, 0, -0.09)), V(0, 0, -1), 1e-12);
}

/// The unit cube as 12 outward triangles (each face split along a diagonal).
TriangleMesh cube_mesh() {
  TriangleMesh m;
  for (int v = 0; v < 8; ++v) m.vertices.emplace_back(v & 1, (v >> 1) & 1, (v >> 2) & 1);
  const int quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                           {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& q : quads) {
    m.triangles.push_back({q[0], q[1], q[2]});
    m.triangles.push_back({q[0], q[2], q[3]});
  }
  return m;
}

TEST(Crossing, MeshUsesTheNearestTriangleNormal) {
  const std::vector<GeometryOp> ops{{OpMode::add, make_mesh_solid(cube_mesh()), 0}};
  const auto x = find_crossing(ops, V(0.5, 0.3, 0.6), V(0.5, 1.3, 0.6));
  ASSERT_TRUE(x);
  EXPECT_NEAR(x->t, 0.7, 1e-8);
  expect_near(x->normal, V(0, 1, 0), 1e-12);
}

TEST(Crossing, MeshCrossingIsTheExactSegmentTriangleIntersection) {
  const auto cube = make_mesh_solid(cube_mesh());
  // One face crossed: its parameter, exactly.
  const auto s = cube->surface_crossing(V(0.5, 0.3, 0.6), V(0.5, 1.3, 0.6));
  ASSERT_TRUE(s);
  EXPECT_NEAR(*s, 0.7, 1e-15);
  // Two faces, none, or a point on the diagonal two triangles share: no single answer.
  EXPECT_FALSE(cube->surface_crossing(V(-0.5, 0.3, 0.6), V(1.5, 0.3, 0.6)));
  EXPECT_FALSE(cube->surface_crossing(V(2, 0.3, 0.6), V(3, 0.3, 0.6)));
  EXPECT_FALSE(cube->surface_crossing(V(0.5, 0.5, 0.5), V(0.5, 1.5, 0.5)));
  // find_crossing takes it instead of bisecting: t exact to round-off (bisection alone stops
  // at 2^-31 of the segment), and on the shared diagonal it bisects on to 1e-9.
  const std::vector<GeometryOp> ops{{OpMode::add, cube, 0}};
  const auto x = find_crossing(ops, V(0.5, 0.3, 0.6), V(0.5, 1.3, 0.6));
  ASSERT_TRUE(x);
  EXPECT_NEAR(x->t, 0.7, 1e-13);
  const auto y = find_crossing(ops, V(0.5, 0.5, 0.5), V(0.5, 1.5, 0.5));
  ASSERT_TRUE(y);
  EXPECT_NEAR(y->t, 0.5, 1e-9);
  // A subtracted mesh: the cavity's surface, crossed from the material into it.
  const std::vector<GeometryOp> cavity{{OpMode::add, make_box(V(-1, -1, -1), V(2, 2, 2)), 0},
                                       {OpMode::subtract, cube, 0}};
  const auto z = find_crossing(cavity, V(0.5, 1.7, 0.6), V(0.5, 0.7, 0.6));
  ASSERT_TRUE(z);
  EXPECT_NEAR(z->t, 0.7, 1e-13);
  expect_near(z->normal, V(0, -1, 0), 1e-12);
}

TEST(Crossing, ImagesFallBackToTheSegmentDirection) {
  auto image = std::make_shared<VoxelImage>();
  image->dims = {4, 1, 1};
  image->values = {1, 1, 0, 2};  // labels
  const std::vector<GeometryOp> ops{{OpMode::add, make_image_labels(image, {1}), 0}};
  EXPECT_TRUE(inside_after(ops, V(1.5, 0.5, 0.5)));
  EXPECT_FALSE(inside_after(ops, V(3.5, 0.5, 0.5)));   // label 2 is not selected
  EXPECT_FALSE(inside_after(ops, V(-0.5, 0.5, 0.5)));  // outside the image
  const auto x = find_crossing(ops, V(1.5, 0.5, 0.5), V(2.5, 0.5, 0.5));
  ASSERT_TRUE(x);
  EXPECT_NEAR(x->t, 0.5, 1e-8);  // the voxel face at x = 2
  expect_near(x->normal, V(1, 0, 0), 1e-12);
}

TEST(Crossing, ImageLabelsShapeMatchesApplyImageLabels) {
  auto image = std::make_shared<VoxelImage>();
  image->dims = {3, 3, 2};
  image->spacing = V(0.5, 0.5, 1.0);
  image->values = {0, 1, 2, 3, 1.4f, 2.6f, 1, 1, 0, 2, 2, 1, 0, 3, 1, 1, 2, 0};
  LatticeSpec spec;
  spec.h = 0.25;
  spec.dims = {7, 7, 9};
  spec.origin = V(-0.1, -0.1, -0.1);
  auto grid = make_empty_grid(spec);
  apply_image_labels(grid, *image, {{1, 0}, {3, 0}});
  const auto shape = make_image_labels(image, {1, 3});
  for (int k = 0; k < spec.dims[2]; ++k)
    for (int j = 0; j < spec.dims[1]; ++j)
      for (int i = 0; i < spec.dims[0]; ++i)
        EXPECT_EQ(shape->contains(spec.cell_centre(i, j, k)),
                  grid.material[spec.cell_index(i, j, k)] >= 0);
}

}  // namespace
}  // namespace hexcut::geometry
