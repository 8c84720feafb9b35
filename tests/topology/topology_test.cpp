// Vertex copies and partition on small lattices whose answers are known by counting.
#include <gtest/gtest.h>

#include <cstdlib>
#include <map>
#include <set>
#include <string>

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

class Partition : public ::testing::TestWithParam<PartitionMethod> {};

TEST_P(Partition, SuperBlocksStayOnOneRankAndOwnersTouchTheirCopies) {
  std::vector<std::array<int, 3>> all;
  for (int k = 0; k < 16; ++k)
    for (int j = 0; j < 8; ++j)
      for (int i = 0; i < 32; ++i)
        if ((i - 16) * (i - 16) + (k - 8) * (k - 8) > 9) all.push_back({i, j, k});  // a hole
  const auto L = make({32, 8, 16}, all);
  const auto V = build_vertex_copies(L);
  const auto P = partition_lattice(L, V, 3, 4, 1, GetParam());
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
  // 64 super-blocks (8 x 2 x 4) of at most 64 cells over 3 ranks: within one of a third.
  for (int r = 0; r < 3; ++r)
    EXPECT_NEAR(count[r], L.num_cells() / 3.0, 64.0) << "rank " << r << " badly balanced";
  for (std::int32_t v = 0; v < V.num_copies; ++v)
    EXPECT_EQ(P.copy_rank[v], P.cell_rank[V.first_cell[v]]);
  // Compact parts: two cuts across the long axis cut 2 x 8 x 16 = 256 faces (less the hole);
  // at most twice that, where an assignment of blocks at random would cut about 2/3 of the
  // 2176 faces between super-blocks.
  EXPECT_LE(partition_stats(L, V, P).cut_links, 2 * 256);
}

INSTANTIATE_TEST_SUITE_P(Methods, Partition,
                         ::testing::Values(PartitionMethod::metis, PartitionMethod::ptscotch,
                                           PartitionMethod::sfc),
                         [](const auto& info) { return std::string(method_name(info.param)); });

TEST(PartitionStats, CountsLinksAndGhostsOfATwoRankBar) {
  // 8 x 2 x 2 cells, super-blocks of 4 cells split at x = 4: 2 x 2 links cross; the 3 x 3
  // copies of the vertex plane x = 4 belong to the cells at x = 3 (lower in lattice order),
  // so rank 1 has 9 ghosts and rank 0 none.
  std::vector<std::array<int, 3>> all;
  for (int k = 0; k < 2; ++k)
    for (int j = 0; j < 2; ++j)
      for (int i = 0; i < 8; ++i) all.push_back({i, j, k});
  auto L = make({8, 2, 2}, all);
  const auto V = build_vertex_copies(L);
  topology::Partition P;
  P.num_ranks = 2;
  for (std::int32_t c = 0; c < L.num_cells(); ++c) P.cell_rank.push_back(L.ijk[c][0] >= 4);
  for (std::int32_t v = 0; v < V.num_copies; ++v)
    P.copy_rank.push_back(P.cell_rank[V.first_cell[v]]);
  const auto s = partition_stats(L, V, P);
  EXPECT_EQ(s.cut_links, 4);
  EXPECT_EQ(s.ghosts, 9);
  EXPECT_EQ(s.max_ghosts, 9);
  EXPECT_EQ(s.max_cells, 16);
  EXPECT_EQ(s.max_copies, 5 * 9);  // rank 0 owns the vertex planes x = 0..4
  EXPECT_DOUBLE_EQ(s.mean_copies, 9 * 9 / 2.0);
  EXPECT_DOUBLE_EQ(s.copy_imbalance(), 45 / 40.5);
  EXPECT_DOUBLE_EQ(s.cell_imbalance(), 1.0);
  EXPECT_EQ(s.empty_ranks, 0);
  // The balance alone (what the decision after a cut reads) counts the same; a third rank
  // without cells is an empty rank and lowers the means.
  P.num_ranks = 3;
  const auto b = partition_balance(P);
  EXPECT_EQ(b.max_copies, 45);
  EXPECT_EQ(b.empty_ranks, 1);
  EXPECT_DOUBLE_EQ(b.cell_imbalance(), 16 / (32 / 3.0));
  P.num_ranks = 2;
  // A cut across the plane x = 4 (what a blade does) removes those links.
  for (int k = 0; k < 2; ++k)
    for (int j = 0; j < 2; ++j) L.links[L.find(3, j, k)] &= ~lattice::kLinkX;
  EXPECT_EQ(partition_stats(L, V, P).cut_links, 0);
}

TEST(HilbertCurve, ConsecutiveKeysAreFaceNeighbours) {
  // Every cell of a 2^b cube gets a distinct key in [0, 8^b), and cells with consecutive
  // keys share a face: the curve visits the cube without jumps.
  for (int bits = 1; bits <= 4; ++bits) {
    const std::uint32_t n = 1u << bits;
    std::map<std::uint64_t, std::array<int, 3>> at;
    for (std::uint32_t z = 0; z < n; ++z)
      for (std::uint32_t y = 0; y < n; ++y)
        for (std::uint32_t x = 0; x < n; ++x) {
          const auto key = hilbert_key(x, y, z, bits);
          EXPECT_LT(key, std::uint64_t(n) * n * n);
          EXPECT_TRUE(at.emplace(key, std::array<int, 3>{int(x), int(y), int(z)}).second)
              << "key " << key << " twice";
        }
    for (std::uint64_t k = 0; k + 1 < std::uint64_t(n) * n * n; ++k) {
      const auto &a = at[k], &b = at[k + 1];
      EXPECT_EQ(std::abs(a[0] - b[0]) + std::abs(a[1] - b[1]) + std::abs(a[2] - b[2]), 1)
          << "bits " << bits << ", keys " << k << " and " << k + 1;
    }
  }
}

}  // namespace
}  // namespace hexcut::topology
