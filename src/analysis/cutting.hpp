// Cuts during a run (doc/theory.md, "Cutting", "Pipeline": a cut event changes the lattice links
// and then rebuilds the topology): the deck's cut events are applied in the current deformed
// configuration, then vertex copies, DOF layout, DM, cell and boundary data are rebuilt and the
// state (u, v, a) is carried from each old vertex copy to the new copies it split into, so no state
// is lost and momentum is unchanged. Also the pieces (connected components) of the body and whether
// each is supported.
#pragma once

#include <Eigen/Geometry>
#include <functional>
#include <memory>

#include "analysis/model.hpp"
#include "analysis/result_output.hpp"
#include "cut/blade.hpp"
#include "cut/cell_tree.hpp"

namespace hexcut::analysis {

/// What one application of due cut events did (identical on every rank).
struct CutReport {
  int events = 0;              // cut events applied
  std::int64_t links = 0;      // links disconnected
  bool repartitioned = false;  // the rebuild re-partitioned (Model::repartition_imbalance)
};

/// The deck's cut events and the tree that finds the links they cross.
class Cutter {
 public:
  Cutter(const deck::Deck& deck, const lattice::Lattice& lattice);
  bool pending() const { return next_ < events_.size(); }
  /// Time of the next event (pending() must be true).
  double next_time() const { return events_[next_].time; }
  /// Applies every not yet applied event with time <= t to model.lattice's links, in the
  /// configuration of the displacement u (global vector of the model's DM; null =
  /// reference configuration), and says what it did in `report`. Collective. Topology is
  /// NOT rebuilt: call rebuild_after_cut when report->links > 0.
  PetscErrorCode cut_due(MPI_Comm comm, double t, Model& model, Vec u, CutReport* report);
  /// Skips (without cutting) the events with time <= t (restart bookkeeping).
  void skip_due(double t);

 private:
  std::vector<cut::CutEvent> events_;
  std::size_t next_ = 0;
  std::unique_ptr<cut::CellTree> tree_;
};

/// Cell centres of every cell (all ranks get all of them), moved by the mean of their
/// corners' displacement u (null: reference). Collective.
PetscErrorCode deformed_cell_centres(MPI_Comm comm, const Model& model, Vec u,
                                     std::vector<Eigen::Vector3d>* centres);

/// Rebuilds the model's topology after its links changed (the cells keep their ranks unless
/// Model::repartition_imbalance re-partitions them)
/// and carries the state over: every new vertex copy takes u, v, a of the old copy it
/// came from. Collective.
PetscErrorCode rebuild_after_cut(MPI_Comm comm, const deck::Deck& deck, Model* model, State* state);

/// Cutter::cut_due in the configuration of state->u, then, when links were cut
/// (report->links > 0), rebuild_after_cut and `follow_topology`, which rebuilds what
/// depends on the DM (the Simulation, ResultOutput::topology_changed). Both run inside
/// one hexcutRebuild event, logged once per cut. `report` may be null. Collective.
PetscErrorCode apply_due_cuts(MPI_Comm comm, const deck::Deck& deck, Cutter& cutter, double t,
                              Model* model, State* state, CutReport* report = nullptr,
                              const std::function<PetscErrorCode()>& follow_topology = {});

/// Restart: applies cut links read from a checkpoint (in their cutting order) to the
/// uncut model and rebuilds its topology; the model's DM is replaced, so create the state
/// afterwards. Collective.
PetscErrorCode restore_cuts(MPI_Comm comm, const deck::Deck& deck,
                            const std::vector<lattice::CutLink>& links, Model* model);

/// A connected component of the body (cells joined by links).
struct Piece {
  int id = 0;  // 1-based, in order of the lowest cell
  std::int64_t cells = 0;
  Eigen::AlignedBox3d box;  // reference bounding box [m]
  bool supported = false;   // some DOF of it is prescribed
  /// The rigid-body motions its prescribed DOFs leave free (doc/theory.md, "Pieces"),
  /// e.g. "translation x, y; rotation about z"; empty when they hold all six.
  std::string free_modes;
};
/// The pieces of the body and the rigid motions their supports leave free. Collective
/// (supports are known per rank).
std::vector<Piece> find_pieces(MPI_Comm comm, const Model& model);
/// The rigid motions a piece's supports leave free, from G = sum r r^T over its
/// prescribed DOFs (r: the DOF's row of the six rigid modes, translations and rotations
/// about the box centre scaled by the box's half diagonal): "translation x, y; rotation
/// about z (axes through (...))", then any other free motion as a rotation about an axis
/// or a translation along a direction; empty when G has full rank.
std::string free_rigid_modes(const Eigen::Matrix<double, 6, 6>& G, const Eigen::AlignedBox3d& box);
/// "piece 2: 640 cells, box [0.1, 0, 0] - [0.5, 0.1, 0.1] m, unsupported", or
/// "..., supported; free: translation x, y; rotation about z".
std::string describe(const Piece& p);
/// PETSC_ERR_NOT_CONVERGED (a solver failure, exit 3) on `comm` naming every piece whose
/// supports leave a rigid motion free (a static stiffness is then singular: solvers return
/// huge or arbitrary displacements); past what PETSc keeps of a message, the rest are
/// counted. The pieces are those of find_pieces on `comm`.
PetscErrorCode require_supported(MPI_Comm comm, const std::vector<Piece>& pieces);

}  // namespace hexcut::analysis
