#include "multigrid/gmg.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <functional>
#include <map>
#include <set>
#include <utility>

#include "assembly/boundary.hpp"
#include "assembly/fine_cells.hpp"
#include "common/errors.hpp"
#include "common/petsc_check.hpp"
#include "element/element.hpp"
#include "multigrid/host_loop_cycle.hpp"
#include "multigrid/kernels.hpp"

namespace hexcut::multigrid {

namespace {
CycleBackendFactory the_device_cycle_factory = nullptr;
DeviceCount the_device_count = nullptr;
}  // namespace

void set_device_cycle_factory(CycleBackendFactory factory, DeviceCount count) {
  the_device_cycle_factory = factory;
  the_device_count = count;
}
int device_count(std::string* why) {
  if (!the_device_count) {
    if (why)
      *why =
          "this hexcut was built without its CUDA backend (nvcc not found at configure "
          "time, or HEXCUT_CUDA=OFF)";
    return 0;
  }
  std::string runtime;
  const int n = the_device_count(&runtime);
  if (n == 0 && why) *why = "no CUDA device is visible (" + runtime + ")";
  return n;
}
CycleBackendFactory device_cycle_factory() {
  return the_device_cycle_factory;
}

const char* loop_cycle_refusal(const Options& o) {
  // Energy rows across a material jump amplify round-off ~1e3-fold (doc/theory.md, "The CUDA
  // backend: the cycle on the loop layer"): the float cycle's rounding then made the bunny
  // example's preconditioner indefinite on 2 ranks.
  const bool float_energy =
      o.interpolation == Interpolation::energy && o.precision == Precision::single;
  return o.first_level > 0 ? "composite elements"
         : float_energy    ? "-gmg_interpolation energy with -gmg_precision single"
         : o.interpolation == Interpolation::smoothed ? "-gmg_interpolation smoothed"
         : o.schwarz_from >= 0                        ? "-gmg_schwarz_from"
                                                      : nullptr;
}

struct Multigrid::LevelData {
  DM dm = nullptr;
  bool own_dm = false;
  Vec b = nullptr, x = nullptr, r = nullptr, tmp = nullptr;  // global
  Vec dir = nullptr;                                         // global: Chebyshev direction
  Vec mask = nullptr;                                        // global: 1 free, 0 prescribed or dead
  const assembly::CellOperator* op = nullptr;                // level 0: fine_op_; else *stored
  std::unique_ptr<StoredCells> stored;                       // l >= 1: Galerkin blocks
  Children children;                                         // l >= 1: local children per cell
  // l >= 1, levels with remote children: this rank's children of coarse cells on other ranks,
  // grouped by coarse cell (ascending canonical id), and the star forest that sums each
  // group's packed product into its coarse cell's block (leaves: groups; roots: local cells).
  Children remote_groups;
  PetscSF remote_sf = nullptr;
  MPI_Datatype block_type = MPI_DATATYPE_NULL;  // kPackedSize doubles
  std::vector<double> diag_inv;                 // 9 per owned copy
  std::vector<int> colour;                      // per owned copy
  std::vector<std::int32_t> colour_list[8];     // owned copies of each colour
  std::vector<char> dirty;                      // level 0: per local cell, rebuilt by update()
  assembly::CellPositions cell_pos;             // per local cell
  std::vector<std::int32_t> local_cell;         // canonical cell -> local index, -1
  Mat P = nullptr;                              // interpolation from level l+1 (3 DOFs per copy)
  // Smoothed interpolation (levels from assembled_from_ - 1 on): the trilinear P the smoothed
  // one is made from at each full rebuild, the rows smoothed and omega; levels >=
  // assembled_from_ hold their operator as an assembled matrix instead of 24x24 blocks.
  Mat P_trilinear = nullptr;
  Mat A = nullptr;
  std::int64_t smoothed_rows = 0;
  double smoothing_omega = 0.0;
  std::unique_ptr<Schwarz> schwarz;  // Chebyshev's preconditioner where uses_schwarz(l)
  double lambda_max = 0.0;
};

namespace {

const double kIdentity3[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};

/// dR = R R0^T (row-major 3x3): the rotation that turns a block built at R0 into one at R.
void rotation_change(const double* R, const double* R0, double* dR) {
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      dR[3 * i + j] =
          R[3 * i] * R0[3 * j] + R[3 * i + 1] * R0[3 * j + 1] + R[3 * i + 2] * R0[3 * j + 2];
}

PetscErrorCode shell_mult(Mat A, Vec x, Vec y) {
  PetscFunctionBeginUser;
  Multigrid* mg;
  PetscCall(MatShellGetContext(A, &mg));
  PetscCall(mg->apply_fine(x, y));
  PetscFunctionReturn(0);
}

}  // namespace

Multigrid::Multigrid(MPI_Comm comm, const lattice::Lattice& lattice,
                     const topology::VertexCopies& copies, const topology::Partition& partition,
                     const topology::DofLayout& layout, DM fine_dm, const Options& options)
    : comm_(comm), opt_(options) {
  // One class and one set of events for the process, however many hierarchies a run
  // builds (one per cut), so -log_view sums them.
  static const std::array<PetscLogEvent, 5> events = [] {
    PetscClassId id;
    std::array<PetscLogEvent, 5> e{};
    check_petsc(PetscClassIdRegister("hexcut-gmg", &id), "class id");
    check_petsc(PetscLogEventRegister("gmgSetup", id, &e[0]), "event");
    check_petsc(PetscLogEventRegister("gmgCycle", id, &e[1]), "event");
    check_petsc(PetscLogEventRegister("gmgSmooth", id, &e[2]), "event");
    check_petsc(PetscLogEventRegister("gmgInterpSetup", id, &e[3]), "event");
    check_petsc(PetscLogEventRegister("gmgSchwarzSetup", id, &e[4]), "event");
    return e;
  }();
  ev_setup_ = events[0];
  ev_apply_ = events[1];
  ev_smooth_ = events[2];
  ev_interp_ = events[3];
  ev_schwarz_ = events[4];
  check_petsc(build(lattice, copies, partition, layout, fine_dm), "gmg: building the hierarchy");
}

PetscErrorCode Multigrid::build(const lattice::Lattice& lattice,
                                const topology::VertexCopies& copies,
                                const topology::Partition& partition,
                                const topology::DofLayout& layout, DM fine_dm) {
  PetscFunctionBeginUser;
  MPI_Comm comm = comm_;
  // Hierarchy construction counts as multigrid set-up (with update()'s operator build).
  PetscCall(PetscLogEventBegin(ev_setup_, 0, 0, 0, 0));
  const int rank = layout.rank;
  levels_ = hierarchy::build_hierarchy(topology::graph_from_lattice(lattice), copies, partition,
                                       layout, opt_.hierarchy);
  const int L = int(levels_.size());
  // Irregular coarse cells: where energy-minimizing interpolation replaces trilinear.
  irregular_.assign(L, {});
  rows_.assign(std::max(0, L - 1), {});
  energy_stats_.assign(std::max(0, L - 1), {});
  for (int l = 1; l < L; ++l)
    irregular_[l] = multigrid::irregular_cells(levels_[l - 1], levels_[l], irregular_[l - 1],
                                               l == 1 ? lattice.youngs : std::vector<double>{},
                                               l == 1 ? lattice.poisson : std::vector<double>{});
  // From here on only the energy-minimizing rows read the levels' links (at every full
  // rebuild). Otherwise they are freed: on level 0 a CSR copy of the lattice's link bits,
  // about 26 bytes per cell that every rank holds whole.
  if (opt_.interpolation != Interpolation::energy)
    for (auto& lev : levels_) {
      std::vector<std::int32_t>().swap(lev.graph.link_offset);
      std::vector<std::int32_t>().swap(lev.graph.link_target);
    }
  // Smoothed interpolation: the levels below the first transfer that is smoothed are assembled
  // (their operators are general sparse matrices, no longer one 24x24 block per cell).
  assembled_from_ = L;
  if (opt_.interpolation == Interpolation::smoothed) {
    PetscCheck(opt_.first_level == 0, comm, PETSC_ERR_SUP,
               "gmg: -gmg_interpolation smoothed is not available with composite elements");
    PetscCheck(opt_.smoother == Smoother::chebyshev, comm, PETSC_ERR_SUP,
               "gmg: -gmg_interpolation smoothed needs -gmg_smoother chebyshev (assembled levels "
               "have no colour sweeps)");
    for (int l = opt_.energy_from; l + 1 < L; ++l)
      if (has_irregular_parents(l)) {
        assembled_from_ = l + 1;
        break;
      }
  }
  for (int l = 0; l < L; ++l) {
    auto d = std::make_unique<LevelData>();
    const auto& lev = levels_[l];
    if (l == 0) {
      d->dm = fine_dm;
    } else {
      PetscCall(topology::create_dm(comm, lev.layout(), &d->dm));
      d->own_dm = true;
    }
    PetscCall(DMCreateGlobalVector(d->dm, &d->r));
    PetscCall(VecDuplicate(d->r, &d->tmp));
    PetscCall(VecDuplicate(d->r, &d->dir));
    PetscCall(VecDuplicate(d->r, &d->mask));
    if (l == opt_.first_level) {
      // No storage: cycle() places the caller's b and x in them.
      PetscInt n;
      PetscCall(VecGetLocalSize(d->r, &n));
      PetscCall(VecCreateMPIWithArray(comm, 3, n, PETSC_DETERMINE, nullptr, &d->b));
      PetscCall(VecCreateMPIWithArray(comm, 3, n, PETSC_DETERMINE, nullptr, &d->x));
    } else {
      PetscCall(VecDuplicate(d->r, &d->b));
      PetscCall(VecDuplicate(d->r, &d->x));
    }
    const auto& D = lev.layout();
    d->cell_pos.resize(D.cells.size());
    d->local_cell.assign(lev.graph.num_cells(), -1);
    for (std::size_t e = 0; e < D.cells.size(); ++e) {
      const auto& p = lev.graph.ijk[D.cells[e]];
      d->cell_pos[e] = {p[0], p[1], p[2]};
      d->local_cell[D.cells[e]] = std::int32_t(e);
    }
    d->colour.resize(D.num_owned);
    for (std::int32_t i = 0; i < D.num_owned; ++i) {
      const auto& v = lev.copies().vertex[D.copies[i]];
      d->colour[i] = element::parity_octant(v[0], v[1], v[2]);
      d->colour_list[d->colour[i]].push_back(i);
    }
    data_.push_back(std::move(d));
  }
  // Children of every local coarse cell on this rank; on levels with remote children also
  // this rank's children of coarse cells elsewhere (remote_groups).
  for (int l = 1; l < L; ++l) {
    auto& d = *data_[l];
    auto& ch = d.children;
    const auto& fine = levels_[l - 1];
    const std::size_t n = levels_[l].layout().cells.size();
    ch.offset.assign(n + 1, 0);
    std::vector<std::int32_t> parent_of(fine.layout().cells.size());
    std::vector<std::pair<std::int32_t, std::int32_t>> remote;  // (coarse cell, local child)
    for (std::size_t e = 0; e < fine.layout().cells.size(); ++e) {
      const auto P = fine.parent[fine.layout().cells[e]];
      const auto C = d.local_cell[P];
      parent_of[e] = C;
      if (C >= 0)
        ++ch.offset[C + 1];
      else
        remote.emplace_back(P, std::int32_t(e));
    }
    PetscCheck(remote.empty() || levels_[l].remote_children, PETSC_COMM_SELF, PETSC_ERR_PLIB,
               "gmg: level %d has remote children it does not know of", l);
    PetscCheck(!levels_[l].remote_children || l > opt_.first_level, comm, PETSC_ERR_PLIB,
               "gmg: the composite level %d has children on other ranks", l);
    for (std::size_t C = 0; C < n; ++C) ch.offset[C + 1] += ch.offset[C];
    ch.child.resize(std::size_t(ch.offset[n]));
    std::vector<std::int32_t> next(ch.offset.begin(), ch.offset.end() - 1);
    for (std::size_t e = 0; e < fine.layout().cells.size(); ++e)
      if (parent_of[e] >= 0) ch.child[next[parent_of[e]]++] = std::int32_t(e);
    if (l >= assembled_from_) continue;  // an assembled level: no blocks
    d.stored = std::make_unique<StoredCells>(
        levels_[l].layout(), l > opt_.first_level ? opt_.precision : Precision::double_);
    d.op = d.stored.get();
    if (levels_[l].remote_children) PetscCall(build_remote_groups(l, std::move(remote)));
  }
  // Interpolation l+1 -> l as a scalar AIJ over copies, expanded to 3 DOFs with MAIJ.
  for (int l = 0; l + 1 < L; ++l) {
    const auto I = hierarchy::interpolation(levels_[l], levels_[l + 1], rank);
    const auto& fine = levels_[l].layout();
    const auto& coarse = levels_[l + 1].layout();
    // Exact preallocation: a row holds 1-8 weights (3.4 on average), and AIJ keeps the
    // preallocated length after assembly, so a uniform 8 + 8 would store 16 per row.
    const PetscInt fine_begin = fine.first_owned_block(), coarse_begin = coarse.first_owned_block();
    const PetscInt coarse_end = coarse_begin + coarse.num_owned;
    std::vector<PetscInt> d_nnz(fine.num_owned, 0), o_nnz(fine.num_owned, 0);
    for (std::size_t i = 0; i < I.fine.size(); ++i) {
      const PetscInt row = fine.global_block[I.fine[i]] - fine_begin;
      for (int j = 0; j < 8 && I.coarse[i][j] >= 0; ++j) {
        const PetscInt col = coarse.global_block[I.coarse[i][j]];
        ++(col >= coarse_begin && col < coarse_end ? d_nnz : o_nnz)[row];
      }
    }
    Mat P;
    PetscCall(MatCreateAIJ(comm, fine.num_owned, coarse.num_owned, PETSC_DETERMINE, PETSC_DETERMINE,
                           0, d_nnz.data(), 0, o_nnz.data(), &P));
    for (std::size_t i = 0; i < I.fine.size(); ++i) {
      const PetscInt row = fine.global_block[I.fine[i]];
      for (int j = 0; j < 8 && I.coarse[i][j] >= 0; ++j)
        PetscCall(MatSetValue(P, row, coarse.global_block[I.coarse[i][j]], I.weight[i][j],
                              INSERT_VALUES));
    }
    PetscCall(MatAssemblyBegin(P, MAT_FINAL_ASSEMBLY));
    PetscCall(MatAssemblyEnd(P, MAT_FINAL_ASSEMBLY));
    PetscCall(MatCreateMAIJ(P, 3, &data_[l]->P));
    PetscCall(MatDestroy(&P));
    if (l + 1 >= assembled_from_) {
      data_[l]->P_trilinear = data_[l]->P;
      PetscCall(PetscObjectReference((PetscObject)data_[l]->P));
    }
  }
  const int first = opt_.first_level;
  PetscCheck(first < L, comm, PETSC_ERR_USER_INPUT,
             "composite elements of level %d need %d hierarchy levels, but the lattice is a "
             "single cell after %d",
             first, first + 1, L);
  // Composite runs count -gmg_levels from the composite level (analysis/simulation.cpp adds
  // first_level to the user's figure): the message counts the same way.
  PetscCheck(opt_.hierarchy.levels == 0 || L == opt_.hierarchy.levels, comm, PETSC_ERR_USER_INPUT,
             "-gmg_levels %d: the lattice is a single cell after %d levels; ask for at most %d",
             opt_.hierarchy.levels - first, L - first, L - first);
  // Composite runs: each fine cell's ancestor on the first level (its composite element; all
  // on this rank), and a fine cell of each such element, whose rotation is the element's.
  if (first > 0) {
    const auto& fine = levels_[0].layout();
    const auto& top = levels_[first];
    std::vector<std::int32_t> local(top.graph.num_cells(), -1);
    for (std::size_t C = 0; C < top.layout().cells.size(); ++C)
      local[top.layout().cells[C]] = std::int32_t(C);
    composite_element_.resize(fine.cells.size());
    composite_fine_cell_.assign(top.layout().cells.size(), -1);
    for (std::size_t e = 0; e < fine.cells.size(); ++e) {
      std::int32_t c = fine.cells[e];
      for (int k = 0; k < first; ++k) c = levels_[k].parent[c];
      PetscCheck(local[c] >= 0, PETSC_COMM_SELF, PETSC_ERR_PLIB,
                 "gmg: a composite element is not on the rank of its fine cells");
      composite_element_[e] = local[c];
      if (composite_fine_cell_[local[c]] < 0) composite_fine_cell_[local[c]] = std::int32_t(e);
    }
    // Local fine cells are in ascending canonical order: an element's first is its smallest.
    composite_keys_.resize(top.layout().cells.size());
    for (std::size_t C = 0; C < composite_keys_.size(); ++C)
      composite_keys_[C].first_cell = fine.cells[std::size_t(composite_fine_cell_[C])];
    for (auto C : composite_element_) ++composite_keys_[std::size_t(C)].num_cells;
    chain_missing_.assign(fine.cells.size(), 0);
  }
  const auto& D0 = levels_[first].layout();
  PetscCall(MatCreateShell(comm, 3 * D0.num_owned, 3 * D0.num_owned, PETSC_DETERMINE,
                           PETSC_DETERMINE, this, &shell_));
  PetscCall(MatShellSetOperation(shell_, MATOP_MULT, (void (*)(void))shell_mult));
  PetscCall(MatSetBlockSize(shell_, 3));
  PetscCall(MatSetOption(shell_, MAT_SYMMETRIC, PETSC_TRUE));
  PetscCall(MatSetOption(shell_, MAT_SPD, PETSC_TRUE));
  PetscCall(PetscLogEventEnd(ev_setup_, 0, 0, 0, 0));
  PetscFunctionReturn(0);
}

PetscErrorCode Multigrid::build_remote_groups(
    int l, std::vector<std::pair<std::int32_t, std::int32_t>> remote) {
  PetscFunctionBeginUser;
  auto& d = *data_[l];
  const auto& coarse = levels_[l];
  // Each rank's cells are in ascending canonical order: the position of coarse cell C among
  // its owner's cells is its root index there (the partition is known to every rank).
  std::vector<PetscInt> index_on_owner(std::size_t(coarse.graph.num_cells()));
  {
    std::vector<PetscInt> count(std::size_t(coarse.partition().num_ranks), 0);
    for (std::int32_t C = 0; C < coarse.graph.num_cells(); ++C)
      index_on_owner[std::size_t(C)] = count[std::size_t(coarse.partition().cell_rank[C])]++;
  }
  std::sort(remote.begin(), remote.end());
  auto& g = d.remote_groups;
  g.offset.assign(1, 0);
  g.child.clear();
  std::vector<PetscSFNode> roots;
  for (std::size_t k = 0; k < remote.size(); ++k) {
    const auto C = remote[k].first;
    if (k == 0 || C != remote[k - 1].first) {
      if (k > 0) g.offset.push_back(std::int32_t(k));
      roots.push_back({coarse.partition().cell_rank[C], index_on_owner[std::size_t(C)]});
    }
    g.child.push_back(remote[k].second);
  }
  if (!remote.empty()) g.offset.push_back(std::int32_t(remote.size()));
  PetscCall(PetscSFCreate(comm_, &d.remote_sf));
  PetscCall(PetscSFSetGraph(d.remote_sf, PetscInt(coarse.layout().cells.size()),
                            PetscInt(roots.size()), nullptr, PETSC_COPY_VALUES, roots.data(),
                            PETSC_COPY_VALUES));
  PetscCall(PetscSFSetUp(d.remote_sf));
  PetscCallMPI(MPI_Type_contiguous(int(kPackedSize), MPI_DOUBLE, &d.block_type));
  PetscCallMPI(MPI_Type_commit(&d.block_type));
  PetscFunctionReturn(0);
}

PetscErrorCode Multigrid::remote_products(int l, const ChildGalerkin* fast,
                                          std::vector<double>* sum) {
  PetscFunctionBeginUser;
  auto& d = *data_[l];
  const auto& fd = *data_[l - 1];
  const std::size_t groups = d.remote_groups.offset.size() - 1;
  std::vector<double> leaves(kPackedSize * groups);
  children_products(*fd.op, fd.cell_pos, d.remote_groups, fast, leaves.data());
  sum->assign(kPackedSize * levels_[l].layout().cells.size(), 0.0);
  PetscCall(PetscSFReduceBegin(d.remote_sf, d.block_type, leaves.data(), sum->data(), MPI_SUM));
  PetscCall(PetscSFReduceEnd(d.remote_sf, d.block_type, leaves.data(), sum->data(), MPI_SUM));
  PetscFunctionReturn(0);
}

Multigrid::~Multigrid() {
  for (auto& d : data_) {
    VecDestroy(&d->b);
    VecDestroy(&d->x);
    VecDestroy(&d->r);
    VecDestroy(&d->tmp);
    VecDestroy(&d->dir);
    VecDestroy(&d->mask);
    MatDestroy(&d->P);
    MatDestroy(&d->P_trilinear);
    MatDestroy(&d->A);
    PetscSFDestroy(&d->remote_sf);
    if (d->block_type != MPI_DATATYPE_NULL) MPI_Type_free(&d->block_type);
    if (d->own_dm) DMDestroy(&d->dm);
  }
  MatDestroy(&shell_);
  MatDestroy(&coarse_matrix_);
  KSPDestroy(&coarse_ksp_);
}

DM Multigrid::dm(int l) const {
  return data_[l]->dm;
}
Mat Multigrid::interpolation(int l) const {
  return data_[l]->P;
}
Vec Multigrid::mask(int l) const {
  return data_[l]->mask;
}
PetscErrorCode Multigrid::create_vector(int l, Vec* v) const {
  return DMCreateGlobalVector(data_[l]->dm, v);
}

std::vector<std::int32_t> Multigrid::fine_block_keys(const assembly::CellData& cells) const {
  // A fine cell's product with the trilinear weights depends on its stiffness (its kind),
  // density (when the operator has mass) and mask only (rotations are the identity here).
  const auto d = fine_op_->data();
  std::map<std::pair<std::int32_t, double>, std::int32_t> id;
  std::vector<std::int32_t> key(cells.kind.size(), -1);
  for (std::size_t e = 0; e < key.size(); ++e) {
    if (cells.kind[e] < 0 || (d.cell_masked && d.cell_masked[e])) continue;
    const double rho = weights_.mass != 0.0 ? cells.rho[e] : 0.0;
    key[e] = id.emplace(std::make_pair(cells.kind[e], rho), std::int32_t(id.size())).first->second;
  }
  return key;
}

std::vector<std::int32_t> Multigrid::shared_block_keys(
    int l, const std::vector<std::int32_t>& below) const {
  // Coarse cell C's block is sum_c W_c^T A_c W_c over its children, W_c the trilinear weights
  // of child c's octant: it depends on the children's blocks and octants only (not on how
  // the children are linked: their corner copies do not enter). So cells whose children all
  // share one key k and fill the same octants share a block: key (k, octants). A cell with
  // children on other ranks (their products arrive summed, remote_products) keeps its own.
  const auto& fine = levels_[l - 1];
  const auto& ch = data_[l]->children;
  const auto& pos = data_[l - 1]->cell_pos;
  const auto& coarse_cells = levels_[l].layout().cells;
  std::vector<std::int32_t> total;  // children per canonical coarse cell, on every rank
  if (levels_[l].remote_children) {
    total.assign(std::size_t(levels_[l].graph.num_cells()), 0);
    for (auto P : fine.parent) ++total[std::size_t(P)];
  }
  std::map<std::pair<std::int32_t, int>, std::int32_t> id;
  std::vector<std::int32_t> key(coarse_cells.size(), -1);
  for (std::size_t C = 0; C < key.size(); ++C) {
    const auto n = ch.offset[C + 1] - ch.offset[C];
    if (n == 0 || (!total.empty() && total[std::size_t(coarse_cells[C])] != n)) continue;
    const std::int32_t k = below[std::size_t(ch.child[ch.offset[C]])];
    int octants = 0;
    bool same = k >= 0;
    for (auto i = ch.offset[C]; i < ch.offset[C + 1] && same; ++i) {
      const auto e = std::size_t(ch.child[i]);
      octants |= 1 << element::parity_octant(pos[e][0], pos[e][1], pos[e][2]);
      same = below[e] == k;
    }
    if (same)
      key[C] = id.emplace(std::make_pair(k, octants), std::int32_t(id.size())).first->second;
  }
  return key;
}

void Multigrid::mark_dirty_fine_cells(const assembly::CellData& cells, bool full) {
  // A fine cell is dirty when its rotation moved by more than the tolerance since the
  // block of its parent was built (or on a full rebuild), or when the blocks above it
  // were never built (its composite element's block was carried over a cut).
  auto& d = *data_[0];
  const std::size_t n = levels_[0].layout().cells.size();
  d.dirty.assign(n, full ? 1 : 0);
  if (full) return;
  const double tol = opt_.rebuild_tolerance;
  // No rotations stored (linear runs): none moved (a change to or from identity is a full
  // rebuild: update() compares the sizes).
  const bool rotations = !cells.rotation.empty();
  for (std::size_t e = 0; e < n; ++e) {
    d.dirty[e] = !chain_missing_.empty() && chain_missing_[e];
    if (!rotations) continue;
    const double* now = &cells.rotation[9 * e];
    const double* then = &built_rotation_[9 * e];
    for (int k = 0; k < 9 && !d.dirty[e]; ++k)
      if (std::abs(now[k] - then[k]) > tol) d.dirty[e] = 1;
  }
}

std::vector<std::int32_t> match_composite_elements(const std::vector<CompositeKey>& from,
                                                   const std::vector<CompositeKey>& to) {
  // Both in ascending first_cell (the order of the elements' first fine cells): one merge.
  std::vector<std::int32_t> k(from.size());
  for (std::size_t i = 0; i < k.size(); ++i) k[i] = std::int32_t(i);
  std::sort(k.begin(), k.end(), [&](std::int32_t a, std::int32_t b) {
    return from[a].first_cell < from[b].first_cell;
  });
  std::vector<std::int32_t> match(to.size(), -1);
  for (std::size_t i = 0; i < to.size(); ++i) {
    const auto it =
        std::lower_bound(k.begin(), k.end(), to[i].first_cell,
                         [&](std::int32_t a, std::int32_t v) { return from[a].first_cell < v; });
    if (it != k.end() && from[*it] == to[i]) match[i] = *it;
  }
  return match;
}

const double* Multigrid::element_rotation(const assembly::CellData& cells, std::size_t C) const {
  return cells.rotation.size() == 9 * levels_[0].layout().cells.size()
             ? &cells.rotation[9 * std::size_t(composite_fine_cell_[C])]
             : kIdentity3;
}

const StoredCells& Multigrid::stored_cells(int l) const {
  return *data_[l]->stored;
}

const assembly::CellPositions& Multigrid::cell_positions(int l) const {
  return data_[l]->cell_pos;
}

PetscErrorCode Multigrid::solve_coarsest(const double* b, double* x) {
  PetscFunctionBeginUser;
  auto& d = *data_[num_levels() - 1];
  PetscCall(VecPlaceArray(d.b, b));
  PetscCall(VecPlaceArray(d.x, x));
  const PetscErrorCode ierr = KSPSolve(coarse_ksp_, d.b, d.x);
  PetscCall(VecResetArray(d.b));
  PetscCall(VecResetArray(d.x));
  PetscCall(ierr);
  PetscFunctionReturn(0);
}

const assembly::CellOperator* Multigrid::cell_operator(int l) const {
  return data_[l]->A ? nullptr : data_[l]->op;
}

PetscErrorCode Multigrid::scalar_prolongation(
    int l, PetscInt coarse_begin, const std::function<std::int32_t(PetscInt)>& coarse_local,
    LoopLevelArrays* a) const {
  PetscFunctionBeginUser;
  // The scalar AIJ inside the trilinear MAIJ: rows the owned fine copies, columns coarse global
  // blocks (on more ranks, its diagonal part the owned coarse copies, its off-diagonal part
  // the others through colmap).
  const auto& D = levels_[l].layout();
  Mat S, parts[2] = {nullptr, nullptr};
  const PetscInt* colmap = nullptr;
  PetscCall(MatMAIJGetAIJ(data_[l]->P, &S));
  PetscBool mpi;
  PetscCall(PetscObjectTypeCompare(reinterpret_cast<PetscObject>(S), MATMPIAIJ, &mpi));
  if (mpi)
    PetscCall(MatMPIAIJGetSeqAIJ(S, &parts[0], &parts[1], &colmap));
  else
    parts[0] = S;
  a->prolong_weight.assign(8 * std::size_t(D.num_owned), 0.0);
  std::vector<int> filled(std::size_t(D.num_owned), 0);
  for (int part = 0; part < 2; ++part) {
    if (!parts[part]) continue;
    PetscInt rows;
    const PetscInt *ia, *ja;
    PetscBool done;
    PetscCall(MatGetRowIJ(parts[part], 0, PETSC_FALSE, PETSC_FALSE, &rows, &ia, &ja, &done));
    bool shape_ok = done && rows == D.num_owned;
    for (PetscInt f = 0; shape_ok && f < rows; ++f)
      shape_ok = filled[std::size_t(f)] + (ia[f + 1] - ia[f]) <= 8;
    if (!shape_ok) {
      if (done)
        PetscCall(
            MatRestoreRowIJ(parts[part], 0, PETSC_FALSE, PETSC_FALSE, &rows, &ia, &ja, &done));
      SETERRQ(PETSC_COMM_SELF, PETSC_ERR_PLIB,
              "gmg: level %d's interpolation is not one row of at most 8 weights per copy", l);
    }
    const PetscScalar* w;
    PetscCall(MatSeqAIJGetArrayRead(parts[part], &w));
    for (PetscInt f = 0; f < rows; ++f)
      for (PetscInt k = ia[f]; k < ia[f + 1]; ++k) {
        const PetscInt g = part == 0 ? (mpi ? coarse_begin + ja[k] : ja[k]) : colmap[ja[k]];
        const auto j = 8 * std::size_t(f) + std::size_t(filled[std::size_t(f)]++);
        a->prolong_coarse[j] = coarse_local(g);
        a->prolong_weight[j] = w[k];
      }
    PetscCall(MatSeqAIJRestoreArrayRead(parts[part], &w));
    PetscCall(MatRestoreRowIJ(parts[part], 0, PETSC_FALSE, PETSC_FALSE, &rows, &ia, &ja, &done));
  }
  PetscFunctionReturn(0);
}

PetscErrorCode Multigrid::block_prolongation(
    int l, const std::function<std::int32_t(PetscInt)>& coarse_local, LoopLevelArrays* a) const {
  PetscFunctionBeginUser;
  // Energy-minimizing rows: P is a BAIJ of 3x3 blocks (interpolation_matrix). Its rows read one
  // scalar row at a time (global column 3C + b: block column C, component b), so that the
  // blocks come out row-major whatever the matrix stores.
  const auto& D = levels_[l].layout();
  Mat P = data_[l]->P;
  PetscInt first;
  PetscCall(MatGetOwnershipRange(P, &first, nullptr));
  a->view.weight_block = 9;
  a->prolong_weight.assign(72 * std::size_t(D.num_owned), 0.0);
  for (std::int32_t f = 0; f < D.num_owned; ++f) {
    PetscInt block_col[8];
    int n = 0;
    for (int r = 0; r < 3; ++r) {
      PetscInt nc;
      const PetscInt* cols;
      const PetscScalar* vals;
      PetscCall(MatGetRow(P, first + 3 * f + r, &nc, &cols, &vals));
      for (PetscInt k = 0; k < nc; ++k) {
        const PetscInt C = cols[k] / 3;
        int j = 0;
        while (j < n && block_col[j] != C) ++j;
        if (j == n) {
          if (n == 8) {
            PetscCall(MatRestoreRow(P, first + 3 * f + r, &nc, &cols, &vals));
            SETERRQ(PETSC_COMM_SELF, PETSC_ERR_PLIB,
                    "gmg: level %d's interpolation has more than 8 coarse copies in a row", l);
          }
          block_col[n++] = C;
        }
        a->prolong_weight[72 * std::size_t(f) + 9 * std::size_t(j) + 3 * std::size_t(r) +
                          std::size_t(cols[k] % 3)] = vals[k];
      }
      PetscCall(MatRestoreRow(P, first + 3 * f + r, &nc, &cols, &vals));
    }
    for (int j = 0; j < n; ++j)
      a->prolong_coarse[8 * std::size_t(f) + j] = coarse_local(block_col[j]);
  }
  PetscFunctionReturn(0);
}

PetscErrorCode Multigrid::loop_levels(std::vector<LoopLevelArrays>* out) const {
  PetscFunctionBeginUser;
  const char* why = loop_cycle_refusal(opt_);
  if (!why && !built_) why = "a cycle before the first update()";
  PetscCheck(!why, comm_, PETSC_ERR_SUP,
             "gmg: the loop-layer cycle (-gmg_backend cuda) does not support %s yet; the host "
             "backend does",
             why);
  const int L = num_levels();
  for (int l = 0; l + 1 < L; ++l)
    PetscCheck(cell_operator(l), comm_, PETSC_ERR_SUP,
               "gmg: the loop-layer cycle needs cells on level %d, which is assembled", l);
  out->clear();
  out->resize(L);
  // Per level: the coarse copies its finer level's transfer reaches that are neither owned nor
  // ghosts of its cells (global blocks), appended after the layout's ghosts.
  std::vector<std::vector<PetscInt>> extra(L);
  for (int l = 0; l < L; ++l) {
    auto& a = (*out)[l];
    const auto& D = levels_[l].layout();
    const auto owner = [&D](PetscInt g) {  // the last rank whose range begins at or before g
      const auto after = std::upper_bound(D.owned_begin.begin(), D.owned_begin.end(), g);
      return int(after - D.owned_begin.begin() - 1);
    };
    const auto add_ghost = [&](PetscInt g) {
      const int r = owner(g);
      a.ghost_rank.push_back(r);
      a.ghost_index.push_back(std::int32_t(g - D.owned_begin[std::size_t(r)]));
    };
    for (std::int32_t i = D.num_owned; i < D.num_local(); ++i)
      add_ghost(D.global_block[std::size_t(D.copies[std::size_t(i)])]);
    for (const PetscInt g : extra[l]) add_ghost(g);
    const PetscScalar* m;
    PetscCall(VecGetArrayRead(data_[l]->mask, &m));
    a.mask.assign(m, m + 3 * std::size_t(D.num_owned));
    PetscCall(VecRestoreArrayRead(data_[l]->mask, &m));
    a.view.num_copies = D.num_owned;
    a.view.num_local = D.num_local() + std::int64_t(extra[l].size());
    a.view.diag_inv = data_[l]->diag_inv.empty() ? nullptr : data_[l]->diag_inv.data();
    a.view.lambda_max = data_[l]->lambda_max;
    // Multigrid::smooth: Chebyshev's degrees grow on irregular levels, Gauss-Seidel's sweeps
    // do not.
    const bool gs = opt_.smoother == Smoother::gauss_seidel;
    a.view.presmooth = gs ? opt_.presmooth : degree(l, opt_.presmooth);
    a.view.postsmooth = gs ? opt_.postsmooth : degree(l, opt_.postsmooth);
    a.view.gauss_seidel = gs;
    a.view.omega = opt_.omega;
    for (int k = 0; k < 8 && gs; ++k) {
      const auto& list = data_[l]->colour_list[k];
      a.colour_copy.insert(a.colour_copy.end(), list.begin(), list.end());
      a.view.colour_begin[k + 1] = std::int64_t(a.colour_copy.size());
    }
    a.view.colour_copy = a.colour_copy.data();
    if (l + 1 < L) {
      // The weights the cycle's interpolation holds: the scalar AIJ inside the MAIJ, whose rows
      // are this rank's owned fine copies and whose columns are coarse global blocks (on more
      // ranks, in its diagonal part the owned coarse copies, in its off-diagonal part others).
      const auto& C = levels_[l + 1].layout();
      const PetscInt coarse_begin = C.first_owned_block();
      std::map<PetscInt, std::int32_t> local_of;  // coarse ghosts: global block -> local copy
      for (std::int32_t i = C.num_owned; i < C.num_local(); ++i)
        local_of[C.global_block[std::size_t(C.copies[std::size_t(i)])]] = i;
      const auto coarse_local = [&](PetscInt g) {
        if (g >= coarse_begin && g < coarse_begin + C.num_owned)
          return std::int32_t(g - coarse_begin);
        const auto [it, added] =
            local_of.emplace(g, C.num_local() + std::int32_t(extra[l + 1].size()));
        if (added) extra[l + 1].push_back(g);
        return it->second;
      };
      a.prolong_coarse.assign(8 * std::size_t(D.num_owned), -1);
      const PetscErrorCode read = rows_[l].empty()
                                      ? scalar_prolongation(l, coarse_begin, coarse_local, &a)
                                      : block_prolongation(l, coarse_local, &a);
      // Collective: a rank whose rows do not fit must not leave the others waiting in the
      // executors' halo set-up.
      int failed = read != 0;
      PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, &failed, 1, MPI_INT, MPI_MAX, comm_));
      PetscCheck(!failed, comm_, PETSC_ERR_PLIB,
                 "gmg: level %d's interpolation could not be read for the loop-layer cycle", l);
      // The restriction: the same weights gathered per coarse local copy (ghosts included).
      const auto num_coarse = std::size_t(C.num_local()) + extra[l + 1].size();
      a.restrict_offset.assign(num_coarse + 1, 0);
      for (const auto c : a.prolong_coarse)
        if (c >= 0) ++a.restrict_offset[std::size_t(c) + 1];
      for (std::size_t c = 0; c < num_coarse; ++c) a.restrict_offset[c + 1] += a.restrict_offset[c];
      a.restrict_fine.resize(std::size_t(a.restrict_offset.back()));
      const auto block = std::size_t(a.view.weight_block);
      a.restrict_weight.resize(block * a.restrict_fine.size());
      std::vector<std::int32_t> next(a.restrict_offset.begin(), a.restrict_offset.end() - 1);
      for (std::int32_t f = 0; f < D.num_owned; ++f)
        for (int k = 0; k < 8 && a.prolong_coarse[8 * std::size_t(f) + k] >= 0; ++k) {
          const auto j = 8 * std::size_t(f) + std::size_t(k);
          const auto c = a.prolong_coarse[j];
          a.restrict_fine[next[c]] = f;
          std::copy_n(&a.prolong_weight[block * j], block,
                      &a.restrict_weight[block * std::size_t(next[c]++)]);
        }
      a.view.num_coarse = std::int64_t(num_coarse);
      a.view.prolong_coarse = a.prolong_coarse.data();
      a.view.prolong_weight = a.prolong_weight.data();
      a.view.restrict_offset = a.restrict_offset.data();
      a.view.restrict_fine = a.restrict_fine.data();
      a.view.restrict_weight = a.restrict_weight.data();
    }
    a.view.mask = a.mask.data();
  }
  PetscFunctionReturn(0);
}

