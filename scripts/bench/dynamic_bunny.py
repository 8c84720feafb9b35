"""Dynamic corotational steps on the Stanford bunny (~270k cells): per step the
rotations, the fine operator data and every Galerkin coarse block are rebuilt, then 2
V-cycles (solver gmg-cycles) solve the Newmark system, once per step: rotations: lagged,
the theses' real-time mode (the default, iterated rotations, solves 3-4 times per step;
doc/theory.md "Mid-point corotational step"). Prints steps/s for 1 and 2 ranks.
  /usr/bin/python3 scripts/bench/dynamic_bunny.py [--h 0.0009] [--steps 10] [--ranks 1 2]
      [--options "-gmg_rebuild_tol 1e-2"]   (extra PETSc/hexcut options, one run each)"""
import argparse
import os
import re
import subprocess
import tempfile

from benchlib import ENV, HEXCUT, ROOT

DECK = """lattice: {{bounds: [[-0.051, 0.0, -0.039], [0.051, 0.098, 0.039]], h: {h}}}
materials: {{tissue: {{E: 1.0e5, nu: 0.3, rho: 1050}}}}
geometry: [{{add: {{mesh: {{file: {mesh}, scale: 0.01}}}}}}]
boundary:
  fixed: [{{where: {{half_space: {{point: [0, 0.003, 0], normal: [0, 1, 0]}}}}}}]
  gravity: [0, -9.81, 0]
analysis: {{type: dynamic, formulation: corotational, rotations: lagged, dt: 0.005, steps: {steps}}}
solver: {{type: gmg-cycles, cycles: 2}}
output: {{directory: {out}, name: bunny, every: 1000, fields: [displacement]}}
"""


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--h", type=float, default=0.0009)
    ap.add_argument("--steps", type=int, default=10)
    ap.add_argument("--ranks", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--options", nargs="+", default=[""], help="option sets to compare, e.g. '' '-gmg_rebuild_tol 1e-2'")
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as work:
        deck = os.path.join(work, "bunny.yaml")
        with open(deck, "w") as f:
            f.write(DECK.format(h=a.h, steps=a.steps, out=work, mesh=os.path.join(ROOT, "input/meshes/bunny.obj")))
        print(f"{'options':>24} {'ranks':>5} {'cells':>8} {'DOFs':>9} {'steps':>6} {'s/step':>8} {'steps/s':>8} "
              f"{'assembly s/step':>16} {'solve s/step':>13}")
        for k, (r, opts) in enumerate([(r, o) for r in a.ranks for o in a.options]):
            # A folder per run: hexcut never overwrites an earlier result.
            out = ["-hexcut_output_directory", os.path.join(work, f"run{k}")]
            cmd = (["mpiexec", "-n", str(r)] if r > 1 else []) + [HEXCUT, deck, "-log_view"] + out + opts.split()
            p = subprocess.run(cmd, env=ENV, capture_output=True, text=True, check=True)
            cells = int(re.search(r"(\d+) cells", p.stdout).group(1))
            dofs = int(re.search(r"(\d+) DOFs", p.stdout).group(1))
            asm = float(re.search(r"^hexcutAssembly\s+\d+\s+[\d.]+\s+([\d.e+-]+)", p.stdout, re.M).group(1))
            sol = float(re.search(r"^hexcutSolve\s+\d+\s+[\d.]+\s+([\d.e+-]+)", p.stdout, re.M).group(1))
            # Time-stepping wall time: assembly + solve + right-hand sides, from the progress line.
            wall = float(re.findall(r"wall ([\d.]+) s", p.stdout)[-1])
            per = wall / a.steps
            print(f"{opts or '(defaults)':>24} {r:>5} {cells:>8} {dofs:>9} {a.steps:>6} {per:>8.3f} {1 / per:>8.2f} {asm / a.steps:>16.3f} "
                  f"{sol / a.steps:>13.3f}", flush=True)


if __name__ == "__main__":
    main()
