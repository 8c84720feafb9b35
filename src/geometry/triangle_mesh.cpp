// OBJ/STL reading and mesh utilities.
#include "geometry/triangle_mesh.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string_view>
#include <unordered_map>

#include "common/errors.hpp"

namespace hexcut::geometry {
namespace {

std::string read_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path + ": cannot open mesh file");
  std::string data((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) throw InputError(path + ": error reading mesh file");
  return data;
}

std::string lower_extension(const std::string& path) {
  const auto slash = path.find_last_of("/\\");
  const auto dot = path.find_last_of('.');
  if (dot == std::string::npos || (slash != std::string::npos && dot < slash)) return "";
  std::string ext = path.substr(dot + 1);
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return ext;
}

// Splits a line into whitespace-separated tokens (views into `line`).
std::vector<std::string_view> tokenize(std::string_view line) {
  std::vector<std::string_view> tokens;
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && std::isspace(static_cast<unsigned char>(line[i]))) ++i;
    const std::size_t start = i;
    while (i < line.size() && !std::isspace(static_cast<unsigned char>(line[i]))) ++i;
    if (i > start) tokens.push_back(line.substr(start, i - start));
  }
  return tokens;
}

// from_chars is locale-independent, unlike strtod, so a host locale with decimal commas
// cannot change how a mesh reads.
bool parse_double(std::string_view s, double& out) {
  if (!s.empty() && s.front() == '+') s.remove_prefix(1);
  const auto r = std::from_chars(s.data(), s.data() + s.size(), out);
  return r.ec == std::errc() && r.ptr == s.data() + s.size();
}

bool parse_int(std::string_view s, long long& out) {
  if (!s.empty() && s.front() == '+') s.remove_prefix(1);
  const auto r = std::from_chars(s.data(), s.data() + s.size(), out);
  return r.ec == std::errc() && r.ptr == s.data() + s.size();
}

std::string quote(std::string_view s) {
  return "'" + std::string(s) + "'";
}

// Iterates over lines, tracking 1-based line numbers; handles \n and \r\n.
class LineReader {
 public:
  explicit LineReader(const std::string& data) : data_(data) {}
  bool next(std::string_view& line) {
    if (pos_ >= data_.size()) return false;
    std::size_t end = data_.find('\n', pos_);
    if (end == std::string::npos) end = data_.size();
    line = std::string_view(data_).substr(pos_, end - pos_);
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    pos_ = end + 1;
    ++line_no_;
    return true;
  }
  int line_no() const { return line_no_; }

 private:
  const std::string& data_;
  std::size_t pos_ = 0;
  int line_no_ = 0;
};

TriangleMesh load_obj(const std::string& path, const std::string& data) {
  TriangleMesh mesh;
  // A positive index may name a vertex defined further down, so indices are checked at
  // the end; the line of each triangle is kept for the message.
  std::vector<int> tri_line;
  LineReader reader(data);
  std::string_view line;
  std::vector<long long> face;
  while (reader.next(line)) {
    const int ln = reader.line_no();
    const auto hash = line.find('#');
    if (hash != std::string_view::npos) line = line.substr(0, hash);
    const auto tok = tokenize(line);
    if (tok.empty()) continue;
    if (tok[0] == "v") {
      if (tok.size() < 4) throw InputError(path, ln, "vertex needs 3 coordinates");
      Eigen::Vector3d v;
      for (int a = 0; a < 3; ++a) {
        if (!parse_double(tok[1 + a], v[a]) || !std::isfinite(v[a])) {
          throw InputError(path, ln, "bad vertex coordinate " + quote(tok[1 + a]));
        }
      }
      mesh.vertices.push_back(v);
    } else if (tok[0] == "f") {
      if (tok.size() < 4) throw InputError(path, ln, "face needs at least 3 vertices");
      face.clear();
      for (std::size_t t = 1; t < tok.size(); ++t) {
        // v, v/vt, v//vn, v/vt/vn: only the position index matters.
        const std::string_view s = tok[t].substr(0, tok[t].find('/'));
        long long idx = 0;
        if (!parse_int(s, idx)) throw InputError(path, ln, "bad face index " + quote(tok[t]));
        if (idx == 0) throw InputError(path, ln, "face index 0 (OBJ indices start at 1)");
        if (idx < 0) {
          // Relative to the vertices read so far.
          idx += static_cast<long long>(mesh.vertices.size());
          if (idx < 0) {
            throw InputError(path, ln,
                             "face index " + std::string(s) + " refers before the first vertex");
          }
        } else {
          idx -= 1;
        }
        if (idx > std::numeric_limits<int>::max()) {
          throw InputError(path, ln, "face index " + std::string(s) + " out of range");
        }
        face.push_back(idx);
      }
      for (std::size_t t = 1; t + 1 < face.size(); ++t) {
        mesh.triangles.push_back(
            {static_cast<int>(face[0]), static_cast<int>(face[t]), static_cast<int>(face[t + 1])});
        tri_line.push_back(ln);
      }
    }
  }
  const auto nv = static_cast<long long>(mesh.vertices.size());
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    for (int idx : mesh.triangles[t]) {
      if (idx >= nv) {
        throw InputError(path, tri_line[t],
                         "face index " + std::to_string(idx + 1) + " out of range (file has " +
                             std::to_string(nv) + " vertices)");
      }
    }
  }
  return mesh;
}