bool Multigrid::has_stored_cells(int l) const {
  return l >= 1 && data_[l]->stored != nullptr;
}

CompositeBlocks Multigrid::composite_blocks() const {
  CompositeBlocks b;
  const int first = opt_.first_level;
  if (first == 0 || !built_) return b;
  const auto& stored = *data_[first]->stored;
  const auto& corners = levels_[first].layout().cell_corners;
  const std::size_t n = composite_keys_.size();
  b.keys = composite_keys_;
  b.packed.resize(kPackedSize * n);
  b.rotation.resize(9 * n);
  b.mask.resize(24 * n);
  for (std::size_t C = 0; C < n; ++C) {
    std::copy_n(stored.block(C), kPackedSize, &b.packed[kPackedSize * C]);
    std::copy_n(composite_rotation_.empty() ? kIdentity3 : &composite_rotation_[9 * C], 9,
                &b.rotation[9 * C]);
    for (int i = 0; i < 24; ++i)
      b.mask[24 * C + i] = composite_mask_[3 * std::size_t(corners[C][i / 3]) + i % 3];
  }
  b.fine_fixed = composite_fine_fixed_;
  b.weights = weights_;
  return b;
}

PetscErrorCode Multigrid::take_carried_blocks(const assembly::CellData& cells,
                                              std::vector<char>* carried) {
  PetscFunctionBeginUser;
  const int first = opt_.first_level;
  auto& stored = *data_[first]->stored;
  const auto& corners = levels_[first].layout().cell_corners;
  const std::size_t n = composite_keys_.size();
  carried->assign(n, 0);
  const auto& c = carried_;
  const bool same_weights = c.weights.stiffness == weights_.stiffness &&
                            c.weights.mass == weights_.mass &&
                            c.weights.lumped_mass == weights_.lumped_mass;
  const auto from = match_composite_elements(c.keys, composite_keys_);
  for (std::size_t C = 0; C < n && same_weights; ++C) {
    const auto k = std::size_t(from[C]);
    if (from[C] < 0 || c.fine_fixed[k] != composite_fine_fixed_[C]) continue;
    bool same_mask = true;
    for (int i = 0; i < 24; ++i)
      same_mask &=
          c.mask[24 * k + i] == composite_mask_[3 * std::size_t(corners[C][i / 3]) + i % 3];
    if (!same_mask) continue;
    // The block was built (or rotated) at R0; the element now turns with R: dR = R R0^T.
    const double* R = element_rotation(cells, C);
    const double* R0 = &c.rotation[9 * k];
    const bool turned = !std::equal(R, R + 9, R0);
    if (turned && !rotatable_) continue;
    stored.set_block(C, &c.packed[kPackedSize * k]);
    if (turned) {
      double dR[9];
      rotation_change(R, R0, dR);
      stored.rotate_block(C, dR);
    }
    (*carried)[C] = 1;
  }
  carried_ = CompositeBlocks{};
  PetscFunctionReturn(0);
}

