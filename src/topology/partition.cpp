#include "topology/partition.hpp"

#include <metis.h>
#include <petscmat.h>

#include <algorithm>
#include <map>
#include <numeric>
#include <stdexcept>
#include <string>

#include "common/errors.hpp"
#include "common/petsc_check.hpp"

namespace hexcut::topology {

const char* method_name(PartitionMethod m) {
  switch (m) {
    case PartitionMethod::metis:
      return "metis";
    case PartitionMethod::ptscotch:
      return "ptscotch";
    case PartitionMethod::sfc:
      return "sfc";
  }
  return "?";
}

std::uint64_t hilbert_key(std::uint32_t x, std::uint32_t y, std::uint32_t z, int bits) {
  // Skilling's transform of the axes into the "transposed" Hilbert index, then its bits
  // interleaved (most significant first).
  std::uint32_t X[3] = {x, y, z};
  if (bits <= 0) return 0;
  const std::uint32_t M = 1u << (bits - 1);
  for (std::uint32_t Q = M; Q > 1; Q >>= 1) {
    const std::uint32_t P = Q - 1;
    for (int i = 0; i < 3; ++i) {
      if (X[i] & Q) {
        X[0] ^= P;  // invert
      } else {
        const std::uint32_t t = (X[0] ^ X[i]) & P;  // exchange
        X[0] ^= t;
        X[i] ^= t;
      }
    }
  }
  for (int i = 1; i < 3; ++i) X[i] ^= X[i - 1];  // Gray encode
  std::uint32_t t = 0;
  for (std::uint32_t Q = M; Q > 1; Q >>= 1)
    if (X[2] & Q) t ^= Q - 1;
  for (auto& v : X) v ^= t;
  std::uint64_t key = 0;
  for (int b = bits - 1; b >= 0; --b)
    for (int i = 0; i < 3; ++i) key = (key << 1) | ((X[i] >> b) & 1u);
  return key;
}

namespace {

/// The super-blocks' face-adjacency graph (CSR, each edge both ways), their lattice
/// positions and their material cell counts.
struct BlockGraph {
  std::vector<std::array<std::int64_t, 3>> position;  // per block: super-block index
  std::vector<idx_t> weight, xadj, adjncy;
  // Empty, or per block the vertex copies whose lowest-numbered cell is in it (their owner's
  // DOFs / 3): a second balance constraint after cuts.
  std::vector<idx_t> copies;
};

BlockGraph block_graph(const std::map<std::int64_t, int>& block_id,
                       const std::array<std::int64_t, 3>& nb,
                       const std::vector<int>& block_of_cell) {
  BlockGraph G;
  const std::size_t n = block_id.size();
  G.position.resize(n);
  G.weight.assign(n, 0);
  for (int b : block_of_cell) ++G.weight[b];
  std::vector<std::vector<idx_t>> adj(n);
  for (const auto& [key, id] : block_id) {
    const std::int64_t b[3] = {key % nb[0], (key / nb[0]) % nb[1], key / (nb[0] * nb[1])};
    G.position[id] = {b[0], b[1], b[2]};
    for (int d = 0; d < 3; ++d)
      for (int s = -1; s <= 1; s += 2) {
        std::int64_t q[3] = {b[0], b[1], b[2]};
        q[d] += s;
        if (q[d] < 0 || q[d] >= nb[d]) continue;
        auto it = block_id.find(q[0] + nb[0] * (q[1] + nb[1] * q[2]));
        if (it != block_id.end()) adj[id].push_back(it->second);
      }
  }
  G.xadj.assign(n + 1, 0);
  for (std::size_t b = 0; b < n; ++b) {
    G.adjncy.insert(G.adjncy.end(), adj[b].begin(), adj[b].end());
    G.xadj[b + 1] = idx_t(G.adjncy.size());
  }
  return G;
}

std::vector<int> metis_parts(BlockGraph& G, int num_ranks) {
  const std::size_t n = G.weight.size();
  idx_t ncon = G.copies.empty() ? 1 : 2, nparts = num_ranks, objval = 0, nv = idx_t(n);
  // Two constraints (cells, copies) interleaved per vertex, as METIS wants them.
  std::vector<idx_t> weights = G.weight;
  if (ncon == 2) {
    weights.resize(2 * n);
    for (std::size_t b = 0; b < n; ++b) {
      weights[2 * b] = G.weight[b];
      weights[2 * b + 1] = G.copies[b];
    }
  }
  std::vector<idx_t> part(n, 0);
  idx_t options[METIS_NOPTIONS];
  METIS_SetDefaultOptions(options);
  options[METIS_OPTION_SEED] = 1;  // deterministic on every rank
  const int status =
      METIS_PartGraphKway(&nv, &ncon, G.xadj.data(), G.adjncy.data(), weights.data(), nullptr,
                          nullptr, &nparts, nullptr, nullptr, options, &objval, part.data());
  if (status != METIS_OK) throw std::runtime_error("METIS_PartGraphKway failed");
  return {part.begin(), part.end()};
}

/// PT-Scotch through PETSc's MatPartitioning: the block graph's rows split evenly over the
/// ranks of `comm` (as a distributed lattice would hold them), the parts gathered on all.
std::vector<int> ptscotch_parts(const BlockGraph& G, int num_ranks, MPI_Comm comm) {
  int rank, size;
  MPI_Comm_rank(comm, &rank);
  MPI_Comm_size(comm, &size);
  const PetscInt n = PetscInt(G.weight.size());
  auto begin_of = [&](int r) { return PetscInt(std::int64_t(n) * r / size); };
  const PetscInt b0 = begin_of(rank), b1 = begin_of(rank + 1), m = b1 - b0;
  // MatCreateMPIAdj and MatPartitioningSetVertexWeights take PetscMalloc'd arrays they free.
  PetscInt *ia, *ja, *w;
  const PetscInt nnz = PetscInt(G.xadj[b1] - G.xadj[b0]);
  check_petsc(PetscMalloc1(m + 1, &ia), "ptscotch: adjacency");
  check_petsc(PetscMalloc1(std::max<PetscInt>(nnz, 1), &ja), "ptscotch: adjacency");
  check_petsc(PetscMalloc1(std::max<PetscInt>(m, 1), &w), "ptscotch: weights");
  for (PetscInt i = 0; i <= m; ++i) ia[i] = PetscInt(G.xadj[b0 + i] - G.xadj[b0]);
  for (PetscInt k = 0; k < nnz; ++k) ja[k] = PetscInt(G.adjncy[G.xadj[b0] + k]);
  for (PetscInt i = 0; i < m; ++i) w[i] = PetscInt(G.weight[b0 + i]);
  Mat adj;
  MatPartitioning mp;
  IS is;
  check_petsc(MatCreateMPIAdj(comm, m, n, ia, ja, nullptr, &adj), "ptscotch: MatCreateMPIAdj");
  check_petsc(MatPartitioningCreate(comm, &mp), "ptscotch: MatPartitioningCreate");
  check_petsc(MatPartitioningSetAdjacency(mp, adj), "ptscotch: adjacency");
  check_petsc(MatPartitioningSetType(mp, MATPARTITIONINGPTSCOTCH), "ptscotch: type");
  check_petsc(MatPartitioningSetNParts(mp, num_ranks), "ptscotch: parts");
  check_petsc(MatPartitioningSetVertexWeights(mp, w), "ptscotch: weights");
  check_petsc(MatPartitioningApply(mp, &is), "ptscotch: MatPartitioningApply");
  const PetscInt* local;
  check_petsc(ISGetIndices(is, &local), "ptscotch: parts");
  std::vector<int> mine(local, local + m), parts(n), counts(size), offsets(size);
  check_petsc(ISRestoreIndices(is, &local), "ptscotch: parts");
  for (int r = 0; r < size; ++r) {
    counts[r] = int(begin_of(r + 1) - begin_of(r));
    offsets[r] = int(begin_of(r));
  }
  MPI_Allgatherv(mine.data(), int(m), MPI_INT, parts.data(), counts.data(), offsets.data(), MPI_INT,
                 comm);
  ISDestroy(&is);
  MatPartitioningDestroy(&mp);
  MatDestroy(&adj);
  return parts;
}

/// The blocks in Hilbert-curve order, cut into num_ranks runs of about equal cell count.
std::vector<int> curve_parts(const BlockGraph& G, const std::array<std::int64_t, 3>& nb,
                             int num_ranks) {
  int bits = 0;
  while ((std::int64_t(1) << bits) < std::max({nb[0], nb[1], nb[2]})) ++bits;
  const std::size_t n = G.weight.size();
  std::vector<std::uint64_t> key(n);
  for (std::size_t b = 0; b < n; ++b)
    key[b] = hilbert_key(std::uint32_t(G.position[b][0]), std::uint32_t(G.position[b][1]),
                         std::uint32_t(G.position[b][2]), bits);
  std::vector<std::size_t> order(n);
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](auto a, auto b) { return key[a] < key[b]; });
  const double total = std::accumulate(G.weight.begin(), G.weight.end(), 0.0);
  std::vector<int> parts(n);
  double before = 0;
  for (auto b : order) {
    // The block goes to the rank whose share holds its middle cell.
    parts[b] =
        std::min(num_ranks - 1, int((before + 0.5 * double(G.weight[b])) * num_ranks / total));
    before += double(G.weight[b]);
  }
  return parts;
}

}  // namespace

