"""Shared set-up of the benchmark scripts: where hexcut is and how to run it."""
import os

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
HEXCUT = os.path.join(os.environ.get("HEXCUT_BUILD_DIR", os.path.join(ROOT, "build")), "src", "app", "hexcut")
# Open MPI refuses root without these; benchmarks may oversubscribe small machines.
ENV = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
           OMPI_MCA_rmaps_base_oversubscribe="1")

# The cantilever of the solver comparisons: a bar of aspect 8:1:1 with n cells across.
CANTILEVER = """lattice: {{h: {h}, dims: [{nx}, {n}, {n}]}}
materials: {{steel: {{E: 200.0e9, nu: 0.3, rho: 7800}}}}
geometry: [{{add: {{box: {{min: [0, 0, 0], max: [1.0, 0.125, 0.125]}}}}}}]
boundary:
  fixed: [{{where: {{plane: {{point: [0, 0, 0], normal: [1, 0, 0]}}}}}}]
  traction:
    - where: {{plane: {{point: [1.0, 0, 0], normal: [1, 0, 0]}}}}
      value: [0, 0, -1.0e5]
solver: {{type: {solver}, rtol: 1.0e-8, max_iterations: 100000}}
output: {{directory: {out}, name: {name}, fields: [displacement]}}
"""


def cantilever(n, solver, out, name="bench"):
    """Deck text of the cantilever with n cells across."""
    return CANTILEVER.format(h=0.125 / n, nx=8 * n, n=n, solver=solver, out=out, name=name)


def residual_history(deck_text, work, name, extra=()):
    """Runs one deck with -hexcut_residual_history; returns (wall times from the start
    of set-up [s], residuals relative to the first) of its (last) solve."""
    import subprocess

    deck = os.path.join(work, f"{name}.yaml")
    with open(deck, "w") as f:
        f.write(deck_text)
    hist = os.path.join(work, f"{name}.txt")
    subprocess.run([HEXCUT, deck, "-hexcut_residual_history", hist, *extra], env=ENV, check=True,
                   capture_output=True)
    rows = [list(map(float, line.split())) for line in open(hist) if not line.startswith("#")]
    r0 = rows[0][3] if rows[0][3] > 0 else 1.0
    return [r[2] for r in rows], [r[3] / r0 for r in rows]