PetscErrorCode Multigrid::update(const assembly::CellData& cells,
                                 const assembly::OperatorWeights& w,
                                 const std::vector<PetscInt>& constrained_rows) {
  PetscFunctionBeginUser;
  PetscCall(PetscLogEventBegin(ev_setup_, 0, 0, 0, 0));
  // A backend cycle holds copies of the levels: none survives an update (nor a failed one).
  backend_cycle_.reset();
  const int L = num_levels();
  // Anything but rotations changed: rebuild everything (a collective decision).
  int full = !built_ || w.stiffness != weights_.stiffness || w.mass != weights_.mass ||
             w.lumped_mass != weights_.lumped_mass || constrained_rows != built_rows_ ||
             built_rotation_.size() != cells.rotation.size() || assembled_from_ < L;
  // (Assembled levels have no partial rebuild: every update rebuilds them.)
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, &full, 1, MPI_INT, MPI_LOR, comm_));
  weights_ = w;
  rebuilt_.assign(L, 0);
  auto& d0 = *data_[0];
  const auto& D0 = levels_[0].layout();
  // The fine operator always uses the current rotations, whatever is rebuilt above it. A
  // full rebuild (also after invalidate(): material data may have changed) makes a new one,
  // which forms the stiffness of cells without a kind once; rotation-only updates keep it.
  if (!fine_op_ || fine_cells_ != &cells || full) {
    fine_op_ = std::make_unique<assembly::FineCells>(D0, cells, w, true);
    fine_tables_ = fine_galerkin_tables(cells);
    fine_cells_ = &cells;
    d0.op = fine_op_.get();
  } else {
    fine_op_->set_weights(w);
  }
  if (full) {
    // Level 0 mask from the prescribed rows, as the assembled path's (assembly/boundary.hpp).
    built_rows_ = constrained_rows;
    std::vector<double> mask;
    PetscCall(assembly::dirichlet_mask(d0.dm, constrained_rows, d0.mask, &mask));
    if (opt_.first_level > 0) {
      composite_fine_fixed_.assign(composite_keys_.size(), 0);
      for (std::size_t e = 0; e < D0.cells.size(); ++e)
        for (auto q : D0.cell_corners[e])
          for (int c = 0; c < 3; ++c)
            composite_fine_fixed_[std::size_t(composite_element_[e])] +=
                mask[3 * std::size_t(q) + c] == 0.0;
    }
    fine_op_->set_mask(std::move(mask));
    if (opt_.first_level > 0) PetscCall(build_composite_mask());
  }
  const int first = opt_.first_level;
  // After a cut: the blocks of the elements it left whole are carried over.
  std::vector<char> carried;
  if (full && first > 0 && !carried_.keys.empty()) PetscCall(take_carried_blocks(cells, &carried));
  if (full) carried_cells_ = std::count(carried.begin(), carried.end(), char(1));
  bool rotated = false;
  if (!full && first > 0) PetscCall(rotate_composite_blocks(cells, &rotated));
  // Rotated composite blocks need no fine cell: none is compared or marked.
  if (rotated)
    d0.dirty.assign(levels_[0].layout().cells.size(), 0);
  else
    mark_dirty_fine_cells(cells, full);
  if (!carried.empty())
    for (std::size_t e = 0; e < d0.dirty.size(); ++e)
      if (carried[std::size_t(composite_element_[e])]) d0.dirty[e] = 0, chain_missing_[e] = 1;
  if (first == 0) PetscCall(build_diagonal(0));
  for (char c : d0.dirty) rebuilt_[0] += c;
  if (uses_schwarz(0)) PetscCall(build_schwarz(0));
  // Galerkin coarse blocks, level by level, for the coarse cells with a dirty child.
  if (built_rotation_.size() != cells.rotation.size())
    built_rotation_.assign(cells.rotation.size(), 0.0);
  // Shared blocks, decided at each full rebuild (the materials or the mask may have changed):
  // linear runs of hexahedra with trilinear transfers, where equal children make equal blocks.
  // (A change to rotations is a full rebuild too: the blocks are then a cell's own again.)
  const bool share = full && opt_.shared_blocks && first == 0 && cells.identity_rotations &&
                     opt_.interpolation == Interpolation::trilinear;
  std::vector<std::int32_t> keys;
  if (share) keys = fine_block_keys(cells);
  for (int l = 1; l < L; ++l) {
    if (l == assembled_from_) {
      PetscCall(build_smoothed_chain());
      for (int k = l; k < L; ++k) rebuilt_[k] = std::int64_t(levels_[k].layout().cells.size());
      break;
    }
    auto& d = *data_[l];
    const auto& fd = *data_[l - 1];
    // The interpolation to level l-1 depends on its operator: recomputed on full rebuilds
    // (kept across rotation-only updates, whose operators differ by rotations only).
    if (full && l - 1 >= first) PetscCall(build_interpolation(l - 1));
    if (share) {
      keys = shared_block_keys(l, keys);
      d.stored->share(keys);
    } else if (full && d.stored->block_of()) {
      d.stored->share({});
    }
    if (rotated && l <= first) {
      // Levels below the composite one are not needed; the composite blocks were rotated.
      rebuilt_[l] = l == first ? std::int64_t(d.stored->dirty().size()) : 0;
    } else if (levels_[l].remote_children) {
      // Children on several ranks: rebuilt whole wherever any block above it changed (a
      // collective decision), from the local children and the others' summed products.
      const auto& fine_dirty = l == 1 ? d0.dirty : fd.stored->dirty();
      int any = std::find(fine_dirty.begin(), fine_dirty.end(), char(1)) != fine_dirty.end();
      PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, &any, 1, MPI_INT, MPI_LOR, comm_));
      const FineChildGalerkin fine_products(fine_tables_, fine_op_->data());
      const ChildGalerkin* fast = l == 1 ? &fine_products : nullptr;
      if (any) {
        std::vector<double> sum;
        PetscCall(remote_products(l, fast, &sum));
        rebuilt_[l] = d.stored->galerkin(*fd.op, fd.cell_pos, d.children, fine_dirty, nullptr, fast,
                                         sum.data());
        if (l == 1) built_rotation_ = cells.rotation;  // every fine cell's block was rebuilt
      } else {
        rebuilt_[l] = d.stored->galerkin(*fd.op, fd.cell_pos, d.children, fine_dirty);
      }
    } else {
      // Level 1 from the fine cells: their products from fine_tables_, rotated.
      const FineChildGalerkin fine_products(fine_tables_, fine_op_->data());
      rebuilt_[l] = d.stored->galerkin(*fd.op, fd.cell_pos, d.children,
                                       l == 1 ? d0.dirty : fd.stored->dirty(), &rows_[l - 1],
                                       l == 1 ? &fine_products : nullptr);
    }
    // -gmg_precision single: level l-1's blocks were kept in double for this product;
    // from now on they are applied from their float rounding (StoredCells::galerkin).
    if (l >= 2 && fd.stored) fd.stored->round_to_single();
    if (l == first && first > 0 && !rotated) {
      // The rotation each composite block now has (its fine cells share it).
      composite_rotation_.resize(9 * composite_fine_cell_.size());
      for (std::size_t C = 0; C < composite_fine_cell_.size(); ++C)
        std::copy_n(element_rotation(cells, C), 9, &composite_rotation_[9 * C]);
      // Carried blocks are new to the levels below too.
      if (!carried.empty()) d.stored->mark_all_dirty();
    }
    if (l == 1 && !cells.rotation.empty()) {
      // The rotations the rebuilt blocks saw: those of all their children.
      const auto& dirty = d.stored->dirty();
      for (std::size_t C = 0; C < dirty.size(); ++C)
        if (dirty[C])
          for (auto k = d.children.offset[C]; k < d.children.offset[C + 1]; ++k) {
            const auto e = std::size_t(d.children.child[k]);
            std::copy_n(&cells.rotation[9 * e], 9, &built_rotation_[9 * e]);
          }
    }
    // The diagonal blocks sum over ranks: rebuilt wherever any rank changed this level (a
    // full update always: its blocks may all have been carried over a cut).
    int changed = full || rebuilt_[l] > 0;
    PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, &changed, 1, MPI_INT, MPI_LOR, comm_));
    // Below the first level only the Galerkin chain is needed.
    if (changed && l >= first) PetscCall(build_diagonal(l));
    if (changed && uses_schwarz(l)) PetscCall(build_schwarz(l));
    if (l == L - 1 && changed) PetscCall(build_coarsest());
  }
  if (L == 1) PetscCall(build_coarsest());
  // Levels the loop left in double (the last before a smoothed chain); the coarsest keeps
  // double: it is only factored, and small.
  for (int l = 1; l + 1 < L; ++l)
    if (data_[l]->stored) data_[l]->stored->round_to_single();
  // The blocks above the fine cells rebuilt now are complete again.
  if (!chain_missing_.empty())
    for (std::size_t e = 0; e < d0.dirty.size(); ++e)
      if (d0.dirty[e]) chain_missing_[e] = 0;
  if (opt_.smoother == Smoother::chebyshev) {
    if (full || ++updates_since_estimate_ >= opt_.eig_every) {
      // Levels whose transfer the smoothed chain made estimated lambda_max for this very
      // operator already (smoothing_omega > 0): the same start vector gives the same value.
      for (int l = first; l + 1 < L; ++l)
        if (data_[l]->smoothing_omega == 0.0) PetscCall(estimate_lambda_max(l));
      updates_since_estimate_ = 0;
    }
  }
  built_ = true;
  // The other backends hold copies of (or pointers into) the levels: made again after every
  // update, rotation-only ones included.
  if (opt_.backend == Backend::host_loop) {
    PetscCall(host_loop_cycle(*this, opt_.precision, &backend_cycle_));
  } else if (opt_.backend == Backend::cuda) {
    std::string why;
    PetscCheck(device_count(&why) > 0, comm_, PETSC_ERR_SUP, "gmg: -gmg_backend cuda: %s",
               why.c_str());
    PetscCall(device_cycle_factory()(*this, &backend_cycle_));
  }
  PetscCall(PetscLogEventEnd(ev_setup_, 0, 0, 0, 0));
  if (opt_.view) PetscCall(view(PETSC_VIEWER_STDOUT_(comm_)));
  PetscFunctionReturn(0);
}

