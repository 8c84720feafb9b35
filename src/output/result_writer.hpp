// hexcut's result file: one HDF5 file per run, written in parallel, plus XDMF indexes
// that ParaView opens as a time series. The layout is specified in doc/output-format.md.
//
// All members are COLLECTIVE over the writer's communicator unless stated otherwise: every
// rank calls them in the same order with the same step/time/names/shapes; only the row
// slabs (row_offset, local_rows, data) differ. Data arrives in canonical (rank-independent)
// row order, as contiguous row slabs. An exception thrown on some ranks only (an I/O
// error) leaves the others inside a collective call: callers should treat it as fatal
// (MPI_Abort). The writer does not depend on PETSc.
#pragma once

#include <mpi.h>

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "common/lattice_spec.hpp"
#include "output/h5_file.hpp"

namespace hexcut::output {

/// This rank's contiguous slab of a global row table.
struct Slab {
  std::int64_t global_rows = 0;
  std::int64_t row_offset = 0;
  std::int64_t local_rows = 0;
};

/// The mesh, as this rank's slabs of the canonical point and cell tables.
struct MeshData {
  LatticeSpec lattice;
  Slab points;                                  // rows of /mesh/points
  const double* positions = nullptr;            // points.local_rows x 3, reference [m]
  Slab cells;                                   // rows of every /mesh/cell_* table
  const std::int64_t* connectivity = nullptr;   // cells.local_rows x 8, VTK_HEXAHEDRON order
  const std::int32_t* lattice_index = nullptr;  // cells.local_rows x 3 (i, j, k)
  const std::int32_t* material = nullptr;       // cells.local_rows
  const double* youngs_modulus = nullptr;       // cells.local_rows [Pa]
};

/// One output step's triangle surface (outer boundary + cut faces) in the DEFORMED
/// configuration, as this rank's slabs of its point and triangle tables. Its points are
/// its own (not rows of the mesh's point table): the surface is for viewing.
struct SurfaceData {
  Slab vertices;                             // rows of the step's surface point table
  const double* positions = nullptr;         // vertices.local_rows x 3, deformed [m]
  const std::int32_t* owner_cell = nullptr;  // vertices.local_rows: cell each vertex moves with
  Slab faces;                                // rows of the triangle table
  const std::int64_t* triangles = nullptr;   // faces.local_rows x 3, global 0-based vertex rows
  const std::int32_t* cut_id = nullptr;      // faces.local_rows: 0 = original boundary, k = cut k
};

/// What produced the run; stored under /input.
struct RunInfo {
  std::string deck;          // the YAML deck text, verbatim
  std::string command_line;  // argv joined with spaces
  // The discretization the fields were computed on: "hexahedra", or "composite" with the
  // composite level (the fields are still per fine point and cell, interpolated).
  std::string discretization = "hexahedra";
  std::int64_t composite_level = 0;
};

/// One row of /solver_history (one linear/nonlinear solve).
struct SolverHistoryRow {
  std::int64_t step = 0;
  double time = 0.0;  // [s]
  std::int64_t iterations = 0;
  double residual_norm = 0.0;         // true (unpreconditioned) residual 2-norm
  double relative_residual = 0.0;     // residual_norm / ||b||
  double setup_seconds = 0.0;         // preconditioner/operator setup wall time [s]
  double solve_seconds = 0.0;         // Krylov solve wall time [s]
  std::int32_t converged_reason = 0;  // PETSc KSPConvergedReason (< 0: diverged)
};

/// The current checkpoint's header.
struct CheckpointInfo {
  std::int64_t step = 0;
  double time = 0.0;
  std::int64_t num_points = 0;  // rows of the u, v, a tables
  std::int64_t link_rows = 0;   // rows of topology/links (0: none stored)
  std::int64_t link_cols = 0;   // columns of topology/links (0: 1-D)
};

/// "/steps/000042" for step 42.
std::string step_group(std::int64_t step);
/// The volume index of a result file: "<path without .h5>.xmf" ("<path>.xmf" when path
/// does not end in .h5).
std::string xdmf_path_for(const std::string& h5_path);
/// The surface index: the volume index's name with "_surface" before ".xmf"
/// ("out/run.h5" -> "out/run_surface.xmf").
std::string surface_xdmf_path_for(const std::string& h5_path);
/// Every index file write_indexes may write for `h5_path` (volume index, surface index),
/// whether or not it exists now: what to remove when the result file goes away. Pure
/// string operation.
std::vector<std::string> index_paths(const std::string& h5_path);
/// Throws std::invalid_argument (a one-line reason) when the result file's basename
/// cannot be referenced from an XDMF index: empty, not UTF-8, control characters, ':'
/// (XDMF's file/dataset separator), a leading or trailing space (readers strip it), or a
/// stem ending in "_surface" (its index would be another run's surface index).
/// doc/output-format.md, "The XDMF indexes".
void check_result_path(const std::string& h5_path);
/// (Re)writes every index of the (closed) result file `h5_path` from its content, each
/// atomically (temporary file + rename): the volume index (xdmf_path_for), listing the
/// complete steps, and the surface index (surface_xdmf_path_for), listing the complete
/// steps with a non-empty surface; when there is no such step, an existing surface index
/// is removed. NOT collective: call it on one process while no one has the file open for
/// writing. Throws std::invalid_argument when check_result_path refuses the name,
/// std::runtime_error on I/O errors.
void write_indexes(const std::string& h5_path);
/// Writes only the volume index of `h5_path` to `xmf_path` (atomically); not collective.
void write_xdmf(const std::string& h5_path, const std::string& xmf_path);

class ResultWriter {
 public:
  /// Creates the result file: writes /mesh, /input and an empty /steps into
  /// "<path>.tmp", closes it, and renames it to `path` (replacing an older file), then
  /// writes the indexes (write_indexes: a volume index with no steps; a surface index of
  /// an older run of that name is removed). `path` never names a half-written file.
  /// Throws std::invalid_argument before anything is written when check_result_path
  /// refuses the name.
  static ResultWriter create(const std::string& path, MPI_Comm comm, const MeshData& mesh,
                             const RunInfo& run);
  /// Re-opens an existing result file (restart). The current mesh is the one of the
  /// highest-numbered complete step ("/mesh" when there is none); num_points()/num_cells()
  /// are its sizes. Throws std::runtime_error for a file of another layout version.
  static ResultWriter open(const std::string& path, MPI_Comm comm);

