// The CUDA backend against the host backend (issue 13): the same functor bodies launched
// per colour on the device give the host's y += A x on every coarse level of a holed,
// two-material, corotated block, in double and in single precision, to 1e-12 relative
// (the sums at a vertex copy are formed in another order). Built only with nvcc
// (cuda/CMakeLists.txt); skips with a message when no device is visible.
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "../analysis/fixture.hpp"
#include "device_backend.hpp"
#include "multigrid/gmg.hpp"

namespace hexcut::testing {
namespace {

const std::string kBlock =
    holed_block_body() +
    "boundary:\n  fixed:\n    - where: {plane: {point: [0, 0, 0], normal: [1, 0, 0]}}\n"
    "analysis: {type: static}\n"
    "solver: {type: gmg}\n";

TEST(Device, StoredCellsApplyEqualsTheHost) {
  std::string why;
  if (cuda::device_count(&why) == 0)
    GTEST_SKIP() << "no CUDA device (" << why << "): the device tests are skipped";
  for (const char* options : {"-gmg_levels 3", "-gmg_levels 3 -gmg_precision single"}) {
    Job job(PETSC_COMM_WORLD, kBlock, 8, options);
    auto& mg = *job.sim->multigrid();
    HEXCUT_CALL(mg.update(job.model.cells, {1.0, 0.0, true}, job.model.boundary.constraints.rows));
    for (int l = 1; l < mg.num_levels(); ++l) {
      const auto& A = mg.stored_cells(l);
      const auto& lev = mg.level(l);
      assembly::CellPositions position(lev.layout().cells.size());
      for (std::size_t e = 0; e < position.size(); ++e) {
        const auto& p = lev.graph.ijk[lev.layout().cells[e]];
        position[e] = {p[0], p[1], p[2]};
      }
      const auto colours = backend::colour_cells(position);
      const std::size_t n = 3 * std::size_t(lev.layout().num_local());
      std::vector<double> x(n), host(n, 0.5), device(n, 0.5);
      for (std::size_t i = 0; i < n; ++i) x[i] = std::sin(0.37 * double(i)) + 0.1;
      A.apply_add(x.data(), host.data());
      cuda::stored_apply_add(A, colours, x.data(), device.data());
      double d = 0, m = 0;
      for (std::size_t i = 0; i < n; ++i)
        d = std::max(d, std::abs(host[i] - device[i])), m = std::max(m, std::abs(host[i]));
      std::printf("%s, level %d: max |y_device - y_host| / max |y_host| = %.1e\n", options, l,
                  d / m);
      EXPECT_LT(d / m, 1e-12) << options << ", level " << l;
    }
  }
}

}  // namespace
}  // namespace hexcut::testing