PetscErrorCode Multigrid::build_diagonal(int l) {
  PetscFunctionBeginUser;
  auto& d = *data_[l];
  const auto& D = levels_[l].layout();
  // 3x3 diagonal blocks, 9 numbers per copy, summed over ranks through a temporary
  // ghost exchange (kept only during set-up: it would be the largest array per DOF).
  Vec diag_g, diag_l;
  VecScatter diag_scatter;
  PetscCall(topology::create_ghost_scatter(comm_, D, 9, &diag_g, &diag_l, &diag_scatter));
  PetscCall(VecSet(diag_l, 0.0));
  PetscScalar* dl;
  PetscCall(VecGetArray(diag_l, &dl));
  d.op->add_diagonal_blocks(dl);
  PetscCall(VecRestoreArray(diag_l, &dl));
  PetscCall(VecSet(diag_g, 0.0));
  PetscCall(VecScatterBegin(diag_scatter, diag_l, diag_g, ADD_VALUES, SCATTER_REVERSE));
  PetscCall(VecScatterEnd(diag_scatter, diag_l, diag_g, ADD_VALUES, SCATTER_REVERSE));
  const PetscScalar* dg;
  PetscCall(VecGetArrayRead(diag_g, &dg));
  PetscScalar* m;
  PetscCall(VecGetArray(d.mask, &m));
  d.diag_inv.assign(9 * std::size_t(D.num_owned), 0.0);
  for (std::int32_t i = 0; i < D.num_owned; ++i) {
    double block[9];
    for (int k = 0; k < 9; ++k) block[k] = dg[9 * i + k];
    for (int c = 0; c < 3; ++c) {
      // Coarse DOFs that no fine DOF reaches (all prescribed) are dead: identity rows.
      if (l > 0) m[3 * i + c] = block[4 * c] != 0.0 ? 1.0 : 0.0;
      if (m[3 * i + c] == 0.0) {
        for (int k = 0; k < 3; ++k) block[3 * c + k] = block[3 * k + c] = 0.0;
        block[4 * c] = 1.0;
      }
    }
    if (!invert3(block, &d.diag_inv[9 * i]))
      SETERRQ(PETSC_COMM_SELF, PETSC_ERR_MAT_LU_ZRPVT,
              "gmg: singular 3x3 diagonal block on level %d", l);
  }
  PetscCall(VecRestoreArray(d.mask, &m));
  PetscCall(VecRestoreArrayRead(diag_g, &dg));
  PetscCall(VecDestroy(&diag_g));
  PetscCall(VecDestroy(&diag_l));
  PetscCall(VecScatterDestroy(&diag_scatter));
  PetscFunctionReturn(0);
}

