"""A converged result is a correct result, and every value that reaches the solver is
checked:

- a static body whose supports leave a rigid motion free stops with exit 3 naming the
  piece and the free motions (before solving; --check says the same), whatever solver;
- a solve that reports convergence while its true relative residual is far above rtol
  fails with exit 3, unless the residual is round-off (an rtol below what double
  precision attains for the system: accepted with one warning);
- nu > 0.49 is warned about (locking) at its line;
- --check applies static cuts: a piece freed by a cut fails --check as it fails the run;
- Young's moduli from an image that are <= 0 are an input error naming the image's line
  and the number of cells; NaN voxels are reported as warnings with their count."""
import os
import struct
import sys

from cli_helpers import BEAM, Checks, run, tempdir, write

# The roller case: a cube standing on its bottom face, held only in z there,
# pushed sideways and down on its top.
ROLLER = """\
lattice: {h: H, bounds: [[0, 0, 0], [1, 1, 1]]}
materials: {m: {E: 1.0e9, nu: 0.3, rho: 1000}}
geometry: [{add: {box: {min: [0, 0, 0], max: [1, 1, 1]}}}]
boundary:
  fixed: [{where: {plane: {point: [0, 0, 0], normal: [0, 0, 1]}}, components: [z]}]
  traction: [{where: {plane: {point: [0, 0, 1], normal: [0, 0, 1]}}, value: [1.0e5, 0, 1.0e6]}]
solver: {type: SOLVER}
output: {directory: OUT}
"""

BAR = (BEAM.replace("steel: {E: 200.0e9, nu: 0.3, rho: 7800}", "m: {E: 1.0e9, nu: NU, rho: 1000}")
       .replace("solver: {type: direct}", "solver: {type: SOLVER, rtol: 1.0e-10}") + "output: {directory: OUT}\n")

IMAGE = """\
lattice: {h: 0.1, bounds: [[0, 0, 0], [0.2, 0.2, 0.4]]}
materials: {bone: {E: 1.0e9, nu: 0.3, rho: 1000}}
geometry:
  - image: {file: FILE, dims: [2, 2, 4], dtype: float32, spacing: [0.1, 0.1, 0.1], threshold: -5, material: bone, youngs_scale: 1.0e9}
boundary:
  fixed: [{where: {plane: {point: [0, 0, 0], normal: [0, 0, 1]}}}]
  traction: [{where: {plane: {point: [0, 0, 0.4], normal: [0, 0, 1]}}, value: [0, 0, 1.0e6]}]
solver: {type: direct}
output: {directory: OUT}
"""


def raw_image(path, values):
    """float32 little endian, x fastest: 2 x 2 x 4 voxels, one value per z layer."""
    with open(path, "wb") as f:
        for layer in values:
            f.write(struct.pack("<4f", *layer))