Partition partition_lattice(const lattice::Lattice& L, const VertexCopies& V, int num_ranks,
                            int superblock, int min_superblock, PartitionMethod method,
                            MPI_Comm comm, bool balance_copies) {
  Partition P;
  P.num_ranks = num_ranks;
  const std::int32_t n = L.num_cells();
  P.cell_rank.assign(n, 0);
  if (num_ranks > 1) {
    int sb = superblock;
    std::map<std::int64_t, int> block_id;  // dense super-block index -> graph vertex
    std::vector<int> block_of_cell(n);
    std::array<std::int64_t, 3> nb{};
    for (;;) {
      block_id.clear();
      for (int d = 0; d < 3; ++d) nb[d] = (L.spec.dims[d] + sb - 1) / sb;
      for (std::int32_t c = 0; c < n; ++c) {
        const auto& p = L.ijk[c];
        const std::int64_t key = p[0] / sb + nb[0] * (p[1] / sb + nb[1] * std::int64_t(p[2] / sb));
        auto it = block_id.emplace(key, int(block_id.size())).first;
        block_of_cell[c] = it->second;
      }
      if (int(block_id.size()) >= 2 * num_ranks || sb <= std::max(1, min_superblock)) break;
      sb /= 2;
    }
    P.superblock = sb;
    // Identical on every rank (replicated lattice): an input error, reported once.
    if (int(block_id.size()) < num_ranks)
      throw InputError(
          "cannot partition " + std::to_string(n) + " cells over " + std::to_string(num_ranks) +
          " ranks: whole super-blocks go to ranks, and "
          "there are " +
          std::to_string(block_id.size()) + " (of " + std::to_string(sb) +
          " cells per side); run on at most " + std::to_string(block_id.size()) + " ranks");
    auto G = block_graph(block_id, nb, block_of_cell);
    if (balance_copies) {
      G.copies.assign(G.weight.size(), 0);
      for (std::int32_t v = 0; v < V.num_copies; ++v) ++G.copies[block_of_cell[V.first_cell[v]]];
      // PT-Scotch and the curve take one weight: cells plus copies.
      if (method != PartitionMethod::metis)
        for (std::size_t b = 0; b < G.weight.size(); ++b) G.weight[b] += G.copies[b];
    }
    const auto part = method == PartitionMethod::metis      ? metis_parts(G, num_ranks)
                      : method == PartitionMethod::ptscotch ? ptscotch_parts(G, num_ranks, comm)
                                                            : curve_parts(G, nb, num_ranks);
    for (std::int32_t c = 0; c < n; ++c) P.cell_rank[c] = part[block_of_cell[c]];
  }
  P.copy_rank.resize(V.num_copies);
  for (std::int32_t v = 0; v < V.num_copies; ++v) P.copy_rank[v] = P.cell_rank[V.first_cell[v]];
  return P;
}