PetscErrorCode Multigrid::apply_level_impl(int l, Vec x, Vec y) {
  const auto& d = *data_[l];
  if (d.A) return MatMult(d.A, x, y);  // assembled: identity rows where dead included
  return assembly::apply(d.dm, *d.op, x, y, d.mask);
}

PetscErrorCode Multigrid::apply_fine(Vec x, Vec y) {
  return apply_level_impl(opt_.first_level, x, y);
}
PetscErrorCode Multigrid::apply_level(int l, Vec x, Vec y) {
  return apply_level_impl(l, x, y);
}

PetscErrorCode Multigrid::gauss_seidel(int l, Vec b, Vec x, bool reverse) {
  PetscFunctionBeginUser;
  auto& d = *data_[l];
  const auto& D = levels_[l].layout();
  // On one rank the local and global numberings coincide (no ghosts): sweep in place.
  // In parallel each colour needs the ghosts of x before and the sum of the residual
  // contributions over ranks after.
  const bool serial = D.num_ranks == 1;
  // Local work vectors from the DM's cache, not the level's own: level 0's are then the
  // ones the fine operator's application uses (assembly::apply), and a Chebyshev run
  // never allocates them.
  Vec xl, yl;
  PetscCall(DMGetLocalVector(d.dm, &xl));
  PetscCall(DMGetLocalVector(d.dm, &yl));
  if (!serial) {
    PetscCall(DMGlobalToLocalBegin(d.dm, x, INSERT_VALUES, xl));
    PetscCall(DMGlobalToLocalEnd(d.dm, x, INSERT_VALUES, xl));
  }
  for (int kk = 0; kk < 8; ++kk) {
    const int k = reverse ? 7 - kk : kk;
    // A x at the copies of colour k, from the rank's cells: each cell has exactly one
    // corner of colour k, so a colour costs 1/8 of an operator application.
    const PetscScalar* xa;
    PetscScalar* ya;
    PetscCall(VecGetArrayRead(serial ? x : xl, &xa));
    PetscCall(VecGetArray(yl, &ya));
    if (serial) {
      for (auto i : d.colour_list[k])
        for (int c = 0; c < 3; ++c) ya[3 * i + c] = 0.0;
    } else {
      std::fill(ya, ya + 3 * D.num_local(), 0.0);
    }
    d.op->apply_add_colour(d.cell_pos, k, xa, ya);
    PetscCall(VecRestoreArrayRead(serial ? x : xl, &xa));
    PetscCall(VecRestoreArray(yl, &ya));
    Vec r = yl;  // serial: the residual contributions are already complete
    if (!serial) {
      PetscCall(VecSet(d.r, 0.0));
      PetscCall(DMLocalToGlobalBegin(d.dm, yl, ADD_VALUES, d.r));
      PetscCall(DMLocalToGlobalEnd(d.dm, yl, ADD_VALUES, d.r));
      r = d.r;
    }
    const PetscScalar *ba, *ra, *ma;
    PetscScalar* xg;
    PetscCall(VecGetArrayRead(b, &ba));
    PetscCall(VecGetArrayRead(r, &ra));
    PetscCall(VecGetArrayRead(d.mask, &ma));
    PetscCall(VecGetArray(x, &xg));
    for (auto i : d.colour_list[k]) {
      double res[3];
      for (int c = 0; c < 3; ++c)
        res[c] = ba[3 * i + c] - ra[3 * i + c] - (ma[3 * i + c] == 0.0 ? xg[3 * i + c] : 0.0);
      const double* Di = &d.diag_inv[9 * i];
      for (int c = 0; c < 3; ++c)
        xg[3 * i + c] +=
            opt_.omega * (Di[3 * c] * res[0] + Di[3 * c + 1] * res[1] + Di[3 * c + 2] * res[2]);
    }
    PetscCall(VecRestoreArray(x, &xg));
    PetscCall(VecRestoreArrayRead(d.mask, &ma));
    PetscCall(VecRestoreArrayRead(r, &ra));
    PetscCall(VecRestoreArrayRead(b, &ba));
    if (!serial) {
      PetscCall(DMGlobalToLocalBegin(d.dm, x, INSERT_VALUES, xl));
      PetscCall(DMGlobalToLocalEnd(d.dm, x, INSERT_VALUES, xl));
    }
  }
  PetscCall(DMRestoreLocalVector(d.dm, &yl));
  PetscCall(DMRestoreLocalVector(d.dm, &xl));
  PetscFunctionReturn(0);
}

namespace {

/// y = D^{-1} x on owned copies (3x3 blocks).
PetscErrorCode block_jacobi(const std::vector<double>& diag_inv, Vec x, Vec y) {
  PetscFunctionBeginUser;
  const PetscScalar* xa;
  PetscScalar* ya;
  PetscCall(VecGetArrayRead(x, &xa));
  PetscCall(VecGetArray(y, &ya));
  const std::size_t n = diag_inv.size() / 9;
  for (std::size_t i = 0; i < n; ++i) {
    const double* Di = &diag_inv[9 * i];
    for (int c = 0; c < 3; ++c)
      ya[3 * i + c] =
          Di[3 * c] * xa[3 * i] + Di[3 * c + 1] * xa[3 * i + 1] + Di[3 * c + 2] * xa[3 * i + 2];
  }
  PetscCall(VecRestoreArray(y, &ya));
  PetscCall(VecRestoreArrayRead(x, &xa));
  PetscFunctionReturn(0);
}

}  // namespace

