// Cuts against independent expectations: piece counts of crossing and overlapping cuts
// as constructed, vertex copies split with the state carried over and momentum
// conserved, a cut bar whose free piece falls with g while the clamped piece does not
// notice, and (2 ranks) a cut across the partition boundary equal to 1 rank.
#include <cmath>
#include <functional>
#include <map>

#include "../analysis/fixture.hpp"
#include "analysis/cutting.hpp"
#include "assembly/operator.hpp"
#include "common/errors.hpp"
#include "cut/blade.hpp"
#include "cut/link_cut.hpp"

namespace hexcut::testing {
namespace {

using analysis::Cutter;

std::string vec(double x, double y, double z) {
  char b[96];
  std::snprintf(b, sizeof b, "[%.17g, %.17g, %.17g]", x, y, z);
  return b;
}

/// A square polygon blade in the plane through `p` with normal axis `axis` (0,1,2),
/// half-size r, as a deck cut entry.
std::string plane_cut(int axis, double offset, double r, double time, double cx = 0.5,
                      double cy = 0.5, double cz = 0.5) {
  std::array<double, 3> c{cx, cy, cz};
  c[axis] = offset;
  const int a = (axis + 1) % 3, b = (axis + 2) % 3;
  std::string s = "  - blade: {polygon: [";
  const double sa[4] = {-r, r, r, -r}, sb[4] = {-r, -r, r, r};
  for (int k = 0; k < 4; ++k) {
    auto p = c;
    p[a] += sa[k];
    p[b] += sb[k];
    s += vec(p[0], p[1], p[2]) + (k < 3 ? ", " : "");
  }
  return s + "]}\n    time: " + std::to_string(time) + "\n";
}

/// Runs the deck's dynamic analysis with its cuts through analysis::Driver, as the app does.
void run_with_cuts(MPI_Comm comm, Job& job, const std::function<void(Job&)>& after_step = {}) {
  analysis::DriverHooks hooks;
  if (after_step) hooks.on_step = [&](const analysis::State&) { after_step(job); };
  analysis::Driver driver(comm, job.deck, job.model, job.state, job.sim, hooks);
  HEXCUT_CALL(driver.begin());
  HEXCUT_CALL(driver.run());
}

int num_ranks() {
  int size;
  MPI_Comm_size(PETSC_COMM_WORLD, &size);
  return size;
}

TEST(Cuts, CrossingAndOverlappingCutsGiveExactPieceCounts) {
  // A 16x16x8 block; the x = 0.5 and y = 0.5 planes run through cell faces (t = 1/2).
  const std::string base =
      "lattice: {h: 0.0625, dims: [16, 16, 8]}\n"
      "materials: {m: {E: 1.0e6, nu: 0.3, rho: 1000}}\n"
      "geometry: [{add: {box: {min: [0, 0, 0], max: [1, 1, 0.5]}}}]\n"
      "analysis: {type: dynamic, dt: 0.001, steps: 1}\n"
      "solver: {type: cg-jacobi}\n";
  struct Case {
    std::string cuts;
    std::size_t pieces;
  };
  const std::vector<Case> cases = {
      {plane_cut(0, 0.5, 2.0, 0.0), 2},
      {plane_cut(0, 0.5, 2.0, 0.0) + plane_cut(1, 0.5, 2.0, 0.0), 4},
      // The same plane twice (overlap) and a third cut crossing both.
      {plane_cut(0, 0.5, 2.0, 0.0) + plane_cut(0, 0.5, 2.0, 0.0) + plane_cut(1, 0.5, 2.0, 0.0), 4},
      // A horizontal cut through half the block only (x < 0.25): no new piece.
      {plane_cut(0, 0.5, 2.0, 0.0) + plane_cut(2, 0.25, 0.25, 0.0, 0.0, 0.5), 2},
      // ... and across the whole block at z = 0.25: every piece splits in two.
      {plane_cut(0, 0.5, 2.0, 0.0) + plane_cut(1, 0.5, 2.0, 0.0) + plane_cut(2, 0.25, 2.0, 0.0), 8},
  };
  for (const auto& c : cases) {
    Job job(PETSC_COMM_WORLD, base + "cuts:\n" + c.cuts);
    Cutter cutter(job.deck, job.model.lattice);
    analysis::CutReport r;
    HEXCUT_CALL(analysis::apply_due_cuts(PETSC_COMM_WORLD, job.deck, cutter, 0.0, &job.model,
                                         &job.state, &r));
    const auto pieces = analysis::find_pieces(PETSC_COMM_WORLD, job.model);
    EXPECT_EQ(pieces.size(), c.pieces) << c.cuts;
    std::int64_t cells = 0;
    for (const auto& p : pieces) {
      cells += p.cells;
      EXPECT_EQ(p.cells, 2048 / std::int64_t(c.pieces)) << analysis::describe(p);
    }
    EXPECT_EQ(cells, 2048);
    // Every cut link is recorded once, whatever the overlaps.
    EXPECT_EQ(std::int64_t(job.model.lattice.cut_links.size()), r.links);
  }
}

TEST(Cuts, ScalpelWindowSchedulesOneQuadPerPathSegment) {
  deck::Cut c;
  c.blade.kind = deck::Blade::Kind::scalpel;
  c.blade.edge = {Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(0, 0, 1)};
  for (int k = 0; k < 5; ++k) c.blade.path.push_back(Eigen::Vector3d(0.1 * k, 0.05 * k * k, 0));
  c.swept = true;
  c.window_begin = 0.1;
  c.window_end = 0.5;
  const auto events = cut::cut_schedule({c});
  ASSERT_EQ(events.size(), 4u);
  double area = 0;
  for (std::size_t k = 0; k < 4; ++k) {
    EXPECT_NEAR(events[k].time, 0.1 + 0.1 * double(k + 1), 1e-15);
    ASSERT_EQ(events[k].triangles.size(), 2u);
    for (const auto& t : events[k].triangles) area += t.area();
  }
  // The swept surface: edge length 1 times the path length (the path is planar in z = 0).
  double path = 0;
  for (int k = 0; k + 1 < 5; ++k) path += (c.blade.path[k + 1] - c.blade.path[k]).norm();
  EXPECT_NEAR(area, path, 1e-12);
}

TEST(Cuts, CylinderStampPunchesOutAPlug) {
  const std::string yaml =
      "lattice: {h: 0.03125, dims: [32, 32, 8]}\n"
      "materials: {m: {E: 1.0e6, nu: 0.3, rho: 1000}}\n"
      "geometry: [{add: {box: {min: [0, 0, 0], max: [1, 1, 0.25]}}}]\n"
      "analysis: {type: dynamic, dt: 0.001, steps: 1}\n"
      "solver: {type: cg-jacobi}\n"
      "cuts:\n  - blade: {cylinder: {start: [0.5, 0.5, -0.1], end: [0.5, 0.5, 0.4], radius: 0.25, "
      "segments: 64}}\n";
  Job job(PETSC_COMM_WORLD, yaml);
  Cutter cutter(job.deck, job.model.lattice);
  HEXCUT_CALL(
      analysis::apply_due_cuts(PETSC_COMM_WORLD, job.deck, cutter, 0.0, &job.model, &job.state));
  const auto pieces = analysis::find_pieces(PETSC_COMM_WORLD, job.model);
  ASSERT_EQ(pieces.size(), 2u);
  // The plug: exactly the cells whose centres lie inside the cylinder (none is within
  // the 64-gon's chord distance of the circle here), about pi r^2 t / h^3.
  const auto& plug = pieces[0].cells < pieces[1].cells ? pieces[0] : pieces[1];
  const auto& L = job.model.lattice;
  std::int64_t inside = 0;
  for (std::int32_t c = 0; c < L.num_cells(); ++c) {
    const auto x = L.spec.cell_centre(L.ijk[c][0], L.ijk[c][1], L.ijk[c][2]);
    inside += std::hypot(x.x() - 0.5, x.y() - 0.5) < 0.25;
  }
  std::printf("plug: %lld cells; centres inside the cylinder %lld; pi r^2 t / h^3 = %.1f\n",
              (long long)plug.cells, (long long)inside,
              M_PI * 0.25 * 0.25 * 0.25 / std::pow(0.03125, 3));
  EXPECT_EQ(plug.cells, inside);
}

TEST(Cuts, MeshBladeCutsTheSameLinksAsTheEquivalentPolygon) {
  // The same inclined quad, once as a polygon and once as a two-triangle OBJ file.
  const std::string obj =
      std::string(HEXCUT_BINARY_DIR) + "/blade_quad_" + std::to_string(num_ranks()) + ".obj";
  int rank;
  MPI_Comm_rank(PETSC_COMM_WORLD, &rank);
  if (rank == 0) {
    std::FILE* f = std::fopen(obj.c_str(), "w");
    std::fprintf(
        f, "v 0.3 -0.1 -0.1\nv 0.7 -0.1 0.6\nv 0.7 0.6 0.6\nv 0.3 0.6 -0.1\nf 1 2 3\nf 1 3 4\n");
    std::fclose(f);
  }
  MPI_Barrier(PETSC_COMM_WORLD);
  const std::string base =
      "lattice: {h: 0.05, dims: [20, 10, 10]}\n"
      "materials: {m: {E: 1.0e6, nu: 0.3, rho: 1000}}\n"
      "geometry: [{add: {box: {min: [0, 0, 0], max: [1, 0.5, 0.5]}}}]\n"
      "analysis: {type: dynamic, dt: 0.001, steps: 1}\n"
      "solver: {type: cg-jacobi}\n";
  std::vector<std::vector<std::int32_t>> cut_cells;
  for (const std::string& blade :
       {std::string(
            "{polygon: [[0.3, -0.1, -0.1], [0.7, -0.1, 0.6], [0.7, 0.6, 0.6], [0.3, 0.6, -0.1]]}"),
        "{mesh: {file: " + obj + "}}"}) {
    Job job(PETSC_COMM_WORLD, base + "cuts:\n  - blade: " + blade + "\n");
    Cutter cutter(job.deck, job.model.lattice);
    HEXCUT_CALL(
        analysis::apply_due_cuts(PETSC_COMM_WORLD, job.deck, cutter, 0.0, &job.model, &job.state));
    std::vector<std::int32_t> cells;
    for (const auto& l : job.model.lattice.cut_links) cells.push_back(3 * l.cell + l.dir);
    cut_cells.push_back(cells);
    EXPECT_EQ(analysis::find_pieces(PETSC_COMM_WORLD, job.model).size(), 2u) << blade;
  }
  EXPECT_GT(cut_cells[0].size(), 100u);
  EXPECT_EQ(cut_cells[0], cut_cells[1]);
}

/// A smooth field of position for the state.
Eigen::Vector3d field(const Eigen::Vector3d& x, double k) {
  return k * Eigen::Vector3d(std::sin(3 * x.x()) + 0.2, std::cos(2 * x.x() + x.y()),
                             x.z() - 0.3 * x.x());
}

void set_field(Job& job, Vec v, double k) {
  const auto& D = job.model.layout;
  PetscScalar* a;
  VecGetArray(v, &a);
  for (std::int32_t i = 0; i < D.num_owned; ++i) {
    const auto f = field(job.position(D.copies[i]), k);
    for (int d = 0; d < 3; ++d) a[3 * i + d] = f[d];
  }
  VecRestoreArray(v, &a);
}

/// Total momentum sum_i (M v)_i with the model's mass matrix.
Eigen::Vector3d momentum(Job& job, bool lumped) {
  Vec Mv;
  VecDuplicate(job.state.v, &Mv);
  check_petsc(assembly::apply(job.model.dm, job.model.layout, job.model.cells, {0.0, 1.0, lumped},
                              job.state.v, Mv),
              "apply");
  const Eigen::Vector3d p = component_sums(Mv);
  VecDestroy(&Mv);
  return p;
}

TEST(Cuts, VertexCopiesSplitWithTheStateAndMomentumIsConserved) {
  for (const char* mass : {"lumped", "consistent"}) {
    const std::string yaml = std::string(
                                 "lattice: {h: 0.05, dims: [20, 2, 2]}\n"
                                 "materials: {m: {E: 1.0e6, nu: 0.3, rho: 1000}}\n"
                                 "geometry: [{add: {box: {min: [0, 0, 0], max: [1, 0.1, 0.1]}}}]\n"
                                 "analysis: {type: dynamic, dt: 0.001, steps: 1, mass: ") +
                             mass + "}\nsolver: {type: cg-jacobi}\ncuts:\n" +
                             plane_cut(0, 0.5, 1.0, 0.0, 0, 0.05, 0.05);
    Job job(PETSC_COMM_WORLD, yaml);
    set_field(job, job.state.u, 1e-4);
    set_field(job, job.state.v, 1.0);
    set_field(job, job.state.a, 5.0);
    const bool lumped = std::string(mass) == "lumped";
    const auto p_before = momentum(job, lumped);
    const auto copies_before = job.model.copies.num_copies;
    Cutter cutter(job.deck, job.model.lattice);
    analysis::CutReport r;
    HEXCUT_CALL(analysis::apply_due_cuts(PETSC_COMM_WORLD, job.deck, cutter, 0.0, &job.model,
                                         &job.state, &r));
    EXPECT_EQ(r.links, 4);  // 2 x 2 cells across the bar
    // The 3 x 3 lattice vertices on the cut face get a second copy each.
    EXPECT_EQ(job.model.copies.num_copies, copies_before + 9);
    // Every copy, old or new, carries the field value of its vertex.
    for (auto [v, k] :
         {std::pair{job.state.u, 1e-4}, std::pair{job.state.v, 1.0}, std::pair{job.state.a, 5.0}}) {
      const auto values = job.canonical(v);
      double worst = 0;
      for (std::int32_t c = 0; c < job.model.copies.num_copies; ++c)
        worst = std::max(worst,
                         (Eigen::Vector3d(&values[3 * c]) - field(job.position(c), k)).norm() / k);
      EXPECT_LT(worst, 1e-14) << mass;
    }
    const auto p_after = momentum(job, lumped);
    EXPECT_LT((p_after - p_before).norm(), 1e-12 * p_before.norm()) << mass;
    std::printf("%s mass: momentum before [%.15g %.15g %.15g], after [%.15g %.15g %.15g]\n", mass,
                p_before.x(), p_before.y(), p_before.z(), p_after.x(), p_after.y(), p_after.z());
  }
}

std::string bar_deck(double length, const std::string& extra) {
  return "lattice: {h: 0.025, dims: [40, 4, 4]}\n"
         "materials: {m: {E: 2.0e5, nu: 0.3, rho: 1000}}\n"
         "geometry: [{add: {box: {min: [0, 0, 0], max: [" +
         std::to_string(length) +
         ", 0.1, 0.1]}}}]\n"
         "boundary:\n  fixed: [{where: {plane: {point: [0, 0, 0], normal: [1, 0, 0]}}}]\n"
         "  gravity: [0, 0, -9.81]\n"
         "analysis: {type: dynamic, dt: 0.002, steps: 40}\n"
         "solver: {type: gmg, rtol: 1.0e-12}\n" +
         extra;
}

/// Cut at x = cells * h at t = 0, before the first step: the free part must fall rigidly,
/// u_z = -g t^2 / 2 (Newmark's average acceleration is exact for constant acceleration),
/// and the clamped part must move exactly like a bar that was only that long. `extra`: more
/// deck text (a discretization).
void check_cut_bar(int cells, const std::string& extra) {
  const double g = 9.81, x = 0.025 * cells;
  Job cut_bar(PETSC_COMM_WORLD,
              bar_deck(1.0, "cuts:\n" + plane_cut(0, x, 1.0, 0.0, 0, 0.05, 0.05) + extra));
  run_with_cuts(PETSC_COMM_WORLD, cut_bar);
  Job short_bar(PETSC_COMM_WORLD, bar_deck(x, extra));
  short_bar.initial_acceleration();
  short_bar.run();
  const double t = cut_bar.state.time;
  const auto u = cut_bar.canonical(cut_bar.state.u);
  const auto u_short = short_bar.canonical(short_bar.state.u);
  // Short bar values by lattice vertex.
  std::map<std::array<std::int32_t, 3>, Eigen::Vector3d> clamped;
  for (std::int32_t c = 0; c < short_bar.model.copies.num_copies; ++c)
    clamped[short_bar.model.copies.vertex[c]] = Eigen::Vector3d(&u_short[3 * c]);
  double fall_error = 0, clamped_error = 0, clamped_scale = 0;
  int free_copies = 0;
  const auto& L = cut_bar.model.lattice;
  for (std::int32_t c = 0; c < cut_bar.model.copies.num_copies; ++c) {
    const Eigen::Vector3d uc(&u[3 * c]);
    const auto cell = cut_bar.model.copies.first_cell[c];
    if (L.ijk[cell][0] >= cells) {  // free piece (cells right of the cut)
      ++free_copies;
      fall_error = std::max(
          fall_error, (uc - Eigen::Vector3d(0, 0, -0.5 * g * t * t)).norm() / (0.5 * g * t * t));
    } else {
      const auto& ref = clamped.at(cut_bar.model.copies.vertex[c]);
      clamped_error = std::max(clamped_error, (uc - ref).norm());
      clamped_scale = std::max(clamped_scale, ref.norm());
    }
  }
  std::printf(
      "cut at x = %g%s: free piece (%d copies): max relative deviation from -g t^2/2 = %.2e at "
      "t = %g s; clamped piece vs a bar of that length: %.2e relative\n",
      x, extra.empty() ? "" : " (composite)", free_copies, fall_error, t,
      clamped_error / clamped_scale);
  EXPECT_GT(free_copies, 0);
  EXPECT_LT(fall_error, 0.01);
  EXPECT_LT(clamped_error, 1e-6 * clamped_scale);
}

TEST(Cuts, CutBarFreePieceFallsWithGravityAndTheClampedPieceIsUndisturbed) {
  check_cut_bar(8, "");
}

TEST(Cuts, CompositeCutBarFreePieceFallsAndTheClampedPieceIsUndisturbed) {
  // Composite elements of level 1 and 2 (2 and 4 fine cells wide): the cut at x = 9 h
  // runs through composite elements, which split into a piece on each side; the clamped
  // side's composite elements are those of a bar that ends at the cut.
  for (int level : {1, 2})
    check_cut_bar(9, "discretization: {type: composite, level: " + std::to_string(level) + "}\n");
}

TEST(Cuts, FreePieceAcceleratesWithGravityAfterALateCut) {
  // Cut at t = 0.02 s while the bar sags: after the cut, the free piece's mass-weighted
  // velocity changes by -g per second (only gravity acts on it as a whole).
  const double g = 9.81;
  Job job(PETSC_COMM_WORLD, bar_deck(1.0, "cuts:\n" + plane_cut(0, 0.2, 1.0, 0.02, 0, 0.05, 0.05)));
  std::vector<std::pair<double, double>> history;  // (t, v_z of the free piece's centre of mass)
  run_with_cuts(PETSC_COMM_WORLD, job, [&](Job& j) {
    if (j.state.time < 0.03) return;
    const auto v = j.canonical(j.state.v);
    // Lumped-mass weights: mass of a copy = rho h^3 / 8 per incident cell.
    std::vector<int> incident(j.model.copies.num_copies, 0);
    for (const auto& corners : j.model.copies.cell_corners)
      for (auto c : corners) ++incident[c];
    double m = 0, p = 0;
    for (std::int32_t c = 0; c < j.model.copies.num_copies; ++c)
      if (j.model.lattice.ijk[j.model.copies.first_cell[c]][0] >= 8)
        m += incident[c], p += incident[c] * v[3 * c + 2];
    history.emplace_back(j.state.time, p / m);
  });
  ASSERT_GE(history.size(), 2u);
  const double accel = (history.back().second - history.front().second) /
                       (history.back().first - history.front().first);
  std::printf("free piece centre-of-mass acceleration after the cut: %.6f m/s^2 (g = %.2f)\n",
              accel, g);
  EXPECT_LT(std::abs(accel + g), 0.01 * g);
}

TEST(Cuts, EverySolverCopesWithSeveralPieces) {
  // After the cut the system has two bodies (the free one held only by its mass term).
  // Smoothed aggregation (GAMG) and BoomerAMG use the near-nullspace per aggregate, and
  // aggregates never span pieces (no coupling), so the 6 rigid-body modes of the whole
  // body restricted to an aggregate are those of its piece.
  auto deck_for = [](const std::string& solver) {
    std::string d = bar_deck(1.0, "cuts:\n" + plane_cut(0, 0.2, 1.0, 0.02, 0, 0.05, 0.05));
    const auto at = d.find("solver: ");
    return d.substr(0, at) + "solver: {type: " + solver + ", rtol: 1.0e-12}\n" +
           d.substr(d.find('\n', at) + 1);
  };
  std::vector<double> reference;
  for (const char* solver : {"gmg", "hypre", "gamg", "cg-jacobi", "direct"}) {
    Job job(PETSC_COMM_WORLD, deck_for(solver));
    run_with_cuts(PETSC_COMM_WORLD, job);
    const auto u = job.canonical(job.state.u);
    if (reference.empty()) {
      reference = u;
      continue;
    }
    ASSERT_EQ(u.size(), reference.size());
    double num = 0, den = 0;
    for (std::size_t i = 0; i < u.size(); ++i)
      num = std::max(num, std::abs(u[i] - reference[i])),
      den = std::max(den, std::abs(reference[i]));
    std::printf("%-10s vs gmg after the cut: %.2e relative\n", solver, num / den);
    EXPECT_LT(num / den, 1e-8) << solver;
  }
}

/// The theses' multigrid stress test (Dick 2012, sec. 4.7.2): a clamped cube cut from the top,
/// halfway down, by a grid of 3 + 3 vertical blades into 16 rods that a spin about the vertical
/// axis fans out. Returns GMG-CG iterations to rtol 1e-8 (cuts: false = the uncut cube) of the
/// static solve, or (dt > 0) of the first Newmark step.
PetscInt grid_cube_iterations(bool cuts, const char* options, double dt = 0.0) {
  const int n = 32;
  std::string yaml =
      "lattice: {h: " + std::to_string(1.0 / n) + ", dims: [32, 32, 32]}\n" +
      "materials: {m: {E: 1.0e6, nu: 0.3, rho: 1000}}\n"
      "geometry: [{add: {box: {min: [0, 0, 0], max: [1, 1, 1]}}}]\n"
      "boundary:\n  fixed: [{where: {plane: {point: [0, 0, 0], normal: [0, 0, 1]}}}]\n"
      "  centrifugal: {point: [0.5, 0.5, 0], axis: [0, 0, 1], omega: 10}\n"
      "solver: {type: gmg, rtol: 1.0e-8}\n";
  if (dt > 0) yaml += "analysis: {type: dynamic, dt: " + std::to_string(dt) + ", steps: 1}\n";
  if (cuts) {
    yaml += "cuts:\n";
    for (int axis : {0, 1})
      for (int k = 1; k <= 3; ++k) {
        std::array<double, 3> lo{-0.1, -0.1, 0.5}, hi{1.1, 1.1, 1.1};
        // Off the coarse cells' boundaries (x = 11/32, 19/32, 27/32), so that merging by
        // position would join cells across the cuts on every coarse level.
        lo[axis] = hi[axis] = 0.25 * k + 3.0 / 32.0;
        const int other = 1 - axis;
        std::array<double, 3> p[4] = {lo, lo, hi, hi};
        p[1][other] = hi[other];
        p[3][other] = lo[other];
        yaml += "  - blade: {polygon: [" + vec(p[0][0], p[0][1], p[0][2]) + ", " +
                vec(p[1][0], p[1][1], 0.5) + ", " + vec(p[2][0], p[2][1], p[2][2]) + ", " +
                vec(p[3][0], p[3][1], 1.1) + "]}\n";
      }
  }
  Job job(PETSC_COMM_WORLD, yaml, 8, options);
  Cutter cutter(job.deck, job.model.lattice);
  analysis::CutReport r;
  HEXCUT_CALL(analysis::apply_due_cuts(PETSC_COMM_WORLD, job.deck, cutter, 1e300, &job.model,
                                       &job.state, &r));
  if (cuts) {
    EXPECT_EQ(r.links, 6 * 32 * 16);  // 6 blades, 32 x 16 links each
    job.sim.reset();
    HEXCUT_CALL(analysis::Simulation::create(PETSC_COMM_WORLD, job.model, job.deck, &job.sim));
  }
  if (dt > 0) {
    job.initial_acceleration();
    job.newmark_step();
  } else {
    job.run();
  }
  PetscInt its;
  KSPGetIterationNumber(job.sim->ksp(), &its);
  KSPConvergedReason reason;
  KSPGetConvergedReason(job.sim->ksp(), &reason);
  EXPECT_GT(reason, 0);
  return its;
}

TEST(Cuts, MultigridHierarchyFollowsTheCuts) {
  // The theses' stress test is dynamic: one Newmark step of 10 ms, default multigrid
  // (automatic depth, V-cycle). The cut-aware hierarchy stays within 1.5x of the uncut
  // cube; merging by position (naive) is clearly worse.
  const PetscInt uncut_dyn = grid_cube_iterations(false, nullptr, 0.01);
  const PetscInt cut_dyn = grid_cube_iterations(true, nullptr, 0.01);
  const PetscInt naive_dyn = grid_cube_iterations(true, "-gmg_hierarchy naive", 0.01);
  // Static, V-cycles with the same depth (3 levels) for both.
  const PetscInt uncut = grid_cube_iterations(false, "-gmg_levels 3 -gmg_cycle v");
  const PetscInt cut = grid_cube_iterations(true, "-gmg_levels 3 -gmg_cycle v");
  const PetscInt naive =
      grid_cube_iterations(true, "-gmg_levels 3 -gmg_cycle v -gmg_hierarchy naive");
  // A 4th level (8^3-cell coarse cells, wider than the 5-cell rods) costs the V-cycle
  // more; the W-cycle recovers it.
  const PetscInt uncut4 = grid_cube_iterations(false, "-gmg_levels 4 -gmg_cycle v");
  const PetscInt cut4 = grid_cube_iterations(true, "-gmg_levels 4 -gmg_cycle v");
  const PetscInt uncut4w = grid_cube_iterations(false, "-gmg_levels 4 -gmg_cycle w");
  const PetscInt cut4w = grid_cube_iterations(true, "-gmg_levels 4 -gmg_cycle w");
  // Static with default settings: automatic depth (3 levels uncut; 4 cut, where the
  // split copies push the 3rd level over -gmg_coarse_dofs) and, for a static analysis of
  // a cut body, the W-cycle.
  const PetscInt uncut_default = grid_cube_iterations(false, nullptr);
  const PetscInt cut_default = grid_cube_iterations(true, nullptr);
  // The V-cycle on the robust coarse space (doc/theory.md, "Coarse spaces after cuts and on
  // thin pieces"): energy-minimizing interpolation, Schwarz-preconditioned Chebyshev of
  // growing degree where coarse cells are irregular.
  const PetscInt cut_robust = grid_cube_iterations(
      true, "-gmg_cycle v -gmg_interpolation energy -gmg_schwarz_from 1 -gmg_degree_growth 2");
  std::printf(
      "GMG-CG iterations to 1e-8, 32^3 cube cut into 16 rods (uncut / cut / naive):\n"
      "  dynamic (dt 10 ms, defaults): %d / %d / %d\n"
      "  static, 3 levels, V-cycle: %d / %d / %d\n"
      "  static, 4 levels: V-cycle %d / %d, W-cycle %d / %d\n"
      "  static, defaults: %d / %d; robust coarse space, V-cycle: cut %d\n",
      int(uncut_dyn), int(cut_dyn), int(naive_dyn), int(uncut), int(cut), int(naive), int(uncut4),
      int(cut4), int(uncut4w), int(cut4w), int(uncut_default), int(cut_default), int(cut_robust));
  EXPECT_LE(double(cut_dyn), 1.5 * double(uncut_dyn));
  EXPECT_GE(double(naive_dyn), 2.0 * double(cut_dyn));
  EXPECT_LE(double(cut), 1.5 * double(uncut));
  EXPECT_GE(double(naive), 3.0 * double(cut));
  EXPECT_LT(cut4w, cut4);
  EXPECT_LE(double(cut_default), 1.5 * double(uncut_default));
  // The robust coarse space takes a quarter of the trilinear V-cycle's iterations off at the
  // same depth (measured 13 against 17).
  EXPECT_LE(double(cut_robust) * 1.25, double(cut4));
}

TEST(Cuts, UnsupportedPieceIsReportedForStaticAnalyses) {
  const std::string yaml =
      "lattice: {h: 0.05, dims: [20, 2, 2]}\n"
      "materials: {m: {E: 1.0e6, nu: 0.3, rho: 1000}}\n"
      "geometry: [{add: {box: {min: [0, 0, 0], max: [1, 0.1, 0.1]}}}]\n"
      "boundary: {fixed: [{where: {plane: {point: [0, 0, 0], normal: [1, 0, 0]}}}], gravity: [0, "
      "0, -9.81]}\n"
      "solver: {type: cg-jacobi}\n"
      "cuts:\n" +
      plane_cut(0, 0.6, 1.0, 0.0, 0, 0.05, 0.05);
  Job job(PETSC_COMM_WORLD, yaml);
  Cutter cutter(job.deck, job.model.lattice);
  HEXCUT_CALL(
      analysis::apply_due_cuts(PETSC_COMM_WORLD, job.deck, cutter, 1e300, &job.model, &job.state));
  const auto pieces = analysis::find_pieces(PETSC_COMM_WORLD, job.model);
  ASSERT_EQ(pieces.size(), 2u);
  EXPECT_TRUE(pieces[0].supported);
  EXPECT_FALSE(pieces[1].supported);
  EXPECT_EQ(pieces[1].cells, 32);
  try {
    HEXCUT_CALL(analysis::require_supported(PETSC_COMM_WORLD, pieces));
    ADD_FAILURE() << "expected a SolverError";
  } catch (const SolverError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("piece 2: 32 cells, box [0.6, 0, 0] - [1, 0.1, 0.1] m, unsupported"),
              std::string::npos)
        << msg;
  }
}

std::vector<double> cut_run(MPI_Comm comm, const std::string& yaml, const char* options = nullptr) {
  Job job(comm, yaml, 4, options);
  run_with_cuts(comm, job);
  return job.canonical(job.state.u);
}

TEST(Cuts, TwoRanksEqualOneRankForACutAcrossThePartitionBoundary) {
  if (num_ranks() < 2) GTEST_SKIP() << "needs mpiexec -n 2";
  int rank;
  MPI_Comm_rank(PETSC_COMM_WORLD, &rank);
  // Where does the partition split the bar? Cut exactly there (links between cells of
  // different ranks), and with an inclined blade through cells of both ranks.
  double x_split = 0;
  {
    Job probe(PETSC_COMM_WORLD, bar_deck(1.0, ""), 4);
    const auto& L = probe.model.lattice;
    for (std::int32_t c = 0; c < L.num_cells(); ++c) {
      const auto nb = L.find(L.ijk[c][0] + 1, L.ijk[c][1], L.ijk[c][2]);
      if (nb >= 0 && probe.model.partition.cell_rank[c] != probe.model.partition.cell_rank[nb])
        x_split = L.spec.h * (L.ijk[c][0] + 1);
    }
  }
  ASSERT_GT(x_split, 0.0);
  const std::string inclined = "  - blade: {polygon: [" + vec(x_split - 0.1, -0.5, -0.5) + ", " +
                               vec(x_split + 0.1, -0.5, 0.6) + ", " + vec(x_split + 0.1, 0.6, 0.6) +
                               ", " + vec(x_split - 0.1, 0.6, -0.5) + "]}\n    time: 0.03\n";
  const std::string yaml =
      bar_deck(1.0, "cuts:\n" + plane_cut(0, x_split, 1.0, 0.01, 0, 0.05, 0.05) + inclined);
  // The default multigrid, and the robust coarse space (energy-minimizing rows and Schwarz
  // patches that straddle the partition boundary).
  for (const char* options :
       {static_cast<const char*>(nullptr),
        "-gmg_interpolation energy -gmg_schwarz_from 0 -gmg_degree_growth 2"}) {
    const auto parallel = cut_run(PETSC_COMM_WORLD, yaml, options);
    MPI_Comm self;
    MPI_Comm_split(PETSC_COMM_WORLD, rank == 0 ? 0 : MPI_UNDEFINED, 0, &self);
    if (rank == 0) {
      const auto serial = cut_run(self, yaml, options);
      ASSERT_EQ(serial.size(), parallel.size());
      double num = 0, den = 0;
      for (std::size_t i = 0; i < serial.size(); ++i) {
        num = std::max(num, std::abs(serial[i] - parallel[i]));
        den = std::max(den, std::abs(serial[i]));
      }
      std::printf(
          "cut at x = %g (partition boundary) + inclined cut, %s: 1 vs 2 ranks max relative "
          "difference %.2e\n",
          x_split, options ? options : "defaults", num / den);
      EXPECT_LT(num / den, 1e-8);
      MPI_Comm_free(&self);
    }
  }
  MPI_Barrier(PETSC_COMM_WORLD);
}

}  // namespace
}  // namespace hexcut::testing
