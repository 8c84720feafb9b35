// Writes a small result file with known values, in parallel:
//   output_write_result_file FILE.h5 [--steps N] [--kill-after-step K] [--kill-during-step K]
//   output_write_result_file FILE.h5 --cuts [--reopen-truncate K]
// Lattice 3x2x2 cells (h = 0.5, origin (1,2,3)), 36 points, 12 cells. Step s has time
// 0.25*s; every field value is value(kind, s, row, col) below, except the pressure,
// -tr(stress)/3 (check_result_file.py repeats the formulas). With --kill-after-step K,
// rank 0 SIGKILLs itself right after step K closed;
// with --kill-during-step K, after the first field of step K (used to probe the window).
// With --cuts: steps 1, 2, 3 on the same lattice; step 2 splits the vertex copies of the
// plane i = 2 (a cut between the cells i = 1 and i = 2: write_mesh with 45 points), and
// steps 1 and 3 carry a surface (the body's box, then the two boxes the cut leaves, whose
// faces on the cut have cut_id 1), moved by surface_offset(step). --reopen-truncate K then
// re-opens the file (restart), prints its mesh, and truncates it after step K.
#include <mpi.h>

#include <array>
#include <csignal>
#include <cstdio>
#include <exception>
#include <functional>
#include <string>
#include <vector>

#include "cut_fixture.hpp"
#include "output/result_writer.hpp"

using hexcut::output::MeshData;
using hexcut::output::ResultWriter;
using hexcut::output::RunInfo;
using hexcut::output::Slab;
using hexcut::output::SolverHistoryRow;

