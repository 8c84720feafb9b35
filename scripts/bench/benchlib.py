"""Shared set-up of the benchmark scripts: where hexcut is and how to run it."""
import os
import re

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


def example_deck(example, edits=()):
    """Text of input/examples/<example> with its mesh paths made absolute (the deck can then be
    written anywhere) and each (old, new) of `edits` replaced; an `old` that is not in the deck
    is an error, so an edited example never runs unedited under a variant's name."""
    text = open(os.path.join(ROOT, "input", "examples", example)).read()
    text = text.replace("../meshes/", os.path.join(ROOT, "input", "meshes") + "/")
    for a, b in edits:
        assert a in text, (example, a)
        text = text.replace(a, b)
    return text


def log_events(text):
    """{event: seconds} of PETSc's -log_view table in `text` (the maximum over ranks)."""
    events = {}
    for line in text.splitlines():
        m = re.match(r"^(\w+)\s+\d+\s+[\d.]+\s+([\d.e+-]+)\s", line)
        if m:
            events[m.group(1)] = float(m.group(2))
    return events


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


# The theses' multigrid stress test (issue 4; Dick 2012, sec. 4.7.2): an n^3 cube clamped
# at its base, cut from the top halfway down by 3 + 3 vertical blades into 16 rods, spun
# about the vertical axis. The blades lie on cell faces 3 cells off the coarse cells'
# boundaries.
CUBE_RODS = """lattice: {{h: {h}, dims: [{n}, {n}, {n}]}}
materials: {{rubber: {{E: 1.0e6, nu: 0.3, rho: 1000}}}}
geometry: [{{add: {{box: {{min: [0, 0, 0], max: [1, 1, 1]}}}}}}]
boundary:
  fixed: [{{where: {{plane: {{point: [0, 0, 0], normal: [0, 0, 1]}}}}}}]
  centrifugal: {{point: [0.5, 0.5, 0], axis: [0, 0, 1], omega: 10}}
cuts:
{blades}
"""


def cube_rods(n, time=None):
    """Deck text (lattice to cuts) of the cube cut into rods; the cuts act at `time`."""
    blades = []
    for axis in (0, 1):
        for k in (1, 2, 3):
            c = (round(0.25 * k * n) + 3) / n
            if axis == 0:
                pts = [[c, -0.1, 0.5], [c, 1.1, 0.5], [c, 1.1, 1.1], [c, -0.1, 1.1]]
            else:
                pts = [[-0.1, c, 0.5], [1.1, c, 0.5], [1.1, c, 1.1], [-0.1, c, 1.1]]
            blades.append(f"  - blade: {{polygon: {pts}}}" + (f"\n    time: {time}" if time is not None else ""))
    return CUBE_RODS.format(h=1.0 / n, n=n, blades="\n".join(blades))


def finish_residual_plot(fig, ax, title, out):
    """Labels, grid and legend of a residual-against-time plot; saves it to `out`."""
    ax.set_xlabel("wall time from the start of set-up [s]")
    ax.set_ylabel("relative residual")
    ax.set_title(title)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(out, dpi=120)
    print(f"wrote {out}")
