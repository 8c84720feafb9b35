// Orientation of meshes used as solids (orient_solid, make_mesh_solid): whatever the
// orientation each triangle is given in, the solid is the same. Expectations are
// independent of the routine: the reference meshes are built outward (or, for cavities,
// inward) by construction, and cell counts are analytic or come from the brute-force
// winding number of the reference mesh.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <bitset>
#include <chrono>
#include <cmath>
#include <random>
#include <sstream>

#include "geometry/triangle_mesh.hpp"
#include "geometry/voxelize.hpp"
#include "test_util.hpp"

namespace hg = hexcut::geometry;
using Eigen::Vector3d;

namespace {

constexpr double kPi = 3.14159265358979323846;

// UV sphere, outward: nu segments round the z axis, nv bands from pole to pole.
hg::TriangleMesh uv_sphere(const Vector3d& centre, double radius, int nu, int nv) {
  hg::TriangleMesh m;
  m.vertices.push_back(centre + Vector3d(0, 0, -radius));
  for (int b = 1; b < nv; ++b) {
    const double phi = -kPi / 2 + kPi * b / nv;
    for (int s = 0; s < nu; ++s) {
      const double th = 2 * kPi * s / nu;
      m.vertices.push_back(centre + radius * Vector3d(std::cos(phi) * std::cos(th),
                                                      std::cos(phi) * std::sin(th), std::sin(phi)));
    }
  }
  m.vertices.push_back(centre + Vector3d(0, 0, radius));
  const int top = static_cast<int>(m.vertices.size()) - 1;
  const auto ring = [&](int b, int s) { return 1 + (b - 1) * nu + (s % nu); };
  for (int s = 0; s < nu; ++s) {
    m.triangles.push_back({0, ring(1, s + 1), ring(1, s)});
    m.triangles.push_back({top, ring(nv - 1, s), ring(nv - 1, s + 1)});
    for (int b = 1; b + 1 < nv; ++b) {
      m.triangles.push_back({ring(b, s), ring(b, s + 1), ring(b + 1, s + 1)});
      m.triangles.push_back({ring(b, s), ring(b + 1, s + 1), ring(b + 1, s)});
    }
  }
  return m;
}

hg::TriangleMesh cube(double lo, double hi) {
  return hg::test::cube_mesh(lo, hi);
}

hg::TriangleMesh box(const Vector3d& lo, const Vector3d& hi) {
  hg::TriangleMesh m = hg::test::cube_mesh(0.0, 1.0);
  for (auto& v : m.vertices) v = lo + (hi - lo).cwiseProduct(v);
  return m;
}

hg::TriangleMesh reversed(hg::TriangleMesh m) {
  for (auto& t : m.triangles) std::swap(t[1], t[2]);
  return m;
}

// Both meshes' vertices and triangles, a's first.
hg::TriangleMesh join(const hg::TriangleMesh& a, const hg::TriangleMesh& b) {
  hg::TriangleMesh m = a;
  const int off = static_cast<int>(a.vertices.size());
  m.vertices.insert(m.vertices.end(), b.vertices.begin(), b.vertices.end());
  for (auto t : b.triangles) m.triangles.push_back({t[0] + off, t[1] + off, t[2] + off});
  return m;
}

// Reverses each triangle with probability 1/2 (also rotates its corners, which must not
// matter); returns how many were reversed.
int scramble(hg::TriangleMesh& m, unsigned seed) {
  std::mt19937 rng(seed);
  int n = 0;
  for (auto& t : m.triangles) {
    if (rng() % 2) {
      std::swap(t[1], t[2]);
      ++n;
    }
    if (rng() % 2) t = {t[1], t[2], t[0]};
  }
  return n;
}

// Triangles equal up to a rotation of their corners, one by one.
::testing::AssertionResult same_orientation(const hg::TriangleMesh& got,
                                            const hg::TriangleMesh& want) {
  if (got.triangles.size() != want.triangles.size()) {
    return ::testing::AssertionFailure()
           << got.triangles.size() << " triangles, want " << want.triangles.size();
  }
  int wrong = 0;
  for (std::size_t t = 0; t < got.triangles.size(); ++t) {
    const auto& g = got.triangles[t];
    const auto& w = want.triangles[t];
    const bool same = g == w || g == std::array<int, 3>{w[1], w[2], w[0]} ||
                      g == std::array<int, 3>{w[2], w[0], w[1]};
    wrong += !same;
  }
  if (wrong) return ::testing::AssertionFailure() << wrong << " triangles oriented wrongly";
  return ::testing::AssertionSuccess();
}

hexcut::LatticeSpec unit_lattice(double h, double lo = 0.0, double hi = 1.0) {
  hexcut::LatticeSpec spec;
  spec.origin = Vector3d::Constant(lo);
  spec.h = h;
  const int n = static_cast<int>(std::lround((hi - lo) / h));
  spec.dims = {n, n, n};
  return spec;
}

std::int64_t filled(const hexcut::LatticeSpec& spec, const std::vector<hg::GeometryOp>& ops) {
  hg::VoxelGrid grid = hg::make_empty_grid(spec);
  for (const auto& op : ops) hg::apply(grid, op);
  return hg::count_filled(grid);
}

std::int64_t cells_inside(const hexcut::LatticeSpec& spec, const hg::TriangleMesh& m) {
  return filled(spec, {{hg::OpMode::add, hg::make_mesh_solid(m), 0}});
}

// Cells whose centre the brute-force winding number of `reference` (as given) puts inside.
std::int64_t reference_cells(const hexcut::LatticeSpec& spec, const hg::TriangleMesh& reference) {
  std::int64_t n = 0;
  for (int k = 0; k < spec.dims[2]; ++k) {
    for (int j = 0; j < spec.dims[1]; ++j) {
      for (int i = 0; i < spec.dims[0]; ++i)
        n += hg::winding_number(reference, spec.cell_centre(i, j, k)) >= 0.5;
    }
  }
  return n;
}

// Cell centres of the lattice strictly inside [lo, hi]^3 (one axis, cubed).
std::int64_t centres_in(const hexcut::LatticeSpec& spec, double lo, double hi) {
  std::int64_t n = 0;
  for (int i = 0; i < spec.dims[0]; ++i) {
    const double c = spec.origin.x() + spec.h * (i + 0.5);
    n += c > lo && c < hi;
  }
  return n * n * n;
}

// The mesh of the field report: the 8 corners of [0.3,0.7]^3 and 6 quads, every
// one inside-out; bit f of `flip` reverses quad f back.
std::string hole_obj(int flip) {
  const int quads[6][4] = {{1, 2, 3, 4}, {5, 8, 7, 6}, {1, 5, 6, 2},
                           {2, 6, 7, 3}, {3, 7, 8, 4}, {4, 8, 5, 1}};
  std::ostringstream os;
  for (double z : {0.3, 0.7}) {
    os << "v 0.3 0.3 " << z << "\nv 0.7 0.3 " << z << "\nv 0.7 0.7 " << z << "\nv 0.3 0.7 " << z
       << "\n";
  }
  for (int f = 0; f < 6; ++f) {
    os << "f";
    for (int c = 0; c < 4; ++c) os << " " << quads[f][(flip >> f & 1) ? 3 - c : c];
    os << "\n";
  }
  return os.str();
}

// Möbius strip of n quads (2 triangles each) round a circle of radius 1, width 0.6; the
// last quad closes it with a half twist. With `fin`, one more triangle shares the edge
// where the twist closes.
hg::TriangleMesh mobius(int n, bool twist, bool fin) {
  hg::TriangleMesh m;
  for (int i = 0; i < n; ++i) {
    const double th = 2 * kPi * i / n, ph = twist ? th / 2 : 0.0;
    const Vector3d c(std::cos(th), std::sin(th), 0.0);
    const Vector3d d = std::cos(ph) * c + std::sin(ph) * Vector3d::UnitZ();
    m.vertices.push_back(c + 0.3 * d);  // 2i: top
    m.vertices.push_back(c - 0.3 * d);  // 2i + 1: bottom
  }
  for (int i = 0; i < n; ++i) {
    const int t0 = 2 * i, b0 = 2 * i + 1;
    int t1 = 2 * ((i + 1) % n), b1 = t1 + 1;
    if (twist && i + 1 == n) std::swap(t1, b1);  // the half twist
    m.triangles.push_back({b0, b1, t1});
    m.triangles.push_back({b0, t1, t0});
  }
  if (fin) {
    m.vertices.emplace_back(1.0, 0.0, 2.0);
    m.triangles.push_back({0, 1, static_cast<int>(m.vertices.size()) - 1});
  }
  return m;
}

std::string orient_error(hg::TriangleMesh m) {
  return hg::test::thrown<std::invalid_argument>([&] { hg::orient_solid(m); }, "(no error)");
}

}  // namespace

