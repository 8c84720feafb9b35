"""Pressures and expressions from the command line: a thick-walled cylinder under internal
pressure runs on 1 and 2 ranks and matches Lamé; every kind of expression error gives
'deck.yaml:LINE: expression error: ...' and exit 2 at --check; an expression that is not
finite where it is used stops the run with exit 2 naming its line (also on 2 ranks, where
only one rank meets the bad value); a traction given as a total force is that force spread
over the selected faces' area (the same displacements as the traction F / A, on 1 and 2
ranks)."""
import sys

import h5py
import numpy as np

from cli_helpers import Checks, run, tempdir, write

# Plane strain ring, inner radius 1, outer 2, 16 cells through the wall (doc/theory.md,
# "Supports and loads"; tests/analysis/loads_test.cpp has the convergence study).
CYLINDER = """\
lattice: {h: 0.0625, bounds: [[-2, -2, 0], [2, 2, 0.0625]]}
materials: {m: {E: 1.0e9, nu: 0.3, rho: 1}}
geometry:
  - add: {cylinder: {start: [0, 0, -1], end: [0, 0, 1], radius: 2}}
  - subtract: {cylinder: {start: [0, 0, -1], end: [0, 0, 1], radius: 1}}
boundary:
  fixed:
    - {where: {all: true}, components: [z]}
    - {where: {plane: {point: [0, 0, 0], normal: [1, 0, 0]}}, components: [x]}
    - {where: {plane: {point: [0, 0, 0], normal: [0, 1, 0]}}, components: [y]}
  pressure:
    - where: {cylinder: {start: [0, 0, 0.015625], end: [0, 0, 0.046875], radius: 1.046875}}
      value: 1.0e6
solver: {type: gmg, rtol: 1.0e-10}
output: {directory: DIR, name: NAME, fields: [displacement]}
"""

# Line numbers below refer to this deck.
GOOD = """\
lattice: {h: 0.1, dims: [10, 2, 2]}
materials:
  steel: {E: 200.0e9, nu: 0.3, rho: 7800}
geometry:
  - add: {box: {min: [0, 0, 0], max: [1.0, 0.2, 0.2]}}
boundary:
  fixed:
    - where: {plane: {point: [0, 0, 0], normal: [1, 0, 0]}}
      value: [0, 0, '1e-6 * y']
  traction:
    - where: {plane: {point: [1.0, 0, 0], normal: [1, 0, 0]}}
      value: [0, 0, '-1000 * (1 + y)']
  pressure:
    - where: {plane: {point: [0, 0, 0.2], normal: [0, 0, 1]}}
      value: '2000 * x'
      scale: {ramp: {value: 1, end: 1}}
solver: {type: direct}
"""

# (description, text to replace, replacement, expected line, expected message part)
ERRORS = [
    ("unknown variable", "'2000 * x'", "'2000 * q'", 15, "expression error: Unexpected token \"q\" found at position 7"),
    ("syntax error", "'2000 * x'", "'2000 * (x'", 15, "expression error: Missing parenthesis at position"),
    ("unknown function", "'-1000 * (1 + y)'", "'-1000 * foo(y)'", 12, "expression error: Unexpected parenthesis \"(\" at position 11"),
    ("several values", "'1e-6 * y'", "'1e-6, y'", 9, "expression error: 2 comma-separated values"),
    ("constant not finite", "'2000 * x'", "'1/0'", 15, "expression error: the value is not finite"),
    ("pressure value a list", "'2000 * x'", "[1, 2, 3]", 15, "pressure.value must be a number or an expression"),
    ("pressure without value", "      value: '2000 * x'\n", "", 14, "pressure needs 'where' and 'value'"),
    ("pressure selects nothing", "point: [0, 0, 0.2]", "point: [0, 0, 5]", 14,
     "this pressure selects no boundary face"),
    ("unknown key in pressure", "scale: {ramp", "factor: {ramp", 16, "unknown key 'factor' in pressure"),
    # Fixed in time: integrated (faces) or evaluated (vertices) when the selectors are
    # resolved, so --check already finds them.
    ("pressure not finite on its faces", "'2000 * x'", "'2000 * sqrt(0.5 - x)'", 15,
     "the expression '2000 * sqrt(0.5 - x)' is nan at x = 0."),
    ("support not finite at a vertex", "'1e-6 * y'", "'sqrt(y - 0.1)'", 9, "the expression 'sqrt(y - 0.1)' is nan at x = 0"),
]


def lame_error(path):
    """Relative L2 error of u_r over the vertices against Lamé (a = 1, b = 2)."""
    with h5py.File(path, "r") as f:
        x = f["mesh/points"][:]
        u = f["steps/000001/displacement"][:]
    a, b, E, nu, p = 1.0, 2.0, 1.0e9, 0.3, 1.0e6
    r = np.hypot(x[:, 0], x[:, 1])
    exact = p * a * a / (E * (b * b - a * a)) * ((1 + nu) * (1 - 2 * nu) * r + (1 + nu) * b * b / r)
    ur = (u[:, 0] * x[:, 0] + u[:, 1] * x[:, 1]) / r
    return np.sqrt(np.sum((ur - exact) ** 2) / np.sum(exact**2)), u