namespace {

double value(int kind, std::int64_t step, std::int64_t row, int col) {
  return 1e6 * kind + 1000.0 * static_cast<double>(step) + 10.0 * static_cast<double>(row) + col +
         0.25;
}

Slab slab_of(std::int64_t global_rows, int rank, int size) {
  Slab s;
  s.global_rows = global_rows;
  s.row_offset = global_rows * rank / size;
  s.local_rows = global_rows * (rank + 1) / size - s.row_offset;
  return s;
}

std::vector<double> table(int kind, std::int64_t step, const Slab& s, int cols) {
  std::vector<double> t;
  for (std::int64_t r = s.row_offset; r < s.row_offset + s.local_rows; ++r)
    for (int c = 0; c < cols; ++c) t.push_back(value(kind, step, r, c));
  return t;
}

std::array<double, 3> surface_offset(int step) {
  return {0.001 * step, 0.002 * step, 0.003 * step};
}

/// The fields and checkpoint of step s (time s/4). `after_first_field` runs between the
/// first and the second field (the killed-writer case kills the process there).
void write_fields(ResultWriter& writer, int s, const Slab& P, const Slab& C,
                  const std::function<void()>& after_first_field = {}) {
  auto u = table(1, s, P, 3), v = table(2, s, P, 3), a = table(3, s, P, 3);
  writer.write_point_field(s, "displacement", 3, P.row_offset, P.local_rows, u.data(), "m");
  if (after_first_field) after_first_field();
  writer.write_point_field(s, "velocity", 3, P.row_offset, P.local_rows, v.data(), "m/s");
  writer.write_point_field(s, "acceleration", 3, P.row_offset, P.local_rows, a.data(), "m/s^2");
  // The stress in VTK's order xx, yy, zz, xy, yz, xz; the pressure is -tr/3 of it, so
  // that trace + 3p = 0 can be checked through every reader.
  auto stress = table(4, s, C, 6), vm = table(5, s, C, 1), pr = table(6, s, C, 1),
       ps = table(7, s, C, 3), pd = table(8, s, C, 9), odd = table(9, s, C, 1);
  for (std::int64_t r = 0; r < C.local_rows; ++r)
    pr[r] = -(stress[6 * r] + stress[6 * r + 1] + stress[6 * r + 2]) / 3.0;
  writer.write_cell_field(s, "stress", 6, C.row_offset, C.local_rows, stress.data(), "Pa");
  writer.write_cell_field(s, "von_mises", 1, C.row_offset, C.local_rows, vm.data(), "Pa");
  writer.write_cell_field(s, "pressure", 1, C.row_offset, C.local_rows, pr.data(), "Pa");
  // principal_stress_k = column k-1 of kind 7, principal_direction_k = columns 3(k-1)..
  // of kind 8, as hexcut writes them (format version 2).
  for (int k = 0; k < 3; ++k) {
    std::vector<double> value, direction;
    for (std::int64_t r = 0; r < C.local_rows; ++r) {
      value.push_back(ps[3 * r + k]);
      for (int d = 0; d < 3; ++d) direction.push_back(pd[9 * r + 3 * k + d]);
    }
    const std::string n = std::to_string(k + 1);
    writer.write_cell_field(s, "principal_stress_" + n, 1, C.row_offset, C.local_rows, value.data(),
                            "Pa");
    writer.write_cell_field(s, "principal_direction_" + n, 3, C.row_offset, C.local_rows,
                            direction.data());
  }
  // A name that XML must escape (the index carries it as an attribute name and a path).
  writer.write_cell_field(s, "energy & <odd> \"name\"", 1, C.row_offset, C.local_rows, odd.data(),
                          "J");
  std::vector<std::int32_t> links;
  for (std::int64_t r = C.row_offset; r < C.row_offset + C.local_rows; ++r)
    links.push_back(static_cast<std::int32_t>(100 * s + r));
  // Uses the current mesh's point count (45 rows from step 2 on in the cut file). The
  // checkpoint of step s goes inside the open step, into the same open file.
  writer.write_checkpoint(s, 0.25 * s, P.row_offset, P.local_rows, u.data(), v.data(), a.data(), C,
                          0, links.data());
}

SolverHistoryRow solve_record(int s) {
  SolverHistoryRow rec;
  rec.step = s;
  rec.time = 0.25 * s;
  rec.iterations = 10 + s;
  rec.residual_norm = 1e-9 * (s + 1);
  rec.relative_residual = 1e-12 * (s + 1);
  rec.setup_seconds = 0.5;
  rec.solve_seconds = 1.5;
  rec.converged_reason = 2;
  return rec;
}

int run_cuts(const std::string& path, int truncate_after, const RunInfo& info) {
  namespace t = hexcut::output::testing;
  int rank = 0, size = 1;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  MPI_Comm_size(MPI_COMM_WORLD, &size);
  hexcut::LatticeSpec lattice;
  lattice.origin = {1.0, 2.0, 3.0};
  lattice.h = 0.5;
  lattice.dims = {3, 2, 2};
  const t::FullMesh before = t::lattice_mesh(lattice), after = t::lattice_mesh(lattice, 2);
  const Slab C = t::even_slab(before.num_cells, rank, size);
  t::MeshSlices m0(before, t::even_slab(before.num_points, rank, size), C);
  t::MeshSlices m1(after, t::even_slab(after.num_points, rank, size), C);
  ResultWriter writer = ResultWriter::create(path, MPI_COMM_WORLD, m0.data, info);
  for (int s = 1; s <= 3; ++s) {
    writer.append_solve(solve_record(s));
    writer.begin_step(s, 0.25 * s);
    if (s == 2) writer.write_mesh(s, m1.data);  // before the step's fields
    const Slab P = t::even_slab(writer.num_points(), rank, size);
    write_fields(writer, s, P, C);
    if (s != 2) {
      const t::FullSurface surface =
          s == 1 ? t::box_surface(lattice, {t::Box{0, 3}}, surface_offset(s))
                 : t::box_surface(lattice, {t::Box{0, 2, 0, 1}, t::Box{2, 3, 1, 0}},
                                  surface_offset(s));
      // Uneven on purpose: rank 0 holds no vertex rows, the last rank all triangles.
      Slab v{surface.num_vertices, 0, 0}, f{surface.num_triangles, 0, 0};
      if (rank == size - 1) f.local_rows = surface.num_triangles;
      if (size == 1) {
        v.local_rows = surface.num_vertices;
      } else if (rank > 0) {
        v = t::even_slab(surface.num_vertices, rank - 1, size - 1);
      }
      t::SurfaceSlices slices(surface, v, f);
      writer.write_surface(s, slices.data);
    }
    writer.end_step();
  }
  if (truncate_after >= 0) {
    ResultWriter reopened = ResultWriter::open(path, MPI_COMM_WORLD);
    if (rank == 0)
      std::printf("reopened: num_points=%lld num_cells=%lld mesh=%s\n",
                  static_cast<long long>(reopened.num_points()),
                  static_cast<long long>(reopened.num_cells()), reopened.mesh_path().c_str());
    reopened.truncate_steps_after(truncate_after);
    if (rank == 0)
      std::printf("truncated after %d: num_points=%lld num_cells=%lld mesh=%s\n", truncate_after,
                  static_cast<long long>(reopened.num_points()),
                  static_cast<long long>(reopened.num_cells()), reopened.mesh_path().c_str());
  }
  return 0;
}

int run(int argc, char** argv) {
  int rank = 0, size = 1;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  MPI_Comm_size(MPI_COMM_WORLD, &size);
  if (argc < 2) {
    std::fprintf(stderr, "usage: %s FILE.h5 [--steps N] [--kill-after-step K]\n", argv[0]);
    return 2;
  }
  const std::string path = argv[1];
  int steps = 2, kill_after = -1, kill_during = -1, truncate_after = -1;
  bool cuts = false;
  for (int i = 2; i < argc; ++i) {
    std::string flag = argv[i];
    if (flag == "--cuts") {
      cuts = true;
      continue;
    }
    if (i + 1 >= argc) break;
    if (flag == "--steps") steps = std::stoi(argv[i + 1]);
    if (flag == "--kill-after-step") kill_after = std::stoi(argv[i + 1]);
    if (flag == "--kill-during-step") kill_during = std::stoi(argv[i + 1]);
    if (flag == "--reopen-truncate") truncate_after = std::stoi(argv[i + 1]);
    ++i;
  }

  MeshData mesh;
  mesh.lattice.origin = {1.0, 2.0, 3.0};
  mesh.lattice.h = 0.5;
  mesh.lattice.dims = {3, 2, 2};
  const int nx = 3, ny = 2, nz = 2;
  const auto vid = [&](int i, int j, int k) {
    return std::int64_t(i) + (nx + 1) * (std::int64_t(j) + (ny + 1) * std::int64_t(k));
  };
  mesh.points = slab_of((nx + 1) * (ny + 1) * (nz + 1), rank, size);
  mesh.cells = slab_of(nx * ny * nz, rank, size);
  std::vector<double> positions;
  for (std::int64_t p = mesh.points.row_offset; p < mesh.points.row_offset + mesh.points.local_rows;
       ++p) {
    const int i = int(p % (nx + 1)), j = int(p / (nx + 1) % (ny + 1)),
              k = int(p / ((nx + 1) * (ny + 1)));
    auto x = mesh.lattice.vertex_position(i, j, k);
    positions.insert(positions.end(), {x.x(), x.y(), x.z()});
  }
  std::vector<std::int64_t> cells;
  std::vector<std::int32_t> ijk, material;
  std::vector<double> youngs;
  for (std::int64_t c = mesh.cells.row_offset; c < mesh.cells.row_offset + mesh.cells.local_rows;
       ++c) {
    const int i = int(c % nx), j = int(c / nx % ny), k = int(c / (nx * ny));
    cells.insert(cells.end(), {vid(i, j, k), vid(i + 1, j, k), vid(i + 1, j + 1, k),
                               vid(i, j + 1, k), vid(i, j, k + 1), vid(i + 1, j, k + 1),
                               vid(i + 1, j + 1, k + 1), vid(i, j + 1, k + 1)});
    ijk.insert(ijk.end(), {i, j, k});
    material.push_back(static_cast<std::int32_t>(c % 2));
    youngs.push_back(c % 2 == 0 ? 210e9 : 70e9);
  }
  mesh.positions = positions.data();
  mesh.connectivity = cells.data();
  mesh.lattice_index = ijk.data();
  mesh.material = material.data();
  mesh.youngs_modulus = youngs.data();

  RunInfo info;
  info.deck = "# test deck\nsolver:\n  type: cg   # trailing spaces kept  \nunit: \"\xC2\xB5m\"\n";
  for (int i = 0; i < argc; ++i) info.command_line += (i ? " " : "") + std::string(argv[i]);
  if (cuts) return run_cuts(path, truncate_after, info);

  ResultWriter writer = ResultWriter::create(path, MPI_COMM_WORLD, mesh, info);
  const Slab& P = mesh.points;
  const Slab& C = mesh.cells;
  for (int s = 0; s < steps; ++s) {
    const double time = 0.25 * s;
    writer.append_solve(solve_record(s));

    writer.begin_step(s, time);
    write_fields(writer, s, P, C, [&] {
      if (s == kill_during) {  // inside an open step, after its first field
        MPI_Barrier(MPI_COMM_WORLD);
        if (rank == 0) std::raise(SIGKILL);
      }
    });
    writer.end_step();
    if (s == kill_after) {
      MPI_Barrier(MPI_COMM_WORLD);
      if (rank == 0) {
        std::printf("killing myself after step %d\n", s);
        std::fflush(stdout);
        std::raise(SIGKILL);
      }
    }
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  MPI_Init(&argc, &argv);
  int status = 1;
  try {
    status = run(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "output_write_result_file: %s\n", e.what());
    MPI_Abort(MPI_COMM_WORLD, 1);
  }
  MPI_Finalize();
  return status;
}