TEST(GeometryOrientation, EveryFlipOfEveryTriangleOfACube) {
  const hg::TriangleMesh ref = cube(0.0, 1.0);
  for (int mask = 0; mask < (1 << 12); ++mask) {
    hg::TriangleMesh m = ref;
    for (int t = 0; t < 12; ++t) {
      if (mask >> t & 1) std::swap(m.triangles[t][1], m.triangles[t][2]);
    }
    const auto r = hg::orient_solid(m);
    ASSERT_TRUE(same_orientation(m, ref)) << "flips " << std::bitset<12>(mask);
    ASSERT_EQ(r.flipped, int(std::bitset<12>(mask).count()));
    ASSERT_EQ(r.pieces, 1);
    ASSERT_EQ(r.cavities, 0);
  }
}

TEST(GeometryOrientation, FieldReportHoleInEveryFaceOrientation) {
  // The deck: box [0,1]^3, h = 0.1, minus the OBJ cube [0.3,0.7]^3 (quads, fan
  // triangulated by the reader). 1000 - 4^3 = 936 cells, the hole in i, j, k = 3..6,
  // for all 64 choices of which quads are inside-out (0 = the report's file).
  hg::test::TempDir dir("orientation_obj");
  const auto spec = unit_lattice(0.1);
  for (int flip = 0; flip < 64; ++flip) {
    const auto mesh = hg::load_triangle_mesh(dir.write("hole.obj", hole_obj(flip)));
    hg::VoxelGrid grid = hg::make_empty_grid(spec);
    hg::apply(grid, {hg::OpMode::add, hg::make_box(Vector3d::Zero(), Vector3d::Ones()), 0});
    hg::apply(grid, {hg::OpMode::subtract, hg::make_mesh_solid(mesh), 0});
    ASSERT_EQ(hg::count_filled(grid), 936) << "flip " << flip;
    for (int k = 0; k < 10; ++k) {
      for (int j = 0; j < 10; ++j) {
        for (int i = 0; i < 10; ++i) {
          const bool hole = i >= 3 && i <= 6 && j >= 3 && j <= 6 && k >= 3 && k <= 6;
          ASSERT_EQ(grid.material[spec.cell_index(i, j, k)], hole ? -1 : 0)
              << "flip " << flip << " cell " << i << " " << j << " " << k;
        }
      }
    }
  }
}

