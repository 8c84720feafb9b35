// Helpers shared by the geometry tests.
#pragma once

#include <unistd.h>

#include <Eigen/Core>
#include <filesystem>
#include <fstream>
#include <string>

#include "geometry/triangle_mesh.hpp"

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

}  // namespace hexcut::geometry::test
