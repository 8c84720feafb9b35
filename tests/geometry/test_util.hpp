// Helpers shared by the geometry tests.
#pragma once

#include <gtest/gtest.h>
#include <unistd.h>

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>

#include "geometry/triangle_mesh.hpp"
#include "geometry/voxel_image.hpp"

namespace hexcut::geometry::test {

/// Axis-aligned cube [lo, hi]^3 as 8 vertices (index x + 2y + 4z) and 12 outward
/// triangles; face f is triangles 2f and 2f+1, the fan of the quad kCubeQuads[f].
inline constexpr int kCubeQuads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                                         {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};

inline TriangleMesh cube_mesh(double lo, double hi) {
  TriangleMesh m;
  for (int v = 0; v < 8; ++v) {
    m.vertices.emplace_back(v & 1 ? hi : lo, v & 2 ? hi : lo, v & 4 ? hi : lo);
  }
  for (const auto& q : kCubeQuads) {
    m.triangles.push_back({q[0], q[1], q[2]});
    m.triangles.push_back({q[0], q[2], q[3]});
  }
  return m;
}

// Cube [0,1]^3 with every face split into n x n quads (2 triangles each), outward.
// Vertex (i,j,k) on the (n+1)^3 grid has index i + (n+1)(j + (n+1)k).
inline TriangleMesh tessellated_cube(int n) {
  TriangleMesh m;
  const int m1 = n + 1;
  for (int k = 0; k <= n; ++k) {
    for (int j = 0; j <= n; ++j) {
      for (int i = 0; i <= n; ++i)
        m.vertices.emplace_back(double(i) / n, double(j) / n, double(k) / n);
    }
  }
  const auto id = [&](std::array<int, 3> g) { return g[0] + m1 * (g[1] + m1 * g[2]); };
  for (int a = 0; a < 3; ++a) {
    const int b = (a + 1) % 3, c = (a + 2) % 3;
    for (int side : {0, n}) {
      for (int v = 0; v < n; ++v) {
        for (int u = 0; u < n; ++u) {
          std::array<int, 4> q;
          const int du[4] = {0, 1, 1, 0}, dv[4] = {0, 0, 1, 1};
          for (int corner = 0; corner < 4; ++corner) {
            std::array<int, 3> g;
            g[a] = side;
            g[b] = u + du[corner];
            g[c] = v + dv[corner];
            q[corner] = id(g);
          }
          // (e_b, e_c) is counter-clockwise about +e_a: keep it on the far side.
          if (side == n) {
            m.triangles.push_back({q[0], q[1], q[2]});
            m.triangles.push_back({q[0], q[2], q[3]});
          } else {
            m.triangles.push_back({q[0], q[2], q[1]});
            m.triangles.push_back({q[0], q[3], q[2]});
          }
        }
      }
    }
  }
  return m;
}

/// A fresh directory under the system temp dir, removed at scope exit.
class TempDir {
 public:
  explicit TempDir(const std::string& tag) {
    path_ = std::filesystem::temp_directory_path() /
            ("hexcut_geometry_" + tag + "_" + std::to_string(::getpid()));
    std::filesystem::remove_all(path_);
    std::filesystem::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  std::string file(const std::string& name) const { return (path_ / name).string(); }
  std::string write(const std::string& name, const std::string& content) const {
    const std::string p = file(name);
    std::ofstream(p, std::ios::binary) << content;
    return p;
  }

 private:
  std::filesystem::path path_;
};

/// The message of the E that f() throws, or `none` when it throws nothing.
template <class E, class F>
std::string thrown(F&& f, const std::string& none = "no error") {
  try {
    f();
  } catch (const E& e) {
    return e.what();
  }
  return none;
}

/// A headerless little-endian int16 image of n voxels, voxel (a, b, c) (x fastest) holding
/// value(a, b, c): the raw twin of a phantom written in a scanner format.
template <class F>
std::string int16_raw(const std::array<int, 3>& n, F value) {
  std::string bytes;
  for (int c = 0; c < n[2]; ++c)
    for (int b = 0; b < n[1]; ++b)
      for (int a = 0; a < n[0]; ++a) {
        const std::int16_t v = value(a, b, c);
        bytes.append(reinterpret_cast<const char*>(&v), 2);
      }
  return bytes;
}

/// img is raw on the same grid (dims; spacing and origin to 1e-15 m) with every value
/// rescaled: slope * raw + intercept, exactly.
inline void expect_rescaled_copy(const VoxelImage& img, const VoxelImage& raw, float slope,
                                 float intercept) {
  ASSERT_EQ(img.dims, raw.dims);
  EXPECT_LT((img.spacing - raw.spacing).norm(), 1e-15);
  EXPECT_LT((img.origin - raw.origin).norm(), 1e-15);
  ASSERT_EQ(img.values.size(), raw.values.size());
  for (std::size_t v = 0; v < raw.values.size(); ++v)
    EXPECT_EQ(img.values[v], slope * raw.values[v] + intercept) << v;
}

}  // namespace hexcut::geometry::test
