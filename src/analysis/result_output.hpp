// Glue between the solver's PETSc-ordered vectors and the result file's canonical,
// rank-independent tables (doc/output-format.md): natural-order scatters, the mesh
// tables, per-step fields (displacement, velocity, acceleration, stress and its derived
// fields), solver history and checkpoints.
#pragma once

#include <petscvec.h>

#include <map>
#include <memory>
#include <string>

#include "analysis/model.hpp"
#include "analysis/reference_state.hpp"
#include "analysis/state.hpp"
#include "output/result_writer.hpp"
#include "solve/linear_solver.hpp"
#include "surface/surface.hpp"

namespace hexcut::analysis {

/// Stress of the local cells from the global displacement (ghosts exchanged through the DM).
/// Corotational runs use each cell's own rotation (doc/theory.md, "Stress"). Only the
/// tensor is kept: the derived fields (von Mises, pressure, principal values and
/// directions) are element::stress_fields(sigma), computed per dataset as it is written,
/// which holds 7 doubles per cell instead of 21 at the output's peak.
struct CellStressFields {
  std::vector<double> sigma;           // 6 per cell [Pa]: sigma0 + sigma(u), ParaView order
  std::vector<double> energy_density;  // 1 per cell: 1/2 sigma:epsilon [Pa]
};
PetscErrorCode compute_stress(const Model& model, bool corotational, Vec u, CellStressFields* out);

/// The members that do PETSc work return a PetscErrorCode (common/petsc_check.hpp); the
/// result file's own errors (HDF5, output::ResultWriter) and the checks of a restart
/// (InputError) are exceptions.
class ResultOutput {
 public:
  /// Creates a new result file (mesh + input written) or, with `restart`, re-opens it.
  static PetscErrorCode create(MPI_Comm comm, const Model& model, const deck::Deck& deck,
                               const std::string& path, const std::string& command_line,
                               bool restart, std::unique_ptr<ResultOutput>* out);
  ~ResultOutput();
  ResultOutput(const ResultOutput&) = delete;
  ResultOutput& operator=(const ResultOutput&) = delete;

  const std::string& path() const { return writer_.path(); }
  output::ResultWriter& writer() { return writer_; }

  /// The model's topology changed (a cut): the point tables are rebuilt, and the next
  /// written step carries the new mesh.
  PetscErrorCode topology_changed();
  /// Writes one output step with the fields the deck asks for. composite_element: per
  /// local cell the id of its composite element (field composite_element; null otherwise).
  PetscErrorCode write_step(const State& s, bool corotational,
                            const std::vector<double>* composite_element = nullptr);
  void record_solve(std::int64_t step, double time, const solve::SolveRecord& r);
  PetscErrorCode write_checkpoint(const State& s);
  /// The cut links stored with the current checkpoint (empty: none, or no checkpoint), in
  /// cutting order: restore them (restore_cuts) before read_checkpoint.
  std::vector<lattice::CutLink> checkpoint_cut_links();
  /// Reads the checkpoint into s (u, v, a, time, step); drops later steps from the file.
  /// Throws InputError when the checkpoint's point count is not the model's.
  PetscErrorCode read_checkpoint(State* s);

 private:
  ResultOutput(MPI_Comm comm, const Model& model, const deck::Deck& deck, const std::string& path,
               const std::string& command_line, bool restart);
  PetscErrorCode cell_scatter(int block, topology::NaturalScatter** scatter);
  PetscErrorCode create_scatters();
  PetscErrorCode destroy_scatters();
  PetscErrorCode write_point_vector(std::int64_t step, const std::string& name, Vec v,
                                    const std::string& unit);
  PetscErrorCode write_cell_values(std::int64_t step, const std::string& name, int block,
                                   const std::vector<double>& values, const std::string& unit);
  PetscErrorCode write_surface(const State& s);
  /// compare.reference: the difference fields of this step's stress against the reference
  /// (doc/user-guide.md, "compare"), and a summary per material on rank 0.
  PetscErrorCode write_comparison(std::int64_t step, const CellStressFields& f);
  /// Scatters x (a global vector of the model's DM, 3 per point) into points_.natural:
  /// this rank's slab of the points in canonical order.
  PetscErrorCode gather_points(Vec x);

  MPI_Comm comm_;
  const Model& model_;
  const deck::Deck& deck_;
  output::ResultWriter writer_;
  std::unique_ptr<ReferenceState> reference_;  // compare.reference, or null
  topology::NaturalScatter points_;
  std::map<int, topology::NaturalScatter> cells_;
  PetscInt first_local_cell_ = 0;  // PETSc-ordered cell offset of this rank
  bool mesh_pending_ = false;      // topology changed since the last written step
  // Surfaces (dual contouring): the boundary's Hermite data (the geometry's, fixed for
  // the run), the surface of the current topology (canonical order, on every rank), the
  // vertices whose cell is this rank's, and the scatter of their positions to the file's
  // row slabs.
  std::unique_ptr<surface::BoundaryHermite> hermite_;
  std::unique_ptr<surface::Surface> surface_;
  std::vector<std::int32_t> surface_mine_;
  topology::NaturalScatter surface_points_;
};

}  // namespace hexcut::analysis
