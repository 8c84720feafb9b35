// Operator throughput on one core: DOF/s of y = A x for the same cantilever system,
//  - assembled: PETSc MatMult on the AIJ matrix (block size 3, inodes);
//  - matrix-free: hexcut's multigrid fine operator (per-material K, no 24x24 per cell),
//    with identity rotations (linear) and with rotations (corotational);
//  - the same fine cells' y += A x on plain arrays with double vectors and arithmetic, and with
//    float ones (the single-precision V-cycle's: float copies of the stiffness);
//  - the multigrid's level 1 (stored Galerkin blocks), with the blocks shared by equal
//    cells (the default for linear runs) and with a block per cell (-gmg_shared_blocks false),
//    each in double and in float (-gmg_precision single);
//  - built with the CUDA backend (cuda/CMakeLists.txt) and a device visible: the fine operator
//    on the device (the same FineCellOps body, colour by colour, data resident), with and
//    without rotations, with double and float vectors, against a copy kernel's bandwidth in
//    the same run (issue 13's
//    "fraction of the measured bandwidth"); otherwise one line saying why not.
// Usage: hexcut_bench_operator [-n CELLS_ACROSS (24)] [-repeat R (20)]
// Prints a table of median times over R applications, measured side by side.
#include <petscksp.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <string>
#include <vector>

#include "analysis/model.hpp"
#include "assembly/boundary.hpp"
#include "assembly/fine_cells.hpp"
#include "assembly/operator.hpp"
#include "common/petsc_check.hpp"
#include "deck/deck.hpp"
#include "multigrid/gmg.hpp"
#ifdef HEXCUT_HAVE_CUDA
#include "device_backend.hpp"
#endif

using namespace hexcut;

