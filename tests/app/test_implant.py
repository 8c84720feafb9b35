"""Implant insertion (doc/user-guide.md "geometry"): a stem mesh, turned and moved by
mesh.rotate and mesh.translate, added into a bone as its own material after the bone, bonded
to it (face neighbours share their vertices):

- the cells that become implant are exactly those whose centres lie inside the turned and
  moved prism (counted here from the prism's own geometry);
- an implant of the bone's own material properties gives the bone's result exactly (same
  cells, same displacements): insertion changes materials, not the mesh or its bonding;
- a titanium stem stiffens the bone (the loaded end moves less) and 2 ranks = 1 rank;
- after a calibrated CT image, the implant's cells carry titanium's E, the bone's cells the
  calibration's (the last operation on a cell decides)."""
import math

import h5py
import numpy as np

from cli_helpers import Checks, run, tempdir, write

R, HALF = 0.025, 0.15  # stem: octagonal prism of circumradius R, length 2 HALF along its z
ANGLE = 12.0  # degrees about y
SHIFT = np.array([0.05, 0.05, 0.25])


def stem_obj():
    ring = [(R * math.cos(2 * math.pi * i / 8), R * math.sin(2 * math.pi * i / 8)) for i in range(8)]
    lines = [f"v {x} {y} {-HALF}" for x, y in ring] + [f"v {x} {y} {HALF}" for x, y in ring]
    lines += [f"f {i + 1} {(i + 1) % 8 + 1} {(i + 1) % 8 + 9} {i + 9}" for i in range(8)]
    lines += ["f " + " ".join(str(i) for i in range(8, 0, -1)), "f " + " ".join(str(i) for i in range(9, 17))]
    return "\n".join(lines) + "\n"


def inside_stem(p):
    """Points p (n, 3) inside the stem after rotate and translate: undo both, then test the
    prism (an octagon is the intersection of 8 half-planes at the apothem)."""
    a = math.radians(ANGLE)
    Ry = np.array([[math.cos(a), 0, math.sin(a)], [0, 1, 0], [-math.sin(a), 0, math.cos(a)]])
    q = (p - SHIFT) @ Ry  # = Ry^T (p - SHIFT) per row
    ok = np.abs(q[:, 2]) < HALF
    apothem = R * math.cos(math.pi / 8)
    for i in range(8):
        t = 2 * math.pi * (i + 0.5) / 8
        ok &= q[:, 0] * math.cos(t) + q[:, 1] * math.sin(t) < apothem
    return ok


def deck(d, name, implant, E_implant=1.0e9, image=""):
    stem = ""
    if implant:
        stem = (f"  - add: {{mesh: {{file: stem.obj, rotate: {{axis: [0, 1, 0], angle: {ANGLE}}}, "
                f"translate: [{SHIFT[0]}, {SHIFT[1]}, {SHIFT[2]}]}}}}\n    material: implant\n")
    return f"""lattice: {{h: 0.01, dims: [10, 10, 50]}}
materials:
  bone: {{E: 1.0e9, nu: 0.3, rho: 1900}}
  implant: {{E: {E_implant}, nu: 0.3, rho: 1900}}
geometry:
  - add: {{box: {{min: [0, 0, 0], max: [0.1, 0.1, 0.5]}}}}
    material: bone
{image}{stem}boundary:
  fixed:
    - where: {{plane: {{point: [0, 0, 0], normal: [0, 0, 1]}}}}
  traction:
    - where: {{plane: {{point: [0, 0, 0.5], normal: [0, 0, 1]}}}}
      value: [2.0e4, 0, -1.0e5]
solver: {{type: direct}}
output: {{directory: {d}/{name}}}
"""


def result(d, name):
    with h5py.File(f"{d}/{name}/{name}.h5") as f:
        step = f["steps/" + sorted(f["steps"].keys())[-1]]
        pts = f["mesh/points"][()]
        cells = f["mesh/cells"][()]
        return {"u": step["displacement"][()], "material": f["mesh/cell_material"][()],
                "E": f["mesh/cell_youngs_modulus"][()], "centres": pts[cells].mean(axis=1)}


def main():
    d = tempdir()
    check = Checks()
    write(d, "stem.obj", stem_obj())
    out = {}
    for name, implant, E in (("bone", False, 1.0e9), ("same", True, 1.0e9), ("titanium", True, 110.0e9)):
        rc, o, err = run([write(d, f"{name}.yaml", deck(d, name, implant, E))])
        check(rc == 0, f"{name}: exit {rc} {err.strip()[-300:]}")
        if rc != 0:
            return check.finish()
        out[name] = result(d, name)
    bone, same, ti = out["bone"], out["same"], out["titanium"]
    expected = inside_stem(same["centres"])
    got = same["material"] == 1
    check(expected.sum() > 100 and np.array_equal(got, expected),
          f"implant cells = cell centres inside the turned, moved prism: {got.sum()} (prism: {expected.sum()})")
    diff = np.abs(same["u"] - bone["u"]).max()
    check(same["u"].shape == bone["u"].shape and diff <= 1e-12 * np.abs(bone["u"]).max(),
          f"an implant of the bone's properties gives the bone's result: same {bone['u'].shape[0]} points, "
          f"max |du| = {diff:.3g} m")
    top_bone, top_ti = np.abs(bone["u"]).max(), np.abs(ti["u"]).max()
    check(top_ti < 0.9 * top_bone,
          f"a titanium stem stiffens the bone: max |u| {top_ti:.4g} m against {top_bone:.4g} m")
    rc, o, err = run([write(d, "titanium2.yaml", deck(d, "titanium2", True, 110.0e9))], ranks=2)
    if rc == 0:
        t2 = result(d, "titanium2")
        diff = np.abs(t2["u"] - ti["u"]).max()
        check(diff <= 1e-10 * top_ti, f"titanium stem on 2 ranks = 1 rank: max |du| = {diff:.3g} m")
    else:
        check(False, f"titanium stem on 2 ranks: exit {rc} {err.strip()[-300:]}")

    # After a calibrated CT image (HU 1000 everywhere, E = a rho^b with rho = 0.001 HU + 1):
    # the implant keeps titanium's E, the bone the law's.
    with h5py.File(f"{d}/ct.h5", "w") as f:
        f["hu"] = np.full((50, 10, 10), 1000.0, dtype=np.float32)
    image = ("  - image: {file: ct.h5, format: hdf5, dataset: hu, spacing: [0.01, 0.01, 0.01], "
             "calibration: {density: {slope: 0.001, intercept: 1.0}, youngs: {a: 6.85e9, b: 1.49}}}\n")
    rc, o, err = run([write(d, "ct.yaml", deck(d, "ct", True, 110.0e9, image))])
    if rc == 0:
        r = result(d, "ct")
        law = 6.85e9 * 2.0 ** 1.49
        imp = r["material"] == 1
        check(np.all(r["E"][imp] == 110.0e9) and np.allclose(r["E"][~imp], law, rtol=1e-6),
              f"after a calibrated image: implant cells E = {np.unique(r['E'][imp])} Pa, bone cells "
              f"{np.unique(r['E'][~imp])} Pa (law: {law:.6g})")
    else:
        check(False, f"implant after a calibrated image: exit {rc} {err.strip()[-300:]}")
    return check.finish()


if __name__ == "__main__":
    raise SystemExit(main())