TEST(GeometryOrientation, NgonsAndStlNormalsDoNotMatter) {
  // A hexagonal prism with 6-gon caps (OBJ), and the cube as STL whose facet normals
  // point the other way from the vertex order (hexcut reads the vertex order, then
  // orients): the same cells as the reference, reversed or not.
  hg::test::TempDir dir("orientation_ngon");
  const auto spec = unit_lattice(0.05, -1.0, 1.0);
  hg::TriangleMesh prism;
  for (double z : {-0.5, 0.5}) {
    for (int s = 0; s < 6; ++s) {
      prism.vertices.emplace_back(0.8 * std::cos(kPi * s / 3), 0.8 * std::sin(kPi * s / 3), z);
    }
  }
  std::ostringstream outward, inward;
  for (const auto& v : prism.vertices) {
    outward << "v " << v.x() << " " << v.y() << " " << v.z() << "\n";
  }
  inward << outward.str();
  outward << "f 6 5 4 3 2 1\nf 7 8 9 10 11 12\n";
  inward << "f 1 2 3 4 5 6\nf 12 11 10 9 8 7\n";
  for (int s = 0; s < 6; ++s) {
    const int a = s + 1, b = (s + 1) % 6 + 1;
    prism.triangles.push_back({a - 1, b - 1, b + 5});
    prism.triangles.push_back({a - 1, b + 5, a + 5});
    outward << "f " << a << " " << b << " " << b + 6 << " " << a + 6 << "\n";
    // Inward sides, and one side left outward: inconsistent on purpose.
    if (s == 2) {
      inward << "f " << a << " " << b << " " << b + 6 << " " << a + 6 << "\n";
    } else {
      inward << "f " << a + 6 << " " << b + 6 << " " << b << " " << a << "\n";
    }
  }
  for (int s = 1; s < 5; ++s) {  // caps as fans, outward
    prism.triangles.push_back({0, s + 1, s});
    prism.triangles.push_back({6, 6 + s, 7 + s});
  }
  const std::int64_t want = reference_cells(spec, prism);
  EXPECT_GT(want, 1000);
  EXPECT_EQ(cells_inside(spec, hg::load_triangle_mesh(dir.write("out.obj", outward.str()))), want);
  EXPECT_EQ(cells_inside(spec, hg::load_triangle_mesh(dir.write("in.obj", inward.str()))), want);

  // STL: the cube [-0.5, 0.5]^3 inside-out, with outward facet normals; and outward with
  // inward normals. Binary and ASCII.
  const hg::TriangleMesh ref = cube(-0.5, 0.5);
  const std::int64_t cube_cells = centres_in(spec, -0.5, 0.5);
  for (bool inside_out : {false, true}) {
    const hg::TriangleMesh m = inside_out ? reversed(ref) : ref;
    std::ostringstream ascii;
    std::string binary(80, ' ');
    const auto put = [&binary](const void* p, int bytes) {
      binary.append(static_cast<const char*>(p), bytes);
    };
    const std::uint32_t n = static_cast<std::uint32_t>(m.triangles.size());
    put(&n, 4);  // little-endian hosts only, as the reader's tests assume
    ascii << "solid c\n";
    for (const auto& t : m.triangles) {
      const Vector3d& a = m.vertices[t[0]];
      Vector3d normal = (m.vertices[t[1]] - a).cross(m.vertices[t[2]] - a).normalized();
      normal = -normal;  // disagrees with the vertex order
      ascii << " facet normal " << normal.x() << " " << normal.y() << " " << normal.z()
            << "\n  outer loop\n";
      for (float f : {float(normal.x()), float(normal.y()), float(normal.z())}) put(&f, 4);
      for (int c = 0; c < 3; ++c) {
        const Vector3d& v = m.vertices[t[c]];
        ascii << "   vertex " << v.x() << " " << v.y() << " " << v.z() << "\n";
        for (float f : {float(v.x()), float(v.y()), float(v.z())}) put(&f, 4);
      }
      ascii << "  endloop\n endfacet\n";
      binary.append(2, '\0');
    }
    ascii << "endsolid c\n";
    EXPECT_EQ(cells_inside(spec, hg::load_triangle_mesh(dir.write("a.stl", ascii.str()))),
              cube_cells);
    EXPECT_EQ(cells_inside(spec, hg::load_triangle_mesh(dir.write("b.stl", binary))), cube_cells);
  }
}

