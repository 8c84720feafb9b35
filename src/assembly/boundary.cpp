#include "assembly/boundary.hpp"

#include <climits>
#include <cmath>
#include <cstdio>
#include <limits>

#include "assembly/field_values.hpp"
#include "assembly/fine_cells.hpp"
#include "common/errors.hpp"
#include "common/mpi_gather.hpp"
#include "deck/expression.hpp"

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

bool uses_expressions(const std::array<deck::Field, 3>& v) {
  return v[0].expression || v[1].expression || v[2].expression;
}

/// How a face's load is evaluated (Boundary::Face::Kind).
Boundary::Face::Kind face_kind(const Boundary::Face& f) {
  using Kind = Boundary::Face::Kind;
  if (f.traction) {
    const auto& v = f.traction->value;
    if (!uses_expressions(v)) return Kind::uniform;
    for (const auto& c : v)
      if (c.depends_on_time()) return Kind::varying;
    return Kind::fixed_in_time;
  }
  const auto& p = f.pressure->value;
  if (!p.expression) return Kind::uniform;
  return p.depends_on_time() ? Kind::varying : Kind::fixed_in_time;
}

/// Load per reference area at x, time t [Pa], without the `scale` time function.
Eigen::Vector3d face_load_density(const Boundary::Face& f, const Eigen::Vector3d& x, double t,
                                  std::string& bad) {
  if (f.traction) {
    const auto& v = f.traction->value;
    return {evaluate(v[0], x, t, bad), evaluate(v[1], x, t, bad), evaluate(v[2], x, t, bad)};
  }
  Eigen::Vector3d n = Eigen::Vector3d::Zero();
  n[f.axis] = f.side ? 1.0 : -1.0;
  return -evaluate(f.pressure->value, x, t, bad) * n;
}

/// The boundary faces of local cells that `selector` selects (by face centre): faces with
/// no linked neighbour across them, so after a cut also the cut faces. `add(face)` gets
/// each with its corners and geometry set; returns how many there were.
template <class Add>
std::int64_t select_faces(const lattice::Lattice& L, const topology::DofLayout& D,
                          const deck::Selector& selector, Add add) {
  std::int64_t hits = 0;
  for (std::size_t e = 0; e < D.cells.size(); ++e) {
    const auto c = D.cells[e];
    if (selector.material >= 0 && L.material[c] != selector.material) continue;
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
        if (!selects_point(selector, centre)) continue;
        Boundary::Face f;
        int n = 0;
        for (int qc = 0; qc < 8; ++qc)
          if (((qc >> d) & 1) == side) f.local_copies[n++] = D.cell_corners[e][qc];
        f.axis = d;
        f.side = side;
        f.origin = L.spec.vertex_position(p[0], p[1], p[2]);
        f.origin[d] += side * L.spec.h;
        add(f);
        ++hits;
      }
  }
  return hits;
}

}  // namespace

