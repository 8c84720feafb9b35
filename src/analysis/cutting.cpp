#include "analysis/cutting.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/SVD>
#include <algorithm>
#include <array>
#include <cstdio>

#include "analysis/events.hpp"
#include "assembly/operator.hpp"
#include "common/mpi_gather.hpp"
#include "cut/link_cut.hpp"
#include "topology/union_find.hpp"

namespace hexcut::analysis {

Cutter::Cutter(const deck::Deck& deck, const lattice::Lattice& lattice)
    : events_(cut::cut_schedule(deck.cuts)) {
  if (!events_.empty()) tree_ = std::make_unique<cut::CellTree>(lattice);
}

void Cutter::skip_due(double t) {
  while (next_ < events_.size() && events_[next_].time <= t + 1e-12 * (std::abs(t) + 1.0)) ++next_;
}

PetscErrorCode Cutter::cut_due(MPI_Comm comm, double t, Model& model, Vec u, CutReport* report) {
  PetscFunctionBeginUser;
  CutReport& r = *report;
  r = CutReport{};
  const double due = t + 1e-12 * (std::abs(t) + 1.0);  // round-off in accumulated step times
  if (next_ >= events_.size() || events_[next_].time > due) PetscFunctionReturn(0);
  EventScope scope(events().cut_links);
  std::vector<Eigen::Vector3d> centres;
  PetscCall(deformed_cell_centres(comm, model, u, &centres));
  tree_->refit(model.lattice, centres);
  // Every rank holds the whole lattice and all centres and runs the same deterministic
  // search, so the links stay identical everywhere without exchanging hits.
  for (; next_ < events_.size() && events_[next_].time <= due; ++next_) {
    const auto& e = events_[next_];
    const auto links =
        cut::find_crossed_links(model.lattice, *tree_, centres, e.triangles, e.cut_id);
    cut::cut_links(model.lattice, links);
    r.links += std::int64_t(links.size());
    ++r.events;
  }
  PetscFunctionReturn(0);
}

PetscErrorCode deformed_cell_centres(MPI_Comm comm, const Model& M, Vec u,
                                     std::vector<Eigen::Vector3d>* out) {
  PetscFunctionBeginUser;
  const auto& L = M.lattice;
  const auto& D = M.layout;
  auto& centres = *out;
  centres.resize(L.num_cells());
  for (std::int32_t c = 0; c < L.num_cells(); ++c)
    centres[c] = L.spec.cell_centre(L.ijk[c][0], L.ijk[c][1], L.ijk[c][2]);
  if (!u) PetscFunctionReturn(0);
  // Each rank moves its own cells, then all ranks exchange the displacements.
  std::vector<std::array<double, 3>> mine(D.cells.size(), {0.0, 0.0, 0.0});
  {
    assembly::LocalValues ul;
    PetscCall(ul.get(M.dm, u));
    const PetscScalar* a = ul.data();
    for (std::size_t e = 0; e < D.cells.size(); ++e)
      for (int q = 0; q < 8; ++q)
        for (int d = 0; d < 3; ++d) mine[e][d] += 0.125 * a[3 * D.cell_corners[e][q] + d];
  }
  const auto ids = allgather(comm, D.cells);
  const auto disp = allgather(comm, mine);
  for (std::size_t k = 0; k < ids.size(); ++k) centres[ids[k]] += Eigen::Vector3d(disp[k].data());
  PetscFunctionReturn(0);
}

PetscErrorCode rebuild_after_cut(MPI_Comm comm, const deck::Deck& deck, Model* M, State* s) {
  PetscFunctionBeginUser;
  // Keep what the state is expressed in: the old copies, layout and DM.
  const topology::VertexCopies old_copies = std::move(M->copies);
  const topology::DofLayout old_layout = std::move(M->layout);
  DM old_dm = M->dm;
  M->dm = nullptr;
  PetscCall(VecDestroy(&M->coordinates));
  PetscCall(rebuild_topology(comm, deck, M));
  // Each new owned copy takes the values of the old copy at the same corner of its
  // lowest-numbered cell (the copies that a cut splits start from the value they had). The
  // old copy may be on another rank when the cut re-partitioned: one scatter moves them.
  std::vector<PetscInt> old_block(std::size_t(M->layout.num_owned));
  for (std::int32_t i = 0; i < M->layout.num_owned; ++i) {
    const auto copy = M->layout.copies[i];
    const auto cell = M->copies.first_cell[copy];
    int q = 0;
    while (M->copies.cell_corners[cell][q] != copy) ++q;
    old_block[std::size_t(i)] = old_layout.global_block[old_copies.cell_corners[cell][q]];
  }
  State fresh;
  PetscCall(create_state(M->dm, &fresh));
  IS from_old;
  VecScatter move;
  PetscCall(ISCreateBlock(comm, 3, PetscInt(old_block.size()), old_block.data(), PETSC_USE_POINTER,
                          &from_old));
  PetscCall(VecScatterCreate(s->u, from_old, fresh.u, nullptr, &move));
  for (auto [from, to] :
       {std::pair{s->u, fresh.u}, std::pair{s->v, fresh.v}, std::pair{s->a, fresh.a}}) {
    PetscCall(VecScatterBegin(move, from, to, INSERT_VALUES, SCATTER_FORWARD));
    PetscCall(VecScatterEnd(move, from, to, INSERT_VALUES, SCATTER_FORWARD));
  }
  PetscCall(VecScatterDestroy(&move));
  PetscCall(ISDestroy(&from_old));
  fresh.time = s->time;
  fresh.step = s->step;
  PetscCall(destroy_state(s));
  *s = fresh;
  PetscCall(DMDestroy(&old_dm));
  PetscFunctionReturn(0);
}

PetscErrorCode apply_due_cuts(MPI_Comm comm, const deck::Deck& deck, Cutter& cutter, double t,
                              Model* M, State* s, CutReport* report,
                              const std::function<PetscErrorCode()>& follow_topology) {
  PetscFunctionBeginUser;
  CutReport r;
  PetscCall(cutter.cut_due(comm, t, *M, s->u, &r));
  if (r.links > 0) {
    EventScope scope(events().rebuild);
    const int before = M->repartitions;
    PetscCall(rebuild_after_cut(comm, deck, M, s));
    r.repartitioned = M->repartitions > before;
    if (follow_topology) PetscCall(follow_topology());
  }
  if (report) *report = r;
  PetscFunctionReturn(0);
}

PetscErrorCode restore_cuts(MPI_Comm comm, const deck::Deck& deck,
                            const std::vector<lattice::CutLink>& links, Model* M) {
  PetscFunctionBeginUser;
  cut::cut_links(M->lattice, links);
  PetscCall(DMDestroy(&M->dm));
  PetscCall(VecDestroy(&M->coordinates));
  PetscCall(rebuild_topology(comm, deck, M));
  PetscFunctionReturn(0);
}

std::vector<Piece> find_pieces(MPI_Comm comm, const Model& M) {
  const auto& L = M.lattice;
  auto root = topology::make_union_find(L.num_cells());
  for (std::int32_t c = 0; c < L.num_cells(); ++c)
    for (int d = 0; d < 3; ++d) {
      if (!L.linked(c, d)) continue;
      const auto nb = L.neighbour(c, d);
      if (nb >= 0) topology::unite(root, c, nb);
    }
  std::vector<int> piece_of_root(L.num_cells(), -1);
  std::vector<Piece> pieces;
  std::vector<int> piece(L.num_cells());
  for (std::int32_t c = 0; c < L.num_cells(); ++c) {
    const auto r = topology::find_root(root, c);
    if (piece_of_root[r] < 0) {
      piece_of_root[r] = int(pieces.size());
      pieces.push_back({int(pieces.size()) + 1, 0, {}, false, {}});
    }
    auto& p = pieces[piece_of_root[r]];
    piece[c] = piece_of_root[r];
    ++p.cells;
    const auto& ijk = L.ijk[c];
    p.box.extend(L.spec.vertex_position(ijk[0], ijk[1], ijk[2]));
    p.box.extend(L.spec.vertex_position(ijk[0] + 1, ijk[1] + 1, ijk[2] + 1));
  }
  // Supports: a prescribed DOF of one of the piece's copies (rows are owned here) holds
  // the rigid motions in which it moves. Per piece, G = sum over its prescribed DOFs of
  // r r^T, r the DOF's row of the six rigid modes (translations; rotations about the
  // box centre, scaled by the box's half diagonal so all entries are <= 1): the modes
  // in G's null space move no prescribed DOF.
  const std::size_t np = pieces.size();
  std::vector<double> gram(36 * np, 0.0);
  const PetscInt first = 3 * M.layout.first_owned_block();
  for (PetscInt row : M.boundary.constraints.rows) {
    const auto copy = M.layout.copies[(row - first) / 3];
    const int d = int((row - first) % 3);
    const auto k = std::size_t(piece[M.copies.first_cell[copy]]);
    const auto& v = M.copies.vertex[copy];
    const auto& box = pieces[k].box;
    const double scale = std::max(0.5 * box.diagonal().norm(), 1e-300);
    const Eigen::Vector3d x = (L.spec.vertex_position(v[0], v[1], v[2]) - box.center()) / scale;
    Eigen::Matrix<double, 6, 1> r = Eigen::Matrix<double, 6, 1>::Zero();
    r[d] = 1.0;
    for (int a = 0; a < 3; ++a) r[3 + a] = Eigen::Vector3d::Unit(a).cross(x)[d];
    Eigen::Map<Eigen::Matrix<double, 6, 6>>(&gram[36 * k]) += r * r.transpose();
  }
  MPI_Allreduce(MPI_IN_PLACE, gram.data(), int(gram.size()), MPI_DOUBLE, MPI_SUM, comm);
  for (std::size_t k = 0; k < np; ++k) {
    const Eigen::Map<const Eigen::Matrix<double, 6, 6>> G(&gram[36 * k]);
    pieces[k].supported = G.trace() > 0;
    pieces[k].free_modes = free_rigid_modes(G, pieces[k].box);
  }
  return pieces;
}

std::string free_rigid_modes(const Eigen::Matrix<double, 6, 6>& G, const Eigen::AlignedBox3d& box) {
  // Null space of G: eigenvalues below a relative 1e-10. Partial supports give exact
  // zeros (1e-16 in floating point); weak but real holds (two fixed vertices h apart on
  // a piece of size 10^3 h) give (h/L)^2 = 1e-6.
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 6, 6>> eig(G);
  const double tol = 1e-10 * std::max(1.0, eig.eigenvalues().maxCoeff());
  Eigen::Matrix<double, 6, Eigen::Dynamic> N(6, 0);
  for (int i = 0; i < 6; ++i)
    if (eig.eigenvalues()[i] <= tol) {
      N.conservativeResize(6, N.cols() + 1);
      N.col(N.cols() - 1) = eig.eigenvectors().col(i);
    }
  if (N.cols() == 0) return "";
  // Name the free modes along the axes (translation x; rotation about the z axis through
  // the box centre) first, then describe what remains of the null space.
  const char* axis = "xyz";
  std::string translations, rotations;
  Eigen::Matrix<double, 6, Eigen::Dynamic> named(6, 0);
  for (int i = 0; i < 6; ++i) {
    const Eigen::Matrix<double, 6, 1> e = Eigen::Matrix<double, 6, 1>::Unit(i);
    if ((N.transpose() * e).squaredNorm() < 1.0 - 1e-8) continue;
    auto& list = i < 3 ? translations : rotations;
    list += std::string(list.empty() ? "" : ", ") + axis[i % 3];
    named.conservativeResize(6, named.cols() + 1);
    named.col(named.cols() - 1) = e;
  }
  std::string out;
  if (!translations.empty()) out += "translation " + translations;
  if (!rotations.empty()) {
    // With both perpendicular translations free, any parallel axis is free too.
    bool any_axis = true;
    for (char r : rotations)
      for (char t : std::string("xyz"))
        if (r != ',' && r != ' ' && t != r && translations.find(t) == std::string::npos)
          any_axis = false;
    char buf[128];
    std::snprintf(buf, sizeof buf, " (axes through (%g, %g, %g))", box.center().x(),
                  box.center().y(), box.center().z());
    out += (out.empty() ? "" : "; ") + std::string("rotation about ") + rotations +
           (any_axis ? "" : buf);
  }
  // The rest: N minus its projection on the named modes, orthonormalized.
  Eigen::Matrix<double, 6, Eigen::Dynamic> rest = N - named * (named.transpose() * N);
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(rest, Eigen::ComputeThinU);
  const double scale = std::max(0.5 * box.diagonal().norm(), 1e-300);
  for (int j = 0; j < int(svd.singularValues().size()); ++j) {
    if (svd.singularValues()[j] < 1e-6) continue;
    const Eigen::Matrix<double, 6, 1> m = svd.matrixU().col(j);
    // Displacement t + w x (p - c)/scale: a rotation about the axis through
    // c + scale (w x t)/|w|^2 along w, or a translation along t when w = 0.
    const Eigen::Vector3d t = m.head<3>(), w = m.tail<3>();
    // Directions with their largest component positive; +0.0 prints -0 as 0.
    auto oriented = [](Eigen::Vector3d a) {
      Eigen::Index i;
      a.cwiseAbs().maxCoeff(&i);
      return Eigen::Vector3d((a[i] < 0 ? -a : a).array() + 0.0);
    };
    char buf[200];
    if (w.norm() < 1e-6) {
      const Eigen::Vector3d a = oriented(t.normalized());
      std::snprintf(buf, sizeof buf, "translation along (%.3g, %.3g, %.3g)", a.x(), a.y(), a.z());
    } else {
      const Eigen::Vector3d a = oriented(w.normalized());
      const Eigen::Vector3d p = (box.center() + scale * w.cross(t) / w.squaredNorm()).array() + 0.0;
      std::snprintf(buf, sizeof buf,
                    "rotation about the axis through (%.4g, %.4g, %.4g) along (%.3g, %.3g, %.3g)",
                    p.x(), p.y(), p.z(), a.x(), a.y(), a.z());
    }
    out += (out.empty() ? "" : "; ") + std::string(buf);
  }
  return out;
}

std::string describe(const Piece& p) {
  char buf[256];
  const auto& a = p.box.min();
  const auto& b = p.box.max();
  std::snprintf(buf, sizeof buf, "piece %d: %lld cells, box [%g, %g, %g] - [%g, %g, %g] m, %s",
                p.id, (long long)p.cells, a.x(), a.y(), a.z(), b.x(), b.y(), b.z(),
                p.supported ? "supported" : "unsupported");
  std::string out = buf;
  if (p.supported && !p.free_modes.empty()) out += "; free: " + p.free_modes;
  return out;
}

PetscErrorCode require_supported(MPI_Comm comm, const std::vector<Piece>& pieces) {
  PetscFunctionBeginUser;
  std::string msg =
      "static analysis with a piece its supports do not hold (it can move rigidly, so its "
      "stiffness is singular; add supports in boundary.fixed, or run a dynamic "
      "analysis):";
  // PETSc keeps the first 1023 characters of an error's message: the pieces past that are
  // counted, not cut off in the middle of a line.
  constexpr std::size_t kMaxMessage = 960;
  int free = 0, unlisted = 0;
  for (const auto& p : pieces) {
    if (p.free_modes.empty()) continue;
    ++free;
    const std::string line = "\n  " + describe(p);
    if (unlisted == 0 && msg.size() + line.size() <= kMaxMessage)
      msg += line;
    else
      ++unlisted;
  }
  if (unlisted > 0) msg += "\n  ... and " + std::to_string(unlisted) + " more such piece(s)";
  if (free > 0) SETERRQ(comm, PETSC_ERR_NOT_CONVERGED, "%s", msg.c_str());
  PetscFunctionReturn(0);
}

}  // namespace hexcut::analysis
