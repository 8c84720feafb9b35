// Primitive shapes and voxelization semantics, checked against closed-form counts.
#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

#include "geometry/shape.hpp"
#include "geometry/voxelize.hpp"

namespace hg = hexcut::geometry;
using Eigen::Vector3d;

namespace {

constexpr double kPi = 3.14159265358979323846;

hexcut::LatticeSpec cube_lattice(double half_width, int n) {
  hexcut::LatticeSpec spec;
  spec.origin = Vector3d::Constant(-half_width);
  spec.h = 2.0 * half_width / n;
  spec.dims = {n, n, n};
  return spec;
}

std::int64_t voxel_count(const hexcut::LatticeSpec& spec, const hg::ShapePtr& shape) {
  hg::VoxelGrid grid = hg::make_empty_grid(spec);
  hg::apply(grid, {hg::OpMode::add, shape, 0});
  return hg::count_filled(grid);
}

}  // namespace

TEST(GeometryPrimitives, SphereVolume) {
  // r/h = 20: the centre-sampled count converges to the volume with O(h) surface noise.
  const double r = 1.0, h = 0.05;
  const auto spec = cube_lattice(1.2, 48);
  ASSERT_DOUBLE_EQ(spec.h, h);
  const double expected = 4.0 / 3.0 * kPi * std::pow(r / h, 3);
  const auto n = voxel_count(spec, hg::make_sphere(Vector3d(0.013, -0.021, 0.007), r));
  EXPECT_NEAR(double(n) / expected, 1.0, 0.01) << n << " vs " << expected;
}

TEST(GeometryPrimitives, BoxCountIsExact) {
  hexcut::LatticeSpec spec;
  spec.h = 0.1;
  spec.dims = {30, 20, 20};
  // Faces lie between cell centres (centres are at 0.05 + 0.1 i).
  const auto box = hg::make_box(Vector3d(0.3, 0.2, 0.5), Vector3d(1.7, 0.9, 1.0));
  EXPECT_EQ(voxel_count(spec, box), 14 * 7 * 5);
  // A box sticking out of the lattice is clipped.
  const auto big = hg::make_box(Vector3d(-5, -5, 0.5), Vector3d(5, 5, 1.0));
  EXPECT_EQ(voxel_count(spec, big), 30 * 20 * 5);
}

TEST(GeometryPrimitives, ObliqueCylinderVolume) {
  const Vector3d p0(-0.5, -0.5, -0.5), p1(0.5, 0.5, 0.5);
  const double r = 0.4;
  const auto spec = cube_lattice(1.0, 100);
  const double expected = kPi * r * r * (p1 - p0).norm() / std::pow(spec.h, 3);
  const auto n = voxel_count(spec, hg::make_cylinder(p0, p1, r));
  EXPECT_NEAR(double(n) / expected, 1.0, 0.01) << n << " vs " << expected;
}

TEST(GeometryPrimitives, CylinderBoundsAreTight) {
  const auto cyl = hg::make_cylinder(Vector3d(0, 0, 0), Vector3d(0, 0, 2), 0.5);
  const auto b = cyl->bounds();
  EXPECT_TRUE(b.lo.isApprox(Vector3d(-0.5, -0.5, 0.0)));
  EXPECT_TRUE(b.hi.isApprox(Vector3d(0.5, 0.5, 2.0)));
  EXPECT_TRUE(cyl->contains(Vector3d(0.49, 0, 1.99)));
  EXPECT_FALSE(cyl->contains(Vector3d(0, 0, 2.01)));
  EXPECT_FALSE(cyl->contains(Vector3d(0.36, 0.36, 1.0)));
}

TEST(GeometryPrimitives, HalfSpace) {
  const auto spec = cube_lattice(1.0, 20);
  // Axis-aligned: cells with centre x <= 0.33, i.e. centres -0.95 .. 0.25 -> 13 columns.
  const auto hx = hg::make_half_space(Vector3d(0.33, 0, 0), Vector3d(2, 0, 0));
  EXPECT_TRUE(std::isfinite(hx->bounds().hi.x()));
  EXPECT_EQ(voxel_count(spec, hx), 13 * 20 * 20);
  // Flipped normal keeps the other side.
  EXPECT_EQ(voxel_count(spec, hg::make_half_space(Vector3d(0.33, 0, 0), Vector3d(-1, 0, 0))),
            7 * 20 * 20);
  // Oblique plane x+y+z = 0 through the lattice centre: no centre lies on it (n even), and
  // the point reflection maps inside to outside, so exactly half the cells are inside.
  const auto oblique = hg::make_half_space(Vector3d::Zero(), Vector3d(1, 1, 1));
  EXPECT_FALSE(oblique->bounds().is_finite());
  EXPECT_EQ(voxel_count(spec, oblique), 20 * 20 * 20 / 2);
}

