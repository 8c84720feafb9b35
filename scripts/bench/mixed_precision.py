"""Mixed precision in hexcut's multigrid (issue 13; doc/theory.md, "Geometric multigrid"):
-gmg_precision single against double, side by side, or any two option sets (--options).
Static solves with solver gmg to rtol 1e-8 on the cantilever (n cells across, 8n x n x n),
the bunny (h 1.2 mm, 112k cells, glued base, gravity) and the n^3 cube cut into 16 rods
(static, gravity; W-cycle, the default for cut static bodies). Each case runs alternately
with each option set, `--repeats` times; the table gives the best of them: CG iterations,
hexcutSolve and gmgSetup seconds, gmgCycle seconds (all V/W-cycles), the multigrid's memory
from -gmg_view, the run's peak memory, and the relative difference of the solutions (each
against the first option set's).

  /usr/bin/python3 scripts/bench/mixed_precision.py [--n 32] [--repeats 2]
  /usr/bin/python3 scripts/bench/mixed_precision.py --options "-gmg_shared_blocks false" ""
"""
import argparse
import os
import re
import tempfile

import h5py
import numpy as np

from benchlib import ROOT, cantilever, cube_rods
from composite import run

BUNNY = """lattice: {{bounds: [[-0.051, 0.0, -0.039], [0.051, 0.098, 0.039]], h: 0.0012}}
materials: {{tissue: {{E: 1.0e5, nu: 0.3, rho: 1050}}}}
geometry: [{{add: {{mesh: {{file: {mesh}, scale: 0.01}}}}}}]
boundary:
  fixed: [{{where: {{half_space: {{point: [0, 0.003, 0], normal: [0, 1, 0]}}}}}}]
  gravity: [0, -9.81, 0]
solver: {{type: gmg, rtol: 1.0e-8}}
"""


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=32, help="cells across the cantilever and the cube")
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--options", nargs="+", default=["-gmg_precision double", "-gmg_precision single"],
                    help="option sets to compare (each one string)")
    a = ap.parse_args()
    work = tempfile.mkdtemp(prefix="hexcut-mixed-")
    out = "output: {directory: results, name: NAME, fields: [displacement]}\n"
    cases = {
        f"cantilever {8 * a.n}x{a.n}x{a.n}": re.sub(r"output:.*\n(  .*\n)*", "", cantilever(a.n, "gmg", "results")),
        "bunny h 1.2 mm": BUNNY.format(mesh=os.path.join(ROOT, "input", "meshes", "bunny.obj")),
        f"cube {a.n}^3 cut into rods": cube_rods(a.n)
        + "solver: {type: gmg, rtol: 1.0e-8}\nanalysis: {type: static}\n",
    }
    print("| case | DOFs | options | CG its | hexcutSolve s | gmgSetup s | gmgCycle s | multigrid MiB "
          "| peak MiB | solution difference |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for name, text in cases.items():
        best, u = {}, {}
        for _ in range(a.repeats):
            for k, opts in enumerate(a.options):
                tag = re.sub(r"\W+", "_", name) + f"_{k}"
                stdout, ev, h5 = run(text + out.replace("NAME", tag), work, tag,
                                     (*opts.split(), "-gmg_view"))
                its = int(re.findall(r"its (\d+)", stdout)[-1])
                mib = float(re.search(r"total ([\d.]+) MiB", stdout).group(1))
                peak = float(re.search(r"peak memory ([\d.]+) MiB", stdout).group(1))
                dofs = int(re.search(r"^\s+0\s+\d+\s+\d+\s+(\d+)", stdout, re.M).group(1))
                row = (ev["hexcutSolve"], ev["gmgSetup"], ev["gmgCycle"], its, mib, peak, dofs)
                if k not in best or row[0] < best[k][0]:
                    best[k] = row
                with h5py.File(h5) as f:
                    last = sorted(f["steps"].keys())[-1]
                    u[k] = np.array(f["steps"][last]["displacement"])
        for k, opts in enumerate(a.options):
            s, setup, c, its, mib, peak, dofs = best[k]
            diff = np.abs(u[k] - u[0]).max() / np.abs(u[0]).max()
            d = f"{diff:.1e}" if k > 0 else ""
            print(f"| {name} | {dofs} | {opts or '(defaults)'} | {its} | {s:.2f} | {setup:.2f} | {c:.2f} "
                  f"| {mib:.1f} | {peak:.1f} | {d} |")


if __name__ == "__main__":
    main()
