"""Coarse spaces after cuts, on thin pieces and across coefficient jumps (issue 10; doc/theory.md,
"Coarse spaces after cuts and on thin pieces"). A family of n^3 bodies clamped at their base
under gravity, each solved to rtol 1e-8 by

  trilinear V / W  the default multigrid (trilinear interpolation, point-block Jacobi Chebyshev;
                   the W-cycle is the default for static analyses of cut bodies),
  robust V         energy-minimizing interpolation where coarse cells are irregular, and there
                   Chebyshev on Schwarz patches with degree growing 2x per level
                   (-gmg_interpolation energy -gmg_schwarz_from 1 -gmg_degree_growth 2),
  smoothed V / W   the transfer to level 1 smoothed, P <- (I - omega D^-1 A) P, on the rows near
                   irregular coarse cells, assembled P^T A P levels below
                   (-gmg_interpolation smoothed),
  smoothed2 W      the same with the transfers to levels 1 and 2 smoothed
                   (-gmg_smoothed_levels 2),
  depth V / W      today's default depth (the duplication rule, -gmg_max_duplication from
                   --max-duplication, its share of the fine DOFs 0.1),
  depth1 V / W     the same rule allowed to stop at level 1 (-gmg_duplication_share 1),
  gamg, hypre      PETSc's GAMG and hypre BoomerAMG (CG, rigid-body near-null space),

on cubes, blade grids (aligned/rotated, every 3 or 6 cells), radial cuts into a cylinder,
stamps, thin and porous bodies and material jumps (cases()), one run per case and configuration, side by side. Prints per case and configuration: CG
iterations, the standalone V-cycle convergence factor (Richardson on the multigrid alone,
geometric mean of r_k+1/r_k over cycles 3..12), set-up and solve seconds (the result file's
solver history; set-up includes the operator's assembly, where the multigrid builds its
hierarchy), and the multigrid's memory over an assembled level-0 matrix (-gmg_view).
  /usr/bin/python3 scripts/bench/coarse_spaces.py [--n 24] [--cases uncut aligned3 ...]
      [--configs "trilinear W" "smoothed W" ...] [--levels 2 3 4]
--levels runs every multigrid configuration at those depths (0: the automatic one)."""
import argparse
import math
import os
import re
import subprocess
import tempfile

import h5py
import numpy as np
from scipy import ndimage

from benchlib import ENV, HEXCUT

HEAD = """lattice: {{h: {h}, dims: [{n}, {n}, {n}]}}
materials: {{soft: {{E: 1.0e6, nu: {nu}, rho: 1000}}, inc: {{E: {E_inc}, nu: 0.3, rho: 1000}}}}
geometry:
{geometry}
boundary:
  fixed: [{{where: {{plane: {{point: [0, 0, 0], normal: [0, 0, 1]}}}}}}]
  gravity: [0, 0, -9.81]
{cuts}analysis: {analysis}
solver: {{type: {solver}, rtol: 1.0e-8, max_iterations: 2000}}
output: {{directory: {out}, name: r, fields: [displacement]}}
"""
BOX = "  - add: {box: {min: [0, 0, 0], max: [1, 1, 1]}}\n    material: soft"
CYLINDER = "  - add: {cylinder: {start: [0.5, 0.5, 0], end: [0.5, 0.5, 1], radius: 0.48}}\n    material: soft"