std::array<Eigen::Vector3d, 4> consistent_face_loads(const Boundary::Face& f, double h, double t,
                                                     std::string& bad) {
  // Gauss points of [0, 1] (±1/√3 on [-1, 1]), weight h²/4 each.
  const double g[2] = {0.5 - 0.5 / std::sqrt(3.0), 0.5 + 0.5 / std::sqrt(3.0)};
  const int a = f.axis == 0 ? 1 : 0, b = f.axis == 2 ? 1 : 2;
  std::array<Eigen::Vector3d, 4> nodal;
  for (auto& v : nodal) v.setZero();
  for (int i = 0; i < 2; ++i)
    for (int j = 0; j < 2; ++j) {
      Eigen::Vector3d x = f.origin;
      x[a] += h * g[i];
      x[b] += h * g[j];
      const Eigen::Vector3d w = face_load_density(f, x, t, bad) * (h * h / 4.0);
      for (int n = 0; n < 4; ++n) {
        const double N = ((n & 1) ? g[i] : 1.0 - g[i]) * ((n >> 1) ? g[j] : 1.0 - g[j]);
        nodal[n] += N * w;
      }
    }
  return nodal;
}

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
  std::vector<const deck::Field*> fixed(3 * std::size_t(D.num_owned), nullptr);
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
    B.constraints.expressions = B.constraints.expressions || uses_expressions(s.value);
  }
  auto& C = B.constraints;
  for (std::int32_t i = 0; i < 3 * D.num_owned; ++i)
    if (fixed[i]) {
      C.rows.push_back(3 * first + i);
      C.value.push_back(fixed[i]);
      C.position.push_back(position(D.copies[i / 3]));
    }
  C.global_count = global_sum(comm, std::int64_t(C.rows.size()));
  // Static analyses use their values at t = 1 only (doc/user-guide.md "Time functions"),
  // so every expression is checked now, before any heavy work; dynamic ones check the
  // expressions of t where they are used.
  const bool static_ = deck.analysis.type == deck::Analysis::Type::static_;
  const double t_check = static_ ? 1.0 : 0.0;
  if (C.expressions) {
    std::string bad;
    for (std::size_t r = 0; r < C.rows.size(); ++r)
      if (C.value[r]->expression && (static_ || !C.value[r]->depends_on_time()))
        evaluate(*C.value[r], C.position[r], t_check, bad);
    throw_if_not_finite(comm, bad);
  }

  // Loaded faces: boundary faces of local cells (no linked neighbour across them).
  for (const auto& t : deck.tractions) {
    const std::size_t begin = B.faces.size();
    const auto hits = select_faces(L, D, t.selector, [&](Boundary::Face f) {
      f.traction = &t;
      B.faces.push_back(f);
    });
    const auto all = global_sum(comm, hits);
    if (all == 0)
      throw InputError(t.selector.where.prefix() +
                       "this traction selects no boundary face of the body");
    // A total force is spread over the selected faces' reference area: F / (n h^2).
    const Eigen::Vector3d density =
        t.force ? Eigen::Vector3d(*t.force / (double(all) * L.spec.h * L.spec.h))
                : Eigen::Vector3d(t.value[0].function.value, t.value[1].function.value,
                                  t.value[2].function.value);
    for (std::size_t i = begin; i < B.faces.size(); ++i) B.faces[i].density = density;
    B.face_expressions = B.face_expressions || uses_expressions(t.value);
  }
  for (const auto& p : deck.pressures) {
    const auto hits = select_faces(L, D, p.selector, [&](Boundary::Face f) {
      f.pressure = &p;
      f.density[f.axis] = f.side ? -p.value.function.value : p.value.function.value;
      B.faces.push_back(f);
    });
    if (global_sum(comm, hits) == 0)
      throw InputError(p.selector.where.prefix() +
                       "this pressure selects no boundary face of the body");
    B.face_expressions = B.face_expressions || p.value.expression;
  }
  if (B.face_expressions) {
    // Expressions without t are integrated once here; those with t of static analyses
    // are checked at t = 1.
    std::string bad;
    for (auto& f : B.faces) {
      f.kind = face_kind(f);
      if (f.kind == Boundary::Face::Kind::fixed_in_time)
        f.nodal = consistent_face_loads(f, L.spec.h, 0.0, bad);
      else if (static_ && f.kind == Boundary::Face::Kind::varying)
        consistent_face_loads(f, L.spec.h, t_check, bad);
    }
    throw_if_not_finite(comm, bad);
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
  using Kind = Boundary::Face::Kind;
  // Faces whose expressions vary in time are integrated first, so that a non-finite value
  // throws before any vector is borrowed.
  std::vector<std::array<Eigen::Vector3d, 4>> varying;
  if (B.face_expressions) {
    std::string bad;
    for (const auto& face : B.faces)
      if (face.kind == Kind::varying) varying.push_back(consistent_face_loads(face, C.h, t, bad));
    throw_if_not_finite(PetscObjectComm((PetscObject)dm), bad);
  }
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
  for (std::size_t i = 0; i < B.initial_stress_load.size(); ++i)
    a[i] += scale * B.initial_stress_load[i];
  std::size_t next_varying = 0;
  for (const auto& face : B.faces) {
    const double tf = face.traction ? face.traction->scale(t) : face.pressure->scale(t);
    std::array<Eigen::Vector3d, 4> load;
    if (face.kind == Kind::uniform) {
      // A constant traction on a bilinear face gives t h^2 / 4 at each face corner.
      load.fill(face.density * tf * (scale * C.h * C.h / 4.0));
    } else {
      load = face.kind == Kind::fixed_in_time ? face.nodal : varying[next_varying++];
      for (auto& v : load) v *= tf * scale;
    }
    for (int n = 0; n < 4; ++n)
      for (int d = 0; d < 3; ++d) a[3 * face.local_copies[n] + d] += load[n][d];
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

namespace {

/// scale * the prescribed value of every row at time t; throws InputError on every rank
/// when an expression is not finite somewhere (collective).
std::vector<double> prescribed_values(MPI_Comm comm, const Constraints& c, double t, double scale) {
  std::vector<double> values(c.rows.size());
  std::string bad;
  for (std::size_t i = 0; i < c.rows.size(); ++i)
    values[i] = scale * evaluate(*c.value[i], c.position[i], t, bad);
  if (c.expressions) throw_if_not_finite(comm, bad);
  return values;
}

PetscErrorCode insert_rows(const Constraints& c, const std::vector<double>& values, Vec x) {
  PetscFunctionBeginUser;
  PetscScalar* a;
  PetscInt lo;
  PetscCall(VecGetOwnershipRange(x, &lo, nullptr));
  PetscCall(VecGetArray(x, &a));
  for (std::size_t i = 0; i < c.rows.size(); ++i) a[c.rows[i] - lo] = values[i];
  PetscCall(VecRestoreArray(x, &a));
  PetscFunctionReturn(0);
}

}  // namespace

PetscErrorCode set_prescribed_values(const Constraints& c, double t, double scale, Vec x) {
  PetscFunctionBeginUser;
  PetscCall(insert_rows(c, prescribed_values(PetscObjectComm((PetscObject)x), c, t, scale), x));
  PetscFunctionReturn(0);
}

PetscErrorCode dirichlet_mask(DM dm, const std::vector<PetscInt>& rows, Vec global_mask,
                              std::vector<double>* local_mask) {
  PetscFunctionBeginUser;
  PetscCall(VecSet(global_mask, 1.0));
  PetscInt lo;
  PetscCall(VecGetOwnershipRange(global_mask, &lo, nullptr));
  PetscScalar* m;
  PetscCall(VecGetArray(global_mask, &m));
  for (PetscInt row : rows) m[row - lo] = 0.0;
  PetscCall(VecRestoreArray(global_mask, &m));
  // To the ghosts: a cell masks every prescribed corner DOF, also those another rank owns.
  Vec ml;
  PetscCall(DMGetLocalVector(dm, &ml));
  PetscCall(global_to_local(dm, global_mask, ml));
  const PetscScalar* a;
  PetscInt n;
  PetscCall(VecGetLocalSize(ml, &n));
  PetscCall(VecGetArrayRead(ml, &a));
  local_mask->assign(a, a + n);
  PetscCall(VecRestoreArrayRead(ml, &a));
  PetscCall(DMRestoreLocalVector(dm, &ml));
  PetscFunctionReturn(0);
}

PetscErrorCode assemble_constrained_matrix(DM dm, const topology::DofLayout& layout,
                                           const CellData& cells, const OperatorWeights& w,
                                           const Constraints& c, Mat A) {
  PetscFunctionBeginUser;
  // A_e with the rows and columns of prescribed DOFs zeroed, summed (A keeps its pattern:
  // create_matrix sets MAT_IGNORE_ZERO_ENTRIES false), then 1 on those diagonals: the matrix
  // of MatZeroRowsColumns(A, rows, 1.0) on the assembled operator, entry for entry.
  Vec mask;
  std::vector<double> local_mask;
  PetscCall(DMGetGlobalVector(dm, &mask));
  PetscCall(dirichlet_mask(dm, c.rows, mask, &local_mask));
  FineCells op(layout, cells, w);
  op.set_mask(std::move(local_mask));
  PetscCall(assemble(op, mask, A));
  PetscCall(DMRestoreGlobalVector(dm, &mask));
  PetscFunctionReturn(0);
}

PetscErrorCode constrain_rhs(DM dm, const topology::DofLayout& D, const CellData& C,
                             const OperatorWeights& w, const Constraints& c, double t, double scale,
                             Vec b) {
  PetscFunctionBeginUser;
  // Evaluated once, before any vector is borrowed (a non-finite expression throws).
  const auto values = prescribed_values(PetscObjectComm((PetscObject)b), c, t, scale);
  Vec u0, Au0;
  PetscCall(DMGetGlobalVector(dm, &u0));
  PetscCall(DMGetGlobalVector(dm, &Au0));
  PetscCall(VecSet(u0, 0.0));
  PetscCall(insert_rows(c, values, u0));
  PetscCall(apply(dm, D, C, w, u0, Au0));
  PetscCall(VecAXPY(b, -1.0, Au0));
  PetscCall(insert_rows(c, values, b));
  PetscCall(DMRestoreGlobalVector(dm, &u0));
  PetscCall(DMRestoreGlobalVector(dm, &Au0));
  PetscFunctionReturn(0);
}

}  // namespace hexcut::assembly
