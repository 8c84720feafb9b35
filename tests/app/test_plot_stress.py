"""scripts/plot_stress.py (doc/user-guide.md, "Stress analysis"): slices of a result's stress
fields against the analytic answer of a bar in uniaxial tension on rollers (sigma_xx = the
traction everywhere: von Mises = t, first principal stress t along x), in a lattice larger
than the bar (the cells outside it are empty: NaN in the slice):

- the slice through z = 0.15 m holds von Mises = t on the bar's 10 x 2 cells and NaN on the
  other cells of the layer; the slice x = 0.55 m likewise on its 2 x 2 cells;
- a run under twice the load compared with the first: the default panels include the
  comparison fields, von_mises_change = t and stress_shielding = -3 in every cell;
- the PNG is written and is not blank;
- a step, field or plane the file does not have is refused with exit 2 and a message."""
import os
import subprocess
import sys

import numpy as np

from cli_helpers import Checks, run, tempdir, write

ROOT = os.environ["HEXCUT_SOURCE_DIR"]
SCRIPT = os.path.join(ROOT, "scripts", "plot_stress.py")
sys.path.insert(0, os.path.join(ROOT, "scripts"))
import plot_stress  # noqa: E402
import h5py  # noqa: E402

T = 1.0e6
BAR = """\
lattice: {{h: 0.1, dims: [12, 4, 3]}}
materials: {{m: {{E: 1.0e9, nu: 0.3, rho: 1}}}}
geometry:
  - add: {{box: {{min: [0, 0, 0], max: [1.0, 0.2, 0.2]}}}}
boundary:
  fixed:
    - {{where: {{plane: {{point: [0, 0, 0], normal: [1, 0, 0]}}}}, components: [x]}}
    - {{where: {{plane: {{point: [0, 0, 0], normal: [0, 1, 0]}}}}, components: [y]}}
    - {{where: {{plane: {{point: [0, 0, 0], normal: [0, 0, 1]}}}}, components: [z]}}
  traction:
    - where: {{plane: {{point: [1.0, 0, 0], normal: [1, 0, 0]}}}}
      value: [{t}, 0, 0]
solver: {{type: direct}}
output: {{directory: {d}, fields: [stress, von_mises, principal_stress, principal_directions,
  strain_energy_density]}}
{extra}"""


def layer(path, axis, at, field, step=-1):
    with h5py.File(path) as f:
        rows, ij, dims2, _, _, _, g, _ = plot_stress.slice_cells(f, step, axis, at)
        return plot_stress.field_image(g, rows, ij, dims2, field)


def plot(args):
    p = subprocess.run([sys.executable, SCRIPT, *args], capture_output=True, text=True)
    return p.returncode, p.stderr


def main():
    d = tempdir()
    check = Checks()
    ref_deck = write(d, "bar.yaml", BAR.format(t=T, d=f"{d}/ref", extra=""))
    rc, out, err = run([ref_deck])
    check(rc == 0, f"bar run: exit {rc} {err.strip()[-200:]}")
    ref = f"{d}/ref/bar.h5"

    vm = layer(ref, "z", 0.15, "von_mises")
    inside = np.zeros_like(vm, dtype=bool)
    inside[:2, :10] = True  # rows: y cells, columns: x cells
    check(vm.shape == (4, 12), f"z slice shape {vm.shape} = (ny, nx) = (4, 12)")
    check(np.all(np.isnan(vm[~inside])), "cells outside the bar are NaN")
    err_vm = np.max(np.abs(vm[inside] - T)) / T
    check(err_vm < 1e-8, f"von Mises = traction on the bar's cells (relative error {err_vm:.1e})")
    s1 = layer(ref, "x", 0.55, "principal_stress_1")
    check(s1.shape == (3, 4) and np.all(np.isfinite(s1[:2, :2])) and np.all(np.isnan(s1[2:, :])),
          f"x slice: (nz, ny) = {s1.shape}, the bar's 2 x 2 cells filled")
    check(np.max(np.abs(s1[:2, :2] - T)) < 1e-8 * T, "first principal stress = traction")

    png = os.path.join(d, "bar.png")
    rc, err = plot([ref, png, "--axis", "z", "--at", "0.15"])
    check(rc == 0 and os.path.getsize(png) > 0, f"PNG written: exit {rc} {err.strip()[-300:]}")
    import matplotlib.image as mpimg
    img = mpimg.imread(png)
    check(img.shape[0] > 100 and np.std(img[..., :3]) > 0.05, f"PNG {img.shape} is not blank")

    cmp_deck = write(d, "twice.yaml", BAR.format(t=2 * T, d=f"{d}/twice",
                                                  extra=f"compare: {{reference: {ref}}}\n"))
    rc, out, err = run([cmp_deck])
    check(rc == 0, f"compared run: exit {rc} {err.strip()[-200:]}")
    twice = f"{d}/twice/twice.h5"
    dv = layer(twice, "z", 0.15, "von_mises_change")
    check(np.max(np.abs(dv[inside] - T)) < 1e-8 * T and np.all(np.isnan(dv[~inside])),
          "von_mises_change = t on the bar, NaN outside")
    sh = layer(twice, "z", 0.15, "stress_shielding")
    check(np.max(np.abs(sh[inside] + 3.0)) < 1e-8, "stress_shielding = -3 under twice the load")
    png2 = os.path.join(d, "twice.png")
    rc, err = plot([twice, png2, "--title", "twice the load"])
    check(rc == 0 and os.path.getsize(png2) > 0, f"default panels with comparison fields: exit {rc} {err[-300:]}")

    for args, want in ((["--step", "5"], "out of range"), (["--fields", "nonsense"], "no cell field 'nonsense'"),
                       (["--axis", "x", "--at", "7"], "outside the lattice")):
        rc, err = plot([ref, os.path.join(d, "x.png"), *args])
        check(rc == 2 and want in err and ref in err, f"{' '.join(args)}: exit {rc}, '{err.strip()}'")
    return check.finish()


if __name__ == "__main__":
    sys.exit(main())
