#include "assembly/boundary.hpp"

#include <limits>

#include "common/errors.hpp"

namespace hexcut::assembly {
namespace {

bool selects_point(const deck::Selector& s, const Eigen::Vector3d& p) {
  return !s.shape || s.shape->contains(p);
}

std::int64_t global_sum(MPI_Comm comm, std::int64_t n) {
  std::int64_t total = 0;
  MPI_Allreduce(&n, &total, 1, MPI_INT64_T, MPI_SUM, comm);
  return total;
}

/// Copies that touch a cell of the given material (all copies when material < 0).
std::vector<char> copies_of_material(const lattice::Lattice& L, const topology::VertexCopies& V,
                                     int material) {
  std::vector<char> mark(V.num_copies, material < 0);
  if (material >= 0)
    for (std::int32_t c = 0; c < L.num_cells(); ++c)
      if (L.material[c] == material)
        for (auto v : V.cell_corners[c]) mark[v] = 1;
  return mark;
}

}  // namespace

Boundary resolve_boundary(MPI_Comm comm, const deck::Deck& deck, const lattice::Lattice& L,
                          const topology::VertexCopies& V, const topology::DofLayout& D) {
  Boundary B;
  B.gravity = deck.gravity;
  B.centrifugal = deck.centrifugal;
  const PetscInt first = D.first_owned_block();
  auto position = [&](std::int32_t copy) {
    const auto& v = V.vertex[copy];
    return Eigen::Vector3d(L.spec.origin[0] + L.spec.h * v[0], L.spec.origin[1] + L.spec.h * v[1],
                           L.spec.origin[2] + L.spec.h * v[2]);
  };

  // Supports: a later support overrides an earlier one on the same DOF.
  std::vector<const deck::TimeFunction*> fixed(3 * std::size_t(D.num_owned), nullptr);
  for (const auto& s : deck.supports) {
    const auto in_material = copies_of_material(L, V, s.selector.material);
    std::int64_t hits = 0;
    for (std::int32_t i = 0; i < D.num_owned; ++i) {
      const auto copy = D.copies[i];
      if (!in_material[copy] || !selects_point(s.selector, position(copy))) continue;
      ++hits;
      for (int d = 0; d < 3; ++d)
        if (s.constrained[d]) fixed[3 * i + d] = &s.value[d];
    }
    if (global_sum(comm, hits) == 0)
      throw InputError(s.selector.where.prefix() + "this support selects no vertex of the body");
  }
  for (std::int32_t i = 0; i < 3 * D.num_owned; ++i)
    if (fixed[i]) {
      B.constraints.rows.push_back(3 * first + i);
      B.constraints.value.push_back(fixed[i]);
    }
  B.constraints.global_count = global_sum(comm, std::int64_t(B.constraints.rows.size()));

  // Traction faces: faces of local cells with no linked neighbour across them.
  for (const auto& t : deck.tractions) {
    std::int64_t hits = 0;
    for (std::size_t e = 0; e < D.cells.size(); ++e) {
      const auto c = D.cells[e];
      if (t.selector.material >= 0 && L.material[c] != t.selector.material) continue;
      const auto& p = L.ijk[c];
      for (int d = 0; d < 3; ++d)
        for (int side = 0; side < 2; ++side) {
          std::array<int, 3> q{p[0], p[1], p[2]};
          q[d] += side ? 1 : -1;
          const auto nb = L.find(q[0], q[1], q[2]);
          const bool open = side ? !(nb >= 0 && L.linked(c, d)) : !(nb >= 0 && L.linked(nb, d));
          if (!open) continue;
          Eigen::Vector3d centre = L.spec.cell_centre(p[0], p[1], p[2]);
          centre[d] += (side ? 0.5 : -0.5) * L.spec.h;
          if (!selects_point(t.selector, centre)) continue;
          Boundary::Face f{{}, &t};
          int n = 0;
          for (int qc = 0; qc < 8; ++qc)
            if (((qc >> d) & 1) == side) f.local_copies[n++] = D.cell_corners[e][qc];
          B.faces.push_back(f);
          ++hits;
        }
    }
    if (global_sum(comm, hits) == 0)
      throw InputError(t.selector.where.prefix() +
                       "this traction selects no boundary face of the body");
  }

  // Point loads: the nearest copy over all ranks (ties: lowest global index).
  for (const auto& pl : deck.point_loads) {
    struct {
      double dist;
      int rank;
    } mine{std::numeric_limits<double>::max(), D.rank}, best;
    std::int32_t best_local = -1;
    for (std::int32_t i = 0; i < D.num_owned; ++i) {
      const double dist = (position(D.copies[i]) - pl.position).norm();
      if (dist < mine.dist) {
        mine.dist = dist;
        best_local = i;
      }
    }
    MPI_Allreduce(&mine, &best, 1, MPI_DOUBLE_INT, MPI_MINLOC, comm);
    if (best.dist > L.spec.h)
      throw InputError(pl.where.prefix() +
                       "point load position is more than one cell (h) away from the body");
    if (best.rank == D.rank) B.points.push_back({3 * (first + best_local), &pl});
  }
  return B;
}

PetscErrorCode assemble_loads(DM dm, const topology::DofLayout& D, const CellData& C,
                              const Boundary& B, double t, double scale, Vec f) {
  PetscFunctionBeginUser;
  Vec fl;
  PetscCall(DMGetLocalVector(dm, &fl));
  PetscCall(VecSet(fl, 0.0));
  PetscScalar* a;
  PetscCall(VecGetArray(fl, &a));
  if (B.gravity.squaredNorm() > 0) {
    // A constant body force gives rho g h^3 / 8 at each corner, consistent or lumped.
    for (std::size_t e = 0; e < D.cells.size(); ++e) {
      const double m = scale * C.rho[e] * C.h * C.h * C.h / 8.0;
      for (int q = 0; q < 8; ++q)
        for (int d = 0; d < 3; ++d) a[3 * D.cell_corners[e][q] + d] += m * B.gravity[d];
    }
  }
  if (B.centrifugal.active) {
    // rho omega^2 r at the cell centre, lumped to the corners (one-point rule: the field
    // is linear, so this is exact for the resultant).
    const auto& cf = B.centrifugal;
    for (std::size_t e = 0; e < D.cells.size(); ++e) {
      const Eigen::Vector3d x =
          Eigen::Vector3d(C.origin[e].data()) + Eigen::Vector3d::Constant(0.5 * C.h);
      Eigen::Vector3d r = x - cf.point;
      r -= r.dot(cf.axis) * cf.axis;
      const Eigen::Vector3d f =
          (scale * C.rho[e] * cf.omega * cf.omega * C.h * C.h * C.h / 8.0) * r;
      for (int q = 0; q < 8; ++q)
        for (int d = 0; d < 3; ++d) a[3 * D.cell_corners[e][q] + d] += f[d];
    }
  }
  // A constant traction on a bilinear face gives t h^2 / 4 at each face corner.
  for (const auto& face : B.faces) {
    const Eigen::Vector3d tr =
        face.traction->value * face.traction->scale(t) * (scale * C.h * C.h / 4.0);
    for (auto v : face.local_copies)
      for (int d = 0; d < 3; ++d) a[3 * v + d] += tr[d];
  }
  PetscCall(VecRestoreArray(fl, &a));
  PetscCall(VecSet(f, 0.0));
  PetscCall(DMLocalToGlobalBegin(dm, fl, ADD_VALUES, f));
  PetscCall(DMLocalToGlobalEnd(dm, fl, ADD_VALUES, f));
  PetscCall(DMRestoreLocalVector(dm, &fl));
  for (const auto& p : B.points) {
    const Eigen::Vector3d F = p.load->force * (scale * p.load->scale(t));
    PetscInt idx[3] = {p.dof, p.dof + 1, p.dof + 2};
    PetscCall(VecSetValues(f, 3, idx, F.data(), ADD_VALUES));
  }
  PetscCall(VecAssemblyBegin(f));
  PetscCall(VecAssemblyEnd(f));
  PetscFunctionReturn(0);
}

PetscErrorCode set_prescribed_values(const Constraints& c, double t, double scale, Vec x) {
  PetscFunctionBeginUser;
  PetscScalar* a;
  PetscInt lo;
  PetscCall(VecGetOwnershipRange(x, &lo, nullptr));
  PetscCall(VecGetArray(x, &a));
  for (std::size_t i = 0; i < c.rows.size(); ++i) a[c.rows[i] - lo] = scale * (*c.value[i])(t);
  PetscCall(VecRestoreArray(x, &a));
  PetscFunctionReturn(0);
}

PetscErrorCode constrain_matrix(const Constraints& c, Mat A) {
  PetscFunctionBeginUser;
  PetscCall(MatZeroRowsColumns(A, PetscInt(c.rows.size()), c.rows.data(), 1.0, nullptr, nullptr));
  PetscFunctionReturn(0);
}

PetscErrorCode constrain_rhs(DM dm, const topology::DofLayout& D, const CellData& C,
                             const OperatorWeights& w, const Constraints& c, double t, double scale,
                             Vec b) {
  PetscFunctionBeginUser;
  Vec u0, Au0;
  PetscCall(DMGetGlobalVector(dm, &u0));
  PetscCall(DMGetGlobalVector(dm, &Au0));
  PetscCall(VecSet(u0, 0.0));
  PetscCall(set_prescribed_values(c, t, scale, u0));
  PetscCall(apply(dm, D, C, w, u0, Au0));
  PetscCall(VecAXPY(b, -1.0, Au0));
  PetscCall(set_prescribed_values(c, t, scale, b));
  PetscCall(DMRestoreGlobalVector(dm, &u0));
  PetscCall(DMRestoreGlobalVector(dm, &Au0));
  PetscFunctionReturn(0);
}

}  // namespace hexcut::assembly
