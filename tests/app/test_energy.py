"""The energy check of dynamic runs (doc/theory.md "Energy balance"): a free rubber brick
spun up by a torque pulse (two opposite end tractions whose time functions, two ramps
superposed, make a triangle pulse over 0.1 s) and then left alone. With lagged rotations
its energy runs away and the run stops with exit 3 (on 1 and 2 ranks), instead of ending
with exit 0; with the default iterated rotations, and with the linear formulation, it
keeps its energy after the pulse and exits 0. analysis.energy_tolerance is read (a huge
value lets the lagged run go on, and its energy is seen to grow), and bad values of the
new keys are deck errors (exit 2)."""
import re
import sys

import h5py

from cli_helpers import Checks, run, tempdir, write

# 0.4 x 0.2 x 0.1 m (8 x 4 x 2 cells), no supports. The couple: 2100 Pa on each 0.02 m^2
# end face, +-y, 0.4 m apart: peak torque 16.8 N m, angular impulse 0.84 N m s about z
# (about 1 rev/s for I_z = 0.133 kg m^2).
DECK = """\
lattice: {h: 0.05, dims: [8, 4, 2]}
materials: {rubber: {E: 1.0e6, nu: 0.3, rho: 1000}}
geometry: [{add: {box: {min: [0, 0, 0], max: [0.4, 0.2, 0.1]}}}]
boundary:
  traction:
    - {where: {plane: {point: [0, 0, 0], normal: [1, 0, 0]}}, value: [0, -2100, 0], scale: {ramp: {value: 1, start: 0, end: 0.05}}}
    - {where: {plane: {point: [0, 0, 0], normal: [1, 0, 0]}}, value: [0, -2100, 0], scale: {ramp: {value: -1, start: 0.05, end: 0.1}}}
    - {where: {plane: {point: [0.4, 0, 0], normal: [1, 0, 0]}}, value: [0, 2100, 0], scale: {ramp: {value: 1, start: 0, end: 0.05}}}
    - {where: {plane: {point: [0.4, 0, 0], normal: [1, 0, 0]}}, value: [0, 2100, 0], scale: {ramp: {value: -1, start: 0.05, end: 0.1}}}
analysis: {type: dynamic, formulation: FORMULATION, dt: 0.01, end_time: END}
solver: {type: direct}
output: {directory: OUT, name: NAME, every: 10}
"""

PROGRESS = re.compile(r"^step (\d+)/\d+\s+t = (\S+) s .*?E (\S+) J\s+created (\S+) J", re.M)


def deck(d, name, formulation="corotational", end=2.0, extra=""):
    text = DECK.replace("FORMULATION", formulation + extra).replace("END", str(end))
    return write(d, name + ".yaml", text.replace("OUT", f"{d}/out").replace("NAME", name))


def energies(out):
    """(step, t, E, created) of every progress line."""
    return [(int(s), float(t), float(e), float(c)) for s, t, e, c in PROGRESS.findall(out)]


def main():
    d = tempdir()
    check = Checks()

    # Lagged rotations (the old behaviour): the energy check stops the run.
    for ranks in (1, 2):
        rc, out, err = run([deck(d, f"lagged{ranks}", extra=", rotations: lagged")], ranks=ranks)
        e = energies(out)
        ok = rc == 3 and "energy check" in err and e and e[-1][0] < 50
        check(ok, f"lagged rotations, {ranks} rank(s): exit {rc} after step {e[-1][0] if e else None} "
              f"(E {e[-1][2] if e else None} J): {err.strip()[:300]}")
    with h5py.File(f"{d}/out/lagged1.h5", "r") as f:
        written = sorted(f["steps"].keys())
    check(written == ["000000", "000010"], f"the steps written before the stop stay readable: {written}")

    # Without the check (a huge tolerance) the same run goes on and its energy grows.
    rc, out, err = run([deck(d, "unchecked", end=1.2, extra=", rotations: lagged, energy_tolerance: 1.0e300")])
    e = energies(out)
    after_pulse = [x for x in e if x[1] > 0.1 + 1e-9]
    ok = rc == 0 and after_pulse and e[-1][2] > 3 * after_pulse[0][2]
    check(ok, f"lagged, no check: exit {rc}, E {after_pulse[0][2] if after_pulse else None} J after the pulse, "
          f"{e[-1][2] if e else None} J at t = {e[-1][1] if e else None} s")

    # Iterated rotations (the default) and the linear formulation: exit 0, energy kept.
    for name, formulation in (("iterated", "corotational"), ("linear", "linear")):
        rc, out, err = run([deck(d, name, formulation=formulation)])
        e = energies(out)
        free = [x[2] for x in e if x[1] > 0.1 + 1e-9]
        spread = (max(free) - min(free)) / max(free) if free else None
        ok = rc == 0 and len(e) == 200 and free and spread < 1e-3 and abs(e[-1][3]) < 1e-4 * free[0]
        check(ok, f"{name}: exit {rc}, {len(e)} steps, energy after the pulse {free[0] if free else None} J, "
              f"spread {spread}, created {e[-1][3] if e else None} J {err.strip()[:300]}")

    # The new keys are checked.
    bad = [("rotations: sideways", "analysis.rotations must be 'iterated' or 'lagged'"),
           ("energy_tolerance: 0", "analysis.energy_tolerance must be > 0")]
    for extra, message in bad:
        rc, out, err = run([deck(d, "bad", extra=", " + extra)])
        check(rc == 2 and "bad.yaml:10:" in err and message in err, f"{extra}: exit {rc}: {err.strip()}")
    rc, out, err = run([deck(d, "bad", formulation="linear", extra=", rotations: lagged")])
    check(rc == 2 and "rotations applies only to formulation: corotational" in err, f"rotations with linear: {rc} {err.strip()}")
    return check.finish()


if __name__ == "__main__":
    sys.exit(main())