TEST(GeometryOrientation, RandomFlipsOnASphere) {
  const hg::TriangleMesh ref = uv_sphere(Vector3d(0.1, -0.05, 0.02), 0.8, 48, 24);
  for (unsigned seed = 1; seed <= 5; ++seed) {
    hg::TriangleMesh m = ref;
    const int n = scramble(m, seed);
    const auto r = hg::orient_solid(m);
    EXPECT_TRUE(same_orientation(m, ref)) << "seed " << seed;
    EXPECT_EQ(r.flipped, n);
  }
  hg::TriangleMesh m = reversed(ref);
  EXPECT_EQ(hg::orient_solid(m).flipped, int(ref.triangles.size()));
  EXPECT_TRUE(same_orientation(m, ref));
  EXPECT_NEAR(hg::enclosed_volume(m), hg::enclosed_volume(ref), 1e-12);
  EXPECT_GT(hg::enclosed_volume(m), 0.0);
}

TEST(GeometryOrientation, HolesDoNotStopPropagation) {
  // Tessellated cube with a 3x3-quad hole in one face and a missing quad in another:
  // orientation still reaches every triangle across the shared edges.
  const int n = 8;
  hg::TriangleMesh ref = hg::test::tessellated_cube(n);
  std::vector<std::array<int, 3>> kept;
  for (std::size_t t = 0; t < ref.triangles.size(); ++t) {
    const int quad = static_cast<int>(t / 2), u = quad % n, v = quad / n;
    const bool hole = quad < n * n && u >= 3 && u < 6 && v >= 2 && v < 5;
    if (!hole && quad != 2 * n * n + 10) kept.push_back(ref.triangles[t]);
  }
  ref.triangles = kept;
  const auto spec = unit_lattice(0.1, -0.2, 1.2);
  const std::int64_t want = reference_cells(spec, ref);
  EXPECT_EQ(want, centres_in(spec, 0.0, 1.0));
  for (unsigned seed : {3u, 4u, 5u}) {
    hg::TriangleMesh m = ref;
    scramble(m, seed);
    EXPECT_EQ(cells_inside(spec, m), want) << "seed " << seed;
    hg::orient_solid(m);
    EXPECT_TRUE(same_orientation(m, ref)) << "seed " << seed;
  }
  hg::TriangleMesh m = reversed(ref);
  EXPECT_EQ(cells_inside(spec, m), want);
}