# The automatic depth before the duplication rule (its default since 2026-12-03), so that
# these configurations keep measuring what doc/benchmarks.md recorded for them.
OLD_DEPTH = ["-gmg_max_duplication", "-1"]
CONFIGS = {
    "trilinear V": ("gmg", OLD_DEPTH + ["-gmg_cycle", "v"]),
    "trilinear W": ("gmg", OLD_DEPTH + ["-gmg_cycle", "w"]),
    "robust V": ("gmg", OLD_DEPTH + ["-gmg_cycle", "v", "-gmg_interpolation", "energy", "-gmg_schwarz_from", "1",
                         "-gmg_degree_growth", "2"]),
    "smoothed V": ("gmg", OLD_DEPTH + ["-gmg_cycle", "v", "-gmg_interpolation", "smoothed"]),
    "smoothed W": ("gmg", OLD_DEPTH + ["-gmg_cycle", "w", "-gmg_interpolation", "smoothed"]),
    "smoothed2 V": ("gmg", OLD_DEPTH + ["-gmg_cycle", "v", "-gmg_interpolation", "smoothed",
                            "-gmg_smoothed_levels", "2"]),
    "smoothed2 W": ("gmg", OLD_DEPTH + ["-gmg_cycle", "w", "-gmg_interpolation", "smoothed",
                            "-gmg_smoothed_levels", "2"]),
    # The automatic depth stops before a level whose coarse cells have outgrown the pieces
    # (-gmg_max_duplication: extra coarse cells per occupied position).
    "depth V": ("gmg", ["-gmg_cycle", "v", "-gmg_max_duplication", "DUP"]),
    "depth W": ("gmg", ["-gmg_cycle", "w", "-gmg_max_duplication", "DUP"]),
    "gamg": ("gamg", []),
    "hypre": ("hypre", []),
}
# The same rule as it was from 2026-12-03 to 2026-12-07: allowed to stop at level 1
# (-gmg_duplication_share 1; the default 0.1 keeps it to levels of 1/10 of the fine DOFs).
for _cycle in "VW":
    CONFIGS[f"depth1 {_cycle}"] = ("gmg", CONFIGS[f"depth {_cycle}"][1] + ["-gmg_duplication_share", "1"])

DEFAULT_CONFIGS = ["trilinear V", "trilinear W", "robust V", "smoothed W", "gamg", "hypre"]


def blade_grid(spacing, angle, depth=0.5, n=24):
    """Vertical blades every `spacing` cells in x and y (3 cells off the coarse cells'
    boundaries for an even spacing), from the top down to `depth`, rotated by `angle`
    degrees about the vertical axis through the centre."""
    a = math.radians(angle)
    ca, sa = math.cos(a), math.sin(a)

    def rot(x, y):
        x, y = x - 0.5, y - 0.5
        return 0.5 + ca * x - sa * y, 0.5 + sa * x + ca * y

    out = []
    p = (3 + 0.3) / n
    while p < 1.0:
        for d in (0, 1):
            pts = []
            for s, z in ((-0.3, depth), (1.3, depth), (1.3, 1.1), (-0.3, 1.1)):
                x, y = (p, s) if d == 0 else (s, p)
                X, Y = rot(x, y)
                pts.append(f"[{X:.6f}, {Y:.6f}, {z}]")
            out.append("  - blade: {polygon: [" + ", ".join(pts) + "]}")
        p += spacing / n
    return "cuts:\n" + "\n".join(out) + "\n"


def radial_cuts(count, depth=0.5):
    """`count` vertical blades from the axis of the cylinder (x = y = 0.5) out past its side,
    from the top down to `depth`, at equal angles (offset by half a step from the lattice
    axes): the top of the cylinder becomes wedges, thinner than any coarse cell near the
    axis."""
    out = []
    for k in range(count):
        a = 2 * math.pi * (k + 0.5) / count
        X, Y = 0.5 + 0.6 * math.cos(a), 0.5 + 0.6 * math.sin(a)
        pts = [f"[0.5, 0.5, {depth}]", f"[{X:.6f}, {Y:.6f}, {depth}]", f"[{X:.6f}, {Y:.6f}, 1.1]",
               "[0.5, 0.5, 1.1]"]
        out.append("  - blade: {polygon: [" + ", ".join(pts) + "]}")
    return "cuts:\n" + "\n".join(out) + "\n"


def stamps(count, radius, depth=0.5):
    """A count x count array of cylinder blades (stamps) of `radius` pressed into the top of
    the cube down to `depth`: plugs joined to the body only below them."""
    out = []
    for i in range(count):
        for j in range(count):
            x, y = (i + 0.5) / count, (j + 0.5) / count
            out.append(f"  - blade: {{cylinder: {{start: [{x:.6f}, {y:.6f}, {depth}], "
                       f"end: [{x:.6f}, {y:.6f}, 1.1], radius: {radius}}}}}")
    return "cuts:\n" + "\n".join(out) + "\n"


def image(work, name, solid, n):
    """An image geometry entry for a boolean n^3 array (x fastest), kept to what touches z = 0
    (every piece supported)."""
    lab, _ = ndimage.label(solid)
    keep = np.isin(lab, np.unique(lab[:, :, 0][lab[:, :, 0] > 0]))
    path = os.path.join(work, f"{name}.raw")
    keep.astype(np.uint8).transpose(2, 1, 0).tofile(path)  # [i, j, k] -> k slowest
    h = 1.0 / n
    return (f"  - image: {{file: {path}, dims: [{n}, {n}, {n}], dtype: uint8, "
            f"spacing: [{h}, {h}, {h}], threshold: 1, material: soft}}")


