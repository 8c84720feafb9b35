"""Convergence factor per V-cycle (standalone Richardson iteration, no CG) against
resolution, for both smoothers: a cube of n^3 cells clamped at its bottom, sheared on
top. Prints a table; the factor is the geometric mean of r_k+1 / r_k over cycles 3..12.
  /usr/bin/python3 scripts/bench/vcycle_factor.py [--sizes 16 32 64]"""
import argparse
import os
import subprocess
import tempfile

from benchlib import ENV, HEXCUT

DECK = """lattice: {{h: {h}, dims: [{n}, {n}, {n}]}}
materials: {{m: {{E: 1.0, nu: 0.3, rho: 1}}}}
geometry: [{{add: {{box: {{min: [0, 0, 0], max: [1, 1, 1]}}}}}}]
boundary:
  fixed: [{{where: {{plane: {{point: [0, 0, 0], normal: [0, 0, 1]}}}}}}]
  traction: [{{where: {{plane: {{point: [0, 0, 1], normal: [0, 0, 1]}}}}, value: [0.01, 0, -0.01]}}]
solver: {{type: gmg-cycles, cycles: 12}}
output: {{directory: {out}, name: cube, fields: [displacement]}}
"""


def factor(n, smoother, sweeps, work):
    deck = os.path.join(work, f"cube{n}.yaml")
    with open(deck, "w") as f:
        f.write(DECK.format(h=1.0 / n, n=n, out=work))
    hist = os.path.join(work, "hist.txt")
    subprocess.run([HEXCUT, deck, "-ksp_norm_type", "unpreconditioned", "-hexcut_residual_history", hist,
                    "-gmg_smoother", smoother, "-gmg_presmooth", str(sweeps), "-gmg_postsmooth", str(sweeps)],
                   env=ENV, check=True, capture_output=True)
    res = [float(line.split()[3]) for line in open(hist) if not line.startswith("#")]
    res = res[:13]  # monitor calls 0..12 (the last line repeats the end point)
    tail = res[3:13]
    return (tail[-1] / tail[0]) ** (1.0 / (len(tail) - 1))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--sizes", type=int, nargs="+", default=[16, 32, 64])
    a = ap.parse_args()
    print(f"{'cells':>8} {'GS V(1,1)':>10} {'GS V(2,2)':>10} {'Cheb V(2,2)':>12} {'Cheb V(3,3)':>12}")
    with tempfile.TemporaryDirectory() as work:
        for n in a.sizes:
            row = [factor(n, "gs", 1, work), factor(n, "gs", 2, work), factor(n, "chebyshev", 2, work),
                   factor(n, "chebyshev", 3, work)]
            print(f"{n:>5}^3 " + " ".join(f"{x:>10.3f}" if i < 2 else f"{x:>12.3f}" for i, x in enumerate(row)),
                  flush=True)


if __name__ == "__main__":
    main()