TEST(GeometryOrientation, SeparateAndOverlappingShellsAreUnited) {
  const auto spec = unit_lattice(0.1, -1.0, 2.0);
  const hg::TriangleMesh a = cube(0.0, 1.0),
                         b = box(Vector3d(-0.8, -0.8, -0.8), Vector3d(-0.3, -0.2, -0.4));
  const hg::TriangleMesh c = cube(0.43, 1.57);  // overlaps a; neither box holds the other
  const std::int64_t na = centres_in(spec, 0.0, 1.0), nc = centres_in(spec, 0.43, 1.57);
  const std::int64_t nb = 5 * 6 * 4, nac = na + nc - centres_in(spec, 0.43, 1.0);
  for (int given = 0; given < 4; ++given) {
    hg::TriangleMesh ab = join(given & 1 ? reversed(a) : a, given & 2 ? reversed(b) : b);
    hg::TriangleMesh ac = join(given & 1 ? reversed(a) : a, given & 2 ? reversed(c) : c);
    EXPECT_EQ(cells_inside(spec, ab), na + nb) << given;
    EXPECT_EQ(cells_inside(spec, ac), nac) << given;
    scramble(ab, given + 10);
    const auto r = hg::orient_solid(ab);
    EXPECT_TRUE(same_orientation(ab, join(a, b))) << given;
    EXPECT_EQ(r.pieces, 2);
    EXPECT_EQ(r.cavities, 0);
  }
}

TEST(GeometryOrientation, APieceThatCrossesAnotherIsNotInsideIt) {
  // A cube whose box lies in the sphere's box, about two thirds of it inside the sphere
  // and a corner sticking out: two overlapping bodies (a union), not a cavity.
  const hg::TriangleMesh sphere = uv_sphere(Vector3d::Zero(), 1.0, 36, 18);
  hg::TriangleMesh a = hg::test::tessellated_cube(4);  // 96 triangles: 32 samples
  for (auto& v : a.vertices) v = Vector3d::Constant(0.1) + 0.7 * v;
  int in = 0, out = 0;
  for (const auto& t : a.triangles) {
    const Vector3d c = (a.vertices[t[0]] + a.vertices[t[1]] + a.vertices[t[2]]) / 3.0;
    const double w = hg::winding_number(sphere, c);
    in += w > 0.75;
    out += w < 0.25;
  }
  ASSERT_GT(2 * in, int(a.triangles.size()));  // most of it inside: not decisive alone
  ASSERT_GT(out, 8);
  const auto spec = unit_lattice(0.12, -1.2, 1.2);
  const std::int64_t want = reference_cells(spec, join(sphere, a));
  EXPECT_GT(want, cells_inside(spec, sphere) + 10);  // the corner sticking out
  for (int given = 0; given < 4; ++given) {
    hg::TriangleMesh m = join(given & 1 ? reversed(sphere) : sphere, given & 2 ? reversed(a) : a);
    EXPECT_EQ(cells_inside(spec, m), want) << given;
    EXPECT_EQ(hg::orient_solid(m).cavities, 0);
  }
}