PetscErrorCode Multigrid::build_schwarz(int l) {
  PetscFunctionBeginUser;
  auto& d = *data_[l];
  PetscCall(PetscLogEventBegin(ev_schwarz_, 0, 0, 0, 0));
  d.schwarz = std::make_unique<Schwarz>();
  PetscCall(Schwarz::create(comm_, d.dm, levels_[l], levels_[l + 1], irregular_[l + 1], *d.op,
                            d.mask, d.schwarz.get()));
  PetscCall(PetscLogEventEnd(ev_schwarz_, 0, 0, 0, 0));
  PetscFunctionReturn(0);
}

std::int64_t Multigrid::schwarz_patches(int l) const {
  return data_[l]->schwarz ? data_[l]->schwarz->num_patches() : 0;
}

bool Multigrid::has_irregular_parents(int l) const {
  // A decision every rank takes alike (the hierarchy and its irregular cells are replicated).
  if (l + 1 >= num_levels()) return false;
  const auto& irr = irregular_[l + 1];
  return std::find(irr.begin(), irr.end(), char(1)) != irr.end();
}

bool Multigrid::uses_schwarz(int l) const {
  return opt_.smoother == Smoother::chebyshev && opt_.schwarz_from >= 0 && l < assembled_from_ &&
         l >= std::max(opt_.schwarz_from, opt_.first_level) && has_irregular_parents(l) &&
         !levels_[l + 1].remote_children;  // a patch holds the children of one rank's cell
}

PetscErrorCode Multigrid::precondition(int l, Vec r, Vec z) {
  PetscFunctionBeginUser;
  auto& d = *data_[l];
  // Point-block Jacobi everywhere; the Schwarz patches then replace it where they reach.
  PetscCall(block_jacobi(d.diag_inv, r, z));
  if (d.schwarz) PetscCall(d.schwarz->apply(r, z));
  PetscFunctionReturn(0);
}

int Multigrid::degree(int l, int sweeps) const {
  // Only where coarse cells are irregular: a solid block's cycle stays as it was.
  if (sweeps == 0 || !has_irregular_parents(l)) return sweeps;
  return std::min(8, std::max(sweeps, int(std::lround(sweeps * std::pow(opt_.degree_growth, l)))));
}

PetscErrorCode Multigrid::estimate_lambda_max(int l) {
  PetscFunctionBeginUser;
  // Power iteration on D^{-1} A from a pseudo-random start vector that is a function of
  // the canonical copy numbering, so the estimate (and hence the smoother) is the same on
  // any number of ranks.
  auto& d = *data_[l];
  const auto& D = levels_[l].layout();
  Vec v = d.tmp, w = d.r;
  PetscScalar* a;
  PetscCall(VecGetArray(v, &a));
  for (std::int32_t i = 0; i < D.num_owned; ++i)
    for (int c = 0; c < 3; ++c) {
      const double k = double(3 * std::int64_t(D.copies[i]) + c);
      const double hash = std::sin(12.9898 * k + 78.233) * 43758.5453;
      a[3 * i + c] = 0.5 + (hash - std::floor(hash));
    }
  PetscCall(VecRestoreArray(v, &a));
  // Power iteration approaches lambda_max from below; the top of a smoothing spectrum is
  // dense, so 15 iterations land within a few per cent, and Chebyshev's interval
  // extends 10% above the estimate.
  double lambda = 0.0;
  for (int it = 0; it < 15; ++it) {
    PetscReal nv;
    PetscCall(VecNormalize(v, &nv));
    PetscCall(apply_level_impl(l, v, w));
    PetscCall(precondition(l, w, v));
    PetscReal nw;
    PetscCall(VecNorm(v, NORM_2, &nw));
    lambda = nw;
  }
  d.lambda_max = lambda;
  PetscFunctionReturn(0);
}

PetscErrorCode Multigrid::chebyshev(int l, Vec b, Vec x, int degree) {
  PetscFunctionBeginUser;
  // Chebyshev iteration on D^{-1} A over [0.2, 1.1] * lambda_max: damps the upper part
  // of the spectrum, which the coarse grid cannot represent.
  auto& d = *data_[l];
  const double hi = 1.1 * d.lambda_max, lo = 0.2 * d.lambda_max;
  const double theta = 0.5 * (hi + lo), delta = 0.5 * (hi - lo), sigma = theta / delta;
  double rho_old = 1.0 / sigma;
  Vec r = d.r, z = d.tmp, dir = d.dir;
  PetscCall(apply_level_impl(l, x, r));
  PetscCall(VecAYPX(r, -1.0, b));
  PetscCall(precondition(l, r, z));
  PetscCall(VecAXPBY(dir, 1.0 / theta, 0.0, z));
  for (int i = 0; i < degree; ++i) {
    PetscCall(VecAXPY(x, 1.0, dir));
    if (i + 1 == degree) break;
    PetscCall(apply_level_impl(l, x, r));
    PetscCall(VecAYPX(r, -1.0, b));
    PetscCall(precondition(l, r, z));
    const double rho = 1.0 / (2.0 * sigma - rho_old);
    PetscCall(VecAXPBY(dir, 2.0 * rho / delta, rho * rho_old, z));
    rho_old = rho;
  }
  PetscFunctionReturn(0);
}

PetscErrorCode Multigrid::smooth(int l, Vec b, Vec x, int sweeps, bool reverse) {
  PetscFunctionBeginUser;
  if (sweeps == 0) PetscFunctionReturn(0);
  PetscCall(PetscLogEventBegin(ev_smooth_, 0, 0, 0, 0));
  if (opt_.smoother == Smoother::chebyshev) {
    PetscCall(chebyshev(l, b, x, degree(l, sweeps)));
  } else {
    for (int s = 0; s < sweeps; ++s) PetscCall(gauss_seidel(l, b, x, reverse));
  }
  PetscCall(PetscLogEventEnd(ev_smooth_, 0, 0, 0, 0));
  PetscFunctionReturn(0);
}

PetscErrorCode Multigrid::build_interpolation(int l) {
  PetscFunctionBeginUser;
  auto& d = *data_[l];
  const auto& irregular = irregular_[l + 1];
  // Transfers to levels with remote children stay trilinear: a child's energy rows would
  // need its coarse cell's corners on the child's rank.
  if (opt_.interpolation != Interpolation::energy || l < opt_.energy_from ||
      !has_irregular_parents(l) || levels_[l + 1].remote_children) {
    rows_[l] = InterpolationRows{};
    energy_stats_[l] = EnergyStats{};
    PetscFunctionReturn(0);  // the trilinear MAIJ of build() stays
  }
  PetscCall(PetscLogEventBegin(ev_interp_, 0, 0, 0, 0));
  PetscCall(energy_interpolation(comm_, levels_[l], levels_[l + 1], irregular, *d.op, d.diag_inv,
                                 d.mask, opt_.energy_iterations, &rows_[l], &energy_stats_[l]));
  PetscCall(MatDestroy(&d.P));
  PetscCall(interpolation_matrix(comm_, levels_[l], levels_[l + 1], rows_[l], &d.P));
  PetscCall(PetscLogEventEnd(ev_interp_, 0, 0, 0, 0));
  PetscFunctionReturn(0);
}

std::int64_t Multigrid::smoothed_rows(int l) const {
  return data_[l]->smoothed_rows;
}
double Multigrid::smoothing_omega(int l) const {
  return data_[l]->smoothing_omega;
}

PetscErrorCode Multigrid::smoothing_jacobi(int l, Mat* Dinv) {
  PetscFunctionBeginUser;
  auto& d = *data_[l];
  const auto& lev = levels_[l];
  const auto& D = lev.layout();
  // The copies whose rows are smoothed (canonical, the same on every rank): the corners of the
  // children of irregular coarse cells, grown by layers of cells.
  const int layers = opt_.smoothed_layers;
  std::vector<char> mark(std::size_t(lev.copies().num_copies), layers < 0 ? 1 : 0);
  if (layers >= 0) {
    const auto& irregular = irregular_[l + 1];
    const auto& corners = lev.copies().cell_corners;
    for (std::size_t c = 0; c < corners.size(); ++c)
      if (irregular[std::size_t(lev.parent[c])])
        for (auto q : corners[c]) mark[std::size_t(q)] = 1;
    for (int k = 0; k < layers; ++k) {
      auto grown = mark;
      for (const auto& cc : corners)
        if (std::any_of(cc.begin(), cc.end(), [&](std::int32_t q) { return mark[std::size_t(q)]; }))
          for (auto q : cc) grown[std::size_t(q)] = 1;
      mark = std::move(grown);
    }
  }
  PetscCall(MatCreateAIJ(comm_, 3 * D.num_owned, 3 * D.num_owned, PETSC_DETERMINE, PETSC_DETERMINE,
                         3, nullptr, 0, nullptr, Dinv));
  d.smoothed_rows = 0;
  for (std::int32_t i = 0; i < D.num_owned; ++i) {
    if (!mark[std::size_t(D.copies[i])]) continue;
    const PetscInt g = D.global_block[std::size_t(D.copies[i])];
    const PetscInt rows[3] = {3 * g, 3 * g + 1, 3 * g + 2};
    PetscCall(
        MatSetValues(*Dinv, 3, rows, 3, rows, &d.diag_inv[9 * std::size_t(i)], INSERT_VALUES));
    d.smoothed_rows += 3;
  }
  PetscCall(MatAssemblyBegin(*Dinv, MAT_FINAL_ASSEMBLY));
  PetscCall(MatAssemblyEnd(*Dinv, MAT_FINAL_ASSEMBLY));
  PetscFunctionReturn(0);
}

PetscErrorCode Multigrid::assembled_diagonal(int l) {
  PetscFunctionBeginUser;
  auto& d = *data_[l];
  const auto& D = levels_[l].layout();
  Mat A = d.A;
  d.diag_inv.assign(9 * std::size_t(D.num_owned), 0.0);
  std::vector<PetscInt> dead;
  PetscScalar* m;
  PetscCall(VecGetArray(d.mask, &m));
  for (std::int32_t i = 0; i < D.num_owned; ++i) {
    const PetscInt g = D.global_block[std::size_t(D.copies[i])];
    double block[9] = {0, 0, 0, 0, 0, 0, 0, 0, 0};
    for (int a = 0; a < 3; ++a) {
      PetscInt nc;
      const PetscInt* cols;
      const PetscScalar* vals;
      PetscCall(MatGetRow(A, 3 * g + a, &nc, &cols, &vals));
      for (PetscInt k = 0; k < nc; ++k)
        if (cols[k] / 3 == g) block[3 * a + int(cols[k] - 3 * g)] = vals[k];
      PetscCall(MatRestoreRow(A, 3 * g + a, &nc, &cols, &vals));
    }
    for (int c = 0; c < 3; ++c) {
      // As build_diagonal: a DOF no free fine DOF reaches (a zero column of P) is dead.
      m[3 * i + c] = block[4 * c] != 0.0 ? 1.0 : 0.0;
      if (m[3 * i + c] == 0.0) {
        for (int k = 0; k < 3; ++k) block[3 * c + k] = block[3 * k + c] = 0.0;
        block[4 * c] = 1.0;
        dead.push_back(3 * g + c);
      }
    }
    if (!invert3(block, &d.diag_inv[9 * std::size_t(i)]))
      SETERRQ(PETSC_COMM_SELF, PETSC_ERR_MAT_LU_ZRPVT,
              "gmg: singular 3x3 diagonal block on assembled level %d", l);
  }
  PetscCall(VecRestoreArray(d.mask, &m));
  // Identity rows for the dead DOFs (their rows and columns are zero).
  PetscCall(MatSetOption(A, MAT_NEW_NONZERO_ALLOCATION_ERR, PETSC_FALSE));
  for (auto r : dead) PetscCall(MatSetValue(A, r, r, 1.0, ADD_VALUES));
  PetscCall(MatAssemblyBegin(A, MAT_FINAL_ASSEMBLY));
  PetscCall(MatAssemblyEnd(A, MAT_FINAL_ASSEMBLY));
  PetscFunctionReturn(0);
}

