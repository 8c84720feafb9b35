// OBJ and STL reading: the same cube written three ways must load to the same mesh.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cstdint>
#include <cstring>
#include <sstream>

#include "common/errors.hpp"
#include "geometry/triangle_mesh.hpp"
#include "test_util.hpp"

namespace hg = hexcut::geometry;
using Eigen::Vector3d;
using hg::test::TempDir;

namespace {

using TriCoords = std::vector<std::array<Vector3d, 3>>;

TriCoords coords(const hg::TriangleMesh& m) {
  TriCoords out;
  for (const auto& t : m.triangles) {
    out.push_back({m.vertices.at(t[0]), m.vertices.at(t[1]), m.vertices.at(t[2])});
  }
  return out;
}

// OBJ exercising v, v/vt, v//vn, v/vt/vn, negative indices, quads, comments and CRLF.
std::string cube_obj(const hg::TriangleMesh& cube) {
  std::ostringstream os;
  os.precision(17);
  os << "# cube\r\nmtllib none.mtl\no cube\n";
  for (const auto& v : cube.vertices) os << "v " << v.x() << " " << v.y() << " " << v.z() << "\n";
  os << "vt 0 0\nvn 0 0 1\ns off\n";
  for (int f = 0; f < 6; ++f) {
    const auto& q = hg::test::kCubeQuads[f];
    os << "f";
    for (int c = 0; c < 4; ++c) {
      const int one_based = q[c] + 1;
      switch ((f + c) % 4) {
        case 0:
          os << " " << one_based;
          break;
        case 1:
          os << " " << one_based << "/1";
          break;
        case 2:
          os << " " << one_based << "//1";
          break;
        default:
          os << " " << (one_based - 9) << "/1/1";
          break;  // negative: 8 vertices
      }
    }
    os << (f % 2 ? "\r\n" : "  # quad\n");
  }
  return os.str();
}

std::string cube_stl_ascii(const hg::TriangleMesh& cube) {
  std::ostringstream os;
  os.precision(17);
  os << "solid cube\r\n";
  for (const auto& t : coords(cube)) {
    os << "  facet normal 0 0 0\r\n    outer loop\r\n";
    for (const auto& v : t)
      os << "      vertex " << v.x() << " " << v.y() << " " << v.z() << "\r\n";
    os << "    endloop\r\n  endfacet\r\n";
  }
  os << "endsolid cube\r\n";
  return os.str();
}

void put_u32(std::string& s, std::uint32_t u) {
  for (int b = 0; b < 4; ++b) s.push_back(static_cast<char>((u >> (8 * b)) & 0xff));
}
void put_f32(std::string& s, float f) {
  std::uint32_t u;
  std::memcpy(&u, &f, 4);
  put_u32(s, u);
}

// Binary STL whose header starts with "solid", as some exporters write it.
std::string cube_stl_binary(const hg::TriangleMesh& cube) {
  std::string s = "solid exported by a tool that should know better";
  s.resize(80, ' ');
  const auto tris = coords(cube);
  put_u32(s, static_cast<std::uint32_t>(tris.size()));
  for (const auto& t : tris) {
    for (int a = 0; a < 3; ++a) put_f32(s, 0.0f);
    for (const auto& v : t) {
      for (int a = 0; a < 3; ++a) put_f32(s, static_cast<float>(v[a]));
    }
    s.append(2, '\0');
  }
  return s;
}

std::string error_of(const std::string& path) {
  return hg::test::thrown<hexcut::InputError>([&] { hg::load_triangle_mesh(path); },
                                              "(no InputError)");
}

}  // namespace

TEST(GeometryMeshIo, ObjAndStlLoadIdentically) {
  TempDir dir("mesh_io");
  // Coordinates exact in float32, so binary STL loses nothing.
  const hg::TriangleMesh cube = hg::test::cube_mesh(-0.5, 1.25);
  const auto obj = hg::load_triangle_mesh(dir.write("cube.obj", cube_obj(cube)));
  const auto ascii = hg::load_triangle_mesh(dir.write("cube_ascii.STL", cube_stl_ascii(cube)));
  const auto binary = hg::load_triangle_mesh(dir.write("cube_binary.stl", cube_stl_binary(cube)));

  EXPECT_EQ(obj.vertices, cube.vertices);
  EXPECT_EQ(obj.triangles, cube.triangles);
  // STL is a triangle soup; identical corners must be merged back into 8 vertices.
  EXPECT_EQ(ascii.vertices.size(), 8u);
  EXPECT_EQ(binary.vertices.size(), 8u);
  EXPECT_EQ(coords(ascii), coords(cube));
  EXPECT_EQ(coords(binary), coords(cube));
  EXPECT_EQ(ascii.triangles, binary.triangles);
  EXPECT_DOUBLE_EQ(hg::enclosed_volume(binary), std::pow(1.75, 3));
}

