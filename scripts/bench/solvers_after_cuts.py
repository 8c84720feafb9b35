"""Solvers after cuts (issue 4): the cube cut into 16 rods (3 + 3 blades halfway down,
off the coarse cells' boundaries), clamped at the base and spun about the vertical axis
(static). Residual reduction per unit of wall time for gmg, hypre, GAMG and Jacobi-CG,
one rank, from -hexcut_residual_history: time to reach 1e-6 and 1e-8 (set-up included),
orders of magnitude per second, ratios to Jacobi-CG; writes a PNG.
  /usr/bin/python3 scripts/bench/solvers_after_cuts.py [--n 48] [--out doc/residual_after_cuts.png]"""
import argparse
import os
import tempfile

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from benchlib import ROOT, cube_rods, finish_residual_plot, residual_history  # noqa: E402

SOLVER = """solver: {{type: {solver}, rtol: 1.0e-9, max_iterations: 100000}}
output: {{directory: {out}, name: r, fields: [displacement]}}
"""


def time_to(t, r, level):
    for ti, ri in zip(t, r):
        if ri <= level:
            return ti
    return float("nan")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--n", type=int, default=48)
    ap.add_argument("--solvers", nargs="+", default=["gmg", "hypre", "gamg", "cg-jacobi"])
    ap.add_argument("--out", default=os.path.join(ROOT, "doc", "residual_after_cuts.png"))
    a = ap.parse_args()
    fig, ax = plt.subplots(figsize=(7, 5))
    rows = {}
    with tempfile.TemporaryDirectory() as work:
        for solver in a.solvers:
            deck = cube_rods(a.n) + SOLVER.format(solver=solver, out=work)
            t, r = residual_history(deck, work, solver)
            ax.semilogy(t, r, label=solver)
            rows[solver] = (len(t) - 1, time_to(t, r, 1e-6), time_to(t, r, 1e-8))
    ref = rows.get("cg-jacobi")
    print(f"cube {a.n}^3 cut into 16 rods, 1 rank, static")
    print(f"{'solver':>10} {'its':>6} {'s to 1e-6':>10} {'s to 1e-8':>10} {'decades/s':>10} {'cg-jacobi / this (1e-8)':>24}")
    for solver, (its, t6, t8) in rows.items():
        ratio = ref[2] / t8 if ref else float("nan")
        print(f"{solver:>10} {its:>6} {t6:>10.2f} {t8:>10.2f} {8 / t8:>10.2f} {ratio:>24.1f}")
    finish_residual_plot(fig, ax, f"Cube {a.n}$^3$ cut into 16 rods, spun (static), 1 rank", a.out)


if __name__ == "__main__":
    main()