// Merges bit-identical positions so an STL triangle soup becomes an indexed mesh whose
// open edges can be found (mesh_solid.cpp relies on shared vertices to find holes).
class VertexWelder {
 public:
  explicit VertexWelder(TriangleMesh& mesh) : mesh_(mesh) {}
  int index(const Eigen::Vector3d& v) {
    Key key;
    std::memcpy(key.bits.data(), v.data(), sizeof(double) * 3);
    const auto [it, inserted] = map_.try_emplace(key, static_cast<int>(mesh_.vertices.size()));
    if (inserted) mesh_.vertices.push_back(v);
    return it->second;
  }

 private:
  struct Key {
    std::array<std::uint64_t, 3> bits;
    bool operator==(const Key& o) const { return bits == o.bits; }
  };
  struct Hash {
    std::size_t operator()(const Key& k) const {
      std::uint64_t h = 1469598103934665603ull;
      for (auto b : k.bits) h = (h ^ b) * 1099511628211ull + (h >> 29);
      return static_cast<std::size_t>(h);
    }
  };
  TriangleMesh& mesh_;
  std::unordered_map<Key, int, Hash> map_;
};

std::uint32_t read_u32_le(const unsigned char* p) {
  return std::uint32_t(p[0]) | (std::uint32_t(p[1]) << 8) | (std::uint32_t(p[2]) << 16) |
         (std::uint32_t(p[3]) << 24);
}

float read_f32_le(const unsigned char* p) {
  const std::uint32_t u = read_u32_le(p);
  float f;
  std::memcpy(&f, &u, sizeof f);
  return f;
}

TriangleMesh load_stl_binary(const std::string& path, const std::string& data) {
  TriangleMesh mesh;
  VertexWelder weld(mesh);
  const auto* bytes = reinterpret_cast<const unsigned char*>(data.data());
  const std::uint32_t n = read_u32_le(bytes + 80);
  mesh.triangles.reserve(n);
  for (std::uint32_t t = 0; t < n; ++t) {
    // Record: normal (3 floats, ignored: orientation comes from the vertex order),
    // 3 vertices (9 floats), 2 attribute bytes.
    const unsigned char* rec = bytes + 84 + std::size_t(50) * t;
    std::array<int, 3> tri;
    for (int c = 0; c < 3; ++c) {
      Eigen::Vector3d v;
      for (int a = 0; a < 3; ++a) v[a] = read_f32_le(rec + 12 + 12 * c + 4 * a);
      if (!v.allFinite()) {
        throw InputError(path + ": triangle " + std::to_string(t) + " has a non-finite coordinate");
      }
      tri[c] = weld.index(v);
    }
    mesh.triangles.push_back(tri);
  }
  return mesh;
}

TriangleMesh load_stl_ascii(const std::string& path, const std::string& data) {
  TriangleMesh mesh;
  VertexWelder weld(mesh);
  LineReader reader(data);
  std::string_view line;
  std::vector<int> loop;
  bool in_loop = false;
  int loop_line = 0;
  while (reader.next(line)) {
    const int ln = reader.line_no();
    const auto tok = tokenize(line);
    if (tok.empty()) continue;
    if (tok[0] == "vertex") {
      if (!in_loop) throw InputError(path, ln, "'vertex' outside 'outer loop'");
      if (tok.size() != 4) throw InputError(path, ln, "vertex needs 3 coordinates");
      Eigen::Vector3d v;
      for (int a = 0; a < 3; ++a) {
        if (!parse_double(tok[1 + a], v[a]) || !std::isfinite(v[a])) {
          throw InputError(path, ln, "bad vertex coordinate " + quote(tok[1 + a]));
        }
      }
      loop.push_back(weld.index(v));
    } else if (tok[0] == "outer") {
      if (in_loop) throw InputError(path, ln, "nested 'outer loop'");
      in_loop = true;
      loop_line = ln;
      loop.clear();
    } else if (tok[0] == "endloop") {
      if (!in_loop) throw InputError(path, ln, "'endloop' without 'outer loop'");
      if (loop.size() < 3) throw InputError(path, loop_line, "facet has fewer than 3 vertices");
      for (std::size_t t = 1; t + 1 < loop.size(); ++t) {
        mesh.triangles.push_back({loop[0], loop[t], loop[t + 1]});
      }
      in_loop = false;
    } else if (tok[0] == "solid" || tok[0] == "endsolid" || tok[0] == "facet" ||
               tok[0] == "endfacet") {
      // Structure only; facet normals are ignored (orientation comes from vertex order).
    } else {
      throw InputError(path, ln, "unexpected STL keyword " + quote(tok[0]));
    }
  }
  if (in_loop) throw InputError(path, loop_line, "'outer loop' without 'endloop'");
  return mesh;
}