TEST(GeometryOrientation, NestedShellsAreCavitiesAndIslands) {
  // Outer [0,1]^3, cavity [0.2,0.8]^3, island [0.4,0.6]^3, given in all 8 orientations and
  // then scrambled: 1000 - 216 + 8 cells at h = 0.1.
  const auto spec = unit_lattice(0.1);
  const hg::TriangleMesh shells[3] = {cube(0.0, 1.0), cube(0.2, 0.8), cube(0.4, 0.6)};
  const hg::TriangleMesh ref = join(join(shells[0], reversed(shells[1])), shells[2]);
  for (int given = 0; given < 8; ++given) {
    hg::TriangleMesh s[3];
    for (int i = 0; i < 3; ++i) s[i] = (given >> i & 1) ? reversed(shells[i]) : shells[i];
    hg::TriangleMesh m = join(join(s[0], s[1]), s[2]);
    EXPECT_EQ(cells_inside(spec, m), 1000 - 216 + 8) << given;
    scramble(m, given);
    EXPECT_EQ(cells_inside(spec, m), 1000 - 216 + 8) << given;
    const auto r = hg::orient_solid(m);
    EXPECT_TRUE(same_orientation(m, ref)) << given;
    EXPECT_EQ(r.pieces, 3);
    EXPECT_EQ(r.cavities, 1);
    EXPECT_NEAR(hg::enclosed_volume(m), 1.0 - 0.216 + 0.008, 1e-12);
  }
  // The order of the shells in the file does not matter either.
  hg::TriangleMesh m = join(join(shells[2], shells[1]), reversed(shells[0]));
  EXPECT_EQ(cells_inside(spec, m), 1000 - 216 + 8);
}

TEST(GeometryOrientation, HollowSphereStaysHollow) {
  const Vector3d c(0.02, -0.01, 0.03);
  const hg::TriangleMesh outer = uv_sphere(c, 0.9, 40, 20), inner = uv_sphere(c, 0.5, 24, 12);
  const hg::TriangleMesh ref = join(outer, reversed(inner));
  const auto spec = unit_lattice(0.1, -1.0, 1.0);
  const std::int64_t want = reference_cells(spec, ref);
  EXPECT_NEAR(double(want), 4.0 / 3.0 * kPi * (0.729 - 0.125) / 1e-3, 60.0);
  for (int given = 0; given < 4; ++given) {
    hg::TriangleMesh m =
        join(given & 1 ? reversed(outer) : outer, given & 2 ? reversed(inner) : inner);
    scramble(m, 7 + given);
    EXPECT_EQ(cells_inside(spec, m), want) << given;
    hg::orient_solid(m);
    EXPECT_TRUE(same_orientation(m, ref)) << given;
  }
}

TEST(GeometryOrientation, TouchingAndSharedFaces) {
  const auto spec = unit_lattice(0.1, -1.0, 3.0);
  const hg::TriangleMesh a = cube(0.0, 1.0);
  // Two cubes sharing an edge (shared vertices, 4 triangles on the edge): two solids.
  const hg::TriangleMesh e = box(Vector3d(1, 1, 0), Vector3d(2, 2, 1));
  // Two boxes side by side, each closed by the face x = 1 they share: a box [0,2]x[0,1]^2
  // whose inner wall is given twice; and the same with the wall given once.
  const hg::TriangleMesh b = box(Vector3d(1, 0, 0), Vector3d(2, 1, 1));
  hg::TriangleMesh b_open = b;  // b without its face x = 1 (kCubeQuads[4]: triangles 8, 9)
  b_open.triangles.erase(b_open.triangles.begin() + 8, b_open.triangles.begin() + 10);
  const std::int64_t one = 1000, two = 2000;
  for (unsigned seed = 0; seed < 6; ++seed) {
    hg::TriangleMesh m = join(a, e);
    scramble(m, seed);
    EXPECT_EQ(cells_inside(spec, m), two) << seed;
    auto r = hg::orient_solid(m);
    EXPECT_TRUE(same_orientation(m, join(a, e))) << seed;
    EXPECT_EQ(r.pieces, 2);

    m = join(a, b);
    scramble(m, seed + 100);
    EXPECT_EQ(cells_inside(spec, m), two) << seed;
    r = hg::orient_solid(m);
    EXPECT_EQ(r.walls, 1);
    EXPECT_EQ(r.removed, 4);
    EXPECT_NEAR(hg::enclosed_volume(m), 2.0, 1e-12);

    m = join(a, b_open);
    scramble(m, seed + 200);
    EXPECT_EQ(cells_inside(spec, m), two) << seed;
    r = hg::orient_solid(m);
    EXPECT_EQ(r.walls, 1);
    EXPECT_EQ(r.removed, 2);

    // A shell given twice, the copies in any orientation: still the one solid.
    m = join(a, a);
    scramble(m, seed + 300);
    EXPECT_EQ(cells_inside(spec, m), one) << seed;
  }
}

