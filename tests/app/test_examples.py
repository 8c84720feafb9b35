"""The shipped examples: every deck validates, the cantilever runs with its default
solver and matches Timoshenko beam theory, the dynamic and bunny decks run (the dynamic
one for its first 20 steps), and the bunny with a swept scalpel and a stamp runs on 2
ranks: the stamp's plug comes loose and falls, and both cuts show in the surface."""
import glob
import os
import sys

import h5py
import numpy as np

from cli_helpers import Checks, run, tempdir

SOURCE = os.environ["HEXCUT_SOURCE_DIR"]


def main():
    d = tempdir()
    check = Checks()

    decks = sorted(glob.glob(os.path.join(SOURCE, "input", "examples", "*.yaml")))
    check(len(decks) >= 3, f"{len(decks)} example decks")
    for deck in decks:
        rc, out, err = run(["--check", deck], cwd=d)
        check(rc == 0, f"--check {os.path.basename(deck)}: {out.strip()} {err.strip()}")

    rc, out, err = run([os.path.join(SOURCE, "input/examples/cantilever.yaml")], cwd=d)
    check(rc == 0, f"cantilever runs: {err.strip()}")
    with h5py.File(f"{d}/results/cantilever.h5", "r") as f:
        p = f["mesh/points"][:]
        u = f["steps/000001/displacement"][:]
    tip = -u[np.isclose(p[:, 0], 1.0), 2].mean()
    P, L, E, nu, b, t = 1000.0, 1.0, 200e9, 0.3, 0.1, 0.1
    I, A, G = b * t**3 / 12, b * t, E / (2 * (1 + nu))
    kappa = 10 * (1 + nu) / (12 + 11 * nu)
    delta = P * L**3 / (3 * E * I) + P * L / (kappa * G * A)
    check(abs(tip / delta - 1) < 0.03, f"cantilever tip deflection {tip:.4e} m vs Timoshenko {delta:.4e} m")

    rc, out, err = run([os.path.join(SOURCE, "input/examples/cantilever_dynamic.yaml"), "-hexcut_max_steps", "20"],
                       cwd=d)
    check(rc == 0 and "step 20/600" in out, f"dynamic example runs 20 steps: {err.strip()}")

    rc, out, err = run([os.path.join(SOURCE, "input/examples/bunny.yaml")], cwd=d, ranks=2)
    ok = rc == 0
    if ok:
        with h5py.File(f"{d}/results/bunny.h5", "r") as f:
            u = f["steps/000001/displacement"][:]
            vm = f["steps/000001/von_mises"][:]
            mat = f["mesh/cell_material"][:]
        # Gravity pushes the body down; the stiff core carries the load with less strain,
        # so its stress is higher than the soft tissue's on average.
        ok = u[:, 1].min() < 0 and vm[mat == 1].mean() > vm[mat == 0].mean()
    check(ok, f"bunny runs on 2 ranks and sags under gravity: {err.strip()}")

    rc, out, err = run([os.path.join(SOURCE, "input/examples/bunny_cuts.yaml")], cwd=d, ranks=2)
    ok = rc == 0 and "2 piece(s)" in out and "unsupported" in out
    if ok:
        with h5py.File(f"{d}/results/bunny_cuts.h5", "r") as f:
            last = sorted(f["steps"].keys())[-1]
            ids = set(f[f"steps/{last}/surface/cut_id"][:].tolist())
            mesh = f[f"steps/{last}"].attrs["mesh"].decode()
            p = f[mesh + "/points"][:]
            u = f[f"steps/{last}/displacement"][:]
        # The plug (inside the stamp: |(x, y) - (0.015, 0.03)| < 1 cm) falls further than
        # the glued body around it.
        r = np.hypot(p[:, 0] - 0.015, p[:, 1] - 0.03)
        ok = ids == {0, 1, 2} and u[r < 0.008, 1].mean() < 2 * u[r > 0.012, 1].mean() < 0
    check(ok, f"bunny_cuts runs on 2 ranks: cuts 1 and 2 in the surface, the plug falls: {err.strip()}")
    return check.finish()


if __name__ == "__main__":
    sys.exit(main())
