"""Each class of deck error gives 'deck.yaml:LINE: message' and exit code 2, before any
heavy work; --version and --check work; a non-converging solve gives exit 3 and keeps
the steps written so far readable."""
import sys

import h5py

from cli_helpers import Checks, run, tempdir, write

GOOD = """\
lattice: {h: 0.1, dims: [10, 2, 2]}
materials:
  steel: {E: 200.0e9, nu: 0.3, rho: 7800}
geometry:
  - add: {box: {min: [0, 0, 0], max: [1.0, 0.2, 0.2]}}
boundary:
  fixed:
    - where: {plane: {point: [0, 0, 0], normal: [1, 0, 0]}}
  traction:
    - where: {plane: {point: [1.0, 0, 0], normal: [1, 0, 0]}}
      value: [0, 0, -1000.0]
solver: {type: direct}
"""

# (description, text to replace, replacement, expected line, expected message part)
CASES = [
    ("unknown key", "solver: {type: direct}", "solver: {type: direct, tolerance: 1}", 12, "unknown key 'tolerance'"),
    ("wrong type", "h: 0.1", "h: fast", 1, "lattice.h must be a number"),
    ("nu >= 0.5", "nu: 0.3", "nu: 0.5", 3, "nu must be in (-1, 0.5)"),
    ("h <= 0", "h: 0.1", "h: -0.1", 1, "lattice.h must be > 0"),
    ("unknown material", "add: {box: {min: [0, 0, 0], max: [1.0, 0.2, 0.2]}}",
     "add: {box: {min: [0, 0, 0], max: [1.0, 0.2, 0.2]}}\n    material: wood", 6, "unknown material 'wood'"),
    ("empty geometry", "max: [1.0, 0.2, 0.2]", "max: [-5.0, -4.0, -4.0]", 5, "box.max must exceed box.min"),
    ("geometry outside the lattice", "min: [0, 0, 0], max: [1.0, 0.2, 0.2]", "min: [5, 5, 5], max: [6, 6, 6]", 5,
     "the geometry is empty"),
    ("selector selects nothing", "point: [1.0, 0, 0]", "point: [3.0, 0, 0]", 10,
     "this traction selects no boundary face"),
    ("support selects nothing", "point: [0, 0, 0], normal: [1, 0, 0]}}\n  traction",
     "point: [-1, 0, 0], normal: [1, 0, 0]}}\n  traction", 8, "this support selects no vertex"),
    ("bad solver", "type: direct", "type: superlu", 12, "solver.type must be one of"),
    ("YAML syntax", "dims: [10, 2, 2]}", "dims: [10, 2, 2]", 2, "YAML syntax error"),
    ("missing mesh file", "add: {box: {min: [0, 0, 0], max: [1.0, 0.2, 0.2]}}", "add: {mesh: {file: nowhere.obj}}", 5,
     "cannot load mesh"),
    ("dynamic without dt", "solver: {type: direct}", "analysis: {type: dynamic, steps: 3}\nsolver: {type: direct}", 12,
     "dynamic analysis needs 'dt'"),
]


def main():
    d = tempdir()
    check = Checks()
    rc, out, err = run(["--version"])
    check(rc == 0 and out.startswith("hexcut "), f"--version: {out.strip()} {err.strip()}")
    good = write(d, "good.yaml", GOOD)
    rc, out, err = run(["--check", good])
    check(rc == 0 and "deck is valid" in out, f"a valid deck passes --check: {out.strip()} {err.strip()}")
    for name, old, new, line, message in CASES:
        assert old in GOOD, name
        path = write(d, "deck.yaml", GOOD.replace(old, new, 1))
        rc, out, err = run(["--check", path])
        expected_prefix = f"{path}:{line}: "
        check(rc == 2 and expected_prefix in err and message in err, f"{name}: exit {rc}: {err.strip()}")
    # A solve that cannot converge: exit 3, the steps written before stay readable.
    dyn = GOOD.replace("solver: {type: direct}",
                       "analysis: {type: dynamic, dt: 1.0e-4, steps: 5}\n"
                       "solver: {type: cg-jacobi, rtol: 1.0e-12, max_iterations: 3}\n"
                       f"output: {{directory: {d}, name: failing}}\n")
    path = write(d, "failing.yaml", dyn)
    rc, out, err = run([path])
    ok = rc == 3 and "DIVERGED_ITS" in err
    with h5py.File(f"{d}/failing.h5", "r") as f:
        ok = ok and f["steps"].attrs["last_complete_step"] == 0 and f["steps/000000/displacement"].shape[1] == 3
    check(ok, f"non-converging solve: exit {rc}: {err.strip()}")
    return check.finish()


if __name__ == "__main__":
    sys.exit(main())