  ResultWriter(ResultWriter&&) noexcept = default;
  ResultWriter& operator=(ResultWriter&&) noexcept = default;
  ~ResultWriter();  // closes an open step without marking it complete; does not throw

  const std::string& path() const { return path_; }
  std::string xdmf_path() const { return xdmf_path_for(path_); }
  std::string surface_xdmf_path() const { return surface_xdmf_path_for(path_); }
  /// Sizes of the current mesh (the one point/cell fields and checkpoints are checked
  /// against).
  std::int64_t num_points() const { return num_points_; }
  std::int64_t num_cells() const { return num_cells_; }
  /// Group of the current mesh: "/mesh", or "/steps/NNNNNN/mesh" of the step whose
  /// write_mesh introduced it. No I/O.
  const std::string& mesh_path() const { return mesh_path_; }
  /// Largest step number marked complete (-1: none). Cached; no I/O.
  std::int64_t last_complete_step() const { return last_complete_step_; }

  /// Opens the file and starts output step `step` at `time` [s]: creates /steps/NNNNNN
  /// (replacing an existing group of that number) with complete = 0 and mesh = the
  /// current mesh. Replacing a group that holds a mesh (written by write_mesh) deletes
  /// that mesh: when it was current, the current mesh falls back to the one of the
  /// highest-numbered other complete step (call write_mesh again if the topology is still
  /// the new one); when another complete step uses it, std::logic_error is thrown before
  /// anything changes (truncate_steps_after first).
  void begin_step(std::int64_t step, double time);
  /// Writes a new mesh (the topology changed, e.g. cuts split vertex copies) into the
  /// open step as /steps/NNNNNN/mesh, with the same datasets and attributes as /mesh, and
  /// makes it current: the step (and every later step) records it in its `mesh`
  /// attribute, and num_points()/num_cells(), the point/cell fields and the checkpoints
  /// follow its sizes. Must come before the step's point/cell fields (std::logic_error
  /// otherwise). Cell connectivity outside [0, mesh.points.global_rows) is rejected.
  void write_mesh(std::int64_t step, const MeshData& mesh);
  /// Writes the triangle surface of the open step under /steps/NNNNNN/surface (replacing
  /// one written before in this step). Triangles must index [0, vertices.global_rows),
  /// owner_cell [0, num_cells()) of the current mesh (so after write_mesh when the step
  /// has both), cut_id must be >= 0. A step without a call has no surface.
  void write_surface(std::int64_t step, const SurfaceData& surface);
  /// Writes a point field (global rows = num_points() of the current mesh; the ranks'
  /// slabs must add up to it) of the open step. cols == 1 stores a 1-D dataset. `step`
  /// must be the open step; "mesh" and "surface" are not field names, and a name must be
  /// UTF-8 without control characters or ':' (the XDMF index carries it). `unit` is
  /// stored as an attribute.
  void write_point_field(std::int64_t step, const std::string& name, int cols,
                         std::int64_t row_offset, std::int64_t local_rows, const double* data,
                         const std::string& unit = "");
  /// As write_point_field, for a cell field (global rows = num_cells()).
  void write_cell_field(std::int64_t step, const std::string& name, int cols,
                        std::int64_t row_offset, std::int64_t local_rows, const double* data,
                        const std::string& unit = "");
  /// A small table of the step that is not a mesh field (e.g. the compare summary):
  /// `rows` x `cols` doubles, row-major, the same on every rank (rank 0's are written), with
  /// string attributes `columns` (the column names, comma-separated) and `rows` (one name
  /// per row, newline-separated), and centering "none" (the XDMF index leaves it out).
  void write_step_table(std::int64_t step, const std::string& name, std::int64_t rows, int cols,
                        const std::vector<double>& data, const std::string& columns,
                        const std::vector<std::string>& row_names);
  /// Marks the open step complete, updates /steps@last_complete_step, flushes and closes
  /// the file, then rank 0 rewrites the XDMF indexes.
  void end_step();
  bool step_open() const { return step_open_; }

