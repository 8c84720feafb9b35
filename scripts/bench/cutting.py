"""Cost of a cut against the cost of a time step (issue 4): the link tests and the
topology rebuild (vertex copies, DOF layout, DM, state transfer, new solver and multigrid
hierarchy) for the cube cut into rods and for the bunny, at >= 200k cells, dynamic corotational with 2 V-cycles per step (the theses'
real-time mode). Figures come from PETSc -log_view events.
  /usr/bin/python3 scripts/bench/cutting.py [--cube 64] [--bunny-h 0.0009] [--ranks 1]"""
import argparse
import os
import re
import subprocess
import tempfile

from benchlib import ENV, HEXCUT, ROOT, cube_rods

COMMON = """analysis: {{type: dynamic, formulation: corotational, rotations: lagged, dt: {dt}, steps: {steps}, rayleigh: [2.0, 0.0]}}
solver: {{type: gmg-cycles, cycles: 2}}
output: {{directory: {out}, name: {name}, every: 1000, fields: [displacement]}}
"""

BUNNY = """lattice: {{bounds: [[-0.051, 0.0, -0.039], [0.051, 0.098, 0.039]], h: {h}}}
materials: {{tissue: {{E: 1.0e5, nu: 0.45, rho: 1050}}}}
geometry: [{{add: {{mesh: {{file: {mesh}, scale: 0.01}}}}}}]
boundary:
  fixed: [{{where: {{half_space: {{point: [0, 0.003, 0], normal: [0, 1, 0]}}}}}}]
  gravity: [0, -9.81, 0]
cuts:
  - blade: {{cylinder: {{start: [0.015, 0.03, -0.06], end: [0.015, 0.03, 0.06], radius: 0.01, segments: 32}}}}
    time: {t_cut}
"""


def event(log, name):
    m = re.search(rf"^{name}\s+(\d+)\s+[\d.]+\s+([\d.e+-]+)", log, re.M)
    return (int(m.group(1)), float(m.group(2))) if m else (0, 0.0)


def run(deck_text, work, name, ranks):
    deck = os.path.join(work, name + ".yaml")
    with open(deck, "w") as f:
        f.write(deck_text)
    cmd = (["mpiexec", "-n", str(ranks)] if ranks > 1 else []) + [HEXCUT, deck, "-log_view"]
    p = subprocess.run(cmd, env=ENV, capture_output=True, text=True, check=True)
    cells = int(re.search(r"(\d+) cells", p.stdout).group(1))
    links = int(re.search(r"disconnected (\d+) links", p.stdout).group(1))
    return cells, links, p.stdout


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--cube", type=int, default=64, help="cells per cube side")
    ap.add_argument("--bunny-h", type=float, default=0.0009)
    ap.add_argument("--ranks", type=int, default=1)
    ap.add_argument("--steps", type=int, default=6)
    a = ap.parse_args()
    dt = 0.01
    t_cut = 2.5 * dt  # acts in step 3
    print(f"{'case':>6} {'ranks':>5} {'cells':>8} {'links cut':>9} {'link tests s':>12} {'rebuild s':>9} "
          f"{'cut s':>7} {'step s':>7} {'cut / step':>10}")
    with tempfile.TemporaryDirectory() as work:
        common = lambda name: COMMON.format(dt=dt, steps=a.steps, out=work, name=name)
        cases = {
            "cube": cube_rods(a.cube, t_cut) + common("cube"),
            "bunny": BUNNY.format(h=a.bunny_h, mesh=os.path.join(ROOT, "input/meshes/bunny.obj"), t_cut=t_cut)
            + common("bunny"),
        }
        for name, text in cases.items():
            cells, links, log = run(text, work, name, a.ranks)
            _, t_links = event(log, "hexcutCutLinks")
            _, t_rebuild = event(log, "hexcutRebuild")
            n_asm, t_asm = event(log, "hexcutAssembly")
            _, t_solve = event(log, "hexcutSolve")
            # A corotational step: its operator set-up (rotations, fine data, Galerkin
            # blocks above changed cells) and its 2 V-cycles, averaged over the run. The
            # first step after a cut sets the new hierarchy up in full (as the first step
            # of any run does); that is inside the average, not in "cut s".
            step = (t_asm + t_solve) / n_asm
            cut = t_links + t_rebuild
            print(f"{name:>6} {a.ranks:>5} {cells:>8} {links:>9} {t_links:>12.3f} {t_rebuild:>9.3f} "
                  f"{cut:>7.3f} {step:>7.3f} {cut / step:>10.2f}", flush=True)


if __name__ == "__main__":
    main()
