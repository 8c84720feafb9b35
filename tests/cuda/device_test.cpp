// The CUDA backend against the host backend (issue 13): the same functor bodies launched
// per colour on the device give the host's y += A x on every coarse level of a holed,
// two-material, corotated block, in double and in single precision, and for its fine cells,
// to 1e-12 relative (the sums at a vertex copy are formed in another order); the whole cycle
// and the whole solve equal the host's loop-layer cycle, with double vectors to 1e-12 and with
// float vectors (-gmg_precision single) to 1e-6. Built only with nvcc (cuda/CMakeLists.txt);
// skips with a message when no device is visible.
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "../analysis/fixture.hpp"
#include "device_backend.hpp"
#include "multigrid/gmg.hpp"
#include "multigrid/host_loop_cycle.hpp"

namespace hexcut::testing {
namespace {

const std::string kBlock =
    holed_block_body() +
    "boundary:\n  fixed:\n    - where: {plane: {point: [0, 0, 0], normal: [1, 0, 0]}}\n"
    "analysis: {type: static}\n"
    "solver: {type: gmg}\n";

/// Skips the test where no CUDA device is visible, with the runtime's reason.
#define SKIP_WITHOUT_A_DEVICE()                                                       \
  do {                                                                                \
    std::string why;                                                                  \
    if (cuda::device_count(&why) == 0)                                                \
      GTEST_SKIP() << "no CUDA device (" << why << "): the device tests are skipped"; \
  } while (0)

/// max |y_device - y_host| / max |y_host| for y = 0.5 + A x, x a fixed smooth field of n
/// values, `host` and `device` each y += A x.
template <class Host, class Device>
double device_host_difference(std::size_t n, const Host& host, const Device& device) {
  std::vector<double> x(n), yh(n, 0.5), yd(n, 0.5);
  for (std::size_t i = 0; i < n; ++i) x[i] = std::sin(0.37 * double(i)) + 0.1;
  host(x.data(), yh.data());
  device(x.data(), yd.data());
  return max_difference(yh.data(), yd.data(), n).relative();
}

TEST(Device, StoredCellsApplyEqualsTheHost) {
  SKIP_WITHOUT_A_DEVICE();
  for (const char* options : {"-gmg_levels 3", "-gmg_levels 3 -gmg_precision single"}) {
    Job job(PETSC_COMM_WORLD, kBlock, 8, options);
    auto& mg = *job.sim->multigrid();
    HEXCUT_CALL(mg.update(job.model.cells, {1.0, 0.0, true}, job.model.boundary.constraints.rows));
    for (int l = 1; l < mg.num_levels(); ++l) {
      const auto& A = mg.stored_cells(l);
      const auto colours = backend::colour_cells(mg.cell_positions(l));
      const double r = device_host_difference(
          3 * std::size_t(mg.level(l).layout().num_local()),
          [&](const double* x, double* y) { A.apply_add(x, y); },
          [&](const double* x, double* y) { cuda::stored_apply_add(A, colours, x, y); });
      std::printf("%s, level %d: max |y_device - y_host| / max |y_host| = %.1e\n", options, l, r);
      EXPECT_LT(r, 1e-12) << options << ", level " << l;
    }
  }
}

TEST(Device, FineOperatorApplyEqualsTheHost) {
  // The fine cells' y += A x (assembly::FineCellOps) on the device against the host, on the
  // holed two-material block: every path of the body (a kind's stiffness; cells without a
  // kind, formed once or applied from the reference matrices; rotations; lumped and
  // consistent mass; a Dirichlet mask), to 1e-12 relative.
  SKIP_WITHOUT_A_DEVICE();
  Job job(PETSC_COMM_WORLD, kBlock, 8, "-gmg_levels 2");
  const auto& layout = job.model.layout;
  const auto colours = backend::colour_cells(job.sim->multigrid()->cell_positions(0));
  // Every 5th cell without a kind (its stiffness from its own lambda and mu); rotations
  // about a tilted axis, different per cell.
  assembly::CellData cells = job.model.cells;
  for (std::size_t e = 0; e < cells.kind.size(); e += 5) cells.kind[e] = -1;
  std::vector<double> rotation(9 * cells.kind.size());
  for (std::size_t e = 0; e < cells.kind.size(); ++e) {
    const double c = std::cos(0.2 + 0.01 * double(e)), s = std::sin(0.2 + 0.01 * double(e));
    const double R[9] = {c, -s, 0, s, c, 0, 0, 0, 1};
    std::copy(R, R + 9, &rotation[9 * e]);
  }
  const std::size_t n = 3 * std::size_t(layout.num_local());
  std::vector<double> mask(n, 1.0);
  for (std::size_t i = 0; i < n; i += 7) mask[i] = 0.0;
  struct Case {
    const char* name;
    assembly::OperatorWeights w;
    bool cache, rotated, masked;
  };
  for (const Case& c : {Case{"stiffness", {1.0, 0.0, true}, true, false, false},
                        Case{"reference matrices", {1.0, 0.0, true}, false, false, false},
                        Case{"rotated, lumped mass, masked", {0.7, 3.0, true}, true, true, true},
                        Case{"rotated, consistent mass", {1.0, 2.0, false}, false, true, false}}) {
    cells.identity_rotations = !c.rotated;
    cells.rotation = c.rotated ? rotation : std::vector<double>{};
    assembly::FineCells A(layout, cells, c.w, c.cache);
    if (c.masked) A.set_mask(mask);
    const double r = device_host_difference(
        n, [&](const double* x, double* y) { A.apply_add(x, y); },
        [&](const double* x, double* y) { cuda::fine_apply_add(A, colours, x, y); });
    std::printf("fine cells, %s: max |y_device - y_host| / max |y_host| = %.1e\n", c.name, r);
    EXPECT_LT(r, 1e-12) << c.name;
  }
}

TEST(Device, RotationUpdateEqualsTheHost) {
  // The corotational rotation update (assembly::CellRotation: the polar factor of F at each
  // cell's centre) on the device against assembly::cell_rotations on the host, for large
  // rotations and strains and for inverted cells (u = -2 x on part of the block: F = -I there,
  // and sheared inversions around it), to 1e-12.
  SKIP_WITHOUT_A_DEVICE();
  Job job(PETSC_COMM_WORLD, kBlock, 8, "-gmg_levels 2");
  const auto& D = job.model.layout;
  std::vector<double> u(3 * std::size_t(D.num_local()));
  for (std::int32_t i = 0; i < D.num_local(); ++i) {
    const auto x = job.position(D.copies[i]);
    const bool invert = x[0] < 0.3;
    for (int c = 0; c < 3; ++c)
      u[3 * i + c] = invert ? -2.0 * x[c] + 0.05 * x[(c + 1) % 3]
                            : 0.8 * std::sin(3.0 * x[(c + 1) % 3]) * x[(c + 2) % 3];
  }
  const std::size_t n = D.cells.size();
  std::vector<double> Rh(9 * n), Rd(9 * n);
  assembly::cell_rotations(D, job.model.cells, u.data(), Rh.data());
  cuda::cell_rotations(D.cell_corners[0].data(), std::int64_t(n), D.num_local(), u.data(),
                       job.model.cells.h, Rd.data());
  const double d = max_difference(Rh.data(), Rd.data(), Rh.size()).difference;
  std::printf("rotations of %zu cells: max |R_device - R_host| = %.1e\n", n, d);
  EXPECT_LT(d, 1e-12);
}

TEST(Device, CycleEqualsTheHostLoopCycle) {
  // The whole cycle on the device (cuda::MultigridDeviceCycle: Chebyshev, residuals,
  // transfers on the device, the coarsest level on the host) against the same cycle on the
  // host backend (multigrid::host_loop_cycle in the Multigrid's precision, itself equal to
  // Multigrid::cycle), on the corotated holed two-material block: V and W, Chebyshev and
  // coloured Gauss-Seidel (cell colour by cell colour on the device), with double vectors
  // and double or float coarse blocks, 1e-12 relative; with -gmg_precision single both cycles'
  // vectors are float, and they agree to 1e-6 relative (float rounds each sum at a vertex copy,
  // and the device forms those sums in another order; each float cycle is ~1e-7 from double's,
  // tests/multigrid "LoopCycleOnTheHost"), while the device's float cycle is more than 1e-9
  // from the host's double cycle (its vectors really are float).
  SKIP_WITHOUT_A_DEVICE();
  struct Case {
    const char* options;
    double tolerance;
  };
  for (const Case& c : {Case{"-gmg_levels 3", 1e-12}, Case{"-gmg_levels 3 -gmg_cycle w", 1e-12},
                        Case{"-gmg_levels 3 -gmg_precision single", 1e-6},
                        Case{"-gmg_levels 3 -gmg_cycle w -gmg_precision single", 1e-6},
                        Case{"-gmg_levels 3 -gmg_smoother gs", 1e-12},
                        Case{"-gmg_levels 3 -gmg_smoother gs -gmg_precision single", 1e-6},
                        // Energy rows (3x3 block transfers): this hierarchy amplifies round-off
                        // 1e3-fold (tests/multigrid "LoopCycleOnTheHost"), hence 1e-9.
                        Case{"-gmg_levels 3 -gmg_interpolation energy", 1e-9}}) {
    Job job(PETSC_COMM_WORLD, kBlock, 8, c.options);
    auto& mg = *job.sim->multigrid();
    HEXCUT_CALL(mg.update(job.model.cells, {1.0, 0.0, true}, job.model.boundary.constraints.rows));
    std::unique_ptr<multigrid::CycleBackend> host, host_double, device;
    HEXCUT_CALL(multigrid::host_loop_cycle(mg, mg.precision(), &host));
    HEXCUT_CALL(multigrid::host_loop_cycle(mg, multigrid::Precision::double_, &host_double));
    HEXCUT_CALL(cuda::device_cycle(mg, &device));
    const std::size_t n = 3 * std::size_t(mg.level(0).layout().num_owned);
    std::vector<double> b(n), xh(n), xhd(n), xd(n);
    for (std::size_t i = 0; i < n; ++i) b[i] = std::sin(0.37 * double(i)) + 0.1;
    HEXCUT_CALL(host->apply(b.data(), xh.data()));
    HEXCUT_CALL(host_double->apply(b.data(), xhd.data()));
    HEXCUT_CALL(device->apply(b.data(), xd.data()));
    const auto d = max_difference(xh.data(), xd.data(), n);
    const double from_double = max_difference(xhd.data(), xd.data(), n).relative();
    std::printf(
        "cycle, %s: max |x_device - x_host| / max |x_host| = %.1e (from the host's "
        "double-vector cycle: %.1e)\n",
        c.options, d.relative(), from_double);
    EXPECT_GT(d.magnitude, 0.0);
    EXPECT_LT(d.relative(), c.tolerance) << c.options;
    if (mg.precision() == multigrid::Precision::single)
      EXPECT_GT(from_double, 1e-9) << c.options << ": the device cycle's vectors are not float";
  }
}

TEST(Device, SolveWithTheCudaBackendEqualsTheHost) {
  // -gmg_backend cuda through the whole static solve of the block against the host's
  // loop-layer cycle: with double vectors the same CG iterations and the same displacements
  // (to the solver's tolerance); with -gmg_precision single (float vectors on both) at most one
  // iteration apart (the two float cycles differ by round-off) and the same displacements.
  SKIP_WITHOUT_A_DEVICE();
  multigrid::set_device_cycle_factory(cuda::device_cycle, cuda::device_count);
  for (const char* precision : {"", " -gmg_precision single"}) {
    PetscInt its[2];
    std::vector<double> u[2];
    const std::string options[2] = {std::string("-gmg_levels 3 -gmg_backend host_loop") + precision,
                                    std::string("-gmg_levels 3 -gmg_backend cuda") + precision};
    for (int k = 0; k < 2; ++k) {
      Job job(PETSC_COMM_WORLD, kBlock, 8, options[k].c_str());
      job.run();
      KSPGetIterationNumber(job.sim->ksp(), &its[k]);
      u[k] = job.canonical(job.state.u);
    }
    ASSERT_EQ(u[0].size(), u[1].size());
    const double d = max_difference(u[0].data(), u[1].data(), u[0].size()).relative();
    std::printf("solve%s: %d iterations (host) / %d (cuda), max |du| / max |u| = %.1e\n", precision,
                int(its[0]), int(its[1]), d);
    if (*precision)
      EXPECT_LE(std::abs(int(its[0]) - int(its[1])), 1) << precision;
    else
      EXPECT_EQ(its[0], its[1]);
    EXPECT_LT(d, 1e-8) << precision;
  }
}

}  // namespace
}  // namespace hexcut::testing
