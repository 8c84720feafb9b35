// 2-rank tests: every rank writes its slab of a known table (values = function of the
// global row); the tables are read back on 2 ranks (other partitions) and on 1 rank.
#include <gtest/gtest.h>
#include <mpi.h>
#include <unistd.h>

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "cut_fixture.hpp"
#include "output/h5_file.hpp"
#include "output/result_writer.hpp"

namespace fs = std::filesystem;
using namespace hexcut::output;
using namespace hexcut::output::testing;

namespace {

int rank() {
  int r = 0;
  MPI_Comm_rank(MPI_COMM_WORLD, &r);
  return r;
}
int size() {
  int s = 1;
  MPI_Comm_size(MPI_COMM_WORLD, &s);
  return s;
}

/// A fresh directory, the same on every rank (named after rank 0's pid).
fs::path scratch_dir(const std::string& name) {
  long pid = ::getpid();
  MPI_Bcast(&pid, 1, MPI_LONG, 0, MPI_COMM_WORLD);
  fs::path dir = fs::temp_directory_path() / ("hexcut_output_mpi_" + std::to_string(pid)) / name;
  if (rank() == 0) {
    fs::remove_all(dir);
    fs::create_directories(dir);
  }
  MPI_Barrier(MPI_COMM_WORLD);
  return dir;
}

/// Removes the scratch directory (rank 0) after the last test.
class RemoveScratch : public ::testing::Environment {
 public:
  void TearDown() override {
    long pid = ::getpid();
    MPI_Bcast(&pid, 1, MPI_LONG, 0, MPI_COMM_WORLD);
    MPI_Barrier(MPI_COMM_WORLD);
    if (rank() == 0)
      fs::remove_all(fs::temp_directory_path() / ("hexcut_output_mpi_" + std::to_string(pid)));
  }
};
[[maybe_unused]] ::testing::Environment* const kRemoveScratch =
    ::testing::AddGlobalTestEnvironment(new RemoveScratch);

/// value of (row, col) in table `kind`.
double value(int kind, std::int64_t row, std::int64_t col) {
  return 1000.0 * kind + 10.0 * static_cast<double>(row) + static_cast<double>(col) + 0.5;
}

/// The rows [offset, offset+count) of table `kind`, converted to T.
template <class T>
std::vector<T> rows_of(int kind, std::int64_t offset, std::int64_t count, std::int64_t cols) {
  std::vector<T> t;
  const std::int64_t c = cols == 0 ? 1 : cols;
  for (std::int64_t r = offset; r < offset + count; ++r)
    for (std::int64_t j = 0; j < c; ++j) {
      double v = value(kind, r, j);
      t.push_back(static_cast<T>(std::is_integral_v<T> ? static_cast<std::int64_t>(v) % 251 : v));
    }
  return t;
}

/// Uneven partition: rank 0 gets `first` rows, the others share the rest.
Slab split(std::int64_t global, std::int64_t first) {
  Slab s{global, 0, 0};
  if (rank() == 0) {
    s.local_rows = first;
  } else {
    std::int64_t rest = global - first, n = size() - 1, r = rank() - 1;
    s.row_offset = first + rest * r / n;
    s.local_rows = first + rest * (r + 1) / n - s.row_offset;
  }
  return s;
}

template <class T>
void write_and_check(const fs::path& file, const std::string& path, int kind, std::int64_t rows,
                     std::int64_t cols) {
  {
    H5File f = H5File::open(file.string(), MPI_COMM_WORLD);
    Slab w = split(rows, rows / 3);
    auto mine = rows_of<T>(kind, w.row_offset, w.local_rows, cols);
    f.write_rows(path, rows, cols, w.row_offset, w.local_rows, mine.data());
    f.close();
  }
  {  // 2 ranks, another partition (rank 0 reads nothing).
    H5File f = H5File::open(file.string(), MPI_COMM_WORLD, H5File::Access::kReadOnly);
    Slab r = split(rows, 0);
    std::vector<T> back(static_cast<std::size_t>(r.local_rows * (cols == 0 ? 1 : cols)));
    f.read_rows(path, rows, cols, r.row_offset, r.local_rows, back.data());
    EXPECT_EQ(back, rows_of<T>(kind, r.row_offset, r.local_rows, cols)) << path;
    f.close();
  }
  if (rank() == 0) {  // 1 rank reads it all
    H5File f = H5File::open(file.string(), MPI_COMM_SELF, H5File::Access::kReadOnly);
    std::vector<T> back(static_cast<std::size_t>(rows * (cols == 0 ? 1 : cols)));
    f.read_rows(path, rows, cols, 0, rows, back.data());
    EXPECT_EQ(back, rows_of<T>(kind, 0, rows, cols)) << path;
    std::vector<std::int64_t> want =
        cols == 0 ? std::vector<std::int64_t>{rows} : std::vector<std::int64_t>{rows, cols};
    EXPECT_EQ(f.dims(path), want) << path;
  }
  MPI_Barrier(MPI_COMM_WORLD);
}

}  // namespace

