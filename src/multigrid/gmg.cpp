#include "multigrid/gmg.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <set>

#include "common/errors.hpp"
#include "common/petsc_check.hpp"
#include "element/element.hpp"
#include "multigrid/kernels.hpp"

namespace hexcut::multigrid {

struct Multigrid::LevelData {
  DM dm = nullptr;
  bool own_dm = false;
  Vec b = nullptr, x = nullptr, r = nullptr, tmp = nullptr;  // global
  Vec dir = nullptr;                                         // global: Chebyshev direction
  Vec xl = nullptr, yl = nullptr;                            // local
  Vec mask = nullptr;                                        // global: 1 free, 0 prescribed or dead
  std::vector<double> mask_local;                            // per local DOF
  std::vector<double> cell_matrix;                           // packed 300 per local cell (l >= 1)
  std::vector<std::int32_t> child_offset, children;          // l >= 1: local children per cell
  std::vector<double> diag_inv;                              // 9 per owned copy
  std::vector<int> colour;                                   // per owned copy
  std::vector<std::int32_t> colour_list[8];                  // owned copies of each colour
  std::vector<char> cell_masked;                             // level 0: cell has a prescribed DOF
  std::vector<char> dirty;                                   // per local cell: rebuilt by update()
  std::vector<FineCell> fine;                                // level 0: kernel view of each cell
  std::vector<std::array<double, 576>> own_stiffness;        // level 0: K of cells without a kind
  std::vector<std::array<int, 3>> cell_pos;                  // per local cell
  std::vector<std::int32_t> local_cell;                      // canonical cell -> local index, -1
  Mat P = nullptr;  // interpolation from level l+1 (3 DOFs per copy)
  double lambda_max = 0.0;
};

namespace {

PetscErrorCode shell_mult(Mat A, Vec x, Vec y) {
  PetscFunctionBeginUser;
  Multigrid* mg;
  PetscCall(MatShellGetContext(A, &mg));
  PetscCall(mg->apply_fine(x, y));
  PetscFunctionReturn(0);
}

PetscErrorCode pc_apply(PC pc, Vec b, Vec x) {
  PetscFunctionBeginUser;
  Multigrid* mg;
  PetscCall(PCShellGetContext(pc, &mg));
  PetscCall(mg->vcycle(b, x));
  PetscFunctionReturn(0);
}

PetscErrorCode pc_view(PC pc, PetscViewer viewer) {
  PetscFunctionBeginUser;
  Multigrid* mg;
  PetscCall(PCShellGetContext(pc, &mg));
  PetscCall(mg->view(viewer));
  PetscFunctionReturn(0);
}

}  // namespace

/// The mask of the local copies (owned + ghosts) from the global mask.
void Multigrid::refresh_local_mask(LevelData& d) {
  check_petsc(DMGlobalToLocalBegin(d.dm, d.mask, INSERT_VALUES, d.xl), "g2l");
  check_petsc(DMGlobalToLocalEnd(d.dm, d.mask, INSERT_VALUES, d.xl), "g2l");
  const PetscScalar* ml;
  PetscInt n;
  check_petsc(VecGetLocalSize(d.xl, &n), "size");
  check_petsc(VecGetArrayRead(d.xl, &ml), "array");
  d.mask_local.assign(ml, ml + n);
  check_petsc(VecRestoreArrayRead(d.xl, &ml), "array");
}

Options read_options() {
  Options o;
  PetscInt n;
  PetscBool set;
  char buf[64];
  check_petsc(PetscOptionsGetInt(nullptr, nullptr, "-gmg_levels", &n, &set), "options");
  if (set) {
    if (n < 1) throw InputError("-gmg_levels must be >= 1");
    o.hierarchy.levels = int(n);
  }
  check_petsc(PetscOptionsGetInt(nullptr, nullptr, "-gmg_coarse_dofs", &n, &set), "options");
  if (set) {
    if (n < 3) throw InputError("-gmg_coarse_dofs must be >= 3");
    o.hierarchy.coarse_dofs = n;
  }
  check_petsc(PetscOptionsGetString(nullptr, nullptr, "-gmg_hierarchy", buf, sizeof buf, &set),
              "options");
  if (set) {
    if (!std::strcmp(buf, "naive"))
      o.hierarchy.mode = hierarchy::Coarsening::naive;
    else if (!std::strcmp(buf, "components"))
      o.hierarchy.mode = hierarchy::Coarsening::components;
    else
      throw InputError(std::string("-gmg_hierarchy must be components or naive, got ") + buf);
  }
  check_petsc(PetscOptionsGetString(nullptr, nullptr, "-gmg_smoother", buf, sizeof buf, &set),
              "options");
  if (set) {
    if (!std::strcmp(buf, "gs"))
      o.smoother = Smoother::gauss_seidel;
    else if (!std::strcmp(buf, "chebyshev"))
      o.smoother = Smoother::chebyshev;
    else
      throw InputError(std::string("-gmg_smoother must be gs or chebyshev, got ") + buf);
  }
  check_petsc(PetscOptionsGetInt(nullptr, nullptr, "-gmg_presmooth", &n, &set), "options");
  if (set) o.presmooth = int(n);
  check_petsc(PetscOptionsGetInt(nullptr, nullptr, "-gmg_postsmooth", &n, &set), "options");
  if (set) o.postsmooth = int(n);
  if (o.presmooth < 0 || o.postsmooth < 0 || o.presmooth + o.postsmooth == 0)
    throw InputError("-gmg_presmooth and -gmg_postsmooth must be >= 0 and not both 0");
  PetscReal w;
  check_petsc(PetscOptionsGetReal(nullptr, nullptr, "-gmg_omega", &w, &set), "options");
  if (set) {
    if (!(w > 0 && w < 2)) throw InputError("-gmg_omega must be in (0, 2)");
    o.omega = w;
  }
  check_petsc(PetscOptionsGetReal(nullptr, nullptr, "-gmg_rebuild_tol", &w, &set), "options");
  if (set) {
    if (!(w >= 0)) throw InputError("-gmg_rebuild_tol must be >= 0");
    o.rebuild_tolerance = w;
  }
  check_petsc(PetscOptionsGetInt(nullptr, nullptr, "-gmg_eig_every", &n, &set), "options");
  if (set) {
    if (n < 1) throw InputError("-gmg_eig_every must be >= 1");
    o.eig_every = int(n);
  }
  check_petsc(PetscOptionsGetString(nullptr, nullptr, "-gmg_cycle", buf, sizeof buf, &set),
              "options");
  o.cycle_set = set;
  if (set) {
    if (!std::strcmp(buf, "v"))
      o.cycle_gamma = 1;
    else if (!std::strcmp(buf, "w"))
      o.cycle_gamma = 2;
    else
      throw InputError(std::string("-gmg_cycle must be v or w, got ") + buf);
  }
  PetscBool view = PETSC_FALSE;
  check_petsc(PetscOptionsGetBool(nullptr, nullptr, "-gmg_view", &view, nullptr), "options");
  o.view = view;
  return o;
}

Multigrid::Multigrid(MPI_Comm comm, const lattice::Lattice& lattice,
                     const topology::VertexCopies& copies, const topology::Partition& partition,
                     const topology::DofLayout& layout, DM fine_dm, const Options& options)
    : comm_(comm), opt_(options) {
  // One class and one set of events for the process, however many hierarchies a run
  // builds (one per cut), so -log_view sums them.
  static const std::array<PetscLogEvent, 3> events = [] {
    PetscClassId id;
    std::array<PetscLogEvent, 3> e{};
    check_petsc(PetscClassIdRegister("hexcut-gmg", &id), "class id");
    check_petsc(PetscLogEventRegister("gmgSetup", id, &e[0]), "event");
    check_petsc(PetscLogEventRegister("gmgVcycle", id, &e[1]), "event");
    check_petsc(PetscLogEventRegister("gmgSmooth", id, &e[2]), "event");
    return e;
  }();
  ev_setup_ = events[0];
  ev_apply_ = events[1];
  ev_smooth_ = events[2];
  // Hierarchy construction counts as multigrid set-up (with update()'s operator build).
  PetscLogEventBegin(ev_setup_, 0, 0, 0, 0);
  const int rank = layout.rank;
  levels_ = hierarchy::build_hierarchy(topology::graph_from_lattice(lattice), copies, partition,
                                       layout, options.hierarchy);
  const int L = int(levels_.size());
  for (int l = 0; l < L; ++l) {
    auto d = std::make_unique<LevelData>();
    const auto& lev = levels_[l];
    if (l == 0) {
      d->dm = fine_dm;
    } else {
      check_petsc(topology::create_dm(comm, lev.layout, &d->dm), "create_dm");
      d->own_dm = true;
    }
    check_petsc(DMCreateGlobalVector(d->dm, &d->b), "vec");
    check_petsc(VecDuplicate(d->b, &d->x), "vec");
    check_petsc(VecDuplicate(d->b, &d->r), "vec");
    check_petsc(VecDuplicate(d->b, &d->tmp), "vec");
    check_petsc(VecDuplicate(d->b, &d->dir), "vec");
    check_petsc(VecDuplicate(d->b, &d->mask), "vec");
    check_petsc(DMCreateLocalVector(d->dm, &d->xl), "vec");
    check_petsc(VecDuplicate(d->xl, &d->yl), "vec");
    const auto& D = lev.layout;
    d->cell_pos.resize(D.cells.size());
    d->local_cell.assign(lev.graph.num_cells(), -1);
    for (std::size_t e = 0; e < D.cells.size(); ++e) {
      const auto& p = lev.graph.ijk[D.cells[e]];
      d->cell_pos[e] = {p[0], p[1], p[2]};
      d->local_cell[D.cells[e]] = std::int32_t(e);
    }
    d->colour.resize(D.num_owned);
    for (std::int32_t i = 0; i < D.num_owned; ++i) {
      const auto& v = lev.copies.vertex[D.copies[i]];
      d->colour[i] = element::parity_octant(v[0], v[1], v[2]);
      d->colour_list[d->colour[i]].push_back(i);
    }
    data_.push_back(std::move(d));
  }
  // Children of every local coarse cell (all on this rank: they share a super-block).
  for (int l = 1; l < L; ++l) {
    auto& d = *data_[l];
    const auto& fine = levels_[l - 1];
    const std::size_t n = levels_[l].layout.cells.size();
    d.child_offset.assign(n + 1, 0);
    std::vector<std::int32_t> parent_of(fine.layout.cells.size());
    for (std::size_t e = 0; e < fine.layout.cells.size(); ++e) {
      const auto C = d.local_cell[fine.parent[fine.layout.cells[e]]];
      if (C < 0) throw std::logic_error("gmg: a coarse cell's children are on different ranks");
      parent_of[e] = C;
      ++d.child_offset[C + 1];
    }
    for (std::size_t C = 0; C < n; ++C) d.child_offset[C + 1] += d.child_offset[C];
    d.children.resize(fine.layout.cells.size());
    std::vector<std::int32_t> next(d.child_offset.begin(), d.child_offset.end() - 1);
    for (std::size_t e = 0; e < fine.layout.cells.size(); ++e)
      d.children[next[parent_of[e]]++] = std::int32_t(e);
  }
  // Interpolation l+1 -> l as a scalar AIJ over copies, expanded to 3 DOFs with MAIJ.
  for (int l = 0; l + 1 < L; ++l) {
    const auto I = hierarchy::interpolation(levels_[l], levels_[l + 1], rank);
    const auto& fine = levels_[l].layout;
    const auto& coarse = levels_[l + 1].layout;
    Mat P;
    check_petsc(MatCreateAIJ(comm, fine.num_owned, coarse.num_owned, PETSC_DETERMINE,
                             PETSC_DETERMINE, 8, nullptr, 8, nullptr, &P),
                "MatCreateAIJ");
    for (std::size_t i = 0; i < I.fine.size(); ++i) {
      const PetscInt row = fine.global_block[I.fine[i]];
      for (int j = 0; j < 8 && I.coarse[i][j] >= 0; ++j)
        check_petsc(
            MatSetValue(P, row, coarse.global_block[I.coarse[i][j]], I.weight[i][j], INSERT_VALUES),
            "MatSetValue");
    }
    check_petsc(MatAssemblyBegin(P, MAT_FINAL_ASSEMBLY), "assembly");
    check_petsc(MatAssemblyEnd(P, MAT_FINAL_ASSEMBLY), "assembly");
    check_petsc(MatCreateMAIJ(P, 3, &data_[l]->P), "MatCreateMAIJ");
    check_petsc(MatDestroy(&P), "MatDestroy");
  }
  const auto& D0 = levels_[0].layout;
  check_petsc(MatCreateShell(comm, 3 * D0.num_owned, 3 * D0.num_owned, PETSC_DETERMINE,
                             PETSC_DETERMINE, this, &shell_),
              "MatCreateShell");
  check_petsc(MatShellSetOperation(shell_, MATOP_MULT, (void (*)(void))shell_mult),
              "MatShellSetOperation");
  check_petsc(MatSetBlockSize(shell_, 3), "MatSetBlockSize");
  check_petsc(MatSetOption(shell_, MAT_SYMMETRIC, PETSC_TRUE), "MatSetOption");
  check_petsc(MatSetOption(shell_, MAT_SPD, PETSC_TRUE), "MatSetOption");
  PetscLogEventEnd(ev_setup_, 0, 0, 0, 0);
}

Multigrid::~Multigrid() {
  for (auto& d : data_) {
    VecDestroy(&d->b);
    VecDestroy(&d->x);
    VecDestroy(&d->r);
    VecDestroy(&d->tmp);
    VecDestroy(&d->dir);
    VecDestroy(&d->mask);
    VecDestroy(&d->xl);
    VecDestroy(&d->yl);
    MatDestroy(&d->P);
    if (d->own_dm) DMDestroy(&d->dm);
  }
  MatDestroy(&shell_);
  MatDestroy(&coarse_matrix_);
  KSPDestroy(&coarse_ksp_);
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

void Multigrid::mark_dirty_fine_cells(const assembly::CellData& cells, bool full) {
  // A fine cell is dirty when its rotation moved by more than the tolerance since the
  // block of its parent was built (or on a full rebuild).
  auto& d = *data_[0];
  const std::size_t n = levels_[0].layout.cells.size();
  d.dirty.assign(n, full ? 1 : 0);
  if (full) return;
  const double tol = opt_.rebuild_tolerance;
  for (std::size_t e = 0; e < n; ++e) {
    const double* now = &cells.rotation[9 * e];
    const double* then = &built_rotation_[9 * e];
    for (int k = 0; k < 9 && !d.dirty[e]; ++k)
      if (std::abs(now[k] - then[k]) > tol) d.dirty[e] = 1;
  }
}

void Multigrid::update(const assembly::CellData& cells, const assembly::OperatorWeights& w,
                       const std::vector<PetscInt>& constrained_rows) {
  PetscLogEventBegin(ev_setup_, 0, 0, 0, 0);
  const int L = num_levels();
  // Anything but rotations changed: rebuild everything (a collective decision).
  int full = !built_ || w.stiffness != weights_.stiffness || w.mass != weights_.mass ||
             w.lumped_mass != weights_.lumped_mass || constrained_rows != built_rows_ ||
             built_rotation_.size() != cells.rotation.size();
  MPI_Allreduce(MPI_IN_PLACE, &full, 1, MPI_INT, MPI_LOR, comm_);
  fine_cells_ = &cells;
  weights_ = w;
  rebuilt_.assign(L, 0);
  auto& d0 = *data_[0];
  const auto& D0 = levels_[0].layout;
  if (full) {
    // Level 0 mask from the prescribed rows, then to the ghosts.
    built_rows_ = constrained_rows;
    check_petsc(VecSet(d0.mask, 1.0), "VecSet");
    PetscInt lo;
    check_petsc(VecGetOwnershipRange(d0.mask, &lo, nullptr), "range");
    PetscScalar* m;
    check_petsc(VecGetArray(d0.mask, &m), "array");
    for (PetscInt row : constrained_rows) m[row - lo] = 0.0;
    check_petsc(VecRestoreArray(d0.mask, &m), "array");
    refresh_local_mask(d0);
    d0.cell_masked.assign(D0.cells.size(), 0);
    for (std::size_t e = 0; e < D0.cells.size(); ++e)
      for (auto v : D0.cell_corners[e])
        for (int c = 0; c < 3; ++c)
          if (d0.mask_local[3 * v + c] == 0.0) d0.cell_masked[e] = 1;
  }
  mark_dirty_fine_cells(cells, full);
  // Kernel views of the fine cells, built once per update rather than per cell visit.
  // The fine operator always uses the current rotations, whatever is rebuilt above it.
  d0.fine.resize(D0.cells.size());
  d0.own_stiffness.clear();
  std::size_t own = 0;
  for (std::size_t e = 0; e < D0.cells.size(); ++e) own += cells.kind[e] < 0;
  d0.own_stiffness.resize(own);
  own = 0;
  for (std::size_t e = 0; e < D0.cells.size(); ++e) {
    double* buffer = cells.kind[e] < 0 ? d0.own_stiffness[own++].data() : nullptr;
    d0.fine[e] = assembly::fine_cell_view(cells, e, w, buffer);
  }
  build_diagonal(0);
  for (char c : d0.dirty) rebuilt_[0] += c;
  // Galerkin coarse blocks, level by level, for the coarse cells with a dirty child: each
  // is accumulated in full 24x24 form from its (at most 8) children, then stored packed.
  if (built_rotation_.size() != cells.rotation.size())
    built_rotation_.assign(cells.rotation.size(), 0.0);
  for (int l = 1; l < L; ++l) {
    auto& d = *data_[l];
    const auto& fd = *data_[l - 1];
    const std::size_t n = levels_[l].layout.cells.size();
    if (d.cell_matrix.size() != kPackedSize * n) d.cell_matrix.assign(kPackedSize * n, 0.0);
    d.dirty.assign(n, 0);
    double child[576], parent[576];
    for (std::size_t C = 0; C < n; ++C) {
      for (auto k = d.child_offset[C]; k < d.child_offset[C + 1]; ++k)
        if (fd.dirty[d.children[k]]) d.dirty[C] = 1;
      if (!d.dirty[C]) continue;
      ++rebuilt_[l];
      std::fill(parent, parent + 576, 0.0);
      for (auto k = d.child_offset[C]; k < d.child_offset[C + 1]; ++k) {
        const auto e = std::size_t(d.children[k]);
        if (l - 1 == 0) {
          masked_fine_operator(e, child);
          std::copy_n(&cells.rotation[9 * e], 9, &built_rotation_[9 * e]);
        } else {
          unpack_symmetric(&fd.cell_matrix[kPackedSize * e], child);
        }
        const auto& p = fd.cell_pos[e];
        galerkin_accumulate(child, element::parity_octant(p[0], p[1], p[2]), parent);
      }
      pack_symmetric(parent, &d.cell_matrix[kPackedSize * C]);
    }
    // The diagonal blocks sum over ranks: rebuilt wherever any rank changed this level.
    int changed = rebuilt_[l] > 0;
    MPI_Allreduce(MPI_IN_PLACE, &changed, 1, MPI_INT, MPI_LOR, comm_);
    if (changed) build_diagonal(l);
    if (l == L - 1 && changed) build_coarsest();
  }
  if (L == 1) build_coarsest();
  if (opt_.smoother == Smoother::chebyshev) {
    if (full || ++updates_since_estimate_ >= opt_.eig_every) {
      for (int l = 0; l + 1 < L; ++l) estimate_lambda_max(l);
      updates_since_estimate_ = 0;
    }
  }
  built_ = true;
  PetscLogEventEnd(ev_setup_, 0, 0, 0, 0);
  if (opt_.view) check_petsc(view(PETSC_VIEWER_STDOUT_(comm_)), "view");
}

void Multigrid::masked_fine_operator(std::size_t e, double* A) const {
  // The fine cell's 24x24 operator with the rows and columns of prescribed DOFs zeroed:
  // the constrained operator the coarse levels are built from.
  assembly::cell_operator(*fine_cells_, e, weights_, A);
  double m[24];
  element::gather_cell(data_[0]->mask_local.data(), levels_[0].layout.cell_corners[e].data(), m);
  for (int r = 0; r < 24; ++r)
    for (int c = 0; c < 24; ++c) A[24 * r + c] *= m[r] * m[c];
}

void Multigrid::build_diagonal(int l) {
  auto& d = *data_[l];
  const auto& D = levels_[l].layout;
  // 3x3 diagonal blocks, 9 numbers per copy, summed over ranks through a temporary
  // ghost exchange (kept only during set-up: it would be the largest array per DOF).
  Vec diag_g, diag_l;
  VecScatter diag_scatter;
  check_petsc(topology::create_ghost_scatter(comm_, D, 9, &diag_g, &diag_l, &diag_scatter),
              "ghost scatter");
  check_petsc(VecSet(diag_l, 0.0), "VecSet");
  PetscScalar* dl;
  check_petsc(VecGetArray(diag_l, &dl), "array");
  double A[576], block[9];
  for (std::size_t e = 0; e < D.cells.size(); ++e) {
    // Level 0: only the 3x3 diagonal blocks of the fine operator, not the 24x24 matrix.
    if (l > 0) unpack_symmetric(&d.cell_matrix[kPackedSize * e], A);
    for (int q = 0; q < 8; ++q) {
      const auto v = D.cell_corners[e][q];
      if (l == 0) {
        element::fine_diagonal_block(d.fine[e], q, block);
      } else {
        for (int i = 0; i < 3; ++i)
          for (int j = 0; j < 3; ++j) block[3 * i + j] = A[24 * (3 * q + i) + 3 * q + j];
      }
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) {
          double a = block[3 * i + j];
          if (l == 0) a *= d.mask_local[3 * v + i] * d.mask_local[3 * v + j];
          dl[9 * v + 3 * i + j] += a;
        }
    }
  }
  check_petsc(VecRestoreArray(diag_l, &dl), "array");
  check_petsc(VecSet(diag_g, 0.0), "VecSet");
  check_petsc(VecScatterBegin(diag_scatter, diag_l, diag_g, ADD_VALUES, SCATTER_REVERSE),
              "scatter");
  check_petsc(VecScatterEnd(diag_scatter, diag_l, diag_g, ADD_VALUES, SCATTER_REVERSE), "scatter");
  const PetscScalar* dg;
  check_petsc(VecGetArrayRead(diag_g, &dg), "array");
  PetscScalar* m;
  check_petsc(VecGetArray(d.mask, &m), "array");
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
      throw SolverError("gmg: singular 3x3 diagonal block on level " + std::to_string(l));
  }
  check_petsc(VecRestoreArray(d.mask, &m), "array");
  check_petsc(VecRestoreArrayRead(diag_g, &dg), "array");
  check_petsc(VecDestroy(&diag_g), "VecDestroy");
  check_petsc(VecDestroy(&diag_l), "VecDestroy");
  check_petsc(VecScatterDestroy(&diag_scatter), "VecScatterDestroy");
  if (l > 0) refresh_local_mask(d);
}