PetscErrorCode Multigrid::build_smoothed_chain() {
  PetscFunctionBeginUser;
  // Smoothed interpolation (Vanek, Mandel and Brezina 1996; doc/theory.md, "Coarse spaces
  // after cuts and on thin pieces"): on the rows near irregular coarse cells,
  // P = (I - omega D^-1 A_l) P_trilinear with omega = 4 / (3 lambda_max(D^-1 A_l)); the
  // coarse operator is then P^T A_l P, a general sparse matrix (PETSc's MatPtAP), for every
  // level from assembled_from_ down. Level assembled_from_ - 1 keeps its own operator and is
  // assembled only here, for the products.
  const int L = num_levels();
  const int S = assembled_from_ - 1;
  PetscCall(PetscLogEventBegin(ev_interp_, 0, 0, 0, 0));
  Mat A;
  PetscCall(assembly::create_matrix(comm_, levels_[S].copies(), levels_[S].layout(), &A));
  PetscCall(assembly::assemble(*data_[S]->op, data_[S]->mask, A));
  for (int l = S; l + 1 < L; ++l) {
    auto& d = *data_[l];
    auto& c = *data_[l + 1];
    // The V-cycle's transfer diag(mask) P, made explicit.
    Mat P;
    PetscCall(MatConvert(d.P_trilinear, MATAIJ, MAT_INITIAL_MATRIX, &P));
    PetscCall(MatDiagonalScale(P, d.mask, nullptr));
    d.smoothed_rows = 0;
    d.smoothing_omega = 0.0;
    if (l >= opt_.energy_from && has_irregular_parents(l) &&
        (opt_.smoothed_levels < 0 || l - S < opt_.smoothed_levels)) {
      PetscCall(estimate_lambda_max(l));
      d.smoothing_omega = 4.0 / (3.0 * d.lambda_max);
      Mat Dinv, DA, DAP;
      PetscCall(smoothing_jacobi(l, &Dinv));
      PetscCall(MatMatMult(Dinv, A, MAT_INITIAL_MATRIX, PETSC_DEFAULT, &DA));
      PetscCall(MatMatMult(DA, P, MAT_INITIAL_MATRIX, PETSC_DEFAULT, &DAP));
      PetscCall(MatAXPY(P, -d.smoothing_omega, DAP, DIFFERENT_NONZERO_PATTERN));
      for (Mat* M : {&Dinv, &DA, &DAP}) PetscCall(MatDestroy(M));
    }
    PetscCall(MatDestroy(&d.P));
    d.P = P;
    PetscCall(MatDestroy(&c.A));
    PetscCall(MatPtAP(A, P, MAT_INITIAL_MATRIX, 2.0, &c.A));
    PetscCall(MatSetOption(c.A, MAT_SYMMETRIC, PETSC_TRUE));
    if (l == S) PetscCall(MatDestroy(&A));  // level S applies its own operator
    PetscCall(assembled_diagonal(l + 1));
    A = c.A;
  }
  PetscCall(PetscLogEventEnd(ev_interp_, 0, 0, 0, 0));
  PetscCall(build_coarsest());
  PetscFunctionReturn(0);
}

PetscErrorCode Multigrid::build_composite_mask() {
  PetscFunctionBeginUser;
  // Wu's fixation propagation (doc/theory.md, "Composite elements"): a composite DOF is fixed
  // when it carries weight from a prescribed fine DOF. The trilinear weights are >= 0, so
  // restricting the indicator of prescribed fine DOFs level by level, P^T v, is positive
  // exactly there (per component: MAIJ keeps x, y, z apart).
  const int first = opt_.first_level;
  Vec v = data_[0]->tmp;
  PetscCall(VecSet(v, 1.0));
  PetscCall(VecAXPY(v, -1.0, data_[0]->mask));
  for (int l = 0; l < first; ++l) {
    Vec c = data_[l + 1]->tmp;
    PetscCall(MatMultTranspose(data_[l]->P, v, c));
    v = c;
  }
  auto& d = *data_[first];
  PetscScalar* m;
  const PetscScalar* a;
  PetscInt n;
  PetscCall(VecGetLocalSize(v, &n));
  PetscCall(VecGetArrayRead(v, &a));
  PetscCall(VecGetArray(d.mask, &m));
  for (PetscInt i = 0; i < n; ++i) m[i] = a[i] > 0.0 ? 0.0 : 1.0;
  PetscCall(VecRestoreArray(d.mask, &m));
  PetscCall(VecRestoreArrayRead(v, &a));
  // The local (owned + ghost) mask for the blocks.
  Vec ml;
  PetscCall(DMGetLocalVector(d.dm, &ml));
  PetscCall(assembly::global_to_local(d.dm, d.mask, ml));
  PetscCall(VecGetLocalSize(ml, &n));
  PetscCall(VecGetArrayRead(ml, &a));
  composite_mask_.assign(a, a + n);
  PetscCall(VecRestoreArrayRead(ml, &a));
  PetscCall(DMRestoreLocalVector(d.dm, &ml));
  d.stored->set_mask(composite_mask_);
  // Rotating a masked block is the Galerkin product of the rotated fine cells only where
  // the mask commutes with the rotation: every vertex fixed in all components or in none.
  int rotatable = 1;
  for (std::size_t v = 0; 3 * v < composite_mask_.size(); ++v)
    rotatable &= composite_mask_[3 * v] == composite_mask_[3 * v + 1] &&
                 composite_mask_[3 * v] == composite_mask_[3 * v + 2];
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, &rotatable, 1, MPI_INT, MPI_LAND, comm_));
  rotatable_ = rotatable;
  PetscFunctionReturn(0);
}

PetscErrorCode Multigrid::rotate_composite_blocks(const assembly::CellData& cells, bool* done) {
  PetscFunctionBeginUser;
  *done = false;
  const auto& D0 = levels_[0].layout();
  // Only for rotation groups that are the composite elements (the simulation sets them).
  int ok = opt_.rotate_composite && rotatable_ && !composite_rotation_.empty() &&
           cells.num_rotation_groups == std::int32_t(composite_fine_cell_.size()) &&
           cells.rotation.size() == 9 * D0.cells.size();
  PetscCallMPI(MPI_Allreduce(MPI_IN_PLACE, &ok, 1, MPI_INT, MPI_LAND, comm_));
  if (!ok) PetscFunctionReturn(0);
  const std::size_t n = composite_fine_cell_.size();
  std::vector<double> dR(9 * n);
  for (std::size_t C = 0; C < n; ++C) {
    const double* R = &cells.rotation[9 * std::size_t(composite_fine_cell_[C])];
    rotation_change(R, &composite_rotation_[9 * C], &dR[9 * C]);
    std::copy_n(R, 9, &composite_rotation_[9 * C]);
  }
  data_[opt_.first_level]->stored->rotate(dR);
  *done = true;
  PetscFunctionReturn(0);
}

PetscErrorCode Multigrid::build_coarsest() {
  PetscFunctionBeginUser;
  const int l = num_levels() - 1;
  const auto& lev = levels_[l];
  auto& d = *data_[l];
  if (d.A) {
    // An assembled level (smoothed interpolation): a new matrix at every rebuild, and a new
    // solver for it (the factor's MUMPS settings below are made on the factor object).
    PetscCall(MatDestroy(&coarse_matrix_));
    PetscCall(KSPDestroy(&coarse_ksp_));
    coarse_matrix_ = d.A;
    PetscCall(PetscObjectReference((PetscObject)d.A));
  } else {
    // The pattern never changes: re-filling the same matrix lets the factorization keep
    // its symbolic phase and redo only the numeric one.
    if (!coarse_matrix_)
      PetscCall(assembly::create_matrix(comm_, lev.copies(), lev.layout(), &coarse_matrix_));
    PetscCall(assembly::assemble(*d.op, d.mask, coarse_matrix_));
  }
  if (!opt_.factor_coarsest) PetscFunctionReturn(0);
  if (!coarse_ksp_) {
    PetscCall(KSPCreate(comm_, &coarse_ksp_));
    PetscCall(KSPSetOptionsPrefix(coarse_ksp_, "gmg_coarse_"));
    PetscCall(KSPSetType(coarse_ksp_, KSPPREONLY));
    PC pc;
    PetscCall(KSPGetPC(coarse_ksp_, &pc));
    PetscCall(PCSetType(pc, PCCHOLESKY));
    PetscCall(PCFactorSetMatSolverType(pc, MATSOLVERMUMPS));
    // The masked Galerkin operator may be singular, though consistent: two coarse copies
    // whose columns of P differ only on prescribed fine DOFs (found on bunny.yaml near
    // its support: three zero eigenvalues of 2814). MUMPS then divides by a pivot that
    // is round-off, or zero, so the coarse correction was huge or NaN, varying with the
    // factorization's parallel scheduling (bunny_cuts on 2 ranks stopped with
    // DIVERGED_NANORINF or DIVERGED_INDEFINITE_PC in about 1 run of 8). Null-pivot
    // detection (ICNTL(24)) sets those components to zero instead; P x is unchanged.
    // Set on this factor object (not in the options database), unless the user set it.
    PetscCall(KSPSetFromOptions(coarse_ksp_));
    PetscCall(KSPSetOperators(coarse_ksp_, coarse_matrix_, coarse_matrix_));
    PetscBool factor = PETSC_FALSE, user = PETSC_FALSE;
    PetscCall(PetscObjectTypeCompareAny((PetscObject)pc, &factor, PCCHOLESKY, PCLU, ""));
    PetscCall(PetscOptionsHasName(nullptr, "gmg_coarse_", "-mat_mumps_icntl_24", &user));
    if (factor && !user) {
      Mat F;
      PetscCall(PCFactorSetUpMatSolverType(pc));
      PetscCall(PCFactorGetMatrix(pc, &F));
      PetscCall(MatMumpsSetIcntl(F, 24, 1));  // does nothing for other factorizations
    }
  }
  PetscCall(KSPSetOperators(coarse_ksp_, coarse_matrix_, coarse_matrix_));
  PetscCall(KSPSetUp(coarse_ksp_));
  PetscFunctionReturn(0);
}

PetscErrorCode Multigrid::cycle_level(int l, bool zero_guess) {
  PetscFunctionBeginUser;
  auto& d = *data_[l];
  if (l == num_levels() - 1) {
    PetscCall(KSPSolve(coarse_ksp_, d.b, d.x));
    PetscFunctionReturn(0);
  }
  auto& c = *data_[l + 1];
  if (zero_guess) PetscCall(VecSet(d.x, 0.0));
  PetscCall(smooth(l, d.b, d.x, opt_.presmooth, false));
  PetscCall(apply_level_impl(l, d.x, d.r));
  PetscCall(VecAYPX(d.r, -1.0, d.b));
  PetscCall(VecPointwiseMult(d.r, d.r, d.mask));
  PetscCall(MatMultTranspose(d.P, d.r, c.b));
  // V-cycle: one cycle on the next level; W-cycle: two, the second continuing from the
  // first, so the coarse problems are solved more accurately where the coarse space is
  // poor (thin pieces after cuts). The coarsest level is solved exactly, once.
  const int visits = l + 2 == num_levels() ? 1 : opt_.cycle_gamma;
  for (int v = 0; v < visits; ++v) PetscCall(cycle_level(l + 1, v == 0));
  PetscCall(MatMult(d.P, c.x, d.tmp));
  PetscCall(VecPointwiseMult(d.tmp, d.tmp, d.mask));
  PetscCall(VecAXPY(d.x, 1.0, d.tmp));
  PetscCall(smooth(l, d.b, d.x, opt_.postsmooth, true));
  PetscFunctionReturn(0);
}