TEST(GeometryOrientation, FlatSheetsBoundNothing) {
  // One free quad: kept as given. Two coincident quads (any orientations): cancel.
  hg::TriangleMesh quad;
  quad.vertices = {{0, 0, 0.5}, {1, 0, 0.5}, {1, 1, 0.5}, {0, 1, 0.5}};
  quad.triangles = {{0, 1, 2}, {0, 2, 3}};
  hg::TriangleMesh m = quad;
  const auto r = hg::orient_solid(m);
  EXPECT_EQ(r.sheets, 1);
  EXPECT_EQ(r.flipped, 0);
  EXPECT_EQ(m.triangles, quad.triangles);
  for (int given = 0; given < 4; ++given) {
    hg::TriangleMesh twice =
        join(given & 1 ? reversed(quad) : quad, given & 2 ? reversed(quad) : quad);
    hg::orient_solid(twice);
    EXPECT_NEAR(hg::winding_number(twice, Vector3d(0.5, 0.5, 0.51)), 0.0, 1e-12) << given;
  }
  // A sheet inside a cube changes no cell.
  const auto spec = unit_lattice(0.1);
  for (int given = 0; given < 2; ++given) {
    EXPECT_EQ(cells_inside(spec, join(cube(0.0, 1.0), given ? reversed(quad) : quad)), 1000);
  }
}

TEST(GeometryOrientation, OneSidedMeshesAreRejected) {
  std::string msg = orient_error(mobius(24, true, false));
  EXPECT_NE(msg.find("cannot be oriented"), std::string::npos) << msg;
  EXPECT_NE(msg.find("Moebius strip"), std::string::npos) << msg;
  EXPECT_NE(msg.find("edge ("), std::string::npos) << msg;
  // The twist passing through an edge of three triangles (a fin on the closing edge).
  msg = orient_error(mobius(24, true, true));
  EXPECT_NE(msg.find("shared by 3 triangles"), std::string::npos) << msg;
  EXPECT_NE(msg.find("(1.3, 0, 0)"), std::string::npos) << msg;
  // The same bands without the twist are two-sided: accepted.
  EXPECT_EQ(orient_error(mobius(24, false, false)), "(no error)");
  EXPECT_EQ(orient_error(mobius(24, false, true)), "(no error)");
  // make_mesh_solid rejects it too.
  EXPECT_THROW(hg::make_mesh_solid(mobius(24, true, false)), std::invalid_argument);
}

TEST(GeometryOrientation, WindingNumbersMatchBruteForce) {
  hg::TriangleMesh m = uv_sphere(Vector3d::Zero(), 1.0, 32, 16);
  m.triangles.erase(m.triangles.begin() + 40, m.triangles.begin() + 44);  // a hole
  std::vector<Vector3d> points;
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1.5, 1.5);
  for (int i = 0; i < 300; ++i) points.emplace_back(u(rng), u(rng), u(rng));
  const auto w = hg::winding_numbers(m, points);
  ASSERT_EQ(w.size(), points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    EXPECT_NEAR(w[i], hg::winding_number(m, points[i]), 1e-9) << i;
  }
}

// Time for 10^5 and 10^6 triangles (not part of the suite; run with
// --gtest_also_run_disabled_tests --gtest_filter='*Timing*').
TEST(GeometryOrientation, DISABLED_Timing) {
  const Vector3d c(0.02, -0.01, 0.03);
  const auto seconds_since = [](auto t0) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  };
  for (int nu : {316, 1000}) {
    hg::TriangleMesh one = uv_sphere(c, 0.9, nu, nu / 2);
    scramble(one, 2);
    auto t0 = std::chrono::steady_clock::now();
    hg::orient_solid(one);
    std::printf("sphere, %zu triangles: orient_solid %.3f s\n", one.triangles.size(),
                seconds_since(t0));
    t0 = std::chrono::steady_clock::now();
    const auto solid = hg::make_mesh_solid(one);
    std::printf("  make_mesh_solid (orientation included) %.3f s\n", seconds_since(t0));
    hg::TriangleMesh m = join(uv_sphere(c, 0.9, nu, nu / 2), uv_sphere(c, 0.5, nu / 2, nu / 4));
    scramble(m, 1);
    t0 = std::chrono::steady_clock::now();
    const auto r = hg::orient_solid(m);
    std::printf("hollow sphere, %zu triangles: orient_solid %.3f s (%d cavity)\n",
                m.triangles.size(), seconds_since(t0), r.cavities);
  }
}
