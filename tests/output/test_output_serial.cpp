// Serial (1 rank) tests of the HDF5 layer and the ResultWriter.
#include <gtest/gtest.h>
#include <mpi.h>
#include <unistd.h>

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "cut_fixture.hpp"
#include "output/h5_file.hpp"
#include "output/result_writer.hpp"

namespace fs = std::filesystem;
using namespace hexcut::output;
using namespace hexcut::output::testing;

namespace {

fs::path scratch_dir(const std::string& name) {
  fs::path dir =
      fs::temp_directory_path() / ("hexcut_output_serial_" + std::to_string(::getpid())) / name;
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

/// Removes this process's scratch directory after the last test.
class RemoveScratch : public ::testing::Environment {
 public:
  void TearDown() override {
    fs::remove_all(fs::temp_directory_path() /
                   ("hexcut_output_serial_" + std::to_string(::getpid())));
  }
};
[[maybe_unused]] ::testing::Environment* const kRemoveScratch =
    ::testing::AddGlobalTestEnvironment(new RemoveScratch);

template <class T>
std::vector<T> table(std::int64_t rows, std::int64_t cols, std::int64_t first_row = 0) {
  std::vector<T> t;
  const std::int64_t c = cols == 0 ? 1 : cols;
  for (std::int64_t r = first_row; r < first_row + rows; ++r)
    for (std::int64_t j = 0; j < c; ++j) t.push_back(static_cast<T>((r * 7 + j) % 100));
  return t;
}

template <class T>
void round_trip(H5File& f, const std::string& path, std::int64_t rows, std::int64_t cols) {
  auto data = table<T>(rows, cols);
  f.write_rows(path, rows, cols, 0, rows, data.data());
  std::vector<T> back(data.size());
  f.read_rows(path, rows, cols, 0, rows, back.data());
  EXPECT_EQ(back, data) << path;
  std::vector<std::int64_t> want =
      cols == 0 ? std::vector<std::int64_t>{rows} : std::vector<std::int64_t>{rows, cols};
  EXPECT_EQ(f.dims(path), want) << path;
}

/// A tiny mesh: n_points points, n_cells cells, all rows on this rank.
struct TinyMesh {
  std::vector<double> points, youngs;
  std::vector<std::int64_t> cells;
  std::vector<std::int32_t> ijk, material;
  MeshData data;
  TinyMesh(std::int64_t n_points, std::int64_t n_cells) {
    points = table<double>(n_points, 3);
    cells = table<std::int64_t>(n_cells, 8);
    ijk = table<std::int32_t>(n_cells, 3);
    material = table<std::int32_t>(n_cells, 0);
    youngs = table<double>(n_cells, 0);
    data.lattice.dims = {2, 1, 1};
    data.points = {n_points, 0, n_points};
    data.cells = {n_cells, 0, n_cells};
    data.positions = points.data();
    data.connectivity = cells.data();
    data.lattice_index = ijk.data();
    data.material = material.data();
    data.youngs_modulus = youngs.data();
  }
};

std::string read_text(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

}  // namespace

TEST(OutputH5File, RowTablesOfEveryTypeRoundTrip) {
  fs::path file = scratch_dir("types") / "t.h5";
  H5File f = H5File::create(file.string(), MPI_COMM_SELF);
  round_trip<double>(f, "/a/b/double", 5, 3);
  round_trip<float>(f, "/float", 4, 2);
  round_trip<std::int32_t>(f, "/int32", 6, 0);
  round_trip<std::int64_t>(f, "/g/int64", 3, 8);
  round_trip<std::uint8_t>(f, "/uint8", 9, 1);
  EXPECT_EQ(f.element_type("/float"), (std::pair<std::string, int>("float", 4)));
  EXPECT_EQ(f.element_type("/uint8"), (std::pair<std::string, int>("uint", 1)));
  EXPECT_EQ(f.element_type("/g/int64"), (std::pair<std::string, int>("int", 8)));
  EXPECT_EQ(f.dims("/uint8"), (std::vector<std::int64_t>{9, 1}));
  EXPECT_TRUE(f.is_group("/a/b"));
  f.close();
  // Re-open read-only and read a middle slab.
  H5File r = H5File::open(file.string(), MPI_COMM_SELF, H5File::Access::kReadOnly);
  std::vector<double> slab(2 * 3);
  r.read_rows("/a/b/double", 5, 3, 2, 2, slab.data());
  EXPECT_EQ(slab, table<double>(2, 3, 2));
}

TEST(OutputH5File, OverwriteInPlaceOrRecreate) {
  fs::path file = scratch_dir("overwrite") / "t.h5";
  H5File f = H5File::create(file.string(), MPI_COMM_SELF);
  std::vector<double> a(6, 1.0), b(6, 2.0), c(8, 3.0);
  f.write_rows("/x", 2, 3, 0, 2, a.data());
  f.write_rows("/x", 2, 3, 0, 2, b.data());  // same shape: in place
  std::vector<double> back(6);
  f.read_rows("/x", 2, 3, 0, 2, back.data());
  EXPECT_EQ(back, b);
  f.write_rows("/x", 4, 2, 0, 4, c.data());  // other shape: re-created
  EXPECT_EQ(f.dims("/x"), (std::vector<std::int64_t>{4, 2}));
  std::vector<std::int32_t> ints(4, 7);
  f.write_rows("/x", 4, 0, 0, 4, ints.data());  // other type: re-created
  EXPECT_EQ(f.element_type("/x").first, "int");
}

TEST(OutputH5File, AttributesStringsLinksAndAppend) {
  fs::path file = scratch_dir("attrs") / "t.h5";
  H5File f = H5File::create(file.string(), MPI_COMM_SELF);
  f.create_group("/g/h");
  f.write_attribute("/g", "d", 2.5);
  f.write_attribute("/g", "i", std::int64_t{-7});
  f.write_attribute("/g", "n", 3);
  f.write_attribute("/g", "s", "h\xC3\xA9llo");
  f.write_attribute("/g", "empty", "");
  f.write_attribute("/g", "v", std::vector<double>{1, 2, 3});
  f.write_attribute("/g", "iv", std::vector<std::int64_t>{4, 5});
  f.write_attribute("/g", "d", 3.5);  // replace
  EXPECT_EQ(f.read_attribute_double("/g", "d"), 3.5);
  EXPECT_EQ(f.read_attribute_int64("/g", "i"), -7);
  EXPECT_EQ(f.read_attribute_int64("/g", "n"), 3);
  EXPECT_EQ(f.read_attribute_string("/g", "s"), "h\xC3\xA9llo");
  EXPECT_EQ(f.read_attribute_string("/g", "empty"), "");
  EXPECT_EQ(f.read_attribute_doubles("/g", "v"), (std::vector<double>{1, 2, 3}));
  EXPECT_EQ(f.read_attribute_int64s("/g", "iv"), (std::vector<std::int64_t>{4, 5}));
  EXPECT_TRUE(f.has_attribute("/g", "s"));
  EXPECT_FALSE(f.has_attribute("/g", "nope"));
  EXPECT_FALSE(f.has_attribute("/nope", "s"));

  const std::string deck = "a: 1\n  b: [2, 3]   \n\n# end\n";
  f.write_string_dataset("/input/deck", deck);
  f.write_string_dataset("/input/empty", "");
  EXPECT_EQ(f.read_string_dataset("/input/deck"), deck);
  EXPECT_EQ(f.read_string_dataset("/input/empty"), "");

  EXPECT_TRUE(f.exists("/g/h"));
  EXPECT_FALSE(f.exists("/g/h/x"));
  EXPECT_FALSE(f.exists("/input/deck/x"));  // through a dataset
  EXPECT_EQ(f.list("/g"), (std::vector<std::string>{"h"}));
  f.delete_link("/g/h");
  EXPECT_FALSE(f.exists("/g/h"));

  std::vector<std::int64_t> v{1, 2, 3};
  f.append_1d("/hist/x", v.data(), 3);
  f.append_1d("/hist/x", v.data(), 2);
  EXPECT_EQ(f.dims("/hist/x"), (std::vector<std::int64_t>{5}));
  f.resize_1d("/hist/x", 4);
  std::vector<std::int64_t> back(4);
  f.read_rows("/hist/x", 4, 0, 0, 4, back.data());
  EXPECT_EQ(back, (std::vector<std::int64_t>{1, 2, 3, 1}));
}

TEST(OutputH5File, ErrorsThrowWithPathAndOperation) {
  fs::path file = scratch_dir("errors") / "t.h5";
  H5File f = H5File::create(file.string(), MPI_COMM_SELF);
  std::vector<double> d(6, 0.0);
  f.write_rows("/x", 2, 3, 0, 2, d.data());
  try {
    f.read_rows("/x", 3, 3, 0, 3, d.data());
    FAIL() << "no throw";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("'/x'"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("read_rows"), std::string::npos) << e.what();
  }
  EXPECT_THROW(f.read_rows("/missing", 2, 3, 0, 2, d.data()), std::runtime_error);
  EXPECT_THROW(f.write_rows("/x", 2, 3, 1, 2, d.data()), std::runtime_error);  // bad slab
  EXPECT_THROW(f.delete_link("/missing"), std::runtime_error);
  EXPECT_THROW(f.read_attribute_double("/x", "missing"), std::runtime_error);
  EXPECT_THROW(f.read_attribute_string("/x", "missing"), std::runtime_error);
  f.write_attribute("/x", "num", 1.0);
  EXPECT_THROW(f.read_attribute_string("/x", "num"), std::runtime_error);
  EXPECT_THROW(H5File::open((file.parent_path() / "nope.h5").string(), MPI_COMM_SELF),
               std::runtime_error);
}

TEST(OutputResultWriter, CreateIsAtomicAndStepsCloseTheFile) {
  fs::path dir = scratch_dir("create");
  const std::string path = (dir / "run.h5").string();
  TinyMesh mesh(12, 2);
  ResultWriter w = ResultWriter::create(path, MPI_COMM_SELF, mesh.data, {"deck: 1\n", "hexcut x"});
  EXPECT_TRUE(fs::exists(path));
  EXPECT_FALSE(fs::exists(path + ".tmp"));
  EXPECT_TRUE(fs::exists(dir / "run.xmf"));
  EXPECT_EQ(read_text(dir / "run.xmf").find("<Grid Name=\"step_"), std::string::npos);
  EXPECT_EQ(w.num_points(), 12);
  EXPECT_EQ(w.num_cells(), 2);
  EXPECT_EQ(w.last_complete_step(), -1);

  std::vector<double> u = table<double>(12, 3), s = table<double>(2, 6);
  w.begin_step(0, 0.0);
  EXPECT_THROW(w.begin_step(1, 0.1), std::logic_error);
  EXPECT_THROW(w.write_point_field(1, "u", 3, 0, 12, u.data()), std::logic_error);
  EXPECT_THROW(w.write_point_field(0, "a/b", 3, 0, 12, u.data()), std::invalid_argument);
  w.write_point_field(0, "displacement", 3, 0, 12, u.data(), "m");
  w.write_cell_field(0, "stress", 6, 0, 2, s.data(), "Pa");
  w.end_step();
  EXPECT_EQ(w.last_complete_step(), 0);
  EXPECT_NE(read_text(dir / "run.xmf").find("run.h5:/steps/000000/stress"), std::string::npos);
  // 6 columns: Matrix, which every ParaView reader passes through unchanged (Tensor6 is
  // reordered by one reader and not by the others).
  EXPECT_NE(read_text(dir / "run.xmf")
                .find("<Attribute Name=\"stress\" AttributeType=\"Matrix\" Center=\"Cell\">"),
            std::string::npos);
  EXPECT_EQ(read_text(dir / "run.xmf").find("hexcut_surface"), std::string::npos);  // none
  EXPECT_FALSE(fs::exists(dir / "run_surface.xmf"));
  EXPECT_FALSE(fs::exists(dir / "run.xmf.tmp"));

  // The file is closed between steps: another (read-only) open sees the complete step.
  H5File r = H5File::open(path, MPI_COMM_SELF, H5File::Access::kReadOnly);
  EXPECT_EQ(r.read_attribute_int64("/steps/000000", "complete"), 1);
  EXPECT_EQ(r.read_attribute_int64("/steps", "last_complete_step"), 0);
  EXPECT_EQ(r.read_string_dataset("/input/deck"), "deck: 1\n");
  EXPECT_EQ(r.read_attribute_string("/steps/000000/stress", "centering"), "cell");
  r.close();

  // Re-creating replaces the old file.
  ResultWriter w2 = ResultWriter::create(path, MPI_COMM_SELF, mesh.data, {"deck: 2\n", ""});
  H5File r2 = H5File::open(path, MPI_COMM_SELF, H5File::Access::kReadOnly);
  EXPECT_EQ(r2.read_string_dataset("/input/deck"), "deck: 2\n");
  EXPECT_TRUE(r2.list("/steps").empty());
}

TEST(OutputResultWriter, CheckpointRoundTripAndTruncate) {
  fs::path dir = scratch_dir("checkpoint");
  const std::string path = (dir / "run.h5").string();
  TinyMesh mesh(8, 3);
  {
    ResultWriter w = ResultWriter::create(path, MPI_COMM_SELF, mesh.data, {"", ""});
    EXPECT_FALSE(w.checkpoint_info().has_value());
    for (int step = 0; step < 4; ++step) {
      SolverHistoryRow rec;
      rec.step = step;
      rec.iterations = step;
      w.append_solve(rec);
      w.begin_step(step, 0.5 * step);
      std::vector<double> f(8 * 3, step);
      w.write_point_field(step, "displacement", 3, 0, 8, f.data());
      w.end_step();
      std::vector<double> u(24, 1.0 * step), v(24, 2.0 * step), a(24, 3.0 * step);
      std::vector<std::int32_t> links{step, step + 1, step + 2, step + 3, step + 4, step + 5};
      w.write_checkpoint(step, 0.5 * step, 0, 8, u.data(), v.data(), a.data(), Slab{3, 0, 3}, 2,
                         links.data());
    }
  }
  ResultWriter w = ResultWriter::open(path, MPI_COMM_SELF);
  EXPECT_EQ(w.last_complete_step(), 3);
  auto info = w.checkpoint_info();
  ASSERT_TRUE(info.has_value());
  EXPECT_EQ(info->step, 3);
  EXPECT_EQ(info->time, 1.5);
  EXPECT_EQ(info->num_points, 8);
  EXPECT_EQ(info->link_rows, 3);
  EXPECT_EQ(info->link_cols, 2);
  std::vector<double> u(24), v(24), a(24);
  std::vector<std::int32_t> links(4);
  CheckpointInfo got = w.read_checkpoint(0, 8, u.data(), v.data(), a.data(), 1, 2, links.data());
  EXPECT_EQ(got.step, 3);
  EXPECT_EQ(u, std::vector<double>(24, 3.0));
  EXPECT_EQ(v, std::vector<double>(24, 6.0));
  EXPECT_EQ(a, std::vector<double>(24, 9.0));
  EXPECT_EQ(links, (std::vector<std::int32_t>{5, 6, 7, 8}));

  w.truncate_steps_after(1);
  EXPECT_EQ(w.last_complete_step(), 1);
  {
    H5File r = H5File::open(path, MPI_COMM_SELF, H5File::Access::kReadOnly);
    EXPECT_EQ(r.list("/steps"), (std::vector<std::string>{"000000", "000001"}));
    EXPECT_EQ(r.read_attribute_int64("/steps", "last_complete_step"), 1);
    EXPECT_EQ(r.dims("/solver_history/step"), (std::vector<std::int64_t>{2}));
    EXPECT_EQ(r.dims("/solver_history/converged_reason"), (std::vector<std::int64_t>{2}));
  }
  const std::string xmf = read_text(dir / "run.xmf");
  EXPECT_NE(xmf.find("step_000001"), std::string::npos);
  EXPECT_EQ(xmf.find("step_000002"), std::string::npos);

  // Continue after the restart: step 2 again, history appended after the kept rows.
  SolverHistoryRow rec;
  rec.step = 2;
  w.append_solve(rec);
  w.begin_step(2, 1.0);
  std::vector<double> f(24, 42.0);
  w.write_point_field(2, "displacement", 3, 0, 8, f.data());
  w.end_step();
  H5File r = H5File::open(path, MPI_COMM_SELF, H5File::Access::kReadOnly);
  std::vector<std::int64_t> steps(3);
  r.read_rows("/solver_history/step", 3, 0, 0, 3, steps.data());
  EXPECT_EQ(steps, (std::vector<std::int64_t>{0, 1, 2}));
  EXPECT_EQ(r.read_attribute_int64("/steps", "last_complete_step"), 2);
  // The previous checkpoint slot survives (step 3 is still the newest checkpoint).
  EXPECT_EQ(r.read_attribute_int64("/checkpoint", "step"), 3);
}

TEST(OutputResultWriter, XdmfPathAndStepNames) {
  EXPECT_EQ(xdmf_path_for("out/run.h5"), "out/run.xmf");
  EXPECT_EQ(xdmf_path_for("run.hdf5"), "run.hdf5.xmf");
  EXPECT_EQ(surface_xdmf_path_for("out/run.h5"), "out/run_surface.xmf");
  EXPECT_EQ(surface_xdmf_path_for("run.hdf5"), "run.hdf5_surface.xmf");
  EXPECT_EQ(index_paths("out/run.h5"),
            (std::vector<std::string>{"out/run.xmf", "out/run_surface.xmf"}));
  EXPECT_EQ(step_group(42), "/steps/000042");
  EXPECT_THROW(step_group(-1), std::invalid_argument);
}

// ------------------------------------------------------------------ topology changes

namespace {

/// 3 x 1 x 1 cells of edge 0.5: 16 points; split at i = 2: 20 points.
hexcut::LatticeSpec row_lattice() {
  hexcut::LatticeSpec l;
  l.origin = {1.0, 2.0, 3.0};
  l.h = 0.5;
  l.dims = {3, 1, 1};
  return l;
}

Slab all_rows(std::int64_t n) {
  return Slab{n, 0, n};
}

/// The <Grid Name="name" ...> ... </Grid> element of an XDMF text ("" when absent).
std::string grid_text(const std::string& xmf, const std::string& name) {
  const auto begin = xmf.find("<Grid Name=\"" + name + "\"");
  if (begin == std::string::npos) return "";
  return xmf.substr(begin, xmf.find("</Grid>", begin) - begin);
}

/// Steps 1..3 of a run whose step 2 splits the vertex copies; surfaces on steps 1 and 3.
void write_cut_run(const std::string& path) {
  const hexcut::LatticeSpec lattice = row_lattice();
  const FullMesh before = lattice_mesh(lattice), after = lattice_mesh(lattice, 2);
  MeshSlices m0(before, all_rows(16), all_rows(3));
  ResultWriter w = ResultWriter::create(path, MPI_COMM_SELF, m0.data, {"", ""});
  EXPECT_EQ(w.mesh_path(), "/mesh");

  w.begin_step(1, 0.25);
  std::vector<double> u16 = table<double>(16, 3), s3 = table<double>(3, 6);
  w.write_point_field(1, "displacement", 3, 0, 16, u16.data(), "m");
  w.write_cell_field(1, "stress", 6, 0, 3, s3.data(), "Pa");
  const FullSurface whole = box_surface(lattice, {Box{0, 3}}, {0.01, 0.0, 0.0});
  SurfaceSlices s1(whole, all_rows(8), all_rows(12));
  w.write_surface(1, s1.data);
  w.end_step();

  w.begin_step(2, 0.5);
  MeshSlices m1(after, all_rows(20), all_rows(3));
  w.write_mesh(2, m1.data);
  EXPECT_EQ(w.num_points(), 20);
  EXPECT_EQ(w.num_cells(), 3);
  EXPECT_EQ(w.mesh_path(), "/steps/000002/mesh");
  std::vector<double> u20 = table<double>(20, 3);
  // The previous mesh's slab no longer covers the point table.
  EXPECT_THROW(w.write_point_field(2, "displacement", 3, 0, 16, u16.data()), std::invalid_argument);
  w.write_point_field(2, "displacement", 3, 0, 20, u20.data(), "m");
  w.write_cell_field(2, "stress", 6, 0, 3, s3.data(), "Pa");
  // Checkpoints follow the current mesh.
  EXPECT_THROW(w.write_checkpoint(2, 0.5, 0, 16, u16.data(), u16.data(), u16.data()),
               std::invalid_argument);
  w.write_checkpoint(2, 0.5, 0, 20, u20.data(), u20.data(), u20.data());
  w.end_step();

  w.begin_step(3, 0.75);
  w.write_point_field(3, "displacement", 3, 0, 20, u20.data(), "m");
  const FullSurface split =
      box_surface(lattice, {Box{0, 2, 0, 1}, Box{2, 3, 1, 0}}, {0.02, 0.0, 0.0});
  SurfaceSlices s3surf(split, all_rows(16), all_rows(24));
  w.write_surface(3, s3surf.data);
  w.end_step();
  EXPECT_EQ(w.num_points(), 20);
}

}  // namespace

TEST(OutputResultWriter, MeshPerTopologyVersionAndSurfaces) {
  fs::path dir = scratch_dir("cuts");
  const std::string path = (dir / "run.h5").string();
  write_cut_run(path);
  {
    H5File r = H5File::open(path, MPI_COMM_SELF, H5File::Access::kReadOnly);
    EXPECT_EQ(r.read_attribute_string("/steps/000001", "mesh"), "/mesh");
    EXPECT_EQ(r.read_attribute_string("/steps/000002", "mesh"), "/steps/000002/mesh");
    EXPECT_EQ(r.read_attribute_string("/steps/000003", "mesh"), "/steps/000002/mesh");
    EXPECT_EQ(r.dims("/mesh/points"), (std::vector<std::int64_t>{16, 3}));
    EXPECT_EQ(r.dims("/steps/000002/mesh/points"), (std::vector<std::int64_t>{20, 3}));
    EXPECT_EQ(r.dims("/steps/000002/mesh/cells"), (std::vector<std::int64_t>{3, 8}));
    EXPECT_EQ(r.read_attribute_int64("/steps/000002/mesh", "num_points"), 20);
    EXPECT_EQ(r.read_attribute_int64("/steps/000002/mesh", "step"), 2);
    EXPECT_EQ(r.read_attribute_int64s("/steps/000002/mesh", "lattice_dims"),
              (std::vector<std::int64_t>{3, 1, 1}));
    EXPECT_EQ(r.read_attribute_string("/steps/000002/mesh/points", "unit"), "m");
    std::vector<std::int64_t> cells(24);
    r.read_rows("/steps/000002/mesh/cells", 3, 8, 0, 3, cells.data());
    EXPECT_EQ(cells, lattice_mesh(row_lattice(), 2).cells);
    EXPECT_EQ(r.dims("/steps/000003/displacement"), (std::vector<std::int64_t>{20, 3}));
    EXPECT_FALSE(r.exists("/steps/000002/surface"));
    EXPECT_EQ(r.dims("/steps/000003/surface/points"), (std::vector<std::int64_t>{16, 3}));
    EXPECT_EQ(r.dims("/steps/000003/surface/triangles"), (std::vector<std::int64_t>{24, 3}));
    EXPECT_EQ(r.dims("/steps/000003/surface/cut_id"), (std::vector<std::int64_t>{24}));
    EXPECT_EQ(r.dims("/steps/000003/surface/owner_cell"), (std::vector<std::int64_t>{16}));
    EXPECT_EQ(r.element_type("/steps/000003/surface/cut_id"),
              (std::pair<std::string, int>("int", 4)));
    EXPECT_EQ(r.element_type("/steps/000003/surface/triangles"),
              (std::pair<std::string, int>("int", 8)));
    EXPECT_EQ(r.read_attribute_int64("/steps/000003/surface", "num_triangles"), 24);
    std::vector<std::int32_t> cut(24);
    r.read_rows("/steps/000003/surface/cut_id", 24, 0, 0, 24, cut.data());
    EXPECT_EQ(std::count(cut.begin(), cut.end(), 1), 4);
    EXPECT_EQ(r.dims("/checkpoint/slot0/displacement"), (std::vector<std::int64_t>{20, 3}));
  }
  // The XDMF: each step's volume grid uses that step's mesh; the surfaces of steps 1 and 3
  // are in their own index (one collection per index, so that every reader keeps the
  // volume's arrays).
  const std::string xmf = read_text(dir / "run.xmf");
  const std::string surfaces = read_text(dir / "run_surface.xmf");
  const std::string g1 = grid_text(xmf, "step_000001"), g3 = grid_text(xmf, "step_000003");
  EXPECT_NE(g1.find("run.h5:/mesh/points"), std::string::npos);
  EXPECT_NE(g3.find("Dimensions=\"20 3\" NumberType=\"Float\" Precision=\"8\" "
                    "Format=\"HDF\">run.h5:/steps/000002/mesh/points"),
            std::string::npos)
      << g3;
  EXPECT_NE(g3.find("run.h5:/steps/000002/mesh/cells"), std::string::npos);
  EXPECT_EQ(g3.find("run.h5:/mesh/"), std::string::npos);
  EXPECT_EQ(xmf.find("surface"), std::string::npos);
  EXPECT_NE(surfaces.find("<Grid Name=\"hexcut_surface\""), std::string::npos);
  EXPECT_EQ(surfaces.find("step_"), std::string::npos);
  const std::string s1 = grid_text(surfaces, "surface_000001"),
                    s3 = grid_text(surfaces, "surface_000003");
  EXPECT_NE(s1.find("TopologyType=\"Triangle\" NumberOfElements=\"12\""), std::string::npos);
  EXPECT_NE(s3.find("run.h5:/steps/000003/surface/triangles"), std::string::npos);
  EXPECT_NE(s3.find("<Attribute Name=\"cut_id\" AttributeType=\"Scalar\" Center=\"Cell\">"),
            std::string::npos);
  EXPECT_NE(s3.find("<Attribute Name=\"owner_cell\" AttributeType=\"Scalar\" Center=\"Node\">"),
            std::string::npos);
  EXPECT_EQ(grid_text(surfaces, "surface_000002"), "");
  // write_indexes rewrites both from the file alone.
  fs::remove(dir / "run.xmf");
  fs::remove(dir / "run_surface.xmf");
  write_indexes(path);
  EXPECT_EQ(read_text(dir / "run.xmf"), xmf);
  EXPECT_EQ(read_text(dir / "run_surface.xmf"), surfaces);
  write_xdmf(path, (dir / "volume_only.xmf").string());  // the volume index alone
  EXPECT_EQ(read_text(dir / "volume_only.xmf"), xmf);

  // Restart: open() continues with the mesh of the last complete step.
  ResultWriter w = ResultWriter::open(path, MPI_COMM_SELF);
  EXPECT_EQ(w.num_points(), 20);
  EXPECT_EQ(w.mesh_path(), "/steps/000002/mesh");
  auto info = w.checkpoint_info();
  ASSERT_TRUE(info.has_value());
  EXPECT_EQ(info->num_points, 20);
  w.truncate_steps_after(2);  // keeps the step that introduced the mesh
  EXPECT_EQ(w.num_points(), 20);
  EXPECT_EQ(w.mesh_path(), "/steps/000002/mesh");
  w.truncate_steps_after(1);  // drops it: back to the original mesh
  EXPECT_EQ(w.num_points(), 16);
  EXPECT_EQ(w.mesh_path(), "/mesh");
  EXPECT_EQ(w.last_complete_step(), 1);
  const std::string xmf1 = read_text(dir / "run.xmf");
  const std::string surfaces1 = read_text(dir / "run_surface.xmf");
  EXPECT_EQ(xmf1.find("/steps/000002"), std::string::npos);
  EXPECT_EQ(grid_text(surfaces1, "surface_000003"), "");
  EXPECT_NE(grid_text(surfaces1, "surface_000001"), "");
  // And goes on with the original mesh.
  w.begin_step(2, 0.5);
  std::vector<double> u16 = table<double>(16, 3);
  w.write_point_field(2, "displacement", 3, 0, 16, u16.data());
  w.end_step();
  H5File r = H5File::open(path, MPI_COMM_SELF, H5File::Access::kReadOnly);
  EXPECT_EQ(r.read_attribute_string("/steps/000002", "mesh"), "/mesh");
  EXPECT_FALSE(r.exists("/steps/000002/mesh"));
  r.close();
  EXPECT_EQ(ResultWriter::open(path, MPI_COMM_SELF).num_points(), 16);
}

TEST(OutputResultWriter, OpenIgnoresTheMeshOfAnIncompleteStep) {
  fs::path dir = scratch_dir("cuts_killed");
  const std::string path = (dir / "run.h5").string();
  const hexcut::LatticeSpec lattice = row_lattice();
  {
    MeshSlices m0(lattice_mesh(lattice), all_rows(16), all_rows(3));
    ResultWriter w = ResultWriter::create(path, MPI_COMM_SELF, m0.data, {"", ""});
    w.begin_step(1, 0.25);
    w.end_step();
    w.begin_step(2, 0.5);
    MeshSlices m1(lattice_mesh(lattice, 2), all_rows(20), all_rows(3));
    w.write_mesh(2, m1.data);
    w.end_step();
    // Step 3 introduces another mesh but never completes (as if killed).
    w.begin_step(3, 0.75);
    MeshSlices m2(lattice_mesh(lattice, 1), all_rows(20), all_rows(3));
    w.write_mesh(3, m2.data);
  }
  ResultWriter w = ResultWriter::open(path, MPI_COMM_SELF);
  EXPECT_EQ(w.last_complete_step(), 2);
  EXPECT_EQ(w.mesh_path(), "/steps/000002/mesh");
  EXPECT_EQ(w.num_points(), 20);
  w.truncate_steps_after(3);  // keeps the incomplete step 3, whose mesh is not used
  EXPECT_EQ(w.mesh_path(), "/steps/000002/mesh");
  EXPECT_EQ(read_text(dir / "run.xmf").find("step_000003"), std::string::npos);
  // Rewriting step 3 deletes its stale mesh; the current mesh stays step 2's.
  w.begin_step(3, 0.75);
  EXPECT_EQ(w.mesh_path(), "/steps/000002/mesh");
  w.end_step();
  H5File r = H5File::open(path, MPI_COMM_SELF, H5File::Access::kReadOnly);
  EXPECT_FALSE(r.exists("/steps/000003/mesh"));
  EXPECT_EQ(r.read_attribute_string("/steps/000003", "mesh"), "/steps/000002/mesh");
}

TEST(OutputResultWriter, MeshAndSurfaceMisuseThrows) {
  fs::path dir = scratch_dir("cuts_misuse");
  const std::string path = (dir / "run.h5").string();
  const hexcut::LatticeSpec lattice = row_lattice();
  MeshSlices m0(lattice_mesh(lattice), all_rows(16), all_rows(3));
  MeshSlices m1(lattice_mesh(lattice, 2), all_rows(20), all_rows(3));
  ResultWriter w = ResultWriter::create(path, MPI_COMM_SELF, m0.data, {"", ""});
  EXPECT_THROW(w.write_mesh(1, m1.data), std::logic_error);  // no open step
  w.begin_step(1, 0.25);
  EXPECT_THROW(w.write_mesh(2, m1.data), std::logic_error);  // not the open step
  std::vector<double> u16 = table<double>(16, 3);
  EXPECT_THROW(w.write_point_field(1, "mesh", 3, 0, 16, u16.data()), std::invalid_argument);
  w.write_point_field(1, "displacement", 3, 0, 16, u16.data());
  EXPECT_THROW(w.write_mesh(1, m1.data), std::logic_error);  // after a field
  EXPECT_EQ(w.num_points(), 16);

  const FullSurface box = box_surface(lattice, {Box{0, 3}}, {0, 0, 0});
  SurfaceSlices bad(box, all_rows(8), all_rows(12));
  bad.triangles[5] = 8;  // vertex rows are 0..7
  EXPECT_THROW(w.write_surface(1, bad.data), std::invalid_argument);
  bad.triangles[5] = 7;
  bad.owner_cell[0] = 3;  // cells are 0..2
  EXPECT_THROW(w.write_surface(1, bad.data), std::invalid_argument);
  bad.owner_cell[0] = 0;
  bad.cut_id[0] = -1;
  EXPECT_THROW(w.write_surface(1, bad.data), std::invalid_argument);
  bad.cut_id[0] = 0;
  w.write_surface(1, bad.data);
  w.end_step();

  w.begin_step(2, 0.5);
  MeshSlices broken(lattice_mesh(lattice, 2), all_rows(20), all_rows(3));
  broken.cells[3] = 20;
  EXPECT_THROW(w.write_mesh(2, broken.data), std::invalid_argument);
  w.write_mesh(2, m1.data);
  w.end_step();
  w.begin_step(3, 0.75);
  w.end_step();
  // Step 3 uses step 2's mesh: rewriting step 2 would delete it.
  EXPECT_THROW(w.begin_step(2, 0.5), std::logic_error);
  EXPECT_FALSE(w.step_open());
  EXPECT_EQ(w.mesh_path(), "/steps/000002/mesh");
  // Once step 3 is gone, rewriting step 2 is allowed; its mesh goes with it.
  w.truncate_steps_after(2);
  w.begin_step(2, 0.5);
  EXPECT_EQ(w.mesh_path(), "/mesh");
  EXPECT_EQ(w.num_points(), 16);
  w.write_mesh(2, m1.data);
  EXPECT_EQ(w.num_points(), 20);
  w.end_step();
  EXPECT_EQ(ResultWriter::open(path, MPI_COMM_SELF).mesh_path(), "/steps/000002/mesh");
}

TEST(OutputResultWriter, CheckpointWithExplicitPointCount) {
  fs::path dir = scratch_dir("cuts_checkpoint");
  const std::string path = (dir / "run.h5").string();
  MeshSlices m0(lattice_mesh(row_lattice()), all_rows(16), all_rows(3));
  ResultWriter w = ResultWriter::create(path, MPI_COMM_SELF, m0.data, {"", ""});
  // After a cut between output steps: the writer's mesh still has 16 points.
  std::vector<double> u = table<double>(20, 3);
  w.write_checkpoint(5, 1.25, Slab{20, 0, 20}, u.data(), u.data(), u.data());
  EXPECT_THROW(w.write_checkpoint(5, 1.25, Slab{20, 0, 19}, u.data(), u.data(), u.data()),
               std::invalid_argument);
  auto info = w.checkpoint_info();
  ASSERT_TRUE(info.has_value());
  EXPECT_EQ(info->num_points, 20);
  std::vector<double> back(60), v(60), a(60);
  w.read_checkpoint(0, 20, back.data(), v.data(), a.data());
  EXPECT_EQ(back, u);
}

TEST(OutputResultWriter, EmptySurfaceIsNotIndexed) {
  fs::path dir = scratch_dir("cuts_empty");
  const std::string path = (dir / "run.h5").string();
  MeshSlices m0(lattice_mesh(row_lattice()), all_rows(16), all_rows(3));
  ResultWriter w = ResultWriter::create(path, MPI_COMM_SELF, m0.data, {"", ""});
  w.begin_step(0, 0.0);
  w.write_surface(0, SurfaceData{});
  w.end_step();
  H5File r = H5File::open(path, MPI_COMM_SELF, H5File::Access::kReadOnly);
  EXPECT_EQ(r.dims("/steps/000000/surface/triangles"), (std::vector<std::int64_t>{0, 3}));
  r.close();
  const std::string xmf = read_text(dir / "run.xmf");
  EXPECT_NE(xmf.find("step_000000"), std::string::npos);
  EXPECT_EQ(xmf.find("hexcut_surface"), std::string::npos);
  EXPECT_FALSE(fs::exists(dir / "run_surface.xmf"));
}

TEST(OutputResultWriter, SurfaceIndexOfAnEarlierRunIsRemoved) {
  fs::path dir = scratch_dir("stale_surface_index");
  const std::string path = (dir / "run.h5").string();
  write_cut_run(path);
  ASSERT_TRUE(fs::exists(dir / "run_surface.xmf"));
  // A new run of that name without surfaces: the old surface index would refer to
  // datasets the new file does not have.
  MeshSlices m0(lattice_mesh(row_lattice()), all_rows(16), all_rows(3));
  ResultWriter w = ResultWriter::create(path, MPI_COMM_SELF, m0.data, {"", ""});
  EXPECT_FALSE(fs::exists(dir / "run_surface.xmf"));
  EXPECT_TRUE(fs::exists(dir / "run.xmf"));
}

TEST(OutputResultWriter, NamesTheIndexCannotReferToAreRefused) {
  fs::path dir = scratch_dir("names");
  MeshSlices m0(lattice_mesh(row_lattice()), all_rows(16), all_rows(3));
  // ':' separates file and dataset in XDMF ("job_12:30.h5" opened as "30.h5"); readers
  // strip surrounding spaces; control characters and non-UTF-8 bytes make the index
  // malformed XML; "x_surface.xmf" would be the surface index of "x".
  for (const std::string name :
       {"job_12:30.h5", " run.h5", "run.h5 ", "a\tb.h5", "a\x01.h5", "\xff\xfe.h5", "caf\xc3.h5",
        "\xed\xa0\x80.h5", "cut_surface.h5"}) {
    const std::string path = (dir / name).string();
    EXPECT_THROW(ResultWriter::create(path, MPI_COMM_SELF, m0.data, {"", ""}),
                 std::invalid_argument)
        << name;
    EXPECT_THROW(check_result_path(path), std::invalid_argument) << name;
    EXPECT_FALSE(fs::exists(path) || fs::exists(path + ".tmp")) << name;
  }
  try {
    check_result_path("out/job_12:30.h5");
    FAIL() << "no throw";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("'job_12:30.h5' contains ':'"), std::string::npos)
        << e.what();
  }

  // Names XML cannot hold verbatim are escaped; a leading non-ASCII character gets "./"
  // (ParaView's Xdmf2 reader drops it otherwise). Field names likewise.
  const std::string odd = "\xc3\xa9t\xc3\xa9 & <b> 'c' \"d\".h5";
  const std::string path = (dir / odd).string();
  ResultWriter w = ResultWriter::create(path, MPI_COMM_SELF, m0.data, {"", ""});
  w.begin_step(0, 0.0);
  std::vector<double> e3 = table<double>(3, 0);
  EXPECT_THROW(w.write_cell_field(0, "a:b", 1, 0, 3, e3.data()), std::invalid_argument);
  EXPECT_THROW(w.write_cell_field(0, "a\nb", 1, 0, 3, e3.data()), std::invalid_argument);
  EXPECT_THROW(w.write_cell_field(0, "\xff", 1, 0, 3, e3.data()), std::invalid_argument);
  w.write_cell_field(0, "energy & <odd> \"name\"", 1, 0, 3, e3.data());
  w.end_step();
  const std::string xmf = read_text(dir / "\xc3\xa9t\xc3\xa9 & <b> 'c' \"d\".xmf");
  EXPECT_NE(xmf.find("<Attribute Name=\"energy &amp; &lt;odd&gt; &quot;name&quot;\""),
            std::string::npos)
      << xmf;
  EXPECT_NE(xmf.find(">./\xc3\xa9t\xc3\xa9 &amp; &lt;b&gt; &apos;c&apos; &quot;d&quot;.h5:"
                     "/steps/000000/energy &amp; &lt;odd&gt; &quot;name&quot;</DataItem>"),
            std::string::npos)
      << xmf;
}

TEST(OutputResultWriter, OpenRefusesAnotherLayoutVersion) {
  fs::path dir = scratch_dir("version");
  const std::string path = (dir / "run.h5").string();
  MeshSlices m0(lattice_mesh(row_lattice()), all_rows(16), all_rows(3));
  ResultWriter::create(path, MPI_COMM_SELF, m0.data, {"", ""});
  EXPECT_NO_THROW(ResultWriter::open(path, MPI_COMM_SELF));
  {
    H5File f = H5File::open(path, MPI_COMM_SELF, H5File::Access::kReadWrite);
    EXPECT_EQ(f.read_attribute_int64("/", "format_version"), 2);
    f.write_attribute("/", "format_version", std::int64_t{1});
  }
  EXPECT_THROW(ResultWriter::open(path, MPI_COMM_SELF), std::runtime_error);
}