  /// Appends one row to /solver_history. All ranks pass identical values. Works inside
  /// or outside an open step (outside: opens and closes the file).
  void append_solve(const SolverHistoryRow& record);

  /// Writes a checkpoint: u, v, a (num_points() x 3 each, the current mesh's point
  /// count; this rank's rows [point_offset, point_offset + local_points); the ranks' rows
  /// must add up to num_points()) and an opaque int32 table topology/links
  /// (links.global_rows x link_cols, link_cols == 0: 1-D; skipped when
  /// links.global_rows == 0). Written into the inactive one of two slots, which becomes
  /// current only after its data is flushed, so the previous checkpoint survives a kill.
  void write_checkpoint(std::int64_t step, double time, std::int64_t point_offset,
                        std::int64_t local_points, const double* u, const double* v,
                        const double* a, const Slab& links = {}, int link_cols = 0,
                        const std::int32_t* link_data = nullptr);
  /// As above with an explicit point count (points.global_rows rows): for a checkpoint
  /// taken after the topology changed but before the next output step wrote its mesh.
  void write_checkpoint(std::int64_t step, double time, const Slab& points, const double* u,
                        const double* v, const double* a, const Slab& links = {}, int link_cols = 0,
                        const std::int32_t* link_data = nullptr);
  /// Header of the current checkpoint, or nullopt when there is none.
  std::optional<CheckpointInfo> checkpoint_info();
  /// Reads this rank's slabs of the current checkpoint (throws when there is none).
  /// The links are read when any rank passes link_data or local_link_rows > 0.
  CheckpointInfo read_checkpoint(std::int64_t point_offset, std::int64_t local_points, double* u,
                                 double* v, double* a, std::int64_t link_offset = 0,
                                 std::int64_t local_link_rows = 0,
                                 std::int32_t* link_data = nullptr);

  /// Restart: deletes every /steps group numbered > step and the /solver_history rows
  /// with step > step, updates last_complete_step and rewrites the XDMF indexes. The
  /// current mesh becomes the one of the highest-numbered remaining complete step
  /// ("/mesh" when none), so dropping the step that introduced a mesh returns to the
  /// previous one.
  void truncate_steps_after(std::int64_t step);
  /// Rewrites every XDMF index (write_indexes on rank 0; collective so all ranks see
  /// errors).
  void rewrite_xdmf();

 private:
  ResultWriter(std::string path, MPI_Comm comm) : path_(std::move(path)), comm_(comm) {}
  void open_file();
  void close_file();
  void write_field(std::int64_t step, const std::string& name, const char* centering,
                   std::int64_t global_rows, int cols, std::int64_t row_offset,
                   std::int64_t local_rows, const double* data, const std::string& unit);
  void append_solve_open(const SolverHistoryRow& record);
  void require_open_step(std::int64_t step, const std::string& what) const;
  /// Makes the mesh group `mesh` of `f` current: reads its sizes.
  void use_mesh(H5File& f, const std::string& mesh);

  std::string path_;
  MPI_Comm comm_ = MPI_COMM_NULL;
  H5File file_;
  std::int64_t num_points_ = 0;
  std::int64_t num_cells_ = 0;
  std::string mesh_path_ = "/mesh";
  std::int64_t last_complete_step_ = -1;
  bool step_open_ = false;
  bool step_has_fields_ = false;  // a point/cell field was written in the open step
  std::int64_t open_step_ = -1;
};

}  // namespace hexcut::output