TEST(GeometryPrimitives, SlabSelectsOneLayer) {
  const auto spec = cube_lattice(1.0, 20);
  const double z = spec.cell_centre(0, 0, 7).z();
  const auto slab = hg::make_slab(Vector3d(0, 0, z + 1e-9), Vector3d(0, 0, -3), 0.4 * spec.h);
  EXPECT_EQ(voxel_count(spec, slab), 20 * 20);
  EXPECT_TRUE(slab->contains(Vector3d(5, -7, z)));
  EXPECT_FALSE(slab->contains(Vector3d(0, 0, z + 0.5 * spec.h)));
}

TEST(GeometryPrimitives, SubtractAndAssign) {
  const auto spec = cube_lattice(1.0, 40);
  const Vector3d box_lo(-0.61, -0.52, -0.43), box_hi(0.55, 0.47, 0.38);
  const Vector3d hole_c(0.5, 0.1, 0.0);
  const double hole_r = 0.3;
  const Vector3d core_c(-0.6, -0.1, 0.05);
  const double core_r = 0.35;

  hg::VoxelGrid grid = hg::make_empty_grid(spec);
  hg::apply(grid, {hg::OpMode::add, hg::make_box(box_lo, box_hi), 1});
  hg::apply(grid, {hg::OpMode::subtract, hg::make_sphere(hole_c, hole_r), 0});
  hg::apply(grid, {hg::OpMode::assign, hg::make_sphere(core_c, core_r), 2});

  std::int64_t expected_filled = 0;
  for (int k = 0; k < 40; ++k) {
    for (int j = 0; j < 40; ++j) {
      for (int i = 0; i < 40; ++i) {
        const Vector3d c = spec.cell_centre(i, j, k);
        const bool in_box =
            (c.array() >= box_lo.array()).all() && (c.array() <= box_hi.array()).all();
        const bool in_hole = (c - hole_c).norm() <= hole_r;
        const bool in_core = (c - core_c).norm() <= core_r;
        const int expected = !in_box || in_hole ? -1 : in_core ? 2 : 1;
        expected_filled += expected >= 0;
        ASSERT_EQ(grid.material[spec.cell_index(i, j, k)], expected) << i << " " << j << " " << k;
      }
    }
  }
  EXPECT_EQ(hg::count_filled(grid), expected_filled);
}

TEST(GeometryPrimitives, InvalidArguments) {
  EXPECT_THROW(hg::make_sphere(Vector3d::Zero(), 0.0), std::invalid_argument);
  EXPECT_THROW(hg::make_sphere(Vector3d::Zero(), -1.0), std::invalid_argument);
  EXPECT_THROW(hg::make_box(Vector3d(0, 0, 0), Vector3d(1, 0, 1)), std::invalid_argument);
  EXPECT_THROW(hg::make_cylinder(Vector3d::Ones(), Vector3d::Ones(), 1.0), std::invalid_argument);
  EXPECT_THROW(hg::make_cylinder(Vector3d::Zero(), Vector3d::Ones(), 0.0), std::invalid_argument);
  EXPECT_THROW(hg::make_half_space(Vector3d::Zero(), Vector3d::Zero()), std::invalid_argument);
  EXPECT_THROW(hg::make_slab(Vector3d::Zero(), Vector3d::UnitX(), -0.1), std::invalid_argument);
  EXPECT_THROW(hg::make_slab(Vector3d::Zero(), Vector3d(0, NAN, 0), 0.1), std::invalid_argument);
  try {
    hg::make_sphere(Vector3d::Zero(), -2.0);
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("radius"), std::string::npos) << e.what();
  }
  const auto spec = cube_lattice(1.0, 4);
  hg::VoxelGrid grid = hg::make_empty_grid(spec);
  EXPECT_THROW(hg::apply(grid, {hg::OpMode::add, nullptr, 0}), std::invalid_argument);
  EXPECT_THROW(hg::apply(grid, {hg::OpMode::add, hg::make_sphere(Vector3d::Zero(), 1), 40000}),
               std::invalid_argument);
  grid.material.pop_back();
  EXPECT_THROW(hg::apply(grid, {hg::OpMode::add, hg::make_sphere(Vector3d::Zero(), 1), 0}),
               std::invalid_argument);
}