void Multigrid::apply_local(int l, const double* x, double* y) const {
  const auto& D = levels_[l].layout;
  const auto& d = *data_[l];
  double xe[24], ye[24];
  if (l == 0) {
    const auto& m = d.mask_local;
    for (std::size_t e = 0; e < D.cells.size(); ++e) {
      const auto& corners = D.cell_corners[e];
      element::gather_cell(x, corners.data(), xe);
      std::fill(ye, ye + 24, 0.0);
      if (d.cell_masked[e]) {
        for (int q = 0; q < 8; ++q)
          for (int k = 0; k < 3; ++k) xe[3 * q + k] *= m[3 * corners[q] + k];
        fine_cell_apply_add(d.fine[e], xe, ye);
        for (int q = 0; q < 8; ++q)
          for (int k = 0; k < 3; ++k) ye[3 * q + k] *= m[3 * corners[q] + k];
      } else {
        fine_cell_apply_add(d.fine[e], xe, ye);
      }
      element::scatter_add_cell(ye, corners.data(), y);
    }
  } else {
    for (std::size_t e = 0; e < D.cells.size(); ++e) {
      element::gather_cell(x, D.cell_corners[e].data(), xe);
      std::fill(ye, ye + 24, 0.0);
      packed_apply_add(&d.cell_matrix[kPackedSize * e], xe, ye);
      element::scatter_add_cell(ye, D.cell_corners[e].data(), y);
    }
  }
}