def main():
    d = tempdir()
    check = Checks()

    # Free rigid motions: translation in x and y and rotation about z are left free.
    for solver, h in [("gmg", "0.1"), ("direct", "0.25"), ("hypre", "0.25")]:
        deck = write(d, f"roller_{solver}.yaml", ROLLER.replace("H", h).replace("SOLVER", solver)
                     .replace("OUT", f"{d}/{solver}"))
        for args in ([deck], ["--check", deck]):
            rc, out, err = run(args)
            check(rc == 3 and "piece 1: " in err and "free: translation x, y; rotation about z" in err
                  and not os.path.exists(f"{d}/{solver}/roller_{solver}.h5"),
                  f"roller support, {solver}, {' '.join(args[:-1])}: exit {rc}: {err.strip()[-160:]}")
    # Held in x along one edge as well: only the translation along that edge stays free.
    deck = write(d, "roller_x.yaml", ROLLER.replace("H", "0.25").replace("SOLVER", "direct").replace("OUT", d)
                 .replace("components: [z]}]", "components: [z]}, {where: {box: {min: [-0.01, -0.01, -0.01], "
                          "max: [0.01, 1.01, 0.01]}}, components: [x]}]"))
    rc, out, err = run(["--check", deck])
    check(rc == 3 and err.strip().endswith("free: translation y"), f"roller plus an edge held in x: {err.strip()[-80:]}")
    # Fully held: runs.
    deck = write(d, "held.yaml", ROLLER.replace("H", "0.25").replace("SOLVER", "direct").replace("OUT", d)
                 .replace(", components: [z]", ""))
    rc, out, err = run([deck])
    check(rc == 0, f"the same cube clamped at its base runs: exit {rc} {err.strip()}")

    # The true residual decides, with round-off as the only excuse. An absolute tolerance
    # that stops CG before its first iteration: "converged", x = 0, true residual 1 and
    # backward error 1: exit 3.
    for solver in ("gmg", "cg-jacobi"):
        deck = write(d, f"atol_{solver}.yaml", BAR.replace("NU", "0.3").replace("SOLVER", solver)
                     .replace("OUT", f"{d}/atol_{solver}"))
        rc, out, err = run([deck, "-ksp_atol", "1e30"])
        check(rc == 3 and "CONVERGED_ATOL, 0 iterations" in err and "relative residual ||b - Ax||/||b|| = 1 " in err
              and "not round-off (backward error 1 = " in err,
              f"bar, -ksp_atol 1e30, {solver}: exit {rc}: {err.strip()[-300:]}")
    # An rtol below what double precision attains: 1e-16 on the bar (kappa >= 1e4), and
    # nu = 0.499999 at rtol 1e-10 (||A|| ||x|| / ||b|| = 5e7: the true residual stops near
    # 3e-9 for CG and MUMPS alike). Both end at the round-off level (backward error below
    # eps): the result is accepted, with one warning per run (a dynamic run's 3 solves
    # included), and the residual reached is what the result file records.
    dynamic = "analysis: {type: dynamic, dt: 1.0e-2, steps: 3}\n"
    for solver, nu, rtol, analysis in [("direct", "0.3", "1.0e-16", ""), ("gmg", "0.3", "1.0e-16", dynamic),
                                       ("gmg", "0.499999", "1.0e-10", ""), ("direct", "0.499999", "1.0e-10", "")]:
        name = f"roundoff_{solver}_{nu}{'_dyn' if analysis else ''}"
        deck = write(d, f"{name}.yaml", BAR.replace("NU", nu).replace("SOLVER", solver).replace("OUT", f"{d}/{name}")
                     .replace("rtol: 1.0e-10", f"rtol: {rtol}") + analysis)
        rc, out, err = run([deck])
        warned = err.count("at the round-off level of double precision for this system (backward error ")
        ok = rc == 0 and warned == 1 and f"rtol {float(rtol):.3g} is below what any solver attains here" in err
        if ok:
            import h5py
            with h5py.File(f"{d}/{name}/{name}.h5") as f:
                res = f["/solver_history/relative_residual"][...]
            # Above 10 x rtol (else there was nothing to excuse), far below anything a
            # wrong result would show.
            ok = res.size == (3 if analysis else 1) and res.max() > 10 * float(rtol) and res.max() < 1e-7
        check(ok, f"bar, nu = {nu}, rtol {rtol}, {solver}{', dynamic' if analysis else ''}: exit {rc}, "
              f"{warned} warnings: {err.strip()[-300:]}")
        if nu == "0.499999":
            check(f"{deck}:3: warning: nu = 0.499999 > 0.49: trilinear displacement elements lock" in err,
                  f"nu = 0.499999 warns at its line: {err.strip()[:200]}")

    # --check applies static cuts: a cut that frees the tip fails --check like the run.
    cut = write(d, "cut.yaml", BAR.replace("NU", "0.3").replace("SOLVER", "direct").replace("OUT", d)
                + "cuts:\n  - blade: {polygon: [[0.55, -1, -1], [0.55, 1, -1], [0.55, 1, 1], [0.55, -1, 1]]}\n")
    rc, out, err = run(["--check", cut])
    check(rc == 3 and "piece 2: 16 cells, box [0.6, 0, 0] - [1, 0.2, 0.2] m, unsupported" in err and "unsupported" in err, f"--check with a freeing cut: exit {rc}: {err.strip()[-160:]}")

    # Images: E <= 0 is an error at the image's line; NaN voxels are counted in warnings.
    raw_image(f"{d}/ct.raw", [[1.0] * 4, [-1.0] * 4, [1.0] * 4, [1.0] * 4])
    deck = write(d, "ct.yaml", IMAGE.replace("FILE", "ct.raw").replace("OUT", d))
    rc, out, err = run([deck])
    check(rc == 2 and f"{deck}:4: image: Young's modulus" in err and "in 4 filled cell(s)" in err
          and "-1e+09 Pa" in err, f"negative E from an image: exit {rc}: {err.strip()}")
    raw_image(f"{d}/inf.raw", [[1.0] * 4, [1.0] * 4, [float("inf"), 1.0, 1.0, 1.0], [1.0] * 4])
    deck = write(d, "inf.yaml", IMAGE.replace("FILE", "inf.raw").replace("OUT", d))
    rc, out, err = run(["--check", deck])
    check(rc == 2 and "in 1 filled cell(s)" in err, f"infinite E from an image: exit {rc}: {err.strip()}")
    raw_image(f"{d}/nan.raw", [[1.0] * 4, [float("nan"), 1.0, float("nan"), 1.0], [1.0] * 4, [1.0] * 4])
    deck = write(d, "nan.yaml", IMAGE.replace("FILE", "nan.raw").replace("OUT", d))
    rc, out, err = run(["--check", deck])
    check(rc == 0 and f"{deck}:4: warning: 2 of 16 voxels are NaN: they count as empty" in err and "14 cells" in out,
          f"NaN voxels of a thresholded image: exit {rc}: {err.strip()} {out.strip()}")
    deck = write(d, "nan_youngs.yaml", IMAGE.replace("FILE", "nan.raw").replace("OUT", d)
                 .replace("  - image", "  - add: {box: {min: [0, 0, 0], max: [1, 1, 1]}}\n  - image")
                 .replace("threshold: -5, material: bone, ", ""))
    rc, out, err = run(["--check", deck])
    check(rc == 0 and f"{deck}:5: warning: 2 filled cell(s) sample a NaN voxel of this image and keep their "
          "material's E" in err, f"NaN voxels of a Young's modulus image: exit {rc}: {err.strip()}")

    # A CT calibration: HU -> density -> E = a rho^b with a floor, per cell (here one voxel
    # each) in the result's cell_youngs_modulus, against the law written out.
    hu = [1000.0, -1000.0, -1240.0, 500.0]
    raw_image(f"{d}/hu.raw", [[v] * 4 for v in hu])
    calibrated = (IMAGE.replace("FILE", "hu.raw").replace("OUT", f"{d}/cal")
                  .replace("youngs_scale: 1.0e9}", "calibration: {density: {slope: 0.0008, intercept: 1.0}, "
                           "youngs: {a: 6.85e9, b: 1.49}, E_min: 1.0e7}}").replace("threshold: -5", "threshold: -2000"))
    deck = write(d, "hu.yaml", calibrated)
    rc, out, err = run([deck])
    check(rc == 0, f"calibrated CT image: exit {rc}: {err.strip()[-300:]}")
    if rc == 0:
        import h5py
        with h5py.File(f"{d}/cal/hu.h5") as f:
            E = f["/mesh/cell_youngs_modulus"][()]
            z = f["/mesh/cell_lattice_index"][()][:, 2]  # the layer of each cell
        want = [max(6.85e9 * max(0.0008 * v + 1.0, 0.0) ** 1.49, 1.0e7) for v in hu]
        worst = max(abs(E[c] - want[z[c]]) / want[z[c]] for c in range(len(E)))
        check(len(E) == 16 and worst < 1e-12, f"calibrated E per cell: {len(E)} cells, worst relative error {worst:.1e}")
    # Voxels of density <= 0 without a floor give E = 0: an error, not a silent zero.
    raw_image(f"{d}/air.raw", [[-2000.0] * 4] + [[v] * 4 for v in hu[1:]])
    air = write(d, "air.yaml", calibrated.replace("hu.raw", "air.raw").replace(", E_min: 1.0e7", "")
                .replace("threshold: -2000", "threshold: -3000"))
    rc, out, err = run(["--check", air])
    check(rc == 2 and "in 4 filled cell(s)" in err and "calibration.E_min" in err,
          f"calibrated E = 0 without E_min: exit {rc}: {err.strip()}")
    bad = write(d, "hu_bad.yaml", calibrated.replace("youngs: {a: 6.85e9, b: 1.49}, ", ""))
    rc, out, err = run(["--check", bad])
    check(rc == 2 and f"{bad}:4:" in err and "needs 'density" in err,
          f"calibration without youngs: exit {rc}: {err.strip()}")
    return check.finish()


if __name__ == "__main__":
    sys.exit(main())