TEST(OutputMpi, SlabsOfEveryTypeRoundTripOnOneAndTwoRanks) {
  ASSERT_GE(size(), 2);
  fs::path file = scratch_dir("slabs") / "t.h5";
  H5File::create(file.string(), MPI_COMM_WORLD).close();
  write_and_check<double>(file, "/mesh/points", 1, 37, 3);
  write_and_check<std::int64_t>(file, "/mesh/cells", 2, 11, 8);
  write_and_check<std::int32_t>(file, "/mesh/cell_material", 3, 11, 0);
  write_and_check<float>(file, "/f/float", 4, 5, 2);
  write_and_check<std::uint8_t>(file, "/f/uint8", 5, 7, 1);
  write_and_check<double>(file, "/mesh/points", 6, 37, 3);  // overwrite in place
  write_and_check<double>(file, "/one_row", 7, 1, 6);       // rank 1 has no rows
}

TEST(OutputMpi, ResultWriterFieldsAndCheckpointInParallel) {
  fs::path dir = scratch_dir("writer");
  const std::string path = (dir / "run.h5").string();
  const std::int64_t np = 27, nc = 8;
  const Slab P = split(np, 10), C = split(nc, 5);
  auto pts = rows_of<double>(1, P.row_offset, P.local_rows, 3);
  auto cells = rows_of<std::int64_t>(2, C.row_offset, C.local_rows, 8);
  auto ijk = rows_of<std::int32_t>(3, C.row_offset, C.local_rows, 3);
  auto mat = rows_of<std::int32_t>(4, C.row_offset, C.local_rows, 0);
  auto ym = rows_of<double>(5, C.row_offset, C.local_rows, 0);
  MeshData mesh;
  mesh.lattice.dims = {2, 2, 2};
  mesh.lattice.h = 0.25;
  mesh.points = P;
  mesh.cells = C;
  mesh.positions = pts.data();
  mesh.connectivity = cells.data();
  mesh.lattice_index = ijk.data();
  mesh.material = mat.data();
  mesh.youngs_modulus = ym.data();
  ResultWriter w = ResultWriter::create(path, MPI_COMM_WORLD, mesh, {"deck\n", "hexcut deck"});
  EXPECT_FALSE(fs::exists(path + ".tmp"));
  EXPECT_TRUE(fs::exists(dir / "run.xmf"));

  for (int step = 0; step < 3; ++step) {
    w.begin_step(step, 0.1 * step);
    auto u = rows_of<double>(10 + step, P.row_offset, P.local_rows, 3);
    auto s = rows_of<double>(20 + step, C.row_offset, C.local_rows, 6);
    auto vm = rows_of<double>(30 + step, C.row_offset, C.local_rows, 1);
    w.write_point_field(step, "displacement", 3, P.row_offset, P.local_rows, u.data(), "m");
    w.write_cell_field(step, "stress", 6, C.row_offset, C.local_rows, s.data(), "Pa");
    w.write_cell_field(step, "von_mises", 1, C.row_offset, C.local_rows, vm.data(), "Pa");
    w.end_step();
    auto v = rows_of<double>(40 + step, P.row_offset, P.local_rows, 3);
    auto links = rows_of<std::int32_t>(50 + step, C.row_offset, C.local_rows, 0);
    w.write_checkpoint(step, 0.1 * step, P.row_offset, P.local_rows, u.data(), v.data(), u.data(),
                       C, 0, links.data());
  }
  EXPECT_EQ(w.last_complete_step(), 2);

  {  // read the mesh and fields back on 2 ranks with another partition
    H5File f = H5File::open(path, MPI_COMM_WORLD, H5File::Access::kReadOnly);
    const Slab R = split(np, 20), RC = split(nc, 1);
    std::vector<double> back(static_cast<std::size_t>(R.local_rows * 3));
    f.read_rows("/mesh/points", np, 3, R.row_offset, R.local_rows, back.data());
    EXPECT_EQ(back, rows_of<double>(1, R.row_offset, R.local_rows, 3));
    f.read_rows("/steps/000002/displacement", np, 3, R.row_offset, R.local_rows, back.data());
    EXPECT_EQ(back, rows_of<double>(12, R.row_offset, R.local_rows, 3));
    std::vector<std::int64_t> cb(static_cast<std::size_t>(RC.local_rows * 8));
    f.read_rows("/mesh/cells", nc, 8, RC.row_offset, RC.local_rows, cb.data());
    EXPECT_EQ(cb, rows_of<std::int64_t>(2, RC.row_offset, RC.local_rows, 8));
    std::vector<double> vm(static_cast<std::size_t>(RC.local_rows));
    f.read_rows("/steps/000001/von_mises", nc, 0, RC.row_offset, RC.local_rows, vm.data());
    EXPECT_EQ(vm, rows_of<double>(31, RC.row_offset, RC.local_rows, 0));
    EXPECT_EQ(f.read_attribute_doubles("/mesh", "lattice_origin"), (std::vector<double>{0, 0, 0}));
    EXPECT_EQ(f.read_attribute_int64s("/mesh", "lattice_dims"),
              (std::vector<std::int64_t>{2, 2, 2}));
    EXPECT_EQ(f.read_attribute_double("/mesh", "lattice_h"), 0.25);
    EXPECT_EQ(f.read_string_dataset("/input/command_line"), "hexcut deck");
    f.close();
  }
  if (rank() == 0) {  // and on 1 rank
    H5File f = H5File::open(path, MPI_COMM_SELF, H5File::Access::kReadOnly);
    std::vector<double> s(static_cast<std::size_t>(nc * 6));
    f.read_rows("/steps/000000/stress", nc, 6, 0, nc, s.data());
    EXPECT_EQ(s, rows_of<double>(20, 0, nc, 6));
    EXPECT_EQ(f.list("/steps"), (std::vector<std::string>{"000000", "000001", "000002"}));
  }
  MPI_Barrier(MPI_COMM_WORLD);

  // Checkpoint read back with another partition.
  const Slab R = split(np, 3), RC = split(nc, 8);
  std::vector<double> u(static_cast<std::size_t>(R.local_rows * 3)), v(u.size()), a(u.size());
  std::vector<std::int32_t> links(static_cast<std::size_t>(RC.local_rows));
  CheckpointInfo info = w.read_checkpoint(R.row_offset, R.local_rows, u.data(), v.data(), a.data(),
                                          RC.row_offset, RC.local_rows, links.data());
  EXPECT_EQ(info.step, 2);
  EXPECT_DOUBLE_EQ(info.time, 0.2);
  EXPECT_EQ(info.link_rows, nc);
  EXPECT_EQ(u, rows_of<double>(12, R.row_offset, R.local_rows, 3));
  EXPECT_EQ(v, rows_of<double>(42, R.row_offset, R.local_rows, 3));
  EXPECT_EQ(a, u);
  EXPECT_EQ(links, rows_of<std::int32_t>(52, RC.row_offset, RC.local_rows, 0));

  // Restart from step 0: later steps disappear from the file and the XDMF.
  ResultWriter restarted = ResultWriter::open(path, MPI_COMM_WORLD);
  EXPECT_EQ(restarted.num_points(), np);
  EXPECT_EQ(restarted.last_complete_step(), 2);
  restarted.truncate_steps_after(0);
  EXPECT_EQ(restarted.last_complete_step(), 0);
  if (rank() == 0) {
    H5File f = H5File::open(path, MPI_COMM_SELF, H5File::Access::kReadOnly);
    EXPECT_EQ(f.list("/steps"), (std::vector<std::string>{"000000"}));
    EXPECT_EQ(f.read_attribute_int64("/steps", "last_complete_step"), 0);
  }
  MPI_Barrier(MPI_COMM_WORLD);
}