def cases(work, n):
    h = 1.0 / n
    i, j, k = np.meshgrid(np.arange(n), np.arange(n), np.arange(n), indexing="ij")
    struts = ((i % 8 < 3).astype(int) + (j % 8 < 3) + (k % 8 < 3)) >= 2
    rng = np.random.default_rng(1)
    field = ndimage.gaussian_filter(rng.standard_normal((n, n, n)), 1.2, mode="wrap")
    trab = field > np.quantile(field, 0.55)
    wall = 2.5 * h
    c = {
        "uncut": dict(geometry=BOX),
        "aligned3": dict(geometry=BOX, cuts=blade_grid(3, 0, n=n)),
        "aligned6": dict(geometry=BOX, cuts=blade_grid(6, 0, n=n)),
        "rotated3": dict(geometry=BOX, cuts=blade_grid(3, 20, n=n)),
        "rotated6": dict(geometry=BOX, cuts=blade_grid(6, 20, n=n)),
        # A solid cylinder whose top half is cut into 12 wedges by radial blades; a cube with
        # a 4 x 4 array of stamps (radius 0.09, about 2 cells at 24^3) to half its depth.
        "cylinder": dict(geometry=CYLINDER),
        "radial12": dict(geometry=CYLINDER, cuts=radial_cuts(12)),
        "stamps": dict(geometry=BOX, cuts=stamps(4, 0.09)),
        "tube": dict(geometry=(
            CYLINDER + "\n" +
            f"  - subtract: {{cylinder: {{start: [0.5, 0.5, -0.1], end: [0.5, 0.5, 1.1], "
            f"radius: {0.48 - wall}}}}}")),
        "shell": dict(geometry=(
            "  - add: {sphere: {centre: [0.5, 0.5, 0.5], radius: 0.5}}\n    material: soft\n"
            f"  - subtract: {{sphere: {{centre: [0.5, 0.5, 0.5], radius: {0.5 - wall}}}}}\n"
            "  - add: {box: {min: [0.3, 0.3, 0], max: [0.7, 0.7, 0.1]}}\n    material: soft")),
        "struts": dict(geometry=image(work, "struts", struts, n)),
        "trabecular": dict(geometry=image(work, "trab", trab, n)),
        "stiff 1e3": dict(geometry=BOX + "\n  - assign: {sphere: {centre: [0.5, 0.5, 0.5], radius: 0.3}}"
                          "\n    material: inc", E_inc=1.0e9),
        "stiff 1e6": dict(geometry=BOX + "\n  - assign: {sphere: {centre: [0.5, 0.5, 0.5], radius: 0.3}}"
                          "\n    material: inc", E_inc=1.0e12),
        "soft 1e-3": dict(geometry=BOX + "\n  - assign: {sphere: {centre: [0.5, 0.5, 0.5], radius: 0.3}}"
                          "\n    material: inc", E_inc=1.0e3),
        "nu 0.45": dict(geometry=BOX, nu=0.45),
        "uncut dyn": dict(geometry=BOX, dynamic=True),
        "aligned3 dyn": dict(geometry=BOX, cuts=blade_grid(3, 0, n=n), dynamic=True),
        "rotated3 dyn": dict(geometry=BOX, cuts=blade_grid(3, 20, n=n), dynamic=True),
    }
    return c


def deck_text(case, solver, out, n):
    analysis = "{type: dynamic, dt: 0.01, end_time: 0.01}" if case.get("dynamic") else "{type: static}"
    return HEAD.format(h=1.0 / n, n=n, nu=case.get("nu", 0.3), E_inc=case.get("E_inc", 1.0e6),
                       geometry=case["geometry"], cuts=case.get("cuts", ""), analysis=analysis,
                       solver=solver, out=out)