PetscErrorCode Multigrid::apply_level_impl(int l, Vec x, Vec y) {
  PetscFunctionBeginUser;
  auto& d = *data_[l];
  PetscCall(DMGlobalToLocalBegin(d.dm, x, INSERT_VALUES, d.xl));
  PetscCall(DMGlobalToLocalEnd(d.dm, x, INSERT_VALUES, d.xl));
  PetscCall(VecSet(d.yl, 0.0));
  const PetscScalar* xa;
  PetscScalar* ya;
  PetscCall(VecGetArrayRead(d.xl, &xa));
  PetscCall(VecGetArray(d.yl, &ya));
  apply_local(l, xa, ya);
  PetscCall(VecRestoreArrayRead(d.xl, &xa));
  PetscCall(VecRestoreArray(d.yl, &ya));
  PetscCall(VecSet(y, 0.0));
  PetscCall(DMLocalToGlobalBegin(d.dm, d.yl, ADD_VALUES, y));
  PetscCall(DMLocalToGlobalEnd(d.dm, d.yl, ADD_VALUES, y));
  // Prescribed and dead DOFs: identity rows.
  const PetscScalar *m, *xg;
  PetscScalar* yg;
  PetscInt n;
  PetscCall(VecGetLocalSize(y, &n));
  PetscCall(VecGetArrayRead(d.mask, &m));
  PetscCall(VecGetArrayRead(x, &xg));
  PetscCall(VecGetArray(y, &yg));
  for (PetscInt i = 0; i < n; ++i)
    if (m[i] == 0.0) yg[i] += xg[i];
  PetscCall(VecRestoreArray(y, &yg));
  PetscCall(VecRestoreArrayRead(x, &xg));
  PetscCall(VecRestoreArrayRead(d.mask, &m));
  PetscFunctionReturn(0);
}