PetscErrorCode Multigrid::cycle(Vec b, Vec x) {
  PetscFunctionBeginUser;
  PetscCall(PetscLogEventBegin(ev_apply_, 0, 0, 0, 0));
  if (backend_cycle_) {
    const PetscScalar* ba;
    PetscScalar* xa;
    PetscCall(VecGetArrayRead(b, &ba));
    PetscCall(VecGetArray(x, &xa));
    const PetscErrorCode ierr = backend_cycle_->apply(ba, xa);
    PetscCall(VecRestoreArray(x, &xa));
    PetscCall(VecRestoreArrayRead(b, &ba));
    PetscCall(ierr);
    PetscCall(PetscLogEventEnd(ev_apply_, 0, 0, 0, 0));
    PetscFunctionReturn(0);
  }
  // The first level's b and x are the caller's arrays (cycle_level only reads b there):
  // two fewer vectors of the largest level, and no copies in or out.
  auto& d = *data_[opt_.first_level];
  const PetscScalar* ba;
  PetscScalar* xa;
  PetscCall(VecGetArrayRead(b, &ba));
  PetscCall(VecGetArray(x, &xa));
  PetscCall(VecPlaceArray(d.b, ba));
  PetscCall(VecPlaceArray(d.x, xa));
  const PetscErrorCode ierr = cycle_level(opt_.first_level, true);
  PetscCall(VecResetArray(d.b));
  PetscCall(VecResetArray(d.x));
  PetscCall(VecRestoreArray(x, &xa));
  PetscCall(VecRestoreArrayRead(b, &ba));
  PetscCall(ierr);
  PetscCall(PetscLogEventEnd(ev_apply_, 0, 0, 0, 0));
  PetscFunctionReturn(0);
}

PetscErrorCode Multigrid::view(PetscViewer viewer) const {
  PetscFunctionBeginUser;
  PetscCall(PetscViewerASCIIPrintf(
      viewer, "hexcut gmg: %d levels, hierarchy %s, %s-cycle, smoother %s (%d,%d)%s%s\n",
      num_levels(),
      opt_.hierarchy.mode == hierarchy::Coarsening::components ? "components" : "naive",
      opt_.cycle_gamma == 2 ? "W" : "V",
      opt_.smoother == Smoother::gauss_seidel ? "8-colour block GS" : "Chebyshev/block Jacobi",
      opt_.presmooth, opt_.postsmooth,
      opt_.smoother == Smoother::gauss_seidel && opt_.omega != 1.0 ? " (omega != 1)" : "",
      opt_.precision == Precision::single
          ? ", coarse blocks in single precision (the coarsest in double)"
          : ""));
  if (opt_.first_level > 0)
    PetscCall(PetscViewerASCIIPrintf(
        viewer,
        "  composite elements: the cycle starts on level %d; levels below it hold the Galerkin "
        "chain only%s\n",
        opt_.first_level,
        rotatable_ && opt_.rotate_composite ? " (rotation updates rotate its blocks)" : ""));
  // "duplicated": cells that share their position with another cell of the level, the
  // pieces of one 2x2x2 block that holes, thin gaps or cuts separate.
  PetscCall(PetscViewerASCIIPrintf(
      viewer, "  level      cells  duplicated      DOFs   nnz-equiv     held MiB   rebuilt\n"));
  double total_bytes = 0.0, fine_nnz = 0.0, fine_dofs = 1.0;
  std::int64_t energy_rows = 0;
  std::vector<std::int64_t> patches(num_levels(), 0);
  for (int l = 0; l < num_levels(); ++l) {
    const auto& lev = levels_[l];
    // Cells that share their position with another cell (components of one block).
    std::set<std::int64_t> seen, dup;
    for (const auto& p : lev.graph.ijk) {
      const auto key = lev.graph.spec.cell_index(p[0], p[1], p[2]);
      if (!seen.insert(key).second) dup.insert(key);
    }
    std::int64_t shared = 0;
    for (const auto& p : lev.graph.ijk)
      shared += dup.count(lev.graph.spec.cell_index(p[0], p[1], p[2]));
    // Nonzeros an assembled matrix of this level would have: 9 per coupled copy pair.
    std::vector<std::vector<std::int32_t>> nb(lev.copies().num_copies);
    for (const auto& corners : lev.copies().cell_corners)
      for (auto a : corners)
        for (auto b : corners) nb[a].push_back(b);
    std::int64_t pairs = 0;
    for (auto& v : nb) {
      std::sort(v.begin(), v.end());
      pairs += std::unique(v.begin(), v.end()) - v.begin();
    }
    // What the multigrid holds for this level, summed over ranks: operator data (level 0:
    // lambda, mu, rho, the kind or own-stiffness index, a masked flag per cell and the mask
    // per DOF, and where rotations are stored (corotational runs) R and the R the coarse
    // blocks were built from; coarse: the stored blocks, a packed 24x24 block per cell or per
    // group of cells sharing one), the inverted 3x3
    // diagonal blocks, the interpolation to this level from the next (the scalar AIJ under
    // the MAIJ: value + column index per weight) and the work vectors (6 global, 4 on the
    // first level, whose b and x are the caller's; 2 local for Gauss-Seidel; ghosts ignored).
    const double cells = double(lev.graph.num_cells()), copies = double(lev.copies().num_copies);
    // Assembled levels (smoothed interpolation) and smoothed transfers: their AIJ nonzeros.
    const auto aij_bytes = [](Mat M) {
      MatInfo info;
      MatGetInfo(M, MAT_GLOBAL_SUM, &info);
      return 12.0 * info.nz_used;
    };
    const auto& d = *data_[l];
    double stored[2] = {0.0, 0.0};  // bytes and blocks, summed over ranks
    if (l > 0 && d.stored)
      stored[0] = double(d.stored->bytes()), stored[1] = double(d.stored->num_blocks());
    MPI_Allreduce(MPI_IN_PLACE, stored, 2, MPI_DOUBLE, MPI_SUM, comm_);
    const double rotations = fine_cells_ && !fine_cells_->rotation.empty() ? 2.0 * 9.0 * 8.0 : 0.0;
    const double op = d.A      ? aij_bytes(d.A)
                      : l == 0 ? cells * (3.0 * 8.0 + 4.0 + 1.0 + rotations) + 3.0 * copies * 8.0
                               : stored[0];
    double transfer = 0.0;
    if (l + 1 < num_levels()) {
      Mat scalar = d.P;
      if (!d.P_trilinear) PetscCall(MatMAIJGetAIJ(d.P, &scalar));
      transfer = aij_bytes(scalar);
    }
    // Gauss-Seidel's two local vectors come from the DM's cache (level 0: shared with the
    // fine operator's application).
    const double vectors =
        (l == opt_.first_level ? 4.0 : 6.0) + (opt_.smoother == Smoother::chebyshev ? 0.0 : 2.0);
    // Energy-minimized rows (8 3x3 blocks + 8 coarse indices each, on the copies' owners and
    // ghosts) and the Schwarz patches' packed Cholesky factors with their DOF lists.
    std::int64_t extra[3] = {0, 0, 0};  // bytes, rows, patches
    if (l + 1 < num_levels()) {
      extra[0] = std::int64_t(rows_[l].block.size() * 8 + rows_[l].coarse.size() * 32);
      extra[1] = energy_stats_[l].rows;
    }
    if (data_[l]->schwarz) {
      extra[0] += std::int64_t(data_[l]->schwarz->stored_numbers() * 8);
      extra[2] = data_[l]->schwarz->num_patches();
    }
    MPI_Allreduce(MPI_IN_PLACE, extra, 1, MPI_INT64_T, MPI_SUM, comm_);
    MPI_Allreduce(MPI_IN_PLACE, extra + 2, 1, MPI_INT64_T, MPI_SUM, comm_);
    const double bytes =
        op + copies * 9.0 * 8.0 + transfer + vectors * 3.0 * copies * 8.0 + double(extra[0]);
    energy_rows += extra[1];
    patches[l] = extra[2];
    std::int64_t rebuilt = rebuilt_.empty() ? 0 : rebuilt_[l];
    MPI_Allreduce(MPI_IN_PLACE, &rebuilt, 1, MPI_INT64_T, MPI_SUM, comm_);
    total_bytes += bytes;
    if (l == 0) fine_nnz = 9.0 * double(pairs), fine_dofs = 3.0 * copies;
    PetscCall(PetscViewerASCIIPrintf(viewer, "  %5d %10d %11lld %9d %11lld %12.2f %9lld%s\n", l,
                                     int(lev.graph.num_cells()), (long long)shared,
                                     3 * int(lev.copies().num_copies), (long long)(9 * pairs),
                                     bytes / (1024.0 * 1024.0), (long long)rebuilt,
                                     l == num_levels() - 1 ? "  (coarsest: assembled, Cholesky)"
                                     : data_[l]->A         ? "  (assembled: P^T A P)"
                                                           : ""));
    if (l > 0 && d.stored && stored[1] < cells)
      PetscCall(PetscViewerASCIIPrintf(
          viewer, "        %.0f blocks stored for its %.0f cells (shared)\n", stored[1], cells));
    if (lev.ranks < levels_[0].ranks || lev.remote_children)
      PetscCall(PetscViewerASCIIPrintf(viewer, "        on %d of %d ranks%s\n", lev.ranks,
                                       levels_[0].ranks,
                                       lev.remote_children ? ", children on other ranks" : ""));
  }
  if (opt_.smoother == Smoother::chebyshev) {
    PetscCall(PetscViewerASCIIPrintf(viewer, "  lambda_max(D^-1 A) estimates:"));
    for (int l = 0; l + 1 < num_levels(); ++l)
      PetscCall(PetscViewerASCIIPrintf(viewer, " %.4f", data_[l]->lambda_max));
    PetscCall(PetscViewerASCIIPrintf(viewer, "\n"));
  }
  const char* interp[] = {"trilinear", "energy", "smoothed"};
  PetscCall(PetscViewerASCIIPrintf(viewer, "  interpolation %s: %lld energy-minimized rows",
                                   interp[int(opt_.interpolation)], (long long)energy_rows));
  for (int l = 0; l + 1 < num_levels(); ++l) {
    std::int64_t rows = data_[l]->smoothed_rows;
    MPI_Allreduce(MPI_IN_PLACE, &rows, 1, MPI_INT64_T, MPI_SUM, comm_);
    if (rows > 0)
      PetscCall(PetscViewerASCIIPrintf(viewer, "; level %d: %lld smoothed rows, omega %.4f", l,
                                       (long long)rows, data_[l]->smoothing_omega));
  }
  for (int l = 0; l + 1 < num_levels(); ++l)
    if (energy_stats_[l].rows > 0)
      PetscCall(PetscViewerASCIIPrintf(viewer, "; level %d: trace(P^T A P) %.3g -> %.3g", l,
                                       energy_stats_[l].energy_before,
                                       energy_stats_[l].energy_after));
  PetscCall(PetscViewerASCIIPrintf(viewer, "\n  Chebyshev degree and preconditioner per level:"));
  for (int l = 0; l + 1 < num_levels(); ++l)
    PetscCall(PetscViewerASCIIPrintf(viewer, " %d/%s", degree(l, opt_.presmooth),
                                     patches[l] > 0 ? "Schwarz" : "Jacobi"));
  PetscCall(PetscViewerASCIIPrintf(viewer, " (Schwarz patches:"));
  for (int l = 0; l + 1 < num_levels(); ++l)
    PetscCall(PetscViewerASCIIPrintf(viewer, " %lld", (long long)patches[l]));
  PetscCall(PetscViewerASCIIPrintf(viewer, ")\n"));
  PetscCall(PetscViewerASCIIPrintf(
      viewer,
      "  total %.1f MiB = %.0f bytes/DOF; an assembled AIJ matrix of level 0 alone "
      "(value + column index per nonzero) would be %.0f bytes/DOF (ratio %.2f)\n",
      total_bytes / (1024.0 * 1024.0), total_bytes / fine_dofs, 12.0 * fine_nnz / fine_dofs,
      total_bytes / (12.0 * fine_nnz)));
  PetscFunctionReturn(0);
}

}  // namespace hexcut::multigrid