TriangleMesh load_stl(const std::string& path, const std::string& data) {
  // Size is the reliable test: some exporters write binary files whose 80-byte header
  // begins with "solid", so the keyword alone would misdetect them as ASCII.
  if (data.size() >= 84) {
    const std::uint64_t n = read_u32_le(reinterpret_cast<const unsigned char*>(data.data()) + 80);
    if (84 + 50 * n == data.size()) return load_stl_binary(path, data);
  }
  std::size_t i = 0;
  while (i < data.size() && std::isspace(static_cast<unsigned char>(data[i]))) ++i;
  if (data.compare(i, 5, "solid") == 0) return load_stl_ascii(path, data);
  throw InputError(path + ": not an STL file (binary size does not match its triangle " +
                   "count, and it does not start with 'solid')");
}

}  // namespace

TriangleMesh load_triangle_mesh(const std::string& path) {
  const std::string ext = lower_extension(path);
  if (ext != "obj" && ext != "stl") {
    throw InputError(path + ": unknown mesh format (expected .obj or .stl)");
  }
  const std::string data = read_file(path);
  TriangleMesh mesh = ext == "obj" ? load_obj(path, data) : load_stl(path, data);
  if (mesh.triangles.empty()) throw InputError(path + ": mesh has no triangles");
  return mesh;
}

void transform(TriangleMesh& mesh, double scale, const Eigen::Vector3d& translate,
               const Eigen::Matrix3d& rotation) {
  if (!std::isfinite(scale) || scale == 0.0) {
    throw std::invalid_argument("mesh transform: scale must be finite and nonzero, got " +
                                std::to_string(scale));
  }
  if (!translate.allFinite()) {
    throw std::invalid_argument("mesh transform: translation is not finite");
  }
  if (!rotation.allFinite() ||
      (rotation.transpose() * rotation - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() >
          1e-9 ||
      rotation.determinant() < 0.0) {
    throw std::invalid_argument("mesh transform: the rotation is not a proper rotation matrix");
  }
  for (auto& v : mesh.vertices) v = rotation * (scale * v) + translate;
  if (scale < 0.0) {
    for (auto& t : mesh.triangles) std::swap(t[1], t[2]);
  }
}

Aabb bounds(const TriangleMesh& mesh) {
  Aabb b{Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity()),
         Eigen::Vector3d::Constant(-std::numeric_limits<double>::infinity())};
  for (const auto& v : mesh.vertices) {
    b.lo = b.lo.cwiseMin(v);
    b.hi = b.hi.cwiseMax(v);
  }
  return b;
}

double enclosed_volume(const TriangleMesh& mesh) {
  double six_v = 0.0;
  for (const auto& t : mesh.triangles) {
    const auto& a = mesh.vertices.at(t[0]);
    const auto& b = mesh.vertices.at(t[1]);
    const auto& c = mesh.vertices.at(t[2]);
    six_v += a.dot(b.cross(c));
  }
  return six_v / 6.0;
}

void check_mesh_indices(const TriangleMesh& mesh) {
  const int nv = static_cast<int>(mesh.vertices.size());
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    for (int v : mesh.triangles[t]) {
      if (v < 0 || v >= nv) {
        throw std::invalid_argument("mesh solid: triangle " + std::to_string(t) +
                                    " has vertex index " + std::to_string(v) +
                                    " out of range [0, " + std::to_string(nv) + ")");
      }
    }
  }
  for (const auto& v : mesh.vertices) {
    if (!v.allFinite()) throw std::invalid_argument("mesh solid: non-finite vertex");
  }
}

}  // namespace hexcut::geometry