PetscErrorCode Multigrid::apply_fine(Vec x, Vec y) {
  return apply_level_impl(0, x, y);
}
PetscErrorCode Multigrid::apply_level(int l, Vec x, Vec y) {
  return apply_level_impl(l, x, y);
}

PetscErrorCode Multigrid::gauss_seidel(int l, Vec b, Vec x, bool reverse) {
  PetscFunctionBeginUser;
  auto& d = *data_[l];
  const auto& D = levels_[l].layout;
  // On one rank the local and global numberings coincide (no ghosts): sweep in place.
  // In parallel each colour needs the ghosts of x before and the sum of the residual
  // contributions over ranks after.
  const bool serial = D.num_ranks == 1;
  if (!serial) {
    PetscCall(DMGlobalToLocalBegin(d.dm, x, INSERT_VALUES, d.xl));
    PetscCall(DMGlobalToLocalEnd(d.dm, x, INSERT_VALUES, d.xl));
  }
  for (int kk = 0; kk < 8; ++kk) {
    const int k = reverse ? 7 - kk : kk;
    // A x at the copies of colour k, from the rank's cells: each cell has exactly one
    // corner of colour k, so a colour costs 1/8 of an operator application.
    const PetscScalar* xa;
    PetscScalar* ya;
    PetscCall(VecGetArrayRead(serial ? x : d.xl, &xa));
    PetscCall(VecGetArray(d.yl, &ya));
    if (serial) {
      for (auto i : d.colour_list[k])
        for (int c = 0; c < 3; ++c) ya[3 * i + c] = 0.0;
    } else {
      std::fill(ya, ya + 3 * D.num_local(), 0.0);
    }
    double xe[24], y3[3];
    for (std::size_t e = 0; e < D.cells.size(); ++e) {
      const auto& corners = D.cell_corners[e];
      const int q = corner_of_colour(d.cell_pos[e].data(), k);
      if (l == 0) {
        element::gather_cell(xa, corners.data(), xe);
        if (d.cell_masked[e]) {
          const auto& m = d.mask_local;
          for (int p = 0; p < 8; ++p)
            for (int c = 0; c < 3; ++c) xe[3 * p + c] *= m[3 * corners[p] + c];
          fine_row_block(d.fine[e], q, xe, y3);
          for (int c = 0; c < 3; ++c) y3[c] *= m[3 * corners[q] + c];
        } else {
          fine_row_block(d.fine[e], q, xe, y3);
        }
      } else {
        element::gather_cell(xa, corners.data(), xe);
        packed_row_block(&d.cell_matrix[kPackedSize * e], q, xe, y3);
      }
      for (int c = 0; c < 3; ++c) ya[3 * corners[q] + c] += y3[c];
    }
    PetscCall(VecRestoreArrayRead(serial ? x : d.xl, &xa));
    PetscCall(VecRestoreArray(d.yl, &ya));
    Vec r = d.yl;  // serial: the residual contributions are already complete
    if (!serial) {
      PetscCall(VecSet(d.r, 0.0));
      PetscCall(DMLocalToGlobalBegin(d.dm, d.yl, ADD_VALUES, d.r));
      PetscCall(DMLocalToGlobalEnd(d.dm, d.yl, ADD_VALUES, d.r));
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
      PetscCall(DMGlobalToLocalBegin(d.dm, x, INSERT_VALUES, d.xl));
      PetscCall(DMGlobalToLocalEnd(d.dm, x, INSERT_VALUES, d.xl));
    }
  }
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

void Multigrid::estimate_lambda_max(int l) {
  // Power iteration on D^{-1} A from a pseudo-random start vector that is a function of
  // the canonical copy numbering, so the estimate (and hence the smoother) is the same on
  // any number of ranks.
  auto& d = *data_[l];
  const auto& D = levels_[l].layout;
  Vec v = d.tmp, w = d.r;
  PetscScalar* a;
  check_petsc(VecGetArray(v, &a), "array");
  for (std::int32_t i = 0; i < D.num_owned; ++i)
    for (int c = 0; c < 3; ++c) {
      const double k = double(3 * std::int64_t(D.copies[i]) + c);
      const double hash = std::sin(12.9898 * k + 78.233) * 43758.5453;
      a[3 * i + c] = 0.5 + (hash - std::floor(hash));
    }
  check_petsc(VecRestoreArray(v, &a), "array");
  // Power iteration approaches lambda_max from below; the top of a smoothing spectrum is
  // dense, so 15 iterations land within a few per cent, and Chebyshev's interval
  // extends 10% above the estimate.
  double lambda = 0.0;
  for (int it = 0; it < 15; ++it) {
    PetscReal nv;
    check_petsc(VecNormalize(v, &nv), "normalize");
    check_petsc(apply_level_impl(l, v, w), "apply");
    check_petsc(block_jacobi(d.diag_inv, w, v), "jacobi");
    PetscReal nw;
    check_petsc(VecNorm(v, NORM_2, &nw), "norm");
    lambda = nw;
  }
  d.lambda_max = lambda;
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
  PetscCall(block_jacobi(d.diag_inv, r, z));
  PetscCall(VecAXPBY(dir, 1.0 / theta, 0.0, z));
  for (int i = 0; i < degree; ++i) {
    PetscCall(VecAXPY(x, 1.0, dir));
    if (i + 1 == degree) break;
    PetscCall(apply_level_impl(l, x, r));
    PetscCall(VecAYPX(r, -1.0, b));
    PetscCall(block_jacobi(d.diag_inv, r, z));
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
    PetscCall(chebyshev(l, b, x, sweeps));
  } else {
    for (int s = 0; s < sweeps; ++s) PetscCall(gauss_seidel(l, b, x, reverse));
  }
  PetscCall(PetscLogEventEnd(ev_smooth_, 0, 0, 0, 0));
  PetscFunctionReturn(0);
}

void Multigrid::build_coarsest() {
  const int l = num_levels() - 1;
  const auto& lev = levels_[l];
  auto& d = *data_[l];
  // The pattern never changes: re-filling the same matrix lets the factorization keep
  // its symbolic phase and redo only the numeric one.
  if (!coarse_matrix_)
    check_petsc(assembly::create_matrix(comm_, lev.copies, lev.layout, &coarse_matrix_),
                "create_matrix");
  else
    check_petsc(MatZeroEntries(coarse_matrix_), "MatZeroEntries");
  double A[576];
  PetscInt idx[8];
  for (std::size_t e = 0; e < lev.layout.cells.size(); ++e) {
    if (l == 0)
      masked_fine_operator(e, A);
    else
      unpack_symmetric(&d.cell_matrix[kPackedSize * e], A);
    for (int q = 0; q < 8; ++q)
      idx[q] = lev.layout.global_block[lev.layout.copies[lev.layout.cell_corners[e][q]]];
    check_petsc(MatSetValuesBlocked(coarse_matrix_, 8, idx, 8, idx, A, ADD_VALUES),
                "MatSetValuesBlocked");
  }
  PetscInt lo;
  check_petsc(VecGetOwnershipRange(d.mask, &lo, nullptr), "range");
  const PetscScalar* m;
  PetscInt n;
  check_petsc(VecGetLocalSize(d.mask, &n), "size");
  check_petsc(VecGetArrayRead(d.mask, &m), "array");
  for (PetscInt i = 0; i < n; ++i)
    if (m[i] == 0.0)
      check_petsc(MatSetValue(coarse_matrix_, lo + i, lo + i, 1.0, ADD_VALUES), "MatSetValue");
  check_petsc(VecRestoreArrayRead(d.mask, &m), "array");
  check_petsc(MatAssemblyBegin(coarse_matrix_, MAT_FINAL_ASSEMBLY), "assembly");
  check_petsc(MatAssemblyEnd(coarse_matrix_, MAT_FINAL_ASSEMBLY), "assembly");
  if (!coarse_ksp_) {
    check_petsc(KSPCreate(comm_, &coarse_ksp_), "KSPCreate");
    check_petsc(KSPSetOptionsPrefix(coarse_ksp_, "gmg_coarse_"), "prefix");
    check_petsc(KSPSetType(coarse_ksp_, KSPPREONLY), "KSPSetType");
    PC pc;
    check_petsc(KSPGetPC(coarse_ksp_, &pc), "KSPGetPC");
    check_petsc(PCSetType(pc, PCCHOLESKY), "PCSetType");
    check_petsc(PCFactorSetMatSolverType(pc, MATSOLVERMUMPS), "solver type");
    // The masked Galerkin operator may be singular, though consistent: two coarse copies
    // whose columns of P differ only on prescribed fine DOFs (found on bunny.yaml near
    // its support: three zero eigenvalues of 2814). MUMPS then divides by a pivot that
    // is round-off, or zero, so the coarse correction was huge or NaN, varying with the
    // factorization's parallel scheduling (bunny_cuts on 2 ranks stopped with
    // DIVERGED_NANORINF or DIVERGED_INDEFINITE_PC in about 1 run of 8). Null-pivot
    // detection (ICNTL(24)) sets those components to zero instead; P x is unchanged.
    check_petsc(set_option_if_unset("-gmg_coarse_mat_mumps_icntl_24", "1"), "options");
    check_petsc(KSPSetFromOptions(coarse_ksp_), "KSPSetFromOptions");
  }
  check_petsc(KSPSetOperators(coarse_ksp_, coarse_matrix_, coarse_matrix_), "KSPSetOperators");
  check_petsc(KSPSetUp(coarse_ksp_), "KSPSetUp");
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

PetscErrorCode Multigrid::vcycle(Vec b, Vec x) {
  PetscFunctionBeginUser;
  PetscCall(PetscLogEventBegin(ev_apply_, 0, 0, 0, 0));
  PetscCall(VecCopy(b, data_[0]->b));
  PetscCall(cycle_level(0, true));
  PetscCall(VecCopy(data_[0]->x, x));
  PetscCall(PetscLogEventEnd(ev_apply_, 0, 0, 0, 0));
  PetscFunctionReturn(0);
}

PetscErrorCode Multigrid::attach(PC pc) {
  PetscFunctionBeginUser;
  PetscCall(PCSetType(pc, PCSHELL));
  PetscCall(PCShellSetContext(pc, this));
  PetscCall(PCShellSetApply(pc, pc_apply));
  PetscCall(PCShellSetView(pc, pc_view));
  PetscCall(PCShellSetName(pc, opt_.cycle_gamma == 2 ? "hexcut geometric multigrid (W-cycle)"
                                                     : "hexcut geometric multigrid (V-cycle)"));
  PetscFunctionReturn(0);
}

PetscErrorCode Multigrid::view(PetscViewer viewer) const {
  PetscFunctionBeginUser;
  PetscCall(PetscViewerASCIIPrintf(
      viewer, "hexcut gmg: %d levels, hierarchy %s, %s-cycle, smoother %s (%d,%d)%s\n",
      num_levels(),
      opt_.hierarchy.mode == hierarchy::Coarsening::components ? "components" : "naive",
      opt_.cycle_gamma == 2 ? "W" : "V",
      opt_.smoother == Smoother::gauss_seidel ? "8-colour block GS" : "Chebyshev/block Jacobi",
      opt_.presmooth, opt_.postsmooth,
      opt_.smoother == Smoother::gauss_seidel && opt_.omega != 1.0 ? " (omega != 1)" : ""));
  // "duplicated": cells that share their position with another cell of the level, the
  // pieces of one 2x2x2 block that holes, thin gaps or cuts separate.
  PetscCall(PetscViewerASCIIPrintf(
      viewer, "  level      cells  duplicated      DOFs   nnz-equiv     held MiB   rebuilt\n"));
  double total_bytes = 0.0, fine_nnz = 0.0, fine_dofs = 1.0;
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
    std::vector<std::vector<std::int32_t>> nb(lev.copies.num_copies);
    for (const auto& corners : lev.copies.cell_corners)
      for (auto a : corners)
        for (auto b : corners) nb[a].push_back(b);
    std::int64_t pairs = 0;
    for (auto& v : nb) {
      std::sort(v.begin(), v.end());
      pairs += std::unique(v.begin(), v.end()) - v.begin();
    }
    // What the multigrid holds for this level, summed over ranks: operator data (level 0:
    // lambda, mu, rho, R and a kernel view per cell; coarse: a packed 24x24 block per
    // cell), the inverted 3x3 diagonal blocks, the interpolation to this level from the
    // next (MAIJ over copies: value + column index, 8 per copy at most) and the work
    // vectors (6 global + 2 local, ghosts ignored). Level 0 also keeps the rotations the
    // coarse blocks were built from (partial rebuilds compare against them).
    const double cells = double(lev.graph.num_cells()), copies = double(lev.copies.num_copies);
    const double op = l == 0 ? cells * (22.0 * 8.0 + sizeof(FineCell)) : cells * kPackedSize * 8.0;
    const double transfer = l + 1 < num_levels() ? copies * 8.0 * 12.0 : 0.0;
    const double bytes = op + copies * 9.0 * 8.0 + transfer + 8.0 * 3.0 * copies * 8.0;
    std::int64_t rebuilt = rebuilt_.empty() ? 0 : rebuilt_[l];
    MPI_Allreduce(MPI_IN_PLACE, &rebuilt, 1, MPI_INT64_T, MPI_SUM, comm_);
    total_bytes += bytes;
    if (l == 0) fine_nnz = 9.0 * double(pairs), fine_dofs = 3.0 * copies;
    PetscCall(PetscViewerASCIIPrintf(
        viewer, "  %5d %10d %11lld %9d %11lld %12.2f %9lld%s\n", l, int(lev.graph.num_cells()),
        (long long)shared, 3 * int(lev.copies.num_copies), (long long)(9 * pairs),
        bytes / (1024.0 * 1024.0), (long long)rebuilt,
        l == num_levels() - 1 ? "  (coarsest: assembled, Cholesky)" : ""));
  }
  if (opt_.smoother == Smoother::chebyshev) {
    PetscCall(PetscViewerASCIIPrintf(viewer, "  lambda_max(D^-1 A) estimates:"));
    for (int l = 0; l + 1 < num_levels(); ++l)
      PetscCall(PetscViewerASCIIPrintf(viewer, " %.4f", data_[l]->lambda_max));
    PetscCall(PetscViewerASCIIPrintf(viewer, "\n"));
  }
  PetscCall(PetscViewerASCIIPrintf(
      viewer,
      "  total %.1f MiB = %.0f bytes/DOF; an assembled AIJ matrix of level 0 alone "
      "(value + column index per nonzero) would be %.0f bytes/DOF (ratio %.2f)\n",
      total_bytes / (1024.0 * 1024.0), total_bytes / fine_dofs, 12.0 * fine_nnz / fine_dofs,
      total_bytes / (12.0 * fine_nnz)));
  PetscFunctionReturn(0);
}

}  // namespace hexcut::multigrid