// Step 2 splits vertex copies (a new mesh with more points); surfaces on steps 1 and 3;
// every table written from uneven slabs (rank 0 owns few or no rows) and read back with
// other partitions; restart on 2 ranks.
// A result name the XDMF index cannot refer to is refused on every rank, before any
// collective I/O (no rank is left waiting), and nothing is created.
TEST(OutputMpi, NamesTheIndexCannotReferToAreRefusedOnEveryRank) {
  fs::path dir = scratch_dir("names");
  hexcut::LatticeSpec lattice;
  lattice.h = 0.5;
  lattice.dims = {4, 2, 1};
  const FullMesh mesh = lattice_mesh(lattice);
  MeshSlices m(mesh, split(30, 7), split(8, 3));
  const std::string path = (dir / "job_12:30.h5").string();
  EXPECT_THROW(ResultWriter::create(path, MPI_COMM_WORLD, m.data, {"", ""}), std::invalid_argument);
  MPI_Barrier(MPI_COMM_WORLD);
  EXPECT_FALSE(fs::exists(path) || fs::exists(path + ".tmp"));
}

TEST(OutputMpi, MeshChangesAndSurfacesInParallel) {
  ASSERT_GE(size(), 2);
  fs::path dir = scratch_dir("cuts");
  const std::string path = (dir / "run.h5").string();
  hexcut::LatticeSpec lattice;
  lattice.h = 0.5;
  lattice.dims = {4, 2, 1};
  const FullMesh before = lattice_mesh(lattice), after = lattice_mesh(lattice, 3);
  ASSERT_EQ(before.num_points, 30);
  ASSERT_EQ(after.num_points, 36);
  const Slab P0 = split(30, 7), P1 = split(36, 0), C = split(8, 3);
  MeshSlices m0(before, P0, C), m1(after, P1, C);
  ResultWriter w = ResultWriter::create(path, MPI_COMM_WORLD, m0.data, {"deck\n", "hexcut"});

  const FullSurface whole = box_surface(lattice, {Box{0, 4}}, {0.0, 0.0, 0.125});
  const FullSurface halves =
      box_surface(lattice, {Box{0, 3, 0, 1}, Box{3, 4, 1, 0}}, {0.0, 0.0, 0.25});
  SurfaceSlices s1(whole, split(8, 8), split(12, 5));  // rank 1 has no vertex rows
  SurfaceSlices s3(halves, split(16, 3), split(24, 0));

  auto field = [](int kind, const Slab& s) {
    return rows_of<double>(kind, s.row_offset, s.local_rows, 3);
  };
  w.begin_step(1, 0.25);
  auto u1 = field(11, P0);
  w.write_point_field(1, "displacement", 3, P0.row_offset, P0.local_rows, u1.data(), "m");
  w.write_surface(1, s1.data);
  w.end_step();

  w.begin_step(2, 0.5);
  w.write_mesh(2, m1.data);
  EXPECT_EQ(w.num_points(), 36);
  auto u2 = field(12, P1);
  w.write_point_field(2, "displacement", 3, P1.row_offset, P1.local_rows, u2.data(), "m");
  w.write_checkpoint(2, 0.5, P1.row_offset, P1.local_rows, u2.data(), u2.data(), u2.data());
  w.end_step();

  w.begin_step(3, 0.75);
  auto u3 = field(13, P1);
  w.write_point_field(3, "displacement", 3, P1.row_offset, P1.local_rows, u3.data(), "m");
  w.write_surface(3, s3.data);
  w.end_step();

  {  // read back on 2 ranks with other partitions
    H5File f = H5File::open(path, MPI_COMM_WORLD, H5File::Access::kReadOnly);
    EXPECT_EQ(f.read_attribute_string("/steps/000003", "mesh"), "/steps/000002/mesh");
    const Slab R = split(36, 30), RC = split(8, 0);
    std::vector<double> pts(static_cast<std::size_t>(R.local_rows * 3));
    f.read_rows("/steps/000002/mesh/points", 36, 3, R.row_offset, R.local_rows, pts.data());
    EXPECT_EQ(pts, rows(after.points, R, 3));
    std::vector<std::int64_t> cells(static_cast<std::size_t>(RC.local_rows * 8));
    f.read_rows("/steps/000002/mesh/cells", 8, 8, RC.row_offset, RC.local_rows, cells.data());
    EXPECT_EQ(cells, rows(after.cells, RC, 8));
    f.read_rows("/steps/000003/displacement", 36, 3, R.row_offset, R.local_rows, pts.data());
    EXPECT_EQ(pts, rows_of<double>(13, R.row_offset, R.local_rows, 3));
    const Slab RT = split(24, 20), RV = split(16, 1);
    std::vector<std::int64_t> tris(static_cast<std::size_t>(RT.local_rows * 3));
    f.read_rows("/steps/000003/surface/triangles", 24, 3, RT.row_offset, RT.local_rows,
                tris.data());
    EXPECT_EQ(tris, rows(halves.triangles, RT, 3));
    std::vector<std::int32_t> cut(static_cast<std::size_t>(RT.local_rows));
    f.read_rows("/steps/000003/surface/cut_id", 24, 0, RT.row_offset, RT.local_rows, cut.data());
    EXPECT_EQ(cut, rows(halves.cut_id, RT, 1));
    std::vector<double> sp(static_cast<std::size_t>(RV.local_rows * 3));
    f.read_rows("/steps/000003/surface/points", 16, 3, RV.row_offset, RV.local_rows, sp.data());
    EXPECT_EQ(sp, rows(halves.positions, RV, 3));
    std::vector<std::int32_t> owner(static_cast<std::size_t>(RV.local_rows));
    f.read_rows("/steps/000003/surface/owner_cell", 16, 0, RV.row_offset, RV.local_rows,
                owner.data());
    EXPECT_EQ(owner, rows(halves.owner_cell, RV, 1));
    f.close();
  }
  if (rank() == 0) {  // and on 1 rank
    H5File f = H5File::open(path, MPI_COMM_SELF, H5File::Access::kReadOnly);
    std::vector<double> sp(8 * 3);
    f.read_rows("/steps/000001/surface/points", 8, 3, 0, 8, sp.data());
    EXPECT_EQ(sp, whole.positions);
    EXPECT_EQ(f.dims("/mesh/points"), (std::vector<std::int64_t>{30, 3}));
    EXPECT_FALSE(f.exists("/steps/000002/surface"));
  }
  MPI_Barrier(MPI_COMM_WORLD);

  // Restart on 2 ranks: the new point count, its checkpoint, then back to the original.
  ResultWriter restarted = ResultWriter::open(path, MPI_COMM_WORLD);
  EXPECT_EQ(restarted.num_points(), 36);
  EXPECT_EQ(restarted.mesh_path(), "/steps/000002/mesh");
  const Slab R = split(36, 36);  // rank 0 reads everything
  std::vector<double> u(static_cast<std::size_t>(R.local_rows * 3)), v(u.size()), a(u.size());
  CheckpointInfo info =
      restarted.read_checkpoint(R.row_offset, R.local_rows, u.data(), v.data(), a.data());
  EXPECT_EQ(info.num_points, 36);
  EXPECT_EQ(u, rows_of<double>(12, R.row_offset, R.local_rows, 3));
  restarted.truncate_steps_after(1);
  EXPECT_EQ(restarted.num_points(), 30);
  EXPECT_EQ(restarted.mesh_path(), "/mesh");
  if (rank() == 0) {
    H5File f = H5File::open(path, MPI_COMM_SELF, H5File::Access::kReadOnly);
    EXPECT_EQ(f.list("/steps"), (std::vector<std::string>{"000001"}));
  }
  MPI_Barrier(MPI_COMM_WORLD);
}