def run(case, config, work, n, cycles=False):
    solver, opts = CONFIGS[config]
    out = os.path.join(work, "out")
    deck = os.path.join(work, "d.yaml")
    with open(deck, "w") as f:
        f.write(deck_text(case, "gmg-cycles" if cycles else solver, out, n).replace(
            "rtol: 1.0e-8, max_iterations: 2000", "cycles: 12" if cycles else
            "rtol: 1.0e-8, max_iterations: 2000"))
    hist = os.path.join(work, "hist.txt")
    log = os.path.join(work, "log.txt")
    extra = (["-ksp_norm_type", "unpreconditioned", "-hexcut_residual_history", hist] if cycles
             else ["-gmg_view", "-log_view", f":{log}"])
    p = subprocess.run([HEXCUT, deck, "--overwrite", *opts, *extra], env=ENV, capture_output=True, text=True)
    # 12 cycles short of the tolerance end with exit 3 (not converged); the history is kept.
    if p.returncode != 0 and not (cycles and p.returncode == 3):
        return {"status": f"exit {p.returncode}"}
    if cycles:
        res = [float(line.split()[3]) for line in open(hist) if not line.startswith("#")][:13]
        tail = res[3:13]
        return {"factor": (tail[-1] / tail[0]) ** (1.0 / (len(tail) - 1)) if tail[0] > 0 else float("nan")}
    with h5py.File(os.path.join(out, "r.h5"), "r") as f:
        h = f["solver_history"]
        row = {"its": int(h["iterations"][-1]), "setup": float(np.sum(h["setup_seconds"])),
               "solve": float(np.sum(h["solve_seconds"]))}
    # The multigrid's hierarchy is built with the operator (hexcutAssembly), the algebraic
    # solvers' matrix too: set-up = operator assembly + KSPSetUp, for every solver alike.
    a = re.search(r"^hexcutAssembly\s+\d+\s+[\d.]+\s+([\d.e+-]+)", open(log).read(), re.M)
    row["setup"] += float(a.group(1)) if a else float("nan")
    lv = re.search(r"hexcut gmg: (\d+) levels", p.stdout)
    row["levels"] = int(lv.group(1)) if lv else 0
    m = re.search(r"\(ratio ([\d.]+)\)", p.stdout)
    row["memory"] = float(m.group(1)) if m else float("nan")
    return row


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--n", type=int, default=24, help="cells per edge of the cube")
    ap.add_argument("--cases", nargs="+", default=None, help="subset of the cases (default: all)")
    ap.add_argument("--configs", nargs="+", default=DEFAULT_CONFIGS,
                    help="subset of " + ", ".join(CONFIGS) + " (default: " + ", ".join(DEFAULT_CONFIGS) + ")")
    ap.add_argument("--levels", type=int, nargs="+", default=[0],
                    help="multigrid depths to run (-gmg_levels; 0: the automatic depth)")
    ap.add_argument("--max-duplication", type=float, default=0.5,
                    help="-gmg_max_duplication of the 'depth' configurations (default 0.5)")
    a = ap.parse_args()
    for c in ("depth V", "depth W", "depth1 V", "depth1 W"):
        CONFIGS[c] = (CONFIGS[c][0], [str(a.max_duplication) if o == "DUP" else o for o in CONFIGS[c][1]])
    # Each multigrid configuration once per depth ("NAME L3": -gmg_levels 3); the algebraic
    # solvers once.
    configs = []
    for c in a.configs:
        solver, opts = CONFIGS[c]
        for lv in (a.levels if solver == "gmg" else [0]):
            if lv > 0:
                CONFIGS[f"{c} L{lv}"] = (solver, opts + ["-gmg_levels", str(lv)])
            configs.append(c if lv == 0 else f"{c} L{lv}")
    a.configs = list(dict.fromkeys(configs))
    with tempfile.TemporaryDirectory() as work:
        family = cases(work, a.n)
        names = a.cases or list(family)
        print(f"{a.n}^3 cells; CG iterations to 1e-8 | V-cycle factor | set-up + solve [s] | "
              "multigrid memory / assembled level-0 matrix")
        print(f"{'case':<14} {'configuration':<15} {'its':>5} {'factor':>7} {'setup':>7} {'solve':>7} "
              f"{'total':>7} {'memory':>7} {'levels':>6}")
        for name in names:
            for config in a.configs:
                r = run(family[name], config, work, a.n)
                if "its" not in r:
                    print(f"{name:<14} {config:<15} {r['status']}", flush=True)
                    continue
                fac = float("nan")
                if CONFIGS[config][0] == "gmg" and not family[name].get("dynamic"):
                    fac = run(family[name], config, work, a.n, cycles=True).get("factor", float("nan"))
                print(f"{name:<14} {config:<15} {r['its']:>5} {fac:>7.3f} {r['setup']:>7.3f} {r['solve']:>7.3f} "
                      f"{r['setup'] + r['solve']:>7.3f} {r['memory']:>7.2f} {r['levels'] or '':>6}", flush=True)


if __name__ == "__main__":
    main()
