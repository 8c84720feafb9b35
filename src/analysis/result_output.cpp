#include "analysis/result_output.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "analysis/events.hpp"
#include "assembly/operator.hpp"
#include "common/errors.hpp"
#include "common/mpi_gather.hpp"
#include "element/element.hpp"
#include "element/stress.hpp"
#include "element/trilinear.hpp"
#include "hexcut_version.hpp"

namespace hexcut::analysis {
namespace {

/// Even split of n rows over the communicator (same rule as PetscSplitOwnership).
output::Slab even_slab(MPI_Comm comm, std::int64_t n) {
  int rank, size;
  MPI_Comm_rank(comm, &rank);
  MPI_Comm_size(comm, &size);
  output::Slab s;
  s.global_rows = n;
  s.local_rows = n / size + (rank < n % size ? 1 : 0);
  s.row_offset = rank * (n / size) + std::min<std::int64_t>(rank, n % size);
  return s;
}

/// A cut link as a row of the checkpoint's int32 topology table: cell, direction, cut id,
/// then t and the normal in fixed point (2^-30 resolution: far below what a surface shows;
/// the mechanics does not use them), portable across byte orders.
constexpr int kCutLinkColumns = 7;
constexpr double kFixedPoint = 1073741824.0;  // 2^30

void encode_cut_link(const lattice::CutLink& l, std::int32_t* row) {
  row[0] = l.cell;
  row[1] = l.dir;
  row[2] = l.cut_id;
  row[3] = std::int32_t(std::lround(l.t * kFixedPoint));
  for (int d = 0; d < 3; ++d) row[4 + d] = std::int32_t(std::lround(l.normal[d] * kFixedPoint));
}

lattice::CutLink decode_cut_link(const std::int32_t* row) {
  lattice::CutLink l;
  l.cell = row[0];
  l.dir = row[1];
  l.cut_id = row[2];
  l.t = row[3] / kFixedPoint;
  for (int d = 0; d < 3; ++d) l.normal[d] = row[4 + d] / kFixedPoint;
  return l;
}

/// The mesh tables of this rank's canonical slabs: they are computed directly from the
/// replicated lattice and copies, so no communication is needed.
struct MeshTables {
  std::vector<double> positions;
  std::vector<std::int64_t> connectivity;
  std::vector<std::int32_t> ijk, material;
  std::vector<double> youngs;
  output::MeshData mesh;
};

void fill_mesh_tables(MPI_Comm comm, const Model& M, MeshTables* t) {
  const auto& L = M.lattice;
  auto& mesh = t->mesh;
  mesh.lattice = L.spec;
  mesh.points = even_slab(comm, M.copies.num_copies);
  mesh.cells = even_slab(comm, L.num_cells());
  t->positions.resize(3 * mesh.points.local_rows);
  for (std::int64_t i = 0; i < mesh.points.local_rows; ++i) {
    const auto& v = M.copies.vertex[mesh.points.row_offset + i];
    for (int d = 0; d < 3; ++d) t->positions[3 * i + d] = L.spec.origin[d] + L.spec.h * v[d];
  }
  t->connectivity.resize(8 * mesh.cells.local_rows);
  t->ijk.resize(3 * mesh.cells.local_rows);
  t->material.resize(mesh.cells.local_rows);
  t->youngs.resize(mesh.cells.local_rows);
  for (std::int64_t i = 0; i < mesh.cells.local_rows; ++i) {
    const auto c = mesh.cells.row_offset + i;
    for (int q = 0; q < 8; ++q)
      t->connectivity[8 * i + q] = M.copies.cell_corners[c][topology::kVtkHexOrder[q]];
    for (int d = 0; d < 3; ++d) t->ijk[3 * i + d] = L.ijk[c][d];
    t->material[i] = L.material[c];
    t->youngs[i] = L.youngs[c];
  }
  mesh.positions = t->positions.data();
  mesh.connectivity = t->connectivity.data();
  mesh.lattice_index = t->ijk.data();
  mesh.material = t->material.data();
  mesh.youngs_modulus = t->youngs.data();
}

output::ResultWriter create_writer(MPI_Comm comm, const Model& M, const deck::Deck& deck,
                                   const std::string& path, const std::string& command_line) {
  MeshTables t;
  fill_mesh_tables(comm, M, &t);
  output::RunInfo run{deck.text, command_line};
  if (deck.discretization.type == deck::Discretization::Type::composite) {
    run.discretization = "composite";
    run.composite_level = deck.discretization.level;
  }
  return output::ResultWriter::create(path, comm, t.mesh, run);
}

}  // namespace

PetscErrorCode compute_stress(const Model& M, bool corotational, Vec u, CellStressFields* out) {
  PetscFunctionBeginUser;
  const auto& D = M.layout;
  const auto& C = M.cells;
  const std::size_t n = D.cells.size();
  out->sigma.resize(6 * n);
  out->energy_density.resize(n);
  Vec ul;
  PetscCall(DMGetLocalVector(M.dm, &ul));
  PetscCall(assembly::global_to_local(M.dm, u, ul));
  const PetscScalar* ua;
  PetscCall(VecGetArrayRead(ul, &ua));
  double x24[24];
  element::corner_positions(C.h, nullptr, x24);
  const double identity[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  std::vector<double> rotations;
  if (corotational) {
    rotations.resize(9 * n);
    assembly::cell_rotations(D, C, ua, rotations.data());
  }
  for (std::size_t e = 0; e < n; ++e) {
    double u24[24];
    element::gather_cell(ua, D.cell_corners[e].data(), u24);
    const double* R = corotational ? &rotations[9 * e] : identity;
    double* sigma = &out->sigma[6 * e];
    element::recover_cell_stress(u24, x24, R, C.h, C.lambda[e], C.mu[e], sigma);
    if (!C.initial_stress.empty())  // sigma0 + sigma(u): the derived fields are of that sum
      for (int i = 0; i < 6; ++i) sigma[i] += C.initial_stress[6 * e + i];
    out->energy_density[e] = element::strain_energy_density(sigma, C.lambda[e], C.mu[e]);
  }
  PetscCall(VecRestoreArrayRead(ul, &ua));
  PetscCall(DMRestoreLocalVector(M.dm, &ul));
  PetscFunctionReturn(0);
}

ResultOutput::ResultOutput(MPI_Comm comm, const Model& model, const deck::Deck& deck,
                           const std::string& path, const std::string& command_line, bool restart)
    : comm_(comm),
      model_(model),
      deck_(deck),
      writer_(restart ? output::ResultWriter::open(path, comm)
                      : create_writer(comm, model, deck, path, command_line)) {}

PetscErrorCode ResultOutput::create(MPI_Comm comm, const Model& model, const deck::Deck& deck,
                                    const std::string& path, const std::string& command_line,
                                    bool restart, std::unique_ptr<ResultOutput>* out) {
  PetscFunctionBeginUser;
  std::unique_ptr<ResultOutput> o(new ResultOutput(comm, model, deck, path, command_line, restart));
  PetscCall(o->create_scatters());
  if (deck.compare)
    o->reference_ = std::make_unique<ReferenceState>(comm, *deck.compare, model.lattice.spec);
  *out = std::move(o);
  PetscFunctionReturn(0);
}

ResultOutput::~ResultOutput() {
  destroy_scatters();
}

PetscErrorCode ResultOutput::create_scatters() {
  PetscFunctionBeginUser;
  const auto& D = model_.layout;
  PetscCall(topology::create_natural_scatter(
      comm_, D.num_global_copies,
      std::vector<std::int32_t>(D.copies.begin(), D.copies.begin() + D.num_owned),
      D.first_owned_block(), 3, &points_));
  const PetscInt n_local = PetscInt(D.cells.size());
  first_local_cell_ = 0;
  PetscCallMPI(MPI_Exscan(&n_local, &first_local_cell_, 1, MPIU_INT, MPI_SUM, comm_));
  if (D.rank == 0) first_local_cell_ = 0;
  PetscFunctionReturn(0);
}

PetscErrorCode ResultOutput::destroy_scatters() {
  PetscFunctionBeginUser;
  PetscCall(destroy_natural_scatter(&points_));
  PetscCall(destroy_natural_scatter(&surface_points_));
  for (auto& [b, s] : cells_) PetscCall(destroy_natural_scatter(&s));
  cells_.clear();
  PetscFunctionReturn(0);
}

PetscErrorCode ResultOutput::topology_changed() {
  PetscFunctionBeginUser;
  PetscCall(destroy_scatters());
  PetscCall(create_scatters());
  mesh_pending_ = true;
  surface_.reset();
  PetscFunctionReturn(0);
}

PetscErrorCode ResultOutput::write_surface(const State& s) {
  PetscFunctionBeginUser;
  const auto& M = model_;
  const auto& D = M.layout;
  if (!hermite_) {
    // The geometry's crossings cost ~30 membership tests per boundary face (seconds for a
    // mesh body): each rank does a share of the cells, and all gather the table.
    int size;
    PetscCallMPI(MPI_Comm_size(comm_, &size));
    const std::int64_t n = M.lattice.num_cells();
    const auto mine = surface::boundary_hermite(M.lattice, deck::membership_ops(deck_),
                                                std::int32_t(n * D.rank / size),
                                                std::int32_t(n * (D.rank + 1) / size));
    hermite_ = std::make_unique<surface::BoundaryHermite>();
    hermite_->faces = allgather(comm_, mine.faces);
  }
  if (!surface_) {
    // Every rank builds the same surface from the replicated lattice (canonical vertex
    // order); each moves the vertices of its own cells and a scatter puts them in order.
    surface_ = std::make_unique<surface::Surface>(
        surface::build_surface(M.lattice, M.copies, hermite_.get()));
    surface_mine_.clear();
    for (std::size_t v = 0; v < surface_->cell.size(); ++v)
      if (M.partition.cell_rank[surface_->cell[v]] == D.rank)
        surface_mine_.push_back(std::int32_t(v));
    const PetscInt mine = PetscInt(surface_mine_.size());
    PetscInt begin = 0;
    PetscCallMPI(MPI_Exscan(&mine, &begin, 1, MPIU_INT, MPI_SUM, comm_));
    if (D.rank == 0) begin = 0;
    PetscCall(destroy_natural_scatter(&surface_points_));
    PetscCall(topology::create_natural_scatter(comm_, PetscInt(surface_->position.size()),
                                               surface_mine_, begin, 3, &surface_points_));
  }
  const auto& S = *surface_;
  // Deformed positions of this rank's vertices: trilinear in the owning cell's corners.
  Vec moved;
  PetscCall(VecCreateMPI(comm_, 3 * PetscInt(surface_mine_.size()), PETSC_DETERMINE, &moved));
  {
    assembly::LocalValues ul;
    PetscCall(ul.get(M.dm, s.u));
    const PetscScalar* u = ul.data();
    PetscScalar* x;
    PetscCall(VecGetArray(moved, &x));
    for (std::size_t i = 0; i < surface_mine_.size(); ++i) {
      const auto v = surface_mine_[i];
      const auto e = std::size_t(std::lower_bound(D.cells.begin(), D.cells.end(), S.cell[v]) -
                                 D.cells.begin());
      const auto& xi = S.local[v];
      for (int d = 0; d < 3; ++d) x[3 * i + d] = S.position[v][d];
      for (int q = 0; q < 8; ++q) {
        const double w = element::trilinear_weight(xi.data(), q);
        for (int d = 0; d < 3; ++d) x[3 * i + d] += w * u[3 * D.cell_corners[e][q] + d];
      }
    }
    PetscCall(VecRestoreArray(moved, &x));
  }
  auto& ns = surface_points_;
  PetscCall(VecScatterBegin(ns.scatter, moved, ns.natural, INSERT_VALUES, SCATTER_FORWARD));
  PetscCall(VecScatterEnd(ns.scatter, moved, ns.natural, INSERT_VALUES, SCATTER_FORWARD));
  PetscCall(VecDestroy(&moved));
  output::SurfaceData data;
  data.vertices = {std::int64_t(S.position.size()), ns.row_begin, ns.rows};
  const PetscScalar* positions;
  PetscCall(VecGetArrayRead(ns.natural, &positions));
  data.positions = positions;
  data.owner_cell = S.cell.data() + ns.row_begin;
  data.faces = even_slab(comm_, std::int64_t(S.triangles.size()));
  std::vector<std::int64_t> triangles(3 * data.faces.local_rows);
  for (std::int64_t f = 0; f < data.faces.local_rows; ++f)
    for (int k = 0; k < 3; ++k) triangles[3 * f + k] = S.triangles[data.faces.row_offset + f][k];
  data.triangles = triangles.data();
  data.cut_id = S.cut_id.data() + data.faces.row_offset;
  writer_.write_surface(s.step, data);
  PetscCall(VecRestoreArrayRead(ns.natural, &positions));
  PetscFunctionReturn(0);
}

PetscErrorCode ResultOutput::cell_scatter(int block, topology::NaturalScatter** scatter) {
  PetscFunctionBeginUser;
  auto it = cells_.find(block);
  if (it == cells_.end()) {
    it = cells_.emplace(block, topology::NaturalScatter{}).first;
    PetscCall(topology::create_natural_scatter(comm_, model_.lattice.num_cells(),
                                               model_.layout.cells, first_local_cell_, block,
                                               &it->second));
  }
  *scatter = &it->second;
  PetscFunctionReturn(0);
}

PetscErrorCode ResultOutput::gather_points(Vec x) {
  PetscFunctionBeginUser;
  PetscCall(VecScatterBegin(points_.scatter, x, points_.natural, INSERT_VALUES, SCATTER_FORWARD));
  PetscCall(VecScatterEnd(points_.scatter, x, points_.natural, INSERT_VALUES, SCATTER_FORWARD));
  PetscFunctionReturn(0);
}

PetscErrorCode ResultOutput::write_point_vector(std::int64_t step, const std::string& name, Vec v,
                                                const std::string& unit) {
  PetscFunctionBeginUser;
  PetscCall(gather_points(v));
  const PetscScalar* a;
  PetscCall(VecGetArrayRead(points_.natural, &a));
  writer_.write_point_field(step, name, 3, points_.row_begin, points_.rows, a, unit);
  PetscCall(VecRestoreArrayRead(points_.natural, &a));
  PetscFunctionReturn(0);
}

PetscErrorCode ResultOutput::write_cell_values(std::int64_t step, const std::string& name,
                                               int block, const std::vector<double>& values,
                                               const std::string& unit) {
  PetscFunctionBeginUser;
  topology::NaturalScatter* s;
  PetscCall(cell_scatter(block, &s));
  Vec local;
  PetscCall(VecCreateMPIWithArray(comm_, block, PetscInt(values.size()), PETSC_DETERMINE,
                                  values.data(), &local));
  PetscCall(VecScatterBegin(s->scatter, local, s->natural, INSERT_VALUES, SCATTER_FORWARD));
  PetscCall(VecScatterEnd(s->scatter, local, s->natural, INSERT_VALUES, SCATTER_FORWARD));
  PetscCall(VecDestroy(&local));
  const PetscScalar* a;
  PetscCall(VecGetArrayRead(s->natural, &a));
  writer_.write_cell_field(step, name, block, s->row_begin, s->rows, a, unit);
  PetscCall(VecRestoreArrayRead(s->natural, &a));
  PetscFunctionReturn(0);
}

PetscErrorCode ResultOutput::write_comparison(std::int64_t step, const CellStressFields& f) {
  PetscFunctionBeginUser;
  const auto& R = reference_->fields(step);
  const auto& L = model_.lattice;
  const auto& D = model_.layout;
  const std::size_t n = D.cells.size();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  std::vector<double> diff(6 * n, nan), norm(n, nan), dvm(n, nan), dsed(n, nan), shield(n, nan);
  // Per material: compared cells, sums of |d sigma|, d von Mises, shielding.
  const std::size_t M = deck_.materials.size();
  std::vector<double> sums(5 * M, 0.0);  // cells, |d sigma|, d von Mises, shielding, W_ref > 0
  for (std::size_t e = 0; e < n; ++e) {
    const auto c = D.cells[e];
    const auto& p = L.ijk[c];
    const std::size_t id =
        std::size_t(p[0]) +
        std::size_t(L.spec.dims[0]) *
            (std::size_t(p[1]) + std::size_t(L.spec.dims[1]) * std::size_t(p[2]));
    const double W0 = R.energy[id];
    if (std::isnan(W0)) continue;  // no material in the reference
    const double* s0 = &R.stress[6 * id];
    const double* s1 = &f.sigma[6 * e];
    double q = 0.0;
    for (int k = 0; k < 6; ++k) {
      diff[6 * e + k] = s1[k] - s0[k];
      q += (k < 3 ? 1.0 : 2.0) * diff[6 * e + k] * diff[6 * e + k];  // tensor norm
    }
    norm[e] = std::sqrt(q);
    dvm[e] = element::von_mises_stress(s1) - element::von_mises_stress(s0);
    dsed[e] = f.energy_density[e] - W0;
    shield[e] = W0 > 0.0 ? (W0 - f.energy_density[e]) / W0 : nan;
    const auto m = std::size_t(L.material[c]);
    sums[5 * m] += 1.0, sums[5 * m + 1] += norm[e], sums[5 * m + 2] += dvm[e];
    if (W0 > 0.0) sums[5 * m + 3] += shield[e], sums[5 * m + 4] += 1.0;
  }
  PetscCall(write_cell_values(step, "stress_difference", 6, diff, "Pa"));
  PetscCall(write_cell_values(step, "stress_difference_norm", 1, norm, "Pa"));
  PetscCall(write_cell_values(step, "von_mises_change", 1, dvm, "Pa"));
  PetscCall(write_cell_values(step, "strain_energy_density_change", 1, dsed, "Pa"));
  PetscCall(write_cell_values(step, "stress_shielding", 1, shield, "1"));
  PetscCallMPI(
      MPI_Allreduce(MPI_IN_PLACE, sums.data(), int(sums.size()), MPI_DOUBLE, MPI_SUM, comm_));
  // Per material with compared cells: printed, and stored in the step as one table row.
  std::vector<double> table;
  std::vector<std::string> names;
  for (std::size_t m = 0; m < M; ++m) {
    const double k = sums[5 * m], loaded = sums[5 * m + 4];
    if (k == 0) continue;
    const double mean_norm = sums[5 * m + 1] / k, mean_dvm = sums[5 * m + 2] / k,
                 mean_shield = loaded > 0 ? sums[5 * m + 3] / loaded : 0.0;
    PetscCall(PetscPrintf(comm_,
                          "compare step %lld (reference step %lld): %s: %lld cells, mean |sigma - "
                          "sigma_ref| %.4g Pa, mean von Mises change %.4g Pa, mean stress "
                          "shielding %.4g (over the %lld cells with W_ref > 0)\n",
                          (long long)step, (long long)R.step, deck_.materials[m].name.c_str(),
                          (long long)k, mean_norm, mean_dvm, mean_shield, (long long)loaded));
    names.push_back(deck_.materials[m].name);
    table.insert(table.end(), {double(R.step), k, mean_norm, mean_dvm, mean_shield, loaded});
  }
  writer_.write_step_table(
      step, "compare_summary", std::int64_t(names.size()), 6, table,
      "reference_step,cells,mean_stress_difference_norm,"
      "mean_von_mises_change,mean_stress_shielding,cells_with_reference_energy",
      names);
  PetscFunctionReturn(0);
}

PetscErrorCode ResultOutput::write_step(const State& s, bool corotational,
                                        const std::vector<double>* composite_element) {
  PetscFunctionBeginUser;
  const auto& o = deck_.output;
  writer_.begin_step(s.step, s.time);
  if (mesh_pending_) {
    // The vertex copies were split by a cut: this step and the later ones use a new mesh.
    MeshTables t;
    fill_mesh_tables(comm_, model_, &t);
    writer_.write_mesh(s.step, t.mesh);
    mesh_pending_ = false;
  }
  if (o.has_field("surface")) PetscCall(write_surface(s));
  if (o.has_field("displacement")) PetscCall(write_point_vector(s.step, "displacement", s.u, "m"));
  if (o.has_field("velocity")) PetscCall(write_point_vector(s.step, "velocity", s.v, "m/s"));
  if (o.has_field("acceleration"))
    PetscCall(write_point_vector(s.step, "acceleration", s.a, "m/s^2"));
  if (o.has_field("composite_element") && composite_element)
    PetscCall(write_cell_values(s.step, "composite_element", 1, *composite_element, "1"));
  const bool any_stress = o.has_field("stress") || o.has_field("von_mises") ||
                          o.has_field("pressure") || o.has_field("principal_stress") ||
                          o.has_field("principal_directions") ||
                          o.has_field("strain_energy_density") || reference_;
  if (any_stress) {
    CellStressFields f;
    {
      EventScope scope(events().stress);
      PetscCall(compute_stress(model_, corotational, s.u, &f));
    }
    if (o.has_field("stress")) PetscCall(write_cell_values(s.step, "stress", 6, f.sigma, "Pa"));
    if (o.has_field("strain_energy_density"))
      PetscCall(write_cell_values(s.step, "strain_energy_density", 1, f.energy_density, "Pa"));
    if (reference_) PetscCall(write_comparison(s.step, f));
    // The derived fields, one dataset at a time through two buffers (value: 1 per cell,
    // direction: 3), each from the tensor. One dataset per principal value and direction
    // (format version 2): scalars to colour by and vectors that ParaView's Glyph takes,
    // where a (n, 3) or (n, 9) table reads as one vector or 9 unnamed components
    // (doc/output-format.md). The eigenproblem is solved once per cell and index i, for
    // the value and the direction together.
    const std::size_t n = f.energy_density.size();
    const double* sigma = f.sigma.data();
    std::vector<double> value(n), direction;
    if (o.has_field("von_mises")) {
      for (std::size_t e = 0; e < n; ++e) value[e] = element::von_mises_stress(&sigma[6 * e]);
      PetscCall(write_cell_values(s.step, "von_mises", 1, value, "Pa"));
    }
    if (o.has_field("pressure")) {
      for (std::size_t e = 0; e < n; ++e) value[e] = element::pressure(&sigma[6 * e]);
      PetscCall(write_cell_values(s.step, "pressure", 1, value, "Pa"));
    }
    const bool values = o.has_field("principal_stress"),
               directions = o.has_field("principal_directions");
    if (directions) direction.resize(3 * n);
    for (int i = 0; i < 3 && (values || directions); ++i) {
      for (std::size_t e = 0; e < n; ++e) {
        const auto c = element::stress_fields(&sigma[6 * e]);
        value[e] = c.principal[i];
        if (directions) std::copy_n(&c.directions[3 * i], 3, &direction[3 * e]);
      }
      const std::string k = std::to_string(i + 1);
      if (values) PetscCall(write_cell_values(s.step, "principal_stress_" + k, 1, value, "Pa"));
      if (directions)
        PetscCall(write_cell_values(s.step, "principal_direction_" + k, 3, direction, "1"));
    }
  }
  writer_.end_step();
  PetscFunctionReturn(0);
}

void ResultOutput::record_solve(std::int64_t step, double time, const solve::SolveRecord& r) {
  output::SolverHistoryRow rec;
  rec.step = step;
  rec.time = time;
  rec.iterations = r.iterations;
  rec.relative_residual = r.residual;
  rec.residual_norm = r.residual_norm;
  rec.setup_seconds = r.setup_seconds;
  rec.solve_seconds = r.solve_seconds;
  rec.converged_reason = r.reason;
  writer_.append_solve(rec);
}

PetscErrorCode ResultOutput::write_checkpoint(const State& s) {
  PetscFunctionBeginUser;
  std::vector<double> fields[3];  // u, v, a
  const Vec x[3] = {s.u, s.v, s.a};
  for (int k = 0; k < 3; ++k) {
    PetscCall(gather_points(x[k]));
    const PetscScalar* p;
    PetscCall(VecGetArrayRead(points_.natural, &p));
    fields[k].assign(p, p + 3 * points_.rows);
    PetscCall(VecRestoreArrayRead(points_.natural, &p));
  }
  // The current topology's point count: after a cut the writer's mesh is the old one
  // until the next output step.
  const output::Slab points{model_.layout.num_global_copies, points_.row_begin, points_.rows};
  // The cut links, so that a restart can rebuild the topology (topology/links).
  const auto& cuts = model_.lattice.cut_links;
  const auto links = even_slab(comm_, std::int64_t(cuts.size()));
  std::vector<std::int32_t> table(kCutLinkColumns * links.local_rows);
  for (std::int64_t i = 0; i < links.local_rows; ++i)
    encode_cut_link(cuts[links.row_offset + i], &table[kCutLinkColumns * i]);
  writer_.write_checkpoint(s.step, s.time, points, fields[0].data(), fields[1].data(),
                           fields[2].data(), links, kCutLinkColumns, table.data());
  PetscFunctionReturn(0);
}

std::vector<lattice::CutLink> ResultOutput::checkpoint_cut_links() {
  const auto info = writer_.checkpoint_info();
  if (!info || info->link_rows == 0) return {};
  if (info->link_cols != kCutLinkColumns)
    throw InputError(path() + ": the checkpoint's topology/links table has " +
                     std::to_string(info->link_cols) + " columns, not the " +
                     std::to_string(kCutLinkColumns) + " of cut links");
  // Every rank needs every cut link (the lattice is replicated): all read all rows.
  std::vector<std::int32_t> table(kCutLinkColumns * info->link_rows);
  writer_.read_checkpoint(0, 0, nullptr, nullptr, nullptr, 0, info->link_rows, table.data());
  std::vector<lattice::CutLink> links(info->link_rows);
  for (std::int64_t i = 0; i < info->link_rows; ++i)
    links[i] = decode_cut_link(&table[kCutLinkColumns * i]);
  return links;
}

PetscErrorCode ResultOutput::read_checkpoint(State* s) {
  PetscFunctionBeginUser;
  const auto header = writer_.checkpoint_info();
  if (!header) throw InputError(path() + ": the file has no checkpoint to restart from");
  if (header->num_points != model_.layout.num_global_copies ||
      writer_.num_cells() != model_.lattice.num_cells())
    throw InputError(path() + ": the checkpoint (" + std::to_string(header->num_points) +
                     " points, " + std::to_string(writer_.num_cells()) +
                     " cells) does not match this deck's model (" +
                     std::to_string(model_.layout.num_global_copies) + " points, " +
                     std::to_string(model_.lattice.num_cells()) + " cells)");
  std::vector<double> fields[3];  // u, v, a
  for (auto& f : fields) f.resize(3 * points_.rows);
  const auto info = writer_.read_checkpoint(points_.row_begin, points_.rows, fields[0].data(),
                                            fields[1].data(), fields[2].data());
  const Vec x[3] = {s->u, s->v, s->a};
  for (int k = 0; k < 3; ++k) {
    PetscScalar* p;
    PetscCall(VecGetArray(points_.natural, &p));
    std::copy(fields[k].begin(), fields[k].end(), p);
    PetscCall(VecRestoreArray(points_.natural, &p));
    PetscCall(
        VecScatterBegin(points_.scatter, points_.natural, x[k], INSERT_VALUES, SCATTER_REVERSE));
    PetscCall(
        VecScatterEnd(points_.scatter, points_.natural, x[k], INSERT_VALUES, SCATTER_REVERSE));
  }
  s->step = info.step;
  s->time = info.time;
  writer_.truncate_steps_after(info.step);
  PetscFunctionReturn(0);
}

}  // namespace hexcut::analysis
