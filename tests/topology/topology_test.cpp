// Vertex copies and partition on small lattices whose answers are known by counting.
#include <gtest/gtest.h>

#include <map>
#include <set>

#include "topology/partition.hpp"
#include "topology/vertex_copies.hpp"

namespace hexcut::topology {
namespace {

lattice::Lattice make(const std::array<int, 3>& dims,
                      const std::vector<std::array<int, 3>>& filled) {
  LatticeSpec spec;
  spec.dims = dims;
  std::vector<std::int16_t> dense(spec.num_cells(), -1);
  for (const auto& c : filled) dense[spec.cell_index(c[0], c[1], c[2])] = 0;
  return lattice::build_lattice(spec, dense, {}, {{1.0, 0.3, 1.0}});
}

TEST(VertexCopies, SolidBlockHasOneCopyPerVertex) {
  std::vector<std::array<int, 3>> all;
  for (int k = 0; k < 3; ++k)
    for (int j = 0; j < 4; ++j)
      for (int i = 0; i < 5; ++i) all.push_back({i, j, k});
  const auto L = make({5, 4, 3}, all);
  const auto V = build_vertex_copies(L);
  EXPECT_EQ(V.num_copies, 6 * 5 * 4);
  // Face neighbours share exactly the 4 copies of their common face.
  const auto a = L.find(1, 1, 1), b = L.find(2, 1, 1);
  std::set<std::int32_t> sa(V.cell_corners[a].begin(), V.cell_corners[a].end());
  int shared = 0;
  for (auto v : V.cell_corners[b]) shared += sa.count(v);
  EXPECT_EQ(shared, 4);
}

TEST(VertexCopies, EdgeAndCornerContactsAreSplit) {
  // Two cells sharing only an edge: 8 + 8 copies (2 vertices duplicated).
  EXPECT_EQ(build_vertex_copies(make({2, 2, 1}, {{0, 0, 0}, {1, 1, 0}})).num_copies, 16);
  // Sharing only a corner: 16 copies.
  EXPECT_EQ(build_vertex_copies(make({2, 2, 2}, {{0, 0, 0}, {1, 1, 1}})).num_copies, 16);
  // An L of three cells: the corner cells connect through the middle one; the vertex
  // shared by all three (edge between the two outer cells) is one copy: 8+4+4 = 16.
  EXPECT_EQ(build_vertex_copies(make({2, 2, 1}, {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}})).num_copies, 16);
}

TEST(VertexCopies, ClearedLinkSplitsTheSharedFace) {
  auto L = make({2, 1, 1}, {{0, 0, 0}, {1, 0, 0}});
  EXPECT_EQ(build_vertex_copies(L).num_copies, 12);
  L.links[L.find(0, 0, 0)] &= ~lattice::kLinkX;  // what a cut does
  EXPECT_EQ(build_vertex_copies(L).num_copies, 16);
}

TEST(Partition, SuperBlocksStayOnOneRankAndOwnersTouchTheirCopies) {
  std::vector<std::array<int, 3>> all;
  for (int k = 0; k < 16; ++k)
    for (int j = 0; j < 8; ++j)
      for (int i = 0; i < 32; ++i)
        if ((i - 16) * (i - 16) + (k - 8) * (k - 8) > 9) all.push_back({i, j, k});  // a hole
  const auto L = make({32, 8, 16}, all);
  const auto V = build_vertex_copies(L);
  const auto P = partition_lattice(L, V, 3, 4);
  EXPECT_EQ(P.superblock, 4);
  std::map<std::int64_t, int> block_rank;
  std::vector<int> count(3, 0);
  for (std::int32_t c = 0; c < L.num_cells(); ++c) {
    const auto& p = L.ijk[c];
    const std::int64_t key = p[0] / 4 + 8 * (p[1] / 4 + 2 * std::int64_t(p[2] / 4));
    auto [it, fresh] = block_rank.emplace(key, P.cell_rank[c]);
    EXPECT_EQ(it->second, P.cell_rank[c]) << "super-block split over ranks";
    ++count[P.cell_rank[c]];
  }
  for (int r = 0; r < 3; ++r)
    EXPECT_GT(count[r], L.num_cells() / 6) << "rank " << r << " badly balanced";
  for (std::int32_t v = 0; v < V.num_copies; ++v)
    EXPECT_EQ(P.copy_rank[v], P.cell_rank[V.first_cell[v]]);
}

}  // namespace
}  // namespace hexcut::topology