namespace {

double median_seconds(int repeat, const std::function<void()>& f) {
  std::vector<double> t;
  for (int i = 0; i < repeat; ++i) {
    PetscLogDouble a, b;
    PetscTime(&a);
    f();
    PetscTime(&b);
    t.push_back(b - a);
  }
  std::sort(t.begin(), t.end());
  return t[t.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
  PetscCall(PetscInitialize(&argc, &argv, nullptr, nullptr));
  PetscInt n = 24, repeat = 20;
  PetscCall(PetscOptionsGetInt(nullptr, nullptr, "-n", &n, nullptr));
  PetscCall(PetscOptionsGetInt(nullptr, nullptr, "-repeat", &repeat, nullptr));
  const double h = 0.125 / double(n);
  const std::string yaml =
      "lattice: {h: " + std::to_string(h) + ", dims: [" + std::to_string(8 * n) + ", " +
      std::to_string(n) + ", " + std::to_string(n) + "]}\n" +
      "materials: {steel: {E: 200.0e9, nu: 0.3, rho: 7800}}\n"
      "geometry: [{add: {box: {min: [0, 0, 0], max: [1.0, 0.125, 0.125]}}}]\n"
      "boundary: {fixed: [{where: {plane: {point: [0, 0, 0], normal: [1, 0, 0]}}}]}\n"
      "solver: {type: gmg}\n";
  {  // everything PETSc owns is destroyed before PetscFinalize
    auto deck = deck::parse_deck(yaml, "bench.yaml");
    analysis::Model model;
    PetscCall(analysis::build_model(PETSC_COMM_WORLD, deck, 8, &model));
    const assembly::OperatorWeights w{1.0, 0.0, true};
    Mat A;
    PetscCall(assembly::create_matrix(PETSC_COMM_WORLD, model.copies, model.layout, &A));
    PetscCall(assembly::assemble_constrained_matrix(model.dm, model.layout, model.cells, w,
                                                    model.boundary.constraints, A));
    // The default (automatic) hierarchy: only its fine-level operator is timed, but a
    // one-level hierarchy would factor the whole fine matrix as its coarsest level.
    multigrid::Options opt;
    multigrid::Multigrid mg(PETSC_COMM_WORLD, model.lattice, model.copies, model.partition,
                            model.layout, model.dm, opt);
    mg.update(model.cells, w, model.boundary.constraints.rows);
    Vec x, y;
    PetscCall(MatCreateVecs(A, &x, &y));
    PetscCall(VecSet(x, 1.0));
    PetscInt N;
    PetscCall(VecGetSize(x, &N));
    MatInfo info;
    PetscCall(MatGetInfo(A, MAT_GLOBAL_SUM, &info));
    const double t_aij =
        median_seconds(int(repeat), [&] { check_petsc(MatMult(A, x, y), "MatMult"); });
    const double t_mf =
        median_seconds(int(repeat), [&] { check_petsc(mg.apply_fine(x, y), "apply"); });
    // The fine cells' y += A x on plain local arrays, with double and with float vectors (the
    // single-precision V-cycle's, -gmg_backend host_loop -gmg_precision single): the same
    // cells, in double and in float arithmetic (FineCellOpsSingle).
    double t_fine_vectors[2];
    {
      const assembly::FineCells fine(model.layout, model.cells, w, true);
      const auto values = 3 * std::size_t(fine.layout().num_local());
      std::vector<double> xd(values, 1.0), yd(values, 0.0);
      std::vector<float> xs(values, 1.0f), ys(values, 0.0f);
      t_fine_vectors[0] =
          median_seconds(int(repeat), [&] { fine.apply_add(xd.data(), yd.data()); });
      t_fine_vectors[1] =
          median_seconds(int(repeat), [&] { fine.apply_add(xs.data(), ys.data()); });
    }
    // Level 1's stored cells, shared and a block per cell (two hierarchies side by side).
    struct LevelTiming {
      double seconds;
      PetscInt dofs, cells, blocks;
    };
    const auto time_level1 = [&](multigrid::Multigrid& m) {
      Vec x1, y1;
      check_petsc(m.create_vector(1, &x1), "vector");
      check_petsc(VecDuplicate(x1, &y1), "vector");
      check_petsc(VecSet(x1, 1.0), "set");
      LevelTiming t{};
      t.seconds =
          median_seconds(int(repeat), [&] { check_petsc(m.apply_level(1, x1, y1), "apply"); });
      check_petsc(VecGetSize(x1, &t.dofs), "size");
      t.cells = PetscInt(m.stored_cells(1).num_cells());
      t.blocks = PetscInt(m.stored_cells(1).num_blocks());
      check_petsc(VecDestroy(&x1), "destroy");
      check_petsc(VecDestroy(&y1), "destroy");
      return t;
    };
    const LevelTiming t_shared = time_level1(mg);
    // The same level without sharing, and both in single precision, each in a hierarchy
    // of its own.
    const auto time_variant = [&](bool shared, multigrid::Precision precision) {
      multigrid::Options o = opt;
      o.shared_blocks = shared;
      o.precision = precision;
      multigrid::Multigrid m(PETSC_COMM_WORLD, model.lattice, model.copies, model.partition,
                             model.layout, model.dm, o);
      m.update(model.cells, w, model.boundary.constraints.rows);
      return time_level1(m);
    };
    const LevelTiming t_own = time_variant(false, multigrid::Precision::double_);
    const LevelTiming t_shared_single = time_variant(true, multigrid::Precision::single);
    const LevelTiming t_own_single = time_variant(false, multigrid::Precision::single);
    // Corotational: the same operator with (non-trivial) per-cell rotations (a linear
    // model stores none).
    model.cells.rotation.resize(9 * model.cells.lambda.size());
    for (std::size_t e = 0; e < model.cells.lambda.size(); ++e) {
      const double c = std::cos(0.1 + 1e-6 * double(e)), s = std::sin(0.1 + 1e-6 * double(e));
      const double R[9] = {c, -s, 0, s, c, 0, 0, 0, 1};
      std::copy(R, R + 9, &model.cells.rotation[9 * e]);
    }
    model.cells.identity_rotations = false;
    mg.update(model.cells, w, model.boundary.constraints.rows);
    const double t_mf_rot =
        median_seconds(int(repeat), [&] { check_petsc(mg.apply_fine(x, y), "apply"); });
    PetscCall(
        PetscPrintf(PETSC_COMM_WORLD,
                    "operator throughput, %d DOFs, %d cells, %d ranks, median of %d applications\n"
                    "%-34s %10s %12s %14s\n",
                    int(N), int(model.lattice.num_cells()), model.layout.num_ranks, int(repeat),
                    "operator", "ms/apply", "MDOF/s", "bytes/DOF"));
    const double matrix_bytes = info.nz_used * 12.0 / double(N);  // AIJ: value + column index
    const double mf_bytes = (12.0 * model.lattice.num_cells()) * 8.0 / double(N);
    const double mf_rot_bytes = (12.0 * model.lattice.num_cells()) * 8.0 / double(N);
    auto row = [&](const char* name, double t, double bytes) {
      PetscPrintf(PETSC_COMM_WORLD, "%-34s %10.2f %12.2f %14.1f\n", name, 1e3 * t,
                  1e-6 * double(N) / t, bytes);
    };
    row("assembled AIJ MatMult", t_aij, matrix_bytes);
    row("matrix-free, identity rotations", t_mf, mf_bytes);
    row("matrix-free, with rotations", t_mf_rot, mf_rot_bytes);
    row("fine cells, double vectors", t_fine_vectors[0], mf_bytes);
    row("fine cells, float vectors", t_fine_vectors[1], mf_bytes);
    // Level 1: MDOF/s of level 1's DOFs; bytes/DOF of its packed blocks (300 numbers each).
    const auto level_row = [&](const char* name, const LevelTiming& t, double bytes) {
      PetscPrintf(PETSC_COMM_WORLD, "%-34s %10.2f %12.2f %14.1f   (%d cells, %d blocks)\n", name,
                  1e3 * t.seconds, 1e-6 * double(t.dofs) / t.seconds,
                  300.0 * bytes * double(t.blocks) / double(t.dofs), int(t.cells), int(t.blocks));
    };
    level_row("level 1, shared blocks", t_shared, 8.0);
    level_row("level 1, a block per cell", t_own, 8.0);
    level_row("level 1, shared blocks, float", t_shared_single, 4.0);
    level_row("level 1, a block per cell, float", t_own_single, 4.0);
#ifdef HEXCUT_HAVE_CUDA
    // The device rows: the fine cells as the multigrid applies them (unmasked here), linear
    // and with the rotations above. Traffic model for the bandwidth fraction: each DOF of x
    // read once and of y read and written once (24 bytes per DOF), and per cell its 8
    // corners and kind (36 bytes) and, rotated, its rotation (72 bytes): what a perfectly
    // cached gather and scatter would move.
    std::string why;
    if (model.layout.num_ranks == 1 && cuda::device_count(&why) > 0) {
      const auto colours = backend::colour_cells(mg.cell_positions(0));
      const double cells = double(model.layout.cells.size());
      for (const bool rotated : {false, true}) {
        model.cells.identity_rotations = !rotated;
        const assembly::FineCells fine(model.layout, model.cells, w, true);
        cuda::FineTables tables;
        const auto arrays = cuda::fine_cell_arrays(fine, colours, &tables);
        const auto t =
            cuda::time_fine_apply(fine.data(), tables, arrays, int(repeat), std::size_t(1) << 28);
        for (const bool single : {false, true}) {
          // Float vectors: 12 bytes per DOF instead of 24; the cells' bytes are the same.
          const double bytes =
              (single ? 12.0 : 24.0) * double(N) + cells * (rotated ? 108.0 : 36.0);
          const double s = single ? t.fine_apply_single_seconds : t.fine_apply_seconds;
          const std::string name =
              std::string(rotated ? "device, with rotations" : "device, identity rotations") +
              (single ? ", float" : "");
          PetscPrintf(PETSC_COMM_WORLD,
                      "%-34s %10.3f %12.1f %14.1f   (%.0f GB/s: %.0f %% of the copy kernel's "
                      "%.0f GB/s, %s)\n",
                      name.c_str(), 1e3 * s, 1e-6 * double(N) / s, bytes / double(N),
                      1e-9 * bytes / s, 100.0 * bytes / s / t.copy_bandwidth,
                      1e-9 * t.copy_bandwidth, t.device.c_str());
        }
      }
    } else {
      PetscPrintf(PETSC_COMM_WORLD, "device rows: not measured (%s)\n",
                  model.layout.num_ranks > 1 ? "one rank only" : why.c_str());
    }
#else
    PetscPrintf(PETSC_COMM_WORLD, "device rows: not measured (built without the CUDA backend)\n");
#endif
    PetscCall(PetscPrintf(PETSC_COMM_WORLD,
                          "bytes/DOF: operator storage only (matrix values+indices; matrix-free: "
                          "lambda, mu, rho, R per "
                          "cell); ratio matrix-free/AIJ time: %.2f\n",
                          t_mf / t_aij));
    PetscCall(VecDestroy(&x));
    PetscCall(VecDestroy(&y));
    PetscCall(MatDestroy(&A));
    PetscCall(analysis::destroy_model(&model));
  }
  PetscCall(PetscFinalize());
  return 0;
}
