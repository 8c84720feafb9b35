// Union-find over integer ids, the one piece behind every "connected components" of
// hexcut: vertex copies (cells around a vertex), coarse cells (cells of a 2x2x2 block)
// and pieces (the whole body). Unions keep the smaller id as the root, so the roots, and
// everything numbered from them, do not depend on the order of the unions.
#pragma once

#include <algorithm>
#include <cstdint>
#include <numeric>
#include <vector>

namespace hexcut::topology {

/// parent[i] = i for n ids.
inline std::vector<std::int32_t> make_union_find(std::int32_t n) {
  std::vector<std::int32_t> parent(n);
  std::iota(parent.begin(), parent.end(), 0);
  return parent;
}

/// The root of a's set (with path halving).
inline std::int32_t find_root(std::vector<std::int32_t>& parent, std::int32_t a) {
  while (parent[a] != a) a = parent[a] = parent[parent[a]];
  return a;
}

/// Joins the sets of a and b; the smaller root becomes the root of both.
inline void unite(std::vector<std::int32_t>& parent, std::int32_t a, std::int32_t b) {
  const auto ra = find_root(parent, a), rb = find_root(parent, b);
  if (ra != rb) parent[std::max(ra, rb)] = std::min(ra, rb);
}

}  // namespace hexcut::topology
