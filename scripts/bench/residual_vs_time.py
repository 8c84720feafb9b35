"""Residual against wall time for every solver on one problem (the 400k-DOF cantilever
of scripts/bench/solvers), one rank, from -hexcut_residual_history; writes a PNG.
  /usr/bin/python3 scripts/bench/residual_vs_time.py [--n 24] [--out doc/residual_vs_time.png]"""
import argparse
import os
import tempfile

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from benchlib import ROOT, cantilever, finish_residual_plot, residual_history  # noqa: E402
def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--n", type=int, default=24)
    ap.add_argument("--solvers", nargs="+", default=["gmg", "gamg", "hypre", "cg-jacobi", "direct"])
    ap.add_argument("--out", default=os.path.join(ROOT, "doc", "residual_vs_time.png"))
    a = ap.parse_args()
    fig, ax = plt.subplots(figsize=(7, 5))
    with tempfile.TemporaryDirectory() as work:
        for solver in a.solvers:
            t, r = residual_history(cantilever(a.n, solver, work, name="r"), work, solver)
            if solver == "direct":  # one point at the end of the factorization + solve
                ax.semilogy([0, t[-1]], [1, max(r[-1], 1e-16)], "k:", marker="o", label="direct (MUMPS)")
            else:
                ax.semilogy(t, r, label=solver)
            print(f"{solver:>10}: {len(t) - 1:>5} iterations, {t[-1]:8.2f} s to {r[-1]:.1e}")
    finish_residual_plot(fig, ax, f"Cantilever, {3 * (8 * a.n + 1) * (a.n + 1) ** 2} DOFs, 1 rank", a.out)


if __name__ == "__main__":
    main()