TEST(GeometryMeshIo, ObjErrorsNameFileAndLine) {
  TempDir dir("mesh_io_err");
  const std::string verts = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\n";
  std::string msg = error_of(dir.write("bad_index.obj", verts + "f 1 2 5\n"));
  EXPECT_NE(msg.find("bad_index.obj:5:"), std::string::npos) << msg;
  msg = error_of(dir.write("neg.obj", verts + "f 1 2 3\n\nf -1 -2 -7\n"));
  EXPECT_NE(msg.find("neg.obj:7:"), std::string::npos) << msg;
  msg = error_of(dir.write("zero.obj", verts + "f 0 1 2\n"));
  EXPECT_NE(msg.find(":5:"), std::string::npos) << msg;
  msg = error_of(dir.write("coord.obj", "v 0 0 0\nv 1 x 0\n"));
  EXPECT_NE(msg.find("coord.obj:2:"), std::string::npos) << msg;
  msg = error_of(dir.write("short.obj", verts + "f 1 2\n"));
  EXPECT_NE(msg.find(":5:"), std::string::npos) << msg;
  msg = error_of(dir.write("empty.obj", verts));
  EXPECT_NE(msg.find("no triangles"), std::string::npos) << msg;
  msg = error_of(dir.file("missing.obj"));
  EXPECT_NE(msg.find("missing.obj"), std::string::npos) << msg;
  msg = error_of(dir.write("mesh.ply", "ply\n"));
  EXPECT_NE(msg.find("unknown mesh format"), std::string::npos) << msg;
}

TEST(GeometryMeshIo, StlErrors) {
  TempDir dir("stl_err");
  const hg::TriangleMesh cube = hg::test::cube_mesh(0, 1);
  std::string bin = cube_stl_binary(cube);
  bin.replace(0, 5, "xxxxx");  // neither "solid" nor the right size
  bin.pop_back();
  std::string msg = error_of(dir.write("truncated.stl", bin));
  EXPECT_NE(msg.find("not an STL file"), std::string::npos) << msg;
  msg = error_of(dir.write("bad.stl",
                           "solid s\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\n"
                           "vertex 1 0\nvertex 0 1 0\nendloop\nendfacet\nendsolid\n"));
  EXPECT_NE(msg.find("bad.stl:5:"), std::string::npos) << msg;
  msg = error_of(dir.write("empty.stl", "solid s\nendsolid s\n"));
  EXPECT_NE(msg.find("no triangles"), std::string::npos) << msg;
}

TEST(GeometryMeshIo, TransformAndBounds) {
  hg::TriangleMesh m = hg::test::cube_mesh(0, 1);
  hg::transform(m, 2.0, Vector3d(1, 2, 3));
  auto b = hg::bounds(m);
  EXPECT_EQ(b.lo, Vector3d(1, 2, 3));
  EXPECT_EQ(b.hi, Vector3d(3, 4, 5));
  EXPECT_DOUBLE_EQ(hg::enclosed_volume(m), 8.0);
  // Mirroring keeps the triangles outward: the volume stays positive.
  hg::transform(m, -0.5, Vector3d::Zero());
  EXPECT_DOUBLE_EQ(hg::enclosed_volume(m), 1.0);
  EXPECT_NEAR(hg::winding_number(m, Vector3d(-1, -1.5, -2)), 1.0, 1e-12);
  EXPECT_THROW(hg::transform(m, 0.0, Vector3d::Zero()), std::invalid_argument);
}

TEST(GeometryMeshIo, RotationTurnsAboutTheOriginBeforeTheTranslation) {
  // The unit cube scaled by 2, turned 90 degrees about z, then moved by (10, 0, 0): its
  // corner (2, 0, 0) goes to (10, 2, 0), the box to [8, 10] x [0, 2] x [0, 2]; the volume
  // and the outward orientation stay (a rotation is proper). A reflection is refused.
  hg::TriangleMesh m = hg::test::cube_mesh(0, 1);
  const Eigen::Matrix3d R = Eigen::AngleAxisd(M_PI / 2, Vector3d::UnitZ()).toRotationMatrix();
  hg::transform(m, 2.0, Vector3d(10, 0, 0), R);
  const auto b = hg::bounds(m);
  EXPECT_LT((b.lo - Vector3d(8, 0, 0)).norm(), 1e-12);
  EXPECT_LT((b.hi - Vector3d(10, 2, 2)).norm(), 1e-12);
  EXPECT_NEAR(hg::enclosed_volume(m), 8.0, 1e-12);
  EXPECT_NEAR(hg::winding_number(m, Vector3d(9, 1, 1)), 1.0, 1e-12);
  Eigen::Matrix3d mirror = Eigen::Matrix3d::Identity();
  mirror(0, 0) = -1;
  EXPECT_THROW(hg::transform(m, 1.0, Vector3d::Zero(), mirror), std::invalid_argument);
  EXPECT_THROW(hg::transform(m, 1.0, Vector3d::Zero(), 2.0 * R), std::invalid_argument);
}