PartitionBalance partition_balance(const Partition& P) {
  PartitionBalance b;
  const int R = P.num_ranks;
  std::vector<std::int64_t> cells(R, 0), copies(R, 0);
  for (int r : P.cell_rank) ++cells[r];
  for (int r : P.copy_rank) ++copies[r];
  b.max_cells = *std::max_element(cells.begin(), cells.end());
  b.max_copies = *std::max_element(copies.begin(), copies.end());
  b.empty_ranks = std::count(cells.begin(), cells.end(), std::int64_t(0));
  b.mean_cells = double(P.cell_rank.size()) / R;
  b.mean_copies = double(P.copy_rank.size()) / R;
  return b;
}

PartitionStats partition_stats(const lattice::Lattice& L, const VertexCopies& V,
                               const Partition& P) {
  PartitionStats s;
  static_cast<PartitionBalance&>(s) = partition_balance(P);
  const int R = P.num_ranks;
  std::vector<std::int64_t> ghosts(R, 0);
  for (std::int32_t c = 0; c < L.num_cells(); ++c)
    for (int d = 0; d < 3; ++d)
      if (L.linked(c, d)) {
        const auto nb = L.neighbour(c, d);
        if (nb >= 0 && P.cell_rank[nb] != P.cell_rank[c]) ++s.cut_links;
      }
  // Ghosts: distinct (rank, copy) pairs of a cell's corners the cell's rank does not own.
  std::vector<std::int64_t> pairs;
  for (std::int32_t c = 0; c < L.num_cells(); ++c)
    for (auto v : V.cell_corners[c])
      if (P.copy_rank[v] != P.cell_rank[c])
        pairs.push_back(std::int64_t(P.cell_rank[c]) * V.num_copies + v);
  std::sort(pairs.begin(), pairs.end());
  pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
  for (auto p : pairs) ++ghosts[p / V.num_copies];
  s.max_ghosts = *std::max_element(ghosts.begin(), ghosts.end());
  s.ghosts = std::int64_t(pairs.size());
  return s;
}

}  // namespace hexcut::topology