def main():
    d = tempdir()
    check = Checks()

    errors = {}
    for ranks in (1, 2):
        path = write(d, f"cylinder{ranks}.yaml", CYLINDER.replace("DIR", d).replace("NAME", f"cyl{ranks}"))
        rc, out, err = run([path], ranks=ranks)
        check(rc == 0, f"cylinder on {ranks} rank(s) runs: {err.strip()[-300:]}")
        if rc == 0:
            errors[ranks] = lame_error(f"{d}/cyl{ranks}.h5")
    if len(errors) == 2:
        e1, u1 = errors[1]
        e2, u2 = errors[2]
        check(e1 < 0.04, f"cylinder, 16 cells through the wall: u_r within {e1:.4f} (L2, relative) of Lamé")
        diff = np.abs(u1 - u2).max() / np.abs(u1).max()
        check(diff < 1e-8, f"cylinder: 2 ranks equal 1 rank to {diff:.1e}")

    good = write(d, "good.yaml", GOOD)
    rc, out, err = run(["--check", good])
    check(rc == 0 and "deck is valid" in out, f"a deck with expressions passes --check: {out.strip()} {err.strip()}")
    for name, old, new, line, message in ERRORS:
        assert old in GOOD, name
        path = write(d, "deck.yaml", GOOD.replace(old, new, 1))
        rc, out, err = run(["--check", path])
        check(rc == 2 and f"{path}:{line}: " in err and message in err, f"{name}: exit {rc}: {err.strip()}")

    # Expressions of t: static analyses use t = 1 only, so --check evaluates them there;
    # dynamic ones are checked where the loads are assembled: this one meets the bad
    # value at its third step (t = 0.375 s), only on the faces beyond x = 0.8, which are
    # on one of the two ranks.
    runtime = [
        ("traction at t = 1 (static)", "'-1000 * (1 + y)'", "'-1000 / (t - 1)'", 12, "{type: static}", 1),
        ("support at t = 1 (static)", "'1e-6 * y'", "'sqrt(0.5 - t) * y'", 9, "{type: static}", 1),
        ("pressure at t = 0.375 (dynamic), 2 ranks", "'2000 * x'", "'2000 / (t - 0.375 + (x < 0.8))'", 15,
         "{type: dynamic, dt: 0.125, steps: 5}", 2),
    ]
    for k, (name, old, new, line, analysis, ranks) in enumerate(runtime):
        text = GOOD.replace(old, new, 1).replace(
            "solver:", f"analysis: {analysis}\noutput: {{directory: {d}, name: runtime{k}}}\nsolver:")
        path = write(d, f"runtime{k}.yaml", text)
        message = f"{path}:{line}: the expression"
        rc, out, err = run(["--check", path])
        static = "static" in analysis
        bad = rc == 2 and message in err and any(f"is {v} at" in err for v in ("inf", "-inf", "nan"))
        check(bad if static else rc == 0, f"{name}: --check: exit {rc}: {err.strip()}")
        if not static:
            rc, out, err = run([path], ranks=ranks)
            bad = rc == 2 and message in err and any(f"is {v} at" in err for v in ("inf", "-inf", "nan"))
            check(bad and "step 2/5" in out and "step 3/5" not in out, f"{name}: exit {rc}: {err.strip()[-400:]}")

    # traction.force: a total force over the selected faces (here the end face 0.2 x 0.2 m
    # and, with a box selector, the upper half of it) = the traction F / A on those faces.
    from cli_helpers import BEAM
    force = [300.0, -200.0, -1000.0]
    runs = {}
    for name, where, load in (
            ("value", "{plane: {point: [1.0, 0, 0], normal: [1, 0, 0]}}", f"value: {[f / 0.04 for f in force]}"),
            ("force", "{plane: {point: [1.0, 0, 0], normal: [1, 0, 0]}}", f"force: {force}"),
            ("half_value", "{box: {min: [0.99, -1, 0.1], max: [1.01, 1, 1]}}", f"value: {[f / 0.02 for f in force]}"),
            ("half_force", "{box: {min: [0.99, -1, 0.1], max: [1.01, 1, 1]}}", f"force: {force}")):
        text = BEAM.replace("{plane: {point: [1.0, 0, 0], normal: [1, 0, 0]}}\n      value: [0, 0, -1000.0]",
                            f"{where}\n      {load}")
        assert text != BEAM
        for ranks in (1, 2):
            path = write(d, f"{name}{ranks}.yaml", text + f"output: {{directory: {d}/{name}{ranks}}}\n")
            rc, out, err = run([path], ranks=ranks)
            check(rc == 0, f"traction {name} on {ranks} rank(s): exit {rc} {err.strip()[-300:]}")
            if rc == 0:
                with h5py.File(f"{d}/{name}{ranks}/{name}{ranks}.h5") as f:
                    runs[name, ranks] = f["steps/" + sorted(f["steps"].keys())[-1] + "/displacement"][()]
    for a, b in (("value", "force"), ("half_value", "half_force")):
        if all((k, r) in runs for k in (a, b) for r in (1, 2)):
            ref = np.abs(runs[a, 1]).max()
            diff = max(np.abs(runs[b, r] - runs[a, 1]).max() for r in (1, 2))
            check(diff <= 1e-9 * ref, f"traction force {force} N over {b}'s faces = traction F / A: "
                  f"max |du| = {diff:.3g} m (of {ref:.3g}) on 1 and 2 ranks")
    both = BEAM.replace("value: [0, 0, -1000.0]", "value: [0, 0, -1000.0]\n      force: [0, 0, 1]")
    rc, out, err = run(["--check", write(d, "both.yaml", both)])
    check(rc == 2 and "both.yaml:12:" in err and "not both" in err, f"traction with value and force: exit {rc}: {err.strip()}")
    return check.finish()


if __name__ == "__main__":
    sys.exit(main())
